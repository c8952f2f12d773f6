"""numba's function cache, pointed at driftframe's folder and checked on every load (see :mod:`.kernels`).

numba's own ``FunctionCache`` with four changes: the folder is
:func:`kernels.cache_dir` (keyed by the digest of every kernel module), the
source stamp is that digest (so an index written for other sources is stale
even in the same folder), and each file is ``sha256(payload) + payload``
with each compiled entry saved beside its index key. A file that fails the
check, or an entry under another key (two processes that numbered their
entries alike, numba issue 4807), is treated as missing: compiled again and
written anew. A folder that cannot be written: one warning, then the kernels
are compiled in this process only. And a load sets up only numba's runtime,
not its whole compiler (:meth:`KernelCache.load_overload`).
"""
from __future__ import annotations

import hashlib
import inspect
import itertools
import os
import pickle
import sys
import tempfile

from numba.core.caching import (CompileResultCacheImpl, FunctionCache, IndexDataCacheFile, _CacheLocator)
from numba.core.serialize import dumps

from driftframe.framework import kernel_shortcuts, kernels
from driftframe.framework.output import write_file

_DIGEST = 32                      # bytes of SHA-256 in front of each file's payload
# A kernel that calls one of numba's NumPy functions written in numba.np.arraymath (np.round: the Kepler
# kernels) carries that module's name in its cached environment, and unpickling it imports the module, which
# imports scipy.linalg unless kernels.before_compile() has imported it first (kernels._blas_without_scipy)
_ARRAYMATH = b"numba.np.arraymath"


class _Locator(_CacheLocator):
    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._folder = str(kernels.cache_dir())

    def ensure_cache_path(self):
        os.makedirs(self._folder, exist_ok=True)
        tempfile.TemporaryFile(dir=self._folder).close()      # writable, as numba's own locators check

    def get_cache_path(self):
        return self._folder

    def get_source_stamp(self):
        return kernels.source_digest()

    def get_disambiguator(self):
        return str(self._lineno)


class _Impl(CompileResultCacheImpl):
    """numba's ``CacheImpl.__init__`` with our locator in place of its search through its own."""

    def __init__(self, py_func):
        filename = inspect.getfile(py_func)
        self._lineno = py_func.__code__.co_firstlineno
        self._locator = _Locator(py_func, filename)
        modname = os.path.splitext(os.path.basename(filename))[0]
        qualname = getattr(py_func, "__qualname__", py_func.__name__)
        self._filename_base = self.get_filename_base(f"{modname}.{qualname}", getattr(sys, "abiflags", ""))

    def reduce(self, cres):
        kernel_shortcuts.link_only_ok(cres.library)      # a callee's library may be saved without machine code
        return super().reduce(cres)

    def rebuild(self, target_context, payload):
        return super().rebuild(target_context, (kernel_shortcuts.readable(payload[0]),) + tuple(payload[1:]))


class _CheckedFile(IndexDataCacheFile):
    """Index and data files with a SHA-256 of their bytes; each data file holds ``(key, entry)``."""

    def _dump(self, obj):
        payload = dumps(obj)
        return hashlib.sha256(payload).digest() + payload

    @staticmethod
    def _checked(blob):
        if len(blob) < _DIGEST or hashlib.sha256(blob[_DIGEST:]).digest() != blob[:_DIGEST]:
            return None
        return pickle.loads(blob[_DIGEST:])

    def _load_index(self):
        try:
            with open(self._index_path, "rb") as f:
                version = pickle.load(f)
                blob = f.read()
        except FileNotFoundError:
            return {}
        except Exception:          # noqa: BLE001 - a damaged file: whatever unpickling raised, it is stale
            return {}
        if version != self._version:
            return {}
        try:
            stamp, overloads = self._checked(blob)
        except Exception:          # noqa: BLE001 - None (the check failed) or a bad pickle
            return {}
        return overloads if stamp == self._source_stamp else {}

    def has_entries(self) -> bool:
        return bool(self._load_index())

    def save(self, key, data):
        overloads = self._load_index()
        name = overloads.get(key)
        if name is None:
            taken = set(overloads.values())
            name = next(n for n in (self._data_name(i) for i in itertools.count(1)) if n not in taken)
            overloads[key] = name
            self._save_index(overloads)
        self._save_data(name, (key, data))

    def load(self, key):
        name = self._load_index().get(key)
        if name is None:
            return None
        try:
            with open(self._data_path(name), "rb") as f:
                blob = f.read()
            if _ARRAYMATH in blob:
                kernels.before_compile()
            saved_key, data = self._checked(blob)
        except Exception:          # noqa: BLE001 - missing, damaged (the check failed) or a bad pickle
            return None
        return data if saved_key == key else None


