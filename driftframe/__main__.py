"""``python -m driftframe`` and the ``driftframe`` command: the command line (see :mod:`driftframe.cli`).

:func:`run` is the entry point. It loads the command line with Ctrl-C noted, so a Ctrl-C while those
modules load (the first tens of ms) is one line and 130 whatever it interrupted (numpy turns an
interrupted import of its own into an ImportError), not a traceback; :func:`driftframe.cli.main` then
takes the stop signals for the command itself, and a compile a signal stopped ends the process at once
(:func:`driftframe.cli_compile.exit_if_compiling`). A stop signal after the command's own handlers (the
command has finished: its last lines are out, the process is ending) is the same one line and 128 + n,
never a traceback nor a death by the signal (Python re-raises an uncaught Ctrl-C at exit: status -2)."""
import os
import signal
import sys


def _interrupted(signum: int) -> int:
    print(f"driftframe: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
    return 128 + signum


def _late(signum, frame):
    """A stop signal once the command has finished: end the process now, as 128 + n, with the one line.

    A signal handler, so it may run inside a write of the main thread's or in the interpreter's
    shutdown (atexit): it flushes what it can and writes its line straight to descriptor 2."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, RuntimeError):     # a closed pipe; a flush this handler interrupted
            pass
    try:
        os.write(2, f"driftframe: interrupted ({signal.Signals(signum).name})\n".encode())
    except OSError:
        pass
    os._exit(128 + signum)


def _ending() -> None:
    """From here to the process's end, Ctrl-C, SIGTERM and SIGHUP (where they have their default
    handlers: under nohup SIGHUP stays ignored) go to :func:`_late`."""
    defaults = {signal.SIGINT: signal.default_int_handler}
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        s = getattr(signal, name, None)
        if s is not None and signal.getsignal(s) is defaults.get(s, signal.SIG_DFL):
            signal.signal(s, _late)


def run() -> int:
    # One OpenBLAS thread for the command (and the processes it starts), set before numpy loads OpenBLAS: the
    # physics is numba's and numpy's BLAS calls here are small, while OpenBLAS's worker thread spins on the other
    # core after numpy's import and after each call it shares (perf: blas_thread_server). A value the user
    # set is kept.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    got: list[int] = []

    def stop(signum, frame):
        got.append(signum)
        raise KeyboardInterrupt

    before = signal.signal(signal.SIGINT, stop)
    try:
        from driftframe.cli import main
    except BaseException:
        if got:
            return _interrupted(signal.SIGINT)
        raise
    finally:
        signal.signal(signal.SIGINT, before)
    from driftframe.cli_compile import exit_if_compiling
    try:
        code = main()
        _ending()
    except KeyboardInterrupt as e:
        # between main()'s own handlers and _ending (main() restoring the handlers it took, returning)
        code = _interrupted(getattr(e, "signum", signal.SIGINT))
    return exit_if_compiling(code)


if __name__ == "__main__":
    sys.exit(run())
