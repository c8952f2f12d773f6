"""Sphere collisions: exact, continuous, order-independent (and the articles' method as a baseline).

The collision stage runs *after* movement has advanced every body by the
whole step, so it sees the end-of-step state ``x1, v1`` and reconstructs the
step's path:

* a free body moved in a straight line, ``x0 = x1 - v1 dt``;
* a body with an :class:`~components.body.Acceleration` moved on a parabola
  (``x1 = x0 + v0 dt + a dt^2/2``). The collision system treats it as a
  straight path at its *average* velocity over the step,
  ``u = (x1 - x0)/dt = v1 - a dt/2``, which has the same end points; an
  impulse changes ``u``, and ``a dt/2`` is added back to give the velocity at
  the end of the step. (Contacts of thrusting bodies are therefore placed on
  the chord of their parabola, an error of at most ``|a| dt^2 / 8``.)

**Continuous method** (the default). Every body moves as ``p(t) = xr + u t``
for ``0 <= t <= dt``. For each candidate pair the earliest time of impact is
the smaller root of ``|d + w t|^2 = R^2`` (``d`` relative position, ``w``
relative velocity, ``R = r_a + r_b``), written ``t = c / (-b + sqrt(b^2 - a
c))`` with ``a = w.w``, ``b = d.w``, ``c = d.d - R^2`` so nothing cancels.
Contacts are taken in time order. At the earliest instant ``t*``, every pair
that is touching (gap <= 1e-9 R) and approaching is resolved *together*, in
one wave: impulses ``lambda >= 0`` along the normals so that each contact's
normal relative velocity becomes ``-e`` times what it was,

    A lambda = -(1 + e) v_n,   A = J M^-1 J^T   (J: contact normals, M: masses)

(one small linear solve; a negative ``lambda`` would pull, so those contacts
are dropped and the rest solved again). With ``e = 1`` every contact in the
wave reverses its normal velocity and kinetic energy is kept exactly:
``dKE = lambda . (v_n + v_n')/2 = 0``. The bodies that changed are
re-advanced from ``t*`` with their new velocities, the pairs they belong to
are re-checked, and contacts that now approach at ``t*`` form the next wave.
So a chain of touching spheres (Newton's cradle) passes the impulse ball by
ball inside one instant, a symmetric hit stays symmetric, and nothing depends
on the order of entities. Pairs that overlap (at spawn, or by rounding) but
separate are left alone: they never stick, and no position is ever moved
except by velocity times time, so nothing jumps.

Broad phase: all pairs up to :data:`framework.broadphase.ALL_PAIRS_MAX`
bodies; above that a :class:`~framework.broadphase.NeighbourList` (built with
the uniform grid, rebuilt when a body strays half its skin) plus a per-step
sweep of "fast" bodies against all. A body whose new path after a contact
leaves its skin is swept against all for the rest of the step.

**The articles' method** (``method="articles"``, a labelled baseline): after
the step, for every pair in turn (a Python double loop, in entity order),
if the spheres overlap, move both back along their velocities until the
centres are ``r_a + r_b`` apart, and reflect each velocity about the contact
normal in the centre-of-mass frame (``v' = v - 2 n (n.v)``). As written
there: it only sees overlaps at the end of a step (fast spheres pass through
each other), the remaining time of the step is not re-advanced, pairs are
handled one after another (so a break or a cradle depends on order), and it
does not check that the pair approaches (spheres left overlapping can stick).

Masses: :class:`~components.body.Mass` (``math.inf`` = immovable); a collider
without ``Mass`` weighs 1 kg; one without ``Velocity`` is a fixed obstacle.
Two immovable bodies pass through each other. Restitution of a pair: the
smaller of the two :class:`~components.collision.SphereCollider` values.
Spin is not touched (frictionless spheres exert no torque).
"""
from __future__ import annotations

import math
import warnings

import esper
import numpy as np

from components.body import Acceleration, Mass, Transform, Velocity
from components.collision import CollisionEvent, SphereCollider
from framework import broadphase as bp
from framework.store import as_index

METHODS = ("continuous", "articles")

