"""Symplectic n-body integrators as numba kernels: Wisdom–Holman about a dominant mass, leapfrog without one.

**Wisdom–Holman** (Wisdom & Holman 1991; Rein & Tamayo 2015, REBOUND's WHFast). Bodies about a dominant
mass (body 0) move on nearly Keplerian orbits. Split ``H = H_kepler + H_interaction``: ``H_kepler`` is a
sum of two-body problems, solved exactly (the drift), ``H_interaction`` depends on positions only (the
kick). One step is ``drift(dt/2) kick(dt) drift(dt/2)``; the error is ``O(eps dt^2)`` with ``eps`` the
planets-to-star mass ratio, not ``O(dt^2)``. Between the steps of one call the two half drifts are joined
into one, so ``n_steps`` steps cost ``n_steps`` drifts and kicks (WHFast's ``safe_mode = 0``).

* Jacobi coordinates (the default, as WHFast's): body ``i``'s position is taken from the centre of mass
  of bodies ``0..i-1``, ``xj_i = x_i - C_{i-1}``, its velocity likewise; ``eta_i = G (m_0 + ... + m_i)``.
  Drift: each ``xj_i`` on its Kepler orbit of ``mu = eta_i``, the centre of mass on its straight line.
  Kick: ``H_int = sum_i G m_i eta_{i-1}/|xj_i| - sum_{i<j} G m_i m_j/|x_i - x_j|``; its acceleration on
  ``xj_i`` is the Jacobi transform of the pairwise accelerations (the pair 0–1 left out: it is body 1's
  Kepler term exactly) plus ``eta_i xj_i/|xj_i|^3`` for ``i >= 2`` (the Kepler pull put back).
* Democratic heliocentric (Duncan, Levison & Lee 1998): positions from body 0, velocities from the centre
  of mass. Drift: Kepler with ``mu = G m_0``; kick: the pairs without body 0; a *jump*
  ``X_i += t P / m_0`` (``P = sum m_j V_j``) either side of the kick. ``fixed_centre`` makes body 0 an
  immovable well (no jump; its constant velocity kept): the gravity system's wells, which no body pulls.
* The symplectic corrector (Wisdom, Holman & Touma 1996; order 3, 5, 7, 11 or 17, REBOUND's coefficients)
  is applied once when a call starts and undone once when it ends: the error of the kernel it wraps drops
  from ``O(eps dt^2)`` to ``O(eps^2 dt^2)``. Jacobi only.

**The Kepler drift** (:func:`_kepler_drift`): the universal-variable solution, one body at a time, in
place. ``alpha = 2/r0 - v0^2/mu`` (1/a), ``sigma0 = r0.v0/sqrt(mu)``, ``psi = alpha chi^2``, Stumpff's
``c2, c3`` (the series with as many terms as ``|psi|`` needs, :func:`_stumpff`); Kepler's equation in
``chi`` (m^1/2), ``sqrt(mu) t = chi^3 c3 + sigma0 chi^2 c2 + r0 chi (1 - psi c3)``, solved by Laguerre's
method (n = 5, Conway 1986: it converges from any start), from the third-order guess ``chi = sqrt(mu) u
(1 - u rd/2 + u^2 (rd^2 - r0 rdd/2)/3)``, ``u = t/r0`` (``rd``, ``rdd``: the first two time derivatives of
``r``; a drift of a few percent of an orbit then needs one iteration; a long one starts from Vallado's
guesses inside a bracket of the root, and bisects whenever Laguerre leaves it), a whole number of periods
taken out of ``t`` first. Then ``f - 1 = -chi^2 c2/r0``,
``g = t - chi^3 c3/sqrt(mu)``, ``fdot = sqrt(mu) chi (psi c3 - 1)/(r r0)``, ``gdot - 1 = -chi^2 c2/r``
(``r`` = Kepler's equation's derivative), added as increments (``x += (f-1) x0 + g v0``) so a short drift
loses no digits. The project's :func:`~framework.kepler_kernels._at_compiled` propagates whole columns from
an epoch with a dozen derived per-body arrays; a drift per body inside a loop wants this compact form.

**Leapfrog** (:func:`leapfrog`): drift-kick-drift on the plain ``1/r^2`` pulls, second order, for scenes
without a dominant mass (the figure-eight), the half drifts joined between steps.

Units: any consistent set; masses enter as ``gm = G m`` (m^3/s^2 in SI). Positions ``x`` and velocities
``v`` are ``(n, 3)`` float64 arrays in an inertial frame, changed in place. Sums run in a fixed order:
the same input gives the same bits.
"""
from __future__ import annotations

