"""The compiled (numba) twins of the Kepler solution in :mod:`driftframe.framework.kepler_universal`, and the
swept boxes of arcs of conics: one body at a time in a compiled loop.

The same solution as the numpy path, one pass over the columns instead of ~170 numpy
passes. Formulas and tolerances are those of the numpy path: Stumpff's series for
``|psi| <= 1`` (12 terms, Horner), the half-angle closed forms beyond; Laguerre
(n = 5) from the guess, bracketed, Newton after 8 iterations; f, g from chi, or for
conics from e = 0.1 (ellipses) and 1.01 (hyperbolas) on the focal frame (``_focal1``,
``_focal_dd``, ``_focal_dd_hyp``). The
series' coefficients live here (the kernels read them at compile time; the numpy
path imports them from here).
"""
from __future__ import annotations

import types

import numpy as np

from driftframe.framework.kernels import kernel

# Series of c2 and c3 in psi: c2 = sum (-psi)^k / (2k+2)!, c3 = sum (-psi)^k / (2k+3)!;
# 12 terms at |psi| <= 1 leave a remainder below 1/27! ~ 1e-28.
_K = np.arange(12)
_C2_SERIES = np.array([(-1.0) ** k / float(np.prod(np.arange(1, 2 * k + 3, dtype=np.float64))) for k in _K])
_C3_SERIES = np.array([(-1.0) ** k / float(np.prod(np.arange(1, 2 * k + 4, dtype=np.float64))) for k in _K])


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


@kernel(inline="always")
def _stumpff_half(psi):
    """:func:`_stumpff1` for the on-rails loop, with ``sin(x/2), cos(x/2)`` (``x = sqrt(psi)``, ``psi > 1``;
    NaN otherwise) for the focal frame, which then needs no sine of its own; ``sin x = 2 sin(x/2) cos(x/2)``."""
    if psi > 1.0:
        x = np.sqrt(psi)
        s = np.sin(0.5 * x)
        c = np.cos(0.5 * x)
        return 2.0 * s * s / psi, (x - 2.0 * s * c) / (psi * x), s, c
    c2, c3 = _stumpff1(psi)
    return c2, c3, np.nan, np.nan


_C2_NB = _C2_SERIES.copy()
_C3_NB = _C3_SERIES.copy()


@kernel(inline="always")
def _next_chi1(chi, r0, r1, r2, v0, v1, v2, mu, step):
    """:func:`next_chi` of one body, its state ``(r0, r1, r2), (v0, v1, v2)`` about the well."""
    rn2 = r0 * r0 + r1 * r1 + r2 * r2
    rn = np.sqrt(rn2)
    rv = r0 * v0 + r1 * v1 + r2 * v2
    d1 = np.sqrt(mu / rn2)
    dchi = step * d1 * (1.0 - 0.5 * step * rv / rn2)
    alpha = 2.0 / rn - (v0 * v0 + v1 * v1 + v2 * v2) / mu
    return chi + dchi if abs(alpha) * dchi * dchi <= 0.2 else np.nan


@kernel
def _next_chi_compiled(chi, r, v, X, V, mu, step, out):
    """:func:`next_chi` for ``(n, 3)`` states relative to ``X, V``, one body at a time."""
    for i in range(r.shape[0]):
        out[i] = _next_chi1(chi[i], r[i, 0] - X[0], r[i, 1] - X[1], r[i, 2] - X[2],
                            v[i, 0] - V[0], v[i, 1] - V[1], v[i, 2] - V[2], mu, step)


