"""`driftframe batch` under faults: stop signals at three moments, a second Ctrl-C stuck in C code, a
worker killed, the batch process SIGKILLed, an --overwrite batch stopped mid-run.

Each case runs the real command in a process group of its own and checks what the issue asked: no
finished output lost (every output there is whole, and so is every old output a stopped run was
replacing), no process left behind, no traceback, the signal reported as itself with 128 + n. Runs are
tiny (64x64, a few seconds of simulated time at most) and the kernels come from the shared warm cache.
"""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from videos import mp4_frames

from driftframe.batch_report import COLUMNS

HERE = Path(__file__).parent
EXE = [sys.executable, "-m", "driftframe"]
SUMMARY = {"summary.csv", "summary.md", "summary.png", "journal.jsonl"}


def _start(tmp_path, toml: str, *args, out="o"):
    spec = tmp_path / "s.toml"
    spec.write_text(toml)
    return subprocess.Popen(EXE + ["batch", str(spec), "-o", str(tmp_path / out), "--quiet", *args], cwd=HERE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _descendants(pid: int) -> set[int]:
    """Every process below ``pid`` now (workers, multiprocessing's resource tracker)."""
    found, todo = set(), [pid]
    while todo:
        p = todo.pop()
        try:
            tasks = os.listdir(f"/proc/{p}/task")
        except OSError:
            continue
        for t in tasks:
            try:
                kids = Path(f"/proc/{p}/task/{t}/children").read_text().split()
            except OSError:
                continue
            for k in map(int, kids):
                if k not in found:
                    found.add(k)
                    todo.append(k)
    return found


def _alive(pids) -> list[int]:
    """Those of ``pids`` still running (a zombie waiting for its reaper has ended)."""
    out = []
    for pid in pids:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state != "Z":
            out.append(pid)
    return out


def _wait_for(cond, proc, timeout=240.0, what=""):
    deadline = time.monotonic() + timeout
    seen: set[int] = set()
    while not cond():
        seen |= _descendants(proc.pid)
        assert proc.poll() is None, (what, proc.communicate())
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.02)
    return seen | _descendants(proc.pid)


def _left_after(children, seconds: float) -> list[int]:
    """Those of ``children`` still running ``seconds`` from now, or none as soon as all have ended (the
    check a fixed sleep of ``seconds`` then :func:`_alive` makes, without waiting out the sleep)."""
    deadline = time.monotonic() + seconds
    while _alive(children) and time.monotonic() < deadline:
        time.sleep(0.02)
    return _alive(children)


def _outputs(folder: Path, frames: int) -> list[str]:
    """Every output in ``folder`` is whole (``frames`` frames), no temporary file is left; their names."""
    names = sorted(p.name for p in folder.iterdir() if p.name not in SUMMARY)
    assert not [n for n in names if n.startswith(".")], names
    for n in names:
        assert len(mp4_frames(folder / n)[1]) == frames, n
    return names


RECORDINGS = 'scene = "batch_scenes:box"\nseeds = "0..5"\nseconds = 2\nsize = "64x64"\nfps = 30\n' \
             'output = "box-{seed}.mp4"\n'


