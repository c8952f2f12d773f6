"""Sphere contacts along the bodies' own paths: every contact of the step in time order, exact on each
body's conic or drift line, with the impulse along the line of centres and the CollisionEvent."""
from __future__ import annotations

import numpy as np

from driftframe.components.body import Mass
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.framework import kepler
from driftframe.systems.gravity.context import LINE, OBSTACLE, RAILS, Drift, GravityStep, Movers, PassResult
from driftframe.systems.gravity.movers import _PairTimes, _overlapping

#: Most sphere-sphere contacts one body on rails may have in one step; past it, its further contacts
#: in that step are not looked for (a warning says so once): only a resting or jammed cluster gets there.
MAX_SPHERE_CONTACTS = 16

_NO_BODIES = np.empty(0, np.intp)


def _settle(tc, ts, idx, t, start, upto) -> None:
    """Pairs ``idx`` were searched from ``start`` to ``upto``: their contact time ``t`` (inf: none, or
    a search that could not start), and how far each is now known to be apart (``ts``)."""
    t = np.where(start <= upto, t, np.inf)
    tc[idx] = t
    ts[idx] = np.where(np.isfinite(t), start, upto)


class SphereContacts:
    """The contact pass (a part of :class:`~.system.GravitySystem`)."""

    def _contacts(self, step: GravityStep, ends: dict, nb, drift: Drift | None) -> PassResult:
        """Every sphere contact of the step in time order, exact on each body's path: colliders on
        rails (each on its conic about its well, which may itself move on a conic), n-body colliders
        on the leapfrog's straight drift, and obstacles (straight, inverse mass 0), together with the
        surface contacts of the colliders on rails. Pairs on rails about one well take the conic
        search with the tidal bound (:func:`framework.kepler.time_to_touch`); a collider on rails about
        a root well against a straight path takes it with ``line_b``; every other pair (different wells,
        a moon's frame against a line, two lines) the same conservative advancement on the world-frame
        paths (:func:`framework.kepler.time_to_touch_paths`, the bound on the relative acceleration the
        sum of each body's pull and its well's)."""
        t0, t1, events = step.t0, step.t1, step.events
        mv = self._movers(step, ends, nb, drift)
        kind, body, well = mv.kind, mv.body, mv.well
        pairs = _PairTimes(*self._candidates(mv, step.dt), t0, mv.kind.size)
        rails_m = np.flatnonzero(kind == RAILS)
        xing = self.ep_cross                             # (sphere-of-influence crossings to come, or None)
        if xing is not None and not (xing[body[rails_m]] <= t1).any():
            xing = None
        lines_m = np.flatnonzero(kind == LINE)
        nb_surf = np.full(kind.size, np.inf)              # each n-body collider's next surface contact, and where
        nb_well = np.full(kind.size, -1, np.intp)
        if lines_m.size:
            nb_surf[lines_m], nb_well[lines_m] = self._line_surfaces(step, mv.lp[lines_m], mv.lu[lines_m],
                                                                     np.full(lines_m.size, t0))
        if not pairs.pa.size and xing is None and not (nb_surf <= t1).any():   # the usual step: nobody near
            return PassResult(self._surfaces_of(mv, t1, events), drift, False)
        # (from here the n-body colliders' surface contacts are met in the pass, in time order)
        wells = self._wells
        touched = []
        count = np.zeros(mv.kind.size, np.intp)        # (an obstacle's count stays 0: no cap on it)
        for _ in range(64 + 4 * count.size):
            need = np.flatnonzero(np.isnan(pairs.tc))
            if need.size:
                self._search(step, mv, need, pairs)
            k = int(np.argmin(pairs.tc)) if pairs.tc.size else -1
            tp = float(pairs.tc[k]) if k >= 0 else np.inf
            surf = self.ep_contact[body[rails_m]]
            ts_min = float(surf.min()) if surf.size else np.inf
            tx = float(xing[body[rails_m]].min()) if xing is not None else np.inf
            tn = float(nb_surf.min())
            if not min(tp, ts_min, tx, tn) <= t1:
                break
            if tn < min(tp, ts_min, tx):
                # an n-body collider meets a well's surface: its drift reflected there (relative to the well)
                moved = np.flatnonzero(nb_surf == tn)
                for m in moved:
                    mv.lp[m], mv.lu[m] = self._reflect(step, body[m], mv.lp[m], mv.lu[m], int(nb_well[m]), tn)
                    mv.after[m] = tn
                nb_surf[moved], nb_well[moved] = self._line_surfaces(step, mv.lp[moved], mv.lu[moved],
                                                                     np.full(moved.size, tn))
                for m in moved:
                    self._rebox(step, mv, int(m), tn)
                pairs.renew(moved, tn)
                for c in moved:
                    pairs.add(_overlapping(mv, int(c), pairs), tn)
                continue
            if ts_min < tp and ts_min <= tx:              # surface contacts come first
                hm = rails_m[(surf < tp) & (surf <= t1) & (surf <= tx)]
                for wi in np.unique(well[hm]):
                    self._bounce(body[hm[well[hm] == wi]], int(wi), events)
                touched.append(body[hm])
                if xing is not None:                      # (a new conic: its crossing looked for again)
                    self._recross(step, body[hm], ts_min)
                # their pairs were followed up to the bounce (their boxes hold both conics): on from there
                pairs.look_again(hm, t1)
                continue
            if tx < tp:
                # bodies that change sphere of influence: a new epoch about the new well at the crossing,
                # then as after a contact (new boxes, their pairs looked at again from there)
                moved = rails_m[xing[body[rails_m]] == tx]
                for m in moved:
                    i = int(body[m])
                    self._epoch_version += 1
                    self._cross(i, int(self.cross_to[i]), tx)
                    well[m] = self.ep_well[i]
                    mv.wA[m] = step.wA[well[m]]
                    mv.root[m] = wells.parent[well[m]] < 0
                    touched.append(body[m:m + 1])
                self._recross(step, body[moved], tx)
                tp, resting = tx, False
            else:
                ia, ib = int(pairs.pa[k]), int(pairs.pb[k])
                resting = self._resolve(step, mv, ia, ib, tp)
                moved = np.array([m for m in (ia, ib) if kind[m] != OBSTACLE], np.intp)
                count[moved] += 1
                on_rails = moved[kind[moved] == RAILS]
                touched.append(body[on_rails])
                if xing is not None:
                    self._recross(step, body[on_rails], tp)
                on_line = moved[kind[moved] == LINE]
                if on_line.size:
                    nb_surf[on_line], nb_well[on_line] = self._line_surfaces(step, mv.lp[on_line], mv.lu[on_line],
                                                                             np.full(on_line.size, tp))
            # their paths from tp on: new boxes, their pairs looked at again from tp, and new pairs
            for m in moved:
                self._rebox(step, mv, int(m), tp)
            pairs.renew(moved, tp)
            if resting:
                # not looked at again this step (the next step resolves it afresh, one impulse per step)
                # instead of a cascade of ever smaller impulses
                pairs.settle(k, t1)
            for c in moved:
                pairs.add(_overlapping(mv, int(c), pairs), tp)
            full = count >= MAX_SPHERE_CONTACTS
            if full.any():
                pairs.drop(full[pairs.pa] | full[pairs.pb], t1)
                self._warn_once("cap", f"gravity: a body met {MAX_SPHERE_CONTACTS} sphere contacts "
                                       "in one step; its further contacts in that step are not resolved")
        else:
            self._warn_once("events", "gravity: too many contacts in one step; the rest of that step's "
                                      "contacts are not resolved")
        return PassResult(np.unique(np.concatenate(touched)) if touched else _NO_BODIES,
                          self._lines_after(step, mv, nb, drift), True)

    def _surfaces_of(self, mv: Movers, t1: float, events: list):
        """No pair near: only the rails movers' surface contacts, well by well. Returns those that bounced."""
        moved = []
        for wi, ms in mv.groups:
            cs = mv.body[ms]
            if (self.ep_contact[cs] <= t1).any():
                hit0 = self.ep_t[cs].copy()
                self._surfaces(cs, wi, t1, events)
                moved.append(cs[self.ep_t[cs] != hit0])
        return np.concatenate(moved) if moved else _NO_BODIES

    def _search(self, step: GravityStep, mv: Movers, need, pairs: _PairTimes) -> None:
        """The contact times of pairs ``need`` (from what each is known to be apart, ``pairs.ts``)."""
        wells = self._wells
        kind, body, well, rad = mv.kind, mv.body, mv.well, mv.rad
        A, rho, wA, root, after = mv.A, mv.rho, mv.wA, mv.root, mv.after
        t0, t1 = step.t0, step.t1
        ts, tc = pairs.ts, pairs.tc
        ia, ib = pairs.pa[need], pairs.pb[need]
        ka, kb = body[ia], body[ib]
        ra, rb = kind[ia] == RAILS, kind[ib] == RAILS
        # a pair is followed up to the first surface contact of a body on rails in it (its path changes
        # there), and from its last contact (a rails body's epoch, a line's last contact)
        upto = np.minimum(t1, np.minimum(np.where(ra, self.ep_contact[ka], np.inf),
                                         np.where(rb, self.ep_contact[kb], np.inf)))
        if self.ep_cross is not None:                     # (and up to a change of sphere of influence)
            upto = np.minimum(upto, np.minimum(np.where(ra, self.ep_cross[ka], np.inf),
                                               np.where(rb, self.ep_cross[kb], np.inf)))
        start = np.maximum(ts[need], np.maximum(np.where(ra, self.ep_t[ka], t0), np.where(rb, self.ep_t[kb], t0)))
        start = np.maximum(start, np.maximum(after[ia], after[ib]))
        reach = rad[ia] + rad[ib]
        t = np.full(need.size, np.inf)
        stuck = np.zeros(need.size, bool)
        same = ra & rb & (well[ia] == well[ib])
        line = ra & ~rb & root[ia]
        for wi in np.unique(well[ia[same]]):
            m = np.flatnonzero(same & (well[ia] == wi))
            t[m], stuck[m] = kepler.time_to_touch(
                self.ep_r[ka[m]], self.ep_v[ka[m]], self.ep_t[ka[m]], self.ep_r[kb[m]], self.ep_v[kb[m]],
                self.ep_t[kb[m]], wells.mu[wi], reach[m], start[m], upto[m], A[ia[m]] + A[ib[m]],
                np.minimum(rho[ia[m]], rho[ib[m]]))
        X0, V0 = step.X0, step.V0
        for wi in np.unique(well[ia[line]]):
            m = np.flatnonzero(line & (well[ia] == wi))
            q0 = mv.lp[ib[m]] - X0[wi]                  # the line relative to the (straight-moving) root
            qv = mv.lu[ib[m]] - V0[wi]
            t[m], stuck[m] = kepler.time_to_touch(
                self.ep_r[ka[m]], self.ep_v[ka[m]], self.ep_t[ka[m]], q0, qv, t0, wells.mu[wi], reach[m],
                start[m], upto[m], A[ia[m]], line_b=True)
        gen = np.flatnonzero(~same & ~line)
        if gen.size:
            ga, gb = ia[gen], ib[gen]
            t[gen], stuck[gen] = kepler.time_to_touch_paths(
                lambda i, tt: self._movers_at(step, mv, ga[i], tt), lambda i, tt: self._movers_at(step, mv, gb[i], tt),
                reach[gen], start[gen], upto[gen], A[ga] + wA[ga] + A[gb] + wA[gb])
        _settle(tc, ts, need, t, start, upto)
        if stuck.any():
            m = int(np.flatnonzero(stuck)[0])
            self._warn_once("graze", f"gravity: {self._mover_name(mv, ia[m])} and {self._mover_name(mv, ib[m])} "
                                     "graze too slowly to converge; their contact (if any) in this step is not "
                                     "resolved")

    def _mover_mass_rest(self, mv: Movers, ms):
        """Inverse masses (1/kg: Mass, 1 kg without; an obstacle's 0) and restitutions of movers ``ms``."""
        world = self.world
        kg_t = world.table(Mass).data["kg"]
        col = world.table(SphereCollider).data["restitution"]
        inv, rest = np.zeros(ms.size), np.zeros(ms.size)
        for j, m in enumerate(ms):
            k = mv.body[m]
            if mv.kind[m] == OBSTACLE:
                rest[j] = col[self.ob_c_rows[k]]
                continue
            rest[j] = col[self.c_rows[k] if mv.kind[m] == RAILS else self.nb_c_rows[k]]
            inv[j] = 1.0 / (kg_t[self.m_rows[k]] if self.m_rows[k] >= 0 else 1.0)
        return inv, rest

    def _mover_name(self, mv: Movers, m: int) -> str:
        k = mv.body[m]
        if mv.kind[m] == OBSTACLE:
            return f"obstacle {int(self.ob_ents[k])}"
        return f"body {int(self.ents[k])}"

    def _resolve(self, step: GravityStep, mv: Movers, ia: int, ib: int, tp: float) -> bool:
        """Movers ``ia`` and ``ib`` touch at ``tp``: the impulse, their new paths, the event. Returns
        whether the contact is resting (the pair separates slower than the pulls on it can undo within
        the step: not looked at again in this step)."""
        kind, body, well, rad = mv.kind, mv.body, mv.well, mv.rad
        A, rho, wA = mv.A, mv.rho, mv.wA
        if kind[ia] == RAILS and kind[ib] == RAILS and well[ia] == well[ib]:
            wi = int(well[ia])
            sep = self._collide(step, int(body[ia]), int(body[ib]), wi, tp)
            # a resting contact (e = 0, or a slow one): separating slower than the tidal pull between them
            reach = rad[ia] + rad[ib]
            seg = min(rho[ia], rho[ib]) - reach
            return bool(seg > 0 and sep < 2.0 * self._wells.mu[wi] * 2.0 * reach / seg ** 3 * (step.t1 - tp))
        return self._collide_paths(step, mv, ia, ib, tp, A[ia] + wA[ia] + A[ib] + wA[ib])

    def _collide_paths(self, step: GravityStep, mv: Movers, ia: int, ib: int, tp: float, accel: float) -> bool:
        """Any pair but two bodies on rails about one well touches at ``tp``: the impulse along the line
        of centres in the world frame (masses from Mass, 1 kg without; an obstacle's inverse mass 0, so
        its velocity is left alone; restitution the smaller of the two), a new epoch about its well for
        a body on rails, a new drift line for an n-body body, and the CollisionEvent
        (``method="kepler"`` where a body on rails is in it, else ``"leapfrog"``). Returns whether the
        contact is resting.

        A slow contact against an obstacle (separating slower than ``accel (t1 - tp) / 2``, ``accel`` the
        bound on the pair's relative acceleration: restitution 0, or a body pressed on by a well's pull)
        leaves at that speed, the least that keeps the gap ``g >= s tau - accel tau^2 / 2`` open up to
        ``t1``: the obstacle feels none of the pull, so a body left at rest on it would sink by
        ``accel dt^2 / 2`` a step and, step after step, pass through it. The cost is a hop of at most
        ``accel dt^2 / 8``, only in such slow contacts. Between two bodies such a contact is resting."""
        kind, body, well = mv.kind, mv.body, mv.well
        t0, t1 = step.t0, step.t1
        ms = np.array([ia, ib])
        pos, vel = self._movers_at(step, mv, ms, np.full(2, tp))
        d = pos[1] - pos[0]
        nrm = d / np.linalg.norm(d)
        vn = float((vel[1] - vel[0]) @ nrm)                # < 0: approaching (the search finds only those)
        inv, rest = self._mover_mass_rest(mv, ms)
        e = float(rest.min())
        fixed = bool((inv == 0).any())
        keep_out = 0.5 * accel * (t1 - tp)
        if vn < 0 and inv.sum() > 0:
            sep = max(-e * vn, keep_out) if fixed else -e * vn
            impulse = (sep - vn) / (inv[0] + inv[1])
        else:
            impulse = 0.0
        vel[0] -= impulse * inv[0] * nrm
        vel[1] += impulse * inv[1] * nrm
        wells = self._wells
        for j, m in enumerate(ms):
            k = body[m]
            if kind[m] == RAILS:
                wi = int(well[m])
                W, Wv = self._well_at(step, wi, np.array([tp]))
                self._epoch_version += 1
                self.ep_r[k] = pos[j] - W[0]
                self.ep_v[k] = vel[j] - Wv[0]
                self.ep_t[k] = tp
                self.ep_chi[k] = 0.0
                self.ep_contact[k] = tp + kepler.time_to_radius(self.ep_r[k], self.ep_v[k], wells.mu[wi],
                                                                wells.radius[wi], np.inf)[0]
            elif kind[m] == LINE:
                mv.lp[m] = pos[j] - vel[j] * (tp - t0)   # the line through the contact, as of t0
                mv.lu[m] = vel[j]
                mv.after[m] = tp
        ents = [int(self.ob_ents[body[m]]) if kind[m] == OBSTACLE else int(self.ents[body[m]]) for m in ms]
        first = 0 if ents[0] < ents[1] else 1
        n_ab = nrm if first == 0 else -nrm
        point = pos[first] + float(mv.rad[ms[first]]) * n_ab
        method = "kepler" if (kind[ms] == RAILS).any() else "leapfrog"
        step.events.append(CollisionEvent(min(ents), max(ents), float(tp), float(tp - t0),
                                     tuple(float(c) for c in point), tuple(float(c) for c in n_ab),
                                     float(impulse), method=method, step=self.world.step_count))
        sep_now = float((vel[1] - vel[0]) @ nrm)
        return not fixed and sep_now < keep_out * 2.0

    def _collide(self, step: GravityStep, i: int, j: int, wi: int, tc: float) -> float:
        """Bodies ``i`` and ``j`` touch at ``tc``: the impulse along the line of centres (masses from
        Mass, 1 kg without; restitution the smaller of the two), new epochs for both at ``tc``, their
        next surface contacts, the CollisionEvent. Returns their separating speed along the normal after
        the impulse."""
        world = self.world
        wells = self._wells
        mu, R = wells.mu[wi], wells.radius[wi]
        k = np.array([i, j])
        rc, uc = kepler.propagate(self.ep_r[k], self.ep_v[k], mu, tc - self.ep_t[k])
        d = rc[1] - rc[0]
        nrm = d / np.linalg.norm(d)
        vn = float((uc[1] - uc[0]) @ nrm)                  # < 0: approaching (the search finds only those)
        kg = np.where(self.m_rows[k] >= 0, world.table(Mass).data["kg"][np.maximum(self.m_rows[k], 0)], 1.0)
        with np.errstate(divide="ignore"):
            inv = 1.0 / kg
        rest = world.table(SphereCollider).data["restitution"][self.c_rows[k]]
        e = float(min(rest[0], rest[1]))
        impulse = -(1.0 + e) * vn / (inv[0] + inv[1]) if vn < 0 and inv.sum() > 0 else 0.0
        uc[0] -= impulse * inv[0] * nrm
        uc[1] += impulse * inv[1] * nrm
        self._epoch_version += 1
        self.ep_r[k], self.ep_v[k], self.ep_t[k] = rc, uc, tc
        self.ep_chi[k] = 0.0
        self.ep_contact[k] = tc + kepler.time_to_radius(rc, uc, mu, R, np.inf)
        # the event in the world frame, named as the collision system names it (lower entity first)
        well = self._well_at(step, wi, np.array([tc]))[0][0]
        radius = world.table(SphereCollider).data["radius"][self.c_rows[k]]
        ea, eb = int(self.ents[i]), int(self.ents[j])
        first = 0 if ea < eb else 1
        n_ab = nrm if first == 0 else -nrm
        point = well + rc[first] + float(radius[first]) * n_ab
        step.events.append(CollisionEvent(min(ea, eb), max(ea, eb), float(tc), float(tc - step.t0),
                                     tuple(float(c) for c in point), tuple(float(c) for c in n_ab),
                                     float(impulse), method="kepler", step=world.step_count))
        return float((uc[1] - uc[0]) @ nrm)