# The kernels call the compiled twins of the helpers below, ``compiled._focal_dd(...)``, not the helpers.
# Why: numba knows a ``register_jitable(inline="always")`` helper (as these were) only as an overload, and
# types and compiles it anew at each call site while typing the kernel, and so again for every helper it
# calls: typing cost ~ sum over call sites of (helper + its callees). A dispatcher with inline="always"
# has its untyped IR pasted into the caller before typing (twins within twins too), so the kernel and its
# helpers are typed once: _at_compiled's cold compile ~3.5x less CPU, _at_small's ~2.4x
# (docs/bench/compile.md). The same operations in the same order: the same bits. The numpy path keeps the
# plain function (a dispatcher called on numpy columns would compile itself for arrays); the twin is a
# second function over the same code whose globals are the module ``compiled``, where each helper's name
# is its twin (numba resolves a callee's names in its globals) and numba inlines ``module.name(...)``.
compiled = types.ModuleType(f"{__name__}.compiled", "The compiled (inline) twins of kepler_kernels' helpers.")
compiled.np = np                   # the twins' only other global: a helper reading another one needs it here


def _both(fn):
    """One source for numpy and the kernels: ``fn`` stays a plain function (elementwise on numpy columns);
    ``compiled.<its name>`` is its twin for kernels (the comment above)."""
    twin = types.FunctionType(fn.__code__, vars(compiled), fn.__name__, fn.__defaults__, fn.__closure__)
    setattr(compiled, fn.__name__, kernel(inline="always")(twin))       # (never compiled on its own)
    return fn


# Error-free transformations (Dekker 1971, Knuth's TwoSum) for the focal state of very eccentric
# ellipses: plain + - * / on doubles only (no fma, which numba does not promise), so one source serves
# numpy (elementwise on columns) and the compiled loop, in the same order.
@_both
def _two_sum(a, b):
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


@_both
def _fast_two_sum(a, b):          # |a| >= |b|
    s = a + b
    return s, b - (s - a)


@_both
def _two_prod(a, b):
    p = a * b
    c = 134217729.0 * a           # 2^27 + 1: Dekker's split into 26-bit halves
    ah = c - (c - a)
    al = a - ah
    c = 134217729.0 * b
    bh = c - (c - b)
    bl = b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


@_both
def _dd_mul_d(xh, xl, y):
    p, e = _two_prod(xh, y)
    return _fast_two_sum(p, e + xl * y)


@_both
def _dd_div(xh, xl, yh, yl):
    q = xh / yh
    ph, pl = _two_prod(q, yh)
    r = ((xh - ph) - pl - q * yl + xl) / yh
    return _fast_two_sum(q, r)


@_both
def _dd_mul(xh, xl, yh, yl):
    p, e = _two_prod(xh, yh)
    return _fast_two_sum(p, e + (xh * yl + xl * yh))


@_both
def _dd_sqrt(xh, xl):
    s = np.sqrt(xh)
    ph, pl = _two_prod(s, s)
    return _fast_two_sum(s, ((xh - ph) - pl + xl) / (2.0 * s))


