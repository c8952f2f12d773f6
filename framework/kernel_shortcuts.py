"""A cold compile made cheaper in five ways that leave the code numba generates unchanged.

A cold compile is mostly numba's own Python. A sampling profile of billiards' cold compile (numba 0.68.1;
the shares are in docs/bench/compile.md, "Fourth pass") found:

- **Python's cyclic garbage collector**: a compile allocates millions of small objects (numba IR, types,
  llvmlite instructions), so the collector runs over and over, and each full collection walks every
  object alive, to free almost nothing. It is paused while one of driftframe's kernels compiles (numba's ``numba:compile`` events, the
  outermost compile of one of ours: the callees and numba's own overloads it compiles are inside it) and
  resumed after, as it was.

and three places where numba's Python does work whose result is thrown away or recomputed, each replaced
here by a function that returns exactly what numba's returns:

- **Liveness** (``numba.core.analysis.compute_live_map``). numba runs it after most of
  its passes (``PostProcessor``). Its first fix-point (``def_reach``) collects, for every block, every
  variable defined or used in any block that can reach it, and then only ever intersects those sets with
  the live variables, which are all in some block's *use* set. Most of a kernel's variables are
  temporaries local to one block (``$binop_add.5``), so the sets it carried were mostly names that can
  never be live. Here ``def_reach`` keeps only the variables some block uses before defining; restricted
  and unrestricted fix-points agree on those (both are the least fix-point of the same monotone union
  equations, and restricting to a set commutes with union and intersection), so the live map returned is
  the same.
- **ABI sizes** (``BaseContext.get_abi_sizeof``). llvmlite answers it by printing a module with one
  global of the type and parsing it with LLVM, every time; numba asks it for every user variable it
  allocates (for debug info it then discards unless ``debug=True``). Remembered per data layout and type
  text, for types that name no identified (named) struct, whose text alone would not say what they are.
- **Error-message markup** (``HighlightColorScheme._markup``): typing tries templates that fail, and
  every failure builds a highlighted message (``NumbaError``, ``Loc.strformat``) that is then thrown away.
  When colorama is installed numba wraps and unwraps ``sys.stdout``/``sys.stderr`` for each piece of text
  it highlights (``ColorShell``); the text it makes is the colour codes, the message, and a reset code,
  made here directly. The same text, including for the user's errors.

In LLVM's part:

- **One function pass manager a module** (``CPUCodeLibrary._optimize_functions``): numba built a new pass
  builder and function pass manager (LLVM's analysis managers registered anew) for each function of each
  module it adds; one pair serves the module's functions here. LLVM keeps analyses per function and drops
  them as a pass changes the function, so each function is optimised as before.

``DRIFTFRAME_COMPILE_SHORTCUTS=0`` leaves numba as it is; so does a numba whose internals differ from those
this was written for (each piece checks what it replaces first). tests/test_kernel_shortcuts.py compares
the optimised LLVM IR of kernels compiled with and without.
"""
from __future__ import annotations

import os

_installed: list = []           # names of the pieces installed (what the tests look at)


def install(ours) -> list:
    """Install every piece that fits this numba (once per process); returns the names of those installed.
    ``ours(dispatcher)``: whether a dispatcher is one of driftframe's kernels (the collector pauses for those)."""
    if _installed or os.environ.get("DRIFTFRAME_COMPILE_SHORTCUTS", "1") == "0":
        return list(_installed)
    pieces = (("gc_paused", lambda: _gc_paused(ours)), ("liveness", _liveness), ("abi_size", _abi_size),
              ("markup", _markup), ("one_function_pass_manager", _one_function_pass_manager))
    for name, piece in pieces:
        try:
            if piece():
                _installed.append(name)
        except (ImportError, AttributeError, TypeError, ValueError):
            pass
    return list(_installed)


def _gc_paused(ours) -> bool:
    import gc
    import threading

    from numba.core import event
    lock = threading.Lock()
    state = {"depth": 0, "resume": False}      # depth: compiles open inside an outermost one of ours

    class Pause(event.Listener):
        def on_start(self, ev):
            with lock:
                if state["depth"] == 0:
                    if not ours(ev.data["dispatcher"]):
                        return
                    state["resume"] = gc.isenabled()
                    gc.disable()
                state["depth"] += 1

        def on_end(self, ev):
            with lock:
                if state["depth"] == 0:
                    return
                state["depth"] -= 1
                if state["depth"] == 0 and state["resume"]:
                    gc.enable()

    event.register("numba:compile", Pause())
    return True


