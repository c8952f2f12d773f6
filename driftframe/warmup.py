"""``driftframe warm``: the calls that reach every kernel, for :func:`framework.kernels.warm`.

Here, in the application shell, because they build the demo scenes; the cache, the lock and the
progress are in :mod:`driftframe.framework.kernels`.
"""
from __future__ import annotations

from driftframe.framework import kernels


def _demos(names) -> None:
    """Two steps of each demo (the second checks the neighbour list), and a third on the collision solver's
    variant with the jam path where a demo has one."""
    from driftframe.app import make_world

    for name in names:
        world, _ = make_world(name)
        try:
            world.step()
            world.step()
            jam_path = [s for stage in world.systems.values() for s in stage if getattr(s, "_stick", None) is False]
            for system in jam_path:      # the collision solver's variant with the jam path, taken after a jam
                system._stick = True
            if jam_path:
                world.step()
        finally:
            world.close()


def _collision_world(stick: bool, fill) -> None:
    """One step of a world with movement and collision, ``fill(world)`` making its entities; ``stick``: the
    solver's variant with the jam path."""
    from driftframe.framework.world import World
    from driftframe.systems.collision import CollisionSystem
    from driftframe.systems.movement import MovementSystem

    world = World(dt=1.0 / 60.0)
    try:
        world.add_system(MovementSystem())
        world.add_system(CollisionSystem())._stick = stick
        fill(world)
        world.step()
    finally:
        world.close()


def _row(world) -> None:
    """A row of 40 balls (more than the all-pairs path takes) in touch and closing: a first step that is not
    quiet, on the neighbour list."""
    import numpy as np

    from driftframe.components.body import Transform, Velocity
    from driftframe.components.collision import SphereCollider
    row = np.zeros((40, 3))
    row[:, 0] = np.arange(40.0)
    world.create_entities(Transform.bulk(40, position=row),
                          Velocity.bulk(40, linear=np.where(np.arange(40)[:, None] % 2, -1.0, 1.0) * [1, 0, 0]),
                          SphereCollider.bulk(40, radius=np.full(40, 0.5)))


def _shapes(world) -> None:
    """A ball against a plane and a box (the static-shape solvers; billiards' cushions reach them too)."""
    from driftframe.components.body import Transform, Velocity
    from driftframe.components.collision import BoxCollider, PlaneCollider, SphereCollider
    world.create_entity(Transform((0.0, -0.5, 0.0)), PlaneCollider(normal=(0.0, 1.0, 0.0)))
    world.create_entity(Transform((1.0, 0.0, 0.0)), BoxCollider(half_extents=(0.5, 0.5, 0.5)))
    world.create_entity(Transform((0.0, 0.0, 0.0)), Velocity((1.0, -1.0, 0.0)), SphereCollider(0.5))


def _rails(r, v) -> None:
    """Bodies on rails about one well, enough of them for the gravity system's compiled quiet step
    (``Epoch.step_from``): three steps (the first takes the epochs, the next are quiet)."""
    from driftframe.components.body import Transform, Velocity
    from driftframe.components.gravity import GravityWell
    from driftframe.framework.world import World
    from driftframe.systems.gravity import GravitySystem
    from driftframe.systems.movement import MovementSystem

    world = World(dt=0.01)
    try:
        world.add_system(MovementSystem())
        world.add_system(GravitySystem())
        world.create_entity(Transform(), GravityWell(mu=1.0, radius=0.1))
        world.create_entities(Transform.bulk(len(r), position=2.0 * r), Velocity.bulk(len(v), linear=0.7 * v))
        world.step(3)
    finally:
        world.close()


def claimed(part):
    """``part``, run only when this process claims it (:func:`framework.kernels.claim`): during a warm-up on
    two cores the helper runs the parts after the first in order and the first process, done with its own,
    takes them from the far end, so that neither waits while the other compiles and no part runs in both."""
    import functools

    @functools.wraps(part)
    def run() -> None:
        if kernels.claim(part.__name__):
            part()
    return run


def static_scenes() -> None:
    """The static-shape solvers and the pieces every solver shares (compiled first, here, so that the
    other parts load them): billiards and the cradle, a ball against a plane and a box."""
    _demos(("billiards", "cradle"))
    for stick in (False, True):
        _collision_world(stick, _shapes)


@claimed
def listed_scenes() -> None:
    """The neighbour list (its grid and sweep) and its solver with the jam path: the asteroids and the swarm."""
    _demos(("asteroids", "swarm"))