@_both
def _focal_dd(a, ome, b_h, b_l, sq_h, sq_l, h_h, h_l, s, c):
    """The focal state's scalars ``a (cos E - e), b sin E, -sqrt(mu a) sin E / |r|, h cos E / |r|`` as
    double-doubles from ``s = sin(E/2), c = cos(E/2)``; ``b, sqrt(mu a), h`` as double-doubles
    (hi, lo pairs) *of the double a and ome* (:func:`_focal_dd_constants`), so that ``v^2/2 - mu/|r|``
    is ``-mu/(2a)`` of that ``a`` to ~1e-32, whatever ``ome``'s rounding: their roundings are what is left of the energy
    error near periapsis (each ulp of ``|v|`` there is ``4/(1 - e)`` ulp of energy), so they are kept
    to ~1e-32 and the state is rounded once (:func:`_dd_dot2`). ``s, c`` themselves may be off by an
    ulp: that moves the body along the orbit (``E``), and off it unless they stay on the unit circle, so
    they are taken as the point ``(s, c) / sqrt(s^2 + c^2)``: ``sin^2(E/2) = s^2/n^2``, ``sin E = 2 s c/n^2``
    in double-double. (Each ulp of ``s^2 + c^2 - 1`` is ``~v^2/|E|`` ulp of energy through ``|v|``: 2-3x
    the double-rounding floor at e = 0.9999 from E0 = 1 rad, 1x with the point on the circle.)"""
    ph, pl = _two_prod(s, s)
    qh, ql = _two_prod(c, c)
    nh, nl = _two_sum(ph, qh)
    nh, nl = _fast_two_sum(nh, nl + (pl + ql))                        # n^2 = s^2 + c^2 (1 to an ulp)
    s2h, s2l = _dd_div(ph, pl, nh, nl)                               # sin^2(E/2)
    seh, sel = _two_prod(s, c)
    seh, sel = _dd_div(2.0 * seh, 2.0 * sel, nh, nl)                 # sin E
    ch_, cl_ = _two_sum(1.0, -2.0 * s2h)
    ceh, cel = _fast_two_sum(ch_, cl_ - 2.0 * s2l)                   # cos E = 1 - 2 s^2
    th, tl = _two_sum(ome, -2.0 * s2h)
    th, tl = _two_sum(th, tl - 2.0 * s2l)                           # ome - 2 s^2 (may cross 0)
    xh, xl = _dd_mul_d(th, tl, a)                                    # a (ome - 2 s^2)
    eh, el = _two_sum(1.0, -ome)                                     # e
    uh, ul = _two_prod(2.0 * s2h, eh)
    ul = ul + 2.0 * s2h * el + 2.0 * s2l * eh
    wh, wl = _two_sum(ome, uh)
    wh, wl = _fast_two_sum(wh, wl + ul)                              # ome + 2 e s^2 (> 0)
    rh, rl = _dd_mul_d(wh, wl, a)                                    # |r|
    yh, yl = _dd_mul(seh, sel, b_h, b_l)                            # b sin E
    nh, nl = _dd_mul(seh, sel, sq_h, sq_l)                          # sqrt(mu a) sin E
    vxh, vxl = _dd_div(-nh, -nl, rh, rl)
    mh, ml = _dd_mul(ceh, cel, h_h, h_l)                            # h cos E
    vyh, vyl = _dd_div(mh, ml, rh, rl)
    return xh, xl, yh, yl, vxh, vxl, vyh, vyl


def _focal_dd_constants(a, ome, mu):
    """``(n, 6)``: ``b = a sqrt(ome (2 - ome)), sqrt(mu a), h = sqrt(mu a ome (2 - ome))`` as hi, lo pairs."""
    th, tl = _two_sum(2.0, -ome)
    qh, ql = _dd_mul_d(th, tl, ome)                                   # ome (2 - ome) = 1 - e^2
    bh, bl = _dd_sqrt(qh, ql)
    bh, bl = _dd_mul_d(bh, bl, a)
    mh, ml = _two_prod(mu, a)
    sh, sl = _dd_sqrt(mh, ml)
    hh, hl = _dd_mul(mh, ml, qh, ql)
    hh, hl = _dd_sqrt(hh, hl)
    return np.stack([bh, bl, sh, sl, hh, hl], axis=1)


@_both
def _dd_dot2(xh, xl, p, p_lo, yh, yl, q, q_lo):
    """``x p + y q`` rounded once, ``x, y, p, q`` double-doubles (``p_lo, q_lo``: the low parts)."""
    ph, pl = _two_prod(xh, p)
    qh, ql = _two_prod(yh, q)
    sh, sl = _two_sum(ph, qh)
    return sh + (sl + pl + ql + xl * p + yl * q + xh * p_lo + yh * q_lo)


@_both
def _hyp_half(sh0, ch0, alpha, chi):
    """``sinh(H/2)`` at ``H = H0 + sqrt(-alpha) chi`` from ``sinh(H0/2), cosh(H0/2)``."""
    half = 0.5 * np.sqrt(-alpha) * chi
    return sh0 * np.cosh(half) + ch0 * np.sinh(half)


