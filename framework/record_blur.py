"""Motion blur for recordings: each frame the integer average of N renders across the frame's interval.

The poses between fixed steps come from the caller's ``interpolate`` object
(e.g. :class:`driftframe.systems.motion_blur.SubframePoses`); the
simulation is not touched, and the poses are restored after each frame.
"""
from __future__ import annotations

from fractions import Fraction

import numpy as np

#: Most sub-frames averaged into one frame (their sum of 255s must fit the uint16 accumulator: 64 x 255).
MAX_MOTION_BLUR = 64
_POSES = ("start", "after_step", "pose", "restore")


def check_blur(motion_blur: int, interpolate) -> None:
    """A clear error for too many sub-frames, or an ``interpolate`` that cannot pose them."""
    if motion_blur > MAX_MOTION_BLUR:
        raise ValueError(f"motion_blur must be at most {MAX_MOTION_BLUR} sub-frames, got {motion_blur}")
    if motion_blur > 1:
        for method in _POSES:
            if not callable(getattr(interpolate, method, None)):
                raise TypeError("motion_blur needs interpolate=, an object with start/after_step/pose/restore "
                                f"(e.g. driftframe.systems.motion_blur.SubframePoses()), got {interpolate!r}")


def _blurred(world, target, poses, n: int, steps_per_frame: int):
    """A ``grab()`` that renders ``n`` sub-frames across the frame's interval and returns their average.

    Sub-frame ``j`` (0..n-1) shows the scene at fraction ``(j + 1) / n`` of
    the interval since the previous frame: the last one is the frame itself.
    Sums in uint16 (64 x 255 fits), then ``(sum + n // 2) // n`` in place:
    integer arithmetic, the same bytes on every run (uint16 rather than
    uint32: numpy divides it much faster; docs/design/recorder.md).
    """
    w, h = target.size
    acc = np.zeros(w * h * 4, np.uint16)
    half, count = np.uint16(n // 2), np.uint16(n)

    def grab():
        acc[:] = 0
        try:
            for j in range(n):
                poses.pose(world, Fraction(j + 1, n))
                world.render()
                np.add(acc, np.frombuffer(target.read_raw(), np.uint8), out=acc, casting="unsafe")
        finally:
            poses.restore(world)
        np.add(acc, half, out=acc)
        np.floor_divide(acc, count, out=acc)
        return acc.astype(np.uint8).tobytes()

    return grab
