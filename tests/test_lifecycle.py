"""Lifecycle: close() frees every GL object, cameras outlive their targets, the hash ignores presentation."""
import gc

import esper
import moderngl
import numpy as np
import pytest

from driftframe.app import attach_rendering, make_world
from driftframe.components.body import Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.control import Player
from driftframe.components.render import ModelRef
from driftframe.systems.hud import HudSystem

pytestmark = pytest.mark.gl

_GL_TYPES = (moderngl.Buffer, moderngl.Program, moderngl.Texture, moderngl.VertexArray, moderngl.Framebuffer,
             moderngl.Renderbuffer, moderngl.TextureCube)


def _live_gl_objects() -> list:
    gc.collect()
    # type(), not isinstance(): the heap can hold a weakref.proxy whose target is gone (numba keeps
    # some), and isinstance() on one raises ReferenceError
    return [o for o in gc.get_objects()
            if issubclass(type(o), _GL_TYPES) and not isinstance(o.mglo, moderngl.InvalidObject)]


def test_close_releases_every_gl_object_any_system_made(ctx):
    before = {id(o) for o in _live_gl_objects()}
    world, _ = make_world("asteroids", seed=1)
    attach_rendering(world, ctx, size=(160, 90), own_context=False)
    world.step(3)
    world.render()
    made = [o for o in _live_gl_objects() if id(o) not in before]
    assert len(made) > 10                          # programs, buffers, vertex arrays, the HUD's font texture
    assert any(isinstance(o, moderngl.Texture) for o in made)
    world.close()
    left = [o for o in made if not isinstance(o.mglo, moderngl.InvalidObject)]
    assert left == [], [type(o).__name__ for o in left]


def test_a_camera_whose_target_dies_holds_its_last_pose_and_the_hud_says_so(world, ctx):
    ship = world.create_entity(Player(), Transform((0, 0, 0)), Velocity((0, 0, 3.0)), ModelRef("ship"))
    cam_ent = world.create_entity(Camera(target=ship, mode="chase"))
    attach_rendering(world, ctx, size=(160, 90), own_context=False)
    from driftframe.systems.movement import MovementSystem
    world.add_system(MovementSystem())
    world.step(10)
    world.render()
    eye = esper.component_for_entity(cam_ent, Transform).position
    world.delete_entity(ship)
    world.step(10)                                 # nothing raises mid-step
    world.render()
    cam = esper.component_for_entity(cam_ent, Camera)
    assert cam.target_lost
    np.testing.assert_array_equal(esper.component_for_entity(cam_ent, Transform).position, eye)
    assert any("TARGET LOST" in line for line in world.get_system(HudSystem).last["text"])


def test_the_state_hash_is_the_same_with_or_without_rendering(ctx):
    hashes = []
    for rendered in (False, True):
        world, _ = make_world("asteroids", seed=2)
        try:
            if rendered:
                attach_rendering(world, ctx, size=(64, 36), own_context=False)
            for _ in range(30):
                world.step(2)
                if rendered:
                    world.render()
            hashes.append(world.state_hash())
        finally:
            world.close()
    assert hashes[0] == hashes[1]


def test_prepare_builds_the_systems_caches_and_changes_nothing():
    """World.prepare() does the first step's one-time work at load: same states, hash and events after."""
    from driftframe import CollisionSystem, Mass, MovementSystem, SphereCollider, Transform, Velocity, World

    def world(prepared):
        w = World()
        w.add_system(MovementSystem())
        cs = w.add_system(CollisionSystem())
        rng = np.random.default_rng(4)
        n = 60
        w.create_entities(Transform.bulk(n, position=rng.uniform(0, 30, (n, 3))),
                          Velocity.bulk(n, linear=rng.normal(0, 2, (n, 3))), Mass.bulk(n, kg=np.ones(n)),
                          SphereCollider.bulk(n, radius=np.full(n, 0.5)))
        w.create_entity(Transform((100.0, 0, 0)), Velocity((1.0, 0, 0)))      # a free body: movement's own
        if prepared:
            before = w.state_hash()
            w.prepare()
            assert w.state_hash() == before
            assert cs._layout is not None and cs._layout.state is not None       # built at load, not in step 1
            assert cs._list_layout is cs._layout                                   # and the neighbour list
        w.step()
        first_builds = cs.stats["builds"]
        w.step(39)
        return w.state_hash(), len(w.events), first_builds

    (h1, n1, builds1), (h0, n0, builds0) = world(True), world(False)
    assert (h1, n1) == (h0, n0)
    assert builds0 == 1 and builds1 == 0              # prepared: the first step builds nothing

    # a state changed between prepare() and the first step: the list built at load is not trusted blindly
    def moved(teleport):
        w = World()
        w.add_system(MovementSystem())
        w.add_system(CollisionSystem())
        a = w.create_entity(Transform((0.0, 0, 0)), Velocity((0.0, 0, 0)), SphereCollider(radius=0.5))
        w.create_entity(Transform((50.0, 0, 0)), Velocity((0.0, 0, 0)), SphereCollider(radius=0.5))
        for k in range(58):                            # enough bodies for the list (far off, at rest)
            w.create_entity(Transform((0.0, 1e3 + 5.0 * k, 0)), Velocity((0.0, 0, 0)), SphereCollider(radius=0.5))
        w.prepare()
        if teleport:
            w.columns(Transform, [a]).position = np.array([[48.0, 0.0, 0.0]])   # 1 m off b, closing fast
            w.columns(Velocity, [a]).linear = np.array([[30.0, 0.0, 0.0]])
        hits = []
        from driftframe.components.collision import CollisionEvent
        w.subscribe(CollisionEvent, hits.append)
        w.step(3)
        w.close()
        return hits
    assert moved(False) == [] and len(moved(True)) == 1
