"""`driftframe play` in a real window under Xvfb: real key events fly the ship, switch the camera, toggle
fullscreen and the overlay; a flight saved with --save-track re-renders byte for byte.

``./run tests`` installs Xvfb and xdotool; this module starts its own X
server on a free display, so it needs no display of the user's.
"""
import json
import os
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest

pytestmark = [pytest.mark.window, pytest.mark.gl]


@pytest.fixture(scope="module")
def display():
    if not (shutil.which("Xvfb") and shutil.which("xdotool")):
        pytest.fail("window tests need Xvfb and xdotool: `./run tests` installs them "
                    "(apt-get install xvfb xdotool)")
    from driftframe.xvfb import virtual_display
    with virtual_display((1280, 720)) as name:      # a private server: no other job's windows or keys
        yield name


def _xdo(display, *args):
    return subprocess.run(["xdotool", *args], env={**os.environ, "DISPLAY": display}, capture_output=True,
                          text=True, timeout=30)


def _wait_for_window(display, proc, title="driftframe"):
    deadline = time.time() + 60
    while time.time() < deadline:
        if proc.poll() is not None:
            raise AssertionError(f"play exited early: {proc.stderr.read()}")
        out = _xdo(display, "search", "--name", title).stdout.split()
        if out:
            return out[0]
        time.sleep(0.2)
    raise AssertionError("no driftframe window appeared")


_STARTED: list[subprocess.Popen] = []
#: Every key a test here presses.
_KEYS = ("Escape", "w", "d", "x", "c", "F3", "F11", "F12")


@pytest.fixture(autouse=True)
def _no_window_left_open(display):
    """A test that fails half-way must not leave its window, or a key held down, for the next one."""
    yield
    while _STARTED:
        proc = _STARTED.pop()
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    _xdo(display, "keyup", *_KEYS)                    # XTEST, whatever window has the focus now


def _quit(display, wid):
    """Esc, as a user presses it. The release goes to no window in particular: play quits on the press and
    its window is gone before the release, which ``key --window`` then never sent, so the X server kept
    Escape down and auto-repeated it into the next test's window (which quit after one or two frames)."""
    _xdo(display, "keydown", "--window", wid, "Escape")
    time.sleep(0.05)
    _xdo(display, "keyup", "Escape")


def _play(display, tmp_path, *extra):
    env = {**os.environ, "DISPLAY": display}
    return _started(subprocess.Popen([sys.executable, "-m", "driftframe", "play", "asteroids", "--size", "480x270",
                             "--state-out", str(tmp_path / "state.json"), "--screenshots", str(tmp_path), *extra],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))


def _started(proc):
    _STARTED.append(proc)
    return proc


def _finish(proc):
    try:
        proc.wait(60)
    finally:
        if proc.poll() is None:
            proc.kill()
    err = proc.stderr.read()
    assert proc.returncode == 0, err
    return err


