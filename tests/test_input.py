"""Input mapping and scripted tracks: held actions, presses fired exactly once, bad tracks rejected."""
import esper
import numpy as np
import pytest

from driftframe.components.body import Acceleration, AngularVelocity, Transform, Velocity
from driftframe.components.control import FlightControl, FlightInput, Player
from driftframe.framework.input import KEYMAP, HELD, PRESSED, Hold, Press, Track, intent_from_held, keys_help
from driftframe.systems.control import ControlSystem
from driftframe.systems.input import InputSystem
from driftframe.systems.movement import MovementSystem


def test_opposite_keys_cancel_and_kill_rotation_is_a_flag():
    assert intent_from_held({"thrust_forward", "thrust_back"})["throttle"] == 0.0
    got = intent_from_held({"pitch_up", "yaw_right", "kill_rotation"})
    assert got["pitch"] == -1.0 and got["yaw"] == 1.0 and got["kill_rotation"] is True


def test_every_action_has_a_key_and_the_help_lists_them():
    assert set(KEYMAP) == set(HELD) | set(PRESSED)
    text = keys_help()
    for keys in KEYMAP.values():
        assert " / ".join(keys) in text


def test_track_holds_are_half_open_and_add_then_clamp():
    tr = Track((Hold(1.0, 2.0, throttle=0.7), Hold(1.5, 3.0, throttle=0.7, yaw=-0.5)))
    at = lambda t: tr.intent_at_step(round(t * 100), 0.01)  # noqa: E731
    assert at(0.99)["throttle"] == 0.0
    assert at(1.0)["throttle"] == 0.7
    assert at(1.5)["throttle"] == 1.0          # 1.4 clamped
    assert at(2.0)["throttle"] == 0.7 and at(2.0)["yaw"] == -0.5
    assert at(3.0)["yaw"] == 0.0
    assert tr.duration == 3.0


@pytest.mark.parametrize("dt", [1 / 100, 1 / 60, 1 / 64, 0.1])
def test_holds_cover_the_same_number_of_steps_at_any_start(dt):
    # half-second holds on every 1/100 s boundary: float times would give 29, 30 or 31 steps
    want = round(0.5 / dt)
    for k in range(1500):
        start = k * 0.01
        hold = Hold(start, start + 0.5, throttle=1.0)
        tr = Track((hold,))
        first = hold.steps(dt).start
        covered = sum(tr.intent_at_step(s, dt)["throttle"] == 1.0 for s in range(first - 2, first + want + 3))
        assert covered == want, (start, covered)


@pytest.mark.parametrize("dt", [1 / 60, 1 / 64, 1 / 30, 0.1])
def test_each_press_fires_exactly_once(dt):
    tr = Track(tuple(Press(t, "switch_camera") for t in (0.0, 0.1, 0.5, 1.0, 4.0, 2.3456)))
    fired = [len(tr.presses_at_step(k, dt)) for k in range(int(5 / dt) + 2)]
    assert sum(fired) == 6


def _piloted(world, track):
    inputs = InputSystem(track)
    for s in (inputs, ControlSystem(), MovementSystem()):
        world.add_system(s)
    e = world.create_entity(Player(), FlightInput(), FlightControl(thrust=2.0), Transform(), Velocity(),
                            AngularVelocity(), Acceleration())
    return e, inputs


def test_a_scripted_track_flies_the_player(world):
    e, _ = _piloted(world, Track((Hold(0.0, 1.0, throttle=1.0),)))
    world.step(120)
    np.testing.assert_allclose(esper.component_for_entity(e, Velocity).linear, [0, 0, 2.0], atol=1e-12)
    assert esper.component_for_entity(e, FlightInput).throttle == 0.0


def test_live_keys_and_presses_go_through_the_same_path(world):
    e, inputs = _piloted(world, None)
    calls = []
    inputs.handlers["pause"] = lambda w: calls.append(w.step_count)
    inputs.held.add("thrust_forward")
    inputs.press("pause")
    world.step(60)
    assert calls == [0]
    np.testing.assert_allclose(esper.component_for_entity(e, Velocity).linear, [0, 0, 2.0], atol=1e-12)
    with pytest.raises(ValueError, match="'warp'"):
        inputs.press("warp")


@pytest.mark.parametrize("make,match", [
    (lambda: Hold(2.0, 1.0), "end must be after"),
    (lambda: Hold(0.0, 1.0, yaw=2.0), r"FlightInput.yaw must be in \[-1.0, 1.0\], got 2.0"),
    (lambda: Hold(0.0, 1.0, warp=1.0), r"unknown channel 'warp'"),
    (lambda: Hold(-1.0, 1.0), r"Hold.start"),
    (lambda: Press(1.0, "fly"), "'fly'"),
    (lambda: Track(("x",)), "Hold or Press"),
])
def test_bad_track_entries_are_rejected_by_name(make, match):
    with pytest.raises((ValueError, TypeError), match=match):
        make()
