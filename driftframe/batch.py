"""Many runs at once: one picklable function per run, mapped over worker processes or a Dask cluster.

A :class:`Spec` says what one run is (a demo, or a scene-building function
named by import path; seed, length, frame rate, size, camera, overrides,
an output file or none, the stats to collect). :func:`run` does it and returns
a :class:`Result`: the state hash, the stats, the output path, the wall
time. It is a pure function of its spec: the same spec gives the same hash and
the same output bytes in this process, in a pool worker or on a cluster::

    from driftframe.batch import Spec, run, run_all
    r = run(Spec(demo="asteroids", seed=3, seconds=5))          # headless: physics only
    r.state_hash, r.stats["energy_drift"], r.stats["contacts"]
    out = run_all([Spec(demo="asteroids", seed=s, seconds=5) for s in range(100)], jobs=2)
    out.results                      # a Result (or a Failure) per spec, in spec order
    out.exit_status                  # 0; 1 if a run failed; 128 + n if signal n stopped it

:func:`run_all` is the map (the modules: ``batch_spec`` what a run is and its
checks, ``batch_run`` one run, ``batch_exec`` where runs go).

* Local (default): ``jobs=N`` is N processes running specs: N - 1 ``spawn``-ed
  workers (a fork after a GL context exists hangs; see ``framework/gl.py``)
  take them from the front of the queue, and this process (already set up)
  takes them from the back on a helper thread, so one worker's start-up
  (about 0.6 s: an interpreter, the imports, the compiled kernels) is saved.
  ``jobs=1`` runs serially in this process. Workers belong to this process:
  they end within a second of it, however it ended (SIGKILL included); a
  worker that dies is reported and its run given to a new one (``retries``,
  default 1), and no other run is failed with it.
* A cluster: ``scheduler="tcp://host:8786"`` submits the same function to a
  ``dask.distributed`` scheduler (the optional ``cluster`` extra), each task
  with ``retries``, after checking that every worker has the versions of
  driftframe, numpy, numba and PyAV this process has. Workers need the same
  file system for outputs.

Worker count (:func:`plan_jobs`): the cores this process may use, divided
by what one run keeps busy. A headless run is one busy thread. An MP4
recording adds its x264 encoder beside it, on the recorder's writer
thread (x264's threads pinned at ``recorder.X264_THREADS`` because the
bytes depend on it, so its load is counted: :data:`RECORDING_CORES`).
Mesa starts ``LP_NUM_THREADS`` rasteriser threads in every process (by
default one per core): with several workers each gets ``LP_NUM_THREADS =
cores // jobs``, or 0 (rasterise on the run's own thread) where that is 1,
unless you set it yourself. Give ``jobs`` to override.

Failures: a run that raises becomes a :class:`Failure` (its spec, the error,
the traceback) and the others go on. Signals: the first Ctrl-C, SIGTERM or
SIGHUP stops the batch (queued runs never start, running ones stop at their
next step and delete what they had written; finished outputs stay whole, and
an old output a run was replacing stays as it was); the Outcome then names
the signal. A second one aborts at once (:class:`Aborted`), within a second
even while a first run compiles. Every run writes its output under a
temporary name and moves it into place only when complete
(``framework/recorder.py``), so no output is ever half-written.

Only one world runs at a time in one process (esper keeps its current world
in a module global): on a Dask worker with several threads, runs queue for a
lock. Start Dask workers with ``--nthreads 1`` and as many processes as cores.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from typing import Callable

from driftframe.batch_exec import (CONNECT_TIMEOUT, RECORDING_CORES, Aborted, StopFlag, _cancel_unstarted,
                                   _scheduler_states, check_versions, connect, cores, dashboard, plan_jobs,
                                   run_cluster, run_local, signal_name, versions)
from driftframe.batch_run import Failure, Result, attempt, run
from driftframe.batch_spec import (DEFAULT_SIZE, SKIES, STATS, Interrupted, Spec, SpecError, check_all,
                                   check_output_names)
from driftframe.framework.output import no_space

__all__ = ["Spec", "SpecError", "Result", "Failure", "Outcome", "Interrupted", "Aborted", "run", "attempt",
           "run_all", "check_all", "check_output_names", "plan_jobs", "cores", "connect", "check_versions",
           "versions", "dashboard", "signal_name", "STATS", "SKIES", "DEFAULT_SIZE", "RECORDING_CORES",
           "CONNECT_TIMEOUT", "StopFlag", "_cancel_unstarted", "_scheduler_states"]


@dataclass
class Outcome:
    """What :func:`run_all` returns: a Result or Failure per spec (None: never ran, after a stop)."""

    results: list
    #: The signal that stopped the batch (SIGINT for Ctrl-C, SIGTERM, SIGHUP), or None.
    signal: int | None
    wall_seconds: float
    jobs: int
    where: str
    #: Why the batch stopped by itself, naming the file (a full disk: a run's output or the caller's
    #: journal could not be written), or None. The run that met it is None in :attr:`results`.
    halted: str | None = None

    @property
    def interrupted(self) -> bool:
        return self.signal is not None

    @property
    def place(self) -> str:
        """Where the runs went, in words: "in this process (serially)", "on 2 processes", "on cluster tcp://..."."""
        return "in this process (serially)" if self.where == "serial" else f"on {self.where}"

    @property
    def failures(self) -> list[Failure]:
        return [r for r in self.results if isinstance(r, Failure)]

    @property
    def done(self) -> list[Result]:
        return [r for r in self.results if isinstance(r, Result)]

    @property
    def exit_status(self) -> int:
        """As a shell reports it: 128 + the signal's number if one stopped the batch, else 1 if any run
        failed or the batch halted (a full disk), else 0."""
        if self.signal is not None:
            return 128 + self.signal
        return 1 if self.failures or self.halted else 0


def _note(line: str) -> None:
    from tqdm import tqdm
    tqdm.write(f"driftframe: {line}", file=sys.stderr)


def run_all(specs, *, jobs: int | None = None, scheduler=None, progress: bool = True,
            on_done: Callable | None = None, retries: int = 1, note: Callable[[str], None] = _note) -> Outcome:
    """Run every spec; an :class:`Outcome` with a Result or Failure per spec, in spec order.

    All specs are checked first (:func:`check_all`): a bad one raises
    :class:`SpecError` before anything runs. ``jobs``: processes running specs
    (default :func:`plan_jobs`; 1 runs serially here). ``scheduler``: a Dask
    scheduler address or a ``distributed.Client``: run there instead (its
    workers' versions checked first). ``progress``: a tqdm bar on stderr.
    ``on_done(index, result)``: called as each run ends (a Failure
    included). ``retries``: how often a run whose worker died is given again
    (then it is a Failure). ``note(line)``: told of each worker that died.
    Signals: see the module docstring; the Outcome then names the signal and
    unfinished runs are None. A full disk stops the batch the same way (every
    later run would fail on it too): a run that fails for it, or an
    ``on_done`` that raises an OSError for it (its journal), halts the batch,
    the run is None and :attr:`Outcome.halted` says which file.
    :attr:`Outcome.exit_status` is non-zero when a run failed or it halted.
    """
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        raise SpecError(f"retries must be an integer >= 0, got {retries!r}")
    specs = check_all(specs)
    t0 = time.perf_counter()
    client = None
    own_client = False
    if scheduler is not None:
        if jobs is not None:
            raise SpecError("jobs and scheduler exclude each other: the cluster's workers decide")
        if isinstance(scheduler, str):
            client = connect(scheduler)
            own_client = True
        else:
            client = scheduler
        try:
            check_versions(client)
        except BaseException:
            if own_client:
                client.close()
            raise
        jobs_used, lp = 0, None
    else:
        jobs_used, lp = plan_jobs(specs, jobs)
    results: list = [None] * len(specs)

    from tqdm import tqdm

    bar = tqdm(total=len(specs), unit="run", desc="batch", disable=not progress, dynamic_ncols=True)
    failed = 0
    flag = StopFlag()
    halted: list[str] = []

    def halt(why: str) -> None:
        if not halted:
            halted.append(why)
            flag.halt()

    def done(i, res):
        nonlocal failed
        if isinstance(res, Failure) and res.no_space:
            halt(res.no_space)          # not the run's fault: it did not finish, --resume runs it again
            return
        results[i] = res
        if isinstance(res, Failure):
            failed += 1
            bar.set_postfix(failed=failed)
        bar.update(1)
        if on_done is not None:
            try:
                on_done(i, res)
            except OSError as e:
                if not no_space(e):
                    raise
                halt(str(e))

    try:
        if client is not None:
            where = f"cluster {client.scheduler.address}"
            signum = run_cluster(client, specs, done, retries=retries, flag=flag)
        else:
            where = "serial" if jobs_used == 1 else f"{jobs_used} processes"
            signum = run_local(specs, jobs_used, lp, done, retries=retries, note=note, flag=flag)
    finally:
        bar.close()
        if own_client:
            client.close()
    return Outcome(results, signum, time.perf_counter() - t0, jobs_used, where, halted[0] if halted else None)
