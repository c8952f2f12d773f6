"""The numba kernels: one decorator, one cache folder per user, compiling ahead, a compile you can watch.

Every compiled function in driftframe is declared with :func:`kernel` (numba's
``njit`` with driftframe's own cache) in one of :data:`KERNEL_MODULES`.

Where the cache lives: ``$NUMBA_CACHE_DIR/driftframe/<key>`` when that
variable is set, else the user's cache folder (``$XDG_CACHE_HOME`` or
``~/.cache`` on Linux, ``~/Library/Caches`` on macOS, ``%LOCALAPPDATA%`` on
Windows) ``/driftframe/kernels/<key>``; never beside the sources, so a
read-only install works and uninstalling leaves nothing behind. ``<key>`` is
driftframe's version and a digest of every kernel module's source: numba
alone checks only the file a kernel is written in, so a kernel that calls
one in another file (``contact_solve.solve_listed`` calls
``broadphase_list.territory_query``) would go on running the old callee after
that file changed. Each cache file also carries a SHA-256 of its bytes and
each compiled entry the key it was saved under: a damaged file, or one
another process overwrote (numba's cache is not safe against concurrent
writers, numba issue 4807), is compiled again, never loaded.

This module imports nothing heavy: :func:`kernel` imports numba when the
first kernel is declared, so ``import driftframe`` stays cheap.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import sys
import threading
import time
from pathlib import Path

from driftframe.framework import __version__

#: The modules (in ``driftframe.framework``) that declare kernels. The cache key digests them and
#: :data:`KERNEL_IMPORTS`: a test checks both lists are complete.
KERNEL_MODULES = ("broadphase_list", "contact_again", "contact_bodies", "contact_heap", "contact_islands",
                  "contact_jam", "contact_pairs", "contact_solve", "contact_toi", "contact_wave", "encounters",
                  "free_flight", "kepler_kernels", "kepler_small", "mercurius", "quiet_step", "sorting",
                  "static_shapes", "wisdom_holman", "yuv")
#: Modules that declare no kernel but whose names kernels read at compile time (numba freezes a global's
#: value into the code): constants and the records kernels take.
KERNEL_IMPORTS = ("contact_params",)
#: What :mod:`.kernel_cache` writes, digested into the cache key with the sources: 2, a callee's library may be
#: saved without machine code (``kernel_shortcuts.LINK_ONLY``), which a driftframe writing format 1 cannot read.
CACHE_FORMAT = 2

_HERE = Path(__file__).resolve().parent
_registry: list = []                 # every kernel's dispatcher, in declaration order
_digest: str | None = None
_warned: set = set()


# -- where ------------------------------------------------------------------------------------------------
def user_cache_root() -> Path:
    """The platform's per-user cache folder for driftframe (not created here)."""
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
        return Path(base) / "driftframe" / "Cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "driftframe"
    xdg = os.environ.get("XDG_CACHE_HOME", "")
    return (Path(xdg) if os.path.isabs(xdg) else Path.home() / ".cache") / "driftframe"   # XDG: relative = unset


def source_digest() -> str:
    """SHA-256 (hex, first 16 digits) of :data:`CACHE_FORMAT` and every kernel module's source, in
    :data:`KERNEL_MODULES` order, then :data:`KERNEL_IMPORTS`."""
    global _digest
    if _digest is None:
        h = hashlib.sha256(f"cache format {CACHE_FORMAT}\n".encode())
        for name in KERNEL_MODULES + KERNEL_IMPORTS:
            data = (_HERE / f"{name}.py").read_bytes()
            h.update(f"{name}.py {len(data)}\n".encode())
            h.update(data)
        _digest = h.hexdigest()[:16]
    return _digest


def cache_dir() -> Path:
    """The folder this process caches kernels in (see the module docstring); not created here."""
    key = f"{__version__}-{source_digest()}"
    numba_dir = _numba_cache_dir()
    if numba_dir:
        return Path(numba_dir) / "driftframe" / key
    return user_cache_root() / "kernels" / key


def _numba_cache_dir() -> str:
    config = sys.modules.get("numba.core.config")    # set in code after numba was imported, or by the env
    return (getattr(config, "CACHE_DIR", "") if config is not None else "") or os.environ.get("NUMBA_CACHE_DIR", "")


def warn_once(key, line: str) -> None:
    """One line on stderr, once per process for each ``key`` (any hashable)."""
    if key not in _warned:
        _warned.add(key)
        print(f"driftframe: warning: {line}", file=sys.stderr, flush=True)


