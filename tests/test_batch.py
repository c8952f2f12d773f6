"""Batch runs: one picklable run per spec, serial, on a spawn process pool and on a Dask cluster.

Runs are tiny (0.2 s headless, 64x64 recordings of a fraction of a second) so the
behaviour, not the speed, is tested; speed lives in benchmarks/batch_scaling.py.
"""
import os
import pickle
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from videos import mp4_frames

from driftframe import batch, batch_exec, batch_file, batch_report, cli
from driftframe.batch import Failure, Result, Spec, SpecError

HERE = Path(__file__).parent
EXE = [sys.executable, "-m", "driftframe"]


def headless(seed, **kw):
    return Spec(scene="batch_scenes:box", seed=seed, seconds=0.2, **kw)


def recording(seed, path, **kw):
    return Spec(scene="batch_scenes:box", seed=seed, seconds=0.25, size=(64, 64), output=str(path), **kw)


def need_distributed():
    """dask.distributed, from the cluster extra: ./run tests (and so CI) installs it; elsewhere skip."""
    if os.environ.get("CI"):
        import distributed
        return distributed
    return pytest.importorskip("distributed", reason="needs the cluster extra: pip install -e '.[cluster]'")


def summary(results):
    """What must not depend on where a run ran: hash, steps, frames, the physical stats."""
    out = []
    for r in results:
        assert isinstance(r, Result), getattr(r, "traceback", r)
        phys = {k: v for k, v in r.stats.items() if k != "stage_seconds"}
        out.append((r.state_hash, r.steps, r.frames, phys))
    return out


# -- one run -------------------------------------------------------------------------------------
def test_a_run_is_a_pure_function_of_its_spec():
    a, b = batch.run(headless(3)), batch.run(headless(3))
    assert a.state_hash == b.state_hash and a.stats["contacts"] == b.stats["contacts"]
    assert batch.run(headless(4)).state_hash != a.state_hash
    assert a.steps == 12 and a.output is None and a.frames == 0 and a.wall_seconds > 0


def test_spec_and_result_survive_pickling():
    spec = headless(1, overrides={"n": 10})
    res = batch.run(spec)
    again = pickle.loads(pickle.dumps(res))
    assert again == res and again.spec == spec.check()


def test_stats_count_contacts_and_conserve_energy_and_momentum():
    from driftframe.components.collision import CollisionEvent

    res = batch.run(Spec(demo="billiards", seconds=2.0))
    st = res.stats
    # the same scene stepped by hand, counting collision events step by step
    from driftframe.app import make_world
    world, _ = make_world("billiards")
    events = 0
    for _ in range(120):
        world.step()
        events += sum(isinstance(e, CollisionEvent) for e in world.events)
    assert world.state_hash() == res.state_hash
    world.close()
    assert st["contacts"] == events > 10
    assert abs(st["energy_drift"]) < 1e-12                                         # elastic hits
    assert st["momentum_drift"] > 0.1           # the cushions (fixed spheres, no Velocity) push the balls back
    assert st["energy_start"] == pytest.approx(0.5 * 1.0 * 12.0 ** 2)              # the cue ball, 1 kg at 12 m/s
    cradle = batch.run(Spec(demo="cradle", seconds=2.0, stats=("momentum", "contacts"))).stats
    assert cradle["contacts"] >= 4 and cradle["momentum_drift"] < 1e-12       # free balls alone: P is kept
    assert set(st["stage_seconds"]) >= {"input", "movement", "collision"}
    only = batch.run(Spec(demo="billiards", seconds=0.5, stats=("contacts",))).stats
    assert set(only) == {"contacts"}


def test_thrust_shows_up_as_energy_drift_and_scripted_false_removes_it():
    flown = batch.run(Spec(demo="asteroids", seed=2, seconds=1.2, stats=("energy",)))
    coast = batch.run(Spec(demo="asteroids", seed=2, seconds=1.2, stats=("energy",), scripted=False))
    assert flown.stats["energy_drift"] > 1e-4             # the ship's 0.6 s burn from 0.5 s
    assert abs(coast.stats["energy_drift"]) < 1e-12


def test_demo_overrides_apply_to_the_run_only():
    from driftframe.demos import billiards

    slow = batch.run(Spec(demo="billiards", seconds=0.2, overrides={"SPEED": 6.0}, stats=("energy",)))
    assert slow.stats["energy_start"] == pytest.approx(0.5 * 6.0 ** 2)
    assert billiards.SPEED == 12.0                          # restored


def test_a_recording_writes_its_output_and_reports_it(tmp_path):
    res = batch.run(recording(1, tmp_path / "box.mp4"))
    assert res.output == str(tmp_path / "box.mp4") and res.frames == 15
    assert (tmp_path / "box.mp4").stat().st_size > 1000
    assert [p.name for p in tmp_path.iterdir()] == ["box.mp4"]


# -- reproducibility: serial, pool, cluster --------------------------------------------------------
def _mixed(folder: Path):
    folder.mkdir()
    return [headless(s) for s in range(3)] + [recording(0, folder / "box-0.mp4", sky="lines"),
                                              recording(1, folder / "box-1.mp4", sky="starfield")] + \
           [Spec(demo="billiards", seconds=0.2, overrides={"SPEED": 9.0})]


def _bytes(folder: Path):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_serial_and_pool_give_the_same_hashes_stats_and_bytes(tmp_path):
    serial = batch.run_all(_mixed(tmp_path / "serial"), jobs=1, progress=False)
    pool = batch.run_all(_mixed(tmp_path / "pool"), jobs=2, progress=False)
    assert serial.where == "serial" and pool.where == "2 processes" and not pool.interrupted
    assert summary(serial.results) == summary(pool.results)
    assert _bytes(tmp_path / "serial") == _bytes(tmp_path / "pool")
    assert len(_bytes(tmp_path / "pool")) == 2