@_both
def _focal_dd_hyp(A, em1, b_h, b_l, sq_h, sq_l, h_h, h_l, s):
    """A hyperbola's focal state ``A (e - cosh H), b sinh H, -sqrt(mu A) sinh H / |r|, h cosh H / |r|``
    (``kepler_universal._focal_state_hyp``) as double-doubles from ``s = sinh(H/2)`` (``A = -a``, ``em1 = e - 1``;
    ``b, sqrt(mu A), h`` double-doubles of the double ``A, em1``: :func:`_focal_dd_constants_hyp`). Why: far
    out ``x vy - y vx`` is ``h`` only through ``cosh^2 - sinh^2 = 1`` between terms ``~ s^4`` times larger, so
    each rounding of the scalars is ``~ s^2`` roundings of ``h``; in double-double, rounded once into the
    state (:func:`_dd_dot2`), what is left is the rounding of the state itself."""
    s2h, s2l = _two_prod(s, s)
    c2h, c2l = _two_sum(1.0, s2h)
    c2h, c2l = _fast_two_sum(c2h, c2l + s2l)                         # cosh^2(H/2) = 1 + s^2
    ch, cl = _dd_sqrt(c2h, c2l)
    shh, shl = _dd_mul_d(ch, cl, s)
    shh, shl = 2.0 * shh, 2.0 * shl                                  # sinh H
    chh, chl = _two_sum(1.0, 2.0 * s2h)
    chh, chl = _fast_two_sum(chh, chl + 2.0 * s2l)                   # cosh H = 1 + 2 s^2
    th, tl = _two_sum(em1, -2.0 * s2h)
    th, tl = _two_sum(th, tl - 2.0 * s2l)                           # e - cosh H = em1 - 2 s^2
    xh, xl = _dd_mul_d(th, tl, A)
    eh, el = _two_sum(1.0, em1)                                      # e
    uh, ul = _two_prod(2.0 * s2h, eh)
    ul = ul + 2.0 * s2h * el + 2.0 * s2l * eh
    wh, wl = _two_sum(em1, uh)
    wh, wl = _two_sum(wh, wl + ul)                                   # em1 + 2 e s^2 (> 0)
    rh, rl = _dd_mul_d(wh, wl, A)                                    # |r|
    yh, yl = _dd_mul(shh, shl, b_h, b_l)                            # b sinh H
    nh, nl = _dd_mul(shh, shl, sq_h, sq_l)                          # sqrt(mu A) sinh H
    vxh, vxl = _dd_div(-nh, -nl, rh, rl)
    mh, ml = _dd_mul(chh, chl, h_h, h_l)                            # h cosh H
    vyh, vyl = _dd_div(mh, ml, rh, rl)
    return xh, xl, yh, yl, vxh, vxl, vyh, vyl


def _focal_dd_constants_hyp(A, em1, mu):
    """``(n, 6)``: ``b = A sqrt(em1 (2 + em1)), sqrt(mu A), h = sqrt(mu A em1 (2 + em1))`` as hi, lo pairs."""
    th, tl = _two_sum(2.0, em1)
    qh, ql = _dd_mul_d(th, tl, em1)                                   # em1 (2 + em1) = e^2 - 1
    bh, bl = _dd_sqrt(qh, ql)
    bh, bl = _dd_mul_d(bh, bl, A)
    mh, ml = _two_prod(mu, A)
    sh, sl = _dd_sqrt(mh, ml)
    hh, hl = _dd_mul(mh, ml, qh, ql)
    hh, hl = _dd_sqrt(hh, hl)
    return np.stack([bh, bl, sh, sl, hh, hl], axis=1)


@_both
def _focal1(a, ome, sh0, ch0, hn, mu, alpha, chi):
    """``kepler_universal._focal_state``'s scalars ``x, y, vx, vy`` and ``s, c`` for one ellipse, same order."""
    half = 0.5 * np.sqrt(alpha) * chi
    return _focal1_sc(a, ome, sh0, ch0, hn, mu, np.sin(half), np.cos(half))