# -- numba's runtime helpers ---------------------------------------------------------------------------------
# numba compiles its runtime's helpers (NRT: incref, decref, the meminfo accessors; nrtdynmod) with LLVM in
# every process, before its first kernel runs: ~45 ms of CPU, a third of loading a scene's cached kernels
# (docs/bench/startup.md). They are the same code on every run of one numba, llvmlite and CPU, so they are
# cached here too, as numba caches a kernel: object code (which the JIT loads) and bitcode (which a kernel
# compiled in the process links), in the kernel folder, checked as every other file.
_NRT_NAME = "nrt-{key}.bin"


def _nrt_path(ctx):
    import llvmlite
    import numba
    magic = repr((numba.__version__, llvmlite.__version__, ctx.codegen().magic_tuple()))
    return kernels.cache_dir() / _NRT_NAME.format(key=hashlib.sha256(magic.encode()).hexdigest()[:16])


def nrt_functions(ctx, compile_fresh):
    """numba's runtime library (``nrtdynmod.compile_nrt_functions(ctx)``): from the cache folder when a checked
    copy for this numba, llvmlite and CPU is there, else compiled (``compile_fresh``: numba's steps, with
    its object code kept) and saved for the next process. Anything wrong with the file: compiled anew."""
    path = _nrt_path(ctx)
    try:
        state = _CheckedFile._checked(path.read_bytes())
        if state is not None:
            return ctx.codegen().unserialize_library(state)
    except Exception:          # noqa: BLE001 - missing, damaged, another layout: compile it as numba does
        pass
    library = compile_fresh(ctx)
    try:
        payload = pickle.dumps(library.serialize_using_object_code(), protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:          # noqa: BLE001 - no object code kept (another numba's JIT): used, not saved
        return library
    try:                       # a whole file or none (framework.output), as every output
        path.parent.mkdir(parents=True, exist_ok=True)
        write_file(path, hashlib.sha256(payload).digest() + payload, overwrite=True, what="kernel cache file")
    except OSError:            # a read-only folder: the kernels' own save says so once; this process goes on
        pass
    return library


def install_nrt_cache() -> bool:
    """Have numba take its runtime library from :func:`nrt_functions` (once per process; False where this
    numba's runtime module is laid out otherwise, or ``DRIFTFRAME_COMPILE_SHORTCUTS=0``)."""
    if os.environ.get("DRIFTFRAME_COMPILE_SHORTCUTS", "1") == "0":
        return False
    from numba.core.runtime import nrtdynmod
    real = nrtdynmod.compile_nrt_functions
    if getattr(real, "_driftframe", False):
        return True
    if not hasattr(nrtdynmod, "create_nrt_module"):
        return False

    def compile_fresh(ctx):
        ir_mod, library = nrtdynmod.create_nrt_module(ctx)      # compile_nrt_functions' steps, and the object
        library.enable_object_caching()                         # code kept to be saved
        library.add_ir_module(ir_mod)
        library.finalize()
        library.get_pointer_to_function("nrt_unresolved_abort")   # the JIT makes the code now (kept above)
        return library

    def compile_nrt_functions(ctx):
        return nrt_functions(ctx, compile_fresh)

    compile_nrt_functions._driftframe = True
    compile_nrt_functions.__doc__ = real.__doc__
    nrtdynmod.compile_nrt_functions = compile_nrt_functions
    return True


class KernelCache(FunctionCache):
    """The cache of one kernel, in :func:`kernels.cache_dir`."""

    _impl_class = _Impl

    def __init__(self, py_func):
        super().__init__(py_func)
        self._cache_file = _CheckedFile(self._cache_path, self._impl.filename_base,
                                        self._impl.locator.get_source_stamp())

    def has_entries(self) -> bool:
        """Whether the index lists anything usable (compiled entries for these sources)."""
        return self._cache_file.has_entries()

    def load_overload(self, sig, target_context):
        """numba's load, without its ``target_context.refresh()``; on a miss, ready the compile that follows.

        numba refreshes the whole target context before every cache load: it
        imports and installs every typing and lowering registry (NumPy's,
        the typed containers', jitclass', ...), once per process, which only
        a compile uses (its cost: docs/bench/startup.md). A cached kernel is object code
        plus its signature; to run it needs numba's runtime (NRT: the
        allocator its arrays call), which is all that is set up here. A
        compile refreshes the context itself (``numba.core.compiler``), so a
        kernel compiled later in the process is typed as before. On a miss
        (numba compiles next) :func:`kernels.before_compile` runs first.
        """
        from numba.core.runtime import rtsys

        rtsys.initialize(target_context)    # idempotent; what refresh() does first for the CPU target
        with self._guard_against_spurious_io_errors():
            loaded = self._load_overload(sig, target_context)
            if loaded is None:
                kernels.before_compile()
            return loaded
        return None     # the guard swallowed an OSError (numba's own handling): compile

    def save_overload(self, sig, data):
        try:
            super().save_overload(sig, data)
        except OSError as e:       # read-only or full: this process keeps what it compiled, in memory
            kernels._unwritable(self._impl.locator.get_cache_path(), e)
