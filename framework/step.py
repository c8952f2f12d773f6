"""The step context: every body's end-of-step state, predicted once, corrected by its owner, committed once.

A fixed step moves bodies in three stages, as Box2D's ``b2World_Step``
carries its ``b2StepContext`` through its solver stages:

1. **predict** (the ``movement`` stage, :class:`~driftframe.systems.movement.MovementSystem`):
   :meth:`StepContext.begin` copies every body's start-of-step position and
   velocity, and movement writes the free-flight end state of every body that
   has a ``Velocity`` with :func:`advance`, the one place the update is written
   (free flight of contiguous rows goes through its compiled twin,
   :func:`~driftframe.framework.free_flight.free_flight`, the same operations
   in the same order: tests/test_free_flight.py holds them to the same bits).
2. **resolve** (gravity, collision): a system that owns a body (the gravity
   system its ``Orbiting`` bodies, the collision system the colliders a
   contact touched) writes that body's end state into the context from the
   start state, which is still what ``Transform`` and ``Velocity`` hold. It
   corrects the prediction; it never undoes a write to the components.
3. **commit** (the ``commit`` stage, :class:`Commit`, which every world has):
   the context is written into ``Transform.position`` and ``Velocity.linear``,
   every body at once.

So a system placed anywhere in the step sees every body in one state: before
``commit`` the start of the step, after it the end. Between ``movement`` and
``commit`` the step holds position and velocity: a system that writes them
there would be overwritten by the commit, so it belongs before ``movement``
(a force, a thrust, drag) or after ``commit`` (a teleport, a clamp).

The context's arrays are the size of the component tables, row for row, so a
system writes ``ctx.position[rows]`` with the rows it reads the components at.
The world owns its context (``world.step_context``) as Box2D's world owns its
step context: it is not a resource, and a save never holds it (between two
steps it is closed).
"""
from __future__ import annotations

import esper
import numpy as np


