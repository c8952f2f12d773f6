"""The universal-variable solution of the two-body problem in numpy: Stumpff's functions, the solver of
Kepler's equation, :class:`Epoch` (what a state's propagation needs, derived once) and :func:`propagate`.
The formulas are in :mod:`driftframe.framework.kepler`'s text; the compiled twin is
:mod:`driftframe.framework.kepler_kernels`."""
from __future__ import annotations

import numpy as np

from driftframe.framework.kepler_kernels import (_C2_SERIES, _C3_SERIES, _at_compiled, _quiet_rails, _dd_div, _dd_dot2,
                                                 _dd_sqrt, _fast_two_sum, _focal1, _focal_dd, _focal_dd_constants,
                                                 _focal_dd_constants_hyp, _focal_dd_hyp, _hyp_half,
                                                 _next_chi_compiled, _two_prod, _two_sum)

TWO_PI = 2.0 * np.pi
_EPS = np.finfo(np.float64).eps
from driftframe.framework.kepler_small import _TERM_LIMIT, DONE, _at_small, _next_chi_small


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
    if (origin is not None and chi.shape == (r.shape[0],) and r.dtype == v.dtype == np.float64 and r.shape[1] == 3
            and np.ndim(mu) == 0 and np.ndim(step) == 0):
        # a few bodies (on rails): the numpy lines below in one compiled pass, their bits (kepler_small)
        out = np.empty(r.shape[0])
        _next_chi_small(*(np.array(a, dtype=np.float64) for a in (chi, r, v, X, V)), float(mu), float(step), out)
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


#: The compiled loop's arguments for a plain Epoch.at (no states at a step's start: not the step on rails).
_NOT_ON_RAILS = (np.empty((0, 3)), np.empty((0, 3)), np.zeros((4, 3)), 0.0, 0.0, 0.0)

#: Bodies from which Epoch.at with a guess uses the compiled loop (below: numpy, whose per-call
#: overhead is smaller than numba's dispatch for a handful of bodies). The two agree to a few ulp, not bit
#: for bit (numpy's Stumpff series takes as many terms as the largest |psi| needs, the loop 12).
COMPILED_MIN = 64


