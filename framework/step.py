"""The step context: every body's end-of-step state, predicted once, corrected by its owner, committed once.

A fixed step moves bodies in three stages, as Box2D's ``b2World_Step``
carries its ``b2StepContext`` through its solver stages:

1. **predict** (the ``movement`` stage, :class:`~driftframe.systems.movement.MovementSystem`):
   :meth:`StepContext.begin` copies every body's start-of-step position and
   velocity, and movement writes the free-flight end state of every body that
   has a ``Velocity`` with :func:`advance`, the one place the update is written.
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


def advance(x0: np.ndarray, v0: np.ndarray, a: np.ndarray | None, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The exact constant-acceleration update over ``dt`` seconds:
    ``x1 = x0 + v0 dt + a dt^2/2`` (m), ``v1 = v0 + a dt`` (m/s); ``a`` None: free flight, ``v1`` is ``v0``.

    Not explicit Euler (which lags by ``a dt^2/2`` each step) nor semi-implicit
    Euler (which leads by as much): a thrust held over the step lands exactly
    (``benchmarks/thrust_accuracy.py``). The operations are done in this order,
    ``(x0 + v0 dt) + (dt^2/2) a``, everywhere the update is needed, so that
    every path gives the same bits.
    """
    x1 = x0 + v0 * dt
    if a is None:
        return x1, v0
    x1 += (0.5 * dt * dt) * a
    return x1, v0 + dt * a


class StepContext:
    """The step's predicted end state (``world.step_context``).

    ``position`` (m) and ``velocity`` (m/s) have one row per row of the
    ``Transform`` and ``Velocity`` tables; ``step`` is the world's step count
    the context is open for (-1: closed), ``dt`` its length (s); ``predicted``
    says whether a movement stage has written every body's free flight this
    step (a world without one leaves each owner to write all of its bodies).
    :meth:`begin` opens it at most once a step, :meth:`end` commits and closes it.
    """

    __slots__ = ("step", "dt", "predicted", "position", "velocity", "_tables", "_t_owner", "_v_owner", "_t_version",
                 "_v_version")

    def __init__(self):
        self.step = -1
        self.dt = 0.0
        self.predicted = False
        self.position = np.empty((0, 3))
        self.velocity = np.empty((0, 3))
        self._tables = None
        self._t_owner = self._v_owner = None
        self._t_version = self._v_version = -1

    @property
    def open(self) -> bool:
        return self.step >= 0

    def begin(self, step: int, dt: float, t_table, v_table) -> bool:
        """Open the context for ``step`` (idempotent within a step): the start state of every row of the
        two tables (``Table`` of Transform and of Velocity). True when it was opened by this call."""
        if self.step == step:
            return False
        self.step, self.dt, self.predicted = step, dt, False
        self._tables = (t_table, v_table)
        self.position = _copy_into(self.position, t_table.data["position"], t_table.size)
        self.velocity = _copy_into(self.velocity, v_table.data["linear"], v_table.size)
        # which entity held each row when the step began: a row freed and taken again before the commit
        # (a body deleted and another spawned by a system mid-step) is not written over
        self._t_owner, self._t_version = t_table.entity[: t_table.size].copy(), t_table.version
        self._v_owner, self._v_version = v_table.entity[: v_table.size].copy(), v_table.version
        return True

    def end(self) -> None:
        """Commit: write the context into the tables' position and velocity columns, and close it."""
        if self.step < 0:
            return
        t_table, v_table = self._tables
        _commit(t_table, "position", self.position, self._t_owner, self._t_version)
        _commit(v_table, "linear", self.velocity, self._v_owner, self._v_version)
        self.step = -1

    def close(self) -> None:
        """Close without a commit (the step failed: the components keep the start of the step)."""
        self.step = -1


class Commit(esper.Processor):
    """Reads the step context; writes Transform.position, Velocity.linear.  The step's end state into the
    components, every body at once (every world has one, in the ``commit`` stage; with the context
    closed, because nothing moved this step, it does nothing)."""

    stage = "commit"
    reads = (StepContext,)
    writes = ("Transform", "Velocity")
    #: what no system may write between the movement stage and this one (the world's schedule refuses
    #: it): the step holds every body's velocity there. (Transform is not listed: the spin stage writes
    #: its orientation there; a position written there is overwritten all the same.)
    holds = ("Velocity",)

    def process(self, dt: float) -> None:
        ctx = self.world.step_context
        if ctx.step >= 0:
            ctx.end()


def _copy_into(buf: np.ndarray, col: np.ndarray, n: int) -> np.ndarray:
    """``col[:n]`` copied into ``buf`` (reused when it is large enough; a view of its first n rows)."""
    if buf.base is not None:
        buf = buf.base
    if len(buf) < n:
        buf = np.empty((max(n, 2 * len(buf)), 3))
    out = buf[:n]
    np.copyto(out, col[:n])
    return out


def _commit(table, field: str, values: np.ndarray, owner: np.ndarray, version: int) -> None:
    col = table.data[field]
    n = len(values)
    if table.version == version:                    # the usual step: no row changed hands
        col[:n] = values
        return
    keep = np.flatnonzero((table.entity[:n] == owner) & (owner >= 0))
    col[keep] = values[keep]
