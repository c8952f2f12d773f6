"""The fixed-step loop: a variable frame rate drives a fixed simulation step.

Each frame, the time that passed on the injected ``clock`` goes into an
accumulator; whole steps of ``world.dt`` are taken out of it::

    acc += clock() - last
    while acc >= dt:  world.step();  acc -= dt

so a slow frame runs more steps and never a longer one: the physics is the
same at any frame rate. The simulation itself never reads a clock; the clock
is passed in (``time.perf_counter`` in a window, a hand-driven function in
tests). What is left in the accumulator, ``alpha = acc / dt`` in [0, 1), is
how far the present lies between the last step and the next: the window
draws poses interpolated by it (:mod:`systems.interpolation`).

The spiral of death, and how the loop avoids it: when one step costs more
wall time than ``dt``, catching up is impossible (each step taken adds more
than ``dt`` of debt), and a loop that keeps trying runs ``max_steps`` steps in
every frame and its frame rate collapses (8 steps of 20 ms: 6 fps). A step
just under ``dt`` does the same in practice: the frame's own drawing time
must be caught up too, ``n = t_draw / (dt - t_step)`` steps a frame, which
hits ``max_steps`` (8 steps of 14 ms and 50 ms to draw: 6 fps). Like bevy's
``Time<Virtual>::max_delta``, this loop *drops time* instead, and says so:

* a frame longer than ``max_delta`` (a debugger, a dragged window) counts as
  ``max_delta``;
* stepping may take at most ``max_step_time`` of wall time per frame: with the
  measured cost of a step (the median over the last 9 frames that stepped),
  a frame takes ``max(1, max_step_time // cost)`` steps at most (one step of
  20 ms, two of 14 ms) and the rest of the debt is dropped: the simulation
  runs slower than real time, at a frame rate that stays usable;
* never more than ``max_steps`` steps in one frame.

``dropped_steps`` / ``dropped_seconds`` count what was dropped, ``behind``
says whether the loop is dropping time now, and ``speed`` is simulated
seconds per wall second over the recent frames (1.0 when it keeps up).

Time warp (:mod:`framework.warp`) multiplies the steps each owed step
becomes: at warp ``W`` a frame that owes ``k`` steps runs ``k W`` of them, all
of the same ``dt``.
"""
from __future__ import annotations

import collections
import statistics
from typing import Callable

from driftframe.framework import validate
from driftframe.framework import warp as time_warp
from driftframe.framework.world import FRAME_STAGES, STEP_STAGES, World


