"""Many runs at once: one picklable function per run, mapped over a process pool or a Dask cluster.

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

:func:`run_all` is the map. No scheduler is written here: it hands the runs
to an executor that exists already.

* Local (default): :class:`concurrent.futures.ProcessPoolExecutor` with the
  ``spawn`` start method (a fork after a GL context exists hangs; see
  ``framework/gl.py``). ``jobs=N`` is N processes running specs: N - 1
  spawned workers take them from the front of the queue, and this process
  (already set up) takes them from the back while it waits, so one worker's
  start-up (about 0.6 s: an interpreter, the imports, the compiled kernels)
  is saved. ``jobs=1`` runs serially in this process.
* A cluster: ``scheduler="tcp://host:8786"`` submits the same function to a
  ``dask.distributed`` scheduler (the optional ``cluster`` extra). Workers
  need driftframe installed and, for outputs, the same file system.

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
the traceback) and the others go on. Ctrl-C: the first one stops the batch
(queued runs are cancelled, running ones stop at their next step and delete
what they had written; finished outputs stay whole), a second one aborts at
once. Every run writes its output under a temporary name and moves it into
place only when complete (``framework/recorder.py``), so no output is ever
half-written.

Only one world runs at a time in one process (esper keeps its current world
in a module global): on a Dask worker with several threads, runs queue for a
lock. Start Dask workers with ``--nthreads 1`` and as many processes as cores.
"""
from __future__ import annotations

import contextlib
import dataclasses
import importlib
import inspect
import math
import os
import signal
import threading
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

#: The stats a run can collect; all of them by default.
STATS = ("energy", "momentum", "contacts", "stages")
SKIES = ("lines", "starfield")
#: Frame size of a recording when a spec gives none (pixels).
DEFAULT_SIZE = (640, 360)

# esper's current world is a module global, and so are the columnar tables: one run at a time per process
_ONE_WORLD = threading.Lock()


class SpecError(ValueError):
    """A spec (or a batch file entry) that cannot run; the message names the entry and the bad value."""


class Interrupted(Exception):
    """A run stopped because the batch was asked to stop (Ctrl-C). Not a failure: nothing was written."""


