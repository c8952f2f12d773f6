"""FixedStepLoop: an injected clock drives whole fixed steps; frame rate never changes the physics."""
import numpy as np
import pytest

from driftframe.components.body import Transform, Velocity
from driftframe.framework.loop import FixedStepLoop
from driftframe.framework.world import World
from driftframe.systems.movement import MovementSystem


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def _run_with_frames(frame_times):
    w = World(dt=1 / 64)
    w.add_system(MovementSystem())
    w.create_entity(Transform(), Velocity((1.0, 0.5, 0)))
    clock = FakeClock()
    loop = FixedStepLoop(w, clock, max_steps=1000)
    for ft in frame_times:
        clock.t += ft
        loop.tick()
    h, n = w.state_hash(), w.step_count
    w.close()
    return h, n


def test_steps_follow_elapsed_time_in_whole_dt():
    w = World(dt=0.25)
    clock = FakeClock()
    loop = FixedStepLoop(w, clock)
    clock.t = 0.6
    assert loop.tick() == 2
    assert loop.alpha == pytest.approx(0.4)
    clock.t = 0.75
    assert loop.tick() == 1
    w.close()


def test_uneven_frame_rates_give_the_same_physics():
    rng = np.random.default_rng(1)
    # 2 s of frames at a steady 60 Hz vs. jittery 15-200 Hz: same number of steps, same state
    steady = [1 / 64] * 128
    jitter = list(rng.uniform(1 / 200, 1 / 15, 400))
    jitter = [t * 2.0 / sum(jitter) for t in jitter]
    a, na = _run_with_frames(steady)
    b, nb = _run_with_frames(jitter + [1e-9])
    assert na == nb == 128
    assert a == b


def test_a_long_stall_is_capped_and_counted():
    w = World(dt=0.1)
    clock = FakeClock()
    loop = FixedStepLoop(w, clock, max_steps=5)
    clock.t = 10.0
    assert loop.tick() == 5
    assert loop.dropped_steps == 95
    w.close()


def test_pause_stops_stepping():
    w = World(dt=0.1)
    clock = FakeClock()
    loop = FixedStepLoop(w, clock)
    loop.paused = True
    clock.t = 1.0
    assert loop.tick() == 0 and w.step_count == 0
    w.close()


def test_bad_clock_and_backwards_time_are_errors():
    w = World()
    with pytest.raises(TypeError, match="clock"):
        FixedStepLoop(w, 5.0)
    clock = FakeClock()
    clock.t = 1.0
    loop = FixedStepLoop(w, clock)
    clock.t = 0.5
    with pytest.raises(ValueError, match="backwards"):
        loop.tick()
    w.close()
