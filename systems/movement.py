"""Newtonian movement."""
from __future__ import annotations

import esper

import numpy as np

from driftframe.components.body import Acceleration, Transform, Velocity
from driftframe.components.collision import SphereCollider
from driftframe.framework.store import as_index, in_sorted, to_indices

#: ``world.resources[SKIP]``: ``{component class: set of claiming systems}``: the bodies with that
#: component are integrated by the claiming system itself (the collision system moves its colliders
#: from the start-of-step state), so movement leaves them alone and the step's data flows one way.
SKIP = "movement.skip"


def _some(rows) -> bool:
    """Rows to touch: a slice (never empty, see store.as_index) or a non-empty index array."""
    return isinstance(rows, slice) or len(rows) > 0


class MovementSystem(esper.Processor):
    """Reads Velocity, Acceleration; writes Transform.position, Velocity.  x += v dt (+ a dt^2/2).

    Free bodies: ``x += v dt`` is exact for constant velocity. Bodies with an
    Acceleration (thrust held constant over the step) take the exact
    constant-acceleration update ``x += v dt + a dt^2 / 2; v += a dt`` — not
    explicit Euler (which lags by ``a dt^2 / 2`` per step) nor semi-implicit
    Euler (which leads by as much); see ``benchmarks/thrust_accuracy.py``.
    Nothing else changes velocity here: there is no drag in space.

    Bodies with a component listed in ``world.resources[SKIP]`` are left to
    the system that claimed them (a CollisionSystem integrates its colliders).

    All matching bodies are updated with whole-column numpy operations; the
    packed rows are rebuilt only when esper's query result changes.
    """

    stage = "movement"
    # SphereCollider: only to leave the colliders to a CollisionSystem in the world (see SKIP)
    reads = (Velocity, Acceleration, SphereCollider)
    writes = (Transform, Velocity)

    requires = (Transform, Velocity)
    #: Resources this system's world makes again on a load, never taken from a save (framework/save.py):
    #: the skip table holds claims by system object ids, which a rebuilt world's systems make anew.
    rebuilt_resources = (SKIP,)

    def __init__(self):
        self._kept = {}
        self._plan_key = None
        self._plan = ()

    def _rows(self, q, types, skip):
        """``q.rows(T)`` for each of ``types``, without the bodies that have a class in ``skip``."""
        got = self._kept.get(q.types)
        if got is not None and got[0] == (q.version, skip):
            return got[1]
        rows = tuple(q.rows(T) for T in types)
        if skip:
            world = self.world
            claimed = []
            for cls in skip:
                c = world.query(cls)
                c.refresh()
                claimed.append(c.entities)
            keep = ~in_sorted(q.entities, claimed[0] if len(claimed) == 1 else np.sort(np.concatenate(claimed)))
            if not keep.all():
                rows = tuple(as_index(to_indices(r)[keep]) if keep.any() else np.empty(0, np.intp)
                             for r in rows)
        self._kept[q.types] = ((q.version, skip), rows)
        return rows

    def _moves(self, skip: frozenset) -> tuple:
        """What a step does, as packed rows: ``((t_rows, v_rows), (t_rows, v_rows, a_rows))`` with either
        left out when it has no body (every body claimed by a collision system: nothing)."""
        world = self.world
        moves = []
        for types in ((Transform, Velocity), (Transform, Velocity, Acceleration)):
            q = world.query(*types)
            q.refresh()
            if len(q):
                rows = self._rows(q, types, skip)
                if _some(rows[0]):
                    moves.append(rows)
            elif len(types) == 2:
                break                           # (no body with a Velocity: none with an Acceleration either)
        return tuple(moves)

    def prepare(self) -> None:
        """The packed rows of the current bodies (see :meth:`World.prepare`)."""
        skip = self._skip()
        self._plan = self._moves(skip)
        self._plan_key = (self.world.epoch, skip)

    def _skip(self) -> frozenset:
        skip = self.world.resources.get(SKIP)
        return frozenset(cls for cls, by in skip.items() if by) if skip else frozenset()

    def process(self, dt: float) -> None:
        world = self.world
        skip = self._skip()
        # the rows change only when entities gain or lose components (the world's epoch) or a system
        # claims or frees a class of bodies; a step otherwise reuses them
        if self._plan_key is None or self._plan_key[0] != world.epoch or self._plan_key[1] != skip:
            self._plan = self._moves(skip)
            self._plan_key = (world.epoch, skip)
        if not self._plan:
            return
        pos = world.table(Transform).data["position"]
        vel = world.table(Velocity).data["linear"]
        for rows in self._plan:
            if len(rows) == 2:
                t_rows, v_rows = rows
                pos[t_rows] += vel[v_rows] * dt
            else:
                t_rows, v_rows, a_rows = rows
                a = world.table(Acceleration).data["linear"][a_rows]
                # the v dt part was added above; add the constant-acceleration term, then update v
                pos[t_rows] += (0.5 * dt * dt) * a
                vel[v_rows] += dt * a
