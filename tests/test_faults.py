"""Fault injection: signals at every moment, a full disk, a lost display, hostile input files.

Whatever happens, no finished output is lost, no part file or process is
left, no traceback is printed, and the exit status says what happened
(128 + the signal's number; 1 for a failed write or a lost display; 2 for
bad input). Saved tracks and hash logs are valid up to the last whole step.

The signal cases run ``driftframe.cli.main`` in one helper process per
command (:data:`DRIVER`), case after case: the signal is sent by the
process to itself at a chosen moment (while the kernels load, while the
world is built, mid-run, at the end), so every moment is hit every time,
and the kernels are loaded once. A few cases send real signals to a real
``driftframe`` process, and one kills the X server under ``play``.

Sections: SIGNALS (record, play), FULL DISK, LOST DISPLAY, OUTPUTS,
INPUT FILES, LIMITS. (Batch cases: the batch section, added by its owner.)
"""
from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import textwrap

import pytest

from driftframe.cli import main
from driftframe.framework.hashlog import first_divergence, read_hash_log
from driftframe.framework.input import load_track

SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")
#: compile: while the kernels load; setup: while the world is built; mid: at step 12; end: in the last
#: frame and again while the video is finished (record), while the flight is written (play); again: at
#: step 12, then once more at once (record: in the next step; play: while the flight is written).
MOMENTS = ("compile", "setup", "mid", "end", "again")


def _parts(folder) -> list[str]:
    """Part files (ours or anyone's) anywhere under ``folder``."""
    return [os.path.join(d, n) for d, dirs, names in os.walk(folder) for n in names + dirs
            if ".part" in n or n.endswith(".old")]


def _check_flight(track_path, log_path, at_least=0):
    """The track and the hash log agree on the steps flown, the log numbered 1..N: valid to the last step."""
    track = load_track(track_path)
    lines = read_hash_log(log_path)
    assert [s for s, _ in lines] == list(range(1, len(lines) + 1))
    assert track.info["steps"] == len(lines) >= at_least, (track.info, len(lines))
    return len(lines)


# The helper process: runs main() for each case it reads, with a fault injected; prints one JSON line a case.
DRIVER = textwrap.dedent(r'''
    import contextlib, io, json, os, signal, sys, threading, time
    import esper
    import driftframe.app as app
    import driftframe.cli as cli
    import driftframe.window as window
    from driftframe.framework import output, recorder

    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):   # a test runner may have them ignored
        signal.signal(s, signal.default_int_handler if s == signal.SIGINT else signal.SIG_DFL)
    real_make, real_load, real_keep, real_write = app.make_world, app.load_kernels, window._Flight.keep, \
        output.PartFile.write
    real_finish = recorder._H264Sink.finish

    class Fault(esper.Processor):
        """A system that sends the signal to this process in step ``at`` (signum None: raises instead)."""
        stage, after, before, reads, writes = None, ("input",), ("camera",), (), ()
        def __init__(self, at, signum):
            self.at, self.signum = at, signum
        def process(self, dt):
            if self.world.step_count + 1 == self.at:
                if self.signum is None:
                    raise RuntimeError("a fault injected in step %d" % self.at)
                os.kill(os.getpid(), self.signum)

    for line in sys.stdin:
        case = json.loads(line)
        signum = getattr(signal, case.get("signal") or "SIGTERM")
        moment = case.get("moment")
        app.make_world, app.load_kernels, window._Flight.keep = real_make, real_load, real_keep
        output.PartFile.write = real_write
        recorder._H264Sink.finish = real_finish

        def make_world(*a, **k):
            world, demo = real_make(*a, **k)
            if threading.current_thread() is not threading.main_thread():
                pass                          # the kernels' warm-up world (cli._compile's helper thread)
            elif moment == "setup":
                os.kill(os.getpid(), signum)
                time.sleep(0.05)
            elif moment == "error":
                world.add_system(Fault(case["at"], None))
            elif moment in ("mid", "again") or moment == "end" and case["argv"][0] == "record":
                world.add_system(Fault(case["at"], signum))
                if moment == "again" and case["argv"][0] == "record":
                    world.add_system(Fault(case["at"] + 1, signum))
            return world, demo
        app.make_world = make_world
        if moment == "compile":
            def load(*a, **k):        # (loads nothing: a real load would go on beside the next case)
                os.kill(os.getpid(), signum)
                time.sleep(0.3)
            app.load_kernels = load
        if moment == "end" and case["argv"][0] == "record":
            def finish(self):                # a second signal while the video is being finished
                os.kill(os.getpid(), signum)
                return real_finish(self)
            recorder._H264Sink.finish = finish
        if moment in ("end", "again") and case["argv"][0] == "play":
            def keep(self):                  # the signal arrives while the flight is being written
                os.kill(os.getpid(), signum)
                return real_keep(self)
            window._Flight.keep = keep
        if case.get("full_disk"):            # the hash log's file system fills up after some lines
            what, after = case["full_disk"]
            def write(self, data, _n=[0]):
                if self.what == what:
                    _n[0] += 1
                    if _n[0] > after:
                        self._failed(OSError(28, "No space left on device"))
                return real_write(self, data)
            output.PartFile.write = write
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(err):
            try:
                rc = cli.main(case["argv"])
            except BaseException as e:
                import traceback
                traceback.print_exc(file=err)
                rc = -1
        print(json.dumps({"id": case["id"], "rc": rc, "err": err.getvalue()}), flush=True)
''')


