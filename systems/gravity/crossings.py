"""Sphere-of-influence changes of bodies on rails, at their exact times within the step (patched conics).

Into a moon's sphere where the body's conic about the parent first comes within
``soi`` of the moon's (:func:`framework.kepler.time_to_touch` about the parent),
out of it where its conic about the moon passes ``soi`` outwards
(:func:`framework.kepler.time_to_radius`, ``outward=True``); the body takes a new
epoch about its new well there."""
from __future__ import annotations

import math

import numpy as np

from driftframe.framework import kepler
from driftframe.systems.gravity.context import GravityStep

#: Most sphere-of-influence changes one body may make in one step (in and out of a moon's sphere is two).
MAX_CROSSINGS = 4


#: Bodies times moons up to which :func:`_far_from_moons` tests in Python floats (numpy's calls on a few
#: elements cost more than the arithmetic: docs/design/costs.md, 'Small gravity scenes').
_FEW = 16


def _far_from_moons(step: GravityStep, kw, wi: int, moons, wells, contact) -> bool:
    """True when none of bodies ``kw`` about root well ``wi``, looked at from the step's start, is ``near``
    a moon in :meth:`Crossings._next_crossing`: the same test on the same numbers in the same order, in
    Python floats (``kepler._norm``'s einsum sums ``(d0^2 + d2^2) + d1^2``). False: let numpy look."""
    t0, t1 = step.t0, step.t1
    span = np.maximum(np.minimum(t1, contact) - t0, 0.0).tolist()
    xs, vs, acc = step.x[kw].tolist(), step.v[kw].tolist(), step.a[kw].tolist()
    X0, V0 = step.X0, step.V0
    Xw, Vw = X0[wi].tolist(), V0[wi].tolist()
    hdt = 0.5 * step.dt
    mu, R = float(wells.mu[wi]), float(wells.radius[wi])
    A = mu / (R * R)
    for wj in moons.tolist():
        rm = (X0[wj] - X0[wi]).tolist()
        um = (V0[wj] - V0[wi]).tolist()
        soi = float(wells.soi[wj])
        for j in range(len(xs)):
            x, v, a = xs[j], vs[j], acc[j]
            d0 = (x[0] - Xw[0]) - rm[0]
            d1 = (x[1] - Xw[1]) - rm[1]
            d2 = (x[2] - Xw[2]) - rm[2]
            e0 = ((v[0] - Vw[0]) + hdt * a[0]) - um[0]
            e1 = ((v[1] - Vw[1]) + hdt * a[1]) - um[1]
            e2 = ((v[2] - Vw[2]) + hdt * a[2]) - um[2]
            gap = math.sqrt((d0 * d0 + d2 * d2) + d1 * d1) - soi
            sp = span[j]
            if not gap > math.sqrt((e0 * e0 + e2 * e2) + e1 * e1) * sp + A * sp * sp:
                return False
    return True


