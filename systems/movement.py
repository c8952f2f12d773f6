"""Newtonian movement."""
from __future__ import annotations

import esper

from driftframe.components.body import Acceleration, Transform, Velocity


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
    reads = (Velocity, Acceleration)
    writes = (Transform, Velocity)

    def process(self, dt: float) -> None:
        world = self.world
        free = world.query(Transform, Velocity)
        free.refresh()
        if len(free):
            pos = world.table(Transform).data["position"]
            vel = world.table(Velocity).data["linear"]
            pos[free.rows(Transform)] += vel[free.rows(Velocity)] * dt

        acc = world.query(Transform, Velocity, Acceleration)
        acc.refresh()
        if len(acc):
            pos = world.table(Transform).data["position"]
            vel = world.table(Velocity).data["linear"]
            a = world.table(Acceleration).data["linear"][acc.rows(Acceleration)]
            # the v dt part was added above; add the constant-acceleration term, then update v
            pos[acc.rows(Transform)] += (0.5 * dt * dt) * a
            vel[acc.rows(Velocity)] += dt * a
