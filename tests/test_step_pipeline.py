"""The step as one pipeline: movement predicts every body, gravity and collision correct the bodies they
own, the commit writes them all at once (framework/step.py). A user's system sees one state."""
import esper
import numpy as np
import pytest

from driftframe.components.body import Acceleration, Mass, Transform, Velocity
from driftframe.components.collision import SphereCollider
from driftframe.components.gravity import GravityWell
from driftframe.framework.step import advance
from driftframe.framework.world import ScheduleError, World
from driftframe.systems.collision import CollisionSystem
from driftframe.systems.gravity import GravitySystem
from driftframe.systems.movement import MovementSystem

DT = 1.0 / 60.0


class Drag(esper.Processor):
    """The GUIDE's example: reads Velocity; writes Velocity.  v *= exp(-k dt)."""
    writes = (Velocity,)
    reads = (Velocity, Transform)                   # (its query takes the bodies: those with a Transform)

    def __init__(self, k):
        self.k = k

    def process(self, dt):
        q = self.world.query(Velocity, Transform)
        q.refresh()
        if not len(q):
            return
        cols = q.columns(Velocity)
        cols.linear = cols.linear * np.exp(-self.k * dt)


class Snapshot(esper.Processor):
    """Reads Transform, Velocity; writes nothing: what it saw, per entity."""
    reads = (Transform, Velocity)
    writes = ()

    def __init__(self, ents):
        self.ents, self.seen = ents, []

    def process(self, dt):
        self.seen.append((self.world.columns(Transform, self.ents).position.copy(),
                          self.world.columns(Velocity, self.ents).linear.copy()))


def two_bodies(world, v=1.0):
    """Two identical bodies far apart, the second a collider (so the collision system owns it)."""
    plain = world.create_entity(Transform((0, 0, 0)), Velocity((v, 0, 0)))
    coll = world.create_entity(Transform((0, 50, 0)), Velocity((v, 0, 0)), SphereCollider(radius=1.0))
    return plain, coll


def standard(world):
    world.add_system(MovementSystem())
    world.add_system(CollisionSystem())


def test_the_guides_drag_moves_a_plain_body_and_a_collider_alike():
    k = 60 * np.log(2)                                  # halves the velocity in one step of 1/60 s
    world = World(dt=DT)
    try:
        standard(world)
        world.add_system(Drag(k), before="movement")
        plain, coll = two_bodies(world)
        world.step()
        x = world.columns(Transform, [plain, coll]).position[:, 0]
        v = world.columns(Velocity, [plain, coll]).linear[:, 0]
        assert x[0] == x[1] == pytest.approx(0.5 * DT, rel=1e-12)   # the whole step moved with the drag
        assert v[0] == v[1] == pytest.approx(0.5, rel=1e-12)
    finally:
        world.close()


def test_a_velocity_writer_between_movement_and_commit_is_refused_by_name():
    world = World(dt=DT)
    try:
        standard(world)
        with pytest.raises(ScheduleError, match=r"system 'drag' writes Velocity between the movement stage and "
                                                r"the commit.*before='movement'.*after='commit'"):
            world.add_system(Drag(1.0), after="movement", before="collision")
        # refused whichever is added first: here the drag is there before the movement system
        other = World(dt=DT)
        try:
            other.add_system(Drag(1.0), before="collision", name="drag")
            with pytest.raises(ScheduleError, match="system 'drag' writes Velocity"):
                other.add_system(MovementSystem())
        finally:
            other.close()
    finally:
        world.close()


@pytest.mark.parametrize("well", [False, True])
@pytest.mark.parametrize("where", [dict(before="movement"), dict(after="movement", before="collision"),
                                   dict(after="collision", before="commit"), dict(after="commit")])
