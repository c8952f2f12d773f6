"""A hybrid symplectic n-body step for close encounters: Wisdom–Holman in democratic heliocentric
coordinates while the bodies are apart, an adaptive integrator for the pairs that come close (Chambers
1999's MERCURY; Rein et al. 2019, "Hybrid symplectic integrators for planetary dynamics", REBOUND's
MERCURIUS, which this follows).

Plain Wisdom–Holman (:mod:`framework.wisdom_holman`) kicks every pair's pull at the step's end points: when
two bodies pass within a few Hill radii the pull changes within a step and the energy error jumps by
orders of magnitude, for good. Here each pair ``i, j`` has a critical radius ``rc_ij = max(rc_i, rc_j)``
(:func:`critical_radii`) and a changeover function ``L(r)`` (:func:`framework.encounters.changeover`, 1 at
``r >= rc``, 0 under ``0.1 rc``). One step of ``dt``:

* kick (``dt/2``): ``V_i += dt/2 sum_j G m_j L(r_ij) (X_j - X_i)/r_ij^3`` over the bodies 1.. (no body 0:
  democratic heliocentric, positions ``X`` from body 0, velocities ``V`` barycentric; ``L`` on the force,
  as REBOUND's);
* jump (``dt/2``): ``X_i += dt/2 P/(G m_0)``, ``P = sum_{i>=1} G m_i V_i``;
* drift (``dt``): each body on its Kepler orbit about ``G m_0`` (the exact drift of
  :func:`framework.wisdom_holman._kepler_drift`). Then the encounter test: a pair's distance over the
  drift is taken as the cubic in time through its squared distance and its rate at both ends (REBOUND's
  prediction); a pair whose minimum is under ``1.1 rc_ij`` puts both bodies in the encounter set, whose
  drift is done again from the step's start by :func:`framework.encounters.bulirsch_stoer` on the Kepler
  pull plus the ``1 - L`` part of their mutual pulls (adaptive, error-controlled; each set body against
  every other set body);
* jump (``dt/2``), kick (``dt/2``). Between the steps of one call the two half kicks are one.

A step with no pair near its critical radius costs the Wisdom–Holman step plus one pass over the pairs for
the prediction, and gives the same result as ``wisdom_holman(coordinates="democratic")`` up to rounding
(``L = 1`` at every pair). Pairs with body 0 are not switched: its pull is the drift's, exact at any
distance. Collisions are not looked for. The critical radii are fixed for a call (the split must not change
within the integration); pass ``dcrit`` to keep them across calls.

Units: any consistent set; ``gm = G m``. ``x, v``: ``(n, 3)`` float64, inertial, changed in place.
"""
from __future__ import annotations

import math

import numpy as np

from numba.extending import register_jitable

from driftframe.framework import wisdom_holman as wh
from driftframe.framework.encounters import bulirsch_stoer, changeover
from driftframe.framework.kernels import kernel

#: The default relative error per adaptive step of the encounter integrator.
TOLERANCE = 1e-13


@kernel(error_model="numpy")
def _switched_kick(X, V, gm, dc, a, t):
    """``V_i += t sum_j G m_j L(r_ij) (X_j - X_i)/r_ij^3`` over the bodies 1.. (each pair once; ``a``:
    scratch). The common case, ``r >= rc``, is one comparison more than the plain kick."""
    n = X.shape[0]
    for i in range(n):
        a[i, 0] = 0.0
        a[i, 1] = 0.0
        a[i, 2] = 0.0
    for i in range(1, n):
        xi0, xi1, xi2 = X[i, 0], X[i, 1], X[i, 2]
        ai0 = 0.0
        ai1 = 0.0
        ai2 = 0.0
        for j in range(i + 1, n):
            d0 = X[j, 0] - xi0
            d1 = X[j, 1] - xi1
            d2 = X[j, 2] - xi2
            r2 = d0 * d0 + d1 * d1 + d2 * d2
            rc = max(dc[i], dc[j])
            r = np.sqrt(r2)
            w = 1.0 / (r2 * r)
            if r < rc:
                w *= changeover(r, rc)
            ai0 += gm[j] * w * d0
            ai1 += gm[j] * w * d1
            ai2 += gm[j] * w * d2
            a[j, 0] -= gm[i] * w * d0
            a[j, 1] -= gm[i] * w * d1
            a[j, 2] -= gm[i] * w * d2
        a[i, 0] += ai0
        a[i, 1] += ai1
        a[i, 2] += ai2
    for i in range(1, n):
        V[i, 0] += t * a[i, 0]
        V[i, 1] += t * a[i, 1]
        V[i, 2] += t * a[i, 2]