import math

import numpy as np

from driftframe.framework.kepler_kernels import _C2_SERIES, _C3_SERIES, _stumpff1
from driftframe.framework.kernels import kernel

#: The corrector orders available (Wisdom, Holman & Touma 1996), 0 = none.
CORRECTOR_ORDERS = (0, 3, 5, 7, 11, 17)
#: The coordinate systems of :func:`wisdom_holman`.
COORDINATES = ("jacobi", "democratic", "fixed")

# Corrector coefficients (Wisdom, Holman & Touma 1996, table 1, as REBOUND's integrator_whfast.c lists them):
# a_k = k sqrt(7/40) and the b's of each order; the corrector is the product of Z(a_k dt, b_k dt) below.
_A = np.array([0.0, 0.41833001326703777398908601289259374469640768464934,
               0.83666002653407554797817202578518748939281536929867,
               1.2549900398011133219672580386777812340892230539480,
               1.6733200530681510959563440515703749787856307385973,
               2.0916500663351888699454300644629687234820384232467,
               2.5099800796022266439345160773555624681784461078960,
               2.9283100928692644179236020902481562128748537925454,
               3.3466401061363021919126881031407499575712614771947])
# for each order: (a index, b) pairs of the negative half; the positive half mirrors them (-a, -b)
_B = {3: [(1, -0.024900596027799867499350357910273437184309981229127)],
      5: [(2, -0.0083001986759332891664501193034244790614366604097090),
          (1, 0.041500993379666445832250596517122395307183302048545)],
      7: [(3, 0.0024926811426922105779030593952776964450539008582219),
          (2, -0.018270923246702131478062356884535264841652263842597),
          (1, 0.053964399093127498721765893493510877532452806339655)],
      11: [(5, 0.00020361579647854651301632818774633716473696537436847),
           (4, -0.0023487215292295354188307328851055489876255097419754),
           (3, 0.012309078592019946317544564763237909911330686448336),
           (2, -0.038121613681288650508647613260247372125243616270670),
           (1, 0.072593394748842738674253180742744961827622366521517)],
      17: [(8, -0.0000043347415473373580190650223498124944896789841432241),
           (7, 0.000076436355227935738363241846979413475106795392377415),
           (6, -0.00063599983075817658983166881625078545864140848560259),
           (5, 0.0033132577069380655655490196833451994080066801611459),
           (4, -0.012071760822342291062449751726959664253913904872527),
           (3, 0.032422198864713580293681523029577130832258806467604),
           (2, -0.065192863576377893658290760803725762027864651086787),
           (1, 0.093056103771425958591541059067553547100903397724386)]}


def _corrector_table(order: int) -> np.ndarray:
    """``(k, 2)`` rows ``(a, b)``, in units of dt, of the operators ``Z(a dt, b dt)`` the corrector of this
    order applies, in the order it applies them (REBOUND's ``reb_whfast_apply_corrector``): order 3 is
    ``Z(a1, -b31)`` then ``Z(-a1, b31)``; higher orders run from ``Z(-a_k, -b_k1)`` up through the mirror."""
    if order == 0:
        return np.zeros((0, 2))
    if order == 3:
        (k, b), = _B[3]
        return np.array([[_A[k], -b], [-_A[k], b]])
    rows = [[-_A[k], -b] for k, b in _B[order]]                # the negative half, outermost a first
    rows += [[_A[k], b] for k, b in reversed(_B[order])]        # the positive half mirrors it
    return np.array(rows)


_CORRECTORS = {order: _corrector_table(order) for order in CORRECTOR_ORDERS}