class FixedStepLoop:
    """Drive ``world.step()`` from a clock. ``tick()`` once per presented frame.

    ``max_steps``: most steps in one frame. ``max_delta``: longest frame
    counted, seconds (None: no limit). ``max_step_time``: most wall seconds of
    stepping per frame (by the measured step cost; at least one step is
    always taken). ``drop_when_behind=False``: no step-time limit, the old
    behaviour (``max_steps`` a frame), kept as the benchmark's baseline.
    """

    #: The step cost is the median over this many recent frames (one slow frame, a GC pause or the
    #: first step's compilation, does not make the loop drop time).
    COST_FRAMES = 9

    def __init__(self, world: World, clock: Callable[[], float], *, max_steps: int = 8, max_delta: float | None = 0.25,
                 max_step_time: float = 1.0 / 30.0, drop_when_behind: bool = True):
        validate.function("clock", clock, what="a function returning seconds")
        if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
            raise ValueError(f"max_steps must be an int >= 1, got {max_steps!r}")
        if max_delta is not None:
            max_delta = validate.scalar("max_delta", max_delta, positive=True)
        self.world = world
        self.clock = clock
        self.max_steps = max_steps
        self.max_delta = max_delta
        self.max_step_time = validate.scalar("max_step_time", max_step_time, positive=True)
        self.drop_when_behind = bool(drop_when_behind)
        self.accumulator = 0.0
        self.paused = False
        #: Steps dropped: debt beyond max_steps, or beyond one step while behind.
        self.dropped_steps = 0
        #: Wall seconds not simulated (frames beyond max_delta, dropped steps), seconds.
        self.dropped_seconds = 0.0
        #: Median wall time of one step over the last COST_FRAMES frames that stepped, seconds.
        self.step_cost = 0.0
        self._costs: collections.deque = collections.deque(maxlen=self.COST_FRAMES)
        #: Frames (ticks) so far.
        self.frames = 0
        self._recent = collections.deque(maxlen=120)     # (wall seconds, simulated seconds) per tick
        self._limited = collections.deque(maxlen=self.COST_FRAMES)   # did the step-time limit drop debt?
        self._last = validate.scalar("clock()", clock())

    @property
    def behind(self) -> bool:
        """True while the step-time limit drops debt (in at least 3 of the last 9 frames): slow motion."""
        return sum(self._limited) >= 3

    @property
    def step_limit(self) -> int:
        """Most steps the next frame may take: ``max_step_time // step_cost``, in [1, max_steps]."""
        if not self.drop_when_behind or len(self._costs) < 3 or self.step_cost <= 0:
            return self.max_steps
        return max(1, min(self.max_steps, int(self.max_step_time / self.step_cost)))

    def tick(self) -> int:
        """Take as many whole steps as the elapsed time allows; return how many ran."""
        now = validate.scalar("clock()", self.clock())
        elapsed = now - self._last
        self._last = now
        if elapsed < 0:
            raise ValueError(f"clock went backwards by {-elapsed!r} s")
        self.frames += 1
        if self.paused:
            return 0
        dt = self.world.dt
        wall = elapsed
        if self.max_delta is not None and elapsed > self.max_delta:
            self.dropped_seconds += elapsed - self.max_delta
            elapsed = self.max_delta
        self.accumulator += elapsed
        # acc / dt rounded, then floored with a hair of tolerance: 10.0 // 0.1 is 99 in floats
        steps = int(self.accumulator / dt + 1e-9)
        limit = self.step_limit
        self._limited.append(steps > limit and limit < self.max_steps)
        if steps > limit:
            self.dropped_steps += steps - limit
            self.dropped_seconds += (steps - limit) * dt
            self.accumulator -= (steps - limit) * dt
            steps = limit
        if steps:
            t0 = self.clock()
            # time warp: each owed step becomes `factor` steps of the same dt (the same physics, sooner);
            # its cost counts as one owed step's, so at a warp the CPU cannot keep up with the loop
            # drops wall time as above instead of spiralling
            self.world.step(steps * time_warp.factor(self.world))
            self._costs.append((self.clock() - t0) / steps)
            self.step_cost = statistics.median(self._costs)
            self.accumulator = max(0.0, self.accumulator - steps * dt)
        self._recent.append((wall, steps * dt))
        return steps

    @property
    def alpha(self) -> float:
        """How far the present is between the last step and the next, in [0, 1)."""
        return min(self.accumulator / self.world.dt, 1.0 - 1e-12)

    @property
    def speed(self) -> float:
        """Simulated seconds per wall second over the last ~120 frames (1.0 when keeping up)."""
        wall = sum(w for w, _ in self._recent)
        return sum(s for _, s in self._recent) / wall if wall > 0 else 1.0


class FrameStats:
    """Frame rate and per-stage times over the last ``window`` seconds, for the overlay.

    ``frame(now, world)`` once per presented frame. ``fps`` is frames per
    second, ``worst_ms`` the longest frame; ``stage_ms`` the mean wall time of
    each stage (per step for the step stages, per frame for render/record),
    from ``world.profile_total`` differences over the window.
    """

    def __init__(self, window: float = 1.0):
        self.window = validate.scalar("window", window, positive=True)
        self._frames: collections.deque = collections.deque()     # (time, steps, frames, totals)
        self.fps = 0.0
        self.worst_ms = 0.0
        self.stage_ms: dict[str, float] = {}

    def frame(self, now: float, world, rendered: int = 1) -> None:
        totals = dict(world.profile_total)
        marks = self._frames
        marks.append((now, world.step_count, rendered, totals))
        while len(marks) > 2 and now - marks[1][0] >= self.window:
            marks.popleft()
        if len(marks) < 2:
            return
        t0, s0, _, tot0 = marks[0]
        span = now - t0
        n = len(marks) - 1
        self.fps = n / span if span > 0 else 0.0
        self.worst_ms = 1e3 * max(b[0] - a[0] for a, b in zip(marks, list(marks)[1:]))
        steps = world.step_count - s0
        out = {}
        for stage in STEP_STAGES + FRAME_STAGES:
            per = steps if stage in STEP_STAGES else n
            d = totals.get(stage, 0.0) - tot0.get(stage, 0.0)
            out[stage] = 1e3 * d / per if per else 0.0
        self.stage_ms = out
