"""Sound synthesised from what happens: impacts and thrust, sample-exactly, with numpy only.

A :class:`Soundtrack` collects *cues* as the simulation makes them (an impact
at a simulated time, the thrust level at the end of a frame) and turns them
into mono float32 samples at :data:`RATE` Hz, one block per presented frame:
:meth:`Soundtrack.take` ``(n, t_end)`` mixes the ``n`` samples that stand for
the simulated interval since the last block, ending at ``t_end``. A cue at
simulated time ``t`` starts at sample ``round(n (t - t_start) / (t_end -
t_start))`` of its block, so time warp and several steps per frame squeeze
the sounds into the frame as they squeeze the pictures, and the recorder and
the window feed the same blocks to an MP4 track or a sound card.

Nothing here reads a clock or a random generator at run time: the noise is
one fixed table (:data:`NOISE`, from a constant seed), indexed by the
absolute sample number for the continuous thrust and from its start for an
impact. The same cues and block sizes give the same samples, bit for bit.

The sounds:

* **impact** ``(time, strength, size)``: ``strength`` is the closing speed the
  impulse took out, ``J (1/m_a + 1/m_b)`` (m/s); the loudness is
  ``min(1, (strength / 6 m/s)^0.6)``, at least 0.05, times :func:`hearing` of its
  distance from the listener (the camera). ``size`` (m, the smaller
  radius) sets the pitch: a thud at ``f0 = 90 Hz (1 m / size)^0.5`` (in
  [45, 700] Hz) gliding down from 1.6 f0 over 30 ms, decaying with time
  constant ``tau = 0.06 s + 0.05 s size`` (at most 0.3 s), plus a noise
  crack (time constant 12 ms) smoothed by a moving average whose length grows
  with the size (bigger bodies sound darker).
* **alert** ``(time, kind)``: the HUD's alerts, two short tones (:func:`alert`);
* **thrust** ``level`` in [0, 1]: a rumble of smoothed noise and a 42 Hz hum,
  its amplitude ramped linearly across each block from the last level to the
  new one (no clicks).

The mix is limited by ``tanh`` (no wrap-around clipping); at most
:data:`MAX_VOICES` impacts sound at once (the loudest are kept), so a billiard
break or a swarm costs a bounded amount of work.
"""
from __future__ import annotations

import functools
import math

import numpy as np

#: Samples per second of every block.
RATE = 48_000
#: Impacts sounding at once at most; a new one beyond it replaces the quietest.
MAX_VOICES = 12
#: The fixed noise table: 2^16 standard normal samples from a constant seed.
NOISE = np.random.default_rng(0x736F756E64).standard_normal(1 << 16).astype(np.float32)   # "sound"


def _smooth(x: np.ndarray, k: int) -> np.ndarray:
    """Moving average over ``k`` samples (a low-pass with its first zero at RATE / k Hz), same length."""
    if k <= 1:
        return x
    c = np.concatenate([[0.0], np.cumsum(x, dtype=np.float64)])
    out = np.empty(len(x), np.float64)
    out[k:] = (c[k + 1:] - c[1:len(x) - k + 1]) / k
    out[:k] = c[1:k + 1] / k
    return out


def impact(strength: float, size: float, distance: float = 0.0) -> np.ndarray:
    """The samples of one impact (float32, starting at its contact), heard ``distance`` m away: see the
    module docstring."""
    gain = max(0.05, min(1.0, (max(strength, 0.0) / 6.0) ** 0.6)) * hearing(distance)
    size = min(max(size, 0.01), 1000.0)
    f0 = min(700.0, max(45.0, 90.0 / math.sqrt(size)))
    tau = min(0.3, 0.06 + 0.05 * size)
    n = int(RATE * 5 * tau) + 1                        # to exp(-5): -43 dB
    t = np.arange(n) / RATE
    # phase of a glide f(t) = f0 (1 + 0.6 exp(-t / 0.03)): the integral of 2 pi f
    phase = 2 * np.pi * f0 * (t + 0.6 * 0.03 * (1.0 - np.exp(-t / 0.03)))
    thud = np.sin(phase) * np.exp(-t / tau)
    k = int(min(64, 2 + 6 * size))
    crack = _smooth(NOISE[:n].astype(np.float64), k) * np.exp(-t / 0.012) * math.sqrt(k) * 0.5
    return (gain * (0.7 * thud + 0.3 * crack)).astype(np.float32)


#: HUD alerts: a warning (the warp dropped, the camera's target lost) falls, a job done (the autopilot
#: arrived or finished a burn) rises.
ALERTS = ("warning", "done")


@functools.lru_cache(maxsize=len(ALERTS))
def alert(kind: str) -> np.ndarray:
    """Two 90 ms sine tones a fifth apart (A5 and D5), 5 ms fades, at 0.35: falling for ``"warning"``,
    rising for ``"done"``."""
    n = int(0.09 * RATE)
    t = np.arange(n) / RATE
    fade = np.minimum(1.0, np.minimum(t, t[::-1]) / 0.005)
    hi, lo = 880.0, 587.33
    pair = (hi, lo) if kind == "warning" else (lo, hi)
    tones = [np.sin(2 * np.pi * f * t) * fade for f in pair]
    out = 0.35 * np.concatenate([tones[0], np.zeros(int(0.03 * RATE)), tones[1]])
    out = out.astype(np.float32)
    out.flags.writeable = False
    return out