@dataclass(frozen=True)
class Spec:
    """One run. Give ``demo`` (a name from ``driftframe list``) or ``scene`` (``"pkg.mod:func"``).

    ``scene``: a function ``func(world, rng, **overrides)`` that creates
    entities in a world that has the standard systems (no scripted input).
    ``overrides``: for a scene, keyword arguments of ``func``; for a demo, its
    module settings (upper-case names such as swarm's ``COUNT``), set only
    while the scene is built. ``seconds``: simulated length (default: the
    demo's ``SECONDS``; required for a scene). ``output``: ``None`` for a
    headless run (physics only), else a ``.mp4``/``.gif`` path or a directory
    for PNG frames, rendered at ``size`` and ``fps`` (which must divide the
    simulation rate), with ``camera`` (one of ``components.camera.MODES``;
    default: the scene's own) and ``sky`` (:data:`SKIES`). ``scripted``: fly the demo's scripted input (its thrust
    adds energy; False measures the solver alone). ``stats``: which of
    :data:`STATS` to collect. ``where``: how error messages name this run.
    """

    demo: str | None = None
    scene: str | None = None
    seed: int = 0
    seconds: float | None = None
    fps: float = 60.0
    size: tuple[int, int] = DEFAULT_SIZE
    camera: str | None = None
    sky: str = "lines"
    overrides: dict = field(default_factory=dict)
    output: str | None = None
    stats: tuple[str, ...] = STATS
    scripted: bool = True
    where: str = ""
    #: Replace an existing output (the batch command checks outputs before any run starts).
    overwrite: bool = False

    def __hash__(self):                 # overrides is a dict: hash what it holds
        return hash((self.demo, self.scene, self.seed, self.seconds, self.fps, tuple(self.size), self.camera,
                     self.sky, repr(sorted(self.overrides.items())), self.output, tuple(self.stats), self.scripted,
                     self.overwrite))

    @property
    def label(self) -> str:
        """Short text for progress lines and tables: ``asteroids seed=3``, plus overrides."""
        what = self.demo if self.demo is not None else str(self.scene)
        extra = "".join(f" {k}={v!r}" for k, v in sorted(self.overrides.items()))
        return f"{what} seed={self.seed}{extra}"

    def _err(self, msg: str) -> SpecError:
        return SpecError(f"{self.where or self.label}: {msg}")

    def check(self) -> "Spec":
        """This spec with its defaults filled in (``seconds``, sizes as tuples), or a :class:`SpecError`.

        Imports the scene, checks every value and that the output can be
        written; runs nothing.
        """
        if (self.demo is None) == (self.scene is None):
            raise self._err("give exactly one of demo or scene "
                            f"(got demo={self.demo!r}, scene={self.scene!r})")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise self._err(f"seed must be an integer >= 0, got {self.seed!r}")
        if not isinstance(self.overrides, dict) or not all(isinstance(k, str) for k in self.overrides):
            raise self._err(f"overrides must be a table of names to values, got {self.overrides!r}")
        if self.demo is not None:
            module = _demo_module(self.demo, self._err)
            _check_demo_overrides(module, self.demo, self.overrides, self._err)
            dt = float(self.overrides.get("DT", getattr(module, "DT", 1.0 / 60.0)))
            default_seconds = self.overrides.get("SECONDS", module.SECONDS)
        else:
            func = _scene_function(self.scene, self._err)
            try:
                inspect.signature(func).bind(None, None, **self.overrides)
            except TypeError as e:
                raise self._err(f"overrides {sorted(self.overrides)} do not fit scene {self.scene!r} "
                                f"(func(world, rng, **overrides)): {e}") from None
            dt = 1.0 / 60.0
            default_seconds = None
        seconds = self.seconds if self.seconds is not None else default_seconds
        if seconds is None:
            raise self._err(f"seconds is required for scene {self.scene!r}")
        seconds = _number(seconds, "seconds", self._err)
        fps = _number(self.fps, "fps", self._err)
        _steps_per_frame(fps, dt, self._err)
        size = self.size
        from driftframe.app import parse_size
        try:
            size = parse_size(size if isinstance(size, str) else "x".join(map(str, size)))
        except (TypeError, ValueError) as e:
            raise self._err(str(e)) from None
        from driftframe.components.camera import MODES
        if self.camera is not None and self.camera not in MODES:
            raise self._err(f"camera must be one of {', '.join(MODES)} (or none), got {self.camera!r}")
        if self.sky not in SKIES:
            raise self._err(f"sky must be one of {', '.join(SKIES)}, got {self.sky!r}")
        stats = (self.stats,) if isinstance(self.stats, str) else tuple(self.stats)
        bad = [s for s in stats if s not in STATS]
        if bad:
            raise self._err(f"unknown stat {bad[0]!r}; stats: {', '.join(STATS)}")
        if not isinstance(self.scripted, bool):
            raise self._err(f"scripted must be true or false, got {self.scripted!r}")
        output = None
        if self.output is not None:
            output = os.fspath(self.output)
            _check_output(output, self._err)
        return dataclasses.replace(self, seconds=seconds, fps=fps, size=size, stats=stats, output=output,
                                   seed=int(self.seed))


@dataclass(frozen=True)
class Result:
    """What one run gave. ``stats`` holds what the spec asked for:

    * ``energy``: ``energy_start``, ``energy_end`` (J, kinetic, every body
      with a Velocity and a finite Mass; 1 kg without a Mass) and
      ``energy_drift`` = (end - start) / start;
    * ``momentum``: ``momentum_drift`` = |P_end - P_start| / sum(m |v|) at
      the start (dimensionless), ``momentum_start``/``momentum_end`` (N s, x y z);
    * ``contacts``: collision events resolved over the run;
    * ``stages``: ``stage_seconds``, wall seconds per stage summed over the
      run (``world.profile_total``: for information, never part of the hash).
    """

    spec: Spec
    #: :meth:`World.state_hash` after the last step: equal bits give equal hashes.
    state_hash: str
    steps: int
    stats: dict
    #: The file or directory written, or None for a headless run.
    output: str | None
    #: Frames written (0 for a headless run).
    frames: int
    wall_seconds: float
    ok = True