def _drive(cases, env=None, timeout=240):
    """Run ``cases`` (dicts with id, argv, signal, moment, ...) in one helper process; {id: result}."""
    proc = subprocess.run([sys.executable, "-c", DRIVER], input="".join(json.dumps(c) + "\n" for c in cases),
                          capture_output=True, text=True, timeout=timeout, env={**os.environ, **(env or {})})
    out = {}
    for line in proc.stdout.splitlines():
        if line.startswith("{"):
            r = json.loads(line)
            out[r["id"]] = r
    assert len(out) == len(cases), f"the helper stopped early (status {proc.returncode}): {proc.stderr[-3000:]}"
    return out


# -- SIGNALS: record -------------------------------------------------------------------------------
RECORD_STEPS = 30                  # --seconds 0.5 at 60 fps: 30 frames of one step each


@pytest.fixture(scope="module")
def record_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("record")
    cases = []
    for sig in SIGNALS:
        for moment in MOMENTS:
            d = root / f"{sig}-{moment}"
            d.mkdir()
            cases.append({"id": f"{sig}-{moment}", "signal": sig, "moment": moment,
                          "at": {"mid": 12, "again": 12, "end": RECORD_STEPS}.get(moment),
                          "argv": ["record", "asteroids", "--seconds", "0.5", "--size", "64x36", "--quiet",
                                   "-o", str(d / "v.mp4"), "--hash-log", str(d / "h.txt")]})
    d = root / "full-log"                  # FULL DISK: the hash log's file system fills after 10 lines
    d.mkdir()
    cases.append({"id": "full-log", "full_disk": ["hash log", 10],
                  "argv": ["record", "asteroids", "--seconds", "0.5", "--size", "64x36", "--quiet",
                           "-o", str(d / "v.mp4"), "--hash-log", str(d / "h.txt")]})
    return root, _drive(cases)


@pytest.mark.gl
@pytest.mark.parametrize("moment", MOMENTS)
@pytest.mark.parametrize("sig", SIGNALS)
def test_record_stopped_by_a_signal_keeps_what_it_finished(record_runs, sig, moment):
    from videos import mp4_frames

    root, runs = record_runs
    r, d = runs[f"{sig}-{moment}"], root / f"{sig}-{moment}"
    signum = getattr(signal, sig)
    assert r["rc"] == 128 + signum, r["err"]
    assert "Traceback" not in r["err"], r["err"]
    assert _parts(d) == []
    if moment in ("compile", "setup"):               # before the first step: nothing was made
        assert sorted(os.listdir(d)) == [], r["err"]
        assert f"interrupted ({sig})" in r["err"]
        return
    steps = len(read_hash_log(d / "h.txt"))
    _, frames = mp4_frames(d / "v.mp4")
    # the log holds every step taken; the video every frame finished (one step each)
    assert len(frames) == steps >= (RECORD_STEPS if moment == "end" else 12), (len(frames), steps)
    assert f"wrote {d / 'v.mp4'} ({len(frames)} frames" in r["err"]