# -- the Kepler drift -------------------------------------------------------------------------------------
@kernel(error_model="numpy")     # a zero divisor gives inf, not a raise (no check per division)
def _stumpff(psi):
    """Stumpff's ``c2, c3`` with as few series terms as ``|psi|`` needs: the remainder of k terms is about
    ``|psi|^k / (2k+2)!``, below 1e-18 with 4 terms at ``|psi| <= 1e-3`` and 7 at ``<= 0.1`` (a drift of
    a few percent of an orbit has ``psi ~ (2 pi dt / P)^2``); the 12-term series and the closed forms
    beyond (:func:`framework.kepler_kernels._stumpff1`) otherwise."""
    a = abs(psi)
    if a <= 1e-3:
        c2 = _C2[0] + psi * (_C2[1] + psi * (_C2[2] + psi * _C2[3]))
        c3 = _C3[0] + psi * (_C3[1] + psi * (_C3[2] + psi * _C3[3]))
        return c2, c3
    if a <= 0.1:
        c2 = _C2[6]
        c3 = _C3[6]
        for k in range(5, -1, -1):
            c2 = c2 * psi + _C2[k]
            c3 = c3 * psi + _C3[k]
        return c2, c3
    return _stumpff1(psi)


_C2 = _C2_SERIES.copy()
_C3 = _C3_SERIES.copy()


@kernel(error_model="numpy")
def _kepler_drift(x, v, i, m, t):
    """Row ``i`` of ``x, v`` (relative to the attracting centre) moved along its Kepler orbit for time ``t``,
    in place (module docstring: the formulas). ``m[i]``: ``(mu, sqrt(mu), 1/mu)``, taken once per call (a
    drift's cost is its chain of square roots and divisions: five here for a short drift)."""
    mu, sqmu, mui = m[i, 0], m[i, 1], m[i, 2]
    x0, x1, x2 = x[i, 0], x[i, 1], x[i, 2]
    v0, v1, v2 = v[i, 0], v[i, 1], v[i, 2]
    r0 = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    r0i = 1.0 / r0
    rv = x0 * v0 + x1 * v1 + x2 * v2
    vv = v0 * v0 + v1 * v1 + v2 * v2
    alpha = 2.0 * r0i - vv * mui
    sigma0 = rv * (sqmu * mui)
    if alpha > 0.0 and t * t * mu * alpha * alpha * alpha > 4.0 * np.pi * np.pi:
        period = 2.0 * np.pi / (sqmu * alpha * np.sqrt(alpha))       # more than an orbit: whole ones out
        t = t - period * np.round(t / period)
    target = sqmu * t
    # chi = sqrt(mu) * integral of dt/r to third order in u = t/r0: r = r0 + rd t + rdd t^2/2 + ...
    u = t * r0i
    rd = rv * r0i
    rdd = (vv - rd * rd) * r0i - mu * r0i * r0i
    chi = sqmu * u * (1.0 - 0.5 * u * rd + u * u * (rd * rd - 0.5 * r0 * rdd) / 3.0)
    lo = 0.0 if t >= 0.0 else -np.inf               # the root's bracket, narrowed by every iterate
    hi = np.inf if t >= 0.0 else 0.0
    if u * u * vv > 0.25:                           # a long drift: a bracket from the orbit, Vallado's starts
        # Kepler's equation rises with chi (its slope is r > 0): an ellipse's chi gains 2 pi/sqrt(alpha)
        # an orbit; an open orbit's at most sqrt(mu)/q a second (q: periapsis, q = p/(1 + e), p = h^2/mu)
        span = np.inf
        if alpha > 0.0:
            span = 2.0 * np.pi / np.sqrt(alpha)
            chi = sqmu * t * alpha
        else:
            h2 = r0 * r0 * vv - rv * rv
            e = np.sqrt(max(1.0 - alpha * h2 * mui, 0.0))             # e^2 = 1 - alpha p
            if h2 > 0.0:
                span = sqmu * abs(t) * (1.0 + e) * mu / h2
            a = 1.0 / alpha
            arg = -2.0 * mu * alpha * t / (rv + np.copysign(np.sqrt(-mu * a), t) * (1.0 - r0 * alpha))
            chi = np.copysign(np.sqrt(-a), t) * np.log(arg) if arg > 0.0 else sqmu * t * r0i
        lo = 0.0 if t >= 0.0 else -span
        hi = span if t >= 0.0 else 0.0
        if not (chi > lo and chi < hi):
            chi = 0.5 * (lo + hi) if span < np.inf else sqmu * t * r0i
    for _ in range(100):
        chi2 = chi * chi
        psi = alpha * chi2
        c2, c3 = _stumpff(psi)
        one_c3 = 1.0 - psi * c3
        f = chi2 * chi * c3 + sigma0 * chi2 * c2 + r0 * chi * one_c3 - target
        if f > 0.0:
            hi = min(hi, chi)
        elif f < 0.0:
            lo = max(lo, chi)
        else:
            break
        fp = chi2 * c2 + sigma0 * chi * one_c3 + r0 * (1.0 - psi * c2)
        fpp = sigma0 * (1.0 - psi * c2) + (1.0 - alpha * r0) * chi * one_c3
        disc = np.sqrt(abs(16.0 * fp * fp - 20.0 * f * fpp))
        step = 5.0 * f / (fp + disc if fp >= 0.0 else fp - disc)
        new = chi - step
        if not (new >= lo and new <= hi):            # out of the bracket (or not a number): bisect
            width = max(abs(chi), abs(target) * r0i)
            new = 0.5 * (lo + hi) if np.isfinite(lo) and np.isfinite(hi) else (
                hi - width if np.isfinite(hi) else lo + width)
            step = chi - new
        chi = new
        if abs(step) <= 1e-7 * abs(chi) or hi - lo <= 4e-16 * abs(chi):   # cubic: the next step is below 1e-20 chi
            break
    chi2 = chi * chi
    psi = alpha * chi2
    c2, c3 = _stumpff(psi)
    r = chi2 * c2 + sigma0 * chi * (1.0 - psi * c3) + r0 * (1.0 - psi * c2)
    ri = 1.0 / r
    fm1 = -chi2 * c2 * r0i
    g = t - chi2 * chi * c3 * (sqmu * mui)
    fd = sqmu * chi * (psi * c3 - 1.0) * ri * r0i
    gdm1 = -chi2 * c2 * ri
    x[i, 0] = x0 + (fm1 * x0 + g * v0)
    x[i, 1] = x1 + (fm1 * x1 + g * v1)
    x[i, 2] = x2 + (fm1 * x2 + g * v2)
    v[i, 0] = v0 + (fd * x0 + gdm1 * v0)
    v[i, 1] = v1 + (fd * x1 + gdm1 * v1)
    v[i, 2] = v2 + (fd * x2 + gdm1 * v2)