class Epoch:
    """States ``(r0, v0)`` about ``mu`` with what :func:`propagate` derives from them computed once:
    for bodies propagated from one epoch step after step (on rails), only ``dt`` changes."""

    __slots__ = ("r0", "v0", "mu", "sqmu", "r0n", "alpha", "sigma0", "period", "chi_turn", "span_rate", "_compiled",
                 "_focal")

    @property
    def focal(self):
        """The focal frames (:func:`_focal_frame`), derived at the first evaluation that needs them."""
        if self._focal is None:
            self._focal = _focal_frame(self.r0, self.v0, self.mu, self.r0n, self.alpha, self.sigma0)
        return self._focal

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
        self._focal = None

    def _columns(self) -> tuple:
        """The compiled loops' inputs: contiguous copies, made once per epoch."""
        c = self._compiled
        if c is None:
            # writable as well as contiguous: a read-only column (a 1-body mu, a crossing's r0/v0 view)
            # would be another numba type, another signature of the loops to compile (seconds each)
            c = self._compiled = tuple(np.require(a, requirements="CW") for a in (
                self.r0, self.v0, self.mu, self.sqmu, self.r0n, self.alpha, self.sigma0, self.period,
                self.chi_turn, self.span_rate[0], self.span_rate[1], *self.focal))
        return c

    def step_from(self, t1, t_epoch, chi, x, v, well, mu, step, out_x, out_v) -> None:
        """The state at ``t1`` (s) of bodies that were at ``x, v`` one ``step`` (s) before, their epochs
        taken at ``t_epoch`` (s, ``(n,)``) about a well of ``mu`` at ``well = (X0, V0, X1, V1)`` (its
        centre and velocity before and after the step, ``(4, 3)``; ``x, v`` are in the same frame),
        in one compiled pass: the same bits as ``at(t1 - t_epoch, next_chi(chi, x, v, mu, step,
        origin=(X0, V0)))`` moved to the well at ``t1``, written into ``out_x, out_v`` (``(n, 3)``);
        ``chi`` (``(n,)``: the last step's) takes the new ``chi`` in place. From :data:`COMPILED_MIN`
        bodies only (below, ``at`` takes the numpy path, whose last bits differ)."""
        if self.r0.shape[0] < COMPILED_MIN:
            raise ValueError(f"Epoch.step_from: {self.r0.shape[0]} bodies; the compiled pass is for "
                             f"{COMPILED_MIN} or more (Epoch.at takes the numpy path below that)")
        _at_compiled(*self._columns(), FOCAL_DD_OME, t_epoch, chi, out_x, out_v, chi, np.ascontiguousarray(x),
                     np.ascontiguousarray(v), np.ascontiguousarray(well, dtype=np.float64), float(t1), float(mu),
                     float(step))

    def quiet_step(self, t_epoch, chi, ep_well, ep_contact, pos, vel, t_idx, v_idx, w_t, w_v, last_x, last_v,
                   t1, dt, mu, xs, vs, well, out_x, out_v, ctx_pos, ctx_vel) -> bool:
        """:meth:`step_from` for the gravity system's quiet step, straight from the tables, with its checks, in
        one compiled call (``kepler_kernels._quiet_rails``): False, and nothing written but ``xs, vs``, unless
        the bodies at rows ``t_idx, v_idx`` of ``pos, vel`` are at ``last_x, last_v``, every ``ep_well`` is 0
        and every ``ep_contact`` after ``t1``; the end states also into rows ``t_idx, v_idx`` of ``ctx_pos,
        ctx_vel``."""
        return _quiet_rails(self._columns(), FOCAL_DD_OME, t_epoch, chi, ep_well, ep_contact, pos, vel, t_idx, v_idx,
                            w_t, w_v, last_x, last_v, float(t1), float(dt), float(mu), xs, vs, well, out_x, out_v,
                            ctx_pos, ctx_vel)

    def at(self, dt, chi=None):
        """``r, v, chi`` after ``dt`` s (scalar or ``(n,)``); ``chi``: a first guess (:func:`next_chi`).

        Many bodies with a guess (on rails) go through the compiled loop (:data:`COMPILED_MIN`);
        the numpy path below is the same solution, array by array, and a few bodies with a guess take
        it compiled with its bits (:mod:`~driftframe.framework.kepler_small`)."""
        n = self.r0.shape[0]
        if chi is not None and n >= COMPILED_MIN:
            # writable copies: a read-only array (np.broadcast_to's view) is another numba type, and each
            # combination of them was a compile of its own (three of this loop after the warm-up)
            dt = np.array(np.broadcast_to(np.asarray(dt, dtype=np.float64), (n,)))
            # (a guess that is not finite fails the loop's bracket test and is replaced there)
            guess = np.array(np.broadcast_to(np.asarray(chi, dtype=np.float64), (n,)))
            out_r = np.empty((n, 3))
            out_v = np.empty((n, 3))
            out_chi = np.empty(n)
            _at_compiled(*self._columns(), FOCAL_DD_OME, dt, guess, out_r, out_v, out_chi, *_NOT_ON_RAILS)
            return out_r, out_v, out_chi
        if chi is not None:
            # a few bodies with a guess (on rails): the numpy path below in one compiled pass, its bits
            # (kepler_small), unless a body needs numpy's own cosh, sinh, log10 or arctan2
            # (fresh writable copies: a read-only array is another type to numba, another compile)
            dt_c = np.array(np.broadcast_to(dt, (n,)), dtype=np.float64)
            guess = np.array(np.broadcast_to(chi, (n,)), dtype=np.float64)
            out_r = np.empty((n, 3))
            out_v = np.empty((n, 3))
            out_chi = np.empty(n)
            if _at_small(*self._columns(), FOCAL_DD_OME, dt_c, guess, out_r, out_v, out_chi) == DONE:
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
        pf = self.focal[0]
        if pf.any():                                         # eccentric ellipses: from the focal frame
            k = np.flatnonzero(pf)
            r[k], v[k] = _focal_state(*(q[k] for q in self.focal[1:]), self.mu[k], self.alpha[k], chi[k])
        zero = dt_red == 0.0                                 # dt = 0 exactly: the same state, bit for bit
        if zero.any():
            r[zero] = r0[zero]
            v[zero] = v0[zero]
        if turns is not None:                                # chi of the whole dt, whole orbits included
            chi = chi + turns * self.chi_turn
        return r, v, chi


