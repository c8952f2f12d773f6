"""n-body bodies (:class:`~components.gravity.NBody`): kick-drift-kick in the pull of every well and of
each other; and the plain mutual pull of ``NBody`` bodies in a scene without a well.

The drift: about a scene's one root well, a body without a collider (or with one, in a step where no
sphere contact can happen: no other collider, no obstacle) whose conic stays above the surface drifts on
that conic (Wisdom–Holman: the well's pull is the exact Kepler drift,
:func:`framework.wisdom_holman.kepler_drift`, the kicks hold only the other bodies' pulls and the thrust;
symplectic, and exact for a lone body at any step); every other n-body body drifts on the straight line
(leapfrog), met against the wells' surfaces and, with a collider, in the contact pass.

Close encounters of bodies on their conics: the hybrid split of :mod:`framework.mercurius` about the fixed
well (Chambers 1999; Rein et al. 2019's MERCURIUS). Each conic body has a critical radius
(:func:`framework.mercurius.critical_radii` of its state about the well at the step's start: three Hill
radii, or the distance a step moves it); a pair of conic bodies nearer than the larger of its two has its
mutual pull in the kicks weighted by the changeover ``L(r)`` (:func:`framework.encounters.changeover_array`,
1 beyond it), and the bodies of a pair whose drift brings it within reach
(:func:`framework.mercurius.encounter_set`) are moved over the step by the adaptive integrator
(:func:`framework.encounters.bulirsch_stoer`) on the well's pull plus the ``1 - L`` part of their mutual
pulls, in place of their Kepler drift. Where no pair comes within reach nothing changes (the same bits)."""
from __future__ import annotations

import numpy as np

from driftframe.components.body import Acceleration, Mass, Transform, Velocity
from driftframe.components.gravity import G, NBody, SurfaceContact
from driftframe.framework import encounters, kepler
from driftframe.framework import mercurius as me
from driftframe.framework import wisdom_holman as wh
from driftframe.framework.step import advance
from driftframe.framework.store import to_indices
from driftframe.systems.gravity.context import Drift, GravityStep