@pytest.fixture(scope="module")
def cluster():
    distributed = need_distributed()
    # in-process workers (threads), loopback only, the dashboard on a free loopback port (None gives the
    # default 8787, which another cluster on the machine may hold): starts in about a second
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp://",
                                  host="127.0.0.1", dashboard_address="127.0.0.1:0") as lc, \
            distributed.Client(lc) as client:
        yield client


def test_a_dask_cluster_gives_the_same_results_as_local_runs(tmp_path, cluster):
    local = batch.run_all(_mixed(tmp_path / "local"), jobs=1, progress=False)
    remote = batch.run_all(_mixed(tmp_path / "dask"), scheduler=cluster, progress=False)
    assert remote.where.startswith("cluster tcp://127.0.0.1:")
    assert summary(remote.results) == summary(local.results)
    assert _bytes(tmp_path / "dask") == _bytes(tmp_path / "local")


def _flag_client_id():
    """On a worker: which client a distributed Event made there talks through (the batch's stop flag's)."""
    from distributed import Event
    return id(Event("driftframe-test-flag").client)


def test_the_batchs_own_client_is_not_the_processs_default(cluster):
    # A task of an in-process worker that asks for a client (the batch's stop flag, a distributed Event) gets
    # the process's default one when it talks to the same scheduler; a batch's client, closed at its end, must
    # not be it: a worker kept such a client half-closed and a later batch's runs failed with
    # "'NoneType' object has no attribute 'event_is_set'" (seen in the full suite)
    from distributed import default_client

    ours = batch_exec.connect(cluster.scheduler.address)
    try:
        assert default_client() is cluster and ours is not cluster
        assert cluster.submit(_flag_client_id, pure=False).result() == id(cluster)    # (workers: threads here)
    finally:
        ours.close()
    assert default_client() is cluster


def test_the_cli_runs_a_batch_on_a_scheduler_address(tmp_path, cluster):
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "batch_scenes:box"\nseeds = "0..2"\nseconds = 0.2\n')
    rc = cli.main(["batch", str(spec), "--scheduler", cluster.scheduler.address, "-o", str(tmp_path / "o"),
                   "--quiet"])
    assert rc == 0
    rows = (tmp_path / "o" / "summary.csv").read_text().splitlines()
    local = [batch.run(headless(s)).state_hash for s in range(3)]
    assert [r.split(",")[COL_HASH] for r in rows[1:]] == local


COL_HASH = batch_report.COLUMNS.index("state_hash")


# -- failures --------------------------------------------------------------------------------------
@pytest.mark.parametrize("jobs", [1, 2])
def test_one_failure_is_reported_with_its_spec_and_traceback_and_the_others_go_on(jobs):
    specs = [headless(s, overrides={"fail": s == 1}) for s in range(4)]
    seen = []
    out = batch.run_all(specs, jobs=jobs, progress=False, on_done=lambda i, r: seen.append(i))
    assert sorted(seen) == [0, 1, 2, 3]
    fail = out.results[1]
    assert isinstance(fail, Failure) and fail.spec == specs[1].check()
    assert fail.error == "RuntimeError: box: asked to fail"
    assert "batch_scenes.py" in fail.traceback and "raise RuntimeError" in fail.traceback
    assert [type(r) for r in out.results] == [Result, Failure, Result, Result]


def test_a_failure_on_the_cluster_is_reported_too(cluster):
    out = batch.run_all([headless(0), headless(1, overrides={"fail": True})], scheduler=cluster, progress=False)
    assert isinstance(out.results[0], Result)
    assert isinstance(out.results[1], Failure) and "asked to fail" in out.results[1].traceback


