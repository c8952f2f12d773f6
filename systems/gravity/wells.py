"""The wells of a gravity scene: their constants in depth order, which one a body moves about, where a
well's centre is during the step.

A root well is fixed in the world frame or moves at its own constant ``Velocity``;
a moon follows its own conic about its parent (its state is that of a body on rails,
kept by :mod:`.rails`). A body moves about the deepest well whose sphere of
influence holds it, ties at one depth going to the strongest pull (patched conics)."""
from __future__ import annotations

import math

import numpy as np

from driftframe.components.body import Transform, Velocity
from driftframe.components.gravity import GravityWell
from driftframe.framework import kepler
from driftframe.framework.store import to_indices
from driftframe.systems.gravity.context import GravityStep


class _Wells:
    """The scene's wells in depth order (parents first), their constants and the checks on them."""

    def __init__(self, world, q):
        ents = [int(e) for e in q.entities]
        objs = q.rows(GravityWell)
        t_rows = to_indices(q.rows(Transform))
        pos = world.table(Transform).data["position"][t_rows]
        has_v = world.query(GravityWell, Transform, optional=(Velocity,))
        has_v.refresh()
        v_rows = has_v.rows(Velocity)
        vel = np.where((v_rows >= 0)[:, None], world.table(Velocity).data["linear"][np.maximum(v_rows, 0)], 0.0)
        by_ent = {e: k for k, e in enumerate(ents)}
        for k, w in enumerate(objs):
            p = w.parent
            if p is not None and p not in by_ent:
                raise ValueError(f"GravityWell of entity {ents[k]}: parent {p!r} is not an entity with a "
                                 f"GravityWell and a Transform")
            if p is not None and v_rows[k] < 0:
                raise ValueError(f"GravityWell of entity {ents[k]} orbits {p} but has no Velocity "
                                 f"(a moon needs its orbital velocity)")
        depth = []
        for k, w in enumerate(objs):
            seen, p, d = {ents[k]}, w.parent, 0
            while p is not None:
                if p in seen:
                    raise ValueError(f"GravityWell parents form a cycle through entity {ents[k]}")
                seen.add(p)
                d += 1
                p = objs[by_ent[p]].parent
            depth.append(d)
        order = sorted(range(len(ents)), key=lambda k: (depth[k], ents[k]))
        self.ents = [ents[k] for k in order]
        self.wells = [objs[k] for k in order]
        self.depth = np.array([depth[k] for k in order], float)
        self.t_rows = t_rows[order]
        self.v_rows = v_rows[order]
        self.mu = np.array([w.mu for w in self.wells])
        self.radius = np.array([w.radius for w in self.wells])
        index = {e: i for i, e in enumerate(self.ents)}
        self.parent = np.array([index[w.parent] if w.parent is not None else -1 for w in self.wells], np.intp)
        pos, vel = pos[order], vel[order]
        self.soi = np.full(len(order), np.inf)
        for i, w in enumerate(self.wells):
            if w.soi is not None:
                self.soi[i] = w.soi
            elif w.parent is not None:
                j = self.parent[i]
                el = kepler.elements(pos[i] - pos[j], vel[i] - vel[j], self.mu[j])
                a = float(el.a[0]) if el.a[0] > 0 else float(np.linalg.norm(pos[i] - pos[j]))
                self.soi[i] = a * (w.mu / self.mu[j]) ** 0.4
        for i in range(len(order)):
            for j in range(i + 1, len(order)):
                d = float(np.linalg.norm(pos[i] - pos[j]))
                if d < self.radius[i] + self.radius[j]:
                    raise ValueError(f"GravityWell of entity {self.ents[j]} (radius {float(self.radius[j])!r} m) "
                                     f"is {d!r} m from well {self.ents[i]} (radius {float(self.radius[i])!r} m): "
                                     f"a well inside another's surface")

    def __len__(self):
        return len(self.ents)


