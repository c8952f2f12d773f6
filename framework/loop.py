"""The fixed-step loop: a variable frame rate drives a fixed simulation step.

Each frame, the time that passed on the injected ``clock`` goes into an
accumulator; whole steps of ``world.dt`` are taken out of it::

    acc += clock() - last
    while acc >= dt:  world.step();  acc -= dt

so a slow frame runs more steps and never a longer one: the physics is the
same at any frame rate. The simulation itself never reads a clock; the clock
is passed in (``time.perf_counter`` in a window, a hand-driven function in
tests). After a very long stall (a debugger, a dragged window) at most
``max_steps`` are taken and the rest is dropped, so the loop cannot spiral.
"""
from __future__ import annotations

from typing import Callable

from driftframe.framework import validate


class FixedStepLoop:
    """Drive ``world.step()`` from a clock. ``tick()`` once per presented frame."""

    def __init__(self, world, clock: Callable[[], float], *, max_steps: int = 8):
        if not callable(clock):
            raise TypeError(f"clock must be a function returning seconds, got {clock!r}")
        if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
            raise ValueError(f"max_steps must be an int >= 1, got {max_steps!r}")
        self.world = world
        self.clock = clock
        self.max_steps = max_steps
        self.accumulator = 0.0
        self.paused = False
        #: Steps dropped because a frame took longer than max_steps * dt.
        self.dropped_steps = 0
        self._last = validate.scalar("clock()", clock())

    def tick(self) -> int:
        """Take as many whole steps as the elapsed time allows; return how many ran."""
        now = validate.scalar("clock()", self.clock())
        elapsed = now - self._last
        self._last = now
        if elapsed < 0:
            raise ValueError(f"clock went backwards by {-elapsed!r} s")
        if self.paused:
            return 0
        dt = self.world.dt
        self.accumulator += elapsed
        # acc / dt rounded, then floored with a hair of tolerance: 10.0 // 0.1 is 99 in floats
        steps = int(self.accumulator / dt + 1e-9)
        if steps > self.max_steps:
            self.dropped_steps += steps - self.max_steps
            self.accumulator -= (steps - self.max_steps) * dt
            steps = self.max_steps
        if steps:
            self.world.step(steps)
            self.accumulator = max(0.0, self.accumulator - steps * dt)
        return steps

    @property
    def alpha(self) -> float:
        """How far the present is between the last step and the next, in [0, 1)."""
        return self.accumulator / self.world.dt