def _unwritable(folder: Path, e: OSError) -> None:
    warn_once(("unwritable", str(folder)),
              f"cannot write the kernel cache folder {folder} ({e.strerror or e}); "
              "kernels are compiled in this process only (set NUMBA_CACHE_DIR to a writable folder)")


# -- declaring ------------------------------------------------------------------------------------------
def kernel(fn=None, **options):
    """``numba.njit(**options)`` with driftframe's cache: ``@kernel`` or ``@kernel(error_model="numpy")``."""
    if "cache" in options:
        raise TypeError("kernel() caches always; do not pass cache=")

    def declare(f):
        from numba import njit

        from driftframe.framework import kernel_cache, kernel_shortcuts, typing_memo

        if not _registry:
            typing_memo.install()           # a cold compile's typing, once per call signature (its docstring)
            # a cheaper compile, same code; ours: a dispatcher with our cache (set below), not a registry scan
            kernel_shortcuts.install(lambda d: isinstance(getattr(d, "_cache", None), kernel_cache.KernelCache))
            kernel_cache.install_nrt_cache()    # numba's runtime helpers from the cache folder, not compiled anew

        dispatcher = njit(**options)(f)
        dispatcher._cache = kernel_cache.KernelCache(f)   # what njit(cache=True) sets, ours
        _registry.append(dispatcher)
        return dispatcher

    return declare(fn) if fn is not None else declare


def variant(fn, name: str, doc: str | None = None, **constants):
    """``fn``'s code as a new function ``name`` whose globals are ``fn``'s (as they are now: call this once the
    module has defined every name ``fn`` reads) with ``constants`` added; to be declared with :func:`kernel`.

    numba reads a global as a constant and prunes the branches that constant rules out before it types the
    code, and it compiles whatever a kernel can call: so ``if _GRID: ...`` in ``fn`` costs the variant made
    with ``_GRID=False`` neither the branch nor the kernels only that branch calls. Each variant is cached
    under its own name."""
    import types
    f = types.FunctionType(fn.__code__, dict(fn.__globals__, **constants), name, fn.__defaults__, fn.__closure__)
    f.__qualname__ = name
    f.__doc__ = fn.__doc__ if doc is None else doc
    f.__module__ = fn.__module__
    return f


def before_compile() -> None:
    """What the first compile of a process needs first (:meth:`kernel_cache.KernelCache.load_overload` calls it
    when a load misses, and before loading a kernel that names ``numba.np.arraymath``): numba's NumPy
    support imported without scipy (:func:`_blas_without_scipy`)."""
    _blas_without_scipy()


def _blas_without_scipy() -> None:
    """Spare the first compile (or a load that imports numba.np.arraymath) an import of scipy.linalg.

    numba's CPU target, set up at the first compile, imports
    ``numba.np.arraymath``, which imports ``scipy.linalg.cython_blas`` only to
    learn whether BLAS is there (``_HAVE_BLAS``, which picks how
    ``np.correlate`` sums). That answer is taken here from whether scipy is
    installed, without importing it. ``np.dot`` and ``np.linalg`` in a kernel
    still import it when they are typed (``numba.np.linalg.ensure_blas``,
    restored below); driftframe's kernels call neither.
    """
    if "numba.np.arraymath" in sys.modules:
        return
    try:
        import importlib.util

        import numba.np.linalg as linalg
        real = linalg.ensure_blas
    except (ImportError, AttributeError):       # another numba layout: leave it as it is
        return

    def installed():
        if importlib.util.find_spec("scipy") is None:
            raise ImportError("scipy 0.16+ is required for linear algebra")

    linalg.ensure_blas = installed
    try:
        import numba.np.arraymath  # noqa: F401  (it binds ensure_blas at import and calls it once)
    finally:
        linalg.ensure_blas = real


def entry(dispatcher, args: tuple):
    """``dispatcher``'s compiled entry point for exactly the types of ``args`` (loaded or compiled now):
    a call to it skips numba's dispatch (typing every argument and finding the overload: its cost in
    docs/design/costs.md; a small scene's step makes two such calls). Only for calls whose arguments keep those types:
    the same array objects (an array's dtype, dimensions and layout stay) and Python floats; the entry
    point unboxes what it is given as the types it was compiled for, unchecked. Under NUMBA_DISABLE_JIT,
    the function itself."""
    if not hasattr(dispatcher, "compile"):
        return dispatcher
    sig = tuple(dispatcher.typeof_pyval(a) for a in args)
    found = dispatcher.overloads.get(sig)
    return found.entry_point if found is not None else dispatcher.compile(sig)