def _dominant(w: _Wells, x, X, moon_parent) -> np.ndarray:
    """Each body's well: the deepest sphere of influence holding it, then the strongest pull.
    ``moon_parent[k] >= 0``: body k is a moon and orbits that well, whatever the spheres say."""
    if x.shape[0] * len(w) <= _FEW:
        found = _dominant_few(w, x, X, moon_parent)
        if found is not None:
            return found
    d2 = np.einsum("nwk,nwk->nw", x[:, None, :] - X[None], x[:, None, :] - X[None])
    inside = d2 < (w.soi * w.soi)[None, :]
    moons = np.flatnonzero(moon_parent >= 0)
    if moons.size:
        inside[moons] = False
        inside[moons, moon_parent[moons]] = True
    with np.errstate(divide="ignore"):
        pull = w.mu[None, :] / d2
    deepest = np.where(inside, w.depth[None, :], -1.0).max(axis=1, keepdims=True)
    return np.argmax(np.where(inside & (w.depth[None, :] == deepest), pull, -np.inf), axis=1)


#: Bodies times wells up to which :func:`_dominant` works in Python floats (numpy's calls on a few elements
#: cost more than the arithmetic: docs/design/costs.md, 'Small gravity scenes').
_FEW = 16


def _dominant_few(w: _Wells, x, X, moon_parent):
    """:func:`_dominant` in Python floats, the same numbers (einsum sums ``(d0^2 + d2^2) + d1^2``) and the
    same choice (the first of equal pulls; ``mu / 0`` is inf, as numpy's); None where a distance is not
    finite (numpy's NaN rules then decide)."""
    xs, Xs = x.tolist(), X.tolist()
    soi2 = (w.soi * w.soi).tolist()
    mu, depth, parents = w.mu.tolist(), w.depth.tolist(), moon_parent.tolist()
    out = []
    for k, p in enumerate(xs):
        best_w, best_pull, deepest, found = 0, -math.inf, -1.0, []
        for i, c in enumerate(Xs):
            d0, d1, d2 = p[0] - c[0], p[1] - c[1], p[2] - c[2]
            r2 = (d0 * d0 + d2 * d2) + d1 * d1
            if not (0.0 <= r2 < math.inf) or (r2 == 0.0 and not mu[i] > 0.0):
                return None
            inside = i == parents[k] if parents[k] >= 0 else r2 < soi2[i]
            if inside:
                deepest = max(deepest, depth[i])
            found.append((inside, mu[i] / r2 if r2 > 0.0 else math.inf))   # (a moon at its own centre)
        for i, (inside, pull) in enumerate(found):
            if inside and depth[i] == deepest and pull > best_pull:
                best_w, best_pull = i, pull
        out.append(best_w)
    return np.array(out, np.intp)


class WellPaths:
    """Where each well's centre is at a time in the step (a part of :class:`~.system.GravitySystem`)."""

    def _well_at(self, step: GravityStep, wi: int, t):
        """Well ``wi``'s centre at absolute times ``t`` ``(n,)`` in the step: positions, velocities (world
        frame). A root well moves straight from its state at the start of ``step``; a moon on its conic about its
        parent."""
        X0, V0, t0 = step.X0, step.V0, step.t0
        wells = self._wells
        t = np.asarray(t, dtype=np.float64)
        p = wells.parent[wi]
        if p < 0:
            return X0[wi] + V0[wi] * (t - t0)[:, None], np.broadcast_to(V0[wi], (t.size, 3))
        kk = int(np.flatnonzero(self.well_index == wi)[0])
        r, v = kepler.propagate(np.broadcast_to(self.ep_r[kk], (t.size, 3)), np.broadcast_to(self.ep_v[kk], (t.size, 3)),
                                wells.mu[p], t - self.ep_t[kk])
        P, Vp = self._well_at(step, int(p), t)
        return P + r, Vp + v
