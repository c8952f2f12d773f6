"""Newtonian movement."""
from __future__ import annotations

import esper

from driftframe.components.body import Acceleration, Transform, Velocity
from driftframe.framework.store import RowCache


class MovementSystem(esper.Processor):
    """Reads Velocity, Acceleration; writes Transform.position, Velocity.  x += v dt (+ a dt^2/2).

    Free bodies: ``x += v dt`` is exact for constant velocity. Bodies with an
    Acceleration (thrust held constant over the step) take the exact
    constant-acceleration update ``x += v dt + a dt^2 / 2; v += a dt`` — not
    explicit Euler (which lags by ``a dt^2 / 2`` per step) nor semi-implicit
    Euler (which leads by as much); see ``benchmarks/thrust_accuracy.py``.
    Nothing else changes velocity here: there is no drag in space.

    All matching bodies are updated with whole-column numpy operations; the
    packed rows are rebuilt only when esper's query result changes.
    """

    stage = "movement"

    def __init__(self):
        self._free = RowCache()
        self._thrust = RowCache()

    def process(self, dt: float) -> None:
        free = self._free
        free.update(esper.get_components(Transform, Velocity))
        if len(free.entities):
            t_rows, v_rows = free.rows
            pos = Transform._table.data["position"]
            vel = Velocity._table.data["linear"]
            pos[t_rows] += vel[v_rows] * dt

        acc = self._thrust
        acc.update(esper.get_components(Transform, Velocity, Acceleration))
        if len(acc.entities):
            t_rows, v_rows, a_rows = acc.rows
            pos = Transform._table.data["position"]
            vel = Velocity._table.data["linear"]
            a = Acceleration._table.data["linear"][a_rows]
            # the v dt part was added above; add the constant-acceleration term, then update v
            pos[t_rows] += (0.5 * dt * dt) * a
            vel[v_rows] += dt * a