@pytest.mark.parametrize("sig,moment,jobs", [
    (signal.SIGTERM, "starting", 2),       # while the workers start (import driftframe, load the kernels)
    (signal.SIGHUP, "running", 2),         # after the first output, with runs going on
    (signal.SIGTERM, "running", 1),        # serial: the run in this process
    (signal.SIGINT, "ending", 2),          # the last runs going: stopped, the rest kept
])
def test_a_stop_signal_stops_the_batch_keeps_what_finished_and_reports_the_signal(tmp_path, sig, moment, jobs):
    proc = _start(tmp_path, RECORDINGS, "-j", str(jobs))
    out = tmp_path / "o"
    if moment == "starting":
        children = _wait_for(lambda: len(_descendants(proc.pid)) >= 2, proc, what="the workers")
    else:
        need = 1 if moment == "running" else 4
        children = _wait_for(lambda: len(list(out.glob("box-*.mp4"))) >= need, proc, what="outputs")
    os.killpg(proc.pid, sig)                 # as a terminal or a service manager does: the whole group
    stdout, stderr = proc.communicate(timeout=60)
    name = signal.Signals(sig).name
    assert proc.returncode == 128 + sig, stderr
    assert f"interrupted ({name})" in stderr and "Traceback" not in stderr and "run failed" not in stderr, stderr
    names = _outputs(out, 60)
    # the summary of what ran: each finished run's row, and the journal --resume reads
    rows = (out / "summary.csv").read_text().splitlines()[1:]
    assert sorted(Path(r.split(",")[COLUMNS.index("output")]).name for r in rows) == names
    assert len((out / "journal.jsonl").read_text().splitlines()) == len(names) < 6
    assert f"Stopped by {name}" in (out / "summary.md").read_text()
    assert not _left_after(children, 0.5), "processes left behind"
    # --resume runs the rest, and only the rest
    res = subprocess.run(EXE + ["batch", str(tmp_path / "s.toml"), "-o", str(out), "--quiet", "--resume", "-j", "1"],
                         cwd=HERE, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert (f"resuming: {len(names)} of 6 runs are done already" in res.stderr) == bool(names), res.stderr
    assert _outputs(out, 60) == [f"box-{s}.mp4" for s in range(6)]
    assert len((out / "summary.csv").read_text().splitlines()) == 7
    assert len((out / "journal.jsonl").read_text().splitlines()) == 6


def test_sigterm_during_an_overwrite_keeps_the_old_output(tmp_path):
    # The recorder kept the frames written so far on SIGTERM, moved that short file over the old
    # output, and the batch then deleted it: the old output was lost. Now a stopped run leaves it.
    out = tmp_path / "o"
    out.mkdir()
    old = {f"box-{s}.mp4": f"an old output {s}".encode() for s in range(6)}
    for n, data in old.items():
        (out / n).write_bytes(data)
    proc = _start(tmp_path, RECORDINGS, "-j", "1", "--overwrite")
    _wait_for(lambda: any(p.name.startswith(".box-0.mp4.") for p in out.iterdir()), proc, what="the first run")
    time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 143 and "interrupted (SIGTERM)" in stderr, stderr
    for n, data in old.items():
        now = (out / n).read_bytes()
        assert now == data or len(mp4_frames(out / n)[1]) == 60, n       # the old bytes, or a whole new run
    assert (out / "box-5.mp4").read_bytes() == old["box-5.mp4"]
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_a_second_ctrl_c_aborts_within_a_second_even_in_c_code(tmp_path):
    # the run sits in Python called back from C for 20 s, as a first run's compile does (numba's
    # compiler calls back into Python through ctypes, which prints and drops a KeyboardInterrupt)
    proc = _start(tmp_path, 'scene = "batch_scenes:in_c_callback"\nseconds = 0.1\nsize = "64x64"\n'
                            'output = "c.mp4"\n', "-j", "1")
    _wait_for(lambda: (tmp_path / "o").is_dir(), proc, what="the output folder")
    time.sleep(1.0)                           # the run is in its scene's C call now
    os.killpg(proc.pid, signal.SIGINT)
    time.sleep(0.3)
    t0 = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    took = time.monotonic() - t0
    assert proc.returncode == 130, stderr
    assert took < 1.0, f"the second Ctrl-C took {took:.2f} s"
    assert "aborted (SIGINT)" in stderr and "Traceback" not in stderr and "Exception ignored" not in stderr, stderr
    assert [p.name for p in (tmp_path / "o").iterdir() if p.name not in SUMMARY] == []


def test_a_second_ctrl_c_aborts_within_a_second_in_a_real_first_compile(tmp_path):
    # an empty kernel cache: the run compiles its kernels (numba, for several seconds); both signals land
    # while it does, as soon as the first kernel is cached (the first Ctrl-C cannot stop a compile)
    cache = tmp_path / "empty-cache"
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "batch_scenes:box"\nseconds = 0.2\nsize = "64x64"\noutput = "c.mp4"\n')
    proc = subprocess.Popen(EXE + ["batch", str(spec), "-o", str(tmp_path / "o"), "--quiet", "-j", "1"], cwd=HERE,
                            env={**os.environ, "NUMBA_CACHE_DIR": str(cache)}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    _wait_for(lambda: any(p.suffix == ".nbi" for p in cache.rglob("*")), proc, timeout=60, what="the compile")
    os.killpg(proc.pid, signal.SIGINT)
    time.sleep(0.2)
    t0 = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    took = time.monotonic() - t0
    assert proc.returncode == 130, stderr
    assert took < 1.0, f"the second Ctrl-C took {took:.2f} s"
    assert "aborted (SIGINT)" in stderr and "Traceback" not in stderr and "Exception ignored" not in stderr, stderr
    assert [p.name for p in (tmp_path / "o").iterdir() if p.name not in SUMMARY] == []     # no part file either


@pytest.mark.parametrize("moment", ["starting", "recording"])
def test_sigkill_of_the_batch_leaves_no_process_behind(tmp_path, moment):
    proc = _start(tmp_path, RECORDINGS.replace("seconds = 2", "seconds = 20"), "-j", "3")
    out = tmp_path / "o"
    if moment == "starting":                # the workers importing driftframe (a SIGTERM handler raising
        children = _wait_for(lambda: len(_descendants(proc.pid)) >= 2, proc, what="the workers")    # there
        time.sleep(0.3)                     # was printed as 'Exception ignored ... _Gone' by an import lock)
    else:                                   # two workers recording (their temporary files are there)
        children = _wait_for(lambda: len([p for p in out.glob(".box-*")]) >= 2, proc, what="two recording")
    assert len(children) >= 2
    os.kill(proc.pid, signal.SIGKILL)       # the batch process alone: its workers must notice by themselves
    _, stderr = proc.communicate(timeout=10)    # (read to the end: the workers share the pipe)
    left = _left_after(children, 2.0)
    assert not left, f"left behind: {left}"
    assert "Traceback" not in stderr and "Exception ignored" not in stderr, stderr
    # no worker's part file left (the batch process's own run, SIGKILLed, leaves its part: the next run
    # writing that output removes it, as for any killed process; framework/output.py)
    assert [p.name for p in out.glob(".*") if f".{proc.pid}." not in p.name] == []


def test_a_killed_worker_is_reported_once_and_its_run_done_again(tmp_path):
    proc = _start(tmp_path, RECORDINGS.replace("seconds = 2", "seconds = 6"), "-j", "3")
    out = tmp_path / "o"
    _wait_for(lambda: len([p for p in out.glob(".box-*")]) >= 2, proc, what="the workers recording")
    busy = sorted(_descendants(proc.pid))
    victim = None
    for pid in busy:                          # a worker, not the resource tracker
        if "spawn_main" in Path(f"/proc/{pid}/cmdline").read_text():
            victim = pid
            break
    assert victim is not None, busy
    os.kill(victim, signal.SIGKILL)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 0, stderr
    assert stderr.count(f"(pid {victim}) killed by SIGKILL") == 1 and "running it again" in stderr, stderr
    assert "Traceback" not in stderr and "InvalidStateError" not in stderr
    assert "6 of 6 runs ok, 0 failed" in stdout
    assert _outputs(out, 180) == [f"box-{s}.mp4" for s in range(6)]


# -- a full disk ---------------------------------------------------------------------------------
def _file_size_limit(nbytes):
    """In the child: every file it writes stops at ``nbytes`` (EFBIG, as a full disk's ENOSPC; SIGXFSZ,
    which would kill it, ignored), so the disk "fills" at a chosen file without a mount."""
    def limit():
        import resource
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))
    return limit


