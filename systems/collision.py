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
c))`` with ``a = w.w``, ``b = d.w``, ``c = d.d - R^2`` so nothing cancels,
and solved once more from the pair's positions at that estimate (``c`` loses
digits when a fast pair starts many radii apart). Contacts are taken in time
order. At the earliest instant ``t*``, every pair
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
on the order of entities. (A sphere wedged between immovable ones has no
elastic answer and would bounce forever in no time: after
``JAM_WAVES + 4 n`` waves at one instant the rest of it is resolved with
``e = 0``, with a warning.) Pairs that overlap (at spawn, or by rounding) but
separate are left alone: they never stick, and no position is ever moved
except by velocity times time, so nothing jumps.

Broad phase: every pair up to :data:`framework.broadphase.ALL_PAIRS_MAX`
bodies (measured faster there); above that a
:class:`~framework.broadphase.NeighbourList` built with the uniform grid and
kept for several steps. A body that leaves its territory (between steps, or
when a contact sends it off) is *swept*: its path box is tested against the
others' territories for the rest of the list's life, and the list is rebuilt
once more than a few bodies are swept. Only the contacts that happen are
visited in a Python loop; pairs are never looped over.

**The articles' method** (``method="articles"``, a labelled baseline): after
the step, for every pair in turn (a Python double loop, in entity order),
if the spheres overlap, move both back along their velocities until the
centres are ``r_a + r_b`` apart, and reflect each velocity about the contact
normal in the centre-of-mass frame (``v' = v - 2 n (n.v)``). As written
there: it only sees overlaps at the end of a step (fast spheres pass through
each other), the remaining time of the step is not re-advanced, pairs are
handled one after another (so a break depends on the order of entities), and
it does not ask whether an overlapping pair approaches: a pair that overlaps
while separating (spawned so, or left so by rounding) is "moved back" through
each other to the far side, a jump.

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

from driftframe.components.body import Acceleration, Mass, Transform, Velocity
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.framework import broadphase as bp
from driftframe.framework.store import as_index

METHODS = ("continuous", "articles")

#: Pairs closer than this fraction of r_a + r_b are touching (contact "now").
TOUCH = 1e-9
#: Normal approach speeds below this fraction of the fastest body's speed are rounding noise.
APPROACH = 1e-12
#: Centres closer than this fraction of r_a + r_b define no contact normal: such a pair is left to pass.
CENTRED = 1e-9
#: Waves at one instant before it is treated as a jam (a sphere wedged between immovable bodies
#: bounces between them forever in no time): JAM_WAVES + 4 per body, then the rest of that instant
#: is resolved with e = 0 (no bounce), which ends it; MAX_WAVES is the last guard.
JAM_WAVES = 1_000
MAX_WAVES = 100_000

_NONE = np.empty(0, np.intp)
_NO_T = np.empty(0)


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
    reads = (Transform, Velocity, Acceleration, Mass, SphereCollider)
    writes = (Transform, Velocity)

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
        # esper drops *every* cached query list when any entity or component changes, so the
        # base query's list object alone tells whether the optional ones may have changed too
        lay = self._layout
        if lay is None or esper.get_components(Transform, SphereCollider) is not lay.queries[0]:
            lay = self._layout = _Layout(_query())
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
        """Path velocity u as (3, n): v1 for free bodies, v1 - a dt/2 (the step's average) with thrust."""
        vel = self.world.table(Velocity).data["linear"]
        if lay.all_v and not len(lay.a_sel):
            return np.ascontiguousarray(vel[lay.v_rows].T)   # a copy: the solver changes it
        u = np.zeros((lay.n, 3))
        u[lay.v_sel] = vel[lay.v_rows]
        if len(lay.a_sel):
            u[lay.a_sel] -= (0.5 * dt) * self.world.table(Acceleration).data["linear"][lay.a_rows]
        return np.ascontiguousarray(u.T)

    def _inverse_mass(self, lay: _Layout) -> np.ndarray:
        """1/kg per collider: 0 for infinite mass or no Velocity; 1 (1 kg) with no Mass."""
        kg = self.world.table(Mass).data["kg"]
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
        x1 = self.world.table(Transform).data["position"][lay.t_rows]
        us = self._velocities(lay, dt)                       # (3, n): 1-D gathers are fast
        vmax = max(float(us.max()), -float(us.min())) * math.sqrt(3.0)   # >= the fastest speed
        if vmax == 0.0:
            return                                           # nothing moves: nothing can approach
        x1 = x1.T
        xr = x1 - us * dt                                    # start of step; p(t) = xr + u t
        r = self.world.table(SphereCollider).data["radius"][lay.c_rows]
        inv = self._inverse_mass(lay)
        self._xr, self._us, self._r, self._inv, self._dt = xr, us, r, inv, dt
        self._eps_v = APPROACH * vmax
        self._static = not inv.all()
        self._e = self.world.table(SphereCollider).data["restitution"][lay.c_rows]

        # -- broad phase: candidate pairs --
        if self.broadphase == "all" or (self.broadphase == "auto" and n <= bp.ALL_PAIRS_MAX):
            self._listed = False                             # every pair is a candidate already
            I, J = bp._triu(n)
            self._adj = _triu_adjacency(n)
            self._I, self._J, self._R = I, J, r[I] + r[J]
            self._base = len(I)                              # pairs past this were added this step
        else:
            self._listed = True
            self._list_pairs(lay, xr, x1, r, dt)
        self.stats["pairs"] = len(self._I)

        # -- narrow phase: earliest times of impact, then contacts in time order --
        pend, toi, slack = self._toi(self._I, self._J, self._R, 0.0)
        if len(pend):
            self._resolve(lay, pend, toi, slack, dt)

    def _list_pairs(self, lay, xr, x1, r, dt):
        """Pairs from the neighbour list, plus this step's sweeps of the bodies it does not cover."""
        nl = self._list
        rebuild = (self._list_dirty or self._list_layout is not lay or len(nl.radius) != lay.n
                   or not np.array_equal(nl.radius, r))
        if not rebuild:
            # the straight path x0 -> x1 stays in the territory if both ends do (a ball is convex)
            stray = nl.strays(xr, x1)
            if stray.any():
                nl.swept |= stray
                rebuild = int(np.count_nonzero(nl.swept)) > nl.budget
        if rebuild:
            us = self._us
            nl.build(xr, r, np.sqrt(us[0] * us[0] + us[1] * us[1] + us[2] * us[2]) * dt)
            self._list_layout = lay
            self._list_dirty = False
            self._list_R = r[nl.i] + r[nl.j]
            self._list_adj = _adjacency(nl.i, nl.j, lay.n)
            self._blo = np.empty((3, lay.n))                 # path boxes of swept bodies
            self._bhi = np.empty((3, lay.n))
            self.stats["builds"] = 1
        self._I, self._J, self._R = nl.i, nl.j, self._list_R
        self._adj = self._list_adj
        self._base = len(nl.i)                               # pairs past this were added this step
        sw = np.flatnonzero(nl.swept)
        if len(sw):
            # the list no longer speaks for swept bodies (their listed pairs stay: a superset):
            # sweep their paths against the territories and each other
            a, b = xr[:, sw], x1[:, sw]
            self._blo[:, sw] = np.minimum(a, b) - r[sw]
            self._bhi[:, sw] = np.maximum(a, b) + r[sw]
            self._add_pairs(*self._sweep_pairs(sw), sw)
            self.stats["swept"] = len(sw)

    def _sweep_pairs(self, which):
        """Pairs of the swept bodies ``which`` with listed territories and with each other (may repeat)."""
        nl, blo, bhi = self._list, self._blo, self._bhi
        out_i, out_j = [_NONE], [_NONE]
        for s in which:
            t = nl.territories(blo[:, s], bhi[:, s])
            out_i.append(np.full(len(t), s, np.intp))
            out_j.append(t)
        sw = np.flatnonzero(nl.swept)
        if len(sw) > 1:                                      # swept against swept: box test
            a = np.repeat(which, len(sw))
            b = np.tile(sw, len(which))
            a, b = bp._overlap(blo, bhi, a[a != b], b[a != b])
            out_i.append(a)
            out_j.append(b)
        return np.concatenate(out_i), np.concatenate(out_j)

    def _pairs_of(self, k: int) -> np.ndarray:
        """Indices of this step's candidate pairs that involve body k."""
        first, pairs = self._adj
        own = pairs[first[k]:first[k + 1]]
        base = self._base
        if len(self._I) == base:
            return own
        extra = base + np.flatnonzero((self._I[base:] == k) | (self._J[base:] == k))
        return np.concatenate([own, extra])

    def _add_pairs(self, fi, fj, which) -> np.ndarray:
        """Append the pairs (fi, fj) that are not candidates yet; return their indices.

        Every pair involves a body of ``which``, so only those bodies' pairs are
        looked up; the rest is whole-array work.
        """
        if not len(fi):
            return _NONE
        n = np.int64(len(self._r))
        keys = np.unique(np.minimum(fi, fj).astype(np.int64) * n + np.maximum(fi, fj))
        have = np.concatenate([self._pairs_of(int(k)) for k in which])
        keys = keys[~np.isin(keys, self._I[have].astype(np.int64) * n + self._J[have])]
        if not len(keys):
            return _NONE
        ni, nj = (keys // n).astype(np.intp), (keys % n).astype(np.intp)
        start = len(self._I)
        self._I = np.concatenate([self._I, ni])
        self._J = np.concatenate([self._J, nj])
        self._R = np.concatenate([self._R, self._r[ni] + self._r[nj]])
        return np.arange(start, start + len(keys))

    def _toi(self, I, J, R, t):
        """Earliest times of impact in [t, dt] of pairs moving as p = xr + u t' (whole arrays).

        Returns (which, time, slack) for the pairs that meet: their positions
        in I, J; when; and ``slack``, how long before that time the pair is
        already within TOUCH * R (``TOUCH R / |v_n|``).
        """
        xr, us = self._xr, self._us
        # per-axis 1-D gathers: several times faster than gathering columns of the (3, n) arrays
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
        a = wx * wx + wy * wy + wz * wz
        RR = R * R
        c = dd - RR
        dist = np.sqrt(dd)
        # approaching; centres closer than CENTRED * R have no normal to push along: left alone
        ok = (b < -self._eps_v * dist) & (dist > CENTRED * R)
        touching = c <= (2.0 * TOUCH) * RR                   # gap <= TOUCH * R
        disc = b * b - a * c
        ok &= touching | (disc >= 0.0)
        if self._static:
            ok &= (self._inv[I] + self._inv[J]) > 0.0        # two immovable bodies pass through
        idx = np.flatnonzero(ok)
        if not len(idx):
            return idx, _NO_T, _NO_T
        b, c, disc, dist, R = b[idx], c[idx], disc[idx], dist[idx], R[idx]
        # b < 0 here, so the denominator is > 0; touching pairs are in contact now
        h = c / (np.sqrt(np.maximum(disc, 0.0)) - b)
        touch = touching[idx]
        # c = |d|^2 - R^2 keeps ~eps |d|^2 / R^2 of relative error: for a pair that starts more than
        # 4 R apart (a fast one: 100 m at 10 km/s) solve once more from where it is at the estimate
        far = np.flatnonzero(dist > 4.0 * R)
        if len(far):
            h[far] += self._toi_refine(I[idx[far]], J[idx[far]], R[far], t + h[far])
        toi = np.where(touch, t, np.maximum(t + h, t))       # (never before now, whatever rounding)
        keep = toi <= self._dt
        if not keep.all():
            idx, toi, b, dist, R = idx[keep], toi[keep], b[keep], dist[keep], R[keep]
        return idx, toi, (TOUCH * R) * dist / -b

    def _toi_refine(self, I, J, R, t):
        """Correction to estimated impact times ``t``: the root of ``|d(t) + w h|^2 = R^2`` nearest 0."""
        xr, us = self._xr, self._us
        w = us[:, J] - us[:, I]
        d = xr[:, J] - xr[:, I] + w * t
        c = (d * d).sum(axis=0) - R * R
        b = (d * w).sum(axis=0)
        a = (w * w).sum(axis=0)
        disc = np.maximum(b * b - a * c, 0.0)
        # h = c / (-b + sqrt(disc)), the root nearest 0 while approaching; no cancellation. A grazing
        # pair (b ~ 0 at contact) has nothing to refine: keep the estimate
        den = np.sqrt(disc) - b
        return np.divide(c, den, out=np.zeros_like(c), where=den > 0.0)

    def _resolve(self, lay, pend, pend_t, pend_s, dt):
        """Take the pending contacts in time order, one wave of simultaneous contacts at a time.

        The loop runs once per wave, over the contacts that happen (few, in
        plain floats: numpy's per-call cost would dominate arrays this small);
        the pairs of the bodies a wave changed are re-checked as one array
        (:meth:`_toi`), so no Python loop runs over candidate pairs.
        """
        xr, us, inv, I, J = self._xr, self._us, self._inv, self._I, self._J
        state: dict[int, list[float]] = {}                   # body -> [xr, u] as floats, as touched

        def body(k):
            s = state.get(k)
            if s is None:
                s = state[k] = [*xr[:, k].tolist(), *us[:, k].tolist()]
            return s

        pending = {p: (t, sl, i, j, R) for p, t, sl, i, j, R in
                   zip(pend.tolist(), pend_t.tolist(), pend_s.tolist(), I[pend].tolist(), J[pend].tolist(),
                       self._R[pend].tolist())}
        changed = set()
        waves = contacts = same = 0
        last_t = -1.0
        jam_after = JAM_WAVES + 4 * lay.n
        t0 = self._now()
        out = self.world if (self.events and self.world is not None) else None
        while pending:
            first = min(pending, key=lambda p: pending[p][0])
            t = pending[first][0]
            same = same + 1 if t == last_t else 0
            last_t = t
            jam = same > jam_after
            if same == jam_after + 1:
                warnings.warn(f"collision: {jam_after} waves at t = {t0 + t!r} s without an end (bodies jammed "
                              f"between immovable ones?); the rest of this instant is resolved without bounce "
                              f"(e = 0)", RuntimeWarning, stacklevel=3)
            if same > MAX_WAVES:
                warnings.warn(f"collision: more than {MAX_WAVES} waves at t = {t0 + t!r} s; {len(pending)} "
                              f"contacts left unresolved this step", RuntimeWarning, stacklevel=3)
                break
            # -- the wave: pending pairs already within TOUCH * R at t, still approaching --
            wave, wave_p = [], []
            for p, (tp, sl, i, j, R) in pending.items():
                if tp - t > sl:
                    continue
                bi, bj = body(i), body(j)
                wx, wy, wz = bj[3] - bi[3], bj[4] - bi[4], bj[5] - bi[5]
                dx = bj[0] - bi[0] + wx * t
                dy = bj[1] - bi[1] + wy * t
                dz = bj[2] - bi[2] + wz * t
                dist = math.sqrt(dx * dx + dy * dy + dz * dz)
                nx, ny, nz = dx / dist, dy / dist, dz / dist
                vn = nx * wx + ny * wy + nz * wz
                if vn < -self._eps_v:
                    e = 0.0 if jam else min(float(self._e[i]), float(self._e[j]))
                    wave.append((i, j, nx, ny, nz, vn, e))
                    wave_p.append(p)
            if not wave:                                      # rounding: the first no longer approaches
                del pending[first]
                continue
            lam, dv = _solve_wave(wave, inv)
            waves += 1
            # -- apply: new velocity from t on; p(t) = xr + u t stays where it was --
            moved = []
            for k, (dvx, dvy, dvz) in dv.items():
                s = body(k)
                s[3] += dvx
                s[4] += dvy
                s[5] += dvz
                s[0] -= dvx * t
                s[1] -= dvy * t
                s[2] -= dvz * t
                xr[0, k], xr[1, k], xr[2, k] = s[0], s[1], s[2]   # the arrays too: _toi reads them
                us[0, k], us[1, k], us[2, k] = s[3], s[4], s[5]
                moved.append(k)
            changed.update(moved)
            hit = [(c, l) for c, l in zip(wave, lam) if l > 0.0]
            contacts += len(hit)
            if out is not None:
                self._emit(out, lay, hit, body, t, t0)
            if not moved:
                continue
            # -- re-check every pair of the bodies that changed, from t on (one array operation) --
            gone = set(moved)
            pending = {p: e for p, e in pending.items() if e[2] not in gone and e[3] not in gone}
            aff = [self._pairs_of(k) for k in moved]
            if self._listed:                                  # and the pairs of a body that left its cover
                aff.append(self._extend(moved, body, t, dt))
            aff = np.concatenate(aff)                         # (a pair of two moved bodies comes twice)
            # a lone contact that took its impulse now separates (v_n' = -e v_n >= 0, exactly): no need
            # to look at it again. (A wave of several is re-checked whole: its solve may be least squares.)
            if len(wave) == 1 and lam[0] > 0.0:
                aff = aff[aff != wave_p[0]]
                if not len(aff):
                    continue
            found, toi, slack = self._toi(self._I[aff], self._J[aff], self._R[aff], t)
            if len(found):
                hit_p = aff[found]
                for p, tp, sl, i, j, R in zip(hit_p.tolist(), toi.tolist(), slack.tolist(),
                                              self._I[hit_p].tolist(), self._J[hit_p].tolist(),
                                              self._R[hit_p].tolist()):
                    pending[p] = (tp, sl, i, j, R)
        self.stats["waves"] = waves
        self.stats["contacts"] = contacts
        # -- write back the bodies that changed: position and velocity at the end of the step --
        if changed:
            ch = np.array(sorted(changed), np.intp)
            x_end = (xr[:, ch] + us[:, ch] * dt).T
            v_end = us[:, ch].T.copy()
            if len(lay.a_sel):
                acc = lay.a_idx[ch]
                thrust = acc >= 0
                if thrust.any():                              # give back the a dt/2 of the average
                    v_end[thrust] += (0.5 * dt) * self.world.table(Acceleration).data["linear"][acc[thrust]]
            self.world.table(Transform).data["position"][lay.t_idx[ch]] = x_end
            self.world.table(Velocity).data["linear"][lay.v_idx[ch]] = v_end

    def _extend(self, moved, body, t, dt) -> np.ndarray:
        """Sweep the changed bodies whose rest-of-step path left their cover; the new pairs."""
        nl, r = self._list, self._r
        go = []
        for k in moved:
            s = body(k)
            b = (s[0] + s[3] * dt, s[1] + s[4] * dt, s[2] + s[5] * dt)   # where it now ends the step
            swept = nl.swept[k]
            if not swept:                                    # listed: covered inside its territory
                c = nl.centre[:, k].tolist()
                if (b[0] - c[0]) ** 2 + (b[1] - c[1]) ** 2 + (b[2] - c[2]) ** 2 < float(nl.skin[k]) ** 2:
                    continue
            a = (s[0] + s[3] * t, s[1] + s[4] * t, s[2] + s[5] * t)
            rk = float(r[k])
            lo = [min(a[x], b[x]) - rk for x in range(3)]
            hi = [max(a[x], b[x]) + rk for x in range(3)]
            if swept and all(lo[x] >= self._blo[x, k] and hi[x] <= self._bhi[x, k] for x in range(3)):
                continue                                     # swept: covered inside its box
            self._blo[:, k] = lo
            self._bhi[:, k] = hi
            nl.swept[k] = True
            go.append(k)
        if not go:
            return _NONE
        if int(np.count_nonzero(nl.swept)) > nl.budget:
            self._list_dirty = True                          # rebuild at the next step
        self.stats["swept"] += len(go)
        go = np.array(go, np.intp)
        return self._add_pairs(*self._sweep_pairs(go), go)

    def _emit(self, out, lay, hit, body, t, t0):
        """One CollisionEvent per contact (a Python loop over contacts that happened: few)."""
        ents, r = lay.entities, self._r
        for (i, j, nx, ny, nz, _, _), lam in hit:
            a, b = int(ents[i]), int(ents[j])
            if a > b:                                         # name the lower entity id first
                i, j, a, b, nx, ny, nz = j, i, b, a, -nx, -ny, -nz
            s, ri = body(i), float(r[i])
            point = (s[0] + s[3] * t + ri * nx, s[1] + s[4] * t + ri * ny, s[2] + s[5] * t + ri * nz)
            out.emit(CollisionEvent(a, b, t0 + t, t, point, (nx, ny, nz), lam, step=self.world.step_count))

    # -- the articles' method (baseline) --------------------------------------
    def _articles(self, lay: _Layout, dt: float) -> None:
        pos_t = self.world.table(Transform).data["position"]
        vel_t = self.world.table(Velocity).data["linear"]
        x = pos_t[lay.t_idx].tolist()
        v = np.zeros((lay.n, 3))
        v[lay.v_sel] = vel_t[lay.v_idx[lay.v_sel]]
        v = v.tolist()
        inv = self._inverse_mass(lay).tolist()
        r = self.world.table(SphereCollider).data["radius"][lay.c_idx].tolist()
        ents = lay.entities.tolist()
        n = lay.n
        touched = set()
        out = self.world if (self.events and self.world is not None) else None
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
                impulse = 2.0 * abs(wx * nx + wy * ny + wz * nz) / (inv[i] + inv[j])   # |m_j dv_j|, N s
                # centre-of-mass velocity, weights m_i/(m_i+m_j) = inv_j/(inv_i+inv_j) (an immovable
                # body is the centre-of-mass frame)
                ki, kj = inv[j], inv[i]
                tot = ki + kj
                cm = [(ki * vi[k] + kj * vj[k]) / tot for k in range(3)]
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
                    out.emit(CollisionEvent(ents[a_], ents[b_], t0 + dt - s, dt - s,
                                            (pa[0] + r[a_] * nn[0], pa[1] + r[a_] * nn[1], pa[2] + r[a_] * nn[2]),
                                            nn, impulse, "articles", step=self.world.step_count))
        self.stats["pairs"] = n * (n - 1) // 2
        self.stats["contacts"] = count
        if touched:
            idx = np.fromiter(sorted(touched), np.intp)
            xs = np.array(x)[idx]
            vs = np.array(v)[idx]
            pos_t[lay.t_idx[idx]] = xs
            has_v = lay.v_idx[idx] >= 0
            vel_t[lay.v_idx[idx[has_v]]] = vs[has_v]


def _adjacency(I: np.ndarray, J: np.ndarray, n: int):
    """Pairs by body (CSR): the pairs of body b are ``pairs[first[b]:first[b + 1]]``."""
    ends = np.concatenate([I, J])
    order = np.argsort(ends, kind="stable")
    first = np.zeros(n + 1, np.intp)
    np.cumsum(np.bincount(ends, minlength=n), out=first[1:])
    return first, order % max(len(I), 1)


_TRIU_ADJ: dict[int, tuple] = {}


def _triu_adjacency(n: int):
    got = _TRIU_ADJ.get(n)
    if got is None:
        got = _TRIU_ADJ[n] = _adjacency(*bp._triu(n), n)
    return got


def _solve_wave(wave, inv):
    """Impulses of one wave of simultaneous contacts.

    ``wave``: contacts ``(i, j, nx, ny, nz, v_n, e)`` with the unit normal from
    body i to body j, the normal relative velocity ``v_n < 0`` (approaching)
    and the restitution ``e``; ``inv``: inverse masses. Returns the impulses
    ``lambda`` (one per contact) and ``{body: velocity change}`` for the
    bodies that move.

    Solves ``A lambda = -(1 + e) v_n`` with ``A = J M^-1 J^T`` (J: one row per
    contact, ``-n`` at body i and ``+n`` at body j); contacts whose impulse
    comes out negative (they would pull) are dropped and the rest solved
    again, until all are >= 0. For one contact this is the textbook
    ``lambda = -(1 + e) v_n / (1/m_i + 1/m_j)``.
    """
    if len(wave) == 1:
        i, j, nx, ny, nz, vn, e = wave[0]
        wi, wj = float(inv[i]), float(inv[j])
        lam = -(1.0 + e) * vn / (wi + wj)
        dv = {}
        if wi:
            dv[i] = (-lam * wi * nx, -lam * wi * ny, -lam * wi * nz)
        if wj:
            dv[j] = (lam * wj * nx, lam * wj * ny, lam * wj * nz)
        return [lam], dv
    K = len(wave)
    ci = np.array([c[0] for c in wave])
    cj = np.array([c[1] for c in wave])
    nrm = np.array([c[2:5] for c in wave])                  # (K, 3)
    rhs = -(1.0 + np.array([c[6] for c in wave])) * np.array([c[5] for c in wave])
    bodies, loc = np.unique(np.concatenate([ci, cj]), return_inverse=True)
    li, lj = loc[:K], loc[K:]
    invb = inv[bodies]
    jac = np.zeros((K, len(bodies), 3))
    rows = np.arange(K)
    jac[rows, li] = -nrm
    jac[rows, lj] = nrm
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
    dv = np.einsum("kbx,k->bx", jac, lam) * invb[:, None]   # dv_b = inv_m_b sum_k lambda_k J_kb
    moves = np.any(dv != 0.0, axis=1)
    return lam.tolist(), {int(b): tuple(d) for b, d, m in zip(bodies, dv.tolist(), moves) if m}