@_both
def _focal1_sc(a, ome, sh0, ch0, hn, mu, sd, cd):
    """:func:`_focal1` from ``sin(dE/2), cos(dE/2)`` already known (the solver's, on rails)."""
    s = sh0 * cd + ch0 * sd
    c = ch0 * cd - sh0 * sd
    s2 = s * s
    sin_e = 2.0 * s * c
    cos_e = 1.0 - 2.0 * s2
    x = a * (ome - 2.0 * s2)
    y = a * np.sqrt(ome * (2.0 - ome)) * sin_e
    rn = a * (ome + 2.0 * s2 - 2.0 * ome * s2)
    vx = -(np.sqrt(mu * a) / rn) * sin_e
    vy = (hn / rn) * cos_e
    return x, y, vx, vy, s, c


@kernel
def _at_compiled(r0, v0, mu, sqmu, r0n, alpha, sigma0, period, chi_turn, span0, span1,
                 focal, a, ome, P, Q, sh0, ch0, hn, Pl, Ql, ddc, dd_ome, dt, guess, out_r, out_v, out_chi,
                 xs, vs, well, t1, mu_w, step):
    """:meth:`Epoch.at` (``xs`` empty): each body ``dt[i]`` s on from its epoch, from the guess ``guess[i]``.

    Or the gravity system's usual step on rails (:meth:`Epoch.step_from`, ``xs`` not empty): the bodies were
    at ``xs, vs`` (world frame) one ``step`` (s) before ``t1``; ``dt`` holds the times of their epochs, so
    each goes ``t1 - dt[i]`` s on, from :func:`next_chi`'s guess out of its last ``chi`` (``guess``) and
    ``xs, vs`` about the well (``well = (X0, V0, X1, V1)``, its centre and velocity at the step's start and
    end; ``mu_w``, its ``mu``), and lands about the well at ``t1``: ``out_r = X1 + r``, ``out_v = V1 + u``.
    The same operations in the same order as ``next_chi``, ``Epoch.at`` and the adds in numpy (the same
    bits), in one pass. Returns the number of bodies that needed the numpy path (none)."""
    n = r0.shape[0]
    tol = 4.0 * 2.220446049250313e-16
    on_rails = xs.shape[0] > 0
    for i in range(n):
        if on_rails:
            t = t1 - dt[i]
            g = _next_chi1(guess[i], xs[i, 0] - well[0, 0], xs[i, 1] - well[0, 1], xs[i, 2] - well[0, 2],
                           vs[i, 0] - well[1, 0], vs[i, 1] - well[1, 1], vs[i, 2] - well[1, 2], mu_w, step)
        else:
            t = dt[i]
            g = guess[i]
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
        chi = g - turns * chi_turn[i]
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
        s_half = np.nan
        c_half = np.nan
        chi_half = np.nan                                # the chi of s_half, c_half
        for it in range(60):
            chi2 = chi * chi
            psi = al * chi2
            c2, c3, s_half, c_half = _stumpff_half(psi)
            chi_half = chi
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
        if focal[i] and t != 0.0 and al < 0:             # a hyperbola: its focal state in double-double
            xh, xl, yh, yl, uh, ul, wh, wl = compiled._focal_dd_hyp(-a[i], -ome[i], ddc[i, 0], ddc[i, 1], ddc[i, 2],
                                                                    ddc[i, 3], ddc[i, 4], ddc[i, 5],
                                                                    compiled._hyp_half(sh0[i], ch0[i], al, chi))
            for k in range(3):
                out_r[i, k] = compiled._dd_dot2(xh, xl, P[i, k], Pl[i, k], yh, yl, Q[i, k], Ql[i, k])
                out_v[i, k] = compiled._dd_dot2(uh, ul, P[i, k], Pl[i, k], wh, wl, Q[i, k], Ql[i, k])
        elif focal[i] and t != 0.0:                      # eccentric conics: from the focal frame
            if chi_half == chi and s_half == s_half:        # the solver's sin(x/2), cos(x/2) at this chi
                x, y, vx, vy, s, c = compiled._focal1_sc(a[i], ome[i], sh0[i], ch0[i], hn[i], mu[i],
                                                         np.copysign(s_half, chi), c_half)
            else:
                x, y, vx, vy, s, c = compiled._focal1(a[i], ome[i], sh0[i], ch0[i], hn[i], mu[i], al, chi)
            if ome[i] < dd_ome:
                xh, xl, yh, yl, uh, ul, wh, wl = compiled._focal_dd(a[i], ome[i], ddc[i, 0], ddc[i, 1], ddc[i, 2],
                                                                    ddc[i, 3], ddc[i, 4], ddc[i, 5], s, c)
                for k in range(3):
                    out_r[i, k] = compiled._dd_dot2(xh, xl, P[i, k], Pl[i, k], yh, yl, Q[i, k], Ql[i, k])
                    out_v[i, k] = compiled._dd_dot2(uh, ul, P[i, k], Pl[i, k], wh, wl, Q[i, k], Ql[i, k])
            else:
                for k in range(3):
                    out_r[i, k] = x * P[i, k] + y * Q[i, k]
                    out_v[i, k] = vx * P[i, k] + vy * Q[i, k]
        else:
            for k in range(3):
                out_r[i, k] = f_ * r0[i, k] + g_ * v0[i, k]
                out_v[i, k] = fd * r0[i, k] + gd * v0[i, k]
        out_chi[i] = chi + turns * chi_turn[i]
        if on_rails:
            for k in range(3):
                out_r[i, k] = well[2, k] + out_r[i, k]
                out_v[i, k] = well[3, k] + out_v[i, k]
    return 0