@pytest.mark.parametrize("full", ["output", "journal"])
def test_a_full_disk_stops_the_batch_keeps_what_finished_and_names_the_file(tmp_path, full):
    # output: the second run's recording (200x200, about 37 KB) does not fit in 24 KB; the first (32x32,
    # 14 KB) does. journal: headless runs, the journal's sixth line (about 700 bytes each) passes 4 KB.
    if full == "output":
        toml = 'scene = "batch_scenes:box"\nseeds = "0..3"\nseconds = 0.5\nsize = ["32x32", "200x200"]\n' \
               'fps = 30\noutput = "box-{index}.mp4"\n'
        limit, bad = 24_000, "box-1.mp4"
    else:
        toml, limit, bad = 'scene = "batch_scenes:box"\nseeds = "0..40"\nseconds = 0.1\n', 4096, "journal.jsonl"
    spec = tmp_path / "s.toml"
    spec.write_text(toml)
    out = tmp_path / "o"
    res = subprocess.run(EXE + ["batch", str(spec), "-o", str(out), "--quiet", "-j", "1"], cwd=HERE,
                         capture_output=True, text=True, timeout=120, preexec_fn=_file_size_limit(limit))
    assert res.returncode == 1, res.stderr
    assert "Traceback" not in res.stderr and "run failed" not in res.stderr, res.stderr
    first = res.stderr.splitlines()[0]
    assert first.startswith(f"driftframe: error: cannot write {'the batch journal ' * (full == 'journal')}"
                            f"'{out / bad}': no space left on the device") and "the batch stopped: " in first, first
    journal = (out / "journal.jsonl").read_text().splitlines()
    assert all(line.endswith("}") for line in journal)            # whole lines: --resume reads every one
    if full == "output":
        assert "the batch stopped: 1 of 8 runs finished" in first and len(journal) == 1
        assert _outputs(out, 15) == ["box-0.mp4"]                 # kept whole; no part file of box-1 left
    else:
        assert 4 <= len(journal) <= 6 and not [p for p in out.iterdir() if p.name.startswith(".")]
    assert "Stopped: cannot write" in (out / "summary.md").read_text()