@register_jitable(inline="always")
def _pair_sums(Xb, Vb, X, V, i, j):
    """The pair ``i, j``'s squared distances ``qo, qn`` at the two ends of a drift from ``(Xb, Vb)`` to
    ``(X, V)`` and half their rates, ``d.w`` (``q' = 2 d.w``), at both ends."""
    qo = 0.0
    qn = 0.0
    ro = 0.0
    rn = 0.0
    for k in range(3):
        do = Xb[j, k] - Xb[i, k]
        dn = X[j, k] - X[i, k]
        qo += do * do
        qn += dn * dn
        ro += do * (Vb[j, k] - Vb[i, k])
        rn += dn * (V[j, k] - V[i, k])
    return qo, qn, ro, rn


@register_jitable(inline="always")
def _least_squared(qo, qn, ro, rn, dt):
    """:func:`_closest_squared` from the pair's :func:`_pair_sums` (``ro, rn``: half the rates)."""
    ro = 2.0 * ro                                     # (x 2 is exact: the bits of summing 2 d.w)
    rn = 2.0 * rn
    qmin = min(qo, qn)
    a = 6.0 * (qo - qn) + 3.0 * dt * (ro + rn)
    b = 6.0 * (qn - qo) - 2.0 * dt * (2.0 * ro + rn)
    c = dt * ro
    # the roots as q/a and c/q, q = -(b + sign(b) sqrt(disc))/2: no cancellation, and a = 0 (q(s) a
    # quadratic, as for two straight lines) gives its one root c/q = -c/b
    q_ = -0.5 * (b + np.copysign(np.sqrt(max(b * b - 4.0 * a * c, 0.0)), b))
    for k in range(2):
        s = (q_ / a if a != 0.0 else -1.0) if k == 0 else (c / q_ if q_ != 0.0 else -1.0)
        if s > 0.0 and s < 1.0:
            u = 1.0 - s
            q = u * u * (1.0 + 2.0 * s) * qo + s * s * (3.0 - 2.0 * s) * qn + s * u * u * dt * ro - s * s * u * dt * rn
            qmin = min(qmin, max(q, 0.0))
    return qmin


@register_jitable(inline="always")
def _closest_squared(Xb, Vb, X, V, i, j, dt):
    """The least squared distance of the pair ``i, j`` over a drift from ``(Xb, Vb)`` to ``(X, V)``: the
    cubic Hermite interpolant in ``s = t/dt`` of ``q = r^2`` from its values and rates ``q' = 2 d.w`` at
    both ends, minimised where its derivative ``a s^2 + b s + c`` vanishes inside (0, 1) (REBOUND's
    prediction, which divides by ``a`` and so misses the minimum when ``a = 0``). A kernel's helper (and plain
    Python, for a check of one pair)."""
    qo, qn, ro, rn = _pair_sums(Xb, Vb, X, V, i, j)
    return _least_squared(qo, qn, ro, rn, dt)


@kernel(error_model="numpy")
def _flag_pairs(Xb, Vb, X, V, dc, dt, first, flag):
    """``flag[i]``: whether body ``i`` (rows ``first..``) is in a pair whose least distance over the drift from
    ``(Xb, Vb)`` to ``(X, V)`` is under ``1.1 max(dc_i, dc_j)`` (:func:`_closest_squared`); returns how many."""
    n = X.shape[0]
    count = 0
    for i in range(n):
        flag[i] = False
    for i in range(first, n):
        for j in range(i + 1, n):
            rc = 1.1 * max(dc[i], dc[j])
            # first a lower bound of the cubic with no root and no division: its weights of qo, qn are >= 0
            # and sum to 1, those of dt q'o, dt q'n lie in [0, 4/27] and [-4/27, 0]
            qo, qn, ro, rn = _pair_sums(Xb, Vb, X, V, i, j)
            if min(qo, qn) - (8.0 / 27.0) * (max(-dt * ro, 0.0) + max(dt * rn, 0.0)) >= rc * rc:
                continue
            if _least_squared(qo, qn, ro, rn, dt) < rc * rc:
                if not flag[i]:
                    count += 1
                flag[i] = True
                if not flag[j]:
                    count += 1
                flag[j] = True
    return count


