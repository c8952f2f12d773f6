"""Where a batch's runs go: this process, worker processes it owns, or a Dask cluster.

Part of :mod:`driftframe.batch` (see its docstring; :func:`driftframe.batch.run_all` picks one).

* This process runs its share of the specs on one helper thread, so that its
  main thread only waits and takes signals: a Ctrl-C, SIGTERM or SIGHUP is
  handled within a fraction of a second even while a first run compiles its
  kernels (numba's compiler calls back into Python through ctypes, where an
  exception raised by a signal handler would be printed and dropped).
* Workers are ``spawn``-ed processes this process owns, one spec at a time
  each over a pipe. Each dies with its parent, whatever killed the parent
  (SIGKILL included): ``prctl(PR_SET_PDEATHSIG, SIGTERM)`` on Linux, and a
  thread that watches the parent's pid everywhere; on SIGTERM a worker stops
  its run (its temporary file deleted) and exits, and after 0.5 s it exits
  regardless. A worker that dies is reported once and its run given again
  to a new one, up to ``retries`` times; no other run is touched.
* A cluster: the same run function submitted to ``dask.distributed``, with
  ``retries=``, after a version check of every worker against this client.
"""
from __future__ import annotations

import contextlib
import gc
import os
import signal
import sys
import threading
import time
import traceback
from collections import deque

from driftframe.batch_run import Failure, attempt
from driftframe.batch_spec import Spec, SpecError

#: Signals that stop a batch: Ctrl-C, and SIGTERM / SIGHUP (as for ``record``).
STOP = tuple(s for s in (signal.SIGINT, getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)) if s)


