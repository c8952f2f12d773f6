"""The compiled kernels: each is compiled once for the types the framework passes it.

numba types a constant that one kernel passes to another (``f(0)``, ``f(False)``,
or ``k = 0`` and then ``f(k)``) as a literal, Literal[int](0), and compiles the
callee for it besides the plain int64 it compiles later: on a machine's first
run each such call costs a second compile (solve_step's took about 15 s).

A kernel loaded from numba's cache does not say what it calls, so the test
compiles a fresh, uncached copy of each kernel the scenes called from Python,
for the same argument types: typing the copy makes every kernel it calls
resolve its arguments again, and a literal one shows among that callee's
signatures. Where the cache is cold (a fresh clone, CI) every level is
compiled and checked; with a warm one, the kernels called from Python and
those they call. The scenes run every solver path (all pairs, the grid with
swept bodies, cradle contacts, gravity).
"""
import sys

import numba
from numba.core import types

from driftframe.app import make_world


def _kernels():
    for mod in list(sys.modules.values()):
        if getattr(mod, "__name__", "").startswith("driftframe"):
            for name, obj in list(vars(mod).items()):
                if isinstance(obj, numba.core.registry.CPUDispatcher):
                    yield f"{mod.__name__}.{name}", obj


def _literal_signatures(kernels):
    return {name: sorted({str(a) for sig in k.signatures for a in sig if isinstance(a, types.Literal)})
            for name, k in kernels.items() if any(isinstance(a, types.Literal) for sig in k.signatures for a in sig)}


def test_no_kernel_is_compiled_for_a_literal_argument():
    for demo in ("billiards", "asteroids", "cradle", "orbit", "swarm"):
        world, _ = make_world(demo, seed=1)
        for _ in range(120):
            world.step()
    kernels = dict(_kernels())
    called = {name: k for name, k in kernels.items() if k.signatures}
    assert "driftframe.framework.contact.solve_all_pairs" in called     # the scenes reached both solver paths
    assert "driftframe.framework.contact.solve_listed" in called
    for name, k in called.items():
        options = {o: v for o, v in k.targetoptions.items() if o not in ("cache", "nopython")}   # njit's own
        copy = numba.njit(cache=False, **options)(k.py_func)
        for sig in list(k.signatures):
            copy.compile(sig)
    assert _literal_signatures(dict(_kernels())) == {}


def _clump(n, stick_from_start, steps=12):
    """Inelastic spheres converging at 5 m/s, at most one bouncing contact per body per step: their
    clusters stick (the jam path) within a few steps."""
    import warnings

    import numpy as np

    from driftframe.components.body import Mass, Transform, Velocity
    from driftframe.components.collision import SphereCollider
    from driftframe.framework import placement
    from driftframe.framework.world import World
    from driftframe.systems.collision import CollisionSystem

    rng = np.random.default_rng(6)
    r = np.full(n, 0.5)
    x = placement.place(rng, r, placement.in_shell(0.0, (n * 1.1 ** 3) ** (1 / 3)), gap=0.02)
    v = -5.0 * x / np.linalg.norm(x, axis=1, keepdims=True)
    with World() as w, warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        cs = w.add_system(CollisionSystem(max_contacts=1))
        ids = w.create_entities(Transform.bulk(n, position=x), Velocity.bulk(n, linear=v), Mass.bulk(n, kg=np.ones(n)),
                                SphereCollider.bulk(n, radius=r, restitution=np.zeros(n)))
        cs._stick = stick_from_start
        switched = None
        for k in range(steps):
            w.step()
            if switched is None and cs._stick:
                switched = k
        pos, vel = w.columns(Transform, ids).position.copy(), w.columns(Velocity, ids).linear.copy()
    return pos, vel, switched, any("centre-of-mass velocity" in str(m.message) for m in rec)


def test_a_step_that_needs_the_jam_path_is_run_again_with_it_and_gives_the_same_bits():
    # solve_all_pairs / solve_listed have no jam path (_stick): a step that needs it ends with F_AGAIN and
    # its inputs as they came, and is run again by the _stick variant; from then on the system uses that
    for n in (24, 120):                                    # every pair; the neighbour list
        pos, vel, switched, stuck = _clump(n, False)
        assert stuck and switched is not None and switched > 0
        pos2, vel2, _, stuck2 = _clump(n, True)
        assert stuck2
        assert pos.tobytes() == pos2.tobytes() and vel.tobytes() == vel2.tobytes()


def test_argsort_stable_and_median_match_numpy():
    import numpy as np

    from driftframe.framework import broadphase as bp

    rng = np.random.default_rng(3)
    for n in (0, 1, 2, 15, 16, 17, 33, 100, 1000):
        for a in (rng.integers(0, 7, n).astype(np.int64), rng.random(n), np.round(rng.random(n), 1)):
            for m in sorted({0, n // 2, n}):
                assert np.array_equal(bp.argsort_stable(a, m), np.argsort(a[:m], kind="stable"))
            if n and a.dtype == np.float64:
                assert bp.median(a) == np.median(a)
    a = np.array([3.0, np.nan, 1.0, 2.0, np.nan, 0.5])
    assert np.array_equal(bp.argsort_stable(a, 6), np.argsort(a, kind="stable"))