@kernel
def _quiet_rails(c, dd_ome, ep_t, ep_chi, ep_well, ep_contact, pos, vel, t_idx, v_idx, w_t, w_v, last_x, last_v,
                 t1, dt, mu, xs, vs, well, out_r, out_v, ctx_pos, ctx_vel):
    """The gravity system's quiet step on rails (one well, no thrust) in one call, from the tables: False,
    and nothing written but ``xs, vs``, unless every body is where the last step left it (``pos[t_idx]``,
    ``vel[v_idx]`` equal to ``last_x``, ``last_v``: no one else moved it), its epoch is about the well
    (``ep_well == 0``) and its next surface contact is after ``t1``; then the bodies' states (``xs, vs``),
    the well's at the step's start and end (``well`` (4, 3): ``X0 = pos[w_t]``, ``V0 = vel[w_v]`` or 0
    when ``w_v < 0``, ``X1 = X0 + V0 dt``, ``V1 = V0``) and :func:`_at_compiled`'s step on rails from the
    epoch columns ``c`` (:meth:`Epoch._columns`) into ``out_r, out_v`` (``ep_chi`` in place), written also
    into the step context's rows (``ctx_pos[t_idx]``, ``ctx_vel[v_idx]``): the same
    numbers as the system's numpy gathers, compares and ``Epoch.step_from``, in one call (a numpy call is
    dear when the step's code and data are cold, as between a game's other work: docs/bench/orbit_accuracy.md)."""
    n = t_idx.shape[0]
    for i in range(n):
        if ep_well[i] != 0 or not ep_contact[i] > t1:
            return False
        ti = t_idx[i]
        vi = v_idx[i]
        for k in range(3):
            x = pos[ti, k]
            v = vel[vi, k]
            if x != last_x[i, k] or v != last_v[i, k]:
                return False
            xs[i, k] = x
            vs[i, k] = v
    for k in range(3):
        x0 = pos[w_t, k]
        v0 = vel[w_v, k] if w_v >= 0 else 0.0
        well[0, k] = x0
        well[1, k] = v0
        well[2, k] = x0 + v0 * dt
        well[3, k] = v0
    _at_compiled(c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], c[10], c[11], c[12], c[13], c[14],
                 c[15], c[16], c[17], c[18], c[19], c[20], c[21], dd_ome, ep_t, ep_chi, out_r, out_v, ep_chi, xs, vs,
                 well, t1, mu, dt)
    for i in range(n):
        for k in range(3):
            ctx_pos[t_idx[i], k] = out_r[i, k]
            ctx_vel[v_idx[i], k] = out_v[i, k]
    return True


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

