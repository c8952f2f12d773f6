"""Replays from the command line: record --track re-renders a flight byte for byte; keys; diverge."""
import json
import os
import subprocess
import sys
import tomllib

import pytest

EXE = [sys.executable, "-m", "driftframe"]


def run(*args, env=None, timeout=300):
    return subprocess.run(EXE + list(args), capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, **(env or {})})


FLIGHT = {"format": "driftframe track", "version": 1, "demo": "asteroids", "seed": 3, "camera": "cockpit",
          "sky": "starfield",
          "dt": 1 / 60, "steps": 45,
          "holds": [{"start": 0.0, "end": 0.5, "throttle": 1.0}, {"start": 0.25, "end": 0.6, "yaw": -0.35}],
          "presses": [{"time": 0.4, "action": "switch_camera"}]}


@pytest.mark.gl
def test_record_track_is_byte_identical_and_uses_the_tracks_seed_camera_and_length(tmp_path):
    track = tmp_path / "flight.json"
    track.write_text(json.dumps(FLIGHT))
    outs = []
    for k in range(2):
        out = tmp_path / f"r{k}.mp4"
        res = run("record", "asteroids", "--track", str(track), "--size", "160x90", "--quiet", "-o", str(out),
                  "--hash-log", str(tmp_path / f"h{k}.txt"))
        assert res.returncode == 0, res.stderr
        assert "45 frames" in res.stdout                     # the track's length
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    assert run("diverge", str(tmp_path / "h0.txt"), str(tmp_path / "h1.txt")).returncode == 0
    # the same flight with another seed is another flight: diverge finds it at the first step
    res = run("record", "asteroids", "--track", str(track), "--seed", "4", "--size", "160x90", "--quiet",
              "-o", str(tmp_path / "other.mp4"), "--hash-log", str(tmp_path / "h2.txt"))
    assert res.returncode == 0, res.stderr
    d = run("diverge", str(tmp_path / "h0.txt"), str(tmp_path / "h2.txt"))
    assert d.returncode == 1 and "part ways at step 1:" in d.stdout
    # without the track the demo's own script flies: a different log
    res = run("record", "asteroids", "--seed", "3", "--seconds", "0.75", "--camera", "cockpit", "--size",
              "160x90", "--quiet", "-o", str(tmp_path / "script.mp4"), "--hash-log", str(tmp_path / "h3.txt"))
    assert res.returncode == 0, res.stderr
    # the track's sky was used: the same flight under the line cube is another picture
    res = run("record", "asteroids", "--track", str(track), "--sky", "lines", "--size", "160x90", "--quiet",
              "-o", str(tmp_path / "lines.mp4"))
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "lines.mp4").read_bytes() != outs[0]
    assert run("diverge", str(tmp_path / "h0.txt"), str(tmp_path / "h3.txt")).returncode == 1


def test_a_track_of_another_demo_or_a_bad_track_is_one_clear_line(tmp_path):
    track = tmp_path / "flight.json"
    track.write_text(json.dumps(FLIGHT))
    res = run("record", "spin", "--track", str(track), "-o", str(tmp_path / "x.mp4"))
    assert res.returncode == 2 and "was flown in 'asteroids', not 'spin'" in res.stderr
    track.write_text(json.dumps({**FLIGHT, "holds": [{"start": 0, "end": 1, "pitch": "up"}]}))
    res = run("record", "asteroids", "--track", str(track), "-o", str(tmp_path / "x.mp4"))
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert f"{track}: holds[0]: FlightInput.pitch must be a number, got 'up'" in res.stderr
    assert not (tmp_path / "x.mp4").exists()


def test_play_refuses_unwritable_outputs_before_opening_a_window(tmp_path):
    for option in ("--save-track", "--hash-log", "--state-out"):
        res = run("play", "asteroids", option, str(tmp_path / "missing" / "f.json"), env={"DISPLAY": ""})
        assert res.returncode == 2, res.stderr
        assert f"cannot write {option} '{tmp_path / 'missing' / 'f.json'}': directory " in res.stderr
        assert "does not exist" in res.stderr


def test_keys_prints_the_default_bindings_as_toml():
    res = run("keys")
    assert res.returncode == 0
    doc = tomllib.loads(res.stdout)
    assert doc["keys"]["thrust_forward"] == ["W"] and doc["keys"]["fullscreen"] == ["F11"]
    assert doc["keys"]["overlay"] == ["F3"]
    assert doc["gamepad"]["axes"]["LEFT_Y"] == {"channel": "pitch", "scale": -1.0}


def test_play_with_a_bad_bindings_file_names_it(tmp_path):
    b = tmp_path / "b.toml"
    b.write_text('[keys]\nquit = ["ESCAPEE"]\n')
    res = run("play", "asteroids", "--bindings", str(b), env={"DISPLAY": ""})
    assert res.returncode == 2 and f"{b}: keys.quit: unknown key 'ESCAPEE'" in res.stderr