class NBodyFlight:
    """The n-body bodies (a part of :class:`~.system.GravitySystem`)."""

    def _pull_without_wells(self, dt: float) -> None:
        """A scene with ``NBody`` bodies and no well: they attract each other all the same.

        Each step is a drift-kick-drift leapfrog on the others' pulls (second order, time-symmetric, energy
        bounded): ``x_h = x + v dt/2``, ``v' = v + dt (g(x_h) + a)``, ``x' = x_h + v' dt/2``, with
        ``g_i = sum_j G m_j (x_j - x_i) / |x_j - x_i|^3`` (:func:`framework.wisdom_holman.pair_accel`, each
        pair once) and ``a`` the body's own thrust; written into the step context in place of the movement
        stage's prediction (without a movement stage, the kick alone, from the step's start). The collision
        system meets them as any other bodies. A body of infinite (or no) mass pulls nothing and is not
        kicked; two at one point pull each other not at all. With a well in the scene they are this
        system's own (kick-drift-kick, above).
        """
        q = self.world.query(NBody, Transform, Velocity, Mass, optional=(Acceleration,))
        q.refresh()
        if len(q) < 2:
            return
        world = self.world
        t_rows, v_rows = to_indices(q.rows(Transform)), to_indices(q.rows(Velocity))
        kg = world.table(Mass).data["kg"][to_indices(q.rows(Mass))]
        live = np.isfinite(kg)
        if np.count_nonzero(live) < 2:
            return
        t_rows, v_rows, gm = t_rows[live], v_rows[live], G * kg[live]
        a_rows = np.asarray(q.rows(Acceleration), np.intp)[live]
        x = world.table(Transform).data["position"][t_rows]
        v = world.table(Velocity).data["linear"][v_rows]
        ctx = world.step_context
        ctx.begin(world.step_count, dt, world.table(Transform), world.table(Velocity))
        if not ctx.predicted:
            ctx.velocity[v_rows] = v + dt * wh.pair_accel(x, gm)
            return
        g = wh.pair_accel(x + (0.5 * dt) * v, gm)                # the pull at the half drift, m/s^2
        vk = v + (0.5 * dt) * g             # advance(x, vk, a, dt) = x + dt (v + v')/2, v' = v + dt (g + a)
        has_a = a_rows >= 0
        for sel, a in ((~has_a, None), (has_a, world.table(Acceleration).data["linear"][a_rows[has_a]])):
            if sel.any():
                x1, v1 = advance(x[sel], vk[sel], a, dt)
                ctx.position[t_rows[sel]] = x1
                ctx.velocity[v_rows[sel]] = v1 + (0.5 * dt) * g[sel]

    def _accel(self, pos, X, gm, on_conic=None, switch=None):
        """Pull of every well at positions ``pos`` and of the n-body bodies on each other (``G m``); the rows
        ``on_conic`` (a mask) get no pull of the wells (their drift carries it); ``switch``: ``(rows,
        critical radii)`` of the conic bodies, whose mutual pulls are weighted by the changeover
        (:meth:`_switch`)."""
        w = self._wells
        acc = np.zeros_like(pos)
        for wi in range(len(X)):
            d = pos - X[wi]
            r2 = np.einsum("ij,ij->i", d, d)
            pull = (w.mu[wi] / (r2 * np.sqrt(r2)))[:, None] * d
            if on_conic is not None:
                pull[on_conic] = 0.0
            acc -= pull
        if len(pos) > 1:
            d = pos[:, None, :] - pos[None, :, :]
            r2 = np.einsum("ijk,ijk->ij", d, d)
            np.fill_diagonal(r2, np.inf)
            w = gm[None, :] / (r2 * np.sqrt(r2))
            if switch is not None:
                rows, dc = switch
                ii, jj = me.near_pairs(pos[rows], dc)
                if ii.size:
                    a, b = rows[ii], rows[jj]
                    L = encounters.changeover_array(np.sqrt(r2[a, b]), np.maximum(dc[ii], dc[jj]))
                    w[a, b] *= L
                    w[b, a] *= L
            acc -= np.einsum("ij,ijk->ik", w, d)
        return acc

    def _kick(self, step: GravityStep, sel) -> Drift:
        """The n-body bodies' first half kick: their straight drift over the step, ``p + u t`` (t from the
        step's start), no contact yet."""
        p = step.x[sel]
        u = step.v[sel] + 0.5 * step.dt * (self._accel(p, step.X0, self.gm[sel]) + step.a[sel])
        return Drift(p, u, np.full(sel.size, -np.inf))

    def _leapfrog_end(self, step: GravityStep, sel, drift: Drift, surfaces_met: bool) -> None:
        """The rest of the n-body step: the drift (met by the sphere contacts in :meth:`_contacts`, so
        each body is on the line ``p + u t`` from its last contact on) against each well's surface (the
        colliders' met there already, when the contact pass ran: ``surfaces_met``), then the second half
        kick, into ``step.x1, step.v1``."""
        gm = self.gm[sel]
        dt, t0 = step.dt, step.t0
        p, u = drift.p.copy(), drift.u.copy()
        kep = self._on_conic(step, sel, p, u)
        todo = np.flatnonzero(~kep)
        if surfaces_met:
            todo = todo[self.nb_c_rows[sel][todo] < 0]
        if todo.size:
            t_hit, w_hit = self._line_surfaces(step, p[todo], u[todo], t0 + np.maximum(drift.since[todo], 0.0))
            for j in np.flatnonzero(np.isfinite(t_hit)):
                k = todo[j]
                p[k], u[k] = self._reflect(step, sel[k], p[k], u[k], int(w_hit[j]), float(t_hit[j]))
        q = p + u * dt
        switch = None
        if kep.any():                                 # on the conic about the well, from the well's frame
            mu = float(self._wells.mu[0])
            r0 = np.ascontiguousarray(p[kep] - step.X0[0])
            w0 = np.ascontiguousarray(u[kep] - step.V0[0])
            switch = self._switch(step, gm, kep, r0, w0)
            r, w = wh.kepler_drift(r0.copy(), w0.copy(), mu, dt)
            if switch is not None:
                self._encounter_drift(switch, sel, gm, mu, dt, r0, w0, r, w)
            q[kep] = r + step.X1[0]
            u[kep] = w + step.V1[0]
        u = u + 0.5 * dt * (self._accel(q, step.X1, gm, kep if kep.any() else None, switch) + step.a[sel])
        step.x1[sel] = q
        step.v1[sel] = u

    def _switch(self, step: GravityStep, gm, kep, r0, w0):
        """The close-encounter split of the conic bodies (module docstring): ``(rows, critical radii)``, or
        None for fewer than two. The first half kick (:meth:`_kick`) gave their pairs the whole pull: the
        ``1 - L`` part of the pairs nearer than their critical radius is taken back from ``w0`` (in place)."""
        rows = np.flatnonzero(kep)
        if rows.size < 2:
            return None
        g = gm[rows]
        dc = me.critical_radii(np.vstack([np.zeros(3), r0]), np.vstack([np.zeros(3), w0]),
                               np.concatenate([[float(self._wells.mu[0])], g]), step.dt)[1:]
        ii, jj = me.near_pairs(r0, dc)
        if ii.size:
            d = r0[jj] - r0[ii]                          # from i to j
            r = np.sqrt(np.einsum("ij,ij->i", d, d))
            k = ((1.0 - encounters.changeover_array(r, np.maximum(dc[ii], dc[jj]))) / r ** 3)[:, None] * d
            np.add.at(w0, ii, -(0.5 * step.dt) * g[jj][:, None] * k)
            np.add.at(w0, jj, (0.5 * step.dt) * g[ii][:, None] * k)
        return rows, dc

    def _encounter_drift(self, switch, sel, gm, mu, dt, r0, w0, r, w):
        """The conic bodies whose pair comes within reach over the drift ``(r0, w0) -> (r, w)`` (about the
        well) moved again from the start by the adaptive integrator (module docstring), into ``r, w``."""
        rows, dc = switch
        flag = me.encounter_set(r0, w0, r, w, dc, dt)
        if not flag.any():
            return
        Xe, Ve = np.ascontiguousarray(r0[flag]), np.ascontiguousarray(w0[flag])
        if encounters.bulirsch_stoer(Xe, Ve, np.ascontiguousarray(gm[rows][flag]), np.ascontiguousarray(dc[flag]),
                                     mu, dt, me.TOLERANCE) < 0:
            raise RuntimeError(f"gravity: the close-encounter integrator found no step within its tolerance for "
                               f"entities {[int(e) for e in self.ents[sel[rows[flag]]]]} (on one point?)")
        r[flag] = Xe
        w[flag] = Ve

    def _on_conic(self, step: GravityStep, sel, p, u):
        """Which n-body bodies ``sel`` drift on their conic about the well (a mask; module docstring): the
        scene's one well is a root, the body has no collider and its conic never reaches the surface
        (periapsis above the radius). ``u`` of those rows loses the well's half kick (in place). A body with a
        collider counts as one without in a step with no contact pass (no other collider and no obstacle: it
        can meet nothing but the surface, which its conic clears); with one it drifts on the straight line,
        where the pass finds its contacts exactly."""
        wells = self._wells
        kep = np.zeros(sel.size, bool)
        if len(wells) != 1 or wells.parent[0] >= 0:
            return kep
        cand = np.flatnonzero(self.nb_c_rows[sel] < 0) if self._spheres_may_meet else np.arange(sel.size)
        if not cand.size:
            return kep
        mu, R = wells.mu[0], wells.radius[0]
        d = p[cand] - step.X0[0]
        r2 = np.einsum("ij,ij->i", d, d)
        w = u[cand] + (0.5 * step.dt * mu / (r2 * np.sqrt(r2)))[:, None] * d - step.V0[0]   # its half kick taken back
        h = np.cross(d, w)
        h2 = np.einsum("ij,ij->i", h, h)
        energy = 0.5 * np.einsum("ij,ij->i", w, w) - mu / np.sqrt(r2)
        e = np.sqrt(np.maximum(1.0 + 2.0 * energy * h2 / (mu * mu), 0.0))
        above = h2 / (mu * (1.0 + e)) > R            # periapsis q = h^2 / (mu (1 + e)), m
        kep[cand[above]] = True
        u[cand[above]] = w[above] + step.V0[0]
        return kep

    def _line_surfaces(self, step: GravityStep, lp, lu, t_from):
        """The first surface contact of drift lines ``lp + lu (t - t0)`` (n-body bodies, world frame,
        ``(n, 3)``) after ``t_from`` ``(n,)``, by the step's end: ``(time, well)`` (inf, -1: none). A root well
        moves straight: the closed form of two lines; a moon on its conic: conservative advancement
        (:func:`framework.kepler.time_to_touch_paths`), after a cheap test of how far the gap can close."""
        wells = self._wells
        X0, V0, t0, t1 = step.X0, step.V0, step.t0, step.t1
        n = lp.shape[0]
        best_t = np.full(n, np.inf)
        best_w = np.full(n, -1, np.intp)
        for wi in range(len(wells)):
            R = wells.radius[wi]
            if wells.parent[wi] < 0:
                d0 = lp + lu * (t_from - t0)[:, None] - (X0[wi] + V0[wi] * (t_from - t0)[:, None])
                w_rel = lu - V0[wi]
                aa = kepler._dot(w_rel, w_rel)
                bb = kepler._dot(d0, w_rel)
                cc = kepler._dot(d0, d0) - R * R
                disc = bb * bb - aa * cc
                with np.errstate(invalid="ignore", divide="ignore"):
                    s = cc / (-bb + np.sqrt(np.maximum(disc, 0.0)))     # the smaller root, without cancelling
                t = t_from + s
                hit = (bb < 0) & (disc >= 0) & (cc > 0) & (t <= t1)
            else:
                X, V = self._well_at(step, wi, t_from)
                span = np.maximum(t1 - t_from, 0.0)
                near = np.flatnonzero(kepler._norm(lp + lu * (t_from - t0)[:, None] - X) - R
                                      <= (kepler._norm(lu - V) + step.wA[wi] * span) * span)
                t = np.full(n, np.inf)
                if near.size:
                    at_line = lambda i, tt: (lp[near[i]] + lu[near[i]] * (tt - t0)[:, None], lu[near[i]])  # noqa: E731
                    at_moon = lambda i, tt: self._well_at(step, wi, tt)                                    # noqa: E731
                    t[near], _ = kepler.time_to_touch_paths(at_line, at_moon, np.full(near.size, R), t_from[near],
                                                            np.full(near.size, t1), np.full(near.size, step.wA[wi]))
                hit = np.isfinite(t)
            better = hit & (t < best_t)
            best_t[better] = t[better]
            best_w[better] = wi
        return best_t, best_w

    def _reflect(self, step: GravityStep, k, p, u, wi: int, tc: float):
        """n-body body ``self.ents[k]`` on the line ``p + u (t - t0)`` meets well ``wi``'s surface at
        ``tc``: its velocity relative to the well reflected about the normal (elastic); returns the line
        through the contact from then on, ``(p, u)``."""
        t0 = step.t0
        xc = p + u * (tc - t0)
        Xc, Vc = self._well_at(step, wi, np.array([tc]))
        n_hat = (xc - Xc[0]) / np.linalg.norm(xc - Xc[0])
        w_rel = u - Vc[0]
        un = float(w_rel @ n_hat)
        step.events.append(SurfaceContact(int(self.ents[k]), self._wells.ents[wi], float(tc),
                                     float(np.linalg.norm(w_rel)), -un))
        u_new = w_rel - 2.0 * un * n_hat + Vc[0]
        return xc - u_new * (tc - t0), u_new