def _liveness() -> bool:
    import inspect
    from collections import defaultdict

    from numba.core import analysis
    original = analysis.compute_live_map
    if list(inspect.signature(original).parameters) != ["cfg", "blocks", "var_use_map", "var_def_map"]:
        return False

    def compute_live_map(cfg, blocks, var_use_map, var_def_map):
        """numba's ``compute_live_map`` (same order of work, same result) with ``def_reach`` restricted to the
        variables that can be live: those some block uses before defining (the live sets start as the use
        sets and only ever take in other blocks' live variables)."""
        topo_order = cfg.topo_order()

        def fix_point(fn, dct):
            old_point, new_point = None, tuple(len(v) for v in dct.values())
            while old_point != new_point:
                fn(dct)
                old_point, new_point = new_point, tuple(len(v) for v in dct.values())

        can_live = set().union(*var_use_map.values())
        seeds = {offset: (var_def_map[offset] | var_use_map[offset]) & can_live for offset in topo_order}

        def def_reach(dct):
            for offset in topo_order:
                dct[offset] |= seeds[offset]
                for out_blk, _ in cfg.successors(offset):
                    dct[out_blk] |= dct[offset]

        def liveness(dct):
            for offset in reversed(topo_order):
                live_vars = dct[offset]
                for inc_blk, _data in cfg.predecessors(offset):
                    reachable = live_vars & def_reach_map[inc_blk]
                    dct[inc_blk] |= reachable - var_def_map[inc_blk]

        live_map = {offset: set(var_use_map[offset]) for offset in blocks.keys()}
        def_reach_map = defaultdict(set)
        fix_point(def_reach, def_reach_map)
        fix_point(liveness, live_map)
        return live_map

    compute_live_map.__wrapped__ = original
    analysis.compute_live_map = compute_live_map
    return True


def _abi_size() -> bool:
    from numba.core import base
    original = base.BaseContext.get_abi_sizeof
    sizes: dict = {}
    layouts: dict = {}              # id(target data) -> (it, its layout text); held, so the id stays its own

    def get_abi_sizeof(self, ty):
        text = str(ty)
        if "%" in text:                 # an identified struct: its name alone does not say what it holds
            return original(self, ty)
        data = self.target_data
        known = layouts.get(id(data))
        if known is None or known[0] is not data:
            known = layouts[id(data)] = (data, str(data))
        key = (known[1], text)
        size = sizes.get(key)
        if size is None:
            size = sizes[key] = original(self, ty)
        return size

    get_abi_sizeof.__wrapped__ = original
    base.BaseContext.get_abi_sizeof = get_abi_sizeof
    return True


def _markup() -> bool:
    from numba.core import errors
    scheme = getattr(errors, "HighlightColorScheme", None)     # absent without colorama: nothing to do
    if scheme is None or not hasattr(errors, "ColorShell") or not hasattr(errors, "Style"):
        return False
    original = scheme._markup
    style_default = errors.Style.BRIGHT
    reset = errors.Style.RESET_ALL

    def _markup(self, msg, color=None, style=style_default):
        # numba: features (colour, style) then the message into a buffer, RESET_ALL appended on leaving,
        # encoded to UTF-8 and decoded again (which raises on a lone surrogate: kept)
        return ((color or "") + (style or "") + msg + reset).encode("utf-8").decode("utf-8")

    _markup.__wrapped__ = original
    scheme._markup = _markup
    return True


def _one_function_pass_manager() -> bool:
    import inspect

    from numba.core import codegen, config
    original = codegen.CPUCodeLibrary._optimize_functions
    if (list(inspect.signature(original).parameters) != ["self", "ll_module"]
            or not hasattr(codegen.CPUCodegen, "_function_pass_manager")):
        return False

    def _optimize_functions(self, ll_module):
        """numba's, with one pass builder and function pass manager for the module's functions instead of a new
        pair for each (LLVM's analyses are kept per function and dropped as each pass changes it)."""
        if config.LLVM_PASS_TIMINGS:           # numba records each function's passes apart: its own way
            return original(self, ll_module)
        ll_module.data_layout = self._codegen._data_layout
        fpm = pb = None
        for func in ll_module.functions:
            if fpm is None:
                fpm, pb = self._codegen._function_pass_manager()
            fpm.run(func, pb)

    _optimize_functions.__wrapped__ = original
    codegen.CPUCodeLibrary._optimize_functions = _optimize_functions
    return True