class Aborted(KeyboardInterrupt):
    """A second stop signal: the batch is abandoned at once. ``signum``: the signal."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


class StopFlag:
    """While active (main thread only), SIGINT, SIGTERM and SIGHUP stop the batch: the first sets
    :attr:`event` and :attr:`signum` (runs stop at their next step), a second raises :class:`Aborted`.
    :meth:`halt` stops it as the first signal would, with no signal (a full disk).

    A signal whose handler is not the default (SIGHUP ignored under ``nohup``,
    an application's own) is left alone; the command line's (which makes
    SIGTERM and SIGHUP an interrupt) is taken over.
    """

    def __init__(self, on_stop=None):
        self.event = threading.Event()
        self.signum: int | None = None
        self.on_stop = on_stop
        self._old: dict = {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            from driftframe.framework.recorder import raise_interrupted     # the command line's own
            for s in STOP:
                default = signal.default_int_handler if s == signal.SIGINT else signal.SIG_DFL
                if signal.getsignal(s) in (default, raise_interrupted):
                    self._old[s] = signal.signal(s, self._handler)
        return self

    def _handler(self, signum, frame):
        if self.signum is not None:
            raise Aborted(signum)
        self.signum = signum
        self.halt()

    def halt(self) -> None:
        """Stop the batch: queued runs never start, running ones stop at their next step."""
        self.event.set()
        if self.on_stop is not None:
            self.on_stop()

    def __exit__(self, *exc):
        for s, old in self._old.items():
            signal.signal(s, old)
        self._old.clear()


def signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


# -- how many workers ----------------------------------------------------------------------------
def cores() -> int:
    """CPUs this process may run on (its affinity mask, which containers and ``taskset`` narrow)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


#: Cores one MP4 recording keeps busy: its own thread, and x264 on the recorder's writer thread. Set above
#: the measured, so more cores err towards fewer workers (docs/design/recorder.md, "How many recordings").
RECORDING_CORES = 1.3


def plan_jobs(specs, jobs: int | None = None, *, ncores: int | None = None) -> tuple[int, int | None]:
    """``(jobs, lp_threads)``: processes that run specs (this one and ``jobs - 1`` workers), and
    ``LP_NUM_THREADS`` for each (None: leave it).

    The rule: ``jobs = round(cores / cores_per_run)``, at least 1 and at most
    the number of runs. A headless run keeps one thread busy: 1 core. An
    MP4 recording keeps :data:`RECORDING_CORES` busy: its own thread
    (Python, the GL driver's vertex work, read-back) and, beside it, the
    x264 encoder, whose thread count is pinned for identical bytes, so its
    load is counted rather than capped. Rounding, not flooring: a slightly
    oversubscribed core costs less than an idle one. Mesa's rasteriser
    starts ``LP_NUM_THREADS`` threads in every process (default: one per
    core): with several workers each gets ``cores // jobs``, and 0 where
    that is 1 (llvmpipe then rasterises on the calling thread: one
    rasteriser thread only adds a hand-off; a recording at 1280x720 made 85
    frames/s with it and 115 without), unless ``LP_NUM_THREADS`` is set
    already, which is left alone. The pictures do not depend on it.
    """
    ncores = ncores or cores()
    specs = list(specs)
    if jobs is None:
        videos = any(s.output is not None and str(s.output).endswith(".mp4") for s in specs)
        per_run = RECORDING_CORES if videos else 1.0
        jobs = max(1, round(ncores / per_run))
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise SpecError(f"jobs must be an integer >= 1, got {jobs!r}")
    jobs = max(1, min(jobs, len(specs) or 1))
    lp = None
    if jobs > 1 and "LP_NUM_THREADS" not in os.environ:
        lp = ncores // jobs
        lp = lp if lp > 1 else 0            # one core a process: rasterise on the run's thread
    return jobs, lp



# -- this process and its workers ---------------------------------------------------------------
@contextlib.contextmanager
def _rasteriser_threads(lp_threads):
    """``LP_NUM_THREADS`` as planned while this process runs a spec of a pool's batch, then as it was; a
    value the user set is left alone. Mesa reads it once a process, when the first GL context is made:
    it holds for this process only if no context was made here before the batch (as in ``driftframe
    batch``; a program that rendered before keeps the threads it started with: the pictures are the
    same, only the speed differs)."""
    if lp_threads is None or "LP_NUM_THREADS" in os.environ:
        yield
        return
    os.environ["LP_NUM_THREADS"] = str(lp_threads)
    try:
        yield
    finally:
        os.environ.pop("LP_NUM_THREADS", None)


def _failure(spec, exc, wall=0.0) -> Failure:
    return Failure(spec, f"{type(exc).__name__}: {exc}", "".join(traceback.format_exception(exc)), wall)


class _Runner:
    """This process's runs, one at a time on a helper thread; a byte on :attr:`wake` as each ends."""

    def __init__(self, stopped, lp):
        self.stopped = stopped              # the batch's stop: polled before every step
        self.lp = lp
        self.wake, self._signal = os.pipe()
        self.busy: tuple[int, Spec] | None = None
        self.result = None
        self._thread: threading.Thread | None = None

    def start(self, i: int, spec: Spec) -> None:
        self.busy, self.result = (i, spec), None
        self._thread = threading.Thread(target=self._run, args=(spec,), name="driftframe-batch-run", daemon=True)
        self._thread.start()

    def _run(self, spec) -> None:
        t0 = time.perf_counter()
        try:
            with _rasteriser_threads(self.lp):      # as planned for every process, this one's runs too
                self.result = attempt(spec, self.stopped)
        except BaseException as e:  # noqa: BLE001 - a run must never take the batch down (SystemExit, ...)
            self.result = _failure(spec, e, time.perf_counter() - t0)
        finally:
            os.write(self._signal, b"x")

    def take(self):
        """(index, result) of the run that ended; None while one is going."""
        if self.busy is None or self._thread is None or self._thread.is_alive():
            return None
        os.read(self.wake, 1)
        (i, _), res = self.busy, self.result
        self.busy = self._thread = None
        return i, res

    def cut(self, timeout: float) -> None:
        """After an abort: wait up to ``timeout`` s for the run (it stops at its next step), then leave it
        to die with the process, deleting its temporary output (a first run can be deep in a compile)."""
        if self._thread is not None:
            self._thread.join(timeout)
            if self._thread.is_alive() and self.busy is not None and self.busy[1].output is not None:
                _remove_parts(self.busy[1].output, os.getpid())

    def close(self) -> None:
        os.close(self.wake)
        os.close(self._signal)


def _remove_parts(output, pid: int) -> None:
    """The temporary outputs of ``output`` made by process ``pid`` (``.NAME.<pid>.<random>.part...``)."""
    import shutil
    from pathlib import Path
    p = Path(output)
    with contextlib.suppress(OSError):
        for name in os.listdir(p.parent):
            if name.startswith(f".{p.name}.{pid}.") and (".part" in name or name.endswith(".old")):
                target = p.parent / name
                if target.is_dir() and not target.is_symlink():
                    shutil.rmtree(target, ignore_errors=True)
                else:
                    target.unlink(missing_ok=True)


def _die_with_parent(parent_pid: int, die) -> None:
    """Make this worker end within a second of its parent, however the parent ended (SIGKILL too):
    SIGTERM at once where the kernel sends it, and a watch that calls ``die(1)`` 0.5 s after it sees the
    parent gone, whatever the run is doing then."""
    if sys.platform.startswith("linux"):
        import ctypes
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGTERM), 0, 0, 0)         # PR_SET_PDEATHSIG = 1 (linux/prctl.h)
        except (OSError, AttributeError):
            pass                                               # the watch below still holds
    if os.getppid() != parent_pid:                             # the parent died before the prctl
        os._exit(1)

    def watch():
        while os.getppid() == parent_pid:
            time.sleep(0.2)
        with contextlib.suppress(OSError):
            os.kill(os.getpid(), signal.SIGTERM)               # where no PDEATHSIG: stop the run, clean up
        time.sleep(0.5)                                        # a run stops at its next step; a compile may not
        die(1)

    threading.Thread(target=watch, name="driftframe-parent-watch", daemon=True).start()


