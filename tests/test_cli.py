"""The command line, end to end: list, record to MP4 / GIF / PNG, and every user error as one clear line."""
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from videos import mp4_frames

from driftframe import demos

EXE = [sys.executable, "-m", "driftframe"]


def run(*args, env=None, timeout=300, cwd=None):
    return subprocess.run(EXE + list(args), capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, **(env or {})}, cwd=cwd)


def test_list_names_every_demo_with_a_description():
    out = run("list")
    assert out.returncode == 0
    lines = out.stdout.strip().splitlines()
    assert [ln.split()[0] for ln in lines] == list(demos.NAMES)
    assert all(len(ln.split()) > 3 for ln in lines)


def test_version_and_help_show_the_keys():
    assert run("--version").stdout.startswith("driftframe ")
    for help_text in (run("play", "--help").stdout, run("--help").stdout):
        for key in ("keys while playing", "W", "ESCAPE", "F12", "kill rotation"):
            assert key in help_text
    assert "keys while playing" not in run("record", "--help").stdout


def test_the_parser_makes_the_keys_help_only_when_help_is_printed():
    """Every command builds the parser; the key list (framework.input) is only for --help."""
    code = ("import sys; from driftframe.cli_parser import build_parser; p = build_parser(); "
            "print('driftframe.framework.input' in sys.modules); p.format_help(); "
            "print('driftframe.framework.input' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "True"]


@pytest.mark.parametrize("given, expected", [(None, "1"), ("3", "3")])
def test_the_command_runs_one_openblas_thread_unless_told_otherwise(given, expected):
    """Set before numpy loads OpenBLAS (its idle worker spins on the other core); a user's setting is kept."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    code = ("import os, sys\n"
            "seen = []\n"
            "class AtNumpy:\n"             # notes the setting when numpy (and with it OpenBLAS) is first imported
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name == 'numpy' and not seen:\n"
            "            seen.append(os.environ.get('OPENBLAS_NUM_THREADS'))\n"
            "sys.meta_path.insert(0, AtNumpy())\n"
            "sys.argv = ['driftframe', 'list']\n"
            "from driftframe.__main__ import run\n"
            "run()\n"
            "print(seen)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[-1] == repr([expected])


@pytest.mark.gl
def test_record_sets_up_without_the_cyclic_collector_and_records_with_it(tmp_path):
    """The set-up's objects are frozen (never walked again), and the frames run with the collector on."""
    code = (
        "import gc, sys\n"
        "import driftframe.app as app, driftframe.framework.recorder as rec\n"
        "seen = {}\n"
        "make, record = app.make_world, rec.record\n"
        "def make_world(*a, **k):\n"
        "    seen['setup'] = gc.isenabled()\n"
        "    return make(*a, **k)\n"
        "def recording(*a, **k):\n"
        "    seen['frames'] = (gc.isenabled(), gc.get_freeze_count())\n"
        "    return record(*a, **k)\n"
        "app.make_world, rec.record = make_world, recording\n"
        "from driftframe.cli import main\n"
        f"rc = main(['record', 'cradle', '--seconds', '0.1', '--size', '64x48', '--quiet',\n"
        f"           '-o', {str(tmp_path / 'c.gif')!r}])\n"
        "print(rc, seen['setup'], *seen['frames'])\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    rc, setup, frames_on, frozen = out.stdout.splitlines()[-1].split()
    assert (rc, setup, frames_on) == ("0", "False", "True")
    assert int(frozen) > 10_000          # numpy's, numba's, the scene's objects


@pytest.mark.gl
def test_record_mp4_end_to_end(tmp_path):
    out = tmp_path / "cradle.mp4"
    res = run("record", "cradle", "--seconds", "0.5", "--size", "320x180", "--quiet", "-o", str(out))
    assert res.returncode == 0, res.stderr
    assert f"wrote {out}" in res.stdout and "30 frames" in res.stdout
    info, frames = mp4_frames(out)
    assert info["size"] == (320, 180) and frames[0].shape == (180, 320, 3)
    assert len(frames) == 30
    assert frames[-1].max() > 100                      # something lit is in the picture
    assert [p.name for p in tmp_path.iterdir()] == ["cradle.mp4"]   # no temporary left


@pytest.mark.gl
def test_preset_and_crf_choose_the_encoder(tmp_path):
    # the default (ultrafast at its own crf), veryfast at crf 20, and a near-lossless crf: three different
    # files of the same frames; the near-lossless one is the largest, and the others decode to within the
    # encoder's loss of it
    outs = {}
    for name, extra in (("default", []), ("veryfast", ["--preset", "veryfast", "--crf", "20"]),
                        ("fine", ["--crf", "4"])):
        out = tmp_path / f"{name}.mp4"
        res = run("record", "asteroids", "--seconds", "0.5", "--size", "320x180", "--quiet", "-o", str(out), *extra)
        assert res.returncode == 0, res.stderr
        outs[name] = out
    sizes = {k: v.stat().st_size for k, v in outs.items()}
    assert len(set(sizes.values())) == 3, sizes
    assert sizes["fine"] > sizes["default"] > sizes["veryfast"], sizes     # veryfast packs tighter
    frames = {k: np.stack(mp4_frames(v)[1])
              for k, v in outs.items()}
    assert {len(f) for f in frames.values()} == {30}
    for k in ("default", "veryfast"):                  # the same picture, within the encoder's loss
        assert np.abs(frames[k].astype(int) - frames["fine"]).mean() < 2.0, k


@pytest.mark.gl
def test_record_gif_and_png_frames_at_30_fps(tmp_path):
    from PIL import Image

    gif = tmp_path / "b.gif"
    res = run("record", "billiards", "--seconds", "0.5", "--fps", "30", "--size", "320x180", "--quiet",
              "-o", str(gif))
    assert res.returncode == 0
    assert "at 30 fps, 160x90)" in res.stdout          # the size of the file, not of the render
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
    (["record", "cradle", "-o", "noext"], "'noext' has no suffix: give NAME.mp4 or NAME.gif, or 'noext/'"),
    (["record", "cradle", "--seconds", "1e9"], "--seconds 1e+09 at 60 fps is about 60,000,000,000 frames"),
    (["record", "cradle", "--seconds", "1e308"], "--seconds 1e+308 at 60 fps is about 6e+309 frames"),
    (["record", "cradle", "--seconds", "1e6", "--fps", "1"], "(6e+7 fixed steps); a recording may have at most 1,000,000 frames"),
    (["record", "cradle", "--motion-blur", "0"], "motion blur must be between 1 and 64"),
    (["record", "cradle", "--fps", "1e-300"], "about 1 frames (6e+301 fixed steps)"),
    (["record", "cradle", "-o", "/proc/x.mp4"], "'/proc' is not writable (it is on a proc file system"),
    (["record", "cradle", "--preset", "fastest"], "invalid choice: 'fastest' (choose from 'ultrafast'"),
    (["record", "cradle", "--crf", "52"], "crf must be a whole number from 0 (lossless) to 51, got '52'"),
    (["record", "cradle", "--crf", "2.5"], "crf must be a whole number from 0 (lossless) to 51, got '2.5'"),
    (["record", "cradle", "--crf", "20", "-o", "c.gif"], "--preset and --crf are for MP4 output, not GIF ('c.gif')"),
    (["record", "cradle", "--preset", "veryfast", "-o", "frames/"], "--preset and --crf are for MP4 output, not PNG"),
    (["play", "pong"], "unknown demo 'pong'"),
])
def test_bad_input_is_one_clear_line_and_exit_2(args, message, tmp_path):
    res = run(*args, env={"DRIFTFRAME_UNUSED": "1"}, cwd=tmp_path)
    assert res.returncode == 2
    assert message in res.stderr
    assert "Traceback" not in res.stderr
    assert not list(tmp_path.iterdir())             # not even the default out/ folder


