"""The look-ahead: the frame a body moves in now, and the next contacts predicted on the conics (for the
warp governor, the flight aids and the orbit readouts)."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from driftframe.components.body import Transform, Velocity
from driftframe.components.collision import SphereCollider
from driftframe.components.gravity import GravityWell
from driftframe.framework import broadphase as bp
from driftframe.framework import kepler
from driftframe.framework.orbit_state import ContactAhead, OrbitState, Reference, SurfaceAhead
from driftframe.systems.gravity.context import OBSTACLE, RAILS, Movers
from driftframe.systems.gravity.movers import _broad_method
from driftframe.systems.gravity.wells import _dominant, _Wells


class _Kept(NamedTuple):
    """The last look at the pairs on rails: the epochs it was made from, its answer, how far it looked."""

    version: int
    found: ContactAhead | None
    upto: float


def _first_reach(g, c, A):
    """The least time a gap ``g`` (m) closing at up to ``c`` (m/s) with up to ``A`` (m/s^2) more can
    reach 0: the smaller positive root of ``g - c t - A t^2 / 2`` (0 where ``g`` is 0)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        t = 2.0 * g / (c + np.sqrt(c * c + 2.0 * A * g))
    return np.where(g > 0, t, 0.0)


class GravityOrbits(OrbitState):
    """The gravity system's :class:`~driftframe.framework.orbit_state.OrbitState`, which it publishes in
    ``world.resources[OrbitState]``: each answer is the system's own (:class:`LookAhead`), from its epochs."""

    def __init__(self, system: LookAhead) -> None:
        self._system = system

    def reference(self, entity: int) -> Reference | None:
        return self._system.reference(entity)

    def next_contact(self) -> SurfaceAhead | None:
        return self._system.next_contact()

    def next_sphere_contact(self, horizon: float) -> ContactAhead | None:
        return self._system.next_sphere_contact(horizon)


