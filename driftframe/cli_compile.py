"""Compiling the physics kernels from the command line: on a helper thread, with a progress line.

``driftframe warm`` compiles them all ahead; ``record``, ``play`` and ``batch`` load (or on a first run
compile) their scene's before the costly part starts.
"""
from __future__ import annotations

import sys
import time

#: The name of the thread that compiles: :func:`exit_if_compiling` looks for it.
HELPER = "driftframe-kernels"

def _compile(task, quiet: bool = False) -> None:
    """``task(watch)`` on a helper thread while this, the main thread, shows the compile and waits.

    ``watch`` is a :class:`~framework.kernels.CompileWatch`. A Ctrl-C, SIGTERM
    or SIGHUP during a first run's compile then stops the command here,
    between waits, with the usual message and exit status (the recorder's
    :class:`~framework.recorder.StopSignals` takes them). In the main thread
    it would land inside numba's compiler, which calls back into Python
    through ctypes, where an exception is printed and dropped and the compile
    goes on. The helper is a daemon: it ends with the process.
    """
    import threading

    from driftframe.framework.kernels import CompileWatch
    from driftframe.framework.recorder import Interrupted, StopSignals

    failed: list[BaseException] = []
    watch = CompileWatch()

    def run():
        try:
            with watch:
                task(watch)
        except BaseException as e:   # noqa: BLE001 - handed to the main thread
            failed.append(e)

    helper = threading.Thread(target=run, name=HELPER, daemon=True)
    shown = _CompileProgress(watch, enabled=not quiet)
    with StopSignals(True) as stop:
        helper.start()
        while helper.is_alive() and stop.requested is None:
            helper.join(0.2)
            shown.tick()
        if stop.requested is not None:
            shown.end(stopped=True)
            raise Interrupted(stop.requested)
    shown.end(stopped=bool(failed))
    if failed:
        raise failed[0]


def exit_if_compiling(code: int) -> int:
    """``code``, or, while a compile stopped by a signal still runs on its helper thread, end the process
    now with ``code`` (after flushing the output).

    numba cannot be stopped inside a compile, and the interpreter's shutdown
    with LLVM still working on the helper thread aborts the process (an
    LLVM assertion, exit -6) instead of ending with the signal's status.
    Skipping the shutdown loses nothing: numba writes each cache file under a
    temporary name and renames it when whole, and the outputs are checked or
    written before the costly part starts, after the kernels are loaded.
    """
    import os
    import threading
    if any(t.name == HELPER and t.is_alive() for t in threading.enumerate()):
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):     # a closed pipe: nothing more to show
                pass
        os._exit(code)
    return code


def _load_kernels(name: str, seed: int, quiet: bool = False, nv12: bool = False) -> None:
    """:func:`driftframe.app.load_kernels` through :func:`_compile`; ``nv12``: the MP4 writer's
    colour conversion kernel too (else a first run compiles it at frame 0, under the progress bar)."""
    from driftframe.app import load_kernels

    def task(watch):
        load_kernels(name, seed=seed)
        if nv12:
            import numpy as np

            from driftframe.framework.yuv import rgba_to_nv12
            rgba_to_nv12(np.zeros((2, 2, 4), np.uint8), 2, 2)
    _compile(task, quiet)


def cmd_warm(args) -> int:
    from driftframe import warmup
    from driftframe.framework import kernels

    missed: list = []
    _compile(lambda watch: missed.extend(warmup.warm(watch)), args.quiet)
    total = len(kernels.registry(load=False))
    if missed:
        print(f"driftframe: warning: the warm-up did not reach {len(missed)} of {total} kernels "
              f"({', '.join(kernels.kernel_name(d) for d in missed)}); they compile at their first call",
              file=sys.stderr)
    print(f"{total - len(missed)} of {total} kernels ready in {kernels.cache_dir()}")
    return 0


class _CompileProgress:
    """Shows a compile while :func:`_compile` waits: a line saying so, then which kernel, n of m and the time.

    numba reports a compile only when its cache misses, so a warm run shows
    nothing. On a terminal the progress line is rewritten in place (``\\r``) at
    least once a second; into a file or a pipe (a CI log) a whole line is
    written at most every :attr:`LOG_EVERY` seconds, and the last state when
    the compile ends. The summary line follows, before the command goes on.
    """

    LOG_EVERY = 5.0

    def __init__(self, watch, enabled: bool):
        self.watch = watch
        self.enabled = enabled
        self.announced = False
        self.last = (None, 0.0)
        self.width = 0
        self.tty = sys.stderr.isatty()
        self.named = None

    def _write(self, text: str) -> None:
        sys.stderr.write(text)
        sys.stderr.flush()

    def tick(self, force: bool = False) -> None:
        if not self.enabled or self.watch.n == 0:
            return
        if not self.announced:
            from driftframe.framework.kernels import cache_dir
            self.announced = True
            self._write(f"driftframe: compiling the physics kernels for this machine: the first run only "
                        f"(they are cached in {cache_dir()})\n")
        line = f"driftframe: compiling {self.watch.line()}"
        now = time.monotonic()
        if not self.tty:
            # a log file or a pipe (CI): a whole line at most every LOG_EVERY s, and the last state at the end
            if ": " in line.rsplit(" kernels, ", 1)[-1]:
                self.named = line                         # the latest state that names its kernel
            if force:
                line = self.named or line
            if force or now - self.last[1] >= self.LOG_EVERY:
                if line != self.last[0]:
                    self._write(line + "\n")
                self.last = (line, now)
            return
        if line != self.last[0] or now - self.last[1] >= 1.0:
            self._write("\r" + line.ljust(self.width))     # spaces over a longer previous line
            self.width = len(line)
            self.last = (line, now)

    def end(self, stopped: bool) -> None:
        if not self.enabled:
            return
        self.tick(force=True)
        if not self.announced:
            return
        seconds, n, m = self.watch.elapsed(), self.watch.n, self.watch.m
        if self.tty:
            self._write("\n")                             # end the line rewritten in place
        if stopped:
            self._write(f"driftframe: stopped after {seconds:.0f} s of compiling kernels: those finished are "
                        f"cached, the rest are compiled on the next run ({n} of {m} begun)\n")
        else:
            self._write(f"driftframe: compiled {n} kernels in {seconds:.0f} s; "
                        "later runs load them from the cache\n")
