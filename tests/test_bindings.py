"""Bindings: a gamepad state becomes the pilot's channels (dead zone, curve), TOML files read back."""
import json
from pathlib import Path

import pytest

from driftframe.framework.bindings import (AXES, BUTTONS, AxisBinding, Bindings, BindingsError, bindings_toml,
                                           gamepad_actions, gamepad_channels, load_bindings, shape_axis)
from driftframe.framework.input import KEYMAP

STATES = json.loads((Path(__file__).parent / "data" / "gamepad_states.json").read_text())["states"]


@pytest.mark.parametrize("state", STATES, ids=[s["name"] for s in STATES])
def test_recorded_gamepad_states_map_to_the_intent_worked_out_by_hand(state):
    got = gamepad_channels(state["axes"])
    assert set(got) == {"roll", "pitch", "yaw", "throttle"}
    for channel, want in state["want"].items():
        assert got[channel] == pytest.approx(want, abs=1e-12), channel
    assert gamepad_actions(state["buttons"]) == set(state["actions"])


def test_the_curve_is_continuous_at_the_dead_zone_and_reaches_full_deflection():
    assert shape_axis(0.15, 0.15, 2.0) == 0.0
    assert shape_axis(0.1500001, 0.15, 2.0) == pytest.approx(0.0, abs=1e-12)
    assert shape_axis(1.0, 0.15, 2.0) == 1.0 and shape_axis(-1.0, 0.15, 2.0) == -1.0
    assert shape_axis(0.575, 0.15, 1.0) == pytest.approx(0.5)          # linear: the zone is cut out
    # monotonic over the whole travel
    vals = [shape_axis(k / 100, 0.1, 1.7) for k in range(-100, 101)]
    assert all(b >= a for a, b in zip(vals, vals[1:]))


def test_per_axis_overrides_and_axes_adding_into_one_channel():
    b = Bindings(axes={"LEFT_X": AxisBinding("yaw", 0.5, dead_zone=0.0, curve=1.0),
                       "RIGHT_X": AxisBinding("yaw", 1.0, dead_zone=0.0, curve=1.0)})
    got = gamepad_channels([0.8, 0, 0.6, 0, -1, -1], b)
    assert got == {"yaw": 1.0}                                          # 0.4 + 0.6, clamped
    assert gamepad_channels([-0.8, 0, 0.2, 0, -1, -1], b)["yaw"] == pytest.approx(-0.2)


def test_a_state_of_the_wrong_shape_is_rejected():
    with pytest.raises(ValueError, match="6 axes"):
        gamepad_channels([0.0] * 4)
    with pytest.raises(ValueError, match="15 buttons"):
        gamepad_actions([0] * 14)


def test_keys_prints_a_file_that_reads_back_as_the_defaults(tmp_path):
    f = tmp_path / "b.toml"
    f.write_text(bindings_toml())
    b = load_bindings(f)
    assert b == Bindings()
    assert b.keys == KEYMAP


def test_a_bindings_file_changes_only_what_it_names(tmp_path):
    f = tmp_path / "b.toml"
    f.write_text('[keys]\nthrust_forward = ["SPACE", "w"]\n[gamepad]\ndead_zone = 0.05\n'
                 '[gamepad.buttons]\nB = "switch_camera"\n')
    b = load_bindings(f)
    assert b.keys["thrust_forward"] == ("SPACE", "W") and b.keys["quit"] == ("ESCAPE",)
    assert b.dead_zone == 0.05 and b.curve == 2.0
    assert b.buttons == {"B": "switch_camera"}                          # a table given replaces its defaults
    assert set(b.axes) == {"LEFT_X", "LEFT_Y", "RIGHT_X", "RIGHT_TRIGGER", "LEFT_TRIGGER"}
    assert all(a in AXES for a in b.axes) and all(n in BUTTONS for n in b.buttons)


@pytest.mark.parametrize("text,match", [
    ('[keys]\nwarp = ["W"]\n', r"keys\.warp: unknown action"),
    ('[keys]\nthrust_forward = ["NOPE"]\n', r"keys\.thrust_forward: unknown key 'NOPE'"),
    ('[keys]\nthrust_back = ["W"]\n', r"key 'W' is bound to both 'thrust_forward' and 'thrust_back'"),
    ('[gamepad]\ndead_zone = 2\n', r"gamepad\.dead_zone must be a number in \[0.0, 0.95\], got 2"),
    ('[gamepad.axes]\nLEFT_Z = { channel = "yaw" }\n', r"gamepad\.axes\.LEFT_Z: unknown axis"),
    ('[gamepad.axes]\nLEFT_X = { channel = "warp" }\n', r"gamepad\.axes\.LEFT_X must be"),
    ('[gamepad.buttons]\nA = "fly"\n', r"gamepad\.buttons\.A: unknown action 'fly'"),
    ('[gamepad]\nmappings = "missing.txt"\n', r"gamepad\.mappings: no such file"),
    ('[mouse]\n', r"unknown table\(s\) 'mouse'"),
    ('version = 2\n', r"version 2 is not supported"),
    ('[keys\n', r"not TOML"),
])
def test_bad_bindings_files_name_the_file_and_the_entry(tmp_path, text, match):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(BindingsError, match=match) as e:
        load_bindings(f)
    assert str(f) in str(e.value)


def test_a_missing_bindings_file_is_named(tmp_path):
    with pytest.raises(BindingsError, match="nope.toml: cannot read"):
        load_bindings(tmp_path / "nope.toml")


def test_the_window_reads_the_first_connected_gamepad_through_glfws_gamepad_api(monkeypatch):
    from types import SimpleNamespace

    from driftframe.window import Gamepads

    state = SimpleNamespace(axes=[0.0, -1.0, 0.0, 0.0, -1.0, 1.0], buttons=[1] + [0] * 14)
    calls = []
    fake = SimpleNamespace(
        JOYSTICK_1=0, JOYSTICK_LAST=15,
        joystick_is_gamepad=lambda jid: jid in (3, 7),           # two pads; the first one counts
        get_gamepad_state=lambda jid: calls.append(jid) or state,
        get_gamepad_name=lambda jid: f"pad {jid}",
        update_gamepad_mappings=lambda text: calls.append(("mappings", text)) or True)
    monkeypatch.setenv("SDL_GAMECONTROLLERCONFIG", "0300,My Pad,a:b0,platform:Linux,")
    pads = Gamepads(fake)
    axes, buttons = pads.state()
    assert calls == [("mappings", "0300,My Pad,a:b0,platform:Linux,"), 3] and pads.name == "pad 3"
    assert gamepad_channels(axes)["pitch"] == 1.0 and gamepad_channels(axes)["throttle"] == 1.0
    assert gamepad_actions(buttons) == {"kill_rotation"}
    fake.joystick_is_gamepad = lambda jid: False
    assert pads.state() is None