# -- SIGNALS: play ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def display():
    import shutil
    if not shutil.which("Xvfb"):
        pytest.fail("play tests need Xvfb: `./run tests` installs it (apt-get install xvfb)")
    from driftframe.xvfb import virtual_display
    with virtual_display((640, 360)) as name:
        yield name


@pytest.fixture(scope="module")
def play_runs(tmp_path_factory, display):
    root = tmp_path_factory.mktemp("play")
    cases = []
    for sig in SIGNALS:
        for moment in MOMENTS:
            d = root / f"{sig}-{moment}"
            d.mkdir()
            cases.append({"id": f"{sig}-{moment}", "signal": sig, "moment": moment, "at": 12,
                          "argv": ["play", "asteroids", "--size", "160x90",
                                   "--frames", "30" if moment == "end" else "100000",
                                   "--screenshots", str(d), "--save-track", str(d / "t.json"),
                                   "--hash-log", str(d / "h.txt"), "--state-out", str(d / "s.json")]})
    d = root / "error"                   # an exception in step 12, after the input system took its input
    d.mkdir()
    cases.append({"id": "error", "moment": "error", "at": 12,
                  "argv": ["play", "asteroids", "--size", "160x90", "--save-track", str(d / "t.json"),
                           "--hash-log", str(d / "h.txt")]})
    for which, what, after in (("log", "hash log", 2), ("track", "track", 0)):     # FULL DISK
        d = root / f"full-{which}"
        d.mkdir()
        cases.append({"id": f"full-{which}", "full_disk": [what, after],
                      "argv": ["play", "asteroids", "--size", "160x90", "--frames", "60", "--save-track",
                               str(d / "t.json"), "--hash-log", str(d / "h.txt")]})
    return root, _drive(cases, env={"DISPLAY": display})


@pytest.mark.window
@pytest.mark.parametrize("moment", MOMENTS)
@pytest.mark.parametrize("sig", SIGNALS)
def test_play_stopped_by_a_signal_keeps_the_flight(play_runs, sig, moment):
    root, runs = play_runs
    r, d = runs[f"{sig}-{moment}"], root / f"{sig}-{moment}"
    signum = getattr(signal, sig)
    assert r["rc"] == 128 + signum, r["err"]
    assert "Traceback" not in r["err"], r["err"]
    assert _parts(d) == []
    if moment == "compile":                          # before the window: no flight yet, nothing made
        assert os.listdir(d) == [] and f"interrupted ({sig})" in r["err"]
        return
    n = _check_flight(d / "t.json", d / "h.txt", at_least=12 if moment in ("mid", "again") else 0)
    assert f"driftframe: interrupted ({sig}) after {n} steps; wrote the track {d / 't.json'} ({n} steps) " \
           f"and the hash log {d / 'h.txt'} ({n} steps)" in r["err"]
    assert json.loads((d / "s.json").read_text())["steps"] == n


@pytest.mark.window
def test_play_keeps_the_flight_to_the_last_whole_step_when_a_step_raises(play_runs):
    root, runs = play_runs
    r, d = runs["error"], root / "error"
    assert "RuntimeError: a fault injected in step 12" in r["err"]      # a bug is a bug: its traceback shows
    n = _check_flight(d / "t.json", d / "h.txt")
    assert n == 11                                                       # step 12 never finished
    assert f"driftframe: stopped by an error after 11 steps; wrote the track {d / 't.json'} (11 steps)" in r["err"]
    assert _parts(d) == []


def _default_signals():
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, signal.SIG_DFL)


