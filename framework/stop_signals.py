"""Stop signals: Ctrl-C, SIGTERM and SIGHUP end a recording (or a played session) between frames.

:class:`StopSignals` is what :func:`framework.recorder.record` and the
window's loop hold while they run; :func:`raise_interrupted` is what the
command line holds from its start, so a signal outside them still ends in
one line and exit status 128 + n.
"""
from __future__ import annotations

import signal
import threading

#: Signals that stop a recording the way Ctrl-C does (SIGINT arrives as KeyboardInterrupt).
STOP_SIGNALS = tuple(s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)) if s)


class Interrupted(KeyboardInterrupt):
    """A stop signal (SIGTERM, SIGHUP) during a recording: handled like Ctrl-C."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def raise_interrupted(signum, frame):
    """A signal handler: SIGTERM and SIGHUP raise :class:`Interrupted`, as Python's own does for SIGINT.

    The command line holds it from its start, so a signal before or between
    the parts that stop gracefully (:class:`StopSignals`, which takes over
    from it) still ends in one line and exit status 128 + n, not a silent
    death; :class:`StopSignals` treats it as the default.
    """
    raise Interrupted(signum)


class StopSignals:
    """While active (main thread only), Ctrl-C, SIGTERM and SIGHUP ask the recording to stop.

    The first one only sets :attr:`requested`: the loop stops at the end of
    the frame it is in, so no system, writer or GL call is cut off halfway
    (an exception raised at any bytecode could leave the world half-stepped).
    A second one raises :class:`Interrupted` at once, for a frame that never
    ends. Signals whose handler is not the default (ignored under ``nohup``,
    or the application's own) are left alone. The command line also holds
    one while a first run compiles its kernels (``driftframe/cli.py``).
    """

    def __init__(self, enabled: bool):
        self._old: dict = {}
        self.requested: int | None = None
        self.finishing = False
        self.enabled = enabled and threading.current_thread() is threading.main_thread()

    def _handle(self, signum, frame):
        if self.requested is not None and not self.finishing:
            raise Interrupted(signum)
        self.requested = self.requested or signum

    def finish(self) -> None:
        """From now on every signal only sets :attr:`requested`: the outputs are being written, which is
        short and bounded, and a second Ctrl-C must not cut the file it is meant to keep."""
        self.finishing = True

    def __enter__(self):
        if self.enabled:
            defaults = {signal.SIGINT: signal.default_int_handler}
            for s in (signal.SIGINT, *STOP_SIGNALS):
                # only where nobody chose otherwise: under nohup, SIGHUP stays ignored
                if signal.getsignal(s) in (defaults.get(s, signal.SIG_DFL), raise_interrupted):
                    self._old[s] = signal.signal(s, self._handle)
        return self

    def __exit__(self, *exc):
        for s, old in self._old.items():
            signal.signal(s, old)
        self._old.clear()


def signal_name(signum: int) -> str:
    """``"SIGTERM"`` for 15; ``"signal 99"`` for a number with no name."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"