def test_play_without_a_display_says_so_at_once(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")   # a first run: the refusal must not wait for a compile
    res = subprocess.run(EXE + ["play", "cradle"], capture_output=True, text=True, env=env, timeout=60)
    assert res.returncode == 2
    assert "no display" in res.stderr and "Traceback" not in res.stderr
    assert "compil" not in res.stderr and not list((tmp_path / "numba").rglob("*.nbi"))


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


# -- recordings that never leave debris ----------------------------------------------------------
def _start_recording(out, *extra):
    """A real ``driftframe record`` process, long enough to be stopped; returns it once it is writing."""
    import signal as sg
    import time

    def default_signals():                          # a test runner may have them ignored (background jobs)
        for s in (sg.SIGINT, sg.SIGTERM, sg.SIGHUP):
            sg.signal(s, sg.SIG_DFL)

    proc = subprocess.Popen(EXE + ["record", "cradle", "--seconds", "600", "--size", "64x36", "--quiet",
                                   "-o", str(out), *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_signals)
    deadline = time.monotonic() + 120
    # ffmpeg writes the MP4 header once the first frame reaches it: a non-empty part file means frames flow
    while not any(p.name.startswith(f".{out.name}.") and p.stat().st_size > 0 for p in out.parent.iterdir()):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the recording never started"
        time.sleep(0.05)
    time.sleep(0.5)
    return proc


@pytest.mark.gl
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_stop_signal_leaves_a_valid_shorter_video_and_exits_as_the_signal(tmp_path, signame):
    import signal as sg

    signum = getattr(sg, signame)
    out = tmp_path / "cut.mp4"
    proc = _start_recording(out)
    proc.send_signal(signum)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signum, stderr
    assert f"recording interrupted after" in stderr and f"({signame}): wrote" in stderr
    assert "Traceback" not in stderr and f"wrote {out}" in stdout
    frames = mp4_frames(out)[1]
    assert 0 < len(frames) < 36000
    assert [p.name for p in tmp_path.iterdir()] == ["cut.mp4"]          # nothing hidden left


@pytest.mark.gl
def test_after_sigkill_the_next_run_of_the_same_output_removes_the_stale_part(tmp_path):
    import signal as sg

    out = tmp_path / "k.mp4"
    proc = _start_recording(out)
    proc.send_signal(sg.SIGKILL)
    proc.wait(timeout=30)
    debris = [p.name for p in tmp_path.iterdir()]
    assert len(debris) == 1 and debris[0].startswith(".k.mp4.") and ".part" in debris[0]
    res = run("record", "cradle", "--seconds", "0.1", "--size", "64x36", "--quiet", "-o", str(out))
    assert res.returncode == 0, res.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["k.mp4"]


@pytest.mark.gl
def test_default_output_folder_is_made_and_an_existing_output_needs_overwrite(tmp_path):
    args = ["record", "cradle", "--seconds", "0.1", "--size", "64x36", "--quiet"]
    first = run(*args, cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    out = tmp_path / "out" / "cradle.mp4"
    before = out.read_bytes()
    again = run(*args, "--seconds", "0.2", cwd=tmp_path)
    assert again.returncode == 2
    assert "'out/cradle.mp4' exists; pass --overwrite to replace it" in again.stderr   # the shell's words (issue 23)
    assert "overwrite=True" not in again.stderr
    assert "Traceback" not in again.stderr and out.read_bytes() == before
    forced = run(*args, "--seconds", "0.2", "--overwrite", cwd=tmp_path)
    assert forced.returncode == 0, forced.stderr
    assert "12 frames" in forced.stdout and out.read_bytes() != before
    assert os.listdir(tmp_path / "out") == ["cradle.mp4"]


def _can_mount_tmpfs():
    import shutil
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(["unshare", "-r", "-m", "sh", "-c", "d=$(mktemp -d) && mount -t tmpfs -o size=64k "
                            "tmpfs \"$d\""], capture_output=True)
    return probe.returncode == 0


@pytest.mark.gl
@pytest.mark.skipif(not _can_mount_tmpfs(), reason="needs unshare and a user namespace to mount a tiny tmpfs; "
                                                   "test_recorder's fake full disk covers the logic")
@pytest.mark.parametrize("name", ["full.mp4", "full.gif", "frames/"])
def test_a_full_disk_is_one_clear_line_and_leaves_nothing(tmp_path, name):
    disk = tmp_path / "disk"
    disk.mkdir()
    # spin: its frames change, so the MP4 fills the disk in ~300 frames (2 s of CPU); the cradle's near-still
    # frames (~150 bytes each) took 1,865 before FFmpeg reported the full disk (7-8 s), whatever the disk's size
    script = (f'mount -t tmpfs -o size=48k tmpfs "{disk}" || exit 99; '
              f'"{sys.executable}" -m driftframe record spin --seconds 60 --size 320x180 --quiet '
              f'-o "{disk}/{name}"; echo "rc=$?"; echo "left:"; ls -A "{disk}"')
    res = subprocess.run(["unshare", "-r", "-m", "sh", "-c", script], capture_output=True, text=True,
                         timeout=300)
    assert "rc=1" in res.stdout, res.stdout + res.stderr
    assert "no space left on the device" in res.stderr and "Traceback" not in res.stderr
    assert res.stdout.split("left:")[1].split() == []                 # nothing half-written


@pytest.mark.gl
def test_record_with_motion_blur(tmp_path):
    sharp, blur = tmp_path / "s.gif", tmp_path / "b.gif"
    for out, extra in ((sharp, []), (blur, ["--motion-blur", "3"])):
        res = run("record", "asteroids", "--seconds", "0.2", "--size", "64x36", "--quiet", "-o", str(out), *extra)
        assert res.returncode == 0, res.stderr
    assert sharp.read_bytes() != blur.read_bytes()


def test_a_first_run_shows_the_compile_kernel_by_kernel_and_a_warm_run_says_nothing(tmp_path):
    # an empty cache is a machine's first run: a line before the wait, a progress line rewritten in
    # place (which kernel, n of m, seconds), then the summary, all before the recording starts
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    args = ("record", "spin", "-o", str(tmp_path / "s.mp4"), "--overwrite", "--seconds", "0.1", "--size", "64x64")
    cold = subprocess.run(EXE + list(args), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=300, env={**os.environ, **env})
    assert cold.returncode == 0, cold.stdout
    out = cold.stdout
    assert out.startswith("driftframe: compiling the physics kernels for this machine: the first run only"), out
    # (text mode reads each \r as a line end)
    progress = re.findall(r"^driftframe: compiling (\d+) of (\d+) kernels, (\d+) s: ([\w.]+)", out, re.M)
    assert progress, out
    (done,) = re.findall(r"\ndriftframe: compiled (\d+) kernels in \d+ s; later runs load them from the cache\n", out)
    n, m = map(int, progress[-1][:2])
    # n of m is honest: it ends at m, and m is the number of kernels numba wrote to the cache
    saved = {p.name.split("-")[0] for p in (tmp_path / "numba").rglob("*.nbi")}
    assert n == m == int(done) == len(saved) > 0, (progress, done, saved)
    assert {name for *_, name in progress} <= saved
    # the summary comes before the recording starts, and so before its final "wrote ..." line
    assert out.index("driftframe: compiled") < out.index("recording s.mp4") < out.index("wrote ")
    warm = run(*args, env=env)
    assert warm.returncode == 0 and "compil" not in warm.stderr, warm.stderr
    # --quiet on a first run says nothing of its compile: a cache lacking one kernel (the NV12 converter,
    # the cheapest), copied from the one just made, so that it compiles one kernel, not the scene's all
    import shutil
    shutil.copytree(tmp_path / "numba", tmp_path / "numba2")
    lacking = [p for p in (tmp_path / "numba2").rglob("yuv._nv12-*")]
    assert lacking, sorted(p.name for p in (tmp_path / "numba2").rglob("*"))
    for p in lacking:
        p.unlink()
    quiet = run(*args, "--quiet", env={"NUMBA_CACHE_DIR": str(tmp_path / "numba2")})
    assert quiet.returncode == 0 and "compil" not in quiet.stderr, quiet.stderr
    assert list((tmp_path / "numba2").rglob("yuv._nv12-*.nbi")), "the --quiet run compiled nothing"


def test_warm_with_a_warm_cache_loads_every_kernel_quietly_and_names_the_folder(tmp_path):
    from driftframe.framework import kernels
    res = run("warm")                     # the suite's own cache: ./run tests warms it before pytest
    assert res.returncode == 0, res.stderr
    from test_kernel_cache import uncalled_kernels
    total, dead = len(kernels.registry()), uncalled_kernels()       # the warm-up reaches every kernel called
    assert res.stdout.strip() == f"{total - len(dead)} of {total} kernels ready in {kernels.cache_dir()}", res.stdout
    again = run("warm")
    assert again.returncode == 0 and "driftframe: compiling" not in again.stderr and again.stdout == res.stdout, \
        again.stderr


def test_an_existing_output_is_refused_before_the_kernels_are_compiled(tmp_path):
    # on a machine's first run the compile takes tens of seconds: the refusal must not wait for it
    (tmp_path / "s.mp4").write_bytes(b"mine")
    res = run("record", "spin", "-o", str(tmp_path / "s.mp4"), "--seconds", "0.1",
              env={"NUMBA_CACHE_DIR": str(tmp_path / "numba")})
    assert res.returncode == 2 and "exists; pass --overwrite" in res.stderr, res.stderr
    assert "compil" not in res.stderr and not list((tmp_path / "numba").rglob("*.nbi"))
    assert (tmp_path / "s.mp4").read_bytes() == b"mine"


@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_signal_while_the_kernels_compile_stops_cleanly_and_says_so(tmp_path, signame):
    import signal
    import time
    signum = getattr(signal, signame)
    out = tmp_path / "a.mp4"
    proc = subprocess.Popen(EXE + ["record", "asteroids", "-o", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")})
    first = proc.stderr.readline()                  # the notice: compiling has begun (it takes ~35 s cold)
    assert first.startswith("driftframe: compiling"), first
    time.sleep(1.0)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signum, err
    assert "s of compiling kernels: those finished are cached, the rest are compiled on the next run" in err
    assert "compiled the kernels in" not in err and "Traceback" not in err
    assert f"interrupted ({signame})" in err and not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name != "numba"]      # no output, no part file


# a stop signal sent by the process to itself after the command's own handlers: as main() returns (the
# command has printed everything and given the signals back), and in the interpreter's shutdown (atexit)
_LATE = {
    "main returning": "real = cli._SignalsInterrupt.__exit__; "
                      "cli._SignalsInterrupt.__exit__ = lambda self, *e: (real(self, *e), os.kill(os.getpid(), {sig}))[0]",
    "shutdown": "atexit.register(os.kill, os.getpid(), {sig})",
}


# (SIGTERM as main() returns is the default's death by the signal, which the shell reports as 143 too)
@pytest.mark.parametrize("when,signame", [("main returning", "SIGINT"), ("shutdown", "SIGINT"), ("shutdown", "SIGTERM")])
def test_a_signal_after_the_command_finished_is_one_line_and_128_plus_n(when, signame):
    # Ctrl-C landing after `driftframe warm` printed its last line (a quiet machine, a test's fixed sleep):
    # Python re-raised the KeyboardInterrupt at exit (status -2, a traceback), or printed it from atexit
    import signal
    code = ("import atexit, os, signal, sys; import driftframe.cli as cli, driftframe.__main__ as entry; "
            "sys.argv[1:] = ['keys']; " + _LATE[when].format(sig=f"signal.{signame}") + "; sys.exit(entry.run())")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 128 + getattr(signal, signame), (res.returncode, res.stderr)
    assert res.stderr == f"driftframe: interrupted ({signame})\n", res.stderr
    from driftframe.framework.bindings import bindings_toml
    assert res.stdout == bindings_toml(None)                  # the command's output, all of it, before the line


@pytest.mark.parametrize("warm, name, scratch_worlds", [
    (True, "spin", 0), (False, "spin", 1), (True, "mygame.scene:build", 1), (False, "mygame.scene:build", 1)])
def test_the_kernels_scratch_world_is_built_unless_the_cache_folder_is_warm_for_a_demo(monkeypatch, warm, name,
                                                                                       scratch_worlds):
    """`driftframe warm` ran every demo into a warm folder: a demo's kernels load at its first step. A scene of
    one's own may have kernels of its own: it is stepped once first, where a compile shows its progress."""
    import driftframe.app as app
    from driftframe.framework import kernels

    built = []

    class Scratch:
        def step(self):
            built[-1] += "+step"

        def close(self):
            built[-1] += "+close"

    def make_world(n, seed=0):
        built.append(n)
        return Scratch(), None
    monkeypatch.setattr(kernels, "is_warm", lambda folder=None: warm)
    monkeypatch.setattr(app, "make_world", make_world)
    app.load_kernels(name, seed=3)
    assert built == [f"{name}+step+close"] * scratch_worlds
