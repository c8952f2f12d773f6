"""A cold compile made cheaper: six ways that leave the code numba generates unchanged, and one that makes a
callee's machine code only when something asks for it.

A cold compile is mostly numba's own Python. A sampling profile of billiards' cold compile (numba 0.68.1;
the shares are in docs/bench/compile.md, "Fourth pass") found:

- **Python's cyclic garbage collector**: a compile allocates millions of small objects (numba IR, types,
  llvmlite instructions), so the collector runs over and over, and each full collection walks every
  object alive, to free almost nothing. It is paused while one of driftframe's kernels compiles (numba's ``numba:compile`` events, the
  outermost compile of one of ours: the callees and numba's own overloads it compiles are inside it) and
  resumed after, as it was.

and four places where numba's Python does work whose result is thrown away or recomputed, each replaced
here by a function that returns exactly what numba's returns:

- **numba's own functions compiled once** (``_OverloadFunctionTemplate._get_impl``): numba compiles the
  implementation of ``np.empty``, ``min``, ... for a call's argument types and keeps it under the calling
  kernel's flags, all of them, so a kernel with a CPython wrapper and one without each compiled their own
  copy. The compile of the implementation inherits four of those flags (``CPUTargetOptions.finalize``: nrt,
  fastmath, error_model, forceinline), so it is looked up under those first: the asteroids demo's cold
  compile made 17 such compiles instead of 23 (docs/bench/compile.md, "Seventh pass").

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
- **Machine code on demand.** numba optimises each kernel's module, links into it the modules of the
  kernels it calls, and then turns the whole into machine code at once, callees included: a kernel called
  only by other kernels (no CPython or C wrapper: most of driftframe's) had machine code made that nothing
  ever runs, since each caller carries its own copy of the callee (numba links a callee into every caller;
  a caller loaded from the cache is one object, callees and all). Here, for the libraries of our compiles
  (numba's ``numba:compile`` events, as for the collector), the engine gets at once only the functions'
  environment globals (numba writes each environment's address there; a caller's copy reads the same
  global), and the code is made when something asks for the address of a function the library defines, or
  when it must be saved with its code (a cache other than driftframe's), or when a recursive call left a
  reference numba's runtime linker must resolve. driftframe's cache (:mod:`.kernel_cache`) saves such a
  library as the bitcode numba links into callers (:data:`LINK_ONLY`), which any later process reads, with or
  without the shortcuts. The one change in generated code: numba's code generation runs LLVM's
  code-generation passes (CodeGenPrepare, loop strength reduction, ...) on the module in place, so a callee
  whose code was made reached its callers already so transformed, and one whose code was not made reaches
  them as optimised, so the machine code of a caller of such callees (the solvers) differs, and the same
  physics comes out of it bit for bit (the golden hashes); docs/bench/compile.md, "Fifth pass", has the
  timings, the warm speed included.

``DRIFTFRAME_COMPILE_SHORTCUTS=0`` leaves numba as it is; so does a numba whose internals differ from those
this was written for (each piece checks what it replaces first). tests/test_kernel_shortcuts.py compares
the optimised LLVM IR of kernels compiled with and without all but the last, and checks the last's code
is made when asked for, runs as numba's, and loads from the cache either way.
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
              ("markup", _markup), ("one_function_pass_manager", _one_function_pass_manager),
              ("overload_once", _overload_once),
              ("code_on_demand", lambda: _code_on_demand(ours)))
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


def _overload_once() -> bool:
    import inspect

    from numba.core import targetconfig
    from numba.core.typing import templates
    cls = templates._OverloadFunctionTemplate
    original = cls._get_impl
    if list(inspect.signature(original).parameters) != ["self", "args", "kws"]:
        return False

    def _get_impl(self, args, kws):
        """numba's, looked up first under the caller's flags that the implementation's compile inherits (numba's
        ``CPUTargetOptions.finalize``: nrt, fastmath, error_model, forceinline) instead of all of them: a caller
        without a CPython wrapper and one with it get the one implementation numba compiled for the first."""
        flags = targetconfig.ConfigStack.top_or_none()
        if flags is None:
            return original(self, args, kws)
        key = (self.context, tuple(args), tuple(kws.items()), "inherited",
               (flags.nrt, tuple(sorted(getattr(flags.fastmath, "flags", ()))), flags.error_model, flags.forceinline))
        got = self._impl_cache.get(key)
        if got is not None:
            return got
        got = original(self, args, kws)
        if (self.context, tuple(args), tuple(kws.items()), flags) in self._impl_cache:     # (numba kept it)
            self._impl_cache[key] = got
        return got

    _get_impl.__wrapped__ = original
    cls._get_impl = _get_impl
    return True


#: The kind (numba's ``serialize_using_object_code`` names ``'object'`` and ``'bitcode'``) a kernel's library is
#: saved in when it has no machine code: the bitcode numba links into callers, as in ``'object'``, without the object.
LINK_ONLY = "driftframe-link-only"


def readable(libdata):
    """``libdata`` (a cached library, ``(name, kind, data)``) as this process's numba can read it: a
    :data:`LINK_ONLY` one as numba's ``'bitcode'`` (its code made at load) unless ``code_on_demand`` is installed."""
    if libdata[1] == LINK_ONLY and "code_on_demand" not in _installed:
        return (libdata[0], "bitcode", libdata[2])
    return libdata


def link_only_ok(library) -> None:
    """Let ``library`` (a compile's, about to be cached by driftframe's cache, which reads :data:`LINK_ONLY`)
    be saved without machine code when none was made."""
    if getattr(library, "_code_pending", None) is not None:
        library._link_only_ok = True