def hearing(distance: float) -> float:
    """How much of an impact's loudness reaches an ear ``distance`` m away: all of it within 10 m, then
    ``1 / (1 + (d - 10 m) / 30 m)`` (a half at 40 m, a third at 70 m): far hits are quieter, never silent."""
    return 1.0 / (1.0 + max(0.0, float(distance) - 10.0) / 30.0)


class Soundtrack:
    """Cues in simulated time, mixed into blocks of samples (see the module docstring).

    ``t0``: the simulated time the first block starts at (s). ``impact(time,
    strength, size)`` and ``thrust(level)`` add cues; ``take(n, t_end)``
    returns the next ``n`` samples (float32 in (-1, 1)) for the interval up to
    ``t_end``. ``samples``: samples given so far.
    """

    #: A world's soundtrack is ``world.resources[Soundtrack]``; a save does not hold it (a recording or a
    #: window makes its own).
    published_by = "driftframe.systems.sound.attach (attach_rendering adds it)"
    saved = False

    def __init__(self, t0: float = 0.0):
        self._t = float(t0)
        # (time, 0, strength, size, distance) | (time, 1, alert, 0, 0), this block
        self._pending: list[tuple[float, int, float, float, float]] = []
        self._voices: list[list] = []                          # [samples, position, loudness]
        self._level = 0.0                                      # thrust at the end of the last block
        self._next_level = 0.0
        self.samples = 0

    def impact(self, time: float, strength: float, size: float, distance: float = 0.0) -> None:
        """An impact at simulated ``time`` (s), closing speed ``strength`` (m/s), smaller radius ``size`` (m),
        ``distance`` m from the listener (:func:`hearing`)."""
        if all(math.isfinite(v) for v in (time, strength, size, distance)):
            self._pending.append((float(time), 0, float(strength), float(size), float(distance)))

    def alert(self, time: float, kind: str) -> None:
        """A HUD alert at simulated ``time``: ``"warning"`` (two falling tones) or ``"done"`` (two rising)."""
        if kind not in ALERTS:
            raise ValueError(f"alert kind must be one of {', '.join(ALERTS)}, got {kind!r}")
        self._pending.append((float(time), 1, float(ALERTS.index(kind)), 0.0, 0.0))

    def thrust(self, level: float) -> None:
        """The engine's level in [0, 1] at the end of the block being made."""
        self._next_level = min(1.0, max(0.0, float(level)))

    def take(self, n: int, t_end: float) -> np.ndarray:
        """The next ``n`` samples, standing for simulated time from the last block's end to ``t_end``."""
        n = int(n)
        out = np.zeros(n, np.float64)
        span = float(t_end) - self._t
        # this block's impacts, in time order (ties by strength, size: the same order on every run)
        for time, what, a, b, d in sorted(self._pending):
            at = 0 if span <= 0 else min(n - 1, max(0, round(n * (time - self._t) / span)))
            voice = impact(a, b, d) if what == 0 else alert(ALERTS[int(a)])
            self._voices.append([voice, -at, float(np.abs(voice).max())])
        self._pending.clear()
        if len(self._voices) > MAX_VOICES:                     # keep the loudest; stable, so ties keep order
            keep = sorted(range(len(self._voices)), key=lambda i: -self._voices[i][2])[:MAX_VOICES]
            self._voices = [self._voices[i] for i in sorted(keep)]
        alive = []
        for voice in self._voices:
            samples, pos = voice[0], voice[1]                  # pos < 0: starts -pos samples into the block
            start = max(0, -pos)
            a = max(0, pos)
            m = min(n - start, len(samples) - a)
            if m > 0:
                out[start:start + m] += samples[a:a + m]
            voice[1] = pos + n
            if voice[1] < len(samples):
                alive.append(voice)
        self._voices = alive
        if self._level > 0 or self._next_level > 0:
            out += self._rumble(n)
        self._level = self._next_level
        self._t = float(t_end)
        self.samples += n
        return np.tanh(out).astype(np.float32)

    def _rumble(self, n: int) -> np.ndarray:
        """Thrust for the next ``n`` samples: continuous across blocks (noise and hum by absolute sample)."""
        k = 24                                            # smoothing: first zero at 2 kHz
        idx = (np.arange(self.samples - k, self.samples + n)) % len(NOISE)
        noise = _smooth(NOISE[idx].astype(np.float64), k)[k:] * math.sqrt(k) * 0.5
        t = (self.samples + np.arange(n)) / RATE
        hum = np.sin(2 * np.pi * 42.0 * t)
        ramp = self._level + (self._next_level - self._level) * (np.arange(1, n + 1) / n)
        return 0.35 * ramp * (0.7 * noise + 0.5 * hum)


def frame_samples(fps, k: int) -> int:
    """Samples of frame ``k`` at ``fps`` frames/s (an int or a Fraction): frame ``k`` ends at sample
    ``floor((k + 1) RATE / fps)``, in exact rational arithmetic, so the blocks add up to the length."""
    from fractions import Fraction

    fps = Fraction(fps)
    return math.floor((k + 1) * RATE / fps) - math.floor(k * RATE / fps)