#: Pairs closer than this fraction of r_a + r_b are touching (contact "now").
TOUCH = 1e-9
#: Normal approach speeds below this fraction of the fastest body's speed are rounding noise.
APPROACH = 1e-12
#: Centres closer than this fraction of r_a + r_b define no contact normal: such a pair is left to pass.
CENTRED = 1e-9
#: Guard against a jam (e.g. a sphere squeezed between two immovable bodies): waves per instant.
MAX_WAVES = 10_000

_NONE = np.empty(0, np.intp)
_NONE_T = np.empty(0)


class _Layout:
    """Packed per-collider indices into the component tables, rebuilt when esper's queries change.

    Packed order is ascending entity id, so results are independent of
    esper's set order. ``*_idx`` are index arrays; ``*_rows`` the same as a
    slice when contiguous (much faster to gather).
    """

    def __init__(self, queries):
        base, withv, withm, witha = queries
        self.queries = queries
        pairs = sorted(((e, c) for e, c in base), key=lambda p: p[0])
        self.n = n = len(pairs)
        self.entities = np.fromiter((e for e, _ in pairs), np.int64, n)
        index = {e: k for k, (e, _) in enumerate(pairs)}
        self.t_idx = np.fromiter((c[0]._row for _, c in pairs), np.intp, n)
        self.c_idx = np.fromiter((c[1]._row for _, c in pairs), np.intp, n)
        self.t_rows = as_index(self.t_idx) if n else self.t_idx
        self.c_rows = as_index(self.c_idx) if n else self.c_idx

        def optional(query):
            k = np.full(n, -1, np.intp)
            for e, comps in query:
                k[index[e]] = comps[-1]._row
            sel = np.flatnonzero(k >= 0)
            return k, sel, (as_index(k[sel]) if len(sel) else k[sel])

        self.v_idx, self.v_sel, self.v_rows = optional(withv)
        self.m_idx, self.m_sel, self.m_rows = optional(withm)
        self.a_idx, self.a_sel, self.a_rows = optional(witha)
        self.all_v = len(self.v_sel) == n
        self.all_m = len(self.m_sel) == n


def _query():
    return (esper.get_components(Transform, SphereCollider),
            esper.get_components(Transform, SphereCollider, Velocity),
            esper.get_components(Transform, SphereCollider, Mass),
            esper.get_components(Transform, SphereCollider, Velocity, Acceleration))