def _code_on_demand(ours) -> bool:
    import weakref

    import llvmlite.binding as ll
    from llvmlite import ir as llvmir
    from numba.core import cgutils, codegen, config, event
    from numba.core.compiler_lock import global_compiler_lock

    base = codegen.JITCodeLibrary
    linker = codegen.RuntimeLinker()
    if (codegen.JITCPUCodegen._library_class is not base or not hasattr(linker, "_unresolved")
            or not all(hasattr(base, name) for name in (
                "_finalize_dynamic_globals", "_verify_declare_only_symbols", "_finalize_specific",
                "_get_module_for_linking", "_unserialize", "_ensure_finalized"))
            or not hasattr(codegen.CPUCodegen, "_scan_and_fix_unresolved_refs")):
        return False
    local = (ll.Linkage.private, ll.Linkage.internal)
    pending = weakref.WeakSet()         # libraries whose code is not made yet
    depth = [0]                         # compiles open inside an outermost one of ours

    class Ours(event.Listener):
        def on_start(self, ev):
            if depth[0] or ours(ev.data["dispatcher"]):
                depth[0] += 1

        def on_end(self, ev):
            if depth[0]:
                depth[0] -= 1

    def env_module(library, module):
        """A module defining ``module``'s environment globals (common, null: numba's ``declare_env_global``),
        parsed; None when ``module`` defines another global that is not local to it."""
        names = []
        for gv in module.global_variables:
            if gv.is_declaration or gv.linkage in local:
                continue
            if gv.linkage != ll.Linkage.common or not gv.name.startswith("_ZN08NumbaEnv"):
                return None
            names.append(gv.name)
        stub = library._codegen._create_empty_module(library.name + ".env")
        for name in names:
            gv = llvmir.GlobalVariable(stub, cgutils.voidptr_t, name=name)
            gv.linkage = "common"
            gv.initializer = cgutils.get_null_value(gv.type.pointee)
        return ll.parse_assembly(str(stub))

    class Library(base):
        """numba's JIT library that makes its machine code when something asks for a symbol it defines."""

        _code_pending = False           # optimised and linked; not in the execution engine yet
        _bitcode = None                 # loaded LINK_ONLY: the module to make the code from, parsed when needed
        _link_only_ok = False           # the kernel cache can save it without machine code

        def _finalize_final_module(self):
            eager = (not depth[0] or self._compiled_object_loaded() or self._codegen._rtlinker._unresolved
                     or config.DUMP_OPTIMIZED or config.DUMP_ASSEMBLY)
            env = None if eager else env_module(self, self._final_module)
            if env is None:
                return super()._finalize_final_module()
            self._finalize_dynamic_globals()
            self._verify_declare_only_symbols()
            self._defer(env)

        def _compiled_object_loaded(self):
            return getattr(self, "_compiled_object", None) is not None     # numba's 'object' kind, from a cache

        def _defer(self, env):
            # the environment globals go into the engine now (get_executable writes the address of the
            # function's environment into its own); the functions when asked for
            self._codegen._add_module(env)
            self._codegen._engine.finalize_object()
            self._code_pending = True
            pending.add(self)
            self._finalized = True

        def make_code(self):
            """What numba's ``_finalize_final_module`` does after the checks: the module into the engine and its
            machine code."""
            with global_compiler_lock:
                if not self._code_pending:
                    return
                self._code_pending = False
                pending.discard(self)
                if self._bitcode is not None:
                    self._final_module, self._bitcode = ll.parse_bitcode(self._bitcode), None
                self._final_module._CPUCodeLibrary__library = weakref.proxy(self)   # numba's object cache hooks
                cleanup = self._codegen._add_module(self._final_module)
                if cleanup:
                    weakref.finalize(self, cleanup)
                self._finalize_specific()

        def _defines(self, name):
            module = self._shared_module if self._bitcode is not None else self._final_module
            try:
                return not module.get_function(name).is_declaration
            except NameError:
                return False

        def get_pointer_to_function(self, name):
            self._ensure_finalized()
            if self._code_pending and self._defines(name):
                self.make_code()
            return super().get_pointer_to_function(name)

        def serialize_using_object_code(self):
            self._ensure_finalized()
            if self._code_pending:
                if self._link_only_ok:
                    return (self.name, LINK_ONLY, self._get_module_for_linking().as_bitcode())
                self.make_code()
            return super().serialize_using_object_code()

        @classmethod
        def _unserialize(cls, codegen_, state):
            name, kind, data = state
            if kind != LINK_ONLY:
                return super()._unserialize(codegen_, state)
            self = codegen_.create_library(name)
            self._shared_module = ll.parse_bitcode(data)
            self._disable_inspection = True
            self._bitcode = data
            env = env_module(self, self._shared_module)
            if env is None:                                    # (not saved so)
                self._final_module, self._bitcode = ll.parse_bitcode(data), None
                self._finalize_final_module()
            else:
                self._defer(env)
            return self

    scan = codegen.CPUCodegen._scan_and_fix_unresolved_refs

    def _scan_and_fix_unresolved_refs(self, module):
        """numba's, but a recursive call's unresolved reference first has every library's code made (one of
        them may define the function)."""
        self._rtlinker.scan_unresolved_symbols(module, self._engine)
        if self._rtlinker._unresolved:
            for library in list(pending):
                library.make_code()
        self._rtlinker.scan_defined_symbols(module)
        self._rtlinker.resolve(self._engine)

    _scan_and_fix_unresolved_refs.__wrapped__ = scan
    event.register("numba:compile", Ours())
    codegen.CPUCodegen._scan_and_fix_unresolved_refs = _scan_and_fix_unresolved_refs
    codegen.JITCPUCodegen._library_class = Library
    return True