def registry(load: bool = True) -> list:
    """Every kernel's dispatcher; ``load`` imports every kernel module first."""
    if load:
        import importlib
        for name in KERNEL_MODULES:
            importlib.import_module(f"driftframe.framework.{name}")
    return list(_registry)


def kernel_name(dispatcher) -> str:
    """``contact_solve.solve_listed``: the module's last part and the function's name."""
    return f"{dispatcher.py_func.__module__.rsplit('.', 1)[-1]}.{dispatcher.py_func.__name__}"


def _inlined(dispatcher) -> bool:
    # inline="always": numba pastes the callee's IR into each caller and never compiles it on its own
    return dispatcher.targetoptions.get("inline", "never") == "always"


def callees(dispatcher) -> set:
    """The kernels ``dispatcher`` names in its code: ``f(...)`` for a kernel global, ``mod.f(...)`` for a module's."""
    import types
    f = dispatcher.py_func
    names, codes = set(), [f.__code__]
    while codes:
        code = codes.pop()
        names.update(code.co_names)
        codes.extend(c for c in code.co_consts if isinstance(c, types.CodeType))
    known = {id(d) for d in _registry}
    found = set()
    for name in names:
        value = f.__globals__.get(name)
        if isinstance(value, types.ModuleType):
            for attr in names:
                candidate = getattr(value, attr, None)
                if id(candidate) in known:
                    found.add(candidate)
        elif id(value) in known and value is not dispatcher:
            found.add(value)
    return found


def closure(dispatcher) -> list:
    """``dispatcher`` and every kernel it can call, directly or through others."""
    seen, todo = {id(dispatcher): dispatcher}, [dispatcher]
    while todo:
        for c in callees(todo.pop()):
            if id(c) not in seen:
                seen[id(c)] = c
                todo.append(c)
    return list(seen.values())


def needs_compile(dispatcher) -> bool:
    """True when ``dispatcher`` has nothing compiled in this process and nothing usable in the cache."""
    return not _inlined(dispatcher) and not dispatcher.overloads and not dispatcher._cache.has_entries()


# -- watching a compile ----------------------------------------------------------------------------------
class KernelCompileError(RuntimeError):
    """A kernel failed to compile; the message names it."""


class CompileWatch:
    """Counts the kernels numba compiles while it is entered (numba's ``numba:compile`` events).

    ``expected``: the kernels known to need compiling so far: those given, and
    when a kernel starts compiling, every kernel it can call that has nothing
    cached (:func:`closure`, :func:`needs_compile`). ``n of m`` is then
    ``len(started)`` of ``len(expected | started)``: m grows only when a
    compile begins that nothing predicted. Thread-safe: the events come from
    the compiling thread, :meth:`line` from any other.
    """

    def __init__(self, expected=()):
        self._lock = threading.Lock()
        self.expected = {id(d): d for d in expected}
        self.started: dict = {}
        self.stack: list = []            # (dispatcher, one of ours) compiling now, outermost first
        self.t0 = None
        self.seconds = 0.0
        self.attempts: list = []         # (kernel, argument types) of each compile begun
        self.remote: list = []           # what a warm-up helper process compiles now, outermost first

    @property
    def n(self) -> int:
        return len(self.started)

    @property
    def m(self) -> int:
        return len(self.expected.keys() | self.started.keys())

    def _start(self, ev) -> None:
        d = ev.data["dispatcher"]       # numba's own numpy functions compile through dispatchers too: not counted
        with self._lock:
            if self.t0 is None:
                self.t0 = time.perf_counter()
            ours = any(d is k for k in _registry)
            if ours and not any(mine for _, mine in self.stack):      # the outermost of ours
                for c in closure(d):
                    if c is d or needs_compile(c):
                        self.expected.setdefault(id(c), c)
            if ours:
                self.started.setdefault(id(d), d)
                self.attempts.append((d, tuple(ev.data["args"])))
            self.stack.append((d, ours))

    def _end(self, ev) -> None:
        with self._lock:
            if self.stack:
                self.stack.pop()

    def elsewhere(self, name: str | None) -> None:
        """A compile in a warm-up helper process (:mod:`.warm_helper`): kernel ``name`` begins; None: the
        last begun ends. Counted as this process's own."""
        with self._lock:
            if name is None:
                if self.remote:
                    self.remote.pop()
                return
            d = next((k for k in _registry if kernel_name(k) == name), None)
            if d is None:
                return
            if self.t0 is None:
                self.t0 = time.perf_counter()
            if not self.remote:
                for c in closure(d):
                    if c is d or needs_compile(c):
                        self.expected.setdefault(id(c), c)
            self.started.setdefault(id(d), d)
            self.remote.append(d)

    def failed(self):
        """The kernel whose compile failed: the last one begun that has no code for its arguments (numba
        reports a typing error after the compile events end, from the outermost call)."""
        with self._lock:
            for d, args in reversed(self.attempts):
                if args not in d.overloads:
                    return d
        return None

    def elapsed(self) -> float:
        return 0.0 if self.t0 is None else time.perf_counter() - self.t0

    def current(self) -> str:
        with self._lock:
            ours = [d for d, mine in self.stack if mine]
            names = [kernel_name(ours[-1])] if ours else []
            return ", ".join(names + ([kernel_name(self.remote[-1])] if self.remote else []))

    def line(self) -> str:
        """``3 of 14 kernels, 12 s: contact_solve.solve_listed``"""
        now = self.current()
        return f"{self.n} of {self.m} kernels, {self.elapsed():.0f} s" + (f": {now}" if now else "")

    def __enter__(self):
        from numba.core import event
        watch = self

        class _Listener(event.Listener):
            def on_start(self, ev):
                watch._start(ev)

            def on_end(self, ev):
                watch._end(ev)

        self._listener = _Listener()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, exc_type, exc, tb):
        from numba.core import event
        event.unregister("numba:compile", self._listener)
        self.seconds = self.elapsed()
        from numba.core.errors import NumbaError
        culprit = self.failed() if isinstance(exc, NumbaError) else None
        if culprit is not None:
            lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip() and not ln.startswith("Failed in")]
            first = lines[0] if lines else exc_type.__name__        # numba's own first line names its pass
            raise KernelCompileError(f"compiling kernel {kernel_name(culprit)} failed: {first}") from exc


