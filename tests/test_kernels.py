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
    for mod in list(sys.modules.values()):
        if getattr(mod, "__name__", "").startswith("driftframe"):
            for name, obj in list(vars(mod).items()):
                if isinstance(obj, numba.core.registry.CPUDispatcher):
                    yield f"{mod.__name__}.{name}", obj


def _literal_signatures(kernels):
    return {name: sorted({str(a) for sig in k.signatures for a in sig if isinstance(a, types.Literal)})
            for name, k in kernels.items() if any(isinstance(a, types.Literal) for sig in k.signatures for a in sig)}


def _type_cached_signatures(kernels, done):
    """Type an uncached copy of each kernel for each signature the cache gave it and not yet in ``done``."""
    todo = [(name, k, sig) for name, k in kernels.items() for sig in k.stats.cache_hits if (name, sig) not in done]
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
    for demo in ("billiards", "asteroids", "cradle", "orbit", "swarm"):
        world, _ = make_world(demo, seed=1)
        for _ in range(120):
            world.step()
    called = {name: k for name, k in _kernels() if k.signatures}
    assert "driftframe.framework.contact.solve_all_pairs" in called     # the scenes reached both solver paths
    assert "driftframe.framework.contact.solve_listed" in called
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
