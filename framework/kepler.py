"""The two-body (Kepler) problem, solved exactly and vectorised over many bodies.

A body moving only under a point mass ``mu`` (m^3/s^2) follows a conic. Given
its state ``(r0, v0)`` relative to the mass, :func:`propagate` returns the
state after ``dt`` seconds for every eccentricity — circle, ellipse, radial,
parabola, hyperbola — with one formula, the *universal variable* formulation
(Battin 1987, ch. 4; Vallado, *Fundamentals of Astrodynamics*, alg. 8)::

    alpha   = 2/|r0| - |v0|^2/mu            (1/a: > 0 ellipse, 0 parabola, < 0 hyperbola)
    sigma0  = r0.v0 / sqrt(mu)
    psi     = alpha chi^2
    sqrt(mu) dt = chi^3 c3(psi) + sigma0 chi^2 c2(psi) + |r0| chi (1 - psi c3(psi))   (*)

``chi`` (the universal anomaly, m^(1/2)) solves (*); ``c2, c3`` are Stumpff's
functions. Position and velocity follow from the Lagrange coefficients::

    r = f r0 + g v0,     f = 1 - chi^2 c2 / |r0|,       g = dt - chi^3 c3 / sqrt(mu)
    v = fd r0 + gd v0,   fd = sqrt(mu) chi (psi c3 - 1) / (|r| |r0|),   gd = 1 - chi^2 c2 / |r|

(*) is solved by Laguerre's method of order 5 (Conway 1986), which converges
from a rough first guess for any conic where Newton's method can cycle, then
polished by Newton steps. The derivatives of the right side of (*) in ``chi``
are ``|r|`` and ``dr/dchi = sigma0 (1 - psi c2) + (1 - alpha |r0|) chi (1 - psi c3)``.

Accuracy: an elliptic ``dt`` is first reduced modulo the period, so the work
and the rounding do not grow with the time propagated; energy and angular
momentum come back to a few units of the last place (``tests/test_kepler.py``,
``benchmarks/orbit_accuracy.py``). Stumpff's functions use their series near
``psi = 0`` (where ``1 - cos`` and ``x - sin x`` cancel) and half-angle forms
elsewhere.

Everything here is plain numpy on arrays of shape ``(n, 3)`` (states) and
``(n,)`` or scalars (``mu``, ``dt``): no components, no systems.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TWO_PI = 2.0 * np.pi
_EPS = np.finfo(np.float64).eps

# Series of c2 and c3 in psi: c2 = sum (-psi)^k / (2k+2)!, c3 = sum (-psi)^k / (2k+3)!;
# 12 terms at |psi| <= 1 leave a remainder below 1/27! ~ 1e-28.
_K = np.arange(12)
_C2_SERIES = np.array([(-1.0) ** k / float(np.prod(np.arange(1, 2 * k + 3, dtype=np.float64))) for k in _K])
_C3_SERIES = np.array([(-1.0) ** k / float(np.prod(np.arange(1, 2 * k + 4, dtype=np.float64))) for k in _K])
_C3_SERIES_ABS = np.abs(_C3_SERIES)
# k terms leave a remainder below 1e-18 where p^k 6 |c3_k| < 1e-18: log10 p < L_k (L_k grows with k)
_TERM_LIMIT = np.array([(-18.0 - np.log10(6.0 * _C3_SERIES_ABS[k])) / k for k in range(1, len(_K))])


def _series_terms(p: float) -> int:
    """Terms of the Stumpff series that leave a remainder below 1e-18 at |psi| <= p (<= 1)."""
    if p <= 0.0:
        return 1
    return int(np.searchsorted(_TERM_LIMIT, np.log10(p), side="right")) + 1


def stumpff(psi):
    """Stumpff's functions ``c2(psi), c3(psi)`` for any real ``psi`` (arrays broadcast).

    ``c2 = (1 - cos sqrt psi) / psi``, ``c3 = (sqrt psi - sin sqrt psi) / psi^(3/2)``
    for ``psi > 0``, the cosh/sinh forms for ``psi < 0``; ``c2(0) = 1/2``,
    ``c3(0) = 1/6``. ``|psi| <= 1`` uses the series (Horner, only as many
    terms as the largest ``|psi|`` needs), where the closed forms lose digits;
    ``1 - cos x`` is written ``2 sin^2(x/2)`` so it never cancels.
    """
    psi = np.asarray(psi, dtype=np.float64)
    if psi.ndim == 0:
        c2, c3 = stumpff(psi[None])
        return c2[0], c3[0]
    apsi = np.abs(psi)
    small = apsi <= 1.0
    n_small = int(np.count_nonzero(small))
    c2 = np.empty_like(psi)
    c3 = np.empty_like(psi)
    if n_small:
        # each branch on its own bodies only: a step on rails mostly has psi > 1, a short one psi < 1
        p = psi if n_small == psi.size else psi[small]
        terms = _series_terms(float(np.abs(p).max()))
        s2 = np.full_like(p, _C2_SERIES[terms - 1])
        s3 = np.full_like(p, _C3_SERIES[terms - 1])
        for k in range(terms - 2, -1, -1):
            s2 *= p
            s2 += _C2_SERIES[k]
            s3 *= p
            s3 += _C3_SERIES[k]
        if n_small == psi.size:
            return s2, s3
        c2[small] = s2
        c3[small] = s3
    big = ~small
    p = psi if not n_small else psi[big]
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        x = np.sqrt(np.abs(p))
        if (p > 0).all():
            s = np.sin(0.5 * x)
            b2 = 2.0 * s * s / p
            b3 = (x - np.sin(x)) / (p * x)
        else:
            pos = p > 0
            s = np.sin(0.5 * x)
            b2 = np.where(pos, 2.0 * s * s / p, (np.cosh(x) - 1.0) / (-p))
            b3 = np.where(pos, (x - np.sin(x)) / (p * x), (np.sinh(x) - x) / (-p * x))
    if not n_small:
        return b2, b3
    c2[big] = b2
    c3[big] = b3
    return c2, c3


def next_chi(chi, r, v, mu, step, *, origin=None):
    """A first guess for ``chi`` one ``step`` (s) further on, from the last solution ``chi`` and its
    state ``r, v``: the Taylor series ``chi + chi' step + chi'' step^2 / 2`` with
    ``chi' = sqrt(mu)/|r|`` and ``chi'' = -sqrt(mu) (r.v)/|r|^3`` (``d|r|/dt = r.v/|r|``). Good to
    ``step^3``: one Laguerre step then lands on the root, for a body propagated step after step
    from one epoch. Where the step sweeps a large anomaly (``|alpha| dchi^2 > 0.2``: a coarse step
    past periapsis) it gives NaN instead, and the solver starts from Kepler's equation (Danby's
    guess), which is better there. ``origin = (X, V)``: ``r`` and ``v`` are absolute and the well
    is at ``X`` moving at ``V`` (3-vectors); the relative state is then formed inside. From
    :data:`COMPILED_MIN` bodies the same formulas run in one compiled pass."""
    r = np.atleast_2d(r)
    v = np.atleast_2d(v)
    if origin is not None:
        X, V = (np.asarray(o, dtype=np.float64).reshape(3) for o in origin)
    else:
        X = V = _ZERO3
    chi = np.asarray(chi, dtype=np.float64)
    if r.shape[0] >= COMPILED_MIN and chi.shape == (r.shape[0],) and r.dtype == v.dtype == np.float64:
        out = np.empty(r.shape[0])
        _next_chi_compiled(chi, r, v, X, V, float(mu), float(step), out)
        return out
    if origin is not None:
        r = r - X
        v = v - V
    rn2 = _dot(r, r)
    rn = np.sqrt(rn2)
    rv = _dot(r, v)
    d1 = np.sqrt(mu / rn2)
    dchi = step * d1 * (1.0 - 0.5 * step * rv / rn2)
    alpha = 2.0 / rn - _dot(v, v) / mu
    return np.where(np.abs(alpha) * dchi * dchi <= 0.2, chi + dchi, np.nan)


_ZERO3 = np.zeros(3)


def _as_states(r0, v0, mu, dt):
    r0 = np.atleast_2d(np.asarray(r0, dtype=np.float64))
    v0 = np.atleast_2d(np.asarray(v0, dtype=np.float64))
    n = r0.shape[0]
    mu = np.broadcast_to(np.asarray(mu, dtype=np.float64), (n,))
    dt = np.broadcast_to(np.asarray(dt, dtype=np.float64), (n,))
    return r0, v0, mu, dt


def _norm(a):
    return np.sqrt(np.einsum("ij,ij->i", a, a))


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def period(alpha, mu):
    """Orbital period ``2 pi sqrt(a^3/mu)`` (s) for ``alpha = 1/a > 0``; ``inf`` otherwise."""
    alpha = np.asarray(alpha, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(alpha > 0, TWO_PI / np.sqrt(np.asarray(mu) * np.abs(alpha) ** 3), np.inf)


def solve_universal(r0n, sigma0, alpha, mu, dt, chi=None, *, iterations: int = 60, span_rate=None):
    """Solve (*) for ``chi``, vectorised; bodies drop out of the arrays as they converge.

    ``r0n`` = |r0| (m), ``sigma0`` = r0.v0/sqrt(mu), ``alpha`` = 1/a (1/m),
    ``dt`` (s). ``chi`` may carry a first guess. Returns ``chi, psi, c2, c3, r``
    at the solution (``r = |r(dt)|``).

    Safeguarded: the right side of (*) grows monotonically in ``chi`` (its
    derivative is ``|r| > 0``), so every evaluation narrows a bracket
    ``[lo, hi]`` around the root, and a step that would leave it bisects
    instead. The bracket starts at ``[0, inf)`` (``dt > 0``; mirrored for
    ``dt < 0``), for ellipses ``[0, (|dM| + 2) sqrt(a)]``, since
    ``chi = sqrt(a) dE`` and ``dE - dM = e (sin E1 - sin E0)`` is at most 2.
    So a poor guess (a warm start across periapsis) costs iterations, never the answer.
    ``span_rate``: ``(sqrt(mu alpha^3), sqrt(|a|))`` where already known (:class:`Epoch`).
    """
    target = np.sqrt(mu) * dt
    chi = _first_guess(r0n, sigma0, alpha, mu, dt) if chi is None else np.array(chi, dtype=np.float64)
    n = chi.shape[0]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        if span_rate is None:
            span_rate = (np.where(alpha > 0, np.sqrt(mu * alpha ** 3), np.inf), np.sqrt(1.0 / np.abs(alpha)))
        span = (span_rate[0] * np.abs(dt) + 2.0) * span_rate[1]       # inf for open orbits
    neg = dt < 0
    lo = np.where(neg, -span, 0.0)
    hi = np.where(neg, 0.0, span)
    outside = ~((chi >= lo) & (chi <= hi))            # (NaN is outside too)
    if outside.any():
        chi[outside] = _first_guess(r0n[outside], sigma0[outside], alpha[outside], mu[outside], dt[outside])
        chi = np.clip(chi, lo, hi)
    out = None                                       # chi, psi, c2, c3, |r| at the solution
    idx = None                                       # None: all bodies; else the ones still iterating
    tol = 4.0 * _EPS
    for it in range(iterations):
        a_, s_, r_, t_ = (alpha, sigma0, r0n, target) if idx is None else \
            (alpha[idx], sigma0[idx], r0n[idx], target[idx])
        chi2 = chi * chi
        psi = a_ * chi2
        c2, c3 = stumpff(psi)
        one_c3 = 1.0 - psi * c3
        one_c2 = 1.0 - psi * c2
        s_chi = s_ * chi
        ta = chi2 * chi * c3
        tb = s_chi * chi * c2
        tc = r_ * chi * one_c3
        f = ta + tb + tc - t_
        fp = chi2 * c2 + s_chi * one_c3 + r_ * one_c2                   # = |r(chi)| > 0
        # converged when f is within the rounding of its own terms (a few ulp of the largest: near
        # periapsis of an eccentric orbit they cancel): this evaluation's c2, c3 and |r| are then the
        # solution's, and no extra pass is needed
        done = np.abs(f) <= tol * (np.abs(ta) + np.abs(tb) + np.abs(tc) + np.abs(t_))
        if it == iterations - 1:
            done[:] = True                           # out of iterations: take the last iterate
        else:
            done |= ~np.isfinite(f)
        all_done = bool(done.all())
        if all_done and idx is None:
            return chi, psi, c2, c3, fp              # the usual case: every body at once, no copies
        # while most bodies still iterate, iterate them all (a converged one only moves by ulp, and
        # gathering costs more than the arithmetic); take them out once they are the minority
        whole = idx is None and not all_done and np.count_nonzero(done) * 2 < n
        if whole:
            done[:] = False
        if out is None and not whole:
            out = [np.empty(n) for _ in range(5)]
        if not whole:
            where = (np.flatnonzero(done) if idx is None else idx[done]) if not all_done else idx
            for o, val in zip(out, (chi, psi, c2, c3, fp)):
                o[where] = val if all_done else val[done]
            if all_done:
                break
        # narrow the bracket: (*) is increasing in chi
        above = f > 0
        np.copyto(hi, chi, where=above & (chi < hi))
        np.copyto(lo, chi, where=~above & (chi > lo))
        if it < 8:   # Laguerre, order 5 (Conway 1986): converges from a rough guess for any conic
            fpp = s_ * one_c2 + (1.0 - a_ * r_) * chi * one_c3             # = dr/dchi
            disc = np.abs(16.0 * fp * fp - 20.0 * f * fpp)               # (n-1)^2 fp^2 - n(n-1) f fpp, n = 5
            new = chi - 5.0 * f / (fp + np.copysign(np.sqrt(disc), fp))
        else:        # Newton near the root: quadratic, never stalls on a flat denominator
            new = chi - f / fp
        leave = ~((new >= lo) & (new <= hi))         # (a converged body, f = 0, sits on its bound)
        if leave.any():                               # bisect (or double towards an open end)
            mid = np.where(np.isfinite(hi), 0.5 * (lo + hi), np.maximum(2.0 * np.abs(lo), 1.0))
            mid = np.where(np.isfinite(lo), mid, np.minimum(-2.0 * np.abs(hi), -1.0))
            new = np.where(leave, mid, new)
        if whole:
            chi = new
            continue
        # keep iterating only the bodies that have not converged (most converge in one or two)
        keep = ~done
        chi, lo, hi = new[keep], lo[keep], hi[keep]
        idx = np.flatnonzero(keep) if idx is None else idx[keep]
    return tuple(out)


def _first_guess(r0n, sigma0, alpha, mu, dt):
    """A starting chi for every conic; Laguerre's method needs no better.

    Short steps (``alpha chi^2 <= 0.1``, the usual case in a fixed-step game):
    the reversion of (*) to third order, ``sqrt(mu) dt = r0 chi + sigma0 chi^2/2
    + (1 - alpha r0) chi^3/6 + ...``. Long steps: Vallado's guesses (alg. 8),
    ``chi = sqrt(mu) dt alpha`` for ellipses and the logarithmic one for hyperbolas.
    """
    sqmu = np.sqrt(mu)
    u = sqmu * dt / r0n
    w = u / r0n
    chi = u * (1.0 - 0.5 * sigma0 * w + (0.5 * sigma0 * sigma0 - r0n * (1.0 - alpha * r0n) / 6.0) * w * w)
    long_step = (np.abs(alpha) * chi * chi > 0.1) | ~np.isfinite(chi)
    if not long_step.any():
        return chi
    k = np.flatnonzero(long_step)
    chi[k] = _long_guess(r0n[k], sigma0[k], alpha[k], mu[k], dt[k])
    return chi


def _long_guess(r0n, sigma0, alpha, mu, dt):
    """chi for long steps from the anomalies: ``chi = sqrt(a) dE`` (ellipse), ``sqrt(-a) dH``
    (hyperbola), with the new anomaly from Kepler's equation (Danby's start, three Newton steps)."""
    sqmu = np.sqrt(mu)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        sa = np.sqrt(1.0 / np.abs(alpha))                    # sqrt(|a|)
        ec = 1.0 - r0n * alpha                                # e cos E0 | e cosh H0
        es = sigma0 * np.sqrt(np.abs(alpha))                  # e sin E0 | e sinh H0  (r.v / sqrt(mu |a|))
        nmean = sqmu * np.abs(alpha) ** 1.5
        ell = alpha > 0
        # ellipse
        e_e = np.hypot(ec, es)
        E0 = np.arctan2(es, ec)
        M1 = E0 - es + nmean * dt
        E = M1 + 0.85 * e_e * np.sign(np.sin(M1))
        for _ in range(3):
            E = E - (E - e_e * np.sin(E) - M1) / (1.0 - e_e * np.cos(E))
        chi_e = sa * (E - E0)
        # hyperbola
        e_h = np.sqrt(np.maximum(ec * ec - es * es, 0.0))
        H0 = np.arcsinh(es / np.where(e_h > 0, e_h, 1.0))
        Mh = es - H0 + nmean * dt
        H = np.arcsinh(Mh / np.where(e_h > 0, e_h, 1.0))
        for _ in range(3):
            H = H - (e_h * np.sinh(H) - H - Mh) / (e_h * np.cosh(H) - 1.0)
        chi_h = sa * (H - H0)
    chi = np.where(ell, chi_e, chi_h)
    # near-parabolic or degenerate: the straight-line guess has the right sign and Laguerre does the rest
    bad = ~np.isfinite(chi) | (chi * dt < 0)
    return np.where(bad, sqmu * dt / r0n, chi)


#: Bodies from which Epoch.at with a guess uses the compiled loop (below: numpy, whose per-call
#: overhead is smaller than numba's dispatch for a handful of bodies... and equal results either way).
COMPILED_MIN = 64


class Epoch:
    """States ``(r0, v0)`` about ``mu`` with what :func:`propagate` derives from them computed once:
    for bodies propagated from one epoch step after step (on rails), only ``dt`` changes."""

    __slots__ = ("r0", "v0", "mu", "sqmu", "r0n", "alpha", "sigma0", "period", "chi_turn", "span_rate", "_compiled")

    def __init__(self, r0, v0, mu):
        r0 = np.atleast_2d(np.asarray(r0, dtype=np.float64))
        v0 = np.atleast_2d(np.asarray(v0, dtype=np.float64))
        self.r0, self.v0 = r0, v0
        self._compiled = None
        self.mu = np.broadcast_to(np.asarray(mu, dtype=np.float64), (r0.shape[0],))
        self.sqmu = np.sqrt(self.mu)
        self.r0n = _norm(r0)
        with np.errstate(divide="ignore", invalid="ignore"):
            self.alpha = 2.0 / self.r0n - _dot(v0, v0) / self.mu
            self.sigma0 = _dot(r0, v0) / self.sqmu
            self.period = period(self.alpha, self.mu)
            # one whole orbit is chi = 2 pi sqrt(a); zero for open orbits
            self.chi_turn = np.where(self.alpha > 0, TWO_PI / np.sqrt(np.abs(self.alpha)), 0.0)
            # the solver's bracket for ellipses: |chi| <= (n |dt| + 2) sqrt(a)
            self.span_rate = (np.where(self.alpha > 0, np.sqrt(self.mu * np.abs(self.alpha) ** 3), np.inf),
                              np.sqrt(1.0 / np.abs(self.alpha)))

    def at(self, dt, chi=None):
        """``r, v, chi`` after ``dt`` s (scalar or ``(n,)``); ``chi``: a first guess (:func:`next_chi`).

        Many bodies with a guess (on rails) go through the compiled loop (:data:`COMPILED_MIN`);
        the numpy path below is the same solution, array by array."""
        n = self.r0.shape[0]
        if chi is not None and n >= COMPILED_MIN:
            dt = np.ascontiguousarray(np.broadcast_to(np.asarray(dt, dtype=np.float64), (n,)))
            # (a guess that is not finite fails the loop's bracket test and is replaced there)
            guess = np.ascontiguousarray(np.broadcast_to(np.asarray(chi, dtype=np.float64), (n,)))
            out_r = np.empty((n, 3))
            out_v = np.empty((n, 3))
            out_chi = np.empty(n)
            c = self._compiled
            if c is None:                                  # contiguous copies, made once per epoch
                c = self._compiled = tuple(np.ascontiguousarray(a) for a in (
                    self.r0, self.v0, self.mu, self.sqmu, self.r0n, self.alpha, self.sigma0, self.period,
                    self.chi_turn, self.span_rate[0], self.span_rate[1]))
            _at_compiled(*c, dt, guess, out_r, out_v, out_chi)
            return out_r, out_v, out_chi
        dt = np.broadcast_to(np.asarray(dt, dtype=np.float64), (n,))
        guess = None if chi is None else np.array(np.broadcast_to(chi, (n,)), dtype=np.float64)
        # ellipses: take whole periods off dt, so the rounding and the work do not grow with time
        with np.errstate(invalid="ignore"):
            longer = np.abs(dt) > self.period              # (period is inf for open orbits)
        turns = None
        dt_red = dt
        if longer.all():                                   # on rails after the first orbit
            turns = np.round(dt / self.period)
            dt_red = dt - self.period * turns
        elif longer.any():
            per = np.where(longer, self.period, 1.0)        # (inf * 0 would be NaN)
            turns = np.where(longer, np.round(dt / per), 0.0)
            dt_red = np.where(longer, dt - per * turns, dt)
        if turns is not None and guess is not None:
            guess -= turns * self.chi_turn
        r0, v0, r0n, sqmu = self.r0, self.v0, self.r0n, self.sqmu
        chi, psi, c2, c3, rn = solve_universal(r0n, self.sigma0, self.alpha, self.mu, dt_red, guess,
                                               span_rate=self.span_rate)
        chi2 = chi * chi
        f = 1.0 - chi2 * c2 / r0n
        # g from chi alone (it equals dt - chi^3 c3 / sqrt(mu) at the root of (*)): then f, g, fd, gd all
        # follow from one chi, so the new state lies on the same conic to rounding even where chi is a
        # few ulp off the root -- a timing error of that size, never an energy error (which would build up)
        g = (r0n * chi * (1.0 - psi * c3) + self.sigma0 * chi2 * c2) / sqmu
        with np.errstate(divide="ignore", invalid="ignore"):
            fd = sqmu * chi * (psi * c3 - 1.0) / (rn * r0n)
            gd = 1.0 - chi2 * c2 / rn
        r = f[:, None] * r0 + g[:, None] * v0
        v = fd[:, None] * r0 + gd[:, None] * v0
        zero = dt_red == 0.0                                 # dt = 0 exactly: the same state, bit for bit
        if zero.any():
            r[zero] = r0[zero]
            v[zero] = v0[zero]
        if turns is not None:                                # chi of the whole dt, whole orbits included
            chi = chi + turns * self.chi_turn
        return r, v, chi


def propagate(r0, v0, mu, dt, *, chi=None, return_chi: bool = False):
    """State after ``dt`` seconds on the conic through ``(r0, v0)`` about a point mass ``mu``.

    ``r0`` (m) and ``v0`` (m/s) are ``(n, 3)`` (or ``(3,)``) relative to the
    mass, in any inertial frame; ``mu`` (m^3/s^2, > 0) and ``dt`` (s, either
    sign) are scalars or ``(n,)``. Returns ``r, v`` with the shape of ``r0``
    (and ``chi``, the universal anomaly of the solution, with ``return_chi``).
    ``chi``: a first guess (:func:`next_chi` gives one for a body propagated
    step after step). A body with ``r0 = 0`` has no defined orbit and gets NaN.
    For many calls from the same states, :class:`Epoch` derives what depends
    on them only once.
    """
    single = np.ndim(r0) == 1
    r, v, chi = Epoch(r0, v0, mu).at(dt, chi)
    if single:
        r, v, chi = r[0], v[0], chi[0]
    if return_chi:
        return r, v, chi
    return r, v


# --------------------------------------------------------------------------- elements
@dataclass(frozen=True)
class Elements:
    """Orbit readouts of states about one mass; arrays of shape ``(n,)`` (``h``, ``e_vec``: ``(n, 3)``).

    Lengths in m, times in s, energies in J/kg. Open orbits (``e >= 1``) have
    ``apoapsis = period = time_to_apoapsis = inf``; ``time_to_periapsis`` is
    negative once a hyperbolic body is past periapsis (it will not come back).
    """

    #: Semi-major axis, m (negative for hyperbolas, inf for a parabola).
    a: np.ndarray
    #: Eccentricity (0 circle, < 1 ellipse, 1 parabola or radial, > 1 hyperbola).
    e: np.ndarray
    #: Eccentricity vector (points at periapsis), world frame.
    e_vec: np.ndarray
    #: Specific angular momentum r x v, world frame, m^2/s.
    h: np.ndarray
    #: Specific orbital energy v^2/2 - mu/r, J/kg.
    energy: np.ndarray
    #: Distances from the mass's centre, m.
    periapsis: np.ndarray
    apoapsis: np.ndarray
    #: s.
    period: np.ndarray
    time_to_periapsis: np.ndarray
    time_to_apoapsis: np.ndarray


def elements(r, v, mu) -> Elements:
    """Readouts of the conics through states ``(r, v)`` about ``mu`` (see :class:`Elements`).

    Periapsis ``p / (1 + e)`` with ``p = h^2/mu`` (exact for radial orbits too:
    ``p = 0``); times from Kepler's equation in the eccentric (or hyperbolic)
    anomaly, ``M = E - e sin E``, ``M = e sinh H - H``.
    """
    r = np.atleast_2d(np.asarray(r, dtype=np.float64))
    v = np.atleast_2d(np.asarray(v, dtype=np.float64))
    n = r.shape[0]
    mu = np.broadcast_to(np.asarray(mu, dtype=np.float64), (n,))
    rn = _norm(r)
    v2 = _dot(v, v)
    rv = _dot(r, v)
    h = np.cross(r, v)
    with np.errstate(divide="ignore", invalid="ignore"):
        e_vec = ((v2 - mu / rn)[:, None] * r - rv[:, None] * v) / mu[:, None]
        e = _norm(e_vec)
        energy = 0.5 * v2 - mu / rn
        alpha = 2.0 / rn - v2 / mu
        a = 1.0 / alpha
        p = _dot(h, h) / mu
        rp = np.where(p > 0, p / (1.0 + e), np.where(alpha > 0, a * (1.0 - e), 0.0))
        ra = np.where(alpha > 0, a * (1.0 + e), np.inf)
        per = period(alpha, mu)
        # elliptic: eccentric anomaly E from e cos E = 1 - r/a, e sin E = r.v / sqrt(mu a)
        ell = alpha > 0                            # bound (radial ones have e = 1 to rounding)
        cosE = 1.0 - rn * alpha
        sinE = rv / np.sqrt(mu * np.abs(a))
        E = np.arctan2(sinE, cosE)
        M = E - sinE                               # e sin E = sinE as defined
        nmean = np.sqrt(mu * np.abs(alpha) ** 3)
        t_peri_e = np.mod(-M, TWO_PI) / nmean
        t_apo_e = np.mod(np.pi - M, TWO_PI) / nmean
        # hyperbolic: e sinh H = r.v / sqrt(-mu a), e cosh H = 1 - r/a
        sinhH_e = rv / np.sqrt(mu * np.abs(a))
        H = np.arcsinh(sinhH_e / np.where(e > 0, e, 1.0))
        Mh = sinhH_e - H
        t_peri_h = -Mh / nmean
        # parabola (alpha = 0): Barker, D = r.v/sqrt(mu), t_p = -(p D/2 + D^3/6)... via D
        D = rv / np.sqrt(mu)
        t_peri_p = -(p * D + D ** 3 / 3.0) / (2.0 * np.sqrt(mu))
    t_peri = np.where(ell, t_peri_e, np.where(alpha < 0, t_peri_h, t_peri_p))
    t_apo = np.where(ell, t_apo_e, np.inf)
    return Elements(a=a, e=e, e_vec=e_vec, h=h, energy=energy, periapsis=rp, apoapsis=ra,
                    period=per, time_to_periapsis=t_peri, time_to_apoapsis=t_apo)


# --------------------------------------------------------------------------- contacts
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


def _mean_anomaly_e(el: Elements, idx):
    """Mean anomaly now (elliptic, mod 2 pi), from the time to periapsis."""
    return -el.time_to_periapsis[idx] * (TWO_PI / el.period[idx])


def closest_approach(r1, v1, r2, v2, mu, horizon, *, samples: int = 256):
    """When and how close two bodies on conics about the same mass come, within ``[0, horizon]`` s.

    ``r1, v1`` and ``r2, v2`` are single states (3,) relative to the mass.
    The distance is sampled at ``samples`` times along both exact conics and
    the smallest sample is refined by golden-section search on its bracket
    (the distance is smooth; one bracket of 1/samples of the horizon holds one
    minimum for any sensible sample count). Returns ``(t, distance)``.
    """
    horizon = float(horizon)
    ts = np.linspace(0.0, horizon, samples + 1)
    n = ts.size
    a, _ = propagate(np.repeat(np.atleast_2d(r1), n, 0), np.repeat(np.atleast_2d(v1), n, 0), mu, ts)
    b, _ = propagate(np.repeat(np.atleast_2d(r2), n, 0), np.repeat(np.atleast_2d(v2), n, 0), mu, ts)
    d = _norm(a - b)
    k = int(np.argmin(d))
    lo, hi = ts[max(k - 1, 0)], ts[min(k + 1, n - 1)]

    def dist(t):
        pa, _ = propagate(r1, v1, mu, t)
        pb, _ = propagate(r2, v2, mu, t)
        return float(np.linalg.norm(pa - pb))

    g = (np.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1, f2 = dist(x1), dist(x2)
    for _ in range(60):
        if hi - lo <= 1e-9 * max(horizon, 1.0):
            break
        if f1 < f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - g * (hi - lo)
            f1 = dist(x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + g * (hi - lo)
            f2 = dist(x2)
    t = 0.5 * (lo + hi)
    dt_ = dist(t)
    if d[k] < dt_:
        return float(ts[k]), float(d[k])
    return float(t), dt_


def orbit_points(r, v, mu, n: int = 128, *, max_radius: float | None = None):
    """``n`` points (n, 3) along the conic through ``(r, v)``, for drawing the predicted orbit.

    Ellipses: one period at equal steps of eccentric anomaly (dense near
    periapsis, where the path bends). Open orbits: from now out to
    ``max_radius`` (default 4 x the current distance), equal steps in time.
    """
    r = np.asarray(r, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    el = elements(r, v, mu)
    if el.e[0] < 1.0 and np.isfinite(el.period[0]):
        # times of equally spaced eccentric anomalies from now
        E0 = -el.time_to_periapsis[0] * TWO_PI / el.period[0]        # mean anomaly now
        Es = np.linspace(0.0, TWO_PI, n)
        M = Es - el.e[0] * np.sin(Es)
        t = np.mod(M - E0, TWO_PI) * el.period[0] / TWO_PI
        pts, _ = propagate(np.repeat(r[None], n, 0), np.repeat(v[None], n, 0), mu, t)
        return pts
    rmax = max_radius if max_radius is not None else 4.0 * float(np.linalg.norm(r))
    # time to reach rmax outbound: bracket by doubling
    horizon = float(np.linalg.norm(r) / max(np.linalg.norm(v), 1e-12))
    for _ in range(60):
        p, _ = propagate(r, v, mu, horizon)
        if np.linalg.norm(p) >= rmax:
            break
        horizon *= 2.0
    t = np.linspace(0.0, horizon, n)
    pts, _ = propagate(np.repeat(r[None], n, 0), np.repeat(v[None], n, 0), mu, t)
    return pts


# --------------------------------------------------------------------------- compiled path
# The same solution, one body at a time in a compiled loop (numba, a dependency of the collision
# kernels): one pass over the columns instead of ~170 numpy passes. Formulas and tolerances are
# those above: Stumpff's series for |psi| <= 1 (12 terms, Horner), the half-angle closed forms
# beyond; Laguerre (n = 5) from the guess, bracketed, Newton after 8 iterations; f, g from chi.
from driftframe.framework.kernels import kernel  # noqa: E402


@kernel
def _stumpff1(psi):
    if abs(psi) <= 1.0:
        c2 = 0.0
        c3 = 0.0
        for k in range(11, -1, -1):
            c2 = c2 * psi + _C2_NB[k]
            c3 = c3 * psi + _C3_NB[k]
        return c2, c3
    x = np.sqrt(abs(psi))
    if psi > 0:
        s = np.sin(0.5 * x)
        return 2.0 * s * s / psi, (x - np.sin(x)) / (psi * x)
    return (np.cosh(x) - 1.0) / (-psi), (np.sinh(x) - x) / (-psi * x)


_C2_NB = _C2_SERIES.copy()
_C3_NB = _C3_SERIES.copy()


@kernel
def _next_chi_compiled(chi, r, v, X, V, mu, step, out):
    """:func:`next_chi` for ``(n, 3)`` states relative to ``X, V``, one body at a time."""
    for i in range(r.shape[0]):
        r0, r1, r2 = r[i, 0] - X[0], r[i, 1] - X[1], r[i, 2] - X[2]
        v0, v1, v2 = v[i, 0] - V[0], v[i, 1] - V[1], v[i, 2] - V[2]
        rn2 = r0 * r0 + r1 * r1 + r2 * r2
        rn = np.sqrt(rn2)
        rv = r0 * v0 + r1 * v1 + r2 * v2
        d1 = np.sqrt(mu / rn2)
        dchi = step * d1 * (1.0 - 0.5 * step * rv / rn2)
        alpha = 2.0 / rn - (v0 * v0 + v1 * v1 + v2 * v2) / mu
        out[i] = chi[i] + dchi if abs(alpha) * dchi * dchi <= 0.2 else np.nan


@kernel
def _at_compiled(r0, v0, mu, sqmu, r0n, alpha, sigma0, period, chi_turn, span0, span1, dt, guess,
                 out_r, out_v, out_chi):
    """Returns the number of bodies that needed the numpy path (a guess outside the bracket)."""
    n = r0.shape[0]
    tol = 4.0 * 2.220446049250313e-16
    for i in range(n):
        t = dt[i]
        turns = 0.0
        if abs(t) > period[i]:
            turns = np.round(t / period[i])
            t = t - period[i] * turns
        target = sqmu[i] * t
        al = alpha[i]
        s0 = sigma0[i]
        rn = r0n[i]
        span = (span0[i] * abs(t) + 2.0) * span1[i]
        lo = -span if t < 0 else 0.0
        hi = 0.0 if t < 0 else span
        chi = guess[i] - turns * chi_turn[i]
        if not (chi >= lo and chi <= hi):
            chi = sqmu[i] * t / rn                       # the straight-line start: right sign, Laguerre does the rest
            if chi < lo:
                chi = lo
            if chi > hi:
                chi = hi
        psi = 0.0
        c2 = 0.5
        c3 = 1.0 / 6.0
        fp = rn
        for it in range(60):
            chi2 = chi * chi
            psi = al * chi2
            c2, c3 = _stumpff1(psi)
            one_c3 = 1.0 - psi * c3
            one_c2 = 1.0 - psi * c2
            ta = chi2 * chi * c3
            tb = s0 * chi2 * c2
            tc = rn * chi * one_c3
            f = ta + tb + tc - target
            fp = chi2 * c2 + s0 * chi * one_c3 + rn * one_c2
            if abs(f) <= tol * (abs(ta) + abs(tb) + abs(tc) + abs(target)) or not np.isfinite(f):
                break
            if f > 0:
                hi = min(hi, chi)
            else:
                lo = max(lo, chi)
            if it < 8:
                fpp = s0 * one_c2 + (1.0 - al * rn) * chi * one_c3
                disc = abs(16.0 * fp * fp - 20.0 * f * fpp)
                new = chi - 5.0 * f / (fp + np.copysign(np.sqrt(disc), fp))
            else:
                new = chi - f / fp
            if not (new >= lo and new <= hi):
                if np.isfinite(hi) and np.isfinite(lo):
                    new = 0.5 * (lo + hi)
                elif np.isfinite(lo):
                    new = max(2.0 * abs(lo), 1.0)
                else:
                    new = min(-2.0 * abs(hi), -1.0)
            chi = new
        chi2 = chi * chi
        f_ = 1.0 - chi2 * c2 / rn
        g_ = (rn * chi * (1.0 - psi * c3) + s0 * chi2 * c2) / sqmu[i]
        fd = sqmu[i] * chi * (psi * c3 - 1.0) / (fp * rn)
        gd = 1.0 - chi2 * c2 / fp
        if t == 0.0:
            f_, g_, fd, gd = 1.0, 0.0, 0.0, 1.0
        for k in range(3):
            out_r[i, k] = f_ * r0[i, k] + g_ * v0[i, k]
            out_v[i, k] = fd * r0[i, k] + gd * v0[i, k]
        out_chi[i] = chi + turns * chi_turn[i]
    return 0


@kernel
def _arc_boxes_compiled(p, w, pe, we, span, mu, surface, ball, grow_by, lo, hi, accel, rho_out):
    for i in range(p.shape[0]):
        rn = np.sqrt(p[i, 0] ** 2 + p[i, 1] ** 2 + p[i, 2] ** 2)
        rn_e = np.sqrt(pe[i, 0] ** 2 + pe[i, 1] ** 2 + pe[i, 2] ** 2)
        w2 = w[i, 0] ** 2 + w[i, 1] ** 2 + w[i, 2] ** 2
        energy = 0.5 * w2 - mu / rn
        hx = p[i, 1] * w[i, 2] - p[i, 2] * w[i, 1]
        hy = p[i, 2] * w[i, 0] - p[i, 0] * w[i, 2]
        hz = p[i, 0] * w[i, 1] - p[i, 1] * w[i, 0]
        h2 = hx * hx + hy * hy + hz * hz
        e = np.sqrt(max(1.0 + 2.0 * energy * h2 / (mu * mu), 0.0))
        q = h2 / mu / (1.0 + e)
        alpha = -2.0 * energy / mu
        half_period = np.pi / np.sqrt(mu * alpha ** 3) if alpha > 0 else np.inf
        rdot = p[i, 0] * w[i, 0] + p[i, 1] * w[i, 1] + p[i, 2] * w[i, 2]
        rdot_e = pe[i, 0] * we[i, 0] + pe[i, 1] * we[i, 1] + pe[i, 2] * we[i, 2]
        if ball[i]:
            rho = max(q, surface)
            grow = np.sqrt(2.0 * max(energy + mu / rho, 0.0)) * span + 1e-12 * rn
            for k in range(3):
                lo[i, k] = p[i, k] - grow - grow_by[i]
                hi[i, k] = p[i, k] + grow + grow_by[i]
        else:
            if (rdot <= 0.0 and rdot_e >= 0.0) or span >= half_period:
                rho = max(q, surface)
            else:
                rho = max(min(rn, rn_e), surface)
            grow = 0.125 * (mu / (rho * rho)) * span * span + 1e-12 * (rn + rn_e)
            for k in range(3):
                lo[i, k] = min(p[i, k], pe[i, k]) - grow - grow_by[i]
                hi[i, k] = max(p[i, k], pe[i, k]) + grow + grow_by[i]
        accel[i] = mu / (rho * rho)
        rho_out[i] = rho


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
