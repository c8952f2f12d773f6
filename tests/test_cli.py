"""The command line, end to end: list, record to MP4 / GIF / PNG, and every user error as one clear line."""
import os
import subprocess
import sys

import numpy as np
import pytest

from driftframe import demos

EXE = [sys.executable, "-m", "driftframe"]


def run(*args, env=None, timeout=300):
    return subprocess.run(EXE + list(args), capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, **(env or {})})


def test_list_names_every_demo_with_a_description():
    out = run("list")
    assert out.returncode == 0
    lines = out.stdout.strip().splitlines()
    assert [ln.split()[0] for ln in lines] == list(demos.NAMES)
    assert all(len(ln.split()) > 3 for ln in lines)


def test_version_and_help_show_the_keys():
    assert run("--version").stdout.startswith("driftframe ")
    help_text = run("play", "--help").stdout
    for key in ("W", "ESCAPE", "F12", "kill rotation"):
        assert key in help_text


@pytest.mark.gl
def test_record_mp4_end_to_end(tmp_path):
    import imageio_ffmpeg

    out = tmp_path / "cradle.mp4"
    res = run("record", "cradle", "--seconds", "0.5", "--size", "320x180", "--quiet", "-o", str(out))
    assert res.returncode == 0, res.stderr
    assert f"wrote {out}" in res.stdout and "30 frames" in res.stdout
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = next(reader)
    assert tuple(meta["size"]) == (320, 180)
    frames = [np.frombuffer(f, np.uint8).reshape(180, 320, 3) for f in reader]
    assert len(frames) == 30
    assert frames[-1].max() > 100                      # something lit is in the picture
    assert [p.name for p in tmp_path.iterdir()] == ["cradle.mp4"]   # no temporary left


@pytest.mark.gl
def test_record_gif_and_png_frames_at_30_fps(tmp_path):
    from PIL import Image

    gif = tmp_path / "b.gif"
    assert run("record", "billiards", "--seconds", "0.5", "--fps", "30", "--size", "320x180", "--quiet",
               "-o", str(gif)).returncode == 0
    with Image.open(gif) as im:
        assert im.size == (160, 90)                     # GIF previews are half size
        assert 1 < im.n_frames <= 15
    frames = tmp_path / "frames"
    res = run("record", "billiards", "--seconds", "0.5", "--fps", "30", "--size", "320x180", "--quiet",
              "-o", str(frames) + "/")
    assert res.returncode == 0, res.stderr
    pngs = sorted(frames.glob("*.png"))
    assert len(pngs) == 15
    assert Image.open(pngs[0]).size == (320, 180)


@pytest.mark.gl
def test_two_recordings_are_byte_identical(tmp_path):
    a, b = tmp_path / "a.mp4", tmp_path / "b.mp4"
    for path in (a, b):
        assert run("record", "asteroids", "--seconds", "0.5", "--size", "320x180", "--seed", "7", "--quiet",
                   "-o", str(path)).returncode == 0
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("args,message", [
    (["record", "pong"], "unknown demo 'pong'"),
    (["record", "cradle", "--size", "12x34x5"], "WIDTHxHEIGHT"),
    (["record", "cradle", "--size", "0x100"], "between 16 and 7680"),
    (["record", "cradle", "--seconds", "0"], "seconds must be a finite number > 0"),
    (["record", "cradle", "--seconds", "nan"], "seconds must be a finite number > 0"),
    (["record", "cradle", "--fps", "-3"], "fps must be a finite number > 0"),
    (["record", "cradle", "--fps", "25"], "must divide the 60 Hz"),
    (["record", "cradle", "--seed", "-1"], "seed must be an integer >= 0"),
    (["record", "cradle", "-o", "clip.avi"], "unknown output format '.avi'"),
    (["record", "cradle", "-o", "/nonexistent/dir/x.mp4"], "does not exist"),
    (["play", "pong"], "unknown demo 'pong'"),
])
def test_bad_input_is_one_clear_line_and_exit_2(args, message, tmp_path):
    res = run(*args, env={"DRIFTFRAME_UNUSED": "1"})
    assert res.returncode == 2
    assert message in res.stderr
    assert "Traceback" not in res.stderr
    assert not list(tmp_path.iterdir())


def test_play_without_a_display_says_so():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = subprocess.run(EXE + ["play", "cradle"], capture_output=True, text=True, env=env, timeout=60)
    assert res.returncode == 2
    assert "no display" in res.stderr and "Traceback" not in res.stderr


def test_an_unwritable_output_directory_is_refused_before_rendering(tmp_path):
    # /sys refuses new files even to root, so this holds whoever runs the suite
    res = run("record", "cradle", "-o", "/sys/driftframe-test.mp4")
    assert res.returncode == 2
    assert "cannot write '/sys/driftframe-test.mp4'" in res.stderr and "Traceback" not in res.stderr


def test_png_output_into_a_folder_of_other_files_is_refused(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    res = run("record", "cradle", "-o", str(tmp_path))
    assert res.returncode == 2 and "holds other files" in res.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]