@kernel(error_model="numpy")
def _mu_rows(mu, m):
    """``m[i] = (mu_i, sqrt(mu_i), 1/mu_i)`` for :func:`_kepler_drift`."""
    for i in range(mu.shape[0]):
        m[i, 0] = mu[i]
        m[i, 1] = np.sqrt(mu[i])
        m[i, 2] = 1.0 / mu[i]


@kernel(error_model="numpy")
def _kepler_drift_all(x, v, mu, t):
    m = np.empty((x.shape[0], 3))
    _mu_rows(np.full(x.shape[0], mu), m)
    for i in range(x.shape[0]):
        _kepler_drift(x, v, i, m, t)


# -- pairwise pulls -------------------------------------------------------------------------------------
@kernel(error_model="numpy")
def _pair_accel(x, gm, first, skip01, a):
    """``a_i = sum_j G m_j (x_j - x_i)/|x_j - x_i|^3`` over bodies ``first..n-1``, each pair once (both
    ends updated); ``skip01``: leave the pair (0, 1) out. Rows before ``first`` are left at zero. Two bodies
    at one point give both their rows NaN (:func:`pair_accel` answers those rows again; no test in the loop,
    which would cost 3.5 % of it)."""
    n = x.shape[0]
    for i in range(n):
        a[i, 0] = 0.0
        a[i, 1] = 0.0
        a[i, 2] = 0.0
    for i in range(first, n):
        xi0, xi1, xi2 = x[i, 0], x[i, 1], x[i, 2]
        gi = gm[i]
        ai0 = 0.0
        ai1 = 0.0
        ai2 = 0.0
        j0 = i + 1
        if skip01 and i == 0:
            j0 = 2
        for j in range(j0, n):
            d0 = x[j, 0] - xi0
            d1 = x[j, 1] - xi1
            d2 = x[j, 2] - xi2
            r2 = d0 * d0 + d1 * d1 + d2 * d2
            w = 1.0 / (r2 * np.sqrt(r2))             # 1/r^3
            wj = gm[j] * w
            wi = gi * w
            ai0 += wj * d0
            ai1 += wj * d1
            ai2 += wj * d2
            a[j, 0] -= wi * d0
            a[j, 1] -= wi * d1
            a[j, 2] -= wi * d2
        a[i, 0] += ai0
        a[i, 1] += ai1
        a[i, 2] += ai2