@claimed
def listed_rows() -> None:
    """The neighbour list's solver without the jam path, and with it: a row of balls in touch."""
    for stick in (False, True):
        _collision_world(stick, _row)


@claimed
def all_pairs() -> None:
    """The all-pairs solvers called directly (a demo's first steps may all be quiet, which
    framework/quiet_step.py answers without the solver), without and with the jam path."""
    import numpy as np

    from driftframe.framework import contact
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])          # two unit balls touching, closing at 2 m/s
    u = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    pi, pj = contact.all_pairs(2)
    for stick in (False, True):
        contact.solve_step(contact.StepInputs(x.copy(), u.copy(), np.full(2, 0.5), np.ones(2), np.ones(2),
                                              np.ones(2, np.bool_), np.full(2, -np.inf), 0.0, pi, pj, 1.0 / 60.0,
                                              contact.TC / 60.0, contact.CAP, None), stick=stick)


@claimed
def orbits_and_the_rest() -> None:
    """Everything else: Kepler propagation of a few bodies and of enough for the compiled loops (on rails in
    a world too), the n-body kernels, one frame through the NV12 converter, the other demos (last: by then
    the first process has saved the movement kernels they share with it)."""
    import numpy as np

    from driftframe.framework import kepler
    from driftframe.framework.yuv import rgba_to_nv12
    n = kepler.COMPILED_MIN
    angle = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    r = np.stack([np.cos(angle), np.sin(angle), np.zeros(n)], axis=1)     # circular orbits, radius 1, mu 1
    v = np.stack([-np.sin(angle), np.cos(angle), np.zeros(n)], axis=1)
    r1, v1, chi = kepler.Epoch(r, v, 1.0).at(0.1, chi=np.full(n, 0.1))
    kepler.next_chi(chi, r1, v1, 1.0, 0.1)
    kepler.Epoch(r[:3], v[:3], 1.0).at(0.1, chi=np.full(3, 0.1))      # a few bodies: kepler_small's kernels
    kepler.next_chi(chi[:3], r1[:3], v1[:3], 1.0, 0.1, origin=(np.zeros(3), np.zeros(3)))
    _rails(r, v)
    from driftframe.framework import wisdom_holman as wh      # the n-body kernels: every coordinate path, a corrector
    for coordinates, corrector in (("jacobi", 3), ("democratic", 0), ("fixed", 0)):
        wh.wisdom_holman(r[:3].copy(), v[:3].copy(), np.array([1.0, 1e-3, 1e-3]), 0.01, 2,
                         coordinates=coordinates, corrector=corrector)
    wh.leapfrog(r[:3].copy(), v[:3].copy(), np.ones(3), 0.01, 2)
    from driftframe.framework import mercurius       # the hybrid step, with a pair close enough to switch
    mercurius.mercurius(np.array([[0.0, 0, 0], [1, 0, 0], [1.01, 0, 0]]),
                        np.array([[0.0, 0, 0], [0, 1, 0], [0, 1.05, 0]]), np.array([1.0, 1e-3, 1e-3]), 0.01, 2)
    mercurius.near_pairs(r[:3].copy(), np.ones(3))   # (the gravity system's n-body switch)
    wh.kepler_drift(r[:2].copy(), v[:2].copy(), 1.0, 0.1)
    rgba_to_nv12(np.zeros((4, 4, 4), np.uint8), 4, 4)
    _demos(("rotation", "spin", "orbit"))


#: The warm-up in parts (:func:`framework.kernels.warm`): on two cores the first runs here while a helper
#: process runs the others in order, and this process then takes those from the far end (each part runs
#: in one of the two: :func:`claimed`). The order follows the parts' compile times on an empty cache
#: (docs/bench/compile.md, "Fourth pass"), so that the two processes end together and a part that calls the
#: solver pieces the first one compiles starts after it has saved them. Together they reach every kernel.
PARTS = (static_scenes, orbits_and_the_rest, all_pairs, listed_rows, listed_scenes)


def workload() -> None:
    """Calls that reach every kernel: each of :data:`PARTS` in turn."""
    for part in PARTS:
        part()


def warm(watch=None) -> list:
    """Compile or load every kernel (:func:`framework.kernels.warm` with :data:`PARTS`)."""
    return kernels.warm(PARTS, watch)


def warm_once() -> None:
    """:func:`warm` unless the cache folder is warm already (:func:`framework.kernels.warm_once`)."""
    kernels.warm_once(PARTS)