def test_a_system_placed_anywhere_sees_every_body_in_one_state(where, well):
    """A free body and a collider (the movement and collision systems' own), or with a well all three on
    rails (the gravity system's): the start of the step for every one of them before the commit, the end
    for every one after it."""
    world = World(dt=DT)
    try:
        standard(world)
        world.add_system(GravitySystem())
        if well:
            world.create_entity(Transform((0, 0, -1e7)), GravityWell(mu=3.986e14, radius=6.4e6))
        plain, coll = two_bodies(world, v=3.0)
        third = world.create_entity(Transform((7e6, 0, -1e7)), Velocity((0, 7.5e3, 0)))
        ents = [plain, coll, third]
        spy = world.add_system(Snapshot(ents), **where)
        world.step(2)
        start = world.columns(Transform, ents).position     # the start of step 3
        world.step()
        end = world.columns(Transform, ents).position
        assert not (start == end).all(axis=1).any()         # every body moved
        assert np.array_equal(spy.seen[2][0], end if where.get("after") == "commit" else start)
    finally:
        world.close()


def test_a_collision_system_alone_still_moves_its_colliders():
    world = World(dt=0.5)
    try:
        world.add_system(CollisionSystem())
        a = world.create_entity(Transform((-2.0, 0, 0)), Velocity((1.0, 0, 0)), SphereCollider(radius=0.5))
        b = world.create_entity(Transform((2.0, 0, 0)), Velocity((-1.0, 0, 0)), SphereCollider(radius=0.5))
        world.step(4)                                   # they meet at t = 1.5 s and swap velocities
        v = world.columns(Velocity, [a, b]).linear[:, 0]
        assert v.tolist() == [-1.0, 1.0]
        assert world.columns(Transform, [a, b]).position[:, 0].tolist() == [-1.0, 1.0]   # met at -0.5, 0.5
    finally:
        world.close()


def test_a_body_spawned_mid_step_in_a_freed_row_keeps_its_values():
    """A system between movement and commit deletes a body and spawns another, which takes the freed
    rows: the commit writes the bodies it predicted, never the newcomer's rows."""
    world = World(dt=1.0)
    try:
        world.add_system(MovementSystem())
        doomed = world.create_entity(Transform((0, 0, 0)), Velocity((1.0, 0, 0)))
        keep = world.create_entity(Transform((10.0, 0, 0)), Velocity((0, 1.0, 0)))
        born = []

        class Swap(esper.Processor):
            reads = ()
            writes = (Transform,)

            def process(self, dt):
                if not born:
                    self.world.delete_entity(doomed)
                    born.append(self.world.create_entity(Transform((-5.0, 0, 0)), Velocity((0, 0, 2.0))))
        world.add_system(Swap(), after="movement", before="commit")
        world.step()
        assert world.columns(Transform, [keep]).position[0].tolist() == [10.0, 1.0, 0.0]
        assert world.columns(Transform, [born[0]]).position[0].tolist() == [-5.0, 0.0, 0.0]   # moves next step
        world.step()
        assert world.columns(Transform, [born[0]]).position[0].tolist() == [-5.0, 0.0, 2.0]
    finally:
        world.close()


def test_advance_is_the_exact_constant_acceleration_update():
    x0, v0, a = np.array([[1.0, 2.0, 3.0]]), np.array([[0.5, -1.0, 0.0]]), np.array([[0.0, 2.0, -4.0]])
    x1, v1 = advance(x0, v0, a, 0.5)
    assert x1.tolist() == [[1.25, 1.75, 2.5]]         # x0 + v0 t + a t^2 / 2
    assert v1.tolist() == [[0.5, 0.0, -2.0]]          # v0 + a t
    x1, v1 = advance(x0, v0, None, 2.0)
    assert x1.tolist() == [[2.0, 0.0, 3.0]] and v1 is v0


def test_thrust_and_a_collider_share_the_one_update():
    """A thrusting collider no contact touches ends exactly where a thrusting plain body does."""
    world = World(dt=0.1)
    try:
        standard(world)
        plain = world.create_entity(Transform((0, 0, 0)), Velocity((1.0, 0, 0)), Acceleration((0.5, 0, 0)))
        coll = world.create_entity(Transform((0, 90, 0)), Velocity((1.0, 0, 0)), Acceleration((0.5, 0, 0)),
                                   SphereCollider(radius=1.0), Mass(2.0))
        world.step(7)
        p = world.columns(Transform, [plain, coll]).position
        assert p[0, 0] == p[1, 0]
        v = world.columns(Velocity, [plain, coll]).linear[:, 0]
        assert v[0] == v[1] == pytest.approx(1.35, rel=1e-15)
    finally:
        world.close()