def _worker_main(conn, parent_pid: int, lp_threads) -> None:
    """A pool worker: runs each (index, spec) it is sent and sends back (index, Result | Failure | None).

    SIGTERM or SIGHUP (its parent died, or someone ended it) stops its run at the next step (the run
    deletes its temporary file) and ends the worker without an answer, so that a living parent gives the
    run again; a run that had already finished (the signal came while it closed its file) is answered
    first, so that its output, in place, is in the summary and the journal. The handler raises nothing: an exception raised by a signal handler inside an import
    lock's callback or numba's compiler (called back from C) is printed and dropped, and the run went on.
    """
    current: list = [None]                  # the spec being run: its part files go if the worker must die

    def die(code: int) -> None:
        spec = current[0]
        if spec is not None and spec.output is not None:
            _remove_parts(spec.output, os.getpid())
        os._exit(code)

    _die_with_parent(parent_pid, die)
    ended: list[int] = []

    def gone(signum, frame):
        if current[0] is None:
            die(128 + signum)                                   # idle: nothing to stop
        if not ended:
            ended.append(signum)
            # a run deep in a compile never reaches its next step: it is cut after 0.5 s
            threading.Timer(0.5, die, args=(128 + signum,)).start()

    signal.signal(signal.SIGINT, signal.SIG_IGN)                # Ctrl-C is the parent's to handle
    for s in STOP[1:]:
        signal.signal(s, gone)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, set(STOP))      # blocked since the spawn
    if lp_threads is not None:
        os.environ["LP_NUM_THREADS"] = str(lp_threads)
    from tqdm import tqdm
    # tqdm's default lock is a multiprocessing semaphore, which the resource tracker would report as
    # leaked when this worker is ended by a signal; a worker draws no bar: a thread lock does
    tqdm.set_lock(threading.RLock())
    stopping = [False]

    def should_stop():
        if ended:
            return True
        if not stopping[0] and conn.poll():
            if conn.recv() == "stop":                           # EOFError: the parent is gone
                stopping[0] = True
        return stopping[0]

    try:
        while True:
            msg = conn.recv()
            if msg is None:
                break
            if msg == "stop":                                  # came after its run had ended
                continue
            i, spec = msg
            stopping[0] = False
            current[0] = spec
            res = attempt(spec, should_stop)
            if ended and (res is None or isinstance(res, Failure)):
                die(128 + ended[0])                             # not an answer: a living parent retries it
            current[0] = None
            conn.send((i, res))
            if ended:       # the run had finished (its output in place) when the signal came: answered, then end
                die(128 + ended[0])
    except (EOFError, OSError, KeyboardInterrupt):
        pass
    finally:
        os._exit(0)                 # no interpreter teardown: nothing of ours is left to flush


