"""FixedStepLoop: an injected clock drives whole fixed steps; frame rate never changes the physics;
a scene whose step costs more than dt drops time instead of collapsing."""
import numpy as np
import pytest

from driftframe.components.body import Transform, Velocity
from driftframe.framework.loop import FixedStepLoop, FrameStats
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
    loop = FixedStepLoop(w, clock, max_steps=1000, max_delta=None)
    for ft in frame_times:
        clock.t += ft
        loop.tick()
    h, n = w.state_hash(), w.step_count
    w.close()
    return h, n


def test_steps_follow_elapsed_time_in_whole_dt():
    w = World(dt=0.25)
    clock = FakeClock()
    loop = FixedStepLoop(w, clock, max_delta=None)
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
    loop = FixedStepLoop(w, clock, max_steps=5, max_delta=None)
    clock.t = 10.0
    assert loop.tick() == 5
    assert loop.dropped_steps == 95
    assert loop.dropped_seconds == pytest.approx(9.5)
    w.close()


def test_a_frame_longer_than_max_delta_counts_as_max_delta():
    # bevy's Time<Virtual>::max_delta: a 3 s stall (a debugger) advances the simulation 0.25 s, not 3 s
    w = World(dt=1 / 64)
    clock = FakeClock()
    loop = FixedStepLoop(w, clock, max_delta=0.25, max_steps=100)
    clock.t = 3.0
    assert loop.tick() == 16
    assert loop.dropped_seconds == pytest.approx(2.75)
    assert loop.dropped_steps == 0
    w.close()


class SlowStep:
    """A system whose step costs ``cost`` seconds on the fake clock (a heavy scene)."""
    stage = "collision"

    def __init__(self, clock, cost):
        self.clock, self.cost = clock, cost

    def process(self, dt):
        self.clock.t += self.cost


def _frames_per_second(step_cost, render_cost, drop_when_behind, seconds=10.0):
    """Run a window's frame loop on a fake clock; frames shown and steps taken in the last 5 s."""
    w = World(dt=1 / 60)
    clock = FakeClock()
    w.add_system(SlowStep(clock, step_cost))
    loop = FixedStepLoop(w, clock, drop_when_behind=drop_when_behind)
    frames, per_frame = 0, []
    while clock.t < seconds:
        n = loop.tick()
        clock.t += render_cost                      # drawing and presenting the frame
        if clock.t > seconds / 2:
            frames += 1
            per_frame.append(n)
    out = frames / (seconds / 2), max(per_frame), loop
    w.close()
    return out


def test_a_step_slower_than_dt_drops_time_instead_of_collapsing():
    # a 20 ms step at dt = 16.7 ms, 4 ms to draw a frame: catching up is impossible
    fps_old, most_old, old = _frames_per_second(0.020, 0.004, drop_when_behind=False)
    fps_new, most_new, new = _frames_per_second(0.020, 0.004, drop_when_behind=True)
    assert fps_old < 7.5 and most_old == 8             # the spiral: 8 steps of 20 ms in every frame
    assert fps_new > 40 and most_new == 1              # one step per frame: 1 / 24 ms
    assert new.behind and new.dropped_steps > 100      # and it says so
    assert new.step_limit == 1
    assert 0.6 < new.speed < 0.75                      # 41.7 steps/s of 60
    assert new.step_cost == pytest.approx(0.020)


def test_a_step_just_under_dt_with_slow_drawing_does_not_collapse_either():
    # 14 ms steps, 50 ms to draw: real time needs 50 / (16.7 - 14) = 19 steps a frame; the old loop
    # takes its 8 (162 ms frames), the new one 2 (78 ms frames: 33 ms of stepping at most)
    fps_old, most_old, _ = _frames_per_second(0.014, 0.050, drop_when_behind=False)
    fps_new, most_new, new = _frames_per_second(0.014, 0.050, drop_when_behind=True)
    assert most_old == 8 and fps_old < 6.5
    assert most_new == 2 and fps_new > 12
    assert new.behind and new.step_limit == 2


def test_a_fast_scene_keeps_real_time_and_drops_nothing():
    fps, _, loop = _frames_per_second(0.002, 0.004, drop_when_behind=True)
    assert fps > 150 and not loop.behind
    assert loop.dropped_steps == 0 and loop.dropped_seconds == 0.0
    assert loop.speed == pytest.approx(1.0, abs=0.05)          # +-1 step in the ~0.7 s it averages over


def test_one_slow_step_is_caught_up_not_dropped():
    # a single 120 ms hitch (a GC pause) among 1 ms steps: the loop catches up, the median cost stays low
    w = World(dt=1 / 60)
    clock = FakeClock()
    slow = w.add_system(SlowStep(clock, 0.001))
    loop = FixedStepLoop(w, clock)
    for k in range(300):
        slow.cost = 0.120 if k == 100 else 0.001
        loop.tick()
        clock.t += 1 / 60
    assert loop.dropped_steps == 0 and not loop.behind
    assert w.step_count == int(clock.t * 60 + 1e-9) or w.step_count == int(clock.t * 60) - 1
    w.close()


def test_alpha_is_the_fraction_of_a_step_left_over():
    w = World(dt=0.1)
    clock = FakeClock()
    loop = FixedStepLoop(w, clock)
    for t, want in ((0.05, 0.5), (0.1, 0.0), (0.18, 0.8), (0.2999, 0.999)):
        clock.t = t
        loop.tick()
        assert loop.alpha == pytest.approx(want, abs=1e-6)
        assert 0.0 <= loop.alpha < 1.0
    w.close()


def test_frame_stats_give_fps_worst_frame_and_stage_times():
    w = World(dt=0.01)
    stats = FrameStats(window=1.0)
    t = 0.0
    for k in range(200):
        w.step(2)
        w.profile_total["collision"] += 0.002 * 2      # 2 ms per step, booked as the world books it
        w.profile_total["render"] += 0.005
        t += 0.05 if k == 150 else 0.01
        stats.frame(t, w)
    assert stats.fps == pytest.approx(1 / 0.01, rel=0.1)
    assert stats.worst_ms == pytest.approx(50.0)
    assert stats.stage_ms["collision"] == pytest.approx(2.0)
    assert stats.stage_ms["render"] == pytest.approx(5.0)
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