def _start_play(display, d, *extra):
    return subprocess.Popen([sys.executable, "-m", "driftframe", "play", "asteroids", "--size", "160x90",
                             "--save-track", str(d / "t.json"), "--hash-log", str(d / "h.txt"), *extra],
                            env={**os.environ, "DISPLAY": display}, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=_default_signals)


def _wait_playing(proc):
    seen = []
    while not (seen and seen[-1].startswith("playing asteroids")):   # said once the loop starts
        seen.append(proc.stderr.readline())
        assert seen[-1], "".join(seen)


@pytest.mark.window
@pytest.mark.gl
def test_a_real_sigterm_to_play_keeps_a_flight_that_record_replays_step_for_step(display, tmp_path):
    import time
    proc = _start_play(display, tmp_path)
    try:
        _wait_playing(proc)
        time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143 and "Traceback" not in err, err
    n = _check_flight(tmp_path / "t.json", tmp_path / "h.txt", at_least=1)
    # the flight is whole: re-rendered from the track, every step's state is the same
    assert main(["record", "asteroids", "--track", str(tmp_path / "t.json"), "--size", "64x36", "--quiet",
                 "-o", str(tmp_path / "r.gif"), "--hash-log", str(tmp_path / "r.txt")]) == 0
    assert len(read_hash_log(tmp_path / "r.txt")) == n
    assert first_divergence(tmp_path / "h.txt", tmp_path / "r.txt") is None


# -- SIGNALS: while the command's modules load ----------------------------------------------------
# main() imports the GL, kernel and recorder modules (numpy, numba: a tenth of a second) before any
# command runs; a signal then must still be one line and 128 + n. The helper signals itself when the
# first of them is imported, from a fresh interpreter where none is loaded yet.
IMPORTING = textwrap.dedent(r'''
    import os, signal, sys
    import driftframe.cli as cli

    class Finder:
        def find_spec(self, name, path=None, target=None):
            if name == "driftframe.framework.gl":
                sys.meta_path.remove(self)
                os.kill(os.getpid(), getattr(signal, sys.argv[1]))
            return None
    sys.meta_path.insert(0, Finder())
    sys.exit(cli.main(["list"]))
''')


@pytest.mark.parametrize("sig", SIGNALS)
def test_a_signal_while_the_modules_load_is_one_line_and_128_plus_n(sig):
    proc = subprocess.run([sys.executable, "-c", IMPORTING, sig], capture_output=True, text=True, timeout=60,
                          preexec_fn=_default_signals)
    assert proc.returncode == 128 + getattr(signal, sig), proc.stderr      # not -n: killed without a word
    assert proc.stderr == f"driftframe: interrupted ({sig})\n" and proc.stdout == ""


# -- LOST DISPLAY ----------------------------------------------------------------------------------
@pytest.mark.window
def test_play_keeps_the_flight_when_the_x_server_dies(tmp_path):
    import time

    from driftframe.xvfb import start_xvfb, stop_xvfb
    server, name = start_xvfb((320, 180))
    try:
        proc = _start_play(name, tmp_path)
        try:
            _wait_playing(proc)
            time.sleep(0.5)
            stop_xvfb(server)
            _, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
    finally:
        stop_xvfb(server)
    assert proc.returncode == 1, err
    assert "Traceback" not in err and "XIO" not in err, err
    n = _check_flight(tmp_path / "t.json", tmp_path / "h.txt", at_least=1)
    assert f"lost the display {name!r}" in err and f"the track {tmp_path / 't.json'} ({n} steps)" in err
    assert _parts(tmp_path) == []


# -- FULL DISK -------------------------------------------------------------------------------------
@pytest.mark.gl
def test_a_full_disk_under_the_hash_log_keeps_the_video_and_names_the_log(record_runs):
    # (the case runs with the signal cases, in the same helper process)
    from videos import mp4_frames

    root, runs = record_runs
    r, d = runs["full-log"], root / "full-log"
    assert r["rc"] == 1 and "Traceback" not in r["err"], r["err"]
    assert f"cannot write the hash log {str(d / 'h.txt')!r}: no space left on the device" in r["err"]
    assert len(mp4_frames(d / "v.mp4")[1]) == RECORD_STEPS             # the healthy video is kept whole
    assert sorted(os.listdir(d)) == ["v.mp4"]                        # the log's part file is gone, nothing else


