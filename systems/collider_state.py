"""The collision system's colliders: their packed rows in the world's tables, and their start-of-step state.

A helper module of :mod:`driftframe.systems.collision` (it defines no system). :class:`Layout` packs the
colliders' rows (ascending entity id, so results do not depend on esper's set order), :class:`WithoutOrbiting`
leaves out the bodies the gravity system integrates, and :class:`State` gathers their start of the step in
one compiled pass into arrays it makes once per layout.
"""
from __future__ import annotations

import math

import numpy as np

from driftframe.components.body import Acceleration, Mass, Transform, Velocity
from driftframe.components.collision import SphereCollider
from driftframe.framework import contact
from driftframe.framework.quiet_step import gather_quiet
from driftframe.framework.step import advance
from driftframe.framework.store import as_index, in_sorted, to_indices

_NO_N3 = np.empty((0, 3))


class Layout:
    """Packed per-collider rows into the world's tables (from its cached query), rebuilt when it changes.

    Packed order is ascending entity id, so results are independent of
    esper's set order. ``*_idx`` are index arrays (-1: the entity lacks that
    component); ``*_rows`` what to gather with (a slice when contiguous).
    """

    def __init__(self, q):
        self.version = q.version                    # (a tuple for a query filtered by WithoutOrbiting)
        self.n = n = len(q)
        self.entities = q.entities
        self.t_rows = q.rows(Transform)
        self.c_rows = q.rows(SphereCollider)
        self.t_idx = np.ascontiguousarray(to_indices(self.t_rows), np.intp)
        self.c_idx = np.ascontiguousarray(to_indices(self.c_rows), np.intp)

        def optional(T):
            k = np.asarray(q.rows(T), np.intp)
            sel = np.flatnonzero(k >= 0)
            return k, sel, (as_index(k[sel]) if len(sel) else k[sel])

        self.v_idx, self.v_sel, self.v_rows = optional(Velocity)
        self.m_idx, self.m_sel, self.m_rows = optional(Mass)
        self.a_idx, self.a_sel, self.a_rows = optional(Acceleration)
        # the five index arrays as the rows of one (the quiet-step kernel takes them packed), each a view
        self.idx = np.stack([self.t_idx, self.v_idx, self.a_idx, self.m_idx, self.c_idx]).astype(np.intp)
        self.t_idx, self.v_idx, self.a_idx, self.m_idx, self.c_idx = self.idx
        self.all_v = len(self.v_sel) == n
        self.all_m = len(self.m_sel) == n
        # the Transform rows of the bodies that move (have a Velocity), for the write-back
        self.tv_rows = as_index(self.t_idx[self.v_sel]) if len(self.v_sel) else self.t_idx[self.v_sel]
        self.state = None                           # the State of this layout (see State.of)
        self.entity_list: list | None = None        # the entities as a list of ints (see CollisionSystem._emit)


class WithoutOrbiting:
    """The collider query less the bodies the gravity system integrates (marked Orbiting): their path
    over the step is a conic the gravity system has already followed, not this system's straight
    chord, so they are left out here. The gravity system finds their contacts on the conics: with a
    well's surface, with each other about the same well, and (about a root well) with the colliders
    gravity does not move (see systems/gravity.py); the other contacts between an orbiting body and
    a collider that is not orbiting are not modelled."""

    def __init__(self, q, orbiting):
        keep = ~in_sorted(q.entities, orbiting.entities)
        self.version = (q.version, orbiting.version)
        self.entities = q.entities[keep]
        self._rows = {}
        for T in q.types:
            self._rows[T] = as_index(to_indices(q.rows(T))[keep])
        for T in q.optional:
            self._rows[T] = np.asarray(q.rows(T), np.intp)[keep]

    def rows(self, T):
        return self._rows[T]

    def __len__(self) -> int:
        return len(self.entities)