class _Worker:
    def __init__(self, ctx, lp):
        parent, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(child, os.getpid(), lp), daemon=True,
                                name="driftframe-batch-worker")
        # a stop signal while it starts (imports driftframe) waits until its handlers are in place
        old = signal.pthread_sigmask(signal.SIG_BLOCK, set(STOP))
        try:
            self.proc.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
        child.close()
        self.conn = parent
        self.busy: tuple[int, Spec] | None = None

    def send(self, msg) -> bool:
        try:
            self.conn.send(msg)
            return True
        except OSError:
            return False

    def end(self, timeout: float) -> None:
        """Ask it to exit (SIGTERM: a run stops at its next step, deleting its temporary file); kill it
        if it has not after ``timeout`` s."""
        if self.proc.is_alive():
            self.send(None)                     # an idle worker reads it and exits
            if self.busy is not None:
                with contextlib.suppress(OSError):
                    self.proc.terminate()
            self.proc.join(timeout)
            if self.proc.is_alive():
                self.proc.kill()
                self.proc.join(1.0)
        self.conn.close()


def _exit_words(code) -> str:
    if code is not None and code < 0:
        return f"killed by {signal_name(-code)}"
    return f"exited with status {code}"


def run_local(specs, jobs: int, lp, done, *, retries: int = 1, note=print, flag: StopFlag | None = None) -> int | None:
    """Run ``specs`` on this process and ``jobs - 1`` workers; the stop signal's number, or None.

    Workers take specs from the front of the queue; this process, already set
    up (imports, the kernels loaded), takes them from the back, which saves
    one worker's start-up (about 0.6 s; on short runs most of what a pool
    costs). ``done(index, result)`` is called in this thread as each run
    ends. A worker that dies is reported through ``note`` and its run given
    to a new worker up to ``retries`` times, then it is a Failure. ``flag``: the batch's stop (one is
    made if None); ``done`` may :meth:`~StopFlag.halt` it.
    """
    import multiprocessing
    from multiprocessing.connection import wait

    ctx = multiprocessing.get_context("spawn")    # never fork: a fork after a GL context exists hangs
    queue = deque(range(len(specs)))
    deaths: dict[int, int] = {}
    workers: list[_Worker] = []
    stopping = False
    with flag or StopFlag() as flag:
        runner = _Runner(flag.event.is_set, lp)
        try:
            workers = [_Worker(ctx, lp) for _ in range(min(jobs - 1, len(specs)))]
            while True:
                if flag.event.is_set() and not stopping:
                    stopping = True
                    queue.clear()
                    for w in workers:
                        if w.busy is not None:
                            w.send("stop")
                if not stopping:
                    for w in workers:
                        if w.busy is None and queue:
                            i = queue.popleft()
                            w.busy = (i, specs[i])
                            if not w.send(w.busy):
                                break               # its death is seen below
                    if runner.busy is None and queue:
                        i = queue.pop() if workers else queue.popleft()     # serial: in order
                        runner.start(i, specs[i])
                if runner.busy is None and all(w.busy is None for w in workers) and (stopping or not queue):
                    break
                wait([runner.wake] + [w.conn for w in workers] + [w.proc.sentinel for w in workers], 0.5)
                ended = runner.take()
                if ended is not None and ended[1] is not None:
                    done(*ended)
                for w in list(workers):
                    try:
                        while w.conn.poll():
                            i, res = w.conn.recv()
                            w.busy = None
                            if res is not None:
                                done(i, res)
                    except (EOFError, OSError):
                        pass
                    if w.proc.is_alive():
                        continue
                    w.proc.join()
                    workers.remove(w)
                    w.conn.close()
                    if w.busy is None:
                        continue
                    i, spec = w.busy
                    if spec.output is not None:             # what a killed worker could not clean up
                        _remove_parts(spec.output, w.proc.pid)
                    if stopping:
                        continue
                    deaths[i] = deaths.get(i, 0) + 1
                    why = (f"a worker (pid {w.proc.pid}) {_exit_words(w.proc.exitcode)} during "
                           f"{spec.where or spec.label}")
                    if deaths[i] <= retries:
                        note(f"{why}; running it again ({deaths[i]} of {retries} retries)")
                        queue.appendleft(i)
                    else:
                        note(f"{why}; no retries left (--retries {retries})")
                        done(i, Failure(spec, f"WorkerDied: {why}", "", 0.0))
                    if queue and not stopping:
                        workers.append(_Worker(ctx, lp))
        except BaseException:
            # aborted (a second signal): every worker is told to exit now, this process's run is cut
            for w in workers:
                with contextlib.suppress(OSError):
                    w.proc.terminate()
            deadline = time.monotonic() + 0.3          # one wait for all: they were told together
            for w in workers:
                w.end(max(0.0, deadline - time.monotonic()))
            runner.cut(max(0.0, deadline - time.monotonic()))
            workers = []
            raise
        finally:
            for w in workers:
                w.end(1.0)
            if runner.busy is None:
                runner.close()
    return flag.signum