@kernel(error_model="numpy")
def _drift(X, V, Xb, Vb, gm, dc, m, dt, flag, tolerance):
    """The drift of one step (module docstring): Kepler for every body, then the encounter set again from
    the start (``Xb, Vb``: scratch for it) by the adaptive integrator. Returns whether a set was found, or
    -1 when the adaptive integrator failed."""
    n = X.shape[0]
    for i in range(1, n):
        for k in range(3):
            Xb[i, k] = X[i, k]
            Vb[i, k] = V[i, k]
        wh._kepler_drift(X, V, i, m, dt)
    count = _flag_pairs(Xb, Vb, X, V, dc, dt, np.int64(1), flag)     # (np.int64: no literal compile)
    if count == 0:
        return 0
    idx = np.empty(count, np.int64)
    e = 0
    for i in range(n):
        if flag[i]:
            idx[e] = i
            e += 1
    Xe = np.empty((count, 3))
    Ve = np.empty((count, 3))
    for e in range(count):
        for k in range(3):
            Xe[e, k] = Xb[idx[e], k]
            Ve[e, k] = Vb[idx[e], k]
    if bulirsch_stoer(Xe, Ve, gm[idx], dc[idx], gm[0], dt, tolerance) < 0:
        return -1
    for e in range(count):
        for k in range(3):
            X[idx[e], k] = Xe[e, k]
            V[idx[e], k] = Ve[e, k]
    return 1


@kernel(error_model="numpy")
def _mercurius(x, v, gm, dc, dt, n_steps, tolerance):
    """``n_steps`` hybrid steps in place (module docstring); returns the number of steps that had an
    encounter, or ``-1 - step`` where the adaptive integrator failed (``x, v`` then unchanged: the caller
    raises)."""
    n = x.shape[0]
    X = np.empty_like(x)
    V = np.empty_like(v)
    Xb = np.empty_like(x)
    Vb = np.empty_like(v)
    a = np.empty_like(x)
    flag = np.zeros(n, np.bool_)
    gtot = 0.0
    for i in range(n):
        gtot += gm[i]
    cx = np.zeros(3)
    cv = np.zeros(3)
    for k in range(3):
        for i in range(n):
            cx[k] += gm[i] * x[i, k]
            cv[k] += gm[i] * v[i, k]
        cx[k] /= gtot
        cv[k] /= gtot
        for i in range(1, n):
            X[i, k] = x[i, k] - x[0, k]
            V[i, k] = v[i, k] - cv[k]
        X[0, k] = 0.0
        V[0, k] = 0.0
    m = np.empty((n, 3))
    wh._mu_rows(np.full(n, gm[0]), m)
    encounters = 0
    _switched_kick(X, V, gm, dc, a, 0.5 * dt)
    for s in range(n_steps):
        wh._jump(X, V, gm, 0.5 * dt)
        got = _drift(X, V, Xb, Vb, gm, dc, m, dt, flag, tolerance)
        if got < 0:
            return -1 - s
        encounters += got
        wh._jump(X, V, gm, 0.5 * dt)
        _switched_kick(X, V, gm, dc, a, dt if s < n_steps - 1 else 0.5 * dt)
    T = n_steps * dt
    for k in range(3):                                # x_0 = C - sum m_i X_i / M,  v_0 = V_C - sum m_i V_i / m_0
        cx[k] += cv[k] * T
        sx = 0.0
        sv = 0.0
        for i in range(1, n):
            sx += gm[i] * X[i, k]
            sv += gm[i] * V[i, k]
        x[0, k] = cx[k] - sx / gtot
        v[0, k] = cv[k] - sv / gm[0]
        for i in range(1, n):
            x[i, k] = X[i, k] + x[0, k]
            v[i, k] = V[i, k] + cv[k]
    return encounters


def critical_radii(x, v, gm, dt: float, hill: float = 3.0):
    """Each body's critical radius (REBOUND MERCURIUS's criteria): the largest of ``0.4 dt`` times its
    circular speed at its semi-major axis ``|a|`` and times its present speed about body 0 (the distance a
    step moves it), and ``hill`` Hill radii, ``hill |a| (m_i/(3 m_0))^(1/3)``; ``a`` from the vis-viva
    equation about ``G (m_0 + m_i)``. Body 0's is 0 (its pairs are never switched). ``(n,)`` array."""
    x = np.asarray(x, np.float64)
    v = np.asarray(v, np.float64)
    gm = np.asarray(gm, np.float64)
    d = x[1:] - x[0]
    w = v[1:] - v[0]
    r = np.linalg.norm(d, axis=1)
    v2 = np.einsum("ij,ij->i", w, w)
    mu = gm[0] + gm[1:]
    with np.errstate(divide="ignore"):
        a = np.abs(mu * r / (2.0 * mu - r * v2))
    dc = np.maximum(np.sqrt(mu / a) * 0.4 * abs(dt), np.sqrt(v2) * 0.4 * abs(dt))
    dc = np.maximum(dc, hill * a * np.cbrt(gm[1:] / (3.0 * gm[0])))
    return np.concatenate([[0.0], np.where(np.isfinite(dc), dc, 0.0)])