# -- Jacobi coordinates ---------------------------------------------------------------------------------
@kernel(error_model="numpy")
def _prefix_masses(gm, eta):
    """``eta_i = G (m_0 + ... + m_i)``."""
    s = 0.0
    for i in range(gm.shape[0]):
        s += gm[i]
        eta[i] = s


@kernel(error_model="numpy")
def _to_jacobi(x, v, gm, eta, xj, vj):
    """Inertial ``x, v`` to Jacobi ``xj, vj``: row i from the centre of mass C_{i-1} of rows 0..i-1, row 0
    the whole system's centre of mass. ``C_i = C_{i-1} + m_i xj_i / eta_i``."""
    for k in range(3):
        c = x[0, k]
        cv = v[0, k]
        for i in range(1, x.shape[0]):
            w = gm[i] / eta[i]
            xj[i, k] = x[i, k] - c
            vj[i, k] = v[i, k] - cv
            c += w * xj[i, k]
            cv += w * vj[i, k]
        xj[0, k] = c
        vj[0, k] = cv


@kernel(error_model="numpy")
def _from_jacobi(xj, vj, gm, eta, x, v, with_v):
    """Jacobi back to inertial (``with_v``: velocities too): ``C_{i-1} = C_i - m_i xj_i / eta_i``,
    ``x_i = xj_i + C_{i-1}``, going down from the whole system's centre of mass."""
    for k in range(3):
        c = xj[0, k]
        cv = vj[0, k]
        for i in range(x.shape[0] - 1, 0, -1):
            w = gm[i] / eta[i]
            c -= w * xj[i, k]
            x[i, k] = xj[i, k] + c
            if with_v:
                cv -= w * vj[i, k]
                v[i, k] = vj[i, k] + cv
        x[0, k] = c
        if with_v:
            v[0, k] = cv


@kernel(error_model="numpy")
def _jacobi_drift(xj, vj, m, t):
    """Every Jacobi row 1.. on its Kepler orbit of ``mu = eta_i`` for ``t`` (the centre of mass moves in
    the caller)."""
    for i in range(1, xj.shape[0]):
        _kepler_drift(xj, vj, i, m, t)


@kernel(error_model="numpy")
def _jacobi_kick(xj, vj, gm, eta, x, a, t):
    """``vj += t * (Jacobi acceleration of H_int)`` (module docstring); ``x, a``: scratch."""
    _from_jacobi(xj, vj, gm, eta, x, x, np.bool_(False))     # np.bool_/np.int64: see contact_params._NOT_LITERAL
    _pair_accel(x, gm, np.int64(0), np.bool_(True), a)
    n = x.shape[0]
    c0, c1, c2 = a[0, 0], a[0, 1], a[0, 2]            # A_{i-1}: mass-weighted mean acceleration of 0..i-1
    for i in range(1, n):
        aj0, aj1, aj2 = a[i, 0] - c0, a[i, 1] - c1, a[i, 2] - c2
        w = gm[i] / eta[i]
        c0 += w * aj0
        c1 += w * aj1
        c2 += w * aj2
        if i >= 2:                                    # body 1's Kepler term is the pair 0-1, left out
            r2 = xj[i, 0] * xj[i, 0] + xj[i, 1] * xj[i, 1] + xj[i, 2] * xj[i, 2]
            k = eta[i] / (r2 * np.sqrt(r2))
            aj0 += k * xj[i, 0]
            aj1 += k * xj[i, 1]
            aj2 += k * xj[i, 2]
        vj[i, 0] += t * aj0
        vj[i, 1] += t * aj1
        vj[i, 2] += t * aj2