def advance(x0: np.ndarray, v0: np.ndarray, a: np.ndarray | None, dt: float,
            out: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The exact constant-acceleration update over ``dt`` seconds:
    ``x1 = x0 + v0 dt + a dt^2/2`` (m), ``v1 = v0 + a dt`` (m/s); ``a`` None: free flight, ``v1`` is ``v0``.

    Not explicit Euler (which lags by ``a dt^2/2`` each step) nor semi-implicit
    Euler (which leads by as much): a thrust held over the step lands exactly
    (``benchmarks/thrust_accuracy.py``). The operations are done in this order,
    ``(x0 + v0 dt) + (dt^2/2) a``, everywhere the update is needed, so that
    every path gives the same bits. ``out``: ``(x1, v1)`` arrays to write the
    result into (none made); with ``a`` None, ``v1`` is not written (it may be
    None) and holds ``v0`` already where a caller passes one.
    """
    if out is None:
        x1 = x0 + v0 * dt
        if a is None:
            return x1, v0
        x1 += (0.5 * dt * dt) * a
        return x1, v0 + dt * a
    x1, v1 = out
    np.multiply(v0, dt, out=x1)
    x1 += x0                                    # (v0 dt) + x0: the same bits as x0 + v0 dt
    if a is not None:
        x1 += (0.5 * dt * dt) * a
        np.multiply(a, dt, out=v1)
        v1 += v0
    return x1, v1


def _bytes(a: np.ndarray) -> memoryview | None:
    """``a``'s bytes as a flat memoryview (non-empty C-contiguous arrays; else None): ``dst[:] = src`` of two
    such views copies a few bytes several times sooner than ``np.copyto`` (a small scene's commit is one
    copy; the figures: docs/design/costs.md)."""
    return memoryview(a).cast("B") if a.size and a.flags.c_contiguous else None


class _Column:
    """One column of the context: a table's field (``position`` of Transform, ``linear`` of Velocity),
    copied in at :meth:`begin` and written back at :meth:`commit`. The views are kept while the table's
    array and size stay the same (until an entity gains or loses the component), so a step costs one
    copy each way (a byte copy where both sides are contiguous: the same bits)."""

    __slots__ = ("table", "field", "buf", "_col", "_src", "_version", "_src_b", "_buf_b")

    def __init__(self, table, field: str):
        self.table, self.field = table, field
        self.buf = np.empty((0, 3))
        self._col = self._src = self._src_b = self._buf_b = None
        self._version = -1

    def prepare(self) -> None:
        """The views for the table as it is now (the buffer kept while its size is)."""
        table = self.table
        col = table.data[self.field]
        n = table.size
        if col is not self._col or len(self.buf) != n:
            self._col, self._src = col, col[:n]
            self.buf = np.empty((n, 3))
            self._src_b, self._buf_b = _bytes(self._src), _bytes(self.buf)
            if self._src_b is None or self._buf_b is None:
                self._src_b = self._buf_b = None

    def begin(self, fill: bool = True) -> None:
        """Open the column for a step: the table's values copied in (``fill``), or not, where the caller
        writes every row before anyone reads one (the movement stage predicting every body)."""
        table = self.table
        if table.data[self.field] is not self._col or len(self.buf) != table.size:
            self.prepare()
        if fill:
            if self._buf_b is not None:
                self._buf_b[:] = self._src_b
            else:
                np.copyto(self.buf, self._src)
        self._version = table.version

    def commit(self) -> None:
        table = self.table
        if table.version == self._version and table.data[self.field] is self._col:
            if self._src_b is not None:             # the usual step: no row changed hands
                self._src_b[:] = self._buf_b
            else:
                np.copyto(self._src, self.buf)
            return
        # rows were taken or freed mid-step (a system deleted or spawned a body): write back the rows that
        # hold the entity they held when the step began, never a row freed or taken since
        n = min(len(self.buf), table.size)
        keep = np.flatnonzero((table.entity[:n] >= 0) & (table.born[:n] <= self._version))
        table.data[self.field][keep] = self.buf[keep]


class StepContext:
    """The step's predicted end state (``world.step_context``).

    ``position`` (m) and ``velocity`` (m/s) have one row per row of the
    ``Transform`` and ``Velocity`` tables; ``step`` is the world's step count
    the context is open for (-1: closed), ``dt`` its length (s); ``predicted``
    says whether a movement stage has written every body's free flight this
    step (a world without one leaves each owner to write all of its bodies).
    :meth:`begin` opens it at most once a step, :meth:`end` commits and closes it.
    """

    __slots__ = ("step", "dt", "predicted", "position", "_x", "_v", "_v_open")

    def __init__(self):
        self.step = -1
        self.dt = 0.0
        self.predicted = False
        self.position = np.empty((0, 3))
        self._x = self._v = None
        self._v_open = False

    @property
    def velocity(self) -> np.ndarray:
        """The velocities (m/s), copied from the table on first use in a step: a step in which no body's
        velocity changes (free flight, no contact) copies them neither in nor out."""
        return self._v.buf if self._v_open else self.open_velocity()

    def open_velocity(self) -> np.ndarray:
        """:attr:`velocity`, its copy of the table made now if it was not yet this step."""
        if not self._v_open:
            if self.step < 0:
                raise RuntimeError("the step context is closed: it is open from the movement stage to the commit")
            self._v.begin()
            self._v_open = True
        return self._v.buf

    @property
    def velocity_buffer(self) -> np.ndarray:
        """The array :attr:`velocity` is (the same object from step to step until the table changes
        size), without copying the table into it."""
        return self._v.buf

    @property
    def open(self) -> bool:
        return self.step >= 0

    def prepare(self, t_table, v_table) -> None:
        """Make the columns' buffers and views for the tables as they are now, without opening the context
        (``World.prepare``: the first step then copies, as every step does, instead of allocating)."""
        x, v = self._x, self._v
        if x is None or x.table is not t_table or v.table is not v_table:
            x, v = self._x, self._v = _Column(t_table, "position"), _Column(v_table, "linear")
        x.prepare()
        v.prepare()
        if self.step < 0:
            self.position = x.buf

    def begin(self, step: int, dt: float, t_table, v_table, whole: bool = False) -> bool:
        """Open the context for ``step`` (idempotent within a step): the start state of every row of the
        two tables (``Table`` of Transform and of Velocity). True when it was opened by this call.
        ``whole``: the caller writes every row of :attr:`position` at once (the movement stage, when every
        row of the Transform table is a body it predicts), so the positions are not copied in first."""
        if self.step == step:
            return False
        self.step, self.dt, self.predicted = step, dt, False
        x, v = self._x, self._v
        if x is None or x.table is not t_table or v.table is not v_table:
            x, v = self._x, self._v = _Column(t_table, "position"), _Column(v_table, "linear")
        if whole and t_table.data["position"] is x._col and len(x.buf) == t_table.size:
            x._version = t_table.version            # (x.begin(False), inline: a small scene's step)
        else:
            x.begin(not whole)
        vt = v.table
        if vt.data["linear"] is not v._col or len(v.buf) != vt.size:
            v.prepare()                             # (the velocities are copied in at their first use)
        self._v_open = False
        self.position = x.buf
        return True

    def end(self) -> None:
        """Commit: write the context into the tables' position and velocity columns, and close it."""
        if self.step < 0:
            return
        x = self._x
        table = x.table
        if table.version == x._version and table.data["position"] is x._col and x._src_b is not None:
            x._src_b[:] = x._buf_b                  # (x.commit()'s usual step, inline: a small scene's step)
        else:
            x.commit()
        if self._v_open:
            self._v.commit()
        self.step = -1

    def close(self) -> None:
        """Close without a commit (the step failed: the components keep the start of the step)."""
        self.step = -1

    def refill(self) -> None:
        """The open columns' buffers filled again from the tables (a dry step's commit then writes back the
        bytes they hold: ``World.prepare``'s rehearsal); closed, nothing."""
        if self.step < 0:
            return
        self._x.begin()
        if self._v_open:
            self._v.begin()


class Commit(esper.Processor):
    """Reads the step context; writes Transform.position, Velocity.linear.  The step's end state into the
    components, every body at once (every world has one, in the ``commit`` stage; with the context
    closed, because nothing moved this step, it does nothing)."""

    stage = "commit"
    reads = (StepContext,)
    writes = ("Transform", "Velocity")
    keeps_entities = True                 # (the world need not look for a change of entities after it)
    #: what no system may write between the movement stage and this one (the world's schedule refuses
    #: it): the step holds every body's velocity there. (Transform is not listed: the spin stage writes
    #: its orientation there; a position written there is overwritten all the same.)
    holds = ("Velocity",)

    def process(self, dt: float) -> None:
        ctx = self.world.step_context
        if ctx.step >= 0:
            ctx.end()
