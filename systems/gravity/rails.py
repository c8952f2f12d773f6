"""Bodies on rails: the exact two-body flow about one well from each body's epoch, thrust as a
kick-drift-kick about it, and the elastic bounce off the well's surface.

Each body on rails keeps an *epoch* (its state about its well at the last time
something changed it: ``ep_r, ep_v, ep_t, ep_well``) and is evaluated each step
from it for the whole time since (:class:`framework.kepler.Epoch`), so no error
builds up from step to step. Its next surface contact (``ep_contact``, absolute
seconds) is found exactly on the conic (:func:`framework.kepler.time_to_radius`)."""
from __future__ import annotations

import numpy as np

from driftframe.components.body import Transform, Velocity
from driftframe.components.gravity import SurfaceContact
from driftframe.framework import kepler
from driftframe.systems.gravity.context import GravityStep, RailsEnd

#: Most surface contacts one body may have in one step (a grazing bounce is one; more is rounding).
MAX_CONTACTS = 4
#: A step's obstacle states where there are none (read-only).
_NO_OBSTACLES = np.zeros((0, 3))
_NO_OBSTACLES.flags.writeable = False


class Rails:
    """The bodies on rails (a part of :class:`~.system.GravitySystem`)."""

    def _take_epochs(self, step: GravityStep, sel, wi: int, done=None) -> None:
        """A new epoch at ``t0`` about well ``wi`` for those of bodies ``sel`` whose engine fires, whose
        well changed, or that someone else moved (not those in ``done``: taken already this step)."""
        g = slice(None) if sel.size == self._n else sel     # a slice gathers faster than an index
        new = step.thrust[g] | step.edited[g] | (self.ep_well[g] != wi)
        if done is not None:
            new &= ~done[g]
        if new.any():
            mu, R = self._wells.mu[wi], self._wells.radius[wi]
            self._epoch_version += 1
            k = sel[new]
            t0 = step.t0
            self.ep_r[k] = step.x[k] - step.X0[wi]
            self.ep_v[k] = step.v[k] - step.V0[wi] + 0.5 * step.dt * step.a[k]     # thrust: the first half kick
            self.ep_t[k] = t0
            self.ep_well[k] = wi
            self.ep_contact[k] = t0 + kepler.time_to_radius(self.ep_r[k], self.ep_v[k], mu, R, np.inf)
            self.ep_chi[k] = 0.0

    def _quiet(self, step: GravityStep) -> bool:
        """The usual step of one root well's bodies on rails in one compiled pass (``Epoch.step_from``:
        the guess, the solution and the move to the well's frame at ``t1`` per body), into ``step.x1,
        step.v1``; False (nothing done) unless it is a step in which the stages would do only that: one
        well, no n-body body, at least ``COMPILED_MIN`` bodies (below, the numpy path's bits), no sphere
        contact looked for (the caller's test), no thrust, no body moved by another system, every epoch
        about the well and no surface contact due by ``t1``. The same bits as the stages (tests/
        test_gravity_step.py). Why: the stages' numpy passes around the compiled loop cost ~40 % of it at
        10,000 bodies (a (3,)-vector added to an (n, 3) array runs numpy's inner loop n times)."""
        n = self._n
        if (len(self._wells) != 1 or n < kepler.COMPILED_MIN or self._n_nb or step.thrust.any()
                or step.edited.any() or (self.ep_well != 0).any() or (self.ep_contact <= step.t1).any()):
            return False
        self.ep_cross = None
        mu = self._wells.mu[0]
        well = np.concatenate([step.X0, step.V0, step.X1, step.V1])           # (4, 3): one well
        self._epoch(0, self._every, mu).step_from(step.t1, self.ep_t, self.ep_chi, step.x, step.v, well, mu,
                                                  step.dt, step.x1, step.v1)
        return True

    def _quiet_from_tables(self, dt: float) -> GravityStep | None:
        """:meth:`_quiet` before :meth:`_begin`, straight from the tables in one compiled call
        (``Epoch.quiet_step``: the gathers, the checks, the well's states, the pass and the writes into the
        step context), the same numbers:
        the step, or None (nothing changed) where that call finds it is not a quiet step or where the
        usual path must decide (more than one well, n-body bodies, a body with an Acceleration, fewer than
        ``COMPILED_MIN`` bodies, the epochs not derived yet). Why: between a game's other work each numpy
        call of the usual path (about 20 a step) finds its code and data cold (docs/bench/orbit_accuracy.md)."""
        n = self._n
        wells = self._wells
        if len(wells) != 1 or n < kepler.COMPILED_MIN or self._n_nb or self._has_a.size:
            return None
        cached = self._epochs.get(0)
        if cached is None or cached[0] != (0, self._epoch_version, n):
            return None
        world = self.world
        t0, t1 = world.step_count * dt, (world.step_count + 1) * dt
        pos_t = world.table(Transform).data["position"]
        vel_t = world.table(Velocity).data["linear"]
        xs, vs, well = self._quiet_bufs[self._quiet_flip]
        mu = wells.mu[0]
        # the step context opened now (at the step's end on the usual path: no stage writes a table, so it
        # holds the same rows either way), so that the pass writes the bodies' rows of it too
        ctx = world.step_context
        ctx.begin(world.step_count, dt, world.table(Transform), world.table(Velocity))
        if not cached[2].quiet_step(self.ep_t, self.ep_chi, self.ep_well, self.ep_contact, pos_t, vel_t, self._t_idx,
                                    self._v_idx, int(wells.t_rows[0]), int(wells.v_rows[0]), self.last_x,
                                    self.last_v, t1, dt, mu, xs, vs, well, self._x1_next, self._v1_next,
                                    ctx.position, ctx.open_velocity()):
            return None
        self._quiet_flip ^= 1                             # (the last step's arrays stay as they were)
        self.ep_cross = None
        if self._n_ob:
            has = self.ob_v_rows >= 0
            ob_x = pos_t[self.ob_t_rows]
            ob_v = np.where(has[:, None], vel_t[np.maximum(self.ob_v_rows, 0)], 0.0)
        else:
            ob_x = ob_v = _NO_OBSTACLES
        return GravityStep(t0=t0, t1=t1, dt=dt, X0=well[0:1], V0=well[1:2], X1=well[2:3], V1=well[3:4],
                           wA=np.zeros(1), x=xs, v=vs, a=self._no_a, thrust=self._none, edited=self._none,
                           ob_x=ob_x, ob_v=ob_v, x1=self._x1_next, v1=self._v1_next, events=[])

    def _rails(self, step: GravityStep, sel, wi: int, look: bool, done=None, crossed=None) -> RailsEnd:
        """Bodies ``sel`` on rails about well ``wi``: their epochs for the step, the surface contacts of
        those whose contacts are not looked for in :meth:`_contacts` (there the colliders meet the
        surface in time order with everything else), and their states about the well at ``t1``
        (before any sphere contact)."""
        mu = self._wells.mu[wi]
        g = slice(None) if sel.size == self._n else sel     # a slice gathers faster than an index
        if done is None or not done[sel].all():           # (else the crossings took them all this step)
            self._take_epochs(step, sel, wi, done)
        plain = sel[self.c_rows[sel] < 0] if look else sel
        if plain.size:
            self._surfaces(plain, wi, step.t1, step.events)
        # from the epoch for the whole time since (no error carried from step to step), warm-started
        # from the last step's chi moved on by its Taylor series over the step (kepler.next_chi; the
        # state at the step's start is the last step's result). The guess changes how fast the solver
        # converges, and where only within its few ulp.
        guess = kepler.next_chi(self.ep_chi[g], step.x[g], step.v[g], mu, step.dt, origin=(step.X0[wi], step.V0[wi]))
        if crossed is not None and crossed[g].any():
            guess[crossed[g]] = np.nan                     # (it started the step about another well: no guess)
        r, u, chi = self._epoch(wi, sel, mu).at(step.t1 - self.ep_t[g], guess)
        return RailsEnd(sel, r, u, chi, guess)

    def _rails_end(self, step: GravityStep, wi: int, end: RailsEnd, touched) -> None:
        """The end-of-step states of a well's bodies (``step.x1, step.v1``): again from their new epochs
        where a sphere contact ``touched`` them, then thrust's second half kick."""
        sel, r, u, chi = end.sel, end.r, end.u, end.chi
        t1, dt, a, thrust = step.t1, step.dt, step.a, step.thrust
        mu = self._wells.mu[wi]
        g = slice(None) if sel.size == self._n else sel
        if touched.size:
            mine = touched[np.isin(touched, sel)]
            mine = mine[self.ep_well[mine] == wi]
            if mine.size:
                p = np.searchsorted(sel, mine)
                r[p], u[p], chi[p] = kepler.Epoch(self.ep_r[mine], self.ep_v[mine], mu).at(
                    t1 - self.ep_t[mine], end.guess[p])
        self.ep_chi[g] = chi
        th = thrust[g]
        if th.any():
            # the second half kick; the state after it is the next step's epoch (taken then, as thrust)
            u[th] += 0.5 * dt * a[sel[th]]
        step.x1[g] = step.X1[wi] + r
        step.v1[g] = step.V1[wi] + u
        if touched.size:
            # colliders that changed sphere of influence in the contact pass: about their new well
            away = touched[np.isin(touched, sel) & (self.ep_well[touched] != wi)]
            for c in away:
                wj = int(self.ep_well[c])
                rr, uu = kepler.propagate(self.ep_r[c], self.ep_v[c], self._wells.mu[wj], t1 - self.ep_t[c])
                step.x1[c] = step.X1[wj] + rr
                step.v1[c] = step.V1[wj] + uu + (0.5 * dt * a[c] if thrust[c] else 0.0)
                self.ep_chi[c] = 0.0
        if th.any():
            self.ep_well[sel[th]] = -1

    def _surfaces(self, sel, wi, t1, events):
        """The surface contacts of bodies ``sel`` up to ``t1``, each body's in its own time order."""
        for _ in range(MAX_CONTACTS):
            hit = sel[self.ep_contact[sel] <= t1]
            if not hit.size:
                break
            self._bounce(hit, wi, events)

    def _bounce(self, hit, wi, events):
        """Bodies ``hit`` touch well ``wi``'s surface at their ``ep_contact``: one elastic bounce each."""
        wells = self._wells
        mu, R = wells.mu[wi], wells.radius[wi]
        self._epoch_version += 1
        tc = self.ep_contact[hit]
        rc, uc = kepler.propagate(self.ep_r[hit], self.ep_v[hit], mu, tc - self.ep_t[hit])
        n_hat = rc / np.linalg.norm(rc, axis=1, keepdims=True)
        un = np.einsum("ij,ij->i", uc, n_hat)
        speed = np.linalg.norm(uc, axis=1)
        uc = uc - 2.0 * un[:, None] * n_hat                        # elastic: reverse the radial part
        for j, k in enumerate(hit):
            events.append(SurfaceContact(int(self.ents[k]), wells.ents[wi], float(tc[j]), float(speed[j]),
                                         float(-un[j])))
        self.ep_r[hit], self.ep_v[hit], self.ep_t[hit] = rc, uc, tc
        self.ep_chi[hit] = 0.0
        # the next contact of the new epoch (an outbound body: after its next periapsis dip, if any), on
        # this very conic: time_to_radius takes a body on the surface moving out (no nudge of rc, which
        # moved the conic: 8e-9 s late a bounce on a radial line, the body then 5e-5 m inside, missed next)
        nxt = kepler.time_to_radius(rc, uc, mu, R, np.inf)
        self.ep_contact[hit] = tc + nxt

    def _epoch(self, wi, sel, mu) -> kepler.Epoch:
        """The epochs of bodies ``sel`` about well ``wi`` as a kepler.Epoch, kept while none changes
        (what depends only on the epoch state is then derived once, not every step)."""
        key = (wi, self._epoch_version, sel.size)
        cached = self._epochs.get(wi)
        # (the same epochs and as many bodies: the same bodies unless the split between wells changed,
        # which is compared; every body about the one well, the usual case, needs no comparison)
        if cached is not None and cached[0] == key and (sel.size == self._n or np.array_equal(cached[1], sel)):
            return cached[2]
        ep = kepler.Epoch(self.ep_r[sel], self.ep_v[sel], mu)
        self._epochs[wi] = (key, sel.copy(), ep)
        return ep