@kernel(error_model="numpy")
def _corrector_z(xj, vj, gm, eta, m, x, a, ta, tb):
    """Wisdom, Holman & Touma's ``Z(a, b) = K(a) I(-b) K(-2a) I(b) K(a)`` (K: drift, I: kick)."""
    _jacobi_drift(xj, vj, m, ta)
    _jacobi_kick(xj, vj, gm, eta, x, a, -tb)
    _jacobi_drift(xj, vj, m, -2.0 * ta)
    _jacobi_kick(xj, vj, gm, eta, x, a, tb)
    _jacobi_drift(xj, vj, m, ta)


@kernel(error_model="numpy")
def _apply_corrector(xj, vj, gm, eta, m, x, a, table, dt, inverse):
    """The corrector (``table``: rows (a, b) in units of dt), or its inverse: the same operators with the
    kick coefficients negated (``Z(a, b)^-1 = Z(-a, b)``, and the product taken in the same order reads
    as the inverse because the table is symmetric: row k mirrors row -k with (-a, -b))."""
    s = -1.0 if inverse else 1.0
    for k in range(table.shape[0]):
        _corrector_z(xj, vj, gm, eta, m, x, a, table[k, 0] * dt, s * table[k, 1] * dt)


@kernel(error_model="numpy")
def _wh_jacobi(x, v, gm, dt, n_steps, table):
    n = x.shape[0]
    eta = np.empty(n)
    _prefix_masses(gm, eta)
    m = np.empty((n, 3))
    _mu_rows(eta, m)
    xj = np.empty_like(x)
    vj = np.empty_like(v)
    sx = np.empty_like(x)
    a = np.empty_like(x)
    _to_jacobi(x, v, gm, eta, xj, vj)
    if table.shape[0]:
        _apply_corrector(xj, vj, gm, eta, m, sx, a, table, dt, np.bool_(False))
    _jacobi_drift(xj, vj, m, 0.5 * dt)
    for s in range(n_steps):
        _jacobi_kick(xj, vj, gm, eta, sx, a, dt)
        _jacobi_drift(xj, vj, m, dt if s < n_steps - 1 else 0.5 * dt)
    for k in range(3):                                # the centre of mass: a straight line
        xj[0, k] += vj[0, k] * (n_steps * dt)
    if table.shape[0]:
        _apply_corrector(xj, vj, gm, eta, m, sx, a, table, dt, np.bool_(True))
    _from_jacobi(xj, vj, gm, eta, x, v, np.bool_(True))


# -- democratic heliocentric ------------------------------------------------------------------------------
@kernel(error_model="numpy")
def _jump(X, V, gm, t):
    """``X_i += t P/(G m_0)``, ``P = sum_{i>=1} G m_i V_i``: the democratic split's momentum term (here and in
    :mod:`framework.mercurius`, whose hybrid step is this split with the pulls switched)."""
    n = X.shape[0]
    p0 = 0.0
    p1 = 0.0
    p2 = 0.0
    for i in range(1, n):
        p0 += gm[i] * V[i, 0]
        p1 += gm[i] * V[i, 1]
        p2 += gm[i] * V[i, 2]
    s = t / gm[0]
    for i in range(1, n):
        X[i, 0] += s * p0
        X[i, 1] += s * p1
        X[i, 2] += s * p2


@kernel(error_model="numpy")
def _dh_kick_jump(X, V, gm, a, t_kick, t_jump, jump):
    """The pairs without body 0 kick the barycentric velocities for ``t_kick``; around it the jump
    ``X_i += t_jump P / (G m_0)``, ``P = sum G m_j V_j`` (when ``jump``: :func:`_jump`)."""
    n = X.shape[0]
    for side in range(2):
        if jump:
            _jump(X, V, gm, t_jump)
        if side == 0:
            _pair_accel(X, gm, np.int64(1), np.bool_(False), a)
            for i in range(1, n):
                for k in range(3):
                    V[i, k] += t_kick * a[i, k]