class CollisionSystem(esper.Processor):
    """Reads Transform, Velocity, Acceleration, Mass, SphereCollider; writes Transform.position,
    Velocity.linear; appends CollisionEvent to world.events.  Elastic (or restitution-scaled)
    sphere impulses at the exact times of impact inside the step.

    ``method``: ``"continuous"`` (default; swept, time-ordered, waves of
    simultaneous contacts) or ``"articles"`` (the articles' discrete method,
    kept as a baseline). ``broadphase``: ``"auto"``, ``"all"`` (every pair every
    step), or the method the neighbour list is built with (``"grid"``,
    ``"sweep"``, ``"kdtree"``). ``skin_steps``: how many steps the neighbour
    list should last (see :class:`~framework.broadphase.NeighbourList`).
    ``events``: append a :class:`CollisionEvent` per contact.

    After each step ``stats`` holds counts: candidate pairs, contacts, waves,
    list builds, bodies swept against all.
    """

    stage = "collision"

    def __init__(self, method: str = "continuous", *, broadphase: str = "auto",
                 skin_steps: float = 8.0, events: bool = True):
        if method not in METHODS:
            raise ValueError(f"CollisionSystem.method must be one of {METHODS}, got {method!r}")
        if broadphase not in bp.METHODS:
            raise ValueError(f"CollisionSystem.broadphase must be one of {bp.METHODS}, got {broadphase!r}")
        if isinstance(skin_steps, bool) or not isinstance(skin_steps, (int, float)) or not skin_steps > 0 \
                or not math.isfinite(skin_steps):
            raise ValueError(f"CollisionSystem.skin_steps must be a finite number > 0, got {skin_steps!r}")
        self.method = method
        self.broadphase = broadphase
        self.events = bool(events)
        self.world = None
        self._layout: _Layout | None = None
        self._list = bp.NeighbourList(skin_steps, "grid" if broadphase in ("auto", "all") else broadphase)
        self._list_layout = None
        self._list_dirty = True
        self.stats = {"pairs": 0, "contacts": 0, "waves": 0, "builds": 0, "swept": 0}

    # -- bookkeeping ----------------------------------------------------------
    def _refresh(self) -> _Layout:
        q = _query()
        lay = self._layout
        if lay is None or any(a is not b for a, b in zip(q, lay.queries)):
            lay = self._layout = _Layout(q)
        return lay

    def _now(self) -> float:
        return self.world.time if self.world is not None else 0.0

    def process(self, dt: float) -> None:
        lay = self._refresh()
        for k in self.stats:
            self.stats[k] = 0
        if lay.n < 2:
            return
        if self.method == "articles":
            self._articles(lay, dt)
        else:
            self._continuous(lay, dt)

    # -- shared gathers -------------------------------------------------------
    def _velocities(self, lay: _Layout, dt: float) -> np.ndarray:
        """Path velocity u (n, 3): v1 for free bodies, v1 - a dt/2 (average over the step) with thrust."""
        vel = Velocity._table.data["linear"]
        if lay.all_v:
            u = np.array(vel[lay.v_rows])
        else:
            u = np.zeros((lay.n, 3))
            u[lay.v_sel] = vel[lay.v_rows]
        if len(lay.a_sel):
            u[lay.a_sel] -= (0.5 * dt) * Acceleration._table.data["linear"][lay.a_rows]
        return u

    def _inverse_mass(self, lay: _Layout) -> np.ndarray:
        """1/kg per collider: 0 for infinite mass or no Velocity; 1 (1 kg) with no Mass."""
        kg = Mass._table.data["kg"]
        if lay.all_m:
            inv = 1.0 / kg[lay.m_rows]
        else:
            inv = np.ones(lay.n)
            inv[lay.m_sel] = 1.0 / kg[lay.m_rows]
        if not lay.all_v:
            inv[lay.v_idx < 0] = 0.0
        return inv

    # -- continuous -----------------------------------------------------------
    def _continuous(self, lay: _Layout, dt: float) -> None:
        n = lay.n
        x1 = Transform._table.data["position"][lay.t_rows]
        u = self._velocities(lay, dt)
        us = np.ascontiguousarray(u.T)                       # (3, n): 1-D gathers are fast
        vmax = float(np.abs(us).max()) * math.sqrt(3.0)
        if vmax == 0.0:
            return                                           # nothing moves: nothing can approach
        x1 = x1.T
        xr = x1 - us * dt                                    # start of step; p(t) = xr + u t
        r = SphereCollider._table.data["radius"][lay.c_rows]
        inv = self._inverse_mass(lay)
        self._xr, self._us, self._r, self._inv, self._dt = xr, us, r, inv, dt
        self._eps_v = APPROACH * vmax
        self._static = not inv.all()
        self._keys = None

        # -- broad phase: candidate pairs --
        if self.broadphase == "all" or (self.broadphase == "auto" and n <= bp.ALL_PAIRS_MAX):
            I, J = bp._triu(n)
            R = r[I] + r[J]
            self._listed = False                             # every pair is a candidate already
        else:
            I, J, R = self._list_pairs(lay, xr, x1, r, dt)
            self._listed = True
        self._I, self._J, self._R = I, J, R
        self.stats["pairs"] = len(I)

        # -- narrow phase: earliest times of impact, then contacts in time order --
        ok, toi, slack = self._toi(I, J, R, 0.0)
        pend = np.flatnonzero(ok)
        if len(pend):
            self._resolve(lay, pend, toi[pend], slack[pend], dt)

    def _list_pairs(self, lay, xr, x1, r, dt):
        """Pairs from the neighbour list, plus the sweeps of the bodies it does not cover."""
        nl = self._list
        rebuild = (self._list_dirty or self._list_layout is not lay or len(nl.radius) != lay.n
                   or not np.array_equal(nl.radius, r))
        if not rebuild:
            # the straight path x0 -> x1 stays in the territory if both ends do (a ball is convex)
            stray = nl.strays(xr) | nl.strays(x1)
            if stray.any():
                nl.swept |= stray
                rebuild = int(np.count_nonzero(nl.swept)) > nl.budget
        if rebuild:
            us = self._us
            nl.build(xr, r, np.sqrt(us[0] * us[0] + us[1] * us[1] + us[2] * us[2]) * dt)
            self._list_layout = lay
            self._list_dirty = False
            self._list_R = r[nl.i] + r[nl.j]
            self._blo = np.empty((3, lay.n))                 # path boxes of swept bodies
            self._bhi = np.empty((3, lay.n))
            self.stats["builds"] = 1
        I, J, R = nl.i, nl.j, self._list_R
        sw = np.flatnonzero(nl.swept)
        if not len(sw):
            return I, J, R
        # the list no longer speaks for swept bodies: drop their listed pairs, sweep their paths
        keep = ~(nl.swept[I] | nl.swept[J])
        a, b = xr[:, sw], x1[:, sw]
        self._blo[:, sw] = np.minimum(a, b) - r[sw]
        self._bhi[:, sw] = np.maximum(a, b) + r[sw]
        si, sj = self._sweep_pairs(sw)
        self.stats["swept"] = len(sw)
        return (np.concatenate([I[keep], si]), np.concatenate([J[keep], sj]),
                np.concatenate([R[keep], r[si] + r[sj]]))

    def _sweep_pairs(self, which):
        """Pairs (i < j) of the swept bodies ``which`` with listed territories and with each other."""
        nl, blo, bhi = self._list, self._blo, self._bhi
        out_i, out_j = [], []
        for s in which:
            t = nl.territories(blo[:, s], bhi[:, s])
            out_i.append(np.full(len(t), s, np.intp))
            out_j.append(t)
        # swept against swept (box test): every swept body, the ones in `which` included
        sw = np.flatnonzero(nl.swept)
        if len(sw) > 1:
            a = np.repeat(which, len(sw))
            b = np.tile(sw, len(which))
            first = (a != b) & (~np.isin(b, which) | (a < b))     # each pair once
            a, b = bp._overlap(blo, bhi, a[first], b[first])
            out_i.append(a)
            out_j.append(b)
        if not out_i:
            return _NONE, _NONE
        i, j = np.concatenate(out_i), np.concatenate(out_j)
        return np.minimum(i, j), np.maximum(i, j)

    def _toi(self, I, J, R, t):
        """Earliest time of impact in [t, dt] of pairs moving as p = xr + u t'.

        Returns (valid, time, slack): ``slack`` is how long before its time of
        impact a pair is already within TOUCH * R, ``TOUCH R / |v_n|``.
        """
        xr, us = self._xr, self._us
        wx = us[0][J] - us[0][I]
        wy = us[1][J] - us[1][I]
        wz = us[2][J] - us[2][I]
        dx = xr[0][J] - xr[0][I]
        dy = xr[1][J] - xr[1][I]
        dz = xr[2][J] - xr[2][I]
        if t:
            dx += wx * t
            dy += wy * t
            dz += wz * t
        dd = dx * dx + dy * dy + dz * dz
        b = dx * wx + dy * wy + dz * wz                      # |d| times the normal relative velocity
        c = dd - R * R
        dist = np.sqrt(dd)
        # approaching; centres closer than CENTRED * R have no normal to push along: left alone
        approach = (b < -self._eps_v * dist) & (dist > CENTRED * R)
        touching = c <= (2.0 * TOUCH) * R * R                # gap <= TOUCH * R
        a = wx * wx + wy * wy + wz * wz
        disc = b * b - a * c
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            toi = t + c / (np.sqrt(np.maximum(disc, 0.0)) - b)
            slack = (TOUCH * R) * dist / -b
        toi[touching] = t
        ok = approach & (touching | (disc >= 0.0)) & (toi <= self._dt)
        if self._static:
            ok &= (self._inv[I] + self._inv[J]) > 0.0        # two immovable bodies pass through
        return ok, toi, slack

    def _resolve(self, lay, pend, pend_t, pend_s, dt):
        """Take the pending contacts in time order, one wave of simultaneous contacts at a time."""
        xr, us, inv = self._xr, self._us, self._inv
        n = lay.n
        changed = np.zeros(n, bool)
        mark = np.zeros(n, bool)
        e_col = SphereCollider._table.data["restitution"][lay.c_rows]
        waves = contacts = same = 0
        last_t = -1.0
        t0 = self._now()
        out = self.world.events if (self.events and self.world is not None) else None
        while len(pend):
            k = int(np.argmin(pend_t))
            t = float(pend_t[k])
            same = same + 1 if t == last_t else 0
            last_t = t
            if same > MAX_WAVES:
                warnings.warn(f"collision: more than {MAX_WAVES} waves at t = {t0 + t!r} s (a jam between "
                              f"immovable bodies?); {len(pend)} contacts left unresolved this step",
                              RuntimeWarning, stacklevel=3)
                break
            I, J, R = self._I, self._J, self._R
            # -- the wave: the pending pairs already within TOUCH * R at t (they approach: pending) --
            sel = np.flatnonzero(pend_t - t <= pend_s)
            if not len(sel):
                sel = np.array([k])
            pk = pend[sel]
            ci, cj = I[pk], J[pk]
            w = us[:, cj] - us[:, ci]
            d = xr[:, cj] - xr[:, ci] + w * t
            dist = np.sqrt((d * d).sum(axis=0))
            nrm = d / dist
            vn = (nrm * w).sum(axis=0)
            go = vn < -self._eps_v
            go[sel == k] = True
            if not go.all():
                ci, cj, nrm, vn = ci[go], cj[go], nrm[:, go], vn[go]
            e = np.minimum(e_col[ci], e_col[cj])
            lam, bodies, dv = _solve_wave(ci, cj, nrm, vn, e, inv)
            waves += 1
            hit = lam > 0.0
            contacts += int(np.count_nonzero(hit))
            if out is not None:
                self._emit(out, lay, ci[hit], cj[hit], nrm[:, hit], lam[hit], t, t0)
            # -- the bodies that changed: new velocity from t on, position at t kept --
            moved = bodies
            for ax in range(3):                               # p(t) = xr + u t stays where it was
                us[ax][moved] += dv[ax]
                xr[ax][moved] -= dv[ax] * t
            changed[moved] = True
            # -- re-check every pair of those bodies from t on --
            mark[moved] = True
            keep = ~(mark[I[pend]] | mark[J[pend]])
            aff = np.flatnonzero(mark[I] | mark[J])
            mark[moved] = False
            ok, toi, slack = self._toi(I[aff], J[aff], R[aff], t)
            pend = np.concatenate([pend[keep], aff[ok]])
            pend_t = np.concatenate([pend_t[keep], toi[ok]])
            pend_s = np.concatenate([pend_s[keep], slack[ok]])
            # -- a body whose new path leaves what the broad phase covered: sweep it against all --
            if self._listed:
                new, new_t, new_s = self._extend(moved, t, dt)
                if len(new):
                    pend = np.concatenate([pend, new])
                    pend_t = np.concatenate([pend_t, new_t])
                    pend_s = np.concatenate([pend_s, new_s])
        self.stats["waves"] = waves
        self.stats["contacts"] = contacts
        # -- write back the bodies that changed: position and velocity at the end of the step --
        ch = np.flatnonzero(changed)
        if len(ch):
            x_end = (xr[:, ch] + us[:, ch] * dt).T
            v_end = us[:, ch].T.copy()
            if len(lay.a_sel):
                acc = lay.a_idx[ch]
                thrust = acc >= 0
                if thrust.any():                              # give back the a dt/2 of the average
                    v_end[thrust] += (0.5 * dt) * Acceleration._table.data["linear"][acc[thrust]]
            Transform._table.data["position"][lay.t_idx[ch]] = x_end
            Velocity._table.data["linear"][lay.v_idx[ch]] = v_end

    def _extend(self, moved, t, dt):
        """Sweep the changed bodies whose rest-of-step path left their cover; new (pending, toi, slack)."""
        nl = self._list
        xr, us, r = self._xr, self._us, self._r
        b = xr[:, moved] + us[:, moved] * dt                  # where the body now ends the step
        swept = nl.swept[moved]
        out = np.zeros(len(moved), bool)
        listed = ~swept
        if listed.any():                                      # listed: covered while inside its territory
            out[listed] = nl.strays(b[:, listed], moved[listed])
        a = xr[:, moved] + us[:, moved] * t
        nlo = np.minimum(a, b) - r[moved]
        nhi = np.maximum(a, b) + r[moved]
        if swept.any():                                       # swept: covered while inside its box
            m = moved[swept]
            out[swept] = ~np.all((nlo[:, swept] >= self._blo[:, m]) & (nhi[:, swept] <= self._bhi[:, m]),
                                 axis=0)
        if not out.any():
            return _NONE, _NONE_T, _NONE_T
        go = moved[out]
        self._blo[:, go] = nlo[:, out]
        self._bhi[:, go] = nhi[:, out]
        nl.swept[go] = True
        if int(np.count_nonzero(nl.swept)) > nl.budget:
            self._list_dirty = True                           # rebuild at the next step
        self.stats["swept"] += len(go)
        fi, fj = self._sweep_pairs(go)
        if not len(fi):
            return _NONE, _NONE_T, _NONE_T
        I, J, R = self._I, self._J, self._R
        nb = np.int64(len(r))
        if self._keys is None:
            self._keys = I.astype(np.int64) * nb + J
        new_keys = fi.astype(np.int64) * nb + fj
        fresh = ~np.isin(new_keys, self._keys)
        fi, fj = fi[fresh], fj[fresh]
        if not len(fi):
            return _NONE, _NONE_T, _NONE_T
        base = len(I)
        fR = r[fi] + r[fj]
        self._I = np.concatenate([I, fi])
        self._J = np.concatenate([J, fj])
        self._R = np.concatenate([R, fR])
        self._keys = np.concatenate([self._keys, new_keys[fresh]])
        ok, toi, slack = self._toi(fi, fj, fR, t)
        return base + np.flatnonzero(ok), toi[ok], slack[ok]

    def _emit(self, out, lay, ci, cj, nrm, lam, t, t0):
        """One CollisionEvent per contact (a Python loop over contacts that happened: few)."""
        ents = lay.entities
        p = (self._xr[:, ci] + self._us[:, ci] * t + self._r[ci] * nrm).T.tolist()   # on i's surface
        q = (self._xr[:, cj] + self._us[:, cj] * t - self._r[cj] * nrm).T.tolist()   # on j's surface
        for a, b, n, pa, pb, imp in zip(ents[ci].tolist(), ents[cj].tolist(), nrm.T.tolist(), p, q,
                                        lam.tolist()):
            if a < b:
                out.append(CollisionEvent(a, b, t0 + t, t, tuple(pa), tuple(n), imp))
            else:                                          # name the lower entity id first
                out.append(CollisionEvent(b, a, t0 + t, t, tuple(pb), (-n[0], -n[1], -n[2]), imp))

    # -- the articles' method (baseline) --------------------------------------
    def _articles(self, lay: _Layout, dt: float) -> None:
        pos_t = Transform._table.data["position"]
        vel_t = Velocity._table.data["linear"]
        x = pos_t[lay.t_idx].tolist()
        v = np.zeros((lay.n, 3))
        v[lay.v_sel] = vel_t[lay.v_idx[lay.v_sel]]
        v = v.tolist()
        inv = self._inverse_mass(lay).tolist()
        r = SphereCollider._table.data["radius"][lay.c_idx].tolist()
        ents = lay.entities.tolist()
        n = lay.n
        touched = set()
        out = self.world.events if (self.events and self.world is not None) else None
        t0 = self._now()
        count = 0
        for i in range(n):
            xi, ri = x[i], r[i]
            for j in range(i + 1, n):
                xj = x[j]
                dx, dy, dz = xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]
                R = ri + r[j]
                if dx * dx + dy * dy + dz * dz >= R * R:
                    continue
                if inv[i] == 0.0 and inv[j] == 0.0:
                    continue
                vi, vj = v[i], v[j]
                # move both back along their velocities until |d - w s| = R (the positive root s)
                wx, wy, wz = vj[0] - vi[0], vj[1] - vi[1], vj[2] - vi[2]
                a = wx * wx + wy * wy + wz * wz
                s = 0.0
                if a > 0.0:
                    b = dx * wx + dy * wy + dz * wz
                    c = dx * dx + dy * dy + dz * dz - R * R
                    s = (b + math.sqrt(max(b * b - a * c, 0.0))) / a
                for p, q in ((xi, vi), (xj, vj)):
                    p[0] -= q[0] * s
                    p[1] -= q[1] * s
                    p[2] -= q[2] * s
                dx, dy, dz = xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]
                dist = math.sqrt(dx * dx + dy * dy + dz * dz) or 1.0
                nx, ny, nz = dx / dist, dy / dist, dz / dist
                # centre-of-mass velocity (an immovable body is the centre-of-mass frame)
                wi, wj = inv[j], inv[i]                       # m_i/(m_i+m_j) = inv_j/(inv_i+inv_j)
                tot = wi + wj
                cm = [(wi * vi[k] + wj * vj[k]) / tot for k in range(3)]
                for q in (vi, vj):
                    rel = [q[k] - cm[k] for k in range(3)]
                    dot = rel[0] * nx + rel[1] * ny + rel[2] * nz
                    q[0] = cm[0] + rel[0] - 2.0 * nx * dot
                    q[1] = cm[1] + rel[1] - 2.0 * ny * dot
                    q[2] = cm[2] + rel[2] - 2.0 * nz * dot
                touched.update((i, j))
                count += 1
                if out is not None:
                    a_, b_, sign = (i, j, 1.0) if ents[i] < ents[j] else (j, i, -1.0)
                    nn = (sign * nx, sign * ny, sign * nz)
                    pa = x[a_]
                    m_i = 0.0 if inv[i] == 0.0 else 1.0 / inv[i]
                    imp = abs(2.0 * dot) * (1.0 / (inv[i] + inv[j])) if m_i else 0.0
                    out.append(CollisionEvent(ents[a_], ents[b_], t0 + dt - s, dt - s,
                                              (pa[0] + r[a_] * nn[0], pa[1] + r[a_] * nn[1], pa[2] + r[a_] * nn[2]),
                                              nn, imp, "articles"))
        self.stats["pairs"] = n * (n - 1) // 2
        self.stats["contacts"] = count
        if touched:
            idx = np.fromiter(sorted(touched), np.intp)
            xs = np.array(x)[idx]
            vs = np.array(v)[idx]
            pos_t[lay.t_idx[idx]] = xs
            has_v = lay.v_idx[idx] >= 0
            vel_t[lay.v_idx[idx[has_v]]] = vs[has_v]


