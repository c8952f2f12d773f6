"""Newtonian movement: the step's predict stage."""
from __future__ import annotations

import esper

import numpy as np

from driftframe.components.body import Acceleration, Transform, Velocity
from driftframe.framework import kernels
from driftframe.framework.step import StepContext, advance
from driftframe.framework.store import as_index, in_sorted, to_indices


def _some(rows) -> bool:
    """Rows to touch: a slice (never empty, see store.as_index) or a non-empty index array."""
    return isinstance(rows, slice) or len(rows) > 0


class MovementSystem(esper.Processor):
    """Reads Transform, Velocity, Acceleration; writes StepContext.  Predicts every body's end of the step:
    ``x1 = x0 + v0 dt + a dt^2/2``, ``v1 = v0 + a dt`` (:func:`~driftframe.framework.step.advance`).

    The prediction goes into the step's :class:`~driftframe.framework.step.StepContext`
    (``world.step_context``), which the gravity and collision systems correct
    for the bodies they own and the commit stage writes into ``Transform`` and
    ``Velocity``: every
    body is predicted, so a body nobody owns ends where free flight takes it,
    and no system is told to skip another's bodies. Bodies with an
    Acceleration (thrust held constant over the step) take the exact
    constant-acceleration update. Nothing else changes velocity here: there is
    no drag in space.

    All matching bodies are updated with whole-column operations (free flight
    of contiguous rows in one compiled call, framework/free_flight.py, the same
    bits as numpy's); the packed rows are rebuilt only when entities gain or
    lose components.
    """

    stage = "movement"
    reads = (Transform, Velocity, Acceleration)
    writes = (StepContext,)
    requires = (Transform, Velocity)
    keeps_entities = True                 # (it adds and removes nothing: the world need not look after it)

    def __init__(self) -> None:
        self._plan_epoch = None
        self._plan = ()
        self._views_key = None
        self._views = ()
        self._tables = (None, None)           # the Transform and Velocity tables (a world's, kept)
        self._whole = False                   # the plan writes every row of the step context's positions
        # dt as a 0-d array (numpy's multiply takes it sooner than a float, which it converts at every call;
        # the same bits: docs/design/costs.md), the dt it was made from, and that as a float (free flight's)
        self._dt, self._dt_f, self._dt_x = np.array(0.0), 0.0, 0.0
        self._free_flight = None              # framework/free_flight.py's kernel, loaded by prepare()

    def _moves(self) -> tuple:
        """What a step does, as packed rows: ``((t_rows, v_rows), (t_rows, v_rows, a_rows))``, the bodies
        without an Acceleration and those with one, either left out when it has no body."""
        world = self.world
        q = world.query(Transform, Velocity)
        q.refresh()
        if not len(q):
            return ()
        qa = world.query(Transform, Velocity, Acceleration)
        qa.refresh()
        if not len(qa):
            return ((q.rows(Transform), q.rows(Velocity)),)
        keep = ~in_sorted(q.entities, qa.entities)
        moves = []
        if keep.any():
            moves.append(tuple(as_index(to_indices(q.rows(T))[keep]) for T in (Transform, Velocity)))
        moves.append((qa.rows(Transform), qa.rows(Velocity), qa.rows(Acceleration)))
        return tuple(m for m in moves if _some(m[0]))

    def prepare(self) -> None:
        """The packed rows of the current bodies, and the step context's buffers and the views into them
        (see :meth:`World.prepare`)."""
        world = self.world
        self._plan = self._moves()
        self._plan_epoch = world.epoch
        ctx = world.step_context
        t_table, v_table = self._tables = world.table(Transform), world.table(Velocity)
        if self._dt_f != world.dt:
            self._set_dt(world.dt)
        if self._free_flight is None and self._plan:
            # (imported here, not at the top: numba is loaded when a world first has a body to move)
            from driftframe.framework.free_flight import free_flight
            self._free_flight = free_flight
        ctx.prepare(t_table, v_table)
        self._views = self._views_of(ctx)           # (free flight's kernel loaded there, not at the first step)
        # one group without an Acceleration over rows 0..size of the Transform table: its prediction is
        # every row of the context's positions, so the step need not copy them in first
        rows = self._plan[0][0] if len(self._plan) == 1 and len(self._plan[0]) == 2 else None
        self._whole = isinstance(rows, slice) and not rows.start and rows.stop == t_table.size \
            and rows.step in (None, 1)

    def _set_dt(self, dt: float) -> None:
        self._dt, self._dt_f, self._dt_x = np.array(float(dt)), dt, float(dt)

    def _views_of(self, ctx) -> tuple:
        """Per group of the plan: ``(x0, v0, a, x1, v1, rows, run)``: ``x0 .. v1`` views into the tables and
        the context where the rows are contiguous (kept until the structure or the context's buffers
        change; ``rows`` None), else ``rows``; ``run``: for contiguous free flight (no ``a``), the compiled
        free flight's entry point for these views' types (kernels.entry: the views and ``float(dt)`` are
        what every call passes), else None."""
        world = self.world
        pos, vel = world.table(Transform).data["position"], world.table(Velocity).data["linear"]
        acc = world.table(Acceleration).data["linear"] if any(len(g) == 3 for g in self._plan) else None
        out = []
        for rows in self._plan:
            t_rows, v_rows = rows[0], rows[1]
            a_rows = rows[2] if len(rows) == 3 else None
            if isinstance(t_rows, slice) and isinstance(v_rows, slice):
                x0, v0, x1 = pos[t_rows], vel[v_rows], ctx.position[t_rows]
                run = kernels.entry(self._free_flight, (x0, v0, self._dt_x, x1)) if a_rows is None else None
                out.append((x0, v0, None if a_rows is None else acc[a_rows], x1, ctx.velocity_buffer[v_rows],
                            None, run))
            else:
                out.append((None, None, None, None, None, rows, None))
        self._views_key = (world.epoch, ctx.position, ctx.velocity_buffer)
        return tuple(out)

    def dry_run_safe(self, dt: float) -> bool:
        """Whether :meth:`process` may run in ``World.prepare``'s dry steps: it writes only into the step
        context (unless a subclass changed it)."""
        return type(self).process is MovementSystem.process

    def process(self, dt: float) -> None:
        world = self.world
        # the rows change only when entities gain or lose components (the world's epoch)
        if self._plan_epoch != world.epoch:
            self.prepare()
        ctx = world.step_context
        t_table, v_table = self._tables
        ctx.begin(world.step_count, dt, t_table, v_table, self._whole)
        key = self._views_key                         # (made at this epoch: prepare() made them both)
        if key[1] is not ctx.position or key[2] is not ctx.velocity_buffer:
            self._views = self._views_of(ctx)
        if self._dt_f != dt:
            self._set_dt(dt)
        dt0 = self._dt
        for x0, v0, a, x1, v1, rows, run in self._views:
            if run is not None:                       # free flight: advance()'s update, compiled (the same bits)
                run(x0, v0, self._dt_x, x1)
                continue
            if rows is None:                          # contiguous rows: views, nothing gathered or made
                ctx.open_velocity()                   # the other bodies' velocities copied in (see StepContext)
                advance(x0, v0, a, dt0, out=(x1, v1))
                continue
            pos = world.table(Transform).data["position"]
            vel = world.table(Velocity).data["linear"]
            t_rows, v_rows = rows[0], rows[1]
            a = world.table(Acceleration).data["linear"][rows[2]] if len(rows) == 3 else None
            x, v = advance(pos[t_rows], vel[v_rows], a, dt)
            ctx.position[t_rows] = x
            if a is not None:
                ctx.velocity[v_rows] = v
        ctx.predicted = True