@pytest.mark.window
@pytest.mark.parametrize("which", ["log", "track"])
def test_a_full_disk_in_play_keeps_the_other_output_and_names_the_file(play_runs, which):
    root, runs = play_runs
    r, d = runs[f"full-{which}"], root / f"full-{which}"
    assert r["rc"] == 1 and "Traceback" not in r["err"], r["err"]
    failed, kept = ("h.txt", "t.json") if which == "log" else ("t.json", "h.txt")
    assert str(d / failed) in r["err"] and "no space left on the device" in r["err"]
    assert sorted(os.listdir(d)) == [kept]
    if which == "log":
        assert load_track(d / kept).info["steps"] >= 1
    else:
        assert len(read_hash_log(d / kept)) >= 1


# -- OUTPUTS ---------------------------------------------------------------------------------------
def _fail_if_compiling(monkeypatch):
    """Outputs are checked before any compile or build: reaching them is a failure here."""
    import driftframe.app as app

    def boom(*a, **k):
        raise AssertionError("reached the compile before the outputs were checked")
    monkeypatch.setattr(app, "load_kernels", boom)
    monkeypatch.setattr(app, "make_world", boom)


@pytest.mark.parametrize("argv, message", [
    (["-o", "{d}/a.mp4", "--hash-log", "{d}/a.mp4"], "-o and --hash-log name the same file"),
    (["-o", "{d}/f/", "--hash-log", "{d}/f"], "-o and --hash-log name the same file"),
    (["-o", "{d}/a.mp4", "--hash-log", "{d}/sub/../a.mp4"], "-o and --hash-log name the same file"),
])
def test_two_options_naming_one_path_are_refused_and_nothing_is_made(tmp_path, capsys, monkeypatch, argv,
                                                                     message):
    (tmp_path / "sub").mkdir()
    _fail_if_compiling(monkeypatch)
    assert main(["record", "asteroids", *(a.format(d=tmp_path) for a in argv)]) == 2
    assert message in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == ["sub"]


