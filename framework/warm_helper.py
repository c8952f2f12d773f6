"""Compiling part of the warm-up in a second process, so that a cold compile uses two cores.

numba compiles on one thread, and a process compiles one kernel at a time.
:func:`framework.kernels.warm` given several parts runs the first in its own
process and the others here, in a helper process it starts with
:func:`start`; both write the same cache folder, which is safe: each cache
entry is saved beside its key, and one that another process overwrote is
compiled again, never loaded (:mod:`.kernel_cache`).

The helper tells the parent what it compiles, one line each on its stdout:
``+ contact_solve.solve_listed`` when one of driftframe's kernels starts
compiling (nested ones too) and ``-`` when it ends, so that the parent's
progress line counts them. It ends itself when the parent goes: at end of
file on its stdin (the parent's end closes the pipe, whatever ended it) and
on a stop signal, at once and quietly (numba writes each cache file under a
temporary name and renames it when whole; a later warm removes the rest).
It also inherits the parent's lock on the cache folder's ``warm.lock``
(flock belongs to the open file, which the helper shares), so that the next
warm cannot start while a helper left over from a stopped one still writes.

Run as ``python -m driftframe.framework.warm_helper module:function ...``.
"""
from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import threading


def start(parts, lock_fd: int | None) -> subprocess.Popen:
    """Start a helper that calls each of ``parts`` (module-level functions) in turn; ``lock_fd``: the
    parent's open, locked ``warm.lock`` (shared with the helper), or None."""
    names = []
    for part in parts:
        name = f"{part.__module__}:{part.__qualname__}"
        if "<" in name:
            raise ValueError(f"a warm-up part must be a module-level function for a helper process: {name}")
        names.append(name)
    fds = (lock_fd,) if lock_fd is not None else ()
    return subprocess.Popen([sys.executable, "-m", __name__, *names], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, pass_fds=fds,
                            start_new_session=False)


def relay(helper: subprocess.Popen, watch) -> None:
    """Read the helper's lines until it ends, telling ``watch`` (a ``CompileWatch`` or None) each compile."""
    for line in helper.stdout:
        if watch is None:
            continue
        if line.startswith("+ "):
            watch.elsewhere(line[2:].strip())
        elif line.startswith("-"):
            watch.elsewhere(None)


def stop(helper: subprocess.Popen) -> None:
    """End the helper (if it still runs) and wait for it."""
    if helper.poll() is None:
        helper.terminate()
    try:
        helper.wait(timeout=30)
    except subprocess.TimeoutExpired:
        helper.kill()
        helper.wait()


def _main(names: list[str]) -> int:
    def gone(*_):
        os._exit(1)

    for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", signal.SIGTERM)):
        signal.signal(s, gone)

    def watch_parent():
        sys.stdin.read()          # returns at end of file: the parent closed the pipe or ended
        os._exit(1)

    threading.Thread(target=watch_parent, daemon=True).start()
    from numba.core import event

    from driftframe.framework import kernels

    ours = {id(d) for d in kernels.registry()}
    out = sys.stdout

    class _Tell(event.Listener):
        def on_start(self, ev):
            d = ev.data["dispatcher"]
            if id(d) in ours:
                out.write(f"+ {kernels.kernel_name(d)}\n")
                out.flush()

        def on_end(self, ev):
            if id(ev.data["dispatcher"]) in ours:
                out.write("-\n")
                out.flush()

    event.register("numba:compile", _Tell())
    for name in names:
        module, _, function = name.partition(":")
        getattr(importlib.import_module(module), function)()
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