_FINISHED_THEN_STOPPED = '''
import os, signal, types
from driftframe import batch_exec

def fake_attempt(spec, should_stop):
    os.kill(os.getpid(), signal.SIGTERM)       # the stop arrives as the run closes its finished file
    return ("finished", spec.label)

def worker(conn, parent_pid):
    batch_exec.attempt = fake_attempt
    batch_exec._worker_main(conn, parent_pid, None)
'''


def test_a_run_finished_when_a_stop_signal_reaches_its_worker_is_answered_before_the_worker_ends(tmp_path):
    # a worker stopped by SIGTERM or SIGHUP ends without an answer, so that the run is given again; but a run
    # that had finished (its output in place) is answered first, or its output would be on disk and missing
    # from the summary and the journal (seen as a batch stopped by SIGHUP keeping box-0.mp4 without its row)
    (tmp_path / "finished_then_stopped.py").write_text(_FINISHED_THEN_STOPPED)
    code = ("import multiprocessing, os, types, finished_then_stopped as f\n"
            "if __name__ == '__main__':\n"
            "    ctx = multiprocessing.get_context('spawn')\n"
            "    here, there = ctx.Pipe()\n"
            "    p = ctx.Process(target=f.worker, args=(there, os.getpid()))\n"
            "    p.start(); there.close()\n"
            "    here.send((3, types.SimpleNamespace(output=None, label='box-3')))\n"
            "    print(here.recv() if here.poll(60) else 'no answer')\n"
            "    p.join(60); print(p.exitcode)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "PYTHONPATH": str(tmp_path)}, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split("\n")[:2] == ["(3, ('finished', 'box-3'))", str(128 + signal.SIGTERM)], res.stdout