@kernel(error_model="numpy")
def _near_pairs(x, dc, fill, ii, jj):
    """The pairs ``i < j`` nearer than ``max(dc_i, dc_j)`` (squared distances compared: no root): their
    count, and (``fill``) their rows into ``ii, jj``."""
    n = x.shape[0]
    count = 0
    for i in range(n):
        for j in range(i + 1, n):
            d0 = x[j, 0] - x[i, 0]
            d1 = x[j, 1] - x[i, 1]
            d2 = x[j, 2] - x[i, 2]
            rc = max(dc[i], dc[j])
            if d0 * d0 + d1 * d1 + d2 * d2 < rc * rc:
                if fill:
                    ii[count] = i
                    jj[count] = j
                count += 1
    return count


def near_pairs(x, dcrit):
    """The pairs of rows of ``x`` (``(n, 3)``) nearer than the larger of their critical radii: ``(i, j)``
    index arrays, ``i < j`` (the pairs whose pull the changeover splits)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    dc = np.ascontiguousarray(dcrit, dtype=np.float64)
    none = np.empty(0, np.int64)
    count = _near_pairs(x, dc, np.bool_(False), none, none)
    ii = np.empty(count, np.int64)
    jj = np.empty(count, np.int64)
    if count:
        _near_pairs(x, dc, np.bool_(True), ii, jj)
    return ii, jj


def encounter_set(x0, v0, x1, v1, dcrit, dt: float):
    """Which bodies a drift of ``dt`` from ``(x0, v0)`` to ``(x1, v1)`` brings within reach of a pair's
    critical radius (``1.1 max(dcrit_i, dcrit_j)``, REBOUND's prediction: module docstring), every pair
    counted (no central body among the rows): a boolean ``(n,)`` mask."""
    arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (x0, v0, x1, v1)]
    flag = np.zeros(arrays[0].shape[0], bool)
    _flag_pairs(*arrays, np.ascontiguousarray(dcrit, dtype=np.float64), float(dt), np.int64(0), flag)
    return flag


def mercurius(x, v, gm, dt: float, n_steps: int = 1, *, dcrit=None, hill: float = 3.0,
              tolerance: float = TOLERANCE) -> int:
    """Advance ``n_steps`` hybrid steps of ``dt`` in place (module docstring); body 0 is the dominant mass.

    ``x, v, gm``: as :func:`framework.wisdom_holman.wisdom_holman`'s. ``dcrit``: the critical radii
    (``(n,)``, m; default :func:`critical_radii` with ``hill`` Hill radii, taken once for the call).
    ``tolerance``: the adaptive integrator's relative error per step. Returns the number of steps in which
    a pair was within reach of its critical radius (those whose close bodies the adaptive integrator moved).
    """
    gm = wh._checked(x, v, gm, dt, n_steps, "mercurius")
    if not gm[0] > 0.0:
        raise ValueError(f"mercurius: body 0 is the dominant mass; its gm must be > 0, got {gm[0]!r}")
    if not (math.isfinite(hill) and hill > 0.0):
        raise ValueError(f"mercurius: hill must be finite and > 0, got {hill!r}")
    if not (math.isfinite(tolerance) and 0.0 < tolerance < 1.0):
        raise ValueError(f"mercurius: tolerance must be in (0, 1), got {tolerance!r}")
    if dcrit is None:
        dcrit = critical_radii(x, v, gm, dt, hill)
    dcrit = np.ascontiguousarray(dcrit, dtype=np.float64)
    if dcrit.shape != (x.shape[0],) or not np.all(np.isfinite(dcrit) & (dcrit >= 0.0)):
        raise ValueError(f"mercurius: dcrit must be {x.shape[0]} finite radii >= 0, got shape {dcrit.shape}")
    if x.shape[0] < 2:
        return 0
    got = _mercurius(x, v, gm, dcrit, float(dt), int(n_steps), float(tolerance))
    if got < 0:
        raise RuntimeError(f"mercurius: the encounter integrator found no step within its tolerance "
                           f"{tolerance!r} in step {-1 - got} (bodies on one point?)")
    return int(got)
