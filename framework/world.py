"""The world: one esper context, the stage order, the step, its profile and its hash.

Data flows one way each step, in the order declared here once::

    input -> control -> movement -> spin -> collision -> camera      (every fixed step)
    render -> record                                                  (every presented frame)

A system is an ``esper.Processor`` with a ``stage`` attribute (one of
:data:`STEP_STAGES` or :data:`FRAME_STAGES`) and ``process(dt)``. Several
systems may share a stage; they run in the order they were added.

``World`` owns a private esper world context and makes it current whenever it
steps, so esper's ordinary module functions (``esper.create_entity``,
``esper.get_components``, ...) act on it from inside systems and from user code
after ``world.activate()`` (a new World is also activated on creation).
"""
from __future__ import annotations

import dataclasses
import hashlib
import itertools
import time
from collections import defaultdict

import esper
import numpy as np

from driftframe.framework import validate
from driftframe.framework.store import Columnar

#: Stages run once per fixed simulation step, in this order.
STEP_STAGES = ("input", "control", "movement", "spin", "collision", "camera")
#: Stages run once per presented frame (window or recorder), in this order.
FRAME_STAGES = ("render", "record")

_ids = itertools.count(1)


def _describe(comp) -> str:
    """Stable text of a plain (non-columnar) component: its fields, never its address."""
    if dataclasses.is_dataclass(comp):
        return repr(dataclasses.astuple(comp))
    fields = getattr(comp, "__dict__", None)
    return repr(sorted(fields.items())) if fields else ""


class World:
    """A simulation: entities (esper), systems in stage order, a fixed time step.

    ``dt`` is the fixed step in seconds (default 1/60 s). The simulation never
    reads the wall clock; ``time`` is ``step_count * dt``.
    """

    def __init__(self, dt: float = 1.0 / 60.0, *, name: str | None = None):
        self.dt = validate.scalar("dt", dt, positive=True)
        self.name = name or f"driftframe-{next(_ids)}"
        if self.name in esper.list_worlds():
            raise ValueError(f"an esper world named {self.name!r} exists already")
        self.systems: dict[str, list] = {s: [] for s in STEP_STAGES + FRAME_STAGES}
        self.step_count = 0
        #: Seconds each stage took in the last step / frame (wall time, for profiling only).
        self.profile: dict[str, float] = {s: 0.0 for s in STEP_STAGES + FRAME_STAGES}
        #: Seconds each stage took in total since creation.
        self.profile_total: dict[str, float] = defaultdict(float)
        #: Things that happened this step (collision events, ...): cleared at each step's start.
        self.events: list = []
        #: Shared per-world services (a GL context, the model cache, ...) keyed by name.
        self.resources: dict = {}
        esper.switch_world(self.name)

    # -- entities ---------------------------------------------------------------
    def activate(self) -> "World":
        """Make this world the current esper context (for esper's module functions)."""
        if esper.current_world != self.name:
            esper.switch_world(self.name)
        return self

    def create_entity(self, *components) -> int:
        """``esper.create_entity`` in this world."""
        self.activate()
        return esper.create_entity(*components)

    def create_entities(self, *columns) -> list[int]:
        """Create ``n`` entities from equally long lists of components (e.g. ``Transform.bulk(n, ...)``).

        ``None`` in place of a list skips it. Returns the entity ids in order.
        """
        cols = [c for c in columns if c is not None]
        if not cols:
            return []
        n = len(cols[0])
        for c in cols:
            if len(c) != n:
                raise ValueError(f"create_entities: component lists differ in length ({len(c)} != {n})")
        self.activate()
        create = esper.create_entity
        return [create(*comps) for comps in zip(*cols)]

    def delete_entity(self, entity: int) -> None:
        self.activate()
        esper.delete_entity(entity, immediate=True)

    # -- systems ----------------------------------------------------------------
    def add_system(self, system, stage: str | None = None):
        """Add an ``esper.Processor`` to its stage (``system.stage`` unless given). Returns it."""
        stage = stage or getattr(system, "stage", None)
        if stage not in self.systems:
            raise ValueError(f"unknown stage {stage!r}; stages are {STEP_STAGES + FRAME_STAGES}")
        if not callable(getattr(system, "process", None)):
            raise TypeError(f"system {system!r} has no process(dt) method")
        system.world = self
        self.systems[stage].append(system)
        return system

    def get_system(self, cls):
        """The first added system that is an instance of ``cls``, or None."""
        for stage in self.systems.values():
            for s in stage:
                if isinstance(s, cls):
                    return s
        return None

    def _run(self, stages, dt) -> None:
        self.activate()
        esper.clear_dead_entities()
        clock = time.perf_counter
        for stage in stages:
            systems = self.systems[stage]
            if not systems:
                self.profile[stage] = 0.0
                continue
            t0 = clock()
            for s in systems:
                s.process(dt)
            took = clock() - t0
            self.profile[stage] = took
            self.profile_total[stage] += took

    def step(self, n: int = 1) -> None:
        """Advance the simulation by ``n`` fixed steps of ``dt``."""
        for _ in range(n):
            self.events.clear()
            self._run(STEP_STAGES, self.dt)
            self.step_count += 1

    def render(self) -> None:
        """Run the per-frame stages (render, record) once."""
        self._run(FRAME_STAGES, self.dt)

    @property
    def time(self) -> float:
        """Simulated seconds since the start (step_count * dt)."""
        return self.step_count * self.dt

    # -- determinism ------------------------------------------------------------
    def state_hash(self) -> str:
        """BLAKE2 hash of every entity's components (exact bytes of the numbers).

        Two runs of the same scene with the same inputs give the same hash;
        any difference in any bit of any component changes it. Entity order
        and table row placement do not matter: values are gathered per entity
        id, in ascending order.
        """
        self.activate()
        h = hashlib.blake2b(digest_size=16)
        h.update(str(self.step_count).encode())
        kinds = sorted(esper._components, key=lambda c: (c.__module__, c.__qualname__))
        for cls in kinds:
            pairs = sorted(esper.get_component(cls), key=lambda p: p[0])
            h.update(cls.__qualname__.encode())
            ents = np.fromiter((e for e, _ in pairs), np.int64, len(pairs))
            h.update(ents.tobytes())
            if issubclass(cls, Columnar):
                rows = np.fromiter((c._row for _, c in pairs), np.intp, len(pairs))
                for name in cls._fields:
                    h.update(np.ascontiguousarray(cls._table.data[name][rows]).tobytes())
            else:
                for _, comp in pairs:
                    h.update(_describe(comp).encode())
        return h.hexdigest()

    def close(self) -> None:
        """Delete the esper world context and drop the world's resources."""
        for res in list(self.resources.values()):
            release = getattr(res, "release", None)
            if callable(release):
                release()
        self.resources.clear()
        if esper.current_world == self.name:
            esper.switch_world("default")
        if self.name in esper.list_worlds():
            esper.delete_world(self.name)

    def __enter__(self):
        return self.activate()

    def __exit__(self, *exc):
        self.close()