class State:
    """The colliders' start-of-step state, gathered in packed order (ascending entity id) in one
    compiled pass (:func:`~driftframe.framework.contact.gather_bodies`), with the solver's copies
    ``x`` (= ``x0``) and ``u`` (the step's mean velocity ``v0 + a dt/2``).

    One per layout (:meth:`of`): its arrays are made once and refilled by :meth:`gather` every step;
    ``x0, v0, x, u`` are the rows of one ``(4, n, 3)`` array and ``inv, r, e`` of one ``(3, n)`` (each a
    contiguous view), which the quiet-step kernel takes packed."""

    def __init__(self, world, lay: Layout):
        n = lay.n
        self._b3, self._b1 = np.empty((4, n, 3)), np.empty((3, n))
        self.x0, self.v0, self.x, self.u = self._b3
        self.inv, self.r, self.e = self._b1
        self.a = np.empty((n, 3)) if len(lay.a_sel) else None
        self.live = np.empty(n, np.bool_)
        self.n_bad, self.moving = 0, False
        self._world = world
        self._epoch = -1
        self._args = None
        self._quiet: tuple | None = None             # the quiet-step kernel's arguments (see gather_quiet)

    @staticmethod
    def of(world, lay: Layout) -> "State":
        """The layout's state (made on first use)."""
        st = lay.state
        if st is None:
            st = lay.state = State(world, lay)
        return st

    def columns(self, lay: Layout) -> tuple:
        """The world's columns the gather reads and the end of step writes, and the gather's arguments.
        A table's arrays are replaced only when rows are added (its entities change): kept for the
        world's structure epoch."""
        world = self._world
        if self._epoch != world.epoch or self._args is None:
            pos, vel = world.table(Transform).data["position"], world.table(Velocity).data["linear"]
            acc = world.table(Acceleration).data["linear"] if self.a is not None else _NO_N3
            col = world.table(SphereCollider).data
            self._args = (pos, vel, acc, world.table(Mass).data["kg"], col["radius"], col["restitution"],
                          lay.t_idx, lay.v_idx, lay.a_idx, lay.m_idx, lay.c_idx)
            self._out = (self.x0, self.v0, self.a if self.a is not None else _NO_N3, self.inv, self.r, self.e,
                         self.x, self.u, self.live)
            self._quiet = None
            self._epoch = world.epoch
        return self._args

    def gather(self, lay: Layout, dt: float) -> "State":
        """Fill the arrays with the start of this step (see the class docstring)."""
        args = self.columns(lay)
        self.n_bad, self.moving = contact.gather_bodies(*args, float(dt), *self._out)
        return self

    def gather_quiet(self, lay: Layout, dt: float, pairs: np.ndarray) -> bool:
        """:meth:`gather`, and whether the step is quiet for the candidate pairs (``pairs``: ``(2, m)``, the
        rows ``pi, pj``; see :func:`~driftframe.framework.quiet_step.gather_quiet`: False when a body is not
        valid or none moves). The kernel's arguments are kept while the world's structure epoch, ``dt``
        and the pairs are the same (a small scene's step is little more than this call)."""
        self.n_bad, self.moving, quiet = gather_quiet(*self.quiet_call(lay, dt, pairs))
        return quiet

    def quiet_call(self, lay: Layout, dt: float, pairs: np.ndarray) -> tuple:
        """The quiet-step kernel's arguments (see :meth:`gather_quiet`), kept while the world's structure
        epoch, ``dt`` and the pairs are the same."""
        call = self._quiet
        if call is None or self._epoch != self._world.epoch or call[7] != dt or call[12] is not pairs:
            args = self.columns(lay)
            call = self._quiet = args[:6] + (lay.idx, float(dt), self._b3, self._out[2], self._b1, self.live,
                                             pairs)
        return call

    def end_of_step(self, dt: float):
        """x1, v1 of every body in free flight (no contact)."""
        return advance(self.x0, self.v0, self.a, dt)

    def bad(self, lay: Layout) -> np.ndarray | None:
        """Bodies with a non-finite or invalid field, or None (found by the gather)."""
        return ~self.live if self.n_bad else None

    def describe(self, k: int) -> str:
        """Which field of body k is bad, and its value."""
        for name, val in (("Transform.position", self.x0[k]), ("Velocity.linear", self.v0[k]),
                          ("Acceleration.linear", None if self.a is None else self.a[k]),
                          ("SphereCollider.radius", self.r[k]), ("SphereCollider.restitution", self.e[k])):
            if val is None:
                continue
            if not np.isfinite(val).all():
                return f"{name} = {np.asarray(val).tolist()!r}"
        if not (self.r[k] > 0):
            return f"SphereCollider.radius = {float(self.r[k])!r}"
        if not (0 <= self.e[k] <= 1):
            return f"SphereCollider.restitution = {float(self.e[k])!r}"
        return f"Mass.kg = {1.0 / float(self.inv[k]) if self.inv[k] else math.inf!r}"
