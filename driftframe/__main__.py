"""``python -m driftframe`` and the ``driftframe`` command: the command line (see :mod:`driftframe.cli`).

:func:`run` is the entry point. It loads the command line with Ctrl-C noted, so a Ctrl-C while those
modules load (the first tens of ms) is one line and 130 whatever it interrupted (numpy turns an
interrupted import of its own into an ImportError), not a traceback; :func:`driftframe.cli.main` then
takes the stop signals for the command itself, and a compile a signal stopped ends the process at once
(:func:`driftframe.cli_compile.exit_if_compiling`)."""
import signal
import sys


def run() -> int:
    got: list[int] = []

    def stop(signum, frame):
        got.append(signum)
        raise KeyboardInterrupt

    before = signal.signal(signal.SIGINT, stop)
    try:
        from driftframe.cli import main
    except BaseException:
        if got:
            print("driftframe: interrupted (SIGINT)", file=sys.stderr)
            return 128 + signal.SIGINT
        raise
    finally:
        signal.signal(signal.SIGINT, before)
    from driftframe.cli_compile import exit_if_compiling
    return exit_if_compiling(main())


if __name__ == "__main__":
    sys.exit(run())