# -- a Dask cluster -----------------------------------------------------------------------------
#: Seconds to wait for a Dask scheduler before calling it unreachable.
CONNECT_TIMEOUT = 10.0


def connect(scheduler: str | None = None, *, scheduler_file=None, timeout: float | None = None):
    """A ``distributed.Client`` for ``scheduler`` (an address) or ``scheduler_file`` (the JSON file
    ``dask scheduler --scheduler-file`` writes); a :class:`SpecError` in one line naming it otherwise:
    unreachable, or something that is not a Dask scheduler."""
    import logging

    timeout = CONNECT_TIMEOUT if timeout is None else timeout
    what = f"--scheduler-file {scheduler_file}" if scheduler_file is not None else f"scheduler {scheduler!r}"
    try:
        from distributed import Client
    except ImportError:
        raise SpecError(f"{what}: dask.distributed is not installed; pip install 'driftframe[cluster]'") from None
    if scheduler_file is not None:
        if not os.path.isfile(scheduler_file):
            raise SpecError(f"{what}: no such file")
    elif not isinstance(scheduler, str) or not scheduler.strip():
        raise SpecError(f"scheduler must be an address like tcp://host:8786, got {scheduler!r}")
    quiet = logging.getLogger("distributed")
    level = quiet.level
    quiet.setLevel(logging.CRITICAL)            # its own warnings about a bad peer: our one line says it
    made: list = []

    def make():
        try:
            # not this process's default client: a task of an in-process worker (a LocalCluster of threads)
            # that asks for a client gets the worker's own, not ours, which the batch closes at its end
            # (the worker kept it, closed: "'NoneType' object has no attribute 'event_is_set'" in a later
            # batch's runs, tests/test_batch.py)
            made.append(Client(scheduler_file=scheduler_file, timeout=timeout, set_as_default=False)
                        if scheduler_file is not None else Client(scheduler, timeout=timeout, set_as_default=False))
        except BaseException as e:  # noqa: BLE001 - handed to the caller's thread
            e.__traceback__ = None              # (its frames held the half-made client: collected below)
            made.append(e)
    try:
        # Client's timeout does not bound its handshake: a server that accepts and then says nothing Dask
        # understands (an HTTP server) held it for ever; here it is a thread, waited for a bounded time.
        # The collector is paused while the client starts (at most the wait below): a Client left half-made
        # by an earlier failed connection closes itself when collected (Client.__del__), which waits for
        # distributed's loop lock; collected inside the loop thread whose start holds that lock, it never
        # got it: a deadlock that hung every later client of the process (a test module's Dask cluster at
        # its teardown). A failed client is collected below instead, at once, with no lock held.
        paused = gc.isenabled()
        gc.disable()
        try:
            helper = threading.Thread(target=make, name="driftframe-dask-connect", daemon=True)
            helper.start()
            helper.join(timeout + min(timeout, 5.0))
        finally:
            if paused:
                gc.enable()
        if made and isinstance(made[0], BaseException):
            gc.collect()
        if not made:
            raise SpecError(f"{what} accepted a connection but did not answer as a Dask scheduler within "
                            f"{timeout + min(timeout, 5.0):.0f} s; is it one?")
        if isinstance(made[0], BaseException):
            raise made[0]
        return made[0]
    except SpecError:
        raise
    except (OSError, TimeoutError) as e:
        raise SpecError(f"{what} cannot be reached, or is not a Dask scheduler: {_one_line(e)}") from None
    except Exception as e:   # noqa: BLE001 - garbage from a non-Dask server, an unsupported protocol, ...
        raise SpecError(f"{what} is not a Dask scheduler it can talk to ({type(e).__name__}: {_one_line(e)})") \
            from None
    finally:
        quiet.setLevel(level)


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def versions() -> dict:
    """The versions a run's bits depend on: driftframe, numpy, numba, PyAV (the encoder's libraries)."""
    import av
    import numba
    import numpy

    from driftframe.framework import __version__
    return {"driftframe": __version__, "numpy": numpy.__version__, "numba": numba.__version__,
            "av": av.__version__}