def test_an_existing_hash_log_is_refused_without_overwrite_and_kept(tmp_path, capsys, monkeypatch):
    (tmp_path / "h.txt").write_text("precious\n")
    _fail_if_compiling(monkeypatch)
    assert main(["record", "asteroids", "-o", str(tmp_path / "v.mp4"), "--hash-log", str(tmp_path / "h.txt")]) == 2
    assert "exists; pass --overwrite" in capsys.readouterr().err
    assert (tmp_path / "h.txt").read_text() == "precious\n"
    for option in ("--save-track", "--hash-log", "--state-out"):
        assert main(["play", "asteroids", option, str(tmp_path / "h.txt")]) == 2
        assert f"{option} '{tmp_path / 'h.txt'}' exists" in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == ["h.txt"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_an_unwritable_output_folder_is_found_before_the_compile(tmp_path, capsys, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    _fail_if_compiling(monkeypatch)
    try:
        assert main(["record", "asteroids", "-o", str(ro / "v.mp4")]) == 2
    finally:
        ro.chmod(0o755)
    assert "is not writable (permission denied)" in capsys.readouterr().err


def test_an_unwritable_file_system_is_found_before_the_compile(capsys, monkeypatch):
    # /proc refuses new files whoever asks (root too): the probe finds it before the costly part
    _fail_if_compiling(monkeypatch)
    assert main(["record", "asteroids", "-o", "/proc/v.mp4"]) == 2
    assert "'/proc' is not writable" in capsys.readouterr().err
    assert main(["record", "asteroids", "-o", "/proc/f/"]) == 2


def test_a_file_name_too_long_is_refused_before_any_folder_is_made(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _fail_if_compiling(monkeypatch)
    long = "x" * 300
    assert main(["record", "asteroids", "--hash-log", f"{long}.txt"]) == 2       # (default -o: out/asteroids.mp4)
    assert main(["record", "asteroids", "-o", f"{long}.mp4"]) == 2
    assert main(["record", "asteroids", "-o", f"{long}/"]) == 2
    err = capsys.readouterr().err
    assert err.count("the file name is 304 bytes long") == 2 and "Traceback" not in err
    assert os.listdir(tmp_path) == []                                           # no out/ made


def test_outputs_follow_the_umask(tmp_path):
    from driftframe.framework.input import Hold, Track, save_track
    from driftframe.framework.output import write_file
    old = os.umask(0o027)
    try:
        p = save_track(Track((Hold(0, 1, yaw=1.0),)), tmp_path / "t.json")
        q = write_file(tmp_path / "s.json", "{}")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(p).st_mode) == 0o640 and stat.S_IMODE(os.stat(q).st_mode) == 0o640


def test_a_file_that_appears_meanwhile_is_never_replaced(tmp_path):
    from driftframe.framework.output import OutputExistsError, PartFile
    f = PartFile(tmp_path / "h.txt", what="hash log")
    f.write("1 abc\n")
    (tmp_path / "h.txt").write_text("someone else's\n")
    with pytest.raises(OutputExistsError):
        f.commit()
    assert (tmp_path / "h.txt").read_text() == "someone else's\n"
    assert os.listdir(tmp_path) == ["h.txt"]


# -- INPUT FILES -----------------------------------------------------------------------------------
def _special_files(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    big = tmp_path / "big"
    with open(big, "wb") as f:
        f.truncate(600 << 20)                    # sparse: 600 MiB long, no disk used
    binary = tmp_path / "binary"
    binary.write_bytes(b"\x00\x89PNG\r\n\x1a\n\xff\xfe")
    return {"fifo": (fifo, "it is a FIFO"), "device": ("/dev/zero", "it is a device"),
            "big": (big, "600 MiB; the limit is"), "binary": (binary, "is not UTF-8 text")}


@pytest.mark.parametrize("kind", ["fifo", "device", "big", "binary"])
@pytest.mark.parametrize("reader", ["track", "bindings", "hash log"])
def test_every_input_reader_refuses_fifos_devices_huge_and_binary_files_by_name(tmp_path, capsys, monkeypatch,
                                                                              reader, kind):
    import time
    path, words = _special_files(tmp_path)[kind]
    _fail_if_compiling(monkeypatch)
    argv = {"track": ["record", "asteroids", "-o", str(tmp_path / "v.mp4"), "--track", str(path)],
            "bindings": ["keys", "--bindings", str(path)],
            "hash log": ["diverge", str(path), str(path)]}[reader]
    if kind == "binary" and reader == "hash log":
        words = "is not 'STEP HASH'"
    t0 = time.process_time()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert time.process_time() - t0 < 2.0                          # nothing read whole, nothing blocked
    assert err.startswith(f"driftframe: error: {path}: ") and words in err, err
    assert err.count("\n") == 1


@pytest.mark.parametrize("text, message", [
    ("keys = 5", "keys must be a table, got 5"),
    ("[gamepad]\naxes = 5", "gamepad.axes must be a table, got 5"),
    ("[gamepad.buttons]\nA = ['kill_rotation']", "gamepad.buttons.A must be an action name, got ['kill_rotation']"),
    ("[gamepad]\ncurve = 1" + "0" * 400, "gamepad.curve must be a number in [0.2, 5.0], got an integer of about"),
    ("[gamepad]\ncurve = 1" + "0" * 5000, "curve (line 2): an integer of over 4,300 digits"),
])
def test_wrong_typed_bindings_are_one_line_naming_file_entry_and_value(tmp_path, capsys, text, message):
    p = tmp_path / "b.toml"
    p.write_text(text)
    assert main(["keys", "--bindings", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"driftframe: error: {p}: {message}") and err.count("\n") == 1, err


def _track(**info):
    return json.dumps({"format": "driftframe track", "version": 1, **info, "holds": [], "presses": []})


@pytest.mark.parametrize("text, message", [
    (_track().replace('"holds": []', '"holds": [{"start": 1' + "0" * 400 + ', "end": 2}]'),
     "holds[0].start: 100000000000... (401 digits) is not a finite number"),
    (_track().replace('"holds": []', '"holds": [{"start": 1' + "0" * 5000 + ', "end": 2}]'),
     "(5001 digits) is not a finite number"),
    (_track(seed=1).replace('"seed": 1', '"seed": 1e400'), "seed: 1e400 is not a finite number"),
    ("[" * 100_000 + "]" * 100_000, "its JSON is nested too deeply"),
    (_track(camera="sideways"), "camera 'sideways' is not one of cockpit, chase, overhead"),
    (_track(sky="plaid"), "sky 'plaid' is not one of lines, starfield"),
    (_track(dt=0.01), "dt 0.01 is not asteroids's step 0.016666666666666666 s"),
])
def test_bad_tracks_are_one_line_naming_file_entry_and_value(tmp_path, capsys, monkeypatch, text, message):
    p = tmp_path / "t.json"
    p.write_text(text)
    _fail_if_compiling(monkeypatch)
    assert main(["record", "asteroids", "-o", str(tmp_path / "v.mp4"), "--track", str(p)]) == 2
    err = capsys.readouterr().err
    assert str(p) in err and message in err and err.count("\n") == 1, err


def test_a_superscript_digit_in_a_hash_log_is_named(tmp_path, capsys):
    p = tmp_path / "h.txt"
    p.write_text("1 ab\n² cd\n")
    assert main(["diverge", str(p), str(p)]) == 2
    assert capsys.readouterr().err == f"driftframe: error: {p}: line 2 is not 'STEP HASH': '² cd'\n"


def test_a_toml_string_with_quotes_and_backslashes_reads_back(tmp_path):
    import tomllib
    from pathlib import Path

    from driftframe.framework.bindings import Bindings, bindings_toml
    weird = Path(tmp_path / 'a "b" \\c\x7f\td.txt')
    assert tomllib.loads(bindings_toml(Bindings(mappings=weird)))["gamepad"]["mappings"] == str(weird)


# -- LIMITS ----------------------------------------------------------------------------------------
def test_numbers_no_float_holds_are_refused_by_name():
    from driftframe.components.body import Mass
    with pytest.raises(ValueError, match=r"Mass.kg is too large for a float .* about 401 digits"):
        Mass(10**400)


@pytest.mark.gl
def test_a_gif_frame_longer_than_655_s_is_split_and_a_vanishing_fps_is_refused(ctx, tmp_path):
    from PIL import Image

    from driftframe.components.body import Transform, Velocity
    from driftframe.components.camera import Camera
    from driftframe.components.render import ModelRef
    from driftframe.framework.recorder import record
    from driftframe.framework.world import World
    from driftframe.systems.movement import MovementSystem
    from driftframe.rendering import attach

    w = World()
    try:
        w.add_system(MovementSystem())
        ship = w.create_entity(Transform((0.0, 0.0, 0.0)), ModelRef("ship"))
        w.create_entity(Camera(target=ship, mode="chase"))
        w.create_entity(Transform((0.0, 0.0, 8.0)), Velocity((3.0, 0.0, 0.0)), ModelRef("sphere"))
        attach(w, ctx, (32, 24))
        with pytest.raises(ValueError, match=r"fps must be at least 1/10000 .* got 1e-300"):
            record(w, tmp_path / "z.gif", frames=2, fps=1e-300, progress=False)
        res = record(w, tmp_path / "slow.gif", frames=2, fps=1 / 1000, progress=False)   # 1,000 s a frame
    finally:
        w.close()
    assert res.frames == 2
    with Image.open(tmp_path / "slow.gif") as im:
        delays = []
        for k in range(im.n_frames):
            im.seek(k)
            delays.append(im.info["duration"])
    assert sum(delays) == 2_000_000 and max(delays) <= 655_350 and len(delays) == 4, delays