#: Ellipses from this eccentricity on take their state from the focal frame (:func:`_focal_state`),
#: and hyperbolas from FOCAL_MIN_HYP_E (near e = 1 the conic is taken as the Lagrange coefficients do).
FOCAL_MIN_E = 0.1
FOCAL_MIN_HYP_E = 1.01
#: Ellipses with 1 - e below this get the focal state's scalars in double-double
#: (:func:`kepler_kernels._focal_dd`): 3x the double-rounding floor -> 1-2x, for ~2x the work.
FOCAL_DD_OME = 0.05


def _cross(a, b):
    """Row-wise ``a x b`` of ``(n, 3)`` arrays (np.cross costs ~15 us a call on a few rows)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _semi_major_axis(r0, v0, mu, alpha):
    """``a = 1 / alpha`` with ``alpha = 2/|r0| - |v0|^2/mu`` in double-double, rounded once: the focal
    state's energy is ``-mu/(2a)`` of this ``a``, and ``alpha`` in doubles carries the rounding of
    ``2/|r0|`` and ``|v0|^2/mu`` (a few ulp, more where they cancel near periapsis)."""
    def sum_sq(x):
        h, lo = _two_prod(x[:, 0], x[:, 0])
        for k in (1, 2):
            ph, pl = _two_prod(x[:, k], x[:, k])
            h, t = _two_sum(h, ph)
            lo = lo + t + pl
        return _fast_two_sum(h, lo)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rh, rl = _dd_sqrt(*sum_sq(r0))
        th, tl = _dd_div(2.0, 0.0, rh, rl)
        vh, vl = sum_sq(v0)
        uh, ul = _dd_div(vh, vl, mu, 0.0)
        ah, al = _two_sum(th, -uh)
        ah, al = _fast_two_sum(ah, al + (tl - ul))
        a = _dd_div(1.0, 0.0, ah, al)[0]
        # where the two alphas differ by more than rounding (near a parabola, 2/|r0| and |v0|^2/mu cancel
        # to a few digits) the solver's chi is tied to the double alpha: keep 1/alpha there
        close = np.abs(a * alpha - 1.0) < 1e-13
    return np.where(np.isfinite(a) & close, a, 1.0 / alpha)


def _focal_frame(r0, v0, mu, r0n, alpha, sigma0):
    """What :func:`_focal_state` needs of each epoch: ``(use, a, ome, P, Q, sin(E0/2), cos(E0/2), |h|, Pl, Ql,
    ddc)`` (``ddc``: :func:`kepler_kernels._focal_dd_constants`).

    ``use``: ellipses with ``e >= FOCAL_MIN_E`` (below it the Lagrange coefficients lose nothing and
    ``P``, the unit eccentricity vector, is ill-defined). ``ome = 1 - e`` from
    ``1 - e^2 = h^2 / (mu a)`` (no cancellation near e = 1; the same ``a`` as the state's, so that
    ``mu a ome (2 - ome)`` is ``h^2``); ``Q = h_hat x P``; ``E0``, the epoch's
    eccentric anomaly, from ``e cos E0 = 1 - |r0| alpha`` and ``e sin E0 = sigma0 sqrt(alpha)``."""
    h = _cross(r0, v0)
    h2 = _dot(h, h)
    hn = np.sqrt(h2)
    vv = _dot(v0, v0)
    rv = _dot(r0, v0)
    with np.errstate(divide="ignore", invalid="ignore"):
        evec = ((vv - mu / r0n)[:, None] * r0 - rv[:, None] * v0) / mu[:, None]
        e = _norm(evec)
        hyp = (alpha < 0) & (e >= FOCAL_MIN_HYP_E)
        use = ((alpha > 0) & (e >= FOCAL_MIN_E) | hyp) & np.isfinite(e) & (r0n > 0) & (hn > 0)
        a = _semi_major_axis(r0, v0, mu, alpha)
        ome = h2 / (mu * a * (1.0 + e))                                # 1 - e (< 0 for a hyperbola)
        P = evec / e[:, None]
        Q = _cross(h / np.where(hn > 0, hn, 1.0)[:, None], P)
        sq = np.sqrt(np.abs(alpha))
        E0 = np.arctan2(sigma0 * sq, 1.0 - r0n * alpha)
        H0 = np.arcsinh(sigma0 * sq / e)                                  # e sinh H0 = sigma0 sqrt(-alpha)
        sh0 = np.where(hyp, np.sinh(0.5 * H0), np.sin(0.5 * E0))
        ch0 = np.where(hyp, np.cosh(0.5 * H0), np.cos(0.5 * E0))
    # the double-double parts only where the state is formed in double-double (zeros elsewhere)
    Pl, Ql, ddc = np.zeros_like(P), np.zeros_like(Q), np.zeros((len(a), 6))
    k = np.flatnonzero(use & (alpha > 0) & (ome < FOCAL_DD_OME))
    if k.size:
        Pl[k], Ql[k] = _unit_frame_lo(P[k], Q[k])
        ddc[k] = _focal_dd_constants(a[k], ome[k], mu[k])
    k = np.flatnonzero(use & (alpha < 0))                           # every hyperbola (_focal_state_hyp)
    if k.size:
        Pl[k], Ql[k] = _unit_frame_lo(P[k], Q[k])
        ddc[k] = _focal_dd_constants_hyp(-a[k], -ome[k], mu[k])
    return use, a, ome, P, Q, sh0, ch0, hn, Pl, Ql, ddc


def _unit_frame_lo(P, Q):
    """Low parts ``Pl, Ql`` that make ``P + Pl`` and ``Q + Ql`` orthonormal to ~1e-32 (double-double):
    a double unit vector is off by an ulp or two, and at periapsis ``|v| = vy |Q|``, each ulp of it
    ``4/(1 - e)`` ulp of energy. First-order corrections: ``n^2 = 1 + d`` gives ``-x d/2``."""
    def norm2_minus_1(x):                                 # |x|^2 - 1, x ~ unit, in double-double, rounded
        h, lo = _two_prod(x[:, 0], x[:, 0])
        for k in (1, 2):
            ph, pl = _two_prod(x[:, k], x[:, k])
            h, t = _two_sum(h, ph)
            lo = lo + t + pl
        return (h - 1.0) + lo                             # (h - 1 exact: h is within a factor 2 of 1)
    Pl = -0.5 * norm2_minus_1(P)[:, None] * P
    dot = np.einsum("ij,ij->i", P, Q)                     # ~1e-16: double is enough
    Ql = -dot[:, None] * P
    Ql = Ql - (0.5 * norm2_minus_1(Q) + np.einsum("ij,ij->i", Q, Ql))[:, None] * Q
    return Pl, Ql


def _focal_state(a, ome, P, Q, sh0, ch0, hn, Pl, Ql, ddc, mu, alpha, chi):
    """The state of an ellipse at ``E = E0 + dE`` (``dE = sqrt(alpha) chi``) in its focal frame:
    ``r = a (cos E - e) P + b sin E Q``, ``v = (-sqrt(mu a) sin E P + h cos E Q) / |r|``, with
    ``cos E - e = ome - 2 s^2``, ``|r| = a (ome + 2 e s^2)``, ``s = sin(E/2)``, ``b = a sqrt(ome (2 - ome))``.

    Why: ``f r0 + g v0`` cancels when an eccentric orbit comes from its far side to periapsis
    (``f = 1 - chi^2 c2 / |r0|`` and ``1 - psi c3`` are differences of near-equal numbers), and the
    energy error grows as ``1/(1 - e)^2`` ulp: 1.9e4 times the double-rounding floor at e = 0.999 from
    E0 = 1 rad, 3.8e-9 from apoapsis. Here every factor is a product or a sum of same-sign terms
    (``ome`` and ``2 s^2``), and the energy ``v^2/2 - mu/|r| = -mu/(2a)`` holds for *any* ``ome``, so
    the error stays a few roundings of the output (about 3x the floor): the energy depends on ``a``
    alone, ``e``'s rounding goes into ``h`` only. From ``1 - e < FOCAL_DD_OME`` the scalars and the sums
    are double-doubles, rounded once (``kepler_kernels._focal_dd``): 0.8-1x the floor. The scalar
    formulas are ``kepler_kernels._focal1``, one source for numpy and the compiled loop."""
    if (alpha < 0).all():
        return _focal_state_hyp(-a, -ome, P, Q, sh0, ch0, Pl, Ql, ddc, alpha, chi)
    if (alpha < 0).any():
        r = np.empty(P.shape)
        v = np.empty(P.shape)
        for k in (alpha > 0, alpha < 0):
            r[k], v[k] = _focal_state(*(q[k] for q in (a, ome, P, Q, sh0, ch0, hn, Pl, Ql, ddc, mu, alpha, chi)))
        return r, v
    x, y, vx, vy, s, c = _focal1(a, ome, sh0, ch0, hn, mu, alpha, chi)
    r = x[:, None] * P + y[:, None] * Q
    v = vx[:, None] * P + vy[:, None] * Q
    dd = ome < FOCAL_DD_OME
    if dd.any():                      # very eccentric: the same scalars in double-double, rounded once
        k = np.flatnonzero(dd)
        xh, xl, yh, yl, uh, ul, wh, wl = (q[:, None] for q in _focal_dd(a[k], ome[k], *ddc[k].T, s[k], c[k]))
        r[k] = _dd_dot2(xh, xl, P[k], Pl[k], yh, yl, Q[k], Ql[k])
        v[k] = _dd_dot2(uh, ul, P[k], Pl[k], wh, wl, Q[k], Ql[k])
    return r, v


def _focal_state_hyp(A, em1, P, Q, sh0, ch0, Pl, Ql, ddc, alpha, chi):
    """:func:`_focal_state` for a hyperbola, ``A = -a``, ``em1 = e - 1``, at ``H = H0 + sqrt(-alpha) chi``:
    ``r = A (e - cosh H) P + b sinh H Q``, ``e - cosh H = em1 - 2 sh^2``, ``|r| = A (em1 + 2 e sh^2)``,
    ``sh = sinh(H/2)``, ``cosh(H/2) = sqrt(1 + sh^2)``, ``b = A sqrt(em1 (2 + em1))``, the scalars and
    the sums in double-double and rounded once (``kepler_kernels._focal_dd_hyp``). Why: ``f r0 + g v0`` lets
    ``h`` drift as ``|chi|`` grows (1e-9 of h after 1e10 s); the focal scalars in doubles keep it to a
    few roundings of ``h`` times ``sh^2`` (``x vy - y vx`` cancels terms ~ ``sh^4`` larger: 2-5x the
    double-rounding floor at 1e8-1e10 s); in double-double what is left is the state's own rounding."""
    s = _hyp_half(sh0, ch0, alpha, chi)
    xh, xl, yh, yl, uh, ul, wh, wl = (q[:, None] for q in _focal_dd_hyp(A, em1, *ddc.T, s))
    return _dd_dot2(xh, xl, P, Pl, yh, yl, Q, Ql), _dd_dot2(uh, ul, P, Pl, wh, wl, Q, Ql)


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

