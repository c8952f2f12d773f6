"""The ``driftframe`` command line: list the demos, record one off-screen, or fly one in a window.

Every error a user can cause (an unknown demo, a bad size, an unwritable
path, an existing output, no display) ends in one line on stderr and exit
status 2, never a traceback. A write that fails while recording (a full
disk) is one line and exit status 1. A recording stopped by Ctrl-C, SIGTERM
or SIGHUP keeps the frames written so far and exits with 128 + the signal's
number (130, 143, 129), as the shell reports a process the signal killed;
``play`` keeps its track and hash log the same way (and exits 1 when the X
server goes away). Every output is written whole or not at all
(:mod:`framework.output`) and checked before the costly part starts.

The parser is :mod:`driftframe.cli_parser`; ``record`` and ``play`` are
:mod:`driftframe.cli_scene`; compiling the kernels with a progress line
(and ``warm``) is :mod:`driftframe.cli_compile`. This module runs a command
and turns its errors into one line and an exit status.
"""
from __future__ import annotations

import signal
import sys

try:
    from driftframe.cli_compile import _compile, cmd_warm
    from driftframe.cli_parser import UsageError, build_parser
    from driftframe.cli_scene import MAX_FRAMES, MAX_STEPS, cmd_play, cmd_record, demo_dt, frame_count, steps_per_frame
except KeyboardInterrupt:
    # Ctrl-C while the command line's modules load (its first tens of ms, before main() takes the stop
    # signals): nothing is touched yet; one line and 130, not a traceback out of the entry point's import
    print("driftframe: interrupted (SIGINT)", file=sys.stderr)
    raise SystemExit(128 + signal.SIGINT) from None

# the names other modules and tests take from here (the parser, the compile, the record/play checks)
__all__ = ["MAX_FRAMES", "MAX_STEPS", "UsageError", "build_parser", "demo_dt", "frame_count", "main",
           "steps_per_frame", "_compile"]


def cmd_list(args) -> int:
    from driftframe import demos
    width = max(map(len, demos.NAMES))
    for name in demos.NAMES:
        print(f"{name:<{width}}  {demos.load(name).DESCRIPTION}")
    return 0


def cmd_keys(args) -> int:
    from driftframe.framework.bindings import bindings_toml, load_bindings
    print(bindings_toml(load_bindings(args.bindings) if args.bindings else None), end="")
    return 0


def cmd_diverge(args) -> int:
    from driftframe.framework.hashlog import count_steps, first_divergence
    d = first_divergence(args.log_a, args.log_b)
    if d is None:
        print(f"the logs agree for all {count_steps(args.log_a)} steps")
        return 0
    print(d)
    return 1


def cmd_batch(args) -> int:
    from driftframe.batch_command import cmd_batch as run
    return run(args)


def cmd_new(args) -> int:
    from driftframe.scaffold import ScaffoldError, new
    try:
        root = new(args.name)
    except ScaffoldError as e:
        raise UsageError(str(e)) from None
    print(f"wrote {root}/. Fly it:\n    cd {root}\n    driftframe play {args.name}.scene:build\n"
          f"    driftframe record {args.name}.scene:build -o out/{args.name}.mp4\n    python -m pytest")
    return 0


class _SignalsInterrupt:
    """SIGTERM and SIGHUP raise an interrupt while a command runs, as Ctrl-C does (where they are not ignored).

    The parts that stop gracefully (recording, playing, compiling) take them
    over with :class:`~framework.recorder.StopSignals`; anywhere else a signal
    ends the command with one line and exit status 128 + n instead of
    killing it without a word.
    """

    def __enter__(self):
        import threading

        from driftframe.framework.stop_signals import STOP_SIGNALS, raise_interrupted    # light: no numpy
        self._old = {}
        if threading.current_thread() is threading.main_thread():
            for s in STOP_SIGNALS:
                if signal.getsignal(s) is signal.SIG_DFL:
                    self._old[s] = signal.signal(s, raise_interrupted)
        return self

    def __exit__(self, *exc):
        for s, old in self._old.items():
            signal.signal(s, old)


def _shell_words(e) -> str:
    """A library message in the command line's words: the library says ``pass overwrite=True (--overwrite)``
    for both; on the command line only the option means anything."""
    return (str(e).replace("pass overwrite=True (--overwrite)", "pass --overwrite")
            .replace("pass --overwrite (overwrite=True)", "pass --overwrite")
            .replace("pass overwrite=True", "pass --overwrite"))


def main(argv: list[str] | None = None) -> int:
    # SIGTERM and SIGHUP end in one line from the start: the imports in _main take a tenth of a second
    with _SignalsInterrupt():
        return _main(argv)


def _main(argv: list[str] | None) -> int:
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 0
        from driftframe.framework.gl import GLUnavailableError
        from driftframe.framework.kernels import KernelCompileError
        from driftframe.framework.recorder import RecordingError
    except KeyboardInterrupt as e:         # a signal while the modules load: nothing touched yet, no traceback
        signum = getattr(e, "signum", signal.SIGINT)
        print(f"driftframe: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
        return 128 + signum

    handlers = {"list": cmd_list, "record": cmd_record, "play": cmd_play, "keys": cmd_keys,
                "diverge": cmd_diverge, "batch": cmd_batch, "warm": cmd_warm,
                "new": cmd_new}
    try:
        return handlers[args.command](args)
    except UsageError as e:
        print(f"driftframe: error: {_shell_words(e)}", file=sys.stderr)
        return 2
    except (RecordingError, KernelCompileError) as e:
        print(f"driftframe: error: {_shell_words(e)}", file=sys.stderr)
        return 1
    except GLUnavailableError as e:
        print(f"driftframe: error: {e}", file=sys.stderr)
        return 2
    except (ValueError, LookupError, OSError) as e:
        # raised by the library's own input checks: they name the bad value; no traceback needed
        print(f"driftframe: error: {_shell_words(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as e:
        # Ctrl-C, or SIGTERM / SIGHUP turned into an interrupt by the recorder: exit as the signal would
        signum = getattr(e, "signum", signal.SIGINT)
        print(f"driftframe: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
        return 128 + signum


if __name__ == "__main__":
    from driftframe.__main__ import run      # the entry point's ending: a late signal is 128 + n too
    sys.exit(run())
