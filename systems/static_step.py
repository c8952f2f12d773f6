"""A step of contacts in a scene with static planes and boxes: the shapes' table, and the solver's call.

The world's :class:`~driftframe.components.collision.PlaneCollider` and
:class:`~driftframe.components.collision.BoxCollider` entities become the rows
of one float table (:mod:`driftframe.framework.static_shapes` gives its layout), in ascending
entity id across both kinds, so that the result does not depend on the order
they were made in. The solver's static variant
(:data:`~driftframe.framework.contact_solve.solve_static`) takes them as its last bodies:
immovable (inverse mass 0), not live (no sphere-sphere code reads them), a
pair with every sphere after the spheres' own pairs. A scene with no shapes
never imports the variant (:meth:`StaticShapes.present` is False), so it pays no
compile time and no time per step for it.

**Overlaps at the start.** A movable sphere that overlaps a shape where a
step starts (made inside a box or behind a plane, or a shape moved onto it)
is reported as overlapping spheres are (``systems.collision``): one
RuntimeWarning per change of the scene (an entity gained or lost a component,
or a shape's values changed), with the count and the deepest sphere and shape.
What then happens is defined (:mod:`driftframe.framework.static_shapes`, "Starting
inside"): moving deeper, it bounces at once off the plane or the box's
nearest face, one impulse and no jump; moving out, it is left to leave.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from driftframe.components.body import Transform
from driftframe.components.collision import BoxCollider, PlaneCollider
from driftframe.framework.contact_params import F_AGAIN, TOUCH
from driftframe.framework.static_shapes import BOX, PLANE, SHAPE_COLS
from driftframe.framework.store import to_indices


def rotation(quat: np.ndarray) -> np.ndarray:
    """(m, 3, 3) rotation matrices (local -> world) of unit quaternions (x, y, z, w), (m, 4)."""
    x, y, z, w = np.asarray(quat, float).T
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
                     np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
                     np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


class StaticShapes:
    """The world's static shapes as the solver's table (``table``, ``(m, SHAPE_COLS)``), their
    restitution (``e``) and entity ids (``entities``, ascending), read from the components at each
    :meth:`refresh` (a shape's Transform may be moved between steps; it does not move within one)."""

    def __init__(self, world):
        self._world = world
        self._epoch = -1
        self.entities = np.empty(0, np.int64)
        self.table = np.empty((0, SHAPE_COLS))
        self.e = np.empty(0)
        self._pairs: tuple | None = None
        self._raw = b""                             # the components' values the table was made from
        self._buffers: tuple | None = None          # the solver's arrays (see _arguments), for one (n, m)
        self._checked: tuple | None = None          # (world epoch, table values) last checked for overlaps

    def present(self) -> bool:
        """Whether the world has any static shape (the queries are re-read once per change of entities)."""
        world = self._world
        if self._epoch != world.epoch:
            self._epoch = world.epoch
            self._queries = [world.query(Transform, T) for T in (PlaneCollider, BoxCollider)]
            for q in self._queries:
                q.refresh()
            self._n = sum(len(q) for q in self._queries)
            self._pairs = None
        return self._n > 0

    def refresh(self) -> "StaticShapes":
        """The table from the components as they are now (made again only when one of the values it is
        made from changed: a step of a table whose shapes stay put reads them and compares bytes)."""
        world = self._world
        tr = world.table(Transform).data
        fields = (("normal", "offset", "restitution"), ("half_extents", "restitution"))
        raw = []
        for q, T, names in zip(self._queries, (PlaneCollider, BoxCollider), fields):
            if len(q):
                ti, ci, col = q.rows(Transform), q.rows(T), world.table(T).data
                raw += [tr["position"][ti].tobytes(), tr["orientation"][ti].tobytes()]
                raw += [col[f][ci].tobytes() for f in names]
        raw = b"".join(raw)
        if raw != self._raw:
            self._make(tr)
            self._raw = raw
        return self

    def _make(self, tr) -> None:
        world = self._world
        ents, rows, es = [], [], []
        for q, T in zip(self._queries, (PlaneCollider, BoxCollider)):
            if not len(q):
                continue
            col = world.table(T).data
            ti, ci = to_indices(q.rows(Transform)), to_indices(q.rows(T))
            pos, Q = tr["position"][ti], rotation(tr["orientation"][ti])
            S = np.zeros((len(ti), SHAPE_COLS))
            S[:, 1:4] = pos
            if T is PlaneCollider:
                n = np.einsum("kab,kb->ka", Q, col["normal"][ci])
                n /= np.sqrt((n * n).sum(axis=1))[:, None]
                S[:, 0] = PLANE
                S[:, 4:7] = n
                S[:, 13] = (n * pos).sum(axis=1) + col["offset"][ci]
            else:
                S[:, 0] = BOX
                S[:, 4:13] = Q.reshape(-1, 9)
                S[:, 13:16] = col["half_extents"][ci]
            ents.append(np.asarray(q.entities, np.int64))
            rows.append(S)
            es.append(col["restitution"][ci])
        ents = np.concatenate(ents)
        order = np.argsort(ents, kind="stable")
        self.entities = ents[order]
        self.table = np.ascontiguousarray(np.concatenate(rows)[order])
        self.e = np.concatenate(es)[order]

    def report_overlaps(self, entities, x: np.ndarray, r: np.ndarray, movable: np.ndarray, now: float) -> int:
        """Warn (once per change of the scene) when movable spheres overlap a shape by more than ``TOUCH r``,
        as the collision system does for overlapping spheres; returns how many do (0 when not checked).

        ``entities``, ``x``, ``r``, ``movable``: the spheres' entity ids, centres (m), radii (m) and
        whether each moves (live and of finite mass). Call after :meth:`refresh`.
        """
        key = (self._world.epoch, self._raw)
        if key == self._checked:
            return 0
        self._checked = key
        x, r = np.asarray(x, float), np.asarray(r, float)
        keep = np.flatnonzero(movable)
        if not len(keep) or not len(self.entities):
            return 0
        # how far each sphere reaches past each shape's surface, m (> 0: overlapping)
        depth = r[keep, None] - signed_distances(self.table, x[keep])
        over = (depth > TOUCH * r[keep, None]).any(axis=1)
        if not over.any():
            return 0
        i, k = np.unravel_index(int(np.argmax(depth)), depth.shape)
        sphere, shape = int(np.asarray(entities)[keep[i]]), int(self.entities[k])
        where = "behind plane" if self.table[k, 0] == PLANE else "into box"
        centre = "its centre inside" if depth[i, k] > r[keep[i]] else "its centre outside"
        warnings.warn(f"collision: {int(over.sum())} spheres overlap a static shape at t = {now!r} s; the deepest: "
                      f"entity {sphere} (radius {r[keep[i]]:.6g} m) reaches {depth[i, k]:.6g} m {where} entity "
                      f"{shape} ({centre}). A sphere moving deeper bounces at once off the plane or the box's "
                      "nearest face, one moving out is left to leave (place spheres clear of the shapes)",
                      RuntimeWarning, stacklevel=4)
        return int(over.sum())

    def pairs(self, pi: np.ndarray, pj: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The spheres' pairs ``pi, pj`` followed by every sphere with every shape (sphere-major): the
        shapes are bodies ``n .. n + m - 1``."""
        m = len(self.entities)
        key = (n, m, len(pi))                       # (the all-pairs path: pi, pj are every pair of n)
        if self._pairs is None or self._pairs[0] != key:
            si = np.repeat(np.arange(n, dtype=np.int64), m)
            sj = np.tile(np.arange(n, n + m, dtype=np.int64), n)
            self._pairs = (key, np.concatenate([np.asarray(pi, np.int64), si]),
                           np.concatenate([np.asarray(pj, np.int64), sj]))
        return self._pairs[1], self._pairs[2]


def signed_distances(S: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(n, m): each centre's signed distance (m, < 0 inside) from each shape's surface, for the table ``S``
    (:mod:`driftframe.framework.static_shapes`): a plane's ``n . x - d``; a box's the usual box distance
    in its frame, ``|max(|q| - h, 0)| + min(max_a(|q_a| - h_a), 0)`` with ``q = Q^T (x - c)``."""
    x = np.asarray(x, float).reshape(-1, 3)
    out = np.empty((len(x), len(S)))
    plane = S[:, 0] == PLANE
    out[:, plane] = x @ S[plane, 4:7].T - S[plane, 13]
    box = np.flatnonzero(S[:, 0] == BOX)
    if len(box):
        Q = S[box, 4:13].reshape(-1, 3, 3)
        q = np.einsum("kab,ika->ikb", Q, x[:, None, :] - S[box, 1:4][None])      # (n, boxes, 3): Q^T (x - c)
        g = np.abs(q) - S[box, 13:16][None]
        out[:, box] = np.sqrt((np.maximum(g, 0.0) ** 2).sum(axis=2)) + np.minimum(g.max(axis=2), 0.0)
    return out


def _arguments(inputs, shapes: StaticShapes) -> list:
    """The static solver's arguments: the spheres' ``inputs`` with the shapes appended as bodies (at rest,
    radius 0, inverse mass 0, not live, no last contact), in arrays kept for this many spheres and shapes."""
    x, u, r, inv, e, live, t_last, now, pi, pj, dt, t_c, cap, _ = inputs
    n, m = len(x), len(shapes.entities)
    S = shapes.table
    buf = shapes._buffers
    if buf is None or buf[0] != (n, m):
        buf = shapes._buffers = ((n, m), np.empty((n + m, 3)), np.zeros((n + m, 3)), np.zeros(n + m),
                                 np.zeros(n + m), np.empty(n + m), np.zeros(n + m, np.bool_), np.empty(n + m))
    _, X, U, R, W, E, L, T = buf
    X[:n] = x
    X[n:] = S[:, 1:4]
    U[:n] = u
    U[n:] = 0.0
    R[:n] = r
    W[:n] = inv
    E[:n] = e
    E[n:] = shapes.e
    L[:n] = live
    T[:n] = t_last
    T[n:] = -math.inf
    return [X, U, R, W, E, L, T, float(now), *shapes.pairs(pi, pj, n), float(dt), float(t_c), int(cap), S]


def load(inputs, shapes: StaticShapes) -> None:
    """Load (from the kernel cache, or compile) the static solver a step of ``inputs`` calls, and its jam
    variant where a restitution below 1 can jam, without calling them (types only; see the collision
    system's ``prepare``)."""
    from driftframe.framework.contact_solve import solve_static, solve_static_stick
    args = _arguments(inputs, shapes)
    jam = float(args[4].min(initial=1.0)) < 1.0
    for solve in (solve_static, solve_static_stick) if jam else (solve_static,):
        if hasattr(solve, "compile"):                      # (a plain function under NUMBA_DISABLE_JIT)
            solve.compile(tuple(solve.typeof_pyval(a) for a in args))


def solve_with_shapes(inputs, shapes: StaticShapes, stick: bool = False):
    """One step of contacts of the spheres ``inputs`` (a :class:`~.contact.StepInputs` on the all-pairs
    path, ``lst`` None) with each other and with ``shapes``: a :class:`~.contact.StepResult`, ``changed``
    for the spheres only, events whose ``j >= n`` name shape ``j - n``. ``inputs.x``, ``u``, ``t_last``
    change in place, as with :func:`~.contact.solve_step` (and with F_AGAIN the step is run again with the
    jam path in the same way)."""
    from driftframe.framework.contact import StepResult, StepStats
    from driftframe.framework.contact_solve import solve_static, solve_static_stick
    x, u, t_last = inputs.x, inputs.u, inputs.t_last
    n = len(x)
    args = _arguments(inputs, shapes)
    X, U, T = args[0], args[1], args[6]
    out = solve_static_stick(*args) if stick else solve_static(*args)
    if out[5] & F_AGAIN:
        stick = True
        out = solve_static_stick(*args)
    changed, ev, ev_n, ev_x, stats, flags = out
    x[:] = X[:n]
    u[:] = U[:n]
    t_last[:] = T[:n]
    return StepResult(changed[:n], ev, ev_n, ev_x, StepStats._make(stats.tolist()), flags, stick)