def _solve_wave(ci, cj, nrm, v_n, e, inv):
    """Impulses of one wave of simultaneous contacts.

    ``ci, cj``: body indices of each contact; ``nrm`` (3, K): unit normals i -> j;
    ``v_n``: normal relative velocities (< 0, approaching); ``e``: restitution;
    ``inv``: inverse masses of all bodies. Returns ``lambda`` (K,), the bodies
    that move (B,) and their velocity changes (3, B).

    Solves ``A lambda = -(1 + e) v_n`` with ``A = J M^-1 J^T``; contacts whose
    impulse comes out negative (they would pull) are dropped and the rest
    solved again, until all are >= 0. For one contact this is the textbook
    ``lambda = -(1 + e) v_n / (1/m_i + 1/m_j)``.
    """
    rhs = -(1.0 + e) * v_n
    K = len(ci)
    if K == 1:
        i, j = int(ci[0]), int(cj[0])
        lam = rhs / (inv[i] + inv[j])
        bodies = np.array([i, j])
        dv = nrm * (lam * np.array([-inv[i], inv[j]]))    # (3, 2)
    else:
        bodies, loc = np.unique(np.concatenate([ci, cj]), return_inverse=True)
        li, lj = loc[:K], loc[K:]
        invb = inv[bodies]
        jac = np.zeros((K, len(bodies), 3))
        rows = np.arange(K)
        jac[rows, li] = -nrm.T
        jac[rows, lj] = nrm.T
        A = np.einsum("kbx,b,lbx->kl", jac, invb, jac)
        active = np.ones(K, bool)
        lam = np.zeros(K)
        while active.any():
            idx = np.flatnonzero(active)
            sol = np.linalg.lstsq(A[np.ix_(idx, idx)], rhs[idx], rcond=None)[0]
            if (sol >= 0.0).all():
                lam[idx] = sol
                break
            active[idx[sol < 0.0]] = False
        dv = np.einsum("kbx,k->xb", jac, lam) * invb          # dv_b = inv_m_b sum_k lambda_k J_kb
    live = np.any(dv != 0.0, axis=0)                         # immovable bodies do not change
    if not live.all():
        bodies, dv = bodies[live], dv[:, live]
    return lam, bodies, dv
