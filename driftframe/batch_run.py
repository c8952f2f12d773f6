"""One batch run: :func:`run` (a pure function of its :class:`~driftframe.batch.Spec`) and :func:`attempt`.

Part of :mod:`driftframe.batch` (import from there).
"""
from __future__ import annotations

import contextlib
import signal
import threading
import time
import traceback
from dataclasses import dataclass
from typing import Callable

import numpy as np

from driftframe.batch_spec import Interrupted, Spec, _demo_module, _scene_function, _steps_per_frame

# esper's current world is a module global, and so are the columnar tables: one run at a time per process
_ONE_WORLD = threading.Lock()


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
    #: Where the run failed for a full disk (or quota): the message, naming the file. Every later run
    #: would fail the same way, so :func:`~driftframe.batch.run_all` stops the batch instead.
    no_space: str | None = None
    ok = False



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


class _Cut(BaseException):
    """A second Ctrl-C during :func:`run` in the main thread: not a KeyboardInterrupt, which the recorder
    would answer by keeping the frames written so far (over an old output, with ``overwrite``)."""


@contextlib.contextmanager
def _ctrl_c_stops(stop: list):
    """In the main thread, while the default Ctrl-C handler is in place: the first Ctrl-C asks the run to
    stop at its next step (``stop[0]``), a second cuts it at once. Elsewhere nothing changes (the batch's
    own executors take the signals)."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return

    def handle(signum, frame):
        if stop[0]:
            raise _Cut
        stop[0] = True

    old = signal.signal(signal.SIGINT, handle)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def run(spec: Spec, *, should_stop: Callable[[], bool] | None = None) -> Result:
    """Do one run; a :class:`Result`. Raises on bad input or failure; never leaves a partial output.

    ``should_stop``: polled before every step; when it returns True the run
    stops and raises :class:`Interrupted` after deleting what it had written
    (a batch's Ctrl-C). A Ctrl-C in this process does the same and raises
    KeyboardInterrupt. Either way an output that was there before (a run
    with ``overwrite``) is left as it was: the recorder never gets to keep a
    shorter file (it is called with ``handle_signals=False``, and a stop
    reaches it as an exception, which discards the temporary file).
    """
    from driftframe.app import attach_rendering
    from driftframe.framework.recorder import record

    spec = spec.check()
    t0 = time.perf_counter()
    ctrl_c = [False]

    def poll(*_):
        if ctrl_c[0] or (should_stop is not None and should_stop()):
            raise Interrupted(f"{spec.where or spec.label}: stopped")

    with _ONE_WORLD, _ctrl_c_stops(ctrl_c):
        try:
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
                    # an exception raised in before_step makes record() delete everything it wrote
                    rec = record(world, spec.output, frames=n, fps=spec.fps, steps_per_frame=k, progress=False,
                                 before_step=poll, overwrite=spec.overwrite, handle_signals=False)
                    if rec.interrupted:       # a KeyboardInterrupt from the scene's own code: not a whole run
                        raise RuntimeError(f"{spec.where or spec.label}: the recording was interrupted "
                                           f"after {rec.frames} of {n} frames")
                    frames = rec.frames
                state_hash = world.state_hash()
                stats = meter.finish()
            finally:
                world.close()
        except (Interrupted, _Cut):
            if ctrl_c[0]:
                raise KeyboardInterrupt from None
            raise
    return Result(spec, state_hash, world.step_count, stats, spec.output, frames, time.perf_counter() - t0)


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
        return Failure(spec, f"{type(e).__name__}: {e}", traceback.format_exc(), time.perf_counter() - t0,
                       no_space=str(e) if _disk_full(e) else None)


def _disk_full(e: BaseException | None) -> bool:
    """Whether ``e``, or an error it was raised from (the recorder's RecordingError is raised ``from None``
    over the OSError: its ``__context__`` keeps it), is a full disk or quota."""
    from driftframe.framework.output import no_space

    seen = 0
    while e is not None and seen < 8:
        if no_space(e):
            return True
        e, seen = e.__cause__ or e.__context__, seen + 1
    return False