def check_versions(client, here: dict | None = None) -> None:
    """A :class:`SpecError` naming each package whose version differs between this client and a worker
    (the same spec must give the same bits wherever it runs), before any run is submitted."""
    here = versions() if here is None else here
    try:
        theirs = client.run(versions)
    except Exception as e:   # noqa: BLE001 - a worker without driftframe cannot even unpickle the call
        raise SpecError(f"the cluster's workers cannot run driftframe ({type(e).__name__}: {_one_line(e)})") \
            from None
    diffs = [f"{name} {got.get(name, 'missing')} on {addr} (here {want})"
             for addr, got in sorted(theirs.items()) for name, want in here.items() if got.get(name) != want]
    if diffs:
        more = f" and {len(diffs) - 3} more" if len(diffs) > 3 else ""
        raise SpecError("the cluster's workers have other versions than this client: " + "; ".join(diffs[:3]) +
                        more + "; install the same versions on both")


def dashboard(client) -> str | None:
    """The scheduler's dashboard link, or None when it serves none."""
    try:
        if "dashboard" not in client.scheduler_info().get("services", {}):
            return None
        return client.dashboard_link
    except Exception:   # noqa: BLE001 - only a convenience
        return None


def _dask_attempt(spec: Spec, stop_name: str):
    """:func:`attempt` on a Dask worker; the batch's stop flag is a distributed Event, read twice a second.

    The worker's first run warms the kernel cache first, one worker at a time per cache folder (a file
    lock): the first compiles, the rest then load."""
    from distributed import Event

    from driftframe.warmup import warm_once

    warm_once()

    stop = Event(stop_name)
    last = [0.0, False]

    def should_stop():
        now = time.monotonic()
        if now - last[0] > 0.5:
            last[0] = now
            last[1] = stop.is_set()
        return last[1]

    return attempt(spec, should_stop)


#: Scheduler task states of a run that has not started on any worker.
_UNSTARTED = frozenset({"released", "waiting", "queued", "no-worker"})


def _scheduler_states(dask_scheduler, keys):
    return {k: ts.state for k in keys if (ts := dask_scheduler.tasks.get(k)) is not None}


def _cancel_unstarted(client, futures) -> list:
    """Cancel the runs of ``futures`` that no worker has started; the futures cancelled.

    Decided by the scheduler's own task states, not the client's copy (which lags:
    a run that has just finished can still read "pending" here, and cancelling it
    would drop a whole output from the results). A run that starts between this
    query and the cancel finds the batch's stop flag set and returns at once,
    and so does every queued run where the scheduler refuses the query (one
    that does not run client code): nothing is cancelled then.
    """
    futures = list(futures)
    try:
        states = client.run_on_scheduler(_scheduler_states, keys=[f.key for f in futures])
    except Exception:   # noqa: BLE001 - a scheduler that refuses it: the stop flag alone stops every run
        return []
    queued = [f for f in futures if states.get(f.key) in _UNSTARTED]
    if queued:
        client.cancel(queued)
    return queued


def run_cluster(client, specs, done, *, retries: int = 1, flag: StopFlag | None = None) -> int | None:
    """Submit every spec to ``client``'s cluster (each task with ``retries``: Dask reruns a task whose
    worker died); ``done(index, result)`` as each ends (it may halt ``flag``, the batch's stop). The stop
    signal's number, or None."""
    import uuid

    from distributed import Event

    tag = uuid.uuid4().hex[:12]
    stop = Event(f"driftframe-batch-stop-{tag}", client=client)
    futures = {client.submit(_dask_attempt, spec, stop.name, pure=False, retries=retries,
                             key=f"driftframe-run-{i}-{tag}"): i
               for i, spec in enumerate(specs)}
    with flag or StopFlag() as flag:
        pending = set(futures)
        stopped_at = None
        while pending:
            finished = {f for f in pending if f.status in ("finished", "error", "cancelled")}
            pending -= finished
            for f in finished:
                i = futures[f]
                if f.status == "finished":
                    res = f.result()
                    if res is not None:
                        done(i, res)
                elif f.status == "error":
                    done(i, _failure(specs[i], f.exception()))
            if flag.event.is_set() and stopped_at is None:
                stopped_at = time.monotonic()
                stop.set()              # running tasks stop within half a second and delete their output
                _cancel_unstarted(client, pending)
            if stopped_at is not None and time.monotonic() - stopped_at > 60:
                break                   # a worker that does not answer: stop waiting for it
            if pending:
                time.sleep(0.05)
        return flag.signum