@kernel(error_model="numpy")
def _wh_democratic(x, v, gm, dt, n_steps, fixed):
    """Democratic heliocentric WH (``fixed``: body 0 an immovable well at its own constant velocity)."""
    n = x.shape[0]
    X = np.empty_like(x)
    V = np.empty_like(v)
    a = np.empty_like(x)
    gtot = 0.0
    for i in range(n):
        gtot += gm[i]
    cx = np.zeros(3)
    cv = np.zeros(3)
    for k in range(3):
        if fixed:
            cx[k] = x[0, k]
            cv[k] = v[0, k]
        else:
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
    _mu_rows(np.full(n, gm[0]), m)
    jump = not fixed
    for i in range(1, n):
        _kepler_drift(X, V, i, m, 0.5 * dt)
    for s in range(n_steps):
        _dh_kick_jump(X, V, gm, a, dt, 0.5 * dt, jump)
        h = dt if s < n_steps - 1 else 0.5 * dt
        for i in range(1, n):
            _kepler_drift(X, V, i, m, h)
    T = n_steps * dt
    for k in range(3):
        cx[k] += cv[k] * T
        if fixed:
            x[0, k] = cx[k]
        else:                                         # x_0 = C - sum m_i X_i / M,  v_0 = V_C - sum m_i V_i / m_0
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


# -- leapfrog -------------------------------------------------------------------------------------------
@kernel(error_model="numpy")
def _leapfrog(x, v, gm, dt, n_steps):
    n = x.shape[0]
    a = np.empty_like(x)
    h = 0.5 * dt
    for s in range(n_steps):
        for i in range(n):
            for k in range(3):
                x[i, k] += h * v[i, k]
        _pair_accel(x, gm, np.int64(0), np.bool_(False), a)
        h = dt if s < n_steps - 1 else 0.5 * dt
        for i in range(n):
            for k in range(3):
                v[i, k] += dt * a[i, k]
    for i in range(n):
        for k in range(3):
            x[i, k] += h * v[i, k]


# -- the public calls -----------------------------------------------------------------------------------
@kernel(error_model="numpy")
def _values_ok(x, v, gm):
    """Whether every position and velocity is finite and every gm finite and >= 0 (one pass, no temporaries:
    a game calls these kernels once a step)."""
    for i in range(x.shape[0]):
        if not (gm[i] >= 0.0 and gm[i] < np.inf):
            return False
        for k in range(3):
            if not (abs(x[i, k]) < np.inf and abs(v[i, k]) < np.inf):
                return False
    return True


def _checked(x, v, gm, dt, n_steps, what):
    for name, arr in (("x", x), ("v", v)):
        if not (isinstance(arr, np.ndarray) and arr.dtype == np.float64 and arr.ndim == 2 and arr.shape[1] == 3
                and arr.flags.c_contiguous and arr.flags.writeable):
            raise TypeError(f"{what}: {name} must be a writable C-contiguous float64 array of shape (n, 3), got "
                            f"{type(arr).__name__} {getattr(arr, 'dtype', '')} {getattr(arr, 'shape', '')}")
    gm = np.ascontiguousarray(gm, dtype=np.float64)
    if x.shape != v.shape or gm.shape != (x.shape[0],):
        raise ValueError(f"{what}: x {x.shape}, v {v.shape} and gm {gm.shape} must agree: (n, 3), (n, 3), (n,)")
    if not _values_ok(x, v, gm):
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
            raise ValueError(f"{what}: x and v must be finite")
        raise ValueError(f"{what}: gm must be finite and >= 0, got {gm[~(np.isfinite(gm) & (gm >= 0))][:3]}")
    if not (math.isfinite(dt) and dt != 0.0):
        raise ValueError(f"{what}: dt must be finite and non-zero, got {dt!r}")
    if isinstance(n_steps, bool) or int(n_steps) != n_steps or n_steps < 1:
        raise ValueError(f"{what}: n_steps must be a whole number >= 1, got {n_steps!r}")
    return gm


