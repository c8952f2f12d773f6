"""Input mapping and scripted tracks: held actions, presses fired exactly once, bad tracks rejected."""
import json

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


# -- compiled tracks, flown tracks, track files ---------------------------------------------------
from driftframe.framework.input import (CHANNELS, TrackFileError, TrackRecorder, load_track,  # noqa: E402
                                        save_track, step_index)


def _brute_intent(track, step, dt):
    """intent_at_step as defined: every hold covering the step, in track order, added then clamped."""
    out = {**dict.fromkeys(CHANNELS, 0.0), "kill_rotation": False}
    for ev in track.events:
        if isinstance(ev, Hold) and step in ev.steps(dt):
            for name, value in ev.channels.items():
                out[name] = max(-1.0, min(1.0, out[name] + value))
            out["kill_rotation"] |= ev.kill_rotation
    return out


def test_the_compiled_track_gives_the_defined_intent_for_overlapping_holds():
    rng = np.random.default_rng(7)
    holds = []
    for _ in range(60):
        s = float(rng.uniform(0, 5))
        ch = {c: float(rng.uniform(-1, 1)) for c in rng.choice(CHANNELS, rng.integers(1, 4), replace=False)}
        holds.append(Hold(s, s + float(rng.uniform(0.01, 1.5)), kill_rotation=bool(rng.random() < 0.2), **ch))
    tr = Track(tuple(holds))
    for dt in (1 / 60, 1 / 64):
        for step in range(int(7 / dt)):
            assert tr.intent_at_step(step, dt) == _brute_intent(tr, step, dt), step


def _fly(rng, steps):
    """A flight: keyboard-like runs of whole values and gamepad-like noisy ones, and some presses."""
    intents, presses = [], {}
    k = 0
    while k < steps:
        n = int(rng.integers(1, 40))
        if rng.random() < 0.5:        # keys: constant for a while (or nothing held)
            v = {c: float(rng.choice([-1.0, 0.0, 0.0, 1.0])) for c in CHANNELS}
            v["kill_rotation"] = bool(rng.random() < 0.2)
            intents += [dict(v) for _ in range(n)]
        else:                         # a stick: a new value every step
            for _ in range(n):
                v = {c: float(np.clip(rng.normal(0, 0.5), -1, 1)) for c in CHANNELS}
                intents.append({**v, "kill_rotation": False})
        k += n
        if rng.random() < 0.3:
            presses.setdefault(k, []).append("switch_camera")
    return intents[:steps], {s: p for s, p in presses.items() if s < steps}


@pytest.mark.parametrize("offset", [0, 1_000_000])
def test_a_flown_track_saved_and_loaded_gives_every_step_back_exactly(tmp_path, offset):
    dt = 1 / 60
    rng = np.random.default_rng(3)
    intents, presses = _fly(rng, 3000)
    rec = TrackRecorder(dt)
    for k, intent in enumerate(intents):
        rec.add(offset + k, intent, presses.get(k, []))
    path = save_track(rec.to_track(demo="asteroids", seed=4, camera="cockpit", sky="starfield"),
                      tmp_path / "flight.json")
    back = load_track(path)
    assert back.info == {"demo": "asteroids", "seed": 4, "camera": "cockpit", "sky": "starfield", "dt": dt,
                         "steps": offset + 3000}
    for k, intent in enumerate(intents):
        assert back.intent_at_step(offset + k, dt) == intent, k           # bit for bit
        assert back.presses_at_step(offset + k, dt) == presses.get(k, [])
    assert back.intent_at_step(offset + 3000, dt)["throttle"] == 0.0
    # keyboard runs became one hold each: far fewer entries than steps
    n_holds = sum(isinstance(e, Hold) for e in back.events)
    assert n_holds < 0.75 * 3000


def test_a_press_at_step_k_fires_in_step_k_at_any_step():
    dt = 1 / 60
    for k in list(range(0, 5000, 7)) + [10**6 + 13]:
        assert step_index(k * dt, dt) == k


def _write(tmp_path, doc, name="t.json"):
    p = tmp_path / name
    p.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return p