class LookAhead:
    """What gravity predicts (a part of :class:`~.system.GravitySystem`)."""

    def reference(self, entity: int) -> Reference | None:
        """The well ``entity`` moves about now (its entity, mu, radius, and its centre's position and
        velocity now, world frame), or None in a scene without wells or for a root well. For orbit readouts
        and flight aids: prograde means along the velocity relative to this well."""
        world = self.world
        wq = world.query(GravityWell, Transform)
        wq.refresh()
        if not len(wq):
            return None
        wells = self._wells if self._wells is not None else _Wells(world, wq)
        pos_t = world.table(Transform).data["position"]
        vel_t = world.table(Velocity).data["linear"]
        X = pos_t[wells.t_rows]
        V = np.where((wells.v_rows >= 0)[:, None], vel_t[np.maximum(wells.v_rows, 0)], 0.0)
        x = world.columns(Transform, [entity]).position
        if entity in wells.ents:
            i = wells.ents.index(entity)
            if wells.parent[i] < 0:
                return None
            wi = int(wells.parent[i])
        else:
            wi = int(_dominant(wells, x, X, np.full(1, -1, np.intp))[0])
        return Reference(wells.ents[wi], float(wells.mu[wi]), float(wells.radius[wi]), X[wi].copy(), V[wi].copy())

    def next_contact(self) -> SurfaceAhead | None:
        """The earliest predicted surface contact of a body on rails (absolute seconds, exact on its
        conic), or None. For the warp governor."""
        if not self._n:
            return None
        valid = self.ep_well >= 0
        if not valid.any():
            return None
        t = np.where(valid, self.ep_contact, np.inf)
        k = int(np.argmin(t))
        if not np.isfinite(t[k]):
            return None
        return SurfaceAhead(float(t[k]), int(self.ents[k]), self._wells.ents[int(self.ep_well[k])])

    def next_sphere_contact(self, horizon: float) -> ContactAhead | None:
        """The earliest predicted contact between two colliders on rails
        about the same well, or a collider on rails about a root well and an obstacle (a collider
        gravity does not move), within ``horizon`` s of the end of this step (absolute seconds, exact on
        their conics: :func:`framework.kepler.time_to_touch` from the epochs), or None; lower entity
        first; ``bound`` where it is only a lower bound (an n-body collider, whose path is not known
        beyond its step, could touch by then). For the warp governor. Each look at the pairs on rails covers twice the horizon and is
        kept while no epoch changes (a thrust, a contact, an edit), so a steady warp looks again only
        every ``horizon`` s; the obstacles (whose velocity anyone may change) are looked at on every
        call, from their state now. A pair is followed up to the first surface contact of the body on
        rails (itself an event the governor slows down for)."""
        exact = [c for c in (self._next_rails_contact(horizon), self._next_obstacle_contact(horizon),
                             self._next_cross_contact(horizon)) if c is not None]
        bound = self._next_nbody_contact(horizon)
        best = min(exact) if exact else None
        #: Whether the last answer is only a lower bound (an n-body pair that *could* touch by then).
        self.lookahead_is_bound = bound is not None and (best is None or bound.time < best.time)
        return bound if self.lookahead_is_bound else best

    def _next_nbody_contact(self, horizon: float):
        """next_sphere_contact's look at the n-body colliders, whose paths are not known beyond their
        step: the earliest time any of them *could* touch another collider within the horizon, a lower
        bound (the gap closed at the pair's speed now plus the most the pulls can add: every well's
        ``mu / R^2`` on each body and the n-body bodies' own pulls; for two n-body bodies, which feel the
        same wells, the tidal difference ``2 mu D / (R - D/2)^3`` instead), so the warp drops before
        such a contact, never after it (two n-body colliders 1 km apart in low orbit hold it at 100x:
        the tidal field can bring them together within a few hundred seconds)."""
        if not self._n_nb_col or not horizon > 0 or self._wells is None or self._n_col + self._n_nb_col + self._n_ob < 2:
            return None
        world = self.world
        now = (world.step_count + 1) * world.dt
        wells = self._wells
        pos_t = world.table(Transform).data["position"]
        vel_t = world.table(Velocity).data["linear"]
        col = world.table(SphereCollider).data["radius"]
        nbk = np.flatnonzero(self.nb_c_rows >= 0)
        rk = np.flatnonzero(self.c_rows >= 0)
        t_rows, v_rows = (np.arange(r.start, r.stop, r.step or 1) if isinstance(r, slice) else r
                          for r in (self.t_rows, self.v_rows))
        x = np.concatenate([pos_t[t_rows[nbk]], pos_t[t_rows[rk]], pos_t[self.ob_t_rows]])
        v = np.concatenate([vel_t[v_rows[nbk]], vel_t[v_rows[rk]],
                            np.where((self.ob_v_rows >= 0)[:, None], vel_t[np.maximum(self.ob_v_rows, 0)], 0.0)])
        r = np.concatenate([col[self.nb_c_rows[nbk]], col[self.c_rows[rk]], col[self.ob_c_rows]]).astype(np.float64)
        pull = float(np.sum(wells.mu / wells.radius ** 2))
        gm = self.gm[nbk]
        acc = np.concatenate([np.full(nbk.size, pull + float(np.sum(gm / (r[:nbk.size].min() * 2.0) ** 2))),
                              np.full(rk.size, pull), np.zeros(self._n_ob)])
        h = horizon
        half = kepler._norm(v) * h + 0.5 * acc * h * h + r
        pa, pb = bp.box_pairs(x - half[:, None], x + half[:, None], "sweep")
        pa, pb = pa.astype(np.intp), pb.astype(np.intp)
        mine = pa < nbk.size                              # (i < j: an n-body collider is always a)
        pa, pb = pa[mine], pb[mine]
        if not pa.size:
            return None
        d = kepler._norm(x[pb] - x[pa])
        g = np.maximum(d - r[pa] - r[pb], 0.0)
        A = acc[pa] + acc[pb]
        # (the leapfrog's first half kick moves a drift's velocity by up to A dt / 2 at once)
        w = kepler._norm(v[pb] - v[pa]) + A * world.dt
        tau = _first_reach(g, w, A)
        both = pb < nbk.size
        if both.any():
            # two n-body bodies feel the same wells: their relative acceleration is the tidal difference
            # (|grad g| = 2 mu / r^3, and no body is nearer a well's centre than its surface) plus their
            # own pulls. Over a trial span T their distance stays under D = d + w T + A_T T^2 / 2, A_T
            # the bound at D (iterated up from the first guess: the least such D is a bound); the step
            # min(root, T) is safe for each trial, and the longest of them is taken
            own = 2.0 * self.gm[nbk].sum() / (2.0 * r[:nbk.size].min()) ** 2
            db, wb, gb = d[both], w[both], g[both]
            best = tau[both]
            for T in h * 0.25 ** np.arange(12):
                D = db + wb * T
                for _ in range(4):
                    seg = wells.radius[None, :] - 0.5 * D[:, None]
                    with np.errstate(divide="ignore", over="ignore"):
                        A_T = np.where((seg > 0).all(axis=1),
                                       np.sum(2.0 * wells.mu[None, :] * D[:, None] / np.where(seg > 0, seg, 1.0) ** 3,
                                              axis=1), np.inf) + own
                    D_next = db + wb * T + 0.5 * A_T * T * T
                    done = D_next <= D * 1.001
                    D = np.maximum(D, D_next)
                ok = done & np.isfinite(A_T)
                best = np.where(ok, np.maximum(best, np.minimum(_first_reach(gb, wb, A_T), T)), best)
            tau[both] = best
        k = int(np.argmin(tau))
        if not tau[k] <= h:
            return None
        ents = np.concatenate([self.ents[nbk], self.ents[rk], self.ob_ents])
        a, b = sorted((int(ents[pa[k]]), int(ents[pb[k]])))
        return ContactAhead(float(now + tau[k]), a, b, bound=True)

    def _next_cross_contact(self, horizon: float):
        """next_sphere_contact's look at the pairs in different frames on rails: colliders on rails about
        different wells, and about a moon against an obstacle, on their world-frame paths
        (:func:`framework.kepler.time_to_touch_paths`) from the last step's epochs and wells."""
        last = self._last_step                            # (the wells' and obstacles' states it started from)
        if self._wells is None or not self._n_col or not horizon > 0 or last is None:
            return None
        wells = self._wells
        cs = np.flatnonzero((self.c_rows >= 0) & (self.ep_well >= 0))
        w_of = self.ep_well[cs]
        moons_in = (wells.parent[w_of] >= 0).any() if cs.size else False
        if not cs.size or (np.unique(w_of).size < 2 and not (moons_in and self._n_ob)):
            return None
        world = self.world
        now = (world.step_count + 1) * world.dt
        end = now + horizon
        col = world.table(SphereCollider).data
        n_ob = self._n_ob
        M = cs.size + n_ob
        mv = Movers(kind=np.concatenate([np.full(cs.size, RAILS, np.intp), np.full(n_ob, OBSTACLE, np.intp)]),
                    body=np.concatenate([cs, np.arange(n_ob)]),
                    well=np.concatenate([w_of, np.full(n_ob, -1, np.intp)]),
                    rad=np.concatenate([col["radius"][self.c_rows[cs]], col["radius"][self.ob_c_rows]]).astype(np.float64),
                    lp=np.concatenate([np.zeros((cs.size, 3)), last.ob_x]),
                    lu=np.concatenate([np.zeros((cs.size, 3)), last.ob_v]))
        pos, vel = self._movers_at(last, mv, np.arange(M), np.full(M, now))
        # a box each can reach within the horizon: its speed now, and a bound on its acceleration (no body
        # on rails comes nearer its well than the surface; a moon nearer its parent than the parent's)
        acc = np.zeros(M)
        for wi in np.unique(w_of):
            chain, w = 0.0, int(wi)
            while w >= 0:
                chain += wells.mu[w] / wells.radius[w] ** 2
                w = int(wells.parent[w])
            acc[: cs.size][w_of == wi] = chain
        h = horizon
        half = kepler._norm(vel) * h + 0.5 * acc * h * h + mv.rad
        lo, hi = pos - half[:, None], pos + half[:, None]
        pa, pb = bp.box_pairs(lo, hi, _broad_method(lo, hi))
        pa, pb = pa.astype(np.intp), pb.astype(np.intp)
        kind, well = mv.kind, mv.well
        cross = (kind[pa] == RAILS) & (((kind[pb] == RAILS) & (well[pa] != well[pb]))
                                   | ((kind[pb] == OBSTACLE) & (wells.parent[np.maximum(well[pa], 0)] >= 0)))
        pa, pb = pa[cross], pb[cross]
        if not pa.size:
            return None
        ka = mv.body[pa]
        upto = np.minimum(end, np.minimum(self.ep_contact[ka],
                                          np.where(kind[pb] == RAILS, self.ep_contact[mv.body[pb]], np.inf)))
        t, _ = kepler.time_to_touch_paths(lambda i, tt: self._movers_at(last, mv, pa[i], tt),
                                          lambda i, tt: self._movers_at(last, mv, pb[i], tt),
                                          mv.rad[pa] + mv.rad[pb], np.full(pa.size, now), upto,
                                          acc[pa] + acc[pb])
        t = np.where(now <= upto, t, np.inf)
        k = int(np.argmin(t))
        if not np.isfinite(t[k]):
            return None
        name = lambda m: int(self.ob_ents[mv.body[m]]) if kind[m] == OBSTACLE else int(self.ents[mv.body[m]])  # noqa: E731
        a, b = sorted((name(pa[k]), name(pb[k])))
        return ContactAhead(float(t[k]), a, b)

    def _next_obstacle_contact(self, horizon: float):
        """next_sphere_contact's look at the obstacles: from their Transform and Velocity now (the
        end of the step: the movement system has moved them), straight, against the conics."""
        if not self._n_ob or not self._n_col or not horizon > 0 or self._wells is None:
            return None
        world = self.world
        now = (world.step_count + 1) * world.dt
        end = now + horizon
        wells = self._wells
        pos_t = world.table(Transform).data["position"]
        vel_t = world.table(Velocity).data["linear"]
        X = pos_t[wells.t_rows]
        V = np.where((wells.v_rows >= 0)[:, None], vel_t[np.maximum(wells.v_rows, 0)], 0.0)
        ox = pos_t[self.ob_t_rows]
        ov = np.where((self.ob_v_rows >= 0)[:, None], vel_t[np.maximum(self.ob_v_rows, 0)], 0.0)
        col = world.table(SphereCollider).data
        orad = col["radius"][self.ob_c_rows].astype(np.float64)
        best = None
        for wi in np.flatnonzero(wells.parent < 0):
            cs = np.flatnonzero((self.c_rows >= 0) & (self.ep_well == wi))
            if not cs.size:
                continue
            nc = cs.size
            mu, R = wells.mu[wi], wells.radius[wi]
            rad = col["radius"][self.c_rows[cs]].astype(np.float64)
            p0, w0 = kepler.propagate(self.ep_r[cs], self.ep_v[cs], mu, now - self.ep_t[cs])
            p1, w1 = kepler.propagate(self.ep_r[cs], self.ep_v[cs], mu, end - self.ep_t[cs])
            lo, hi, A, _ = kepler.arc_boxes(p0, w0, p1, w1, end - now, mu, R, self.ep_contact[cs] <= end, rad)
            q0 = ox - X[wi]
            qv = ov - V[wi]
            q1 = q0 + qv * (end - now)
            lo = np.concatenate([lo, np.minimum(q0, q1) - orad[:, None]])
            hi = np.concatenate([hi, np.maximum(q0, q1) + orad[:, None]])
            pa, pb = bp.box_pairs(lo, hi, _broad_method(lo, hi))
            mixed = (pa < nc) & (pb >= nc)                 # (i < j: the obstacle is pb)
            if not mixed.any():
                continue
            pa, o = pa[mixed].astype(np.intp), (pb[mixed] - nc).astype(np.intp)
            ka = cs[pa]
            upto = np.minimum(end, self.ep_contact[ka])
            t, _ = kepler.time_to_touch(self.ep_r[ka], self.ep_v[ka], self.ep_t[ka], q0[o], qv[o], now, mu,
                                        rad[pa] + orad[o], np.full(len(pa), now), upto, A[pa], line_b=True)
            t = np.where(now <= upto, t, np.inf)
            k = int(np.argmin(t))
            if np.isfinite(t[k]) and (best is None or t[k] < best.time):
                a, b = sorted((int(self.ents[ka[k]]), int(self.ob_ents[o[k]])))
                best = ContactAhead(float(t[k]), a, b)
        return best

    def _next_rails_contact(self, horizon: float):
        """next_sphere_contact's look at the pairs on rails (see there)."""
        if self._n_col < 2 or not horizon > 0 or self._wells is None:
            return None
        world = self.world
        now = (world.step_count + 1) * world.dt           # the state is at the end of this step
        kept = self._lookahead
        if kept is not None and kept.version == self._epoch_version:
            found, upto = kept.found, kept.upto
            if found is not None and found.time >= now:
                return found if found.time <= now + horizon else None
            if found is None and upto >= now + horizon:
                return None
        end = now + 2.0 * horizon
        best = None
        col = world.table(SphereCollider).data
        for wi in range(len(self._wells)):
            cs = np.flatnonzero((self.c_rows >= 0) & (self.ep_well == wi))
            if cs.size < 2:
                continue
            mu, R = self._wells.mu[wi], self._wells.radius[wi]
            rad = col["radius"][self.c_rows[cs]].astype(np.float64)
            p0, w0 = kepler.propagate(self.ep_r[cs], self.ep_v[cs], mu, now - self.ep_t[cs])
            p1, w1 = kepler.propagate(self.ep_r[cs], self.ep_v[cs], mu, end - self.ep_t[cs])
            lo, hi, A, rho = kepler.arc_boxes(p0, w0, p1, w1, end - now, mu, R, self.ep_contact[cs] <= end, rad)
            pa, pb = bp.box_pairs(lo, hi, _broad_method(lo, hi))
            if not len(pa):
                continue
            pa, pb = pa.astype(np.intp), pb.astype(np.intp)
            ka, kb = cs[pa], cs[pb]
            upto = np.minimum(end, np.minimum(self.ep_contact[ka], self.ep_contact[kb]))
            t, _ = kepler.time_to_touch(self.ep_r[ka], self.ep_v[ka], self.ep_t[ka], self.ep_r[kb], self.ep_v[kb],
                                        self.ep_t[kb], mu, rad[pa] + rad[pb], np.full(len(pa), now), upto,
                                        A[pa] + A[pb], np.minimum(rho[pa], rho[pb]))
            t = np.where(now <= upto, t, np.inf)
            k = int(np.argmin(t))
            if np.isfinite(t[k]) and (best is None or t[k] < best.time):
                a, b = sorted((int(self.ents[ka[k]]), int(self.ents[kb[k]])))
                best = ContactAhead(float(t[k]), a, b)
        self._lookahead = _Kept(self._epoch_version, best, end)
        return best if best is not None and best.time <= now + horizon else None