def wisdom_holman(x, v, gm, dt: float, n_steps: int = 1, *, coordinates: str = "jacobi", corrector: int = 0):
    """Advance ``n_steps`` Wisdom–Holman steps of ``dt`` in place; body 0 is the dominant mass.

    ``x, v``: ``(n, 3)`` float64 (C-contiguous, inertial frame); ``gm``: ``G m`` per body (``gm[0] > 0``;
    0 for a test particle, best placed last). ``coordinates``: ``"jacobi"`` (WHFast's default),
    ``"democratic"`` (democratic heliocentric) or ``"fixed"`` (body 0 an immovable well moving at its own
    constant velocity, pulled by nothing). ``corrector``: 0 or an order in :data:`CORRECTOR_ORDERS`
    (Jacobi only). Returns ``(x, v)``, the arrays given.
    """
    gm = _checked(x, v, gm, dt, n_steps, "wisdom_holman")
    if coordinates not in COORDINATES:
        raise ValueError(f"wisdom_holman: coordinates must be one of {COORDINATES}, got {coordinates!r}")
    if corrector not in CORRECTOR_ORDERS:
        raise ValueError(f"wisdom_holman: corrector must be one of {CORRECTOR_ORDERS}, got {corrector!r}")
    if corrector and coordinates != "jacobi":
        raise ValueError(f"wisdom_holman: the corrector needs Jacobi coordinates, got {coordinates!r}")
    if not gm[0] > 0.0:
        raise ValueError(f"wisdom_holman: body 0 is the dominant mass; its gm must be > 0, got {gm[0]!r}")
    if x.shape[0] < 2:
        return x, v
    if coordinates == "jacobi":
        _wh_jacobi(x, v, gm, float(dt), int(n_steps), _CORRECTORS[corrector])
    else:
        _wh_democratic(x, v, gm, float(dt), int(n_steps), coordinates == "fixed")
    return x, v


def leapfrog(x, v, gm, dt: float, n_steps: int = 1):
    """Advance ``n_steps`` drift-kick-drift leapfrog steps of ``dt`` in place on the mutual pulls
    (no dominant mass needed). Arguments as :func:`wisdom_holman`'s. Returns ``(x, v)``."""
    gm = _checked(x, v, gm, dt, n_steps, "leapfrog")
    _leapfrog(x, v, gm, float(dt), int(n_steps))
    return x, v


def pair_accel(x, gm):
    """The pull of every body on every other, ``a_i = sum_j G m_j (x_j - x_i)/|x_j - x_i|^3`` (each pair
    once, in a fixed order; two bodies at one point: none), as a new ``(n, 3)`` array."""
    gm = _checked(x, x, gm, 1.0, 1, "pair_accel")
    a = np.empty_like(x)
    _pair_accel(x, gm, np.int64(0), np.bool_(False), a)
    for i in np.flatnonzero(~np.isfinite(a).all(axis=1)):      # a body on another's point: that pair left out
        d = x - x[i]
        r2 = np.einsum("ij,ij->i", d, d)
        r2[r2 == 0.0] = np.inf
        a[i] = np.sum((gm / (r2 * np.sqrt(r2)))[:, None] * d, axis=0)
    return a


def kepler_drift(x, v, mu: float, t: float):
    """Each row of ``x, v`` (relative to a centre of ``mu``) moved along its Kepler orbit for ``t``, in place
    (the drift of :func:`wisdom_holman`, one body at a time). Returns ``(x, v)``."""
    gm = _checked(x, v, np.zeros(len(x)), t, 1, "kepler_drift")
    del gm
    if not (np.isfinite(mu) and mu > 0.0):
        raise ValueError(f"kepler_drift: mu must be finite and > 0, got {mu!r}")
    _kepler_drift_all(x, v, float(mu), float(t))
    return x, v


def energy(x, v, gm) -> float:
    """``G`` times the total energy, ``sum G m_i v_i^2/2 - sum_{i<j} G m_i G m_j / r_ij`` (numpy; for
    checks: divide by G for the energy itself)."""
    x = np.asarray(x, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    gm = np.asarray(gm, dtype=np.float64)
    kin = 0.5 * float(np.sum(gm * np.einsum("ij,ij->i", v, v)))
    pot = 0.0
    for i in range(len(x) - 1):
        r = np.linalg.norm(x[i + 1:] - x[i], axis=1)
        pot -= float(np.sum(gm[i] * gm[i + 1:] / r))
    return kin + pot