GOOD = {"format": "driftframe track", "version": 1, "holds": [{"start": 0.0, "end": 1.0, "yaw": 0.5}],
        "presses": [{"time": 0.5, "action": "switch_camera"}]}


@pytest.mark.parametrize("change,match", [
    ({"version": 2}, r"track version 2 is not supported \(this driftframe reads version 1\)"),
    ({"format": "something"}, "not a driftframe track"),
    ({"holds": [{"start": 0, "end": 1}, {"start": 0, "end": 1, "yaw": 2.0}]},
     r"holds\[1\]: FlightInput.yaw must be in \[-1.0, 1.0\], got 2.0"),
    ({"holds": [{"start": 0, "end": 1, "warp": 1.0}]}, r"holds\[0\]: .*unknown channel 'warp'"),
    ({"holds": [{"end": 1}]}, r"holds\[0\]: missing 'start'"),
    ({"holds": [{"start": 1, "end": 0.5}]}, r"holds\[0\]: Hold.end must be after"),
    ({"holds": [{"start": 0, "end": 1, "kill_rotation": 1}]}, r"holds\[0\]: kill_rotation must be true or false"),
    ({"presses": [{"time": 1.0, "action": "fly"}]}, r"presses\[0\]: .*'fly'"),
    ({"presses": [{"time": 1.0}]}, r"presses\[0\]: a press has exactly"),
    ({"presses": {"time": 1.0}}, r"presses must be a list"),
    ({"seed": -1}, r"seed has a bad value -1"),
    ({"dt": 0}, r"dt has a bad value 0"),
    ({"speed": 2}, r"unknown key\(s\) 'speed'"),
])
def test_malformed_tracks_name_the_file_and_the_entry(tmp_path, change, match):
    path = _write(tmp_path, {**GOOD, **change})
    with pytest.raises(TrackFileError, match=match) as e:
        load_track(path)
    assert str(e.value).startswith(str(path) + ": ")


def test_not_json_and_missing_track_files_are_named(tmp_path):
    with pytest.raises(TrackFileError, match=r"t.json: not JSON: .* line 1"):
        load_track(_write(tmp_path, "{nope"))
    with pytest.raises(TrackFileError, match="missing.json: cannot read the track"):
        load_track(tmp_path / "missing.json")
    assert load_track(_write(tmp_path, GOOD)).intent_at_step(30, 1 / 60)["yaw"] == 0.5


def test_saving_into_a_missing_folder_fails_and_leaves_nothing(tmp_path):
    with pytest.raises(OSError):
        save_track(Track(), tmp_path / "no" / "t.json")
    # an existing file is replaced whole, never half-written: the temporary sits beside it until complete
    p = save_track(Track((Hold(0, 1, yaw=1.0),)), tmp_path / "t.json")
    assert sorted(x.name for x in tmp_path.iterdir()) == ["t.json"]
    assert load_track(p).events == (Hold(0, 1, yaw=1.0),)


def test_the_input_system_adds_gamepad_axes_to_keys_and_records_what_it_applied(world):
    e, inputs = _piloted(world, None)
    inputs.recorder = TrackRecorder(world.dt)
    inputs.held = {"yaw_right"}
    inputs.axes = {"yaw": 0.5, "throttle": 0.25}
    world.step(3)
    inp = esper.component_for_entity(e, FlightInput)
    assert inp.yaw == 1.0 and inp.throttle == 0.25            # 1 + 0.5 clamped; the stick alone
    inputs.axes = {"pitch": -0.3}
    inputs.held = set()
    inputs.press("switch_camera")
    inputs.handlers["switch_camera"] = lambda w: None
    world.step(2)
    track = inputs.recorder.to_track()
    assert [tuple(h.steps(world.dt)) for h in track.events if isinstance(h, Hold)] == [(0, 1, 2), (3, 4)]
    assert [(p.action, step_index(p.time, world.dt)) for p in track.events if isinstance(p, Press)] == \
        [("switch_camera", 3)]
    assert track.intent_at_step(4, world.dt)["pitch"] == -0.3
    with pytest.raises(ValueError, match="unknown channel 'warp'"):
        inputs.axes = {"warp": 1.0}
        world.step()
