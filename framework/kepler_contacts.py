"""When paths on conics meet: a conic reaching a radius (:func:`time_to_radius`), two bodies coming
within a distance (:func:`time_to_touch`, :func:`time_to_touch_paths`), and the swept boxes and bounds
that prune the pairs (:func:`arc_boxes`)."""
from __future__ import annotations

import numpy as np

from driftframe.framework.kepler_elements import _mean_anomaly_e, elements
from driftframe.framework.kepler_kernels import _arc_boxes_compiled
from driftframe.framework.kepler_universal import _EPS, TWO_PI, Epoch, _dot, _norm, propagate


def time_to_radius(r, v, mu, radius, horizon, *, outward: bool = False):
    """Time (s) until each body first reaches distance ``radius`` from the mass moving inwards,
    within ``[0, horizon]``; ``inf`` where it does not. ``outward=True``: moving outwards, from
    inside ``radius`` (leaving a sphere of influence), the mirror image of the same solution.

    Exact along the conic at any step length (no sampling, so no tunnelling):
    the crossing exists iff periapsis < ``radius`` and the body is outside it,
    or on it moving out to an apoapsis past it (just bounced: the next crossing is a
    cycle on, so no nudge off the surface is needed, which would move the conic);
    it lies on the inbound branch, before the next periapsis. Straight-line (radial)
    orbits, ``h = 0`` and so ``e = 1`` whatever the energy, fall back when bound:
    only ``energy >= 0`` counts as open. The anomaly of
    the crossing comes from ``r = a (1 - e cos E)`` (``a (1 - e cosh H)``), its
    time from Kepler's equation; two Newton steps on ``|r(t)| - radius`` with
    the exact propagator polish it (``d|r|/dt = r.v/|r|``), which also covers
    near-parabolic orbits where Kepler's equation loses digits.
    """
    r = np.atleast_2d(np.asarray(r, dtype=np.float64))
    v = np.atleast_2d(np.asarray(v, dtype=np.float64))
    n = r.shape[0]
    mu = np.broadcast_to(np.asarray(mu, dtype=np.float64), (n,))
    radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (n,))
    horizon = np.broadcast_to(np.asarray(horizon, dtype=np.float64), (n,))
    el = elements(r, v, mu)
    rn = _norm(r)
    rv = _dot(r, v)
    out = np.full(n, np.inf)
    if outward:
        # out through the sphere: from inside it, on an orbit that reaches past it (any open one does)
        # (apoapsis from the energy, not e < 1: a bound straight-line orbit has e = 1 and turns back)
        cand = (rn < radius) & (el.apoapsis > radius)
    else:
        # outside the sphere, or on it (to rounding, after a bounce) on the way out to an apoapsis past it
        cand = (el.periapsis < radius) & ((rn > radius) | ((rv > 0) & (el.apoapsis > radius)))
        # an outbound hyperbola (or parabola) past periapsis never returns. "Open" is decided by the
        # energy (alpha = 2/r - v^2/mu <= 0), not by e >= 1: a straight-line (radial) bound orbit, a
        # body released at rest or thrown straight up, has h = 0 and so e = 1 exactly, yet it falls back.
        cand &= ~((el.energy >= 0.0) & (rv >= 0))
    if not cand.any():
        return out
    idx = np.flatnonzero(cand)
    a, e, mu_i, R = el.a[idx], el.e[idx], mu[idx], radius[idx]
    with np.errstate(divide="ignore", invalid="ignore"):
        alpha = 1.0 / a
        nmean = np.sqrt(mu_i * np.abs(alpha) ** 3)
        ell = alpha > 0
        # elliptic: inbound crossing at E = -E_R; time from the current M
        cosE = np.clip((1.0 - R * alpha) / e, -1.0, 1.0)
        E_R = np.arccos(cosE)
        side = 1.0 if outward else -1.0                    # outbound at E = +E_R, inbound at -E_R
        M_R = side * (E_R - e * np.sin(E_R))
        t_e = np.mod(M_R - _mean_anomaly_e(el, idx), TWO_PI) / nmean
        # hyperbolic: inbound at H = -H_R (outbound at +H_R)
        coshH = np.maximum((1.0 - R * alpha) / e, 1.0)
        H_R = np.arccosh(coshH)
        M_Rh = side * (e * np.sinh(H_R) - H_R)
        t_h = (M_Rh - (-el.time_to_periapsis[idx] * nmean)) / nmean
        t = np.where(ell, t_e, t_h)
        # near-parabolic or degenerate: fall back to the time to periapsis as a bracket start
        t = np.where(np.isfinite(t), t, np.maximum(el.time_to_periapsis[idx], 0.0))
    # polish with the exact propagator: Newton on |r(t)| - R
    ri, vi = r[idx], v[idx]
    for _ in range(3):
        rt, vt = propagate(ri, vi, mu_i, t)
        rtn = _norm(rt)
        rdot = _dot(rt, vt) / rtn
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(rdot > 0 if outward else rdot < 0, (rtn - R) / rdot, 0.0)
        t = t - np.where(np.isfinite(step), step, 0.0)
    t = np.maximum(t, 0.0)
    out[idx] = np.where(t <= horizon[idx], t, np.inf)
    return out


