"""The compiled kernels: each is compiled once for the types the framework passes it.

numba types a constant that one kernel passes to another (``f(0)``, ``f(False)``,
or ``k = 0`` and then ``f(k)``) as a literal, Literal[int](0), and compiles the
callee for it besides the plain int64 it compiles later: on a machine's first
run each such call costs a second compile (solve_step's took about 15 s).

Typing a kernel resolves every kernel it calls, and a literal argument shows
among that callee's signatures. A kernel compiled in this process was typed;
one loaded from numba's cache was not, and does not say what it calls. So the
test types (numba's front end and type inference, no code generation) a fresh
copy of each kernel the cache gave, for the same argument types, until no
newly loaded kernel is left: every level is checked, cold cache or warm. The
scenes run every solver path (all pairs, the grid with swept bodies, cradle
contacts, gravity).
"""
import importlib
import os
import subprocess
import sys

import numba
from numba.core import types
from numba.core.compiler import CompilerBase, DefaultPassBuilder
from numba.core.compiler_machinery import FunctionPass, register_pass
from numba.core.typed_passes import NopythonTypeInference

from driftframe.app import make_world


class _Typed(Exception):
    """Raised by the pass after type inference: the copy was typed, and nothing more is needed of it."""


@register_pass(mutates_CFG=False, analysis_only=True)
class _StopAfterTyping(FunctionPass):
    _name = "driftframe_stop_after_typing"

    def __init__(self):
        FunctionPass.__init__(self)

    def run_pass(self, state):
        raise _Typed


class _TypeOnly(CompilerBase):
    """numba's nopython pipeline up to and including type inference (lowering and LLVM are most of a compile)."""

    def define_pipelines(self):
        pm = DefaultPassBuilder.define_nopython_pipeline(self.state)
        pm.add_pass_after(_StopAfterTyping, NopythonTypeInference)
        pm.finalize()
        return [pm]


def _kernels():
    """Each kernel once (a module that imports another's kernel names the same dispatcher), by its own name."""
    seen = set()
    for mod in list(sys.modules.values()):
        if getattr(mod, "__name__", "").startswith("driftframe"):
            for obj in list(vars(mod).values()):
                if isinstance(obj, numba.core.registry.CPUDispatcher) and id(obj) not in seen:
                    seen.add(id(obj))
                    yield f"{obj.py_func.__module__}.{obj.py_func.__name__}", obj


def _calls_a_kernel(k) -> bool:
    """Only a kernel that calls another can pass it a literal: one naming no kernel in its code (and with no
    closure, where a kernel could hide) is a leaf, and typing its copy would find nothing."""
    f = k.py_func
    if f.__code__.co_freevars:
        return True
    names, codes = set(), [f.__code__]
    while codes:                                   # the function's names and those of the code nested in it
        code = codes.pop()
        names.update(code.co_names)
        codes.extend(c for c in code.co_consts if isinstance(c, type(code)))
    values = [f.__globals__.get(n) for n in names]
    values += [getattr(v, n, None) for v in values if isinstance(v, type(sys)) for n in names]   # mod.f(...)
    return any(isinstance(v, numba.core.registry.CPUDispatcher) and v is not k for v in values)


def _literal_signatures(kernels):
    return {name: sorted({str(a) for sig in k.signatures for a in sig if isinstance(a, types.Literal)})
            for name, k in kernels.items() if any(isinstance(a, types.Literal) for sig in k.signatures for a in sig)}


def _type_cached_signatures(kernels, done):
    """Type an uncached copy of each kernel for each signature the cache gave it and not yet in ``done``."""
    todo = [(name, k, sig) for name, k in kernels.items() if _calls_a_kernel(k)
            for sig in k.stats.cache_hits if (name, sig) not in done]
    for name, k, sig in todo:
        options = {o: v for o, v in k.targetoptions.items() if o not in ("cache", "nopython")}   # njit's own
        copy = numba.njit(cache=False, pipeline_class=_TypeOnly, **options)(k.py_func)
        try:
            copy.compile(sig)
        except _Typed:
            done.add((name, sig))
        else:
            raise AssertionError(f"{name}{sig}: the copy was compiled, not stopped after typing")
    return len(todo)


def test_no_kernel_is_compiled_for_a_literal_argument():
    # in a process of its own: the check types a copy of every kernel the process loaded from the cache, so in
    # a test worker it would also type whatever the tests run before it happened to load (10 s alone, 33-70 s
    # inside the suite, a different set each run); here it checks exactly what the five scenes reach
    res = subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {os.path.dirname(__file__)!r}); "
                          "import test_kernels; test_kernels.check_no_literal_argument()"],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-4000:]


def check_no_literal_argument():
    """The check of the test above, in the calling process."""
    for demo in ("billiards", "asteroids", "cradle", "orbit", "swarm"):
        world, _ = make_world(demo, seed=1)
        for _ in range(120):
            world.step()
    called = {name: k for name, k in _kernels() if k.signatures}
    assert "driftframe.framework.contact_solve.solve_all_pairs" in called     # the scenes reached both solver paths
    assert "driftframe.framework.contact_solve.solve_listed" in called
    done = set()
    while _type_cached_signatures(dict(_kernels()), done):    # typing a copy may load more kernels from the cache
        pass
    assert _literal_signatures(dict(_kernels())) == {}