@dataclass(frozen=True)
class Failure:
    """A run that raised: its spec, the error in one line and the whole traceback."""

    spec: Spec
    error: str
    traceback: str
    wall_seconds: float = 0.0
    ok = False


@dataclass
class Outcome:
    """What :func:`run_all` returns: a Result or Failure per spec (None: never ran, after a stop)."""

    results: list
    interrupted: bool
    wall_seconds: float
    jobs: int
    where: str

    @property
    def failures(self) -> list[Failure]:
        return [r for r in self.results if isinstance(r, Failure)]

    @property
    def done(self) -> list[Result]:
        return [r for r in self.results if isinstance(r, Result)]


# -- checks ----------------------------------------------------------------------------------------
def _number(value, name, err) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value <= 0:
        raise err(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def _steps_per_frame(fps: float, dt: float, err=SpecError) -> int:
    """Whole simulation steps per recorded frame (:func:`driftframe.framework.recorder.steps_per_frame`)."""
    from driftframe.framework.recorder import steps_per_frame
    try:
        return steps_per_frame(fps, dt)
    except ValueError as e:
        raise err(str(e)) from None


def _demo_module(name, err):
    from driftframe import demos
    try:
        return demos.load(name)
    except LookupError as e:
        raise err(str(e)) from None


def _settings(module) -> dict:
    """A demo's overridable settings: its upper-case module constants that are plain numbers."""
    return {k: v for k, v in vars(module).items()
            if k.isupper() and isinstance(v, (int, float)) and not isinstance(v, bool)}


def _check_demo_overrides(module, name, overrides, err) -> None:
    settings = _settings(module)
    for key, value in overrides.items():
        if key not in settings:
            known = ", ".join(sorted(settings)) or "none"
            raise err(f"overrides: demo {name!r} has no setting {key!r}; its settings: {known}")
        old = settings[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                (isinstance(old, int) and not isinstance(value, int)):
            raise err(f"overrides.{key} must be {'an integer' if isinstance(old, int) else 'a number'} "
                      f"like {old!r}, got {value!r}")
        if not math.isfinite(value) or value <= 0:
            raise err(f"overrides.{key} must be > 0, got {value!r}")


def _scene_function(path, err) -> Callable:
    if not isinstance(path, str) or path.count(":") != 1 or not all(path.split(":")):
        raise err(f"scene must be an import path 'package.module:function', got {path!r}")
    mod_name, func_name = path.split(":")
    try:
        module = importlib.import_module(mod_name)
    except ImportError as e:
        raise err(f"scene {path!r}: cannot import module {mod_name!r} ({e})") from None
    func = getattr(module, func_name, None)
    if func is None:
        raise err(f"scene {path!r}: module {mod_name!r} has no {func_name!r}")
    if not callable(func):
        raise err(f"scene {path!r}: {func_name!r} is not a function")
    return func


def _check_output(output: str, err) -> None:
    from driftframe.framework.recorder import output_format
    try:
        output_format(output)
    except ValueError as e:
        raise err(f"output: {e}") from None
    parent = Path(output).parent
    if not parent.is_dir():
        raise err(f"output {output!r}: directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise err(f"output {output!r}: directory {str(parent)!r} is not writable")


def check_output_names(specs) -> None:
    """Each output has a known format and no two runs write the same one (no file system needed)."""
    from driftframe.framework.recorder import output_format

    seen: dict[str, Spec] = {}
    for spec in specs:
        if spec.output is None:
            continue
        try:
            output_format(spec.output)
        except ValueError as e:
            raise spec._err(f"output: {e}") from None
        key = os.path.abspath(os.fspath(spec.output))
        if key in seen:
            raise spec._err(f"output {spec.output!r} is also written by {seen[key].where or seen[key].label}; "
                            "each run needs its own output (put {seed} or another varying field in the name)")
        seen[key] = spec


def check_all(specs) -> list[Spec]:
    """Every spec checked (:meth:`Spec.check`), and no two writing the same output; before anything runs."""
    specs = list(specs)
    for i, spec in enumerate(specs):
        if not isinstance(spec, Spec):
            raise SpecError(f"run {i}: expected a driftframe.batch.Spec, got {spec!r}")
    check_output_names(specs)
    return [spec.check() for spec in specs]


# -- one run ------------------------------------------------------------------------------------
def _build(spec: Spec):
    """A world with the standard systems and the spec's scene; the demo's settings restored after."""
    from driftframe.app import make_world, simulation_systems
    from driftframe.framework.world import World

    if spec.demo is not None:
        module = _demo_module(spec.demo, spec._err)
        saved = {k: getattr(module, k) for k in spec.overrides}
        try:
            for k, v in spec.overrides.items():
                setattr(module, k, v)
            world, _ = make_world(spec.demo, seed=spec.seed, scripted=spec.scripted)
        finally:
            for k, v in saved.items():
                setattr(module, k, v)
        return world
    func = _scene_function(spec.scene, spec._err)
    world = World()
    try:
        for system in simulation_systems(None):
            world.add_system(system)
        func(world, np.random.default_rng(spec.seed), **spec.overrides)
    except BaseException:
        world.close()
        raise
    return world


def _bodies(world):
    """(masses (n,), velocities (n, 3)) of every body with a Velocity and a finite mass, by entity id.

    A body with a Velocity and no Mass weighs 1 kg, as it does in a collision.
    """
    from driftframe.components.body import Mass, Velocity

    vel = world.columns(Velocity)
    ents, v = vel.entities, vel.linear
    kg = np.ones(len(ents))
    massed = world.columns(Mass)
    have = np.isin(ents, massed.entities)
    if have.any():
        kg[have] = world.columns(Mass, ents[have]).kg
    keep = np.isfinite(kg)
    return kg[keep], v[keep]


def _energy(m, v) -> float:
    """Kinetic energy, J: sum of m |v|^2 / 2."""
    return 0.5 * float(np.sum(m * np.einsum("ij,ij->i", v, v)))


class _Meter:
    """Collects a run's stats: energy and momentum at the start and the end, every contact on the way."""

    def __init__(self, world, stats):
        from driftframe.components.collision import CollisionEvent

        self.world = world
        self.stats = stats
        self.contacts = 0
        if "contacts" in stats:
            world.subscribe(CollisionEvent, self._count)
        m, v = _bodies(world)
        self.energy0 = _energy(m, v)
        self.p0 = (m[:, None] * v).sum(axis=0)
        self.pscale = float(np.sum(m * np.linalg.norm(v, axis=1)))

    def _count(self, event) -> None:
        self.contacts += 1

    def finish(self) -> dict:
        out: dict = {}
        m, v = _bodies(self.world)
        if "energy" in self.stats:
            e1 = _energy(m, v)
            out["energy_start"] = self.energy0
            out["energy_end"] = e1
            out["energy_drift"] = (e1 - self.energy0) / self.energy0 if self.energy0 > 0 else e1 - self.energy0
        if "momentum" in self.stats:
            p1 = (m[:, None] * v).sum(axis=0)
            out["momentum_start"] = tuple(float(x) for x in self.p0)
            out["momentum_end"] = tuple(float(x) for x in p1)
            dp = float(np.linalg.norm(p1 - self.p0))
            out["momentum_drift"] = dp / self.pscale if self.pscale > 0 else dp
        if "contacts" in self.stats:
            out["contacts"] = self.contacts
        if "stages" in self.stats:
            out["stage_seconds"] = {k: float(v) for k, v in self.world.profile_total.items()}
        return out


def run(spec: Spec, *, should_stop: Callable[[], bool] | None = None) -> Result:
    """Do one run; a :class:`Result`. Raises on bad input or failure; never leaves a partial output.

    ``should_stop``: polled before every step; when it returns True the run
    stops and raises :class:`Interrupted` after deleting what it had written
    (a batch's Ctrl-C). A KeyboardInterrupt in this process does the same.
    """
    from driftframe.app import attach_rendering
    from driftframe.framework.recorder import record

    spec = spec.check()
    t0 = time.perf_counter()

    def poll(*_):
        if should_stop is not None and should_stop():
            raise Interrupted(f"{spec.where or spec.label}: stopped")

    with _ONE_WORLD:
        world = _build(spec)
        try:
            meter = _Meter(world, spec.stats)
            frames = 0
            if spec.output is None:
                steps = max(1, round(spec.seconds / world.dt))
                for _ in range(steps):
                    poll()
                    world.step()
            else:
                k = _steps_per_frame(spec.fps, world.dt, spec._err)
                n = max(1, round(spec.seconds * spec.fps))
                attach_rendering(world, size=spec.size, camera=spec.camera, sky=spec.sky)

                # an Interrupted raised in before_step makes record() delete everything it wrote
                rec = record(world, spec.output, frames=n, fps=spec.fps, steps_per_frame=k, progress=False,
                             before_step=poll, overwrite=spec.overwrite)
                if rec.interrupted:               # a KeyboardInterrupt: record kept a shorter file; drop it
                    _remove(rec.path)
                    raise KeyboardInterrupt
                frames = rec.frames
            state_hash = world.state_hash()
            stats = meter.finish()
        finally:
            world.close()
    return Result(spec, state_hash, world.step_count, stats, spec.output, frames, time.perf_counter() - t0)


def _remove(path) -> None:
    import shutil
    if path is None:
        return
    p = Path(path)
    if p.is_dir():
        shutil.rmtree(p, ignore_errors=True)
    else:
        p.unlink(missing_ok=True)


def attempt(spec: Spec, should_stop=None):
    """:func:`run`, with any exception turned into a :class:`Failure` (and a stop into ``None``)."""
    t0 = time.perf_counter()
    if should_stop is not None and should_stop():
        return None                     # queued when the batch was stopped: do not even build it
    try:
        return run(spec, should_stop=should_stop)
    except Interrupted:
        return None
    except Exception as e:   # noqa: BLE001 - one run's failure is reported, the batch goes on
        return Failure(spec, f"{type(e).__name__}: {e}", traceback.format_exc(), time.perf_counter() - t0)


# -- how many workers ----------------------------------------------------------------------------
def cores() -> int:
    """CPUs this process may run on (its affinity mask, which containers and ``taskset`` narrow)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


#: Cores one MP4 recording keeps busy, measured alone (CPU time over wall time, asteroids demo, 3 s at
#: 640x360, rasterising on the run's thread): 1.27-1.35 while x264 ran in an ffmpeg process; encoding in
#: the process, 1.08-1.17 against 1.16-1.22 piped on a slower host (kept at 1.3: a pool of 2 cores gets 2
#: workers either way, and more cores err towards fewer). The run's own thread is the critical path; x264
#: (its thread count pinned at ``recorder.X264_THREADS``: the bytes depend on it) runs beside it on the
#: recorder's writer thread, a quarter to a half of the run's own CPU time from 640x360 to 1280x720.
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


# -- many runs -----------------------------------------------------------------------------------
_WORKER_STOP = None


def _worker_init(stop_event, lp_threads) -> None:
    """Pool worker set-up: Ctrl-C is the parent's to handle; the rasteriser's threads as planned."""
    global _WORKER_STOP
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})    # blocked since birth; now ignored
    if lp_threads is not None:
        os.environ["LP_NUM_THREADS"] = str(lp_threads)
    _WORKER_STOP = stop_event


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


def _pool_attempt(spec: Spec):
    return attempt(spec, _WORKER_STOP.is_set if _WORKER_STOP is not None else None)


def _dask_attempt(spec: Spec, stop_name: str):
    """:func:`attempt` on a Dask worker; the batch's stop flag is a distributed Event, read twice a second.

    The worker's first run warms the kernel cache first, one worker at a time per cache folder (a file
    lock): the first compiles, the rest then load."""
    from distributed import Event

    from driftframe.framework.kernels import warm_once

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


class _StopFlag:
    """The first Ctrl-C sets the flag (runs stop at their next step); a second raises KeyboardInterrupt."""

    def __init__(self, on_stop=None):
        self.event = threading.Event()
        self.on_stop = on_stop
        self._old = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum, frame):
        if self.event.is_set():
            raise KeyboardInterrupt
        self.event.set()
        if self.on_stop is not None:
            self.on_stop()

    def __exit__(self, *exc):
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)


#: Seconds to wait for a Dask scheduler before calling it unreachable.
CONNECT_TIMEOUT = 10.0


def connect(scheduler: str, timeout: float | None = None):
    """A ``distributed.Client`` for ``scheduler``; a :class:`SpecError` naming it if it cannot be reached."""
    timeout = CONNECT_TIMEOUT if timeout is None else timeout
    try:
        from distributed import Client
    except ImportError:
        raise SpecError(f"--scheduler {scheduler}: dask.distributed is not installed; "
                        "pip install 'driftframe[cluster]'") from None
    if not isinstance(scheduler, str) or not scheduler.strip():
        raise SpecError(f"scheduler must be an address like tcp://host:8786, got {scheduler!r}")
    try:
        return Client(scheduler, timeout=timeout)
    except (OSError, TimeoutError, ValueError) as e:
        raise SpecError(f"scheduler {scheduler!r} cannot be reached: {e}") from None


def run_all(specs, *, jobs: int | None = None, scheduler=None, progress: bool = True,
            on_done: Callable | None = None) -> Outcome:
    """Run every spec; an :class:`Outcome` with a Result or Failure per spec, in spec order.

    All specs are checked first (:func:`check_all`): a bad one raises
    :class:`SpecError` before anything runs. ``jobs``: processes running specs
    (default :func:`plan_jobs`; 1 runs serially here). ``scheduler``: a Dask
    scheduler address or a ``distributed.Client``: run there instead.
    ``progress``: a tqdm bar on stderr. ``on_done(index, result)``: called
    as each run ends (a Failure included). Ctrl-C: see the module docstring;
    the Outcome then says ``interrupted`` and unfinished runs are None.
    """
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
        jobs_used, lp = 0, None
    else:
        jobs_used, lp = plan_jobs(specs, jobs)
    results: list = [None] * len(specs)

    from tqdm import tqdm

    bar = tqdm(total=len(specs), unit="run", desc="batch", disable=not progress, dynamic_ncols=True)
    failed = 0

    def done(i, res):
        nonlocal failed
        results[i] = res
        if isinstance(res, Failure):
            failed += 1
            bar.set_postfix(failed=failed)
        if res is not None:
            bar.update(1)
            if on_done is not None:
                on_done(i, res)

    try:
        if client is not None:
            where = f"cluster {client.scheduler.address}"
            interrupted = _on_cluster(client, specs, done)
        elif jobs_used == 1:
            where = "serial"
            interrupted = _serial(specs, done)
        else:
            where = f"{jobs_used} processes"
            interrupted = _on_pool(specs, jobs_used, lp, done)
    finally:
        bar.close()
        if own_client:
            client.close()
    return Outcome(results, interrupted, time.perf_counter() - t0, jobs_used, where)


def _serial(specs, done) -> bool:
    with _StopFlag() as flag:
        for i, spec in enumerate(specs):
            if flag.event.is_set():
                break
            done(i, attempt(spec, flag.event.is_set))
        return flag.event.is_set()


def _on_pool(specs, jobs, lp, done) -> bool:
    """``jobs`` processes run the specs: ``jobs - 1`` spawned workers take them from the front of the
    queue, and this process, already set up (imports, compiled kernels loaded), from the back, one at
    a time while it waits for the workers. A worker's start (an interpreter, the imports, loading the
    kernels: about 0.6 s here) is then paid once less, which on short runs is most of what a pool
    costs. This process takes a spec only while its future can still be cancelled (not yet handed to
    a worker), so each spec runs exactly once."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    ctx = multiprocessing.get_context("spawn")      # never fork: a fork after a GL context exists hangs
    stop = ctx.Event()
    with _StopFlag(on_stop=stop.set) as flag, \
            ProcessPoolExecutor(max_workers=jobs - 1, mp_context=ctx, initializer=_worker_init,
                                initargs=(stop, lp)) as pool:
        # workers start inside submit(), with SIGINT blocked (fork and exec keep the signal mask): a Ctrl-C
        # while they import cannot kill one, and in this process it waits until the mask is lifted
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            order = [pool.submit(_pool_attempt, spec) for spec in specs]
        finally:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        futures = {f: i for i, f in enumerate(order)}
        pending = set(futures)
        back = len(order) - 1                       # the next spec this process may take
        while pending:
            mine = None
            while back >= 0 and not flag.event.is_set():
                f = order[back]
                back -= 1
                if f.cancel():                      # still queued: this process runs it
                    pending.discard(f)
                    mine = futures[f]
                    break
                back = -1                           # the workers have reached the back: leave the rest
            if mine is not None:
                with _rasteriser_threads(lp):      # as planned for every process, this one's runs too
                    res = attempt(specs[mine], flag.event.is_set)
                done(mine, res)
                finished, pending = wait(pending, timeout=0, return_when=FIRST_COMPLETED)
            else:
                finished, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            for f in finished:
                i = futures[f]
                if f.cancelled():
                    continue
                exc = f.exception()
                if exc is not None and flag.event.is_set():
                    continue            # stopping: a worker that went down with the batch is not a failure
                if exc is not None:     # the worker itself broke (killed, out of memory)
                    done(i, Failure(specs[i], f"{type(exc).__name__}: {exc}",
                                    "".join(traceback.format_exception(exc))))
                else:
                    done(i, f.result())
            if flag.event.is_set():
                for f in pending:
                    f.cancel()          # queued runs never start; running ones see the stop event
        return flag.event.is_set()


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


def _on_cluster(client, specs, done) -> bool:
    import uuid

    from distributed import Event

    tag = uuid.uuid4().hex[:12]
    stop = Event(f"driftframe-batch-stop-{tag}", client=client)
    futures = {client.submit(_dask_attempt, spec, stop.name, pure=False, key=f"driftframe-run-{i}-{tag}"): i
               for i, spec in enumerate(specs)}
    with _StopFlag() as flag:
        pending = set(futures)
        stopped_at = None
        while pending:
            finished = {f for f in pending if f.status in ("finished", "error", "cancelled")}
            pending -= finished
            for f in finished:
                i = futures[f]
                if f.status == "finished":
                    done(i, f.result())
                elif f.status == "error":
                    exc = f.exception()
                    done(i, Failure(specs[i], f"{type(exc).__name__}: {exc}",
                                    "".join(traceback.format_exception(exc))))
            if flag.event.is_set() and stopped_at is None:
                stopped_at = time.monotonic()
                stop.set()              # running tasks stop within half a second and delete their output
                _cancel_unstarted(client, pending)
            if stopped_at is not None and time.monotonic() - stopped_at > 60:
                break                   # a worker that does not answer: stop waiting for it
            if pending:
                time.sleep(0.05)
        return flag.event.is_set()