# -- compiling ahead -------------------------------------------------------------------------------------
@contextlib.contextmanager
def file_lock(path: Path):
    """An exclusive lock on ``path`` across processes (created if missing); a no-op where it cannot be made.
    Gives the locked descriptor (None where there is none to share)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as e:
        _unwritable(path.parent, e)
        yield None
        return
    try:
        if sys.platform == "win32":
            import msvcrt
            while True:
                try:
                    msvcrt.locking(fd, msvcrt.LK_LOCK, 1)
                    break
                except OSError:      # LK_LOCK gives up after 10 s; a compile takes longer
                    continue
            yield None               # (a helper process cannot share this lock)
        else:
            import fcntl
            fcntl.flock(fd, fcntl.LOCK_EX)
            yield fd                 # a helper process given this descriptor shares the lock (flock: per open file)
    finally:
        os.close(fd)                 # closing releases the lock (once every process sharing it closed it)


WARM_MARK = "warm.done"


def is_warm(folder: Path | None = None) -> bool:
    """Whether :func:`warm` finished in the cache folder (its mark file exists)."""
    return ((folder or cache_dir()) / WARM_MARK).exists()


def warm(parts, watch: CompileWatch | None = None) -> list:
    """Run ``parts`` (one function or several; together, calls that reach every kernel:
    :data:`driftframe.warmup.PARTS`), so that each kernel is compiled or loaded, one warm-up at a time
    per cache folder (a file lock), then mark the folder warm.

    With several parts and more than one core, the parts after the first run at the same time in a helper
    process (:mod:`.warm_helper`), in order; this process, done with the first, takes them from the far
    end (parts that ask :func:`claim` run in one process only), then runs them all again (loading what
    the helper compiled, and compiling whatever it did not finish), so a cold compile takes two cores.

    Returns the kernels still with nothing compiled or cached (the parts did not reach them).
    ``watch``: a :class:`CompileWatch` already entered, to show progress; every kernel with nothing
    cached is added to its ``expected`` here, and the helper's compiles are counted in it.
    """
    with file_lock(cache_dir() / "warm.lock") as fd:
        return _warm(parts, watch, fd)


def warm_once(parts) -> None:
    """:func:`warm` unless the cache folder is warm already; quiet. Each batch worker calls it before a run:
    the first to take the lock compiles, the others wait and then find the folder warm."""
    if not is_warm():
        with file_lock(cache_dir() / "warm.lock") as fd:
            if not is_warm():
                _warm(parts, None, fd)


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:       # (not on macOS or Windows)
        return os.cpu_count() or 1


def _warm(parts, watch, lock_fd=None) -> list:
    import shutil
    global _claims
    folder = cache_dir()
    kernels = registry()
    parts = [parts] if callable(parts) else list(parts)
    for stale in folder.glob("*.tmp.*"):        # a write cut short (Ctrl-C, a crash): numba renames on success
        with contextlib.suppress(OSError):
            stale.unlink()
    cold = [d for d in kernels if needs_compile(d)]
    if watch is not None:
        with watch._lock:
            for d in cold:
                watch.expected.setdefault(id(d), d)
    helper = None
    claims = folder / "warm.claims"
    if len(parts) > 1 and cold and _cores() > 1 and lock_fd is not None:
        from driftframe.framework import warm_helper
        try:                                    # (under the lock: no other warm-up uses this folder)
            shutil.rmtree(claims, ignore_errors=True)
            claims.mkdir(parents=True)
            os.environ[CLAIMS_ENV] = str(claims)    # the helper's: Popen copies the environment
        except OSError:
            pass                                # no claims: the helper runs parts[1:], as before there were any
        try:
            helper = warm_helper.start(parts[1:], lock_fd)
        finally:
            given = os.environ.pop(CLAIMS_ENV, None)
        _claims = given                         # (only once the helper runs: parts are shared from here on)
        relay = threading.Thread(target=warm_helper.relay, args=(helper, watch), daemon=True)
        relay.start()
    try:
        parts[0]()
        if helper is not None:
            # the helper runs parts[1:] in order; this process, done with the first, takes them from the far
            # end: a part claimed by one process (:func:`claim`) returns at once in the other
            for part in reversed(parts[2:] if _claims else ()):
                part()
            helper.wait()
            relay.join()
        _claims = None
        for part in parts[1:]:   # loads what the helper compiled; compiles what it left (or lost to a race)
            part()
    finally:
        _claims = None
        if helper is not None:
            warm_helper.stop(helper)
            shutil.rmtree(claims, ignore_errors=True)
    try:                          # what the warm-up did not reach compiles at its first call, as numba does
        (folder / WARM_MARK).write_text(f"{__version__} {source_digest()}\n")
    except OSError as e:
        _unwritable(folder, e)
    prune(folder)
    # a kernel loaded from the cache as a caller's callee has no overload of its own: its entries count
    return [d for d in kernels if needs_compile(d)]


#: The environment variable that gives a warm-up helper process the folder where parts are claimed.
CLAIMS_ENV = "DRIFTFRAME_WARM_CLAIMS"
_claims: str | None = None       # that folder in the process that started the helper, during its warm-up


def claim(name: str) -> bool:
    """Whether this process runs warm-up part ``name`` now (:data:`driftframe.warmup.PARTS` ask it first):
    True outside a warm-up with a helper process, and for the first of the two processes to ask; False
    in the other. The first process runs every part again after the helper ended, loading what the
    helper compiled (:func:`warm`). One file per part in the claims folder, created exclusively."""
    folder = _claims or os.environ.get(CLAIMS_ENV)
    if not folder:
        return True
    try:
        os.close(os.open(os.path.join(folder, name), os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
    except FileExistsError:
        return False
    except OSError:              # (the folder gone: the warm-up ended) run it, as without claims
        return True
    return True


#: Cache folders of other driftframe versions or sources kept beside this one (the newest warmed first):
#: two installs that alternate keep theirs, and upgrades do not pile up megabytes of stale kernels.
KEEP_OTHERS = 3


def prune(folder: Path) -> list:
    """Remove the cache folders beside ``folder`` (other keys) but the :data:`KEEP_OTHERS` last warmed (by
    their mark, else their own time); returns those removed. A process still loading from a removed folder
    finds its files missing and compiles, as with any cache miss."""
    import shutil

    def when(d: Path) -> float:
        try:
            return (d / WARM_MARK).stat().st_mtime
        except OSError:
            try:
                return d.stat().st_mtime
            except OSError:
                return 0.0

    import re
    key = re.compile(r".+-[0-9a-f]{16}")         # <version>-<source digest>: only folders made as cache_dir() makes them
    try:
        others = [d for d in folder.parent.iterdir() if d.name != folder.name and key.fullmatch(d.name) and d.is_dir()]
    except OSError:
        return []
    others.sort(key=when, reverse=True)
    gone = others[KEEP_OTHERS:]
    for d in gone:
        shutil.rmtree(d, ignore_errors=True)
    return gone
