"""The sound card for ``play``: blocks of samples from the world's soundtrack, played through miniaudio.

Why miniaudio (the ``miniaudio`` package, bindings to the single-file C
library of that name): its wheels carry the whole library, with every
Linux, macOS and Windows back end (PulseAudio, ALSA, JACK, Core Audio,
WASAPI) found at run time, so nothing else is installed and nothing opens
a second window or event loop; pyglet.media would bring a windowing
library beside glfw and needs OpenAL or PulseAudio installed apart.

:class:`Speaker` takes float32 mono blocks (:mod:`framework.audio`) from
the window's frame loop and hands them to the device's callback through a
short queue: at most :data:`MAX_QUEUED` seconds are held (older ones are
dropped, so sound never lags the picture), and an empty queue plays
silence. Where no device can be opened (a server, a container: no sound
card) :func:`open_speaker` prints one line and returns None; play goes on
silently.
"""
from __future__ import annotations

import os
import sys
import threading
from contextlib import contextmanager

import numpy as np

from driftframe.framework.audio import RATE

#: Seconds of sound held for the device at most; more and the oldest samples are dropped.
MAX_QUEUED = 0.25


@contextmanager
def _quiet_stderr():
    """C libraries' own messages on fd 2 (ALSA lists every card it did not find) hidden for a moment."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        yield
        return
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 2)
        os.close(devnull)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


class Speaker:
    """A playback device fed with blocks of samples; ``feed(samples)``, ``close()``."""

    def __init__(self, device):
        self._device = device
        self._lock = threading.Lock()
        self._queue = np.zeros(0, np.float32)
        #: Samples dropped because the queue was full, and samples of silence played for want of any.
        self.dropped = 0
        self.starved = 0
        gen = self._pull()
        next(gen)
        device.start(gen)

    def _pull(self):
        required = yield b""
        while True:
            with self._lock:
                out = self._queue[:required]
                self._queue = self._queue[required:]
            if len(out) < required:
                self.starved += required - len(out)
                out = np.concatenate([out, np.zeros(required - len(out), np.float32)])
            required = yield out.tobytes()

    def feed(self, samples) -> None:
        """Queue ``samples`` (float32 mono at :data:`framework.audio.RATE` Hz) to be played next."""
        limit = int(MAX_QUEUED * RATE)
        with self._lock:
            q = np.concatenate([self._queue, np.asarray(samples, np.float32)])
            if len(q) > limit:
                self.dropped += len(q) - limit
                q = q[-limit:]
            self._queue = q

    def close(self) -> None:
        """Stop and close the device. Safe to call twice."""
        if self._device is not None:
            self._device.close()
            self._device = None


def open_speaker(*, quiet: bool = False) -> Speaker | None:
    """A :class:`Speaker` on the default output device, or None (one line on stderr says why)."""
    try:
        import miniaudio
    except ImportError:
        if not quiet:
            print("driftframe: no sound: the miniaudio package is not installed (pip install miniaudio)",
                  file=sys.stderr)
        return None
    try:
        with _quiet_stderr():
            device = miniaudio.PlaybackDevice(output_format=miniaudio.SampleFormat.FLOAT32, nchannels=1,
                                              sample_rate=RATE, buffersize_msec=40, app_name="driftframe")
        return Speaker(device)
    except miniaudio.MiniaudioError as e:
        if not quiet:
            print(f"driftframe: no sound: no audio output device ({e.args[0] if e.args else e}); "
                  "playing on silently", file=sys.stderr)
        return None