def test_the_cli_reports_a_failed_run_writes_the_summary_and_exits_1(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "batch_scenes:box"\nseeds = "0..2"\nseconds = 0.2\n[overrides]\nfail = [false, true]\n')
    res = subprocess.run(EXE + ["batch", str(spec), "-j", "2", "-o", str(tmp_path / "o"), "--quiet"],
                         capture_output=True, text=True, timeout=120, cwd=HERE)
    assert res.returncode == 1, res.stderr
    assert "run failed: " in res.stderr and "fail=True" in res.stderr and "asked to fail" in res.stderr
    assert "3 of 6 runs ok, 3 failed" in res.stdout
    md = (tmp_path / "o" / "summary.md").read_text()
    assert "## Failures" in md and md.count("RuntimeError: box: asked to fail") >= 3


# -- Ctrl-C --------------------------------------------------------------------------------------
SUMMARY = {"summary.csv", "summary.md", "summary.png", "journal.jsonl"}
COL_OUTPUT = batch_report.COLUMNS.index("output")


def _whole(folder: Path, frames: int):
    """Every file in ``folder`` (but the summary) is a finished MP4 of ``frames`` frames; their names."""
    names = sorted(p.name for p in folder.iterdir() if p.name not in SUMMARY)
    assert all(n.startswith("box-") and n.endswith(".mp4") for n in names), names   # no .part, no summary
    for name in names:
        assert len(mp4_frames(folder / name)[1]) == frames, name
    return names


@pytest.mark.parametrize("jobs", [1, 2])
def test_ctrl_c_stops_the_batch_and_leaves_only_whole_outputs(tmp_path, jobs):
    spec = tmp_path / "long.toml"
    # 8 recordings of 4 s at 64x64: long enough that SIGINT lands while runs are going
    spec.write_text('scene = "batch_scenes:box"\nseeds = "0..7"\nseconds = 4\nsize = "64x64"\n'
                    'output = "box-{seed}.mp4"\n')
    out = tmp_path / "o"
    proc = subprocess.Popen(EXE + ["batch", str(spec), "-j", str(jobs), "-o", str(out), "--quiet"], cwd=HERE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    while not list(out.glob("box-*.mp4")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)                      # wait until the first run has finished, then more are running
    assert proc.poll() is None, proc.communicate()
    time.sleep(0.3)
    os.killpg(proc.pid, signal.SIGINT)       # what a terminal's Ctrl-C does: the whole process group
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "interrupted (SIGINT)" in stderr and "wrote" in stderr and "Traceback" not in stderr
    names = _whole(out, 240)
    assert 1 <= len(names) < 8     # each output that is there is whole: 240 frames
    assert not [p for p in tmp_path.rglob(".*part*")]
    # the summary of what ran: a row per finished run, in the CSV and the journal
    rows = (out / "summary.csv").read_text().splitlines()[1:]
    assert sorted(Path(r.split(",")[COL_OUTPUT]).name for r in rows) == names
    assert len((out / "journal.jsonl").read_text().splitlines()) == len(names)


def test_ctrl_c_while_the_workers_start_is_a_clean_stop_too(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "batch_scenes:box"\nseeds = "0..3"\nseconds = 4\nsize = "64x64"\n'
                    'output = "box-{seed}.mp4"\n')
    out = tmp_path / "o"
    proc = subprocess.Popen(EXE + ["batch", str(spec), "-j", "2", "-o", str(out), "--quiet"], cwd=HERE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children")
    deadline = time.monotonic() + 60
    while len(children.read_text().split()) < 2 and time.monotonic() < deadline:
        time.sleep(0.005)                     # two workers spawned: they are importing driftframe now
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "interrupted (SIGINT)" in stderr and "run failed" not in stderr and "Traceback" not in stderr
    _whole(out, 240)
    assert not [p for p in tmp_path.rglob(".*part*")]


def test_ctrl_c_stops_a_batch_on_the_cluster_cleanly(tmp_path, cluster):
    import threading

    specs = [Spec(scene="batch_scenes:box", seed=s, seconds=4, size=(64, 64), output=str(tmp_path / f"box-{s}.mp4"))
             for s in range(6)]

    def interrupt_after_the_first_output():
        deadline = time.monotonic() + 60
        while not list(tmp_path.glob("box-*.mp4")) and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.3)
        os.kill(os.getpid(), signal.SIGINT)   # a real Ctrl-C, handled in this (the main) thread

    threading.Thread(target=interrupt_after_the_first_output, daemon=True).start()
    out = batch.run_all(specs, scheduler=cluster, progress=False)
    assert out.interrupted and 1 <= len(out.done) < 6 and not out.failures
    time.sleep(1.0)                           # a task that was running stops within half a second
    assert _whole(tmp_path, 240) == sorted(Path(r.output).name for r in out.done)


def _wait_on(name):
    from distributed import Event
    Event(name).wait(30)
    return name


def test_a_stop_cancels_only_the_runs_no_worker_has_started(cluster):
    # The client's copy of a task's state lags the scheduler's: a run that has just finished
    # can still read "pending" on the client. The stop must not cancel it (its output is whole
    # and must be in the results), nor the runs going on; only those still queued.
    from distributed import Event

    gate = Event("gate-" + str(time.monotonic_ns()), client=cluster)
    finished = cluster.submit(sum, [1, 2], pure=False)
    deadline = time.monotonic() + 30
    while cluster.run_on_scheduler(batch._scheduler_states, keys=[finished.key]).get(finished.key) != "memory":
        assert time.monotonic() < deadline
        time.sleep(0.01)
    running = [cluster.submit(_wait_on, gate.name, pure=False) for _ in range(2)]     # both workers busy
    while set(cluster.run_on_scheduler(batch._scheduler_states, keys=[f.key for f in running]).values()) != {"processing"}:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    later = [cluster.submit(sum, [i], pure=False) for i in range(8)]
    while len(states := cluster.run_on_scheduler(batch._scheduler_states, keys=[f.key for f in later])) < 8:
        assert time.monotonic() < deadline            # submit is asynchronous: wait until the scheduler has them
        time.sleep(0.01)
    # the scheduler hands each worker a task or two beyond its threads ("processing", not started
    # yet: they will find the stop flag set and return at once); the rest wait on the scheduler
    queued = sorted(k for k, state in states.items() if state == "queued")
    assert queued
    cancelled = batch._cancel_unstarted(cluster, [finished, *running, *later])
    gate.set()
    assert sorted(f.key for f in cancelled) == queued
    assert finished.result(timeout=10) == 3
    assert [f.result(timeout=30) for f in running] == [gate.name, gate.name]
    assert [f.cancelled() for f in later] == [f.key in queued for f in later]


def test_a_stopped_run_deletes_what_it_had_written(tmp_path):
    calls = []

    def stop_after_some_steps():
        calls.append(1)
        return len(calls) > 5

    with pytest.raises(batch.Interrupted):
        batch.run(recording(0, tmp_path / "x.mp4"), should_stop=stop_after_some_steps)
    assert list(tmp_path.iterdir()) == []


# -- bad input, before any run ----------------------------------------------------------------------
def _batch_cli(tmp_path, text, *extra, name="s.toml"):
    spec = tmp_path / name
    spec.write_text(text)
    out = tmp_path / "o"
    res = subprocess.run(EXE + ["batch", str(spec), "-o", str(out), "--quiet", *extra], capture_output=True,
                         text=True, timeout=120, cwd=HERE)
    return res, out


@pytest.mark.parametrize("text,message", [
    ('demo = "asteroids\n', "not valid TOML"),
    ('demo = "asteroids"\ncolour = "red"\n', "unknown key 'colour'"),
    ('seeds = "0..3"\n', "give demo = ... or scene = ..."),
    ('demo = ["asteroids", "pong"]\nseconds = 0.2\n', "run 1 (pong, seed 0): unknown demo 'pong'"),
    ('scene = "no_such_module:box"\nseconds = 0.2\n', "cannot import module 'no_such_module'"),
    ('scene = "batch_scenes:nope"\nseconds = 0.2\n', "module 'batch_scenes' has no 'nope'"),
    ('scene = "batch_scenes:NOT_CALLABLE"\nseconds = 0.2\n', "'NOT_CALLABLE' is not a function"),
    ('scene = "batch_scenes.box"\nseconds = 0.2\n', "import path 'package.module:function'"),
    ('scene = "batch_scenes:box"\n', "seconds is required for scene 'batch_scenes:box'"),
    ('demo = "cradle"\nseeds = "5..2"\n', "seeds: bad range '5..2': the end 2 is before the start 5"),
    ('demo = "cradle"\nseeds = "0..x"\n', "seeds: bad range '0..x'"),
    ('demo = "cradle"\nseeds = "-3..2"\n', "seeds must be >= 0, got -3"),
    ('demo = "cradle"\nseeds = [1, "a"]\n', "seeds[1]: seeds must be integers"),
    ('demo = "cradle"\nfps = 25\n', "fps must divide the 60 Hz"),
    ('demo = "cradle"\nsize = "64x"\n', "WIDTHxHEIGHT"),
    ('demo = "cradle"\ncamera = "side"\n', "camera must be one of cockpit, chase, overhead"),
    ('demo = "cradle"\nsky = "clouds"\n', "sky must be one of lines, starfield"),
    ('demo = "cradle"\nstats = ["energy", "heat"]\n', "stats[1]: unknown stat 'heat'"),
    ('demo = "swarm"\nseeds = "0..3"\n[overrides]\nCOUNT = [100, -5]\n', "overrides.COUNT must be > 0, got -5"),
    ('demo = "swarm"\n[overrides]\nSIZE = 3\n', "demo 'swarm' has no setting 'SIZE'"),
    ('scene = "batch_scenes:box"\nseconds = 0.2\n[overrides]\nradius = 2\n', "do not fit scene"),
    ('demo = "cradle"\noutput = "{demo}.mp4"\nseeds = "0..1"\n', "is also written by"),
    ('demo = "cradle"\noutput = "{demo}-{colour}.mp4"\n', "unknown field {colour}"),
    ('demo = "cradle"\noutput = "{seed}.avi"\n', "unknown output format '.avi'"),
    ('demo = "cradle"\noutput = "../{seed}.mp4"\n', "must be a relative name inside the output folder"),
])
def test_bad_batch_files_fail_before_any_run_naming_the_entry(tmp_path, text, message, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(text)
    out = tmp_path / "o"
    assert cli.main(["batch", str(spec), "-o", str(out), "--quiet"]) == 2     # in process: fast
    err = capsys.readouterr().err
    assert err.startswith(f"driftframe: error: {spec}: ") and message in err, err
    assert err.count("\n") == 1 and not out.exists()         # one line; nothing ran, no folder was made


def test_a_missing_batch_file_and_bad_jobs_are_clear_errors(tmp_path):
    res = subprocess.run(EXE + ["batch", str(tmp_path / "none.toml")], capture_output=True, text=True)
    assert res.returncode == 2 and "none.toml: no such batch file" in res.stderr
    res, _ = _batch_cli(tmp_path, 'demo = "cradle"\n', "-j", "0")
    assert res.returncode == 2 and "-j must be an integer >= 1, got '0'" in res.stderr


def test_an_unwritable_output_folder_is_refused_before_any_run(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text('demo = "cradle"\nseconds = 0.2\noutput = "{seed}.mp4"\n')
    # /sys refuses new folders even to root; a file cannot be a folder
    for folder, message in (("/sys/driftframe-batch", "output folder '/sys/driftframe-batch' is not writable"),
                            (str(spec), "exists and is not a folder")):
        res = subprocess.run(EXE + ["batch", str(spec), "-o", folder, "--quiet"], capture_output=True, text=True)
        assert res.returncode == 2 and message in res.stderr and "Traceback" not in res.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["s.toml"]


def test_an_unreachable_scheduler_is_refused_before_any_run(tmp_path, monkeypatch, capsys):
    import socket

    need_distributed()
    with socket.socket() as s:                       # a loopback port that nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    spec = tmp_path / "s.toml"
    spec.write_text('demo = "cradle"\nseconds = 0.2\noutput = "{seed}.mp4"\n')
    monkeypatch.setattr(batch_exec, "CONNECT_TIMEOUT", 1.0)
    rc = cli.main(["batch", str(spec), "--scheduler", f"tcp://127.0.0.1:{port}", "-o", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and f"scheduler 'tcp://127.0.0.1:{port}' cannot be reached" in err
    assert not (tmp_path / "o").exists()
    assert cli.main(["batch", str(spec), "--scheduler", "x", "-j", "2"]) == 2
    assert "-j and --scheduler exclude each other" in capsys.readouterr().err


def test_a_failed_connection_leaves_no_half_made_client_for_the_collector():
    # A Client whose start failed closes itself when the collector finds it (Client.__del__), waiting for
    # distributed's loop lock: collected inside another client's loop-thread start, which holds that lock,
    # it hung the process (a test module's cluster at its teardown). connect() collects it at once.
    import gc
    import socket

    distributed = need_distributed()
    with socket.socket() as s:                       # a loopback port that nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]

    def clients():
        return {id(o) for o in gc.get_objects() if isinstance(o, distributed.Client)}

    before = clients()
    with pytest.raises(SpecError, match="cannot be reached"):
        batch_exec.connect(f"tcp://127.0.0.1:{port}", timeout=1.0)
    assert clients() <= before and gc.isenabled()


def test_bad_specs_in_the_api_name_the_value():
    with pytest.raises(SpecError, match="give exactly one of demo or scene"):
        Spec().check()
    with pytest.raises(SpecError, match="seed must be an integer >= 0, got -1"):
        Spec(demo="cradle", seed=-1).check()
    with pytest.raises(SpecError, match=r"run 1: expected a driftframe.batch.Spec"):
        batch.check_all([Spec(demo="cradle"), "cradle"])
    with pytest.raises(SpecError, match="seconds must be a finite number > 0, got nan"):
        batch.run(Spec(demo="cradle", seconds=float("nan")))


# -- the grid, the plan, the summary --------------------------------------------------------------
def test_the_grid_is_every_combination_with_inclusive_ranges(tmp_path):
    specs = batch_file.grid({"demo": ["cradle", "billiards"], "seeds": "3..5", "seconds": 0.2,
                             "overrides": {}, "output": "{demo}/{seed}-{index}.gif"}, tmp_path, check=False)
    assert [(s.demo, s.seed) for s in specs] == [("cradle", 3), ("cradle", 4), ("cradle", 5),
                                                 ("billiards", 3), ("billiards", 4), ("billiards", 5)]
    assert specs[4].output == str(tmp_path / "billiards" / "4-4.gif")
    assert specs[4].where.endswith("run 4 (billiards, seed 4)")
    swept = batch_file.grid({"demo": "swarm", "seeds": [1, 2], "overrides": {"COUNT": [10, 20]}}, tmp_path)
    assert [(s.seed, s.overrides["COUNT"]) for s in swept] == [(1, 10), (1, 20), (2, 10), (2, 20)]
    assert batch_file.parse_seeds("0..99") == list(range(100)) and batch_file.parse_seeds(7) == [7]


def test_the_worker_plan_follows_the_cores_and_the_frame_size(monkeypatch):
    monkeypatch.delenv("LP_NUM_THREADS", raising=False)
    runs = [Spec(demo="cradle")] * 10
    assert batch.plan_jobs(runs, ncores=8) == (8, 0)              # a core each: no rasteriser thread
    assert batch.plan_jobs(runs[:3], ncores=8) == (3, 2)          # never more workers than runs
    assert batch.plan_jobs(runs, 1, ncores=8) == (1, None)        # serial: llvmpipe keeps every core
    videos = [Spec(demo="cradle", output="a.mp4", size=(640, 360))] * 20
    assert batch.plan_jobs(videos, ncores=8) == (6, 0)            # 1.3 cores a recording: the encoder
    assert batch.plan_jobs(videos, ncores=16) == (12, 0)
    assert batch.plan_jobs(videos, ncores=2) == (2, 0)            # 1.54 rounds up: an idle core costs more
    monkeypatch.setenv("LP_NUM_THREADS", "3")
    assert batch.plan_jobs(runs, ncores=8) == (8, None)           # the user's setting is left alone
    with pytest.raises(SpecError, match="jobs must be an integer >= 1, got 0"):
        batch.plan_jobs(runs, 0)


def test_pool_workers_get_the_planned_rasteriser_threads(monkeypatch):
    monkeypatch.delenv("LP_NUM_THREADS", raising=False)
    specs = [Spec(scene="batch_scenes:env_probe", seed=s, seconds=0.1) for s in range(2)]
    lp = batch.plan_jobs(specs, 2)[1]
    out = batch.run_all(specs, jobs=2, progress=False)
    assert [r.error for r in out.results] == [f"RuntimeError: LP_NUM_THREADS={lp}"] * 2
    monkeypatch.setenv("LP_NUM_THREADS", "3")                      # the user's own setting is kept
    out = batch.run_all(specs, jobs=2, progress=False)
    assert [r.error for r in out.results] == ["RuntimeError: LP_NUM_THREADS=3"] * 2


def test_the_summary_has_a_row_per_run_a_report_and_a_chart(tmp_path):
    specs = [headless(s) for s in range(3)] + [headless(9, overrides={"fail": True})]
    out = batch.run_all(specs, jobs=1, progress=False)
    written, note = batch_report.write(out, tmp_path, title="t")
    assert note is None and [p.name for p in written] == ["summary.csv", "summary.md", "summary.png"]
    lines = (tmp_path / "summary.csv").read_text().splitlines()
    assert lines[0].split(",") == batch_report.COLUMNS and len(lines) == 5
    assert [ln.split(",")[COL_HASH] for ln in lines[1:4]] == [r.state_hash for r in out.results[:3]]
    md = (tmp_path / "summary.md").read_text()
    assert "| batch_scenes:box | 3 |" in md and "| batch_scenes:box fail=True | 1 | 1 |" in md
    assert "4 runs in this process (serially): 3 ok, 1 failed" in md       # the command line's words
    assert (tmp_path / "summary.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_without_matplotlib_the_summary_says_why_there_is_no_chart(tmp_path, monkeypatch):
    out = batch.run_all([headless(0)], jobs=1, progress=False)
    monkeypatch.setitem(sys.modules, "matplotlib", None)          # import matplotlib -> ImportError
    written, note = batch_report.write(out, tmp_path, title="t")
    assert "matplotlib is not installed" in note and "driftframe[batch]" in note
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.csv", "summary.md"]


def test_the_cli_batch_end_to_end_with_recordings(tmp_path):
    # the installed console script, run from the folder that holds the scene's module: found from there
    script = Path(sys.executable).with_name("driftframe")
    spec, out = tmp_path / "s.toml", tmp_path / "o"
    spec.write_text('scene = "batch_scenes:box"\nseeds = "0..1"\nseconds = 0.2\nsize = "64x64"\n'
                    'fps = 30\noutput = "clips/box-{seed}.gif"\n')
    res = subprocess.run([str(script), "batch", str(spec), "-j", "2", "-o", str(out), "--quiet"],
                         capture_output=True, text=True, timeout=120, cwd=HERE)
    assert res.returncode == 0, res.stderr
    assert "2 of 2 runs ok, 0 failed, on 2 processes" in res.stdout
    assert sorted(p.name for p in (out / "clips").iterdir()) == [f"box-{s}.gif" for s in range(2)]
    assert sorted(p.name for p in out.iterdir()) == ["clips", "journal.jsonl", "summary.csv", "summary.md",
                                                     "summary.png"]
    from PIL import Image
    with Image.open(out / "clips" / "box-0.gif") as im:
        assert im.size == (32, 32) and im.n_frames >= 2


def test_existing_outputs_are_refused_before_any_run_unless_overwrite(tmp_path):
    spec, out = tmp_path / "s.toml", tmp_path / "o"
    spec.write_text('scene = "batch_scenes:box"\nseeds = "0..1"\nseconds = 0.1\nsize = "64x64"\n'
                    'fps = 30\noutput = "box-{seed}.gif"\n')
    out.mkdir()
    (out / "box-1.gif").write_bytes(b"an older file")
    base = [*EXE, "batch", str(spec), "-j", "1", "-o", str(out), "--quiet"]
    res = subprocess.run(base, capture_output=True, text=True, timeout=120, cwd=HERE)
    assert res.returncode == 2 and res.stderr.count("\n") == 1, res.stderr
    assert "box-1.gif' exists already; pass --overwrite to replace it" in res.stderr
    assert sorted(p.name for p in out.iterdir()) == ["box-1.gif"]          # nothing ran
    res = subprocess.run(base + ["--overwrite"], capture_output=True, text=True, timeout=120, cwd=HERE)
    assert res.returncode == 0, res.stderr
    assert (out / "box-1.gif").read_bytes()[:6] == b"GIF89a"


# -- issue 21: bounded inputs, nothing escapes, resume, owned workers, cluster basics ----------------
def test_size_as_a_toml_pair_is_one_size(tmp_path):
    specs = batch_file.grid({"demo": "cradle", "size": [640, 360], "output": "{width}x{height}.mp4"}, tmp_path)
    assert [s.size for s in specs] == [(640, 360)] and specs[0].output.endswith("640x360.mp4")
    two = batch_file.grid({"demo": "cradle", "size": [[64, 64], "128x96"], "output": "{size}.gif"}, tmp_path)
    assert [s.size for s in two] == [(64, 64), (128, 96)]


@pytest.mark.parametrize("text,message", [
    ('demo = "cradle"\nseconds = 1e300\n', "seconds 1e+300 is 6e+301 fixed steps"),
    ('demo = "cradle"\nseconds = 200000\n', "a run may have at most 10,000,000 steps"),
    ('demo = "cradle"\nseconds = 1e300\noutput = "{seed}.gif"\n', "is 6e+301 frames; a recording may have at most"),
    ('demo = "cradle"\nseconds = 20000\noutput = "{seed}.gif"\n', "is 1.2e+06 frames"),
])
def test_batch_lengths_have_the_limits_of_record(tmp_path, text, message, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(text)
    assert cli.main(["batch", str(spec), "-o", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err


def test_many_runs_are_checked_in_linear_time(tmp_path):
    # recordings: the heavier grid (every output named, checked inside -o, unique, its folder once), checked
    # as the command does (the entries, then the scheduler, then the folders). Linear: ten times the runs
    # cost about ten times the CPU (a quadratic check, 100x), a ratio in one process, whatever the load.
    # 30,000 and 300,000 runs tell the two apart as well as 10^5 and 10^6 did, in a tenth of the time (17 s
    # of the suite's CPU before); the absolute bar (10^6 in under 10 s) is a measurement, not this test's
    def check(n):
        spec = tmp_path / f"big{n}.toml"
        spec.write_text(f'demo = "cradle"\nseeds = "0..{n - 1}"\nseconds = 0.1\nsize = "64x64"\n'
                        f'output = "c-{{seed}}.mp4"\n')
        out = tmp_path / f"o{n}"
        t0 = time.process_time()
        specs = batch.check_all(batch_file.load(spec, out, check=False, overwrite=True), outputs=False)
        specs = batch_file.prepare(specs, out, overwrite=True, checked=True)
        return specs, out, time.process_time() - t0

    _, _, small = check(30_000)
    specs, out, took = check(300_000)
    assert len(specs) == 300_000 and specs[-1].seed == 299_999 and specs[-1].seconds == 0.1
    assert specs[-1].output == str(out / "c-299999.mp4") and specs[-1].overwrite
    assert took < 25 * small, f"300,000 runs {took:.2f} s of CPU, 30,000 runs {small:.3f} s: not linear"


def test_a_batch_file_over_the_cap_is_refused(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text('demo = "cradle"\n' + "# padding\n" * 200_000)
    assert cli.main(["batch", str(spec), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"{spec}: the batch file is 1.91 MiB; the limit is 1 MiB" in err and not (tmp_path / "o").exists()


@pytest.mark.parametrize("name,message", [
    ("../../ESCAPED", "leaves the output folder"),
    ("/tmp/driftframe-escaped-abs", "leaves the output folder"),
    ("link/x", "leaves the output folder"),                           # a folder that is a symlink out
    ("n" * 260, "is 264 bytes; the file system here allows 255"),
])
def test_no_output_escapes_the_output_folder(tmp_path, name, message, capsys):
    outside = tmp_path / "outside"
    outside.mkdir()
    out = tmp_path / "a" / "b" / "o"
    out.mkdir(parents=True)
    (out / "link").symlink_to(outside)
    spec = tmp_path / "s.toml"
    spec.write_text(f'scene = "batch_scenes:box"\nseconds = 0.1\nsize = "64x64"\noutput = "{{name}}.gif"\n'
                    f'[overrides]\nname = "{name}"\n')
    assert cli.main(["batch", str(spec), "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err
    assert sorted(p.name for p in out.iterdir()) == ["link"] and not list(outside.iterdir())
    assert not (tmp_path / "ESCAPED.gif").exists() and not Path("/tmp/driftframe-escaped-abs.gif").exists()


def test_an_existing_output_that_links_out_of_the_folder_is_refused(tmp_path, capsys):
    out, victim = tmp_path / "o", tmp_path / "victim.gif"
    out.mkdir()
    victim.write_bytes(b"not ours")
    (out / "box-0.gif").symlink_to(victim)
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "batch_scenes:box"\nseconds = 0.1\nsize = "64x64"\noutput = "box-{seed}.gif"\n')
    assert cli.main(["batch", str(spec), "-o", str(out), "--quiet", "--overwrite"]) == 2
    assert "is a link to" in capsys.readouterr().err and victim.read_bytes() == b"not ours"


def test_modules_in_the_working_folder_do_not_shadow_installed_ones(tmp_path):
    # a tqdm.py and an av.py lying where the command runs: the batch must use the installed packages,
    # and still find the scene's own module there
    for mod in ("tqdm", "av"):
        (tmp_path / f"{mod}.py").write_text(f"open({str(tmp_path / (mod + '.RAN'))!r}, 'w').close()\n"
                                            f"raise SystemExit('the {mod}.py in the working folder ran')\n")
    (tmp_path / "myscenes.py").write_text((HERE / "batch_scenes.py").read_text())
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "myscenes:box"\nseconds = 0.05\nsize = "64x64"\noutput = "b.mp4"\n')
    script = Path(sys.executable).with_name("driftframe")
    res = subprocess.run([str(script), "batch", str(spec), "-j", "1", "-o", str(tmp_path / "o"), "--quiet"],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert not list(tmp_path.glob("*.RAN")) and (tmp_path / "o" / "b.mp4").stat().st_size > 0


def test_resume_skips_journalled_runs_and_a_journal_needs_resume_or_overwrite(tmp_path, capsys):
    spec, out = tmp_path / "s.toml", tmp_path / "o"
    spec.write_text('scene = "batch_scenes:box"\nseeds = "0..2"\nseconds = 0.1\nsize = "64x64"\nfps = 30\n'
                    'output = "box-{seed}.gif"\n')
    base = ["batch", str(spec), "-o", str(out), "--quiet", "-j", "1"]
    assert cli.main(base) == 0
    first = (out / "summary.csv").read_text()
    journal = (out / "journal.jsonl").read_text().splitlines()
    assert len(journal) == 3
    capsys.readouterr()
    assert cli.main(base) == 2
    assert "journal.jsonl exists: a batch ran into" in capsys.readouterr().err
    # a torn last line (a kill mid-write) and a deleted output: those two runs, and only them, run again
    (out / "journal.jsonl").write_text("\n".join(journal[:2]) + "\n" + journal[2][:20])
    (out / "box-0.gif").unlink()
    stamp = (out / "box-1.gif").stat().st_mtime_ns
    assert cli.main(base + ["--resume"]) == 2           # box-2.gif is there, but not in the journal
    assert "box-2.gif' exists already; pass --overwrite" in capsys.readouterr().err
    assert cli.main(base + ["--resume", "--overwrite"]) == 0
    assert "resuming: 1 of 3 runs are done already" in capsys.readouterr().err
    assert (out / "box-1.gif").stat().st_mtime_ns == stamp and (out / "box-0.gif").exists()
    again = (out / "summary.csv").read_text().splitlines()
    hashes = [r.split(",")[COL_HASH] for r in again[1:]]
    assert hashes == [r.split(",")[COL_HASH] for r in first.splitlines()[1:]]
    # a changed spec (another length) matches no journal row: it runs
    spec.write_text(spec.read_text().replace("seconds = 0.1", "seconds = 0.2"))
    assert cli.main(base + ["--resume"]) == 2           # its outputs exist: written by the other spec
    assert cli.main(base + ["--overwrite"]) == 0
    assert len((out / "journal.jsonl").read_text().splitlines()) == 3


def test_a_dead_worker_is_reported_once_its_run_retried_and_no_other_run_failed(tmp_path):
    specs = [headless(s) for s in range(4)]
    specs[0] = Spec(scene="batch_scenes:die_once", seed=0, seconds=0.2,
                    overrides={"marker": str(tmp_path / "died"), "parent": os.getpid()})
    notes = []
    out = batch.run_all(specs, jobs=2, progress=False, note=notes.append)
    assert [type(r) for r in out.results] == [Result] * 4 and out.exit_status == 0
    assert len(notes) == 1 and "killed by SIGKILL" in notes[0] and "running it again (1 of 1" in notes[0], notes
    (tmp_path / "died").unlink()
    notes.clear()
    out = batch.run_all(specs, jobs=2, progress=False, note=notes.append, retries=0)
    assert isinstance(out.results[0], Failure) and out.results[0].error.startswith("WorkerDied: a worker (pid ")
    assert [type(r) for r in out.results[1:]] == [Result] * 3 and out.exit_status == 1
    assert len(notes) == 1 and "no retries left" in notes[0]


def test_a_non_dask_address_is_one_line(tmp_path, capsys, monkeypatch):
    import socket
    import threading

    need_distributed()
    monkeypatch.setattr(batch_exec, "CONNECT_TIMEOUT", 2.0)
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()

    def answer():                                # an HTTP server's answer: not Dask's framing
        for _ in range(4):
            try:
                conn, _ = server.accept()
            except OSError:
                return
            with conn:
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" + b"\xff" * 64)

    threading.Thread(target=answer, daemon=True).start()
    spec = tmp_path / "s.toml"
    spec.write_text('demo = "cradle"\nseconds = 0.1\n')
    port = server.getsockname()[1]
    try:
        for address in (f"tcp://127.0.0.1:{port}", "ucx://127.0.0.1:1"):
            rc = cli.main(["batch", str(spec), "--scheduler", address, "-o", str(tmp_path / "o"), "--quiet"])
            err = capsys.readouterr().err
            assert rc == 2 and err.count("\n") == 1, err
            assert err.startswith(f"driftframe: error: scheduler {address!r} "), err
    finally:
        server.close()


def test_a_server_that_accepts_and_says_nothing_is_one_line_in_bounded_time(tmp_path, capsys, monkeypatch):
    # as an HTTP server does (it waits for a request line Dask never sends): Client(timeout=) held for ever
    import socket
    import threading

    need_distributed()
    monkeypatch.setattr(batch_exec, "CONNECT_TIMEOUT", 1.0)
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    held = []
    threading.Thread(target=lambda: held.append(server.accept()), daemon=True).start()
    spec = tmp_path / "s.toml"
    spec.write_text('demo = "cradle"\nseconds = 0.1\n')
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    t0 = time.monotonic()
    try:
        rc = cli.main(["batch", str(spec), "--scheduler", address, "-o", str(tmp_path / "o"), "--quiet"])
    finally:
        server.close()
    err = capsys.readouterr().err
    assert rc == 2 and time.monotonic() - t0 < 10, err
    assert err == f"driftframe: error: scheduler {address!r} accepted a connection but did not answer as a " \
                  "Dask scheduler within 2 s; is it one?\n"
    assert not (tmp_path / "o").exists()


def test_the_cluster_is_found_from_the_environment_or_a_scheduler_file(tmp_path, cluster, monkeypatch, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "batch_scenes:box"\nseeds = "0..1"\nseconds = 0.1\n')
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", cluster.scheduler.address)
    assert cli.main(["batch", str(spec), "-o", str(tmp_path / "a"), "--quiet"]) == 0
    assert f"on cluster {cluster.scheduler.address}" in capsys.readouterr().out
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS")
    info = tmp_path / "scheduler.json"
    info.write_text('{"address": "%s", "type": "Scheduler", "services": {}}' % cluster.scheduler.address)
    assert cli.main(["batch", str(spec), "--scheduler-file", str(info), "-o", str(tmp_path / "b"), "--quiet"]) == 0
    assert f"on cluster {cluster.scheduler.address}" in capsys.readouterr().out


def test_cluster_tasks_have_retries_and_the_versions_are_checked_first(cluster, monkeypatch):
    seen = []
    submit = cluster.submit

    def spy(*args, **kw):
        seen.append(kw.get("retries"))
        return submit(*args, **kw)

    monkeypatch.setattr(cluster, "submit", spy)
    out = batch.run_all([headless(0)], scheduler=cluster, progress=False, retries=3)
    assert seen == [3] and isinstance(out.results[0], Result)
    here = batch.versions()
    batch.check_versions(cluster, here)
    with pytest.raises(SpecError, match=r"other versions than this client: numpy " + re.escape(here["numpy"]) +
                       r" on tcp://127\.0\.0\.1:\d+ \(here 0\.0\.1\)"):
        batch.check_versions(cluster, {**here, "numpy": "0.0.1"})


def test_the_dashboard_link_is_given_when_the_scheduler_serves_one(cluster, tmp_path, capsys):
    info = cluster.scheduler_info()
    port = info["services"]["dashboard"]                    # the test cluster serves one
    assert batch.dashboard(cluster) == f"http://127.0.0.1:{port}/status"
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "batch_scenes:box"\nseconds = 0.1\n')
    assert cli.main(["batch", str(spec), "--scheduler", cluster.scheduler.address, "-o", str(tmp_path / "o"),
                     "--quiet"]) == 0
    assert f"driftframe: dashboard: http://127.0.0.1:{port}/status" in capsys.readouterr().err

    class NoDashboard:
        def scheduler_info(self):
            return {"services": {}}

    assert batch.dashboard(NoDashboard()) is None