def test_keys_thrust_the_ship_and_switch_the_camera(display, tmp_path):
    state = tmp_path / "state.json"
    env = {**os.environ, "DISPLAY": display}
    track = tmp_path / "flight.json"
    proc = subprocess.Popen([sys.executable, "-m", "driftframe", "play", "asteroids", "--size", "480x270",
                             "--state-out", str(state), "--screenshots", str(tmp_path), "--save-track", str(track)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wid = _wait_for_window(display, proc)
        _xdo(display, "windowfocus", "--sync", wid)
        time.sleep(1.0)                                 # let it render a few frames first
        _xdo(display, "keydown", "--window", wid, "w")
        time.sleep(1.5)
        _xdo(display, "keyup", "--window", wid, "w")
        _xdo(display, "key", "--window", wid, "c")
        time.sleep(0.5)
        _xdo(display, "key", "--window", wid, "F12")
        time.sleep(0.5)
        _quit(display, wid)
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, proc.stderr.read()
    s = json.loads(state.read_text())
    # thrust acted along the nose (the ship starts facing +z at rest) and the velocity persisted
    v = np.array(s["player"]["velocity"])
    fwd = np.array(s["player"]["forward"])
    # as long as the flight held the key (its track: real keys land on however many steps a loaded
    # machine ran in the 1.5 s), at the ship's 6 m/s^2
    doc = json.loads(track.read_text())
    held = sum(round((h["end"] - h["start"]) / doc["dt"]) for h in doc["holds"] if h.get("throttle") == 1.0)
    assert held >= 1 and v @ fwd == pytest.approx(6.0 * held * doc["dt"], rel=1e-9), (v, held)
    np.testing.assert_allclose(np.cross(v, fwd), 0.0, atol=1e-9)
    assert s["camera"] == "cockpit"                     # the demo starts in chase: C switched it
    assert s["steps"] > 60
    # the screenshot is the window's picture: right size, the starfield (the default sky: no green lines)
    # and the HUD are in it
    from PIL import Image
    assert len(s["screenshots"]) == 1
    img = np.asarray(Image.open(s["screenshots"][0]).convert("RGB")).astype(int)
    assert img.shape == (270, 480, 3)
    green = (img[:, :, 1] > 150) & (img[:, :, 0] < 100) & (img[:, :, 2] < 120)
    assert green.sum() < 20
    white = (img.min(axis=2) > 110) & (np.ptp(img, axis=2) < 60)   # stars (and lit rock), outside the HUD
    assert white[80:].sum() > 10
    assert (img[5:60, 5:150].max(axis=2) > 150).sum() > 50     # HUD text in the top-left corner


def test_a_flight_saved_in_play_re_renders_as_the_same_flight_byte_for_byte(display, tmp_path):
    track, log = tmp_path / "flight.json", tmp_path / "play.txt"
    proc = _play(display, tmp_path, "--save-track", str(track), "--hash-log", str(log))
    wid = _wait_for_window(display, proc)
    _xdo(display, "windowfocus", "--sync", wid)
    time.sleep(0.5)
    _xdo(display, "keydown", "--window", wid, "w")
    time.sleep(0.6)
    _xdo(display, "keydown", "--window", wid, "d")
    time.sleep(0.4)
    _xdo(display, "keyup", "--window", wid, "w")
    _xdo(display, "key", "--window", wid, "c")
    time.sleep(0.3)
    _xdo(display, "keyup", "--window", wid, "d")
    _xdo(display, "key", "--window", wid, "x")          # a tap shorter than a step still acts for a step
    time.sleep(0.3)
    _quit(display, wid)
    err = _finish(proc)
    assert f"track: {track}" in err
    doc = json.loads(track.read_text())
    assert doc["version"] == 1 and doc["demo"] == "asteroids" and doc["steps"] > 1   # (as many as the machine ran)
    assert any(h.get("throttle") == 1.0 for h in doc["holds"]) and any(h.get("yaw") == 1.0 for h in doc["holds"])
    assert any(h.get("kill_rotation") for h in doc["holds"])
    assert doc["presses"] == [{"time": doc["presses"][0]["time"], "action": "switch_camera"}]
    outs = []
    for k in range(2):
        # PNG frames: the frames themselves, byte for byte (tests/test_replay.py checks the MP4 bytes); small
        # ones: the bytes are compared whatever the size (160x90: ~0.8 s of CPU less a recording than 320x180)
        out = tmp_path / f"replay{k}"
        res = subprocess.run([sys.executable, "-m", "driftframe", "record", "asteroids", "--track", str(track),
                              "--size", "160x90", "--quiet", "-o", f"{out}/", "--hash-log",
                              str(tmp_path / f"rec{k}.txt")], capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stderr
        assert f"{doc['steps']} frames" in res.stdout
        outs.append([p.read_bytes() for p in sorted(out.iterdir())])
    assert len(outs[0]) == doc["steps"] and outs[0] == outs[1]
    # the recording flew the flight that was played: the same state after every step
    from driftframe.framework.hashlog import first_divergence
    assert first_divergence(log, tmp_path / "rec0.txt") is None


def test_f11_fullscreen_f3_overlay_and_a_resize_that_keeps_the_aspect_ratio(display, tmp_path):
    proc = _play(display, tmp_path)
    wid = _wait_for_window(display, proc)
    _xdo(display, "windowfocus", "--sync", wid)
    time.sleep(0.5)

    def geometry():
        res = _xdo(display, "getwindowgeometry", wid)
        assert "Geometry:" in res.stdout, (res.stdout, res.stderr, proc.poll())
        return tuple(int(v) for v in res.stdout.split("Geometry:")[1].split()[0].split("x"))

    def becomes(size, timeout=20.0):                    # (a loaded machine answers a key late)
        deadline = time.monotonic() + timeout
        while geometry() != size and time.monotonic() < deadline:
            time.sleep(0.1)
        return geometry()

    assert geometry() == (480, 270)
    _xdo(display, "key", "--window", wid, "F11")
    assert becomes((1280, 720)) == (1280, 720)          # the whole Xvfb screen
    _xdo(display, "key", "--window", wid, "F3")
    time.sleep(0.8)
    _xdo(display, "key", "--window", wid, "F12")
    time.sleep(0.5)
    _xdo(display, "key", "--window", wid, "F11")
    assert becomes((480, 270)) == (480, 270)            # back to the window it was
    _xdo(display, "windowsize", wid, "600", "500")      # taller than 16:9: bars above and below
    time.sleep(0.8)
    _xdo(display, "key", "--window", wid, "F12")
    time.sleep(0.5)
    _quit(display, wid)
    _finish(proc)
    s = json.loads((tmp_path / "state.json").read_text())
    assert s["fullscreen"] is False
    assert s["window"] == [600, 500] and s["picture"] == [600, 338] and s["viewport"] == [0, 81, 600, 338]
    assert s["overlay"][0].startswith("FPS") and any("collision" in ln for ln in s["overlay"])
    assert any("render" in ln for ln in s["overlay"])
    from PIL import Image
    full, boxed = (np.asarray(Image.open(p).convert("RGB")).astype(int) for p in s["screenshots"])
    assert full.shape == (720, 1280, 3)                 # drawn at the fullscreen size
    assert boxed.shape == (338, 600, 3)                 # the picture, without the bars
    # the overlay's text sits in the bottom-left corner of both
    for img in (full, boxed):
        h = img.shape[0]
        assert (img[h - h // 3:, :img.shape[1] // 3].max(axis=2) > 150).sum() > 100


def test_frames_quits_by_itself_and_reports_the_frame_rate(display, tmp_path):
    proc = _play(display, tmp_path, "--frames", "40", "--overlay", "--no-interpolation")
    err = _finish(proc)
    assert "played 40 frames in " in err and " fps (median frame " in err and "real time" in err
    s = json.loads((tmp_path / "state.json").read_text())
    assert s["frames"] == 40 and s["fps"] > 0
    assert s["overlay"][0].startswith("FPS")


def test_two_virtual_displays_started_together_are_separate_servers(display):
    # what let two test runs on one machine press each other's keys: both guessed the same free number
    from driftframe.xvfb import virtual_display
    with virtual_display((640, 360)) as a, virtual_display((320, 200)) as b:
        assert len({display, a, b}) == 3
        assert _xdo(a, "getdisplaygeometry").stdout.split() == ["640", "360"]
        assert _xdo(b, "getdisplaygeometry").stdout.split() == ["320", "200"]
    assert _xdo(display, "getdisplaygeometry").stdout.split() == ["1280", "720"]
