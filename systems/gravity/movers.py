"""The movers of the contact pass (colliders on rails, on the n-body drift, obstacles): their paths,
their swept boxes over the step and the candidate pairs those boxes make."""
from __future__ import annotations

import numpy as np

from driftframe.components.collision import SphereCollider
from driftframe.framework import broadphase as bp
from driftframe.framework import kepler
from driftframe.systems.gravity.context import LINE, OBSTACLE, RAILS, Drift, GravityStep, Movers

#: The broad phase sweeps while the boxes would overlap on the sweep axis at most this many times per
#: box (thin boxes: short steps), else it takes the grid (the measurements: docs/design/gravity.md).
SWEEP_OVERLAPS = 64


def _broad_method(lo, hi) -> str:
    """"sweep" or "grid" for boxes ``lo, hi`` (n, 3): the sweep's work is the overlaps along its axis,
    about ``n^2 width / extent`` for boxes spread evenly."""
    n = len(lo)
    ax = int(np.argmax(np.ptp(lo[:: max(n // 64, 1)], axis=0)))      # (the axis from a sample of boxes)
    l, h = lo[:, ax], hi[:, ax]
    extent = float(h.max() - l.min())
    width = float(h.sum() - l.sum()) / n
    return "sweep" if n * width <= SWEEP_OVERLAPS * extent else "grid"


class _PairTimes:
    """The contact pass's candidate pairs ``(pa, pb)`` (movers, ``pa < pb``), each known to be apart up
    to ``ts`` and touching at ``tc`` (inf: not before ``ts`` in the step; NaN: to be looked at)."""

    def __init__(self, pa, pb, t0, n_movers):
        self.n = n_movers
        self.pa, self.pb = pa, pb
        self.ts = np.full(pa.size, t0)
        self.tc = np.full(pa.size, np.nan)

    def look_again(self, movers, t1):
        """Movers' paths changed at a time their pairs were followed to: look at those pairs again."""
        moved = np.zeros(self.n, bool)
        moved[movers] = True
        again = (moved[self.pa] | moved[self.pb]) & (self.ts < t1)
        self.tc[again] = np.nan

    def renew(self, movers, tp):
        """Movers' paths are new from ``tp``: their pairs are looked at again from there."""
        mine = np.isin(self.pa, movers) | np.isin(self.pb, movers)
        self.tc[mine] = np.nan
        self.ts[mine] = tp

    def settle(self, k, t1):
        """Pair ``k`` is not looked at again in this step."""
        self.tc[k] = np.inf
        self.ts[k] = t1

    def drop(self, mask, t1):
        self.tc[mask] = np.inf
        self.ts[mask] = t1

    def add(self, new, tp):
        """New pairs ``[(a, b), ...]`` (``a < b``), apart up to ``tp``."""
        if new:
            a, b = (np.array(c, np.intp) for c in zip(*new))
            self.pa = np.concatenate([self.pa, a])
            self.pb = np.concatenate([self.pb, b])
            self.ts = np.concatenate([self.ts, np.full(a.size, tp)])
            self.tc = np.concatenate([self.tc, np.full(a.size, np.nan)])


def _overlapping(mv: Movers, c: int, pairs: _PairTimes) -> list:
    """The pairs mover ``c``'s (new) box makes that are not candidates yet (obstacle pairs left out)."""
    lo, hi, kind = mv.lo, mv.hi, mv.kind
    over = np.all((lo[c] <= hi) & (hi[c] >= lo), axis=1)
    over[c] = False
    if kind[c] == OBSTACLE:
        over &= kind != OBSTACLE
    have = set(pairs.pb[pairs.pa == c].tolist()) | set(pairs.pa[pairs.pb == c].tolist())
    return [(min(c, int(o)), max(c, int(o))) for o in np.flatnonzero(over) if int(o) not in have]


class ContactMovers:
    """The contact pass's movers and candidate pairs (a part of :class:`~.system.GravitySystem`)."""

    def _near(self, mv: Movers, pa, pb, span: float, mu: float):
        """Which of the candidate pairs ``(pa, pb)`` (movers on rails about one well) are not proven apart
        for the whole step without solving Kepler's equation: the separation ``d(t)`` leaves the chord between its two
        ends by at most ``A_d span^2 / 8``, with ``A_d`` the bound on ``|d''|`` (the sum of the two
        pulls, or the tidal ``2 mu D / (rho - D/2)^3`` for a pair never more than ``D`` apart; see
        kepler.time_to_touch), so a chord that stays farther than that plus ``r_a + r_b`` from zero
        is a pair that cannot touch. Bodies that touch a surface in the step are kept (two conics)."""
        p0, p1, rad, A, rho, ball = mv.P0, mv.P1, mv.rad, mv.A, mv.rho, mv.ball
        dA = p0[pb] - p0[pa]
        dB = p1[pb] - p1[pa]
        e = dB - dA
        ee = kepler._dot(e, e)
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.clip(np.where(ee > 0, -kepler._dot(dA, e) / ee, 0.0), 0.0, 1.0)
        closest = kepler._norm(dA + f[:, None] * e)
        acc = A[pa] + A[pb]
        D = np.maximum(kepler._norm(dA), kepler._norm(dB)) + 0.125 * acc * span * span
        seg = np.minimum(rho[pa], rho[pb]) - 0.5 * D
        with np.errstate(invalid="ignore", divide="ignore"):
            acc = np.where(seg > 0, np.minimum(acc, 2.0 * mu * D / seg ** 3), acc)
        # (+ the rounding of the states: 1e-12 of their distance from the well, and a micrometre)
        slack = 0.125 * acc * span * span + 1e-12 * (kepler._norm(p0[pa]) + kepler._norm(p0[pb])) + 1e-6
        return (closest - slack <= rad[pa] + rad[pb]) | ball[pa] | ball[pb]

    def _movers_at(self, step: GravityStep, mv: Movers, ms, t):
        """Positions and velocities (world frame) of movers ``ms`` at absolute times ``t`` (the lines and the
        root wells from their states at the start of ``step``)."""
        t0 = step.t0
        kind, body, well = mv.kind[ms], mv.body[ms], mv.well[ms]
        pos = np.empty((ms.size, 3))
        vel = np.empty((ms.size, 3))
        line = kind != RAILS                              # (a line or an obstacle)
        if line.any():
            pos[line] = mv.lp[ms[line]] + mv.lu[ms[line]] * (t[line] - t0)[:, None]
            vel[line] = mv.lu[ms[line]]
        for wi in np.unique(well[~line]):
            m = ~line & (well == wi)
            k = body[m]
            r, u = kepler.propagate(self.ep_r[k], self.ep_v[k], self._wells.mu[wi], t[m] - self.ep_t[k])
            P, V = self._well_at(step, int(wi), t[m])
            pos[m] = P + r
            vel[m] = V + u
        return pos, vel

    def _rail_boxes(self, step: GravityStep, wi: int, rad, p0, w0, p1, w1, span: float, ball):
        """World boxes, bounds ``A`` (on the pull relative to the well) and ``rho`` of colliders of radii
        ``rad`` on rails about well ``wi``, from their states ``p0, w0`` about it at the start of the span
        to ``p1, w1`` at its end: kepler.arc_boxes about the well, then moved into the world frame by the
        box of the well centre's own path over the step (a point for a well at rest)."""
        wells = self._wells
        lo, hi, A, rho = kepler.arc_boxes(p0, w0, p1, w1, span, wells.mu[wi], wells.radius[wi], ball, rad)
        a, b = step.X0[wi], step.X1[wi]
        if np.array_equal(a, b):
            if not a.any():                               # (a well at rest at the origin: the usual case)
                return lo, hi, A, rho
            return lo + a, hi + a, A, rho
        grow = 0.125 * step.wA[wi] * step.dt ** 2
        return lo + (np.minimum(a, b) - grow), hi + (np.maximum(a, b) + grow), A, rho

    def _movers(self, step: GravityStep, ends: dict, nb, drift: Drift | None) -> Movers:
        """The contact pass's movers (see :class:`~.context.Movers`): the colliders on rails of each well's
        end ``ends[wi]``, the n-body colliders ``nb`` on their ``drift``, the obstacles."""
        span = step.dt
        x, v, a, t0, t1 = step.x, step.v, step.a, step.t0, step.t1
        col = self.world.table(SphereCollider).data
        kinds, bodies, wells_of, rads = [], [], [], []
        p0s, p1s, w0s, w1s, balls = [], [], [], [], []
        for wi, (sel, r1, u1, _, _) in ends.items():
            is_c = self.c_rows[sel] >= 0
            if is_c.all():                                # (every body a collider, the usual swarm: slices)
                cs, pc = sel, slice(None)
                g = slice(None) if sel.size == self._n else sel
            else:
                cs = sel[is_c]
                if not cs.size:
                    continue
                pc = np.flatnonzero(is_c)
                g = cs
            p0 = x[g] - step.X0[wi]
            w0 = v[g] - step.V0[wi]
            if a.any():
                w0 += 0.5 * span * a[g]                   # (thrust: after the first half kick)
            late = self.ep_t[g] > t0
            if late.any():
                # bodies that came into this well's sphere in the step: on its conic from then on, boxed as
                # the sphere they can reach from there (their path before was about another well)
                p0[late] = self.ep_r[cs[late]]
                w0[late] = self.ep_v[cs[late]]
            kinds.append(np.full(cs.size, RAILS, np.intp))
            bodies.append(cs)
            wells_of.append(np.full(cs.size, wi, np.intp))
            rads.append(col["radius"][self.c_rows[g]].astype(np.float64))
            p0s.append(p0)
            w0s.append(w0)
            p1s.append(r1[pc])
            w1s.append(u1[pc])
            balls.append((self.ep_contact[g] <= t1) | late)
        n_rail = sum(b.size for b in bodies)
        lp, lu = [], []
        if drift is not None:
            p, u = drift.p, drift.u
            k = np.flatnonzero(self.nb_c_rows[nb] >= 0)
            if k.size:
                kinds.append(np.full(k.size, LINE, np.intp))
                bodies.append(nb[k])
                wells_of.append(np.full(k.size, -1, np.intp))
                rads.append(col["radius"][self.nb_c_rows[nb[k]]].astype(np.float64))
                lp.append(p[k])
                lu.append(u[k])
        if self._n_ob:
            kinds.append(np.full(self._n_ob, OBSTACLE, np.intp))
            bodies.append(np.arange(self._n_ob))
            wells_of.append(np.full(self._n_ob, -1, np.intp))
            rads.append(col["radius"][self.ob_c_rows].astype(np.float64))
            lp.append(step.ob_x)
            lu.append(step.ob_v)
        one = len(kinds) == 1
        cat = (lambda parts: parts[0]) if one else np.concatenate            # noqa: E731
        mv = Movers(kind=cat(kinds), body=cat(bodies), well=cat(wells_of), rad=cat(rads),
                    lp=np.concatenate([np.zeros((n_rail, 3))] + lp) if lp else None,
                    lu=np.concatenate([np.zeros((n_rail, 3))] + lu) if lu else None)
        M = mv.kind.size
        kind, well, rad = mv.kind, mv.well, mv.rad
        groups, at = [], 0
        for p0 in p0s:
            groups.append((int(well[at]), slice(at, at + p0.shape[0])))
            at += p0.shape[0]
        mv.groups = groups
        if one and n_rail:                                # (one well's colliders and nothing else: no copies)
            wi = groups[0][0]
            mv.lo, mv.hi, mv.A, mv.rho = self._rail_boxes(step, wi, rad, p0s[0], w0s[0], p1s[0], w1s[0],
                                                          span, balls[0])
            mv.P0, mv.P1, mv.ball = p0s[0], p1s[0], balls[0]
            mv.wA = np.full(M, step.wA[wi])
            mv.root = np.full(M, self._wells.parent[wi] < 0)
        else:
            lo, hi = np.empty((M, 3)), np.empty((M, 3))
            mv.A, mv.rho = np.zeros(M), np.zeros(M)         # 0 on a line
            mv.P0, mv.P1, mv.ball = np.zeros((M, 3)), np.zeros((M, 3)), np.zeros(M, bool)
            for k, (wi, ms) in enumerate(groups):
                lo[ms], hi[ms], mv.A[ms], mv.rho[ms] = self._rail_boxes(step, wi, rad[ms], p0s[k], w0s[k], p1s[k],
                                                                        w1s[k], span, balls[k])
                mv.P0[ms], mv.P1[ms], mv.ball[ms] = p0s[k], p1s[k], balls[k]
            lines = np.flatnonzero(kind != RAILS)
            if lines.size:
                q0 = mv.lp[lines]
                q1 = q0 + mv.lu[lines] * span
                lo[lines] = np.minimum(q0, q1) - rad[lines, None]
                hi[lines] = np.maximum(q0, q1) + rad[lines, None]
            mv.lo, mv.hi = lo, hi
            mv.wA = np.where(kind == RAILS, step.wA[np.maximum(well, 0)], 0.0)
            mv.root = np.where(kind == RAILS, self._wells.parent[np.maximum(well, 0)] < 0, False)
        mv.after = np.full(M, -np.inf)
        return mv

    def _candidates(self, mv: Movers, span: float):
        """The pairs of movers whose boxes meet (``i < j``: a rails mover before a line), less obstacle
        pairs and the pairs on rails about one well whose chords prove them apart (``_near``)."""
        kind, well = mv.kind, mv.well
        lo, hi = mv.lo, mv.hi
        pa, pb = bp.box_pairs(lo, hi, _broad_method(lo, hi))
        pa, pb = pa.astype(np.intp), pb.astype(np.intp)
        if self._n_ob > 1:
            keep = ~((kind[pa] == OBSTACLE) & (kind[pb] == OBSTACLE))  # obstacle with obstacle: not ours
            pa, pb = pa[keep], pb[keep]
        mu = self._wells.mu
        near = lambda i, j, wi: self._near(mv, i, j, span, mu[wi])                                # noqa: E731
        groups = mv.groups
        if len(groups) == 1 and groups[0][1].stop == kind.size:      # (all on rails about one well)
            keep = near(pa, pb, groups[0][0])
            return pa[keep], pb[keep]
        same = (kind[pa] == RAILS) & (kind[pb] == RAILS) & (well[pa] == well[pb])
        if same.any():
            keep = np.ones(pa.size, bool)
            for wi in np.unique(well[pa[same]]):
                m = np.flatnonzero(same & (well[pa] == wi))
                keep[m] = near(pa[m], pb[m], int(wi))
            pa, pb = pa[keep], pb[keep]
        return pa, pb

    def _rebox(self, step: GravityStep, mv: Movers, m: int, tp: float) -> None:
        """Mover ``m`` is on a new path from ``tp``: its box (and bounds) from there to ``t1``."""
        t0, t1 = step.t0, step.t1
        if mv.kind[m] == RAILS:
            i = mv.body[m]
            wi = int(mv.well[m])
            pe, we = kepler.propagate(self.ep_r[i:i + 1], self.ep_v[i:i + 1], self._wells.mu[wi], t1 - self.ep_t[i])
            ms = np.array([m])
            mv.lo[ms], mv.hi[ms], mv.A[ms], mv.rho[ms] = self._rail_boxes(
                step, wi, mv.rad[ms], self.ep_r[i:i + 1], self.ep_v[i:i + 1], pe, we, t1 - tp,
                np.array([self.ep_contact[i] <= t1]))
        else:
            q0 = mv.lp[m] + mv.lu[m] * (tp - t0)
            q1 = mv.lp[m] + mv.lu[m] * (t1 - t0)
            mv.lo[m] = np.minimum(q0, q1) - mv.rad[m]
            mv.hi[m] = np.maximum(q0, q1) + mv.rad[m]

    def _lines_after(self, step: GravityStep, mv: Movers, nb, drift: Drift | None) -> Drift | None:
        """The n-body drifts after the pass, each from its last contact in the step."""
        if drift is None:
            return None
        k = np.flatnonzero(self.nb_c_rows[nb] >= 0)
        if not k.size:
            return drift
        ms = np.flatnonzero(mv.kind == LINE)
        p, u = drift.p.copy(), drift.u.copy()
        p[k], u[k] = mv.lp[ms], mv.lu[ms]
        since = np.full(nb.size, -np.inf)
        since[k] = mv.after[ms] - step.t0
        return Drift(p, u, since)