class Crossings:
    """Sphere-of-influence changes (a part of :class:`~.system.GravitySystem`)."""

    def _crossings(self, step: GravityStep, rails, dom, defer=None) -> tuple[np.ndarray, np.ndarray]:
        """Sphere-of-influence changes within the step, at their exact times (patched conics): a body
        on rails about well ``w`` enters a moon ``m`` of ``w`` where its conic comes within ``soi_m``
        of the moon's (:func:`framework.kepler.time_to_touch` about ``w``, approaching), and leaves a
        moon where its conic about it passes ``soi`` outwards (:func:`framework.kepler.time_to_radius`,
        ``outward=True``); it takes a new epoch about its new well there, so the rest of the step,
        a surface contact on the moon included, is on the new conic. Takes every body's epoch for the
        step first. The bodies in ``defer`` (the colliders, when the contact pass runs) only get their
        first crossing's time (``ep_cross``, ``cross_to``): the contact pass makes it, in time order with
        their contacts. Returns the bodies whose epochs are taken (all of ``rails``) and those that
        crossed (``dom`` is updated to each body's well at the step's end)."""
        wells = self._wells
        W, n = len(wells), self._n
        t0, t1 = step.t0, step.t1
        done = np.zeros(n, bool)
        for wi in range(W):
            sel = np.flatnonzero(rails & (dom == wi))
            if sel.size:
                self._take_epochs(step, sel, wi)
                done[sel] = True
        crossed = np.zeros(n, bool)
        movers = rails & (self.well_index < 0)            # (a moon keeps its parent, whatever the spheres say)
        self.ep_cross = np.full(n, np.inf)
        self.cross_to = np.full(n, -1, np.intp)
        t_from = np.full(n, t0)
        for _ in range(MAX_CROSSINGS):
            k = np.flatnonzero(movers & (t_from < t1))
            best_t, best_w = self._next_crossing(step, k, t_from[k], from_start=True)
            hit = best_t <= t1
            if defer is not None:
                later = hit & defer[k]
                self.ep_cross[k[later]] = best_t[later]
                self.cross_to[k[later]] = best_w[later]
                hit &= ~defer[k]
            if not hit.any():
                break
            self._epoch_version += 1
            for j in np.flatnonzero(hit):
                self._cross(int(k[j]), int(best_w[j]), float(best_t[j]))
            crossed[k[hit]] = True
            t_from[k[hit]] = best_t[hit]
            movers[k[~hit]] = False
        dom[crossed] = self.ep_well[crossed]
        return done, crossed

    def _next_crossing(self, step: GravityStep, k, t_from, *, from_start: bool = False):
        """The first sphere-of-influence crossing of bodies ``k`` on rails (current epochs) in
        ``[t_from, t1]``, before any surface contact: ``(time, new well)`` (inf, -1: none). ``from_start``:
        the bodies looked at from the step's start take their state there from the step (no Kepler solve)."""
        wells = self._wells
        best_t = np.full(k.size, np.inf)
        best_w = np.full(k.size, -1, np.intp)
        if not k.size:
            return best_t, best_w
        X0, V0, t0, t1 = step.X0, step.V0, step.t0, step.t1
        wells_of = self.ep_well[k]
        # (np.unique's sorted wells; for a few bodies a set of ints is sorted in a fraction of its time)
        for wi in sorted(set(wells_of.tolist())) if k.size <= _FEW else np.unique(wells_of):
            wi = int(wi)
            moons = np.flatnonzero(wells.parent == wi)
            if wells.parent[wi] < 0 and not moons.size:
                continue
            g = np.flatnonzero(self.ep_well[k] == wi)
            kw, tf = k[g], t_from[g]
            if (from_start and wells.parent[wi] < 0 and kw.size * moons.size <= _FEW and not (tf > t0).any()
                    and _far_from_moons(step, kw, wi, moons, wells, self.ep_contact[kw])):
                continue                                    # (the loop below would find no body near a moon)
            mu, R = wells.mu[wi], wells.radius[wi]
            upto = np.minimum(t1, self.ep_contact[kw])      # (a surface contact first: its own conic after)
            span = np.maximum(upto - tf, 0.0)
            # the state at t_from: at the step's start the table's (no Kepler solve), else from the epoch
            later = tf > t0 if from_start else np.ones(kw.size, bool)
            r = np.empty((kw.size, 3))
            u = np.empty((kw.size, 3))
            if (~later).any():
                ke = kw[~later]
                r[~later] = step.x[ke] - X0[wi]
                u[~later] = step.v[ke] - V0[wi] + 0.5 * step.dt * step.a[ke]     # (thrust: the first half kick)
            if later.any():
                kl = kw[later]
                r[later], u[later] = kepler.propagate(self.ep_r[kl], self.ep_v[kl], mu, tf[later] - self.ep_t[kl])
            # how far a body can move in the span: no body on rails about wi comes nearer its centre
            # than its surface, so no pull on it (nor on a moon of wi) exceeds mu / R^2
            A = mu / (R * R)
            if wells.parent[wi] >= 0:                       # out through this moon's sphere
                out = kepler._norm(r) + kepler._norm(u) * span + 0.5 * A * span * span >= wells.soi[wi]
                if out.any():
                    te = tf[out] + kepler.time_to_radius(r[out], u[out], mu, wells.soi[wi], span[out], outward=True)
                    better = te < best_t[g[out]]
                    best_t[g[out][better]] = te[better]
                    best_w[g[out][better]] = wells.parent[wi]
            for wj in moons:                                # into a moon's sphere
                kk = int(np.flatnonzero(self.well_index == wj)[0])
                rm = np.broadcast_to(X0[wj] - X0[wi], (kw.size, 3)).copy()
                um = np.broadcast_to(V0[wj] - V0[wi], (kw.size, 3)).copy()
                if later.any():
                    ml = int(np.count_nonzero(later))
                    rm[later], um[later] = kepler.propagate(np.broadcast_to(self.ep_r[kk], (ml, 3)),
                                                            np.broadcast_to(self.ep_v[kk], (ml, 3)), mu,
                                                            tf[later] - self.ep_t[kk])
                gap = kepler._norm(r - rm) - wells.soi[wj]
                near = gap <= kepler._norm(u - um) * span + A * span * span
                if not near.any():
                    continue
                kn = kw[near]
                tk, _ = kepler.time_to_touch(self.ep_r[kn], self.ep_v[kn], self.ep_t[kn],
                                             np.broadcast_to(self.ep_r[kk], (kn.size, 3)),
                                             np.broadcast_to(self.ep_v[kk], (kn.size, 3)), self.ep_t[kk],
                                             mu, wells.soi[wj], tf[near], upto[near], 2.0 * A)
                better = tk < best_t[g[near]]
                best_t[g[near][better]] = tk[better]
                best_w[g[near][better]] = wj
        return best_t, best_w

    def _cross(self, k, new, tc):
        """Body ``k`` changes well to ``new`` at ``tc``: its state at ``tc`` about the old well, moved
        to the new one by the moon's state there, is its new epoch."""
        wells = self._wells
        old = int(self.ep_well[k])
        r, u = kepler.propagate(self.ep_r[k], self.ep_v[k], wells.mu[old], tc - self.ep_t[k])
        moon, sign = (new, -1.0) if wells.parent[new] == old else (old, 1.0)   # into a moon / out of it
        mk = int(np.flatnonzero(self.well_index == moon)[0])
        rm, um = kepler.propagate(self.ep_r[mk], self.ep_v[mk], wells.mu[wells.parent[moon]], tc - self.ep_t[mk])
        self.ep_r[k] = r + sign * rm
        self.ep_v[k] = u + sign * um
        self.ep_t[k] = tc
        self.ep_well[k] = new
        self.ep_chi[k] = 0.0
        self.ep_contact[k] = tc + kepler.time_to_radius(self.ep_r[k], self.ep_v[k], wells.mu[new],
                                                        wells.radius[new], np.inf)[0]

    def _recross(self, step: GravityStep, ks, t_from: float) -> None:
        """Bodies ``ks`` on rails are on a new conic from ``t_from``: their next sphere-of-influence
        crossing in the step."""
        if self.ep_cross is None or not len(ks):
            return
        ks = np.asarray(ks, np.intp)
        t, w = self._next_crossing(step, ks, np.full(ks.size, float(t_from)))
        self.ep_cross[ks] = t
        self.cross_to[ks] = w
