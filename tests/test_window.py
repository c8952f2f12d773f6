"""`driftframe play` in a real window under Xvfb: real key events fly the ship and switch the camera.

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
    for n in range(170, 260):
        if not os.path.exists(f"/tmp/.X11-unix/X{n}") and not os.path.exists(f"/tmp/.X{n}-lock"):
            break
    server = subprocess.Popen(["Xvfb", f":{n}", "-screen", "0", "1280x720x24", "-nolisten", "tcp"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 10
    while not os.path.exists(f"/tmp/.X11-unix/X{n}"):
        if time.time() > deadline or server.poll() is not None:
            server.kill()
            pytest.fail(f"Xvfb did not start on :{n}")
        time.sleep(0.05)
    yield f":{n}"
    server.terminate()
    server.wait(10)


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


def test_keys_thrust_the_ship_and_switch_the_camera(display, tmp_path):
    state = tmp_path / "state.json"
    env = {**os.environ, "DISPLAY": display}
    proc = subprocess.Popen([sys.executable, "-m", "driftframe", "play", "asteroids", "--size", "480x270",
                             "--state-out", str(state), "--screenshots", str(tmp_path)],
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
        _xdo(display, "key", "--window", wid, "Escape")
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, proc.stderr.read()
    s = json.loads(state.read_text())
    # thrust acted along the nose (the ship starts facing +z at rest) and the velocity persisted
    v = np.array(s["player"]["velocity"])
    fwd = np.array(s["player"]["forward"])
    assert v @ fwd > 3.0, v                             # ~1.5 s at 6 m/s^2 (timing of real keys varies)
    np.testing.assert_allclose(np.cross(v, fwd), 0.0, atol=1e-9)
    assert s["camera"] == "cockpit"                     # the demo starts in chase: C switched it
    assert s["steps"] > 60
    # the screenshot is the window's picture: right size, the green skybox and the HUD are in it
    from PIL import Image
    assert len(s["screenshots"]) == 1
    img = np.asarray(Image.open(s["screenshots"][0]).convert("RGB")).astype(int)
    assert img.shape == (270, 480, 3)
    green = (img[:, :, 1] > 150) & (img[:, :, 0] < 100) & (img[:, :, 2] < 120)
    assert green.sum() > 200
    assert (img[5:60, 5:150].max(axis=2) > 150).sum() > 50     # HUD text in the top-left corner
