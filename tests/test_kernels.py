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
    assert "driftframe.framework.contact.solve_step" in called
    for name, k in called.items():
        options = {o: v for o, v in k.targetoptions.items() if o not in ("cache", "nopython")}   # njit's own
        copy = numba.njit(cache=False, **options)(k.py_func)
        for sig in list(k.signatures):
            copy.compile(sig)
    assert _literal_signatures(dict(_kernels())) == {}