#: Steps of :func:`time_to_touch` before a pair counts as grazing (a clean contact needs a handful).
TOUCH_ITERATIONS = 200


def time_to_touch(ra, va, ta, rb, vb, tb, mu, reach, t_from, t_to, accel, rho=None, *,
                  iterations: int = TOUCH_ITERATIONS, line_b: bool = False):
    """First time in ``[t_from, t_to]`` (absolute s) at which pairs of bodies on conics about the same
    mass come within ``reach`` (m, the sum of their radii) of each other *while approaching*; ``inf``
    where they do not. Vectorised over pairs.

    Body ``a`` of each pair follows the conic through its epoch ``ra, va`` (m, m/s, relative to the
    mass) at time ``ta`` (s), body ``b`` likewise; arrays ``(n, 3)`` and ``(n,)``. ``accel`` (m/s^2,
    ``(n,)``) bounds ``|a_a| + |a_b|`` over the interval (``mu / rho^2`` of each body, ``rho`` a lower
    bound on its distance from the mass there); ``rho`` (m, ``(n,)``, optional): such a lower bound
    for both bodies of the pair, which gives the tighter tidal bound below.

    Conservative advancement on the gap ``g = |d| - reach``, ``d = r_b - r_a``: since
    ``d^2|d|/dt^2 = (|d'|^2 - (d^.d')^2)/|d| + d^.d'' >= -|d''| >= -accel``, the gap can fall no
    faster than ``g(t + tau) >= g + g' tau - accel tau^2 / 2``, so the smaller positive root ``tau``
    of the right side is a step that cannot pass a contact (``g' = d^.d'``, the closing rate taken
    signed: a separating pair steps far, and a pair that has just bounced is not stuck at ``g = 0``).
    Near a contact the step is Newton's on ``g`` and converges quadratically.

    Two bodies close together feel nearly the same pull: ``|d''| = |a(r_b) - a(r_a)| <= 2 mu |d| /
    rho_s^3`` (the tidal tensor's norm is ``2 mu / r^3``; ``rho_s >= rho - |d|/2`` is the segment's
    distance from the mass), and over a step ``tau`` the distance stays below ``D = |d| + |d'| tau +
    accel tau^2/2``. The bound ``A(tau) = min(accel, 2 mu D / (rho - D/2)^3)`` grows with ``tau``, so
    the root ``tau*`` of ``g + g' t - A(T) t^2 / 2`` for a trial ``T`` is safe whenever ``tau* <= T``,
    and ``min(tau*, T)`` is safe always: the step is the largest of these over trials ``T`` (the
    time left, and quarters of it). For a cloud of bodies sharing an orbit the relative acceleration
    is then micro-g instead of ``2 mu / rho^2``, and the steps are hundreds of seconds, not ten.

    A pair is in contact
    where ``g <= 1e-10 reach`` plus the rounding of the positions (``4 eps (|r_a| + |r_b|)``) and
    ``g' < 0``; its time is then polished by one Newton step ``g / -g'``. Pairs that overlap and
    approach at ``t_from`` touch at ``t_from``. No sampling, so no step length can tunnel.

    Returns ``(t, stuck)``: ``stuck`` marks pairs still iterating after ``iterations`` steps (only a
    pair that grazes, ``g' -> 0`` as ``g -> 0``, converges that slowly): those within ``1e-6 reach``
    and approaching are taken to touch where they are (a graze: its impulse is ~0); the others get
    ``inf`` and ``stuck`` True, for the caller to report.

    ``line_b=True``: body ``b`` is not on a conic but moves straight, ``rb + vb (t - tb)`` (an
    obstacle gravity does not move, in the frame of a mass that itself moves straight); ``accel`` is
    then body ``a``'s bound alone, and ``rho`` must be None (no tidal bound: ``b`` feels no pull).
    """
    if line_b and rho is not None:
        raise ValueError("time_to_touch: rho (the tidal bound) needs both bodies on conics; got line_b=True")
    ra, va, rb, vb = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (ra, va, rb, vb))
    n = ra.shape[0]
    b_ = lambda a: np.array(np.broadcast_to(np.asarray(a, dtype=np.float64), (n,)))  # noqa: E731
    ta, tb, reach, t_to, accel = b_(ta), b_(tb), b_(reach), b_(t_to), b_(accel)
    t = b_(t_from)
    out = np.full(n, np.inf)
    stuck = np.zeros(n, bool)
    if not n:
        return out, stuck
    tidal = rho is not None
    if tidal:
        rho = b_(rho)
        trials = 0.25 ** np.arange(10)                           # fractions of the time left
    ea = Epoch(ra, va, mu)
    eb = _Line(rb, vb) if line_b else Epoch(rb, vb, mu)
    idx = np.arange(n)
    chi_a = chi_b = None
    for it in range(iterations):
        pa, ua, chi_a = ea.at(t - ta, chi_a)
        pb, ub, chi_b = eb.at(t - tb, chi_b)
        d = pb - pa
        dist = _norm(d)
        g = dist - reach
        with np.errstate(invalid="ignore", divide="ignore"):
            gd = _dot(d, ub - ua) / dist                       # d|d|/dt (< 0: closing)
        tol = 1e-10 * reach + 4.0 * _EPS * (_norm(pa) + _norm(pb))
        hit = (g <= tol) & (gd < 0)
        if it == iterations - 1:
            graze = ~hit & (g <= 1e-6 * reach) & (gd < 0)
            hit |= graze
        c = -gd
        gp = np.maximum(g, 0.0)
        sq = np.sqrt(np.maximum(c * c + 2.0 * accel * gp, 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            # the smaller positive root of g - c tau - accel tau^2/2, written without cancelling
            tau = np.where(c > 0, 2.0 * gp / (c + sq), (sq - c) / accel)
            if tidal:
                T = np.maximum(t_to - t, 0.0)[:, None] * trials[None, :]
                s_rel = _norm(ub - ua)[:, None]
                D = dist[:, None] + s_rel * T + 0.5 * accel[:, None] * T * T
                seg = rho[:, None] - 0.5 * D
                A_T = np.where(seg > 0, np.minimum(accel[:, None], 2.0 * mu * D / seg ** 3), accel[:, None])
                cc = c[:, None]
                sq_T = np.sqrt(np.maximum(cc * cc + 2.0 * A_T * gp[:, None], 0.0))
                root = np.where(cc > 0, 2.0 * gp[:, None] / (cc + sq_T), (sq_T - cc) / A_T)
                tau = np.maximum(tau, np.nanmax(np.minimum(root, T), axis=1))
        if hit.any():
            with np.errstate(invalid="ignore", divide="ignore"):
                polish = np.where(g > 0, g / c, 0.0)
            out[idx[hit]] = np.minimum(t[hit] + polish[hit], t_to[hit])
        t_new = t + tau
        gone = ~hit & ~(t_new <= t_to)                       # past the end (or NaN): no contact
        keep = ~hit & ~gone
        if it == iterations - 1:
            stuck[idx[keep]] = True
            break
        if not keep.any():
            break
        if not keep.all():
            idx, t_new, chi_a, chi_b = idx[keep], t_new[keep], chi_a[keep], chi_b[keep]
            ta, tb, reach, t_to, accel = ta[keep], tb[keep], reach[keep], t_to[keep], accel[keep]
            if tidal:
                rho = rho[keep]
            ea = Epoch(ea.r0[keep], ea.v0[keep], mu)
            eb = _Line(eb.r0[keep], eb.v0[keep]) if line_b else Epoch(eb.r0[keep], eb.v0[keep], mu)
        t = t_new
    return out, stuck


def time_to_touch_paths(at_a, at_b, reach, t_from, t_to, accel, *, iterations: int = TOUCH_ITERATIONS):
    """:func:`time_to_touch` for any two paths known as functions of time: the first time in
    ``[t_from, t_to]`` (absolute s) at which pairs come within ``reach`` (m) while approaching;
    ``inf`` where they do not. Vectorised over pairs.

    ``at_a(idx, t)`` and ``at_b(idx, t)`` return positions and velocities ``(len(idx), 3)`` (one
    inertial frame, m and m/s) of pairs ``idx`` (indices into the ``(n,)`` arrays given) at absolute
    times ``t``; ``accel`` (m/s^2, ``(n,)``) bounds ``|a_a| + |a_b|`` over the interval. For bodies in
    different frames (a conic about a moon that itself follows a conic, a straight drift, a straight
    obstacle) the bound is the sum of each body's pull and its frame's. The same conservative
    advancement and contact test as :func:`time_to_touch` (without its tidal bound, which needs both
    bodies about one mass), so no step length can tunnel. Returns ``(t, stuck)``."""
    n = np.shape(reach)[0] if np.ndim(reach) else np.shape(t_from)[0]
    b_ = lambda a: np.array(np.broadcast_to(np.asarray(a, dtype=np.float64), (n,)))  # noqa: E731
    reach, t_to, accel, t = b_(reach), b_(t_to), b_(accel), b_(t_from)
    out = np.full(n, np.inf)
    stuck = np.zeros(n, bool)
    idx = np.arange(n)
    for it in range(iterations):
        if not idx.size:
            break
        pa, ua = at_a(idx, t)
        pb, ub = at_b(idx, t)
        d = pb - pa
        dist = _norm(d)
        g = dist - reach
        with np.errstate(invalid="ignore", divide="ignore"):
            gd = _dot(d, ub - ua) / dist
        tol = 1e-10 * reach + 4.0 * _EPS * (_norm(pa) + _norm(pb))
        hit = (g <= tol) & (gd < 0)
        if it == iterations - 1:
            hit |= ~hit & (g <= 1e-6 * reach) & (gd < 0)
        c = -gd
        gp = np.maximum(g, 0.0)
        sq = np.sqrt(np.maximum(c * c + 2.0 * accel * gp, 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            # the smaller positive root of g - c tau - accel tau^2/2 (accel 0 and closing: g / c)
            tau = np.where(c > 0, 2.0 * gp / (c + sq), (sq - c) / accel)
            if hit.any():
                polish = np.where(g > 0, g / c, 0.0)
                out[idx[hit]] = np.minimum(t[hit] + polish[hit], t_to[hit])
        t_new = t + tau
        keep = ~hit & (t_new <= t_to)                      # (past the end, or NaN: no contact)
        if it == iterations - 1:
            stuck[idx[keep]] = True
            break
        idx, t = idx[keep], t_new[keep]
        reach, t_to, accel = reach[keep], t_to[keep], accel[keep]
    return out, stuck


class _Line:
    """A straight path ``r0 + v0 t`` with Epoch.at's signature (time since the epoch, a chi guess)."""

    def __init__(self, r0, v0):
        self.r0, self.v0 = r0, v0

    def at(self, dt, chi=None):
        dt = np.asarray(dt, dtype=np.float64)
        return self.r0 + self.v0 * dt[:, None], self.v0, np.zeros(len(dt))



def arc_boxes(p, w, p_end, w_end, span, mu, surface, ball, grow_by=None):
    """Boxes that hold each body's centre over ``span`` s on its conic about ``mu``, from the state
    ``p, w`` (m, m/s, relative to the mass, ``(n, 3)``) to ``p_end, w_end`` at the span's end, grown
    by ``grow_by`` (m, ``(n,)``: a radius); and for each a bound ``accel`` on its acceleration
    (m/s^2) and ``rho`` on its distance from the mass (m) over the span. Returns ``lo, hi, accel,
    rho``.

    ``rho`` is the smaller end distance while the distance is monotonic (no apsis passed: the radial
    velocity has one sign at both ends and the span is under half a period), else the periapsis
    ``q``; never less than ``surface`` (m, the mass's surface radius, which no body on its conic
    crosses: so a radial orbit, ``q -> 0``, stays bounded). ``accel = mu / rho^2``. The path
    leaves its chord by at most ``accel span^2 / 8`` (the chord error of a curve with ``|p''| <= A``),
    so the box of the two ends grown by that holds it. Where ``ball`` is True the body touches the
    surface within the span (its path is two conics): its box is the cube about ``p`` it can reach
    at its top speed (at ``max(q, surface)``; an elastic bounce off the surface keeps the speed and,
    being radial, ``q``). One compiled pass."""
    p, w, p_end, w_end = (np.ascontiguousarray(a, dtype=np.float64) for a in (p, w, p_end, w_end))
    n = p.shape[0]
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    accel = np.empty(n)
    rho = np.empty(n)
    grow_by = np.zeros(n) if grow_by is None else np.ascontiguousarray(grow_by, dtype=np.float64)
    _arc_boxes_compiled(p, w, p_end, w_end, float(span), float(mu), float(surface),
                        np.ascontiguousarray(ball, dtype=np.bool_), grow_by, lo, hi, accel, rho)
    return lo, hi, accel, rho