def test_the_typing_copy_finds_a_literal_in_a_callee_loaded_from_the_cache(tmp_path, monkeypatch):
    """The check itself: a caller loaded from the cache, typed again, shows the literal it passes its callee."""
    cache = str(tmp_path / "cache")
    monkeypatch.setattr(numba.config, "CACHE_DIR", cache)     # numba read NUMBA_CACHE_DIR at import: this one's
    src = tmp_path / "literal_pair.py"
    src.write_text("import numba\n\n"
                   "@numba.njit(cache=True)\n"
                   "def callee(k):\n    return k + 1\n\n"
                   "@numba.njit(cache=True)\n"
                   "def caller(x):\n    return callee(0) + x\n")
    # compile and cache both in another process, so that this one loads the caller from the cache
    subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {str(tmp_path)!r}); "
                    "import literal_pair; literal_pair.caller(1)"], check=True,
                   env={**os.environ, "NUMBA_CACHE_DIR": cache})
    monkeypatch.syspath_prepend(str(tmp_path))
    mod = importlib.import_module("literal_pair")
    monkeypatch.setitem(sys.modules, "literal_pair", mod)      # (so that the undo removes it after the test)
    assert mod.caller(1) == 2
    assert dict(mod.caller.stats.cache_hits) and not mod.callee.signatures   # loaded: the callee never typed
    kernels = {"caller": mod.caller, "callee": mod.callee}
    assert _type_cached_signatures(kernels, set()) == 1
    assert _literal_signatures(kernels) == {"callee": ["Literal[int](0)"]}


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


def _struck_crystal(side, stick_from_start):
    """A touching simple cubic crystal of side**3 unit spheres squeezed towards its centre (and a random
    jitter): one step, whose first wave is one island of every touching pair (more than DENSE_MAX)."""
    import numpy as np

    from driftframe.components.body import Transform, Velocity
    from driftframe.components.collision import SphereCollider
    from driftframe.framework.world import World
    from driftframe.systems.collision import CollisionSystem

    g = np.stack(np.meshgrid(*[np.arange(float(side))] * 3, indexing="ij"), -1).reshape(-1, 3)
    v = (g.mean(axis=0) - g) + np.random.default_rng(4).uniform(-0.1, 0.1, g.shape)
    with World() as w:
        cs = w.add_system(CollisionSystem())
        ids = w.create_entities(Transform.bulk(len(g), position=g), Velocity.bulk(len(g), linear=v),
                                SphereCollider.bulk(len(g), radius=np.full(len(g), 0.5)))
        cs._stick = stick_from_start
        w.step()
        return (w.columns(Transform, ids).position.tobytes(), w.columns(Velocity, ids).linear.tobytes(),
                cs._stick, cs.stats["sequential"])


def test_a_step_with_an_island_past_dense_max_is_run_again_with_the_stick_variant_and_gives_the_same_bits():
    # the plain solvers leave the big islands' solve (island_sequential) to the _stick variants, as they do
    # the jam path: F_AGAIN, the inputs as they came, the step run again
    from driftframe.framework.contact import DENSE_MAX
    for side in (3, 6):                                    # every pair (27 bodies, 54 contacts); the list
        pos, vel, switched, sequential = _struck_crystal(side, False)
        assert switched and sequential > 0 and 3 * side * side * (side - 1) > DENSE_MAX
        assert (pos, vel, True, sequential) == _struck_crystal(side, True)


def through(k):
    """Kernel ``k`` (no CPython wrapper: only kernels call it) called from Python through a compiled caller."""
    import numba
    return numba.njit(lambda *args: k(*args))


def test_argsort_stable_argsort_spread_and_median_match_numpy():
    import numpy as np

    from driftframe.framework import sorting
    argsort_stable, argsort_spread, median = (through(k) for k in (sorting.argsort_stable, sorting.argsort_spread,
                                                                   sorting.median))

    rng = np.random.default_rng(3)
    for n in (0, 1, 2, 15, 16, 17, 33, 100, 1000):
        for a in (rng.integers(0, 7, n).astype(np.int64), rng.random(n), np.round(rng.random(n), 1)):
            for m in sorted({0, n // 2, n}):
                assert np.array_equal(argsort_stable(a, m), np.argsort(a[:m], kind="stable"))
            if n and a.dtype == np.float64 and not np.isnan(a).any():
                assert median(a) == np.median(a)
    a = np.array([3.0, np.nan, 1.0, 2.0, np.nan, 0.5])
    assert np.array_equal(argsort_stable(a, 6), np.argsort(a, kind="stable"))
    # the bucket sort: the same order, spread or bunched (its merge-sort fallback), ties, -0.0, inf, NaN
    bunched = np.concatenate([rng.random(2000) * 1e-9, [1e9]])
    for a in (rng.random(3000), np.round(rng.random(3000), 2), bunched, np.array([0.0, -0.0, 1.0, -0.0]),
              np.array([1.0, np.inf, 0.0, -np.inf]), np.array([3.0, np.nan, 1.0]), np.full(5, 2.0), np.ones(1)):
        for m in sorted({0, 1, len(a) // 2, len(a)}):
            assert np.array_equal(argsort_spread(a, m), np.argsort(a[:m], kind="stable"))
    # the fallback's int64 keys order floats as the float comparisons do: signs, zeros, subnormals, NaNs
    order_keys = through(sorting.order_keys)
    tiny = np.nextafter(0.0, 1.0)
    odd = np.array([-0.0, 0.0, tiny, -tiny, -1.0, -2.0, 1.0, 2.0, -np.inf, np.inf, np.nan, -np.nan, 0.0, -0.0,
                    -1e308, 1e308, -1.5, 1.5, -2.0, np.nan])
    for a in (odd, rng.permutation(odd), rng.normal(size=500) * 10.0 ** rng.integers(-300, 300, 500),
              np.round(rng.normal(size=500), 1)):
        assert np.array_equal(argsort_stable(order_keys(a, len(a)), len(a)), np.argsort(a, kind="stable"))
