"""The numpy path of :meth:`kepler_universal.Epoch.at` for a few bodies (below ``COMPILED_MIN``), compiled,
with the numpy path's bits.

Why: for 1-3 bodies on rails the numpy path is ~150 numpy calls on 1-3 element arrays a step, most of
a small gravity scene's step (docs/design/costs.md, 'Small gravity scenes'). The compiled loop of
:mod:`kepler_kernels` is not the same solution to the last bit (its Stumpff series takes 12 terms, the
numpy path as many as the largest ``|psi|`` of the bodies still iterating needs; its ``tb`` is rounded in
another order), so this kernel follows the numpy path operation by operation, array semantics included:
the solver iterates every body while most have not converged and then only the rest, and the series'
length is taken over the bodies it iterates. Elementwise ``+ - * /`` and ``sqrt`` round alike in numpy and
in a kernel (no fastmath: no fused multiply-add); ``sin`` and ``cos`` are the C library's in both here.
What numpy computes with functions of its own (``cosh``, ``sinh``, ``log10``, ``arctan2``: SIMD versions
whose last bit may differ from the C library's) is not done here: a body that needs them (a hyperbola
with ``psi < -1``, the focal state of a hyperbola, a first guess for a long step) or a series length
whose ``log10`` lands within 1e-12 of a threshold makes the kernel return 1, and the caller takes the
numpy path for the whole call (the kernel writes only its outputs)."""
from __future__ import annotations

import numpy as np

from driftframe.framework.kepler_kernels import _C2_SERIES, _C3_SERIES, _K, compiled
from driftframe.framework.kernels import kernel

_C3_SERIES_ABS = np.abs(_C3_SERIES)
# k terms leave a remainder below 1e-18 where p^k 6 |c3_k| < 1e-18: log10 p < L_k (L_k grows with k)
_TERM_LIMIT = np.array([(-18.0 - np.log10(6.0 * _C3_SERIES_ABS[k])) / k for k in range(1, len(_K))])
_C2_SM = _C2_SERIES.copy()
_C3_SM = _C3_SERIES.copy()
_LIMITS = _TERM_LIMIT.copy()

#: The kernel's answers: done, or take the numpy path.
DONE, NUMPY = 0, 1


@kernel
def _stumpff_set(psi, m, c2, c3):
    """``kepler_universal.stumpff`` of ``psi[:m]`` into ``c2, c3``: the series on ``|psi| <= 1`` with as many
    terms as the largest of them needs, the closed forms beyond. NUMPY where it cannot give numpy's bits."""
    pmax = -1.0
    n_small = 0
    for j in range(m):
        ap = abs(psi[j])
        if ap <= 1.0:
            n_small += 1
            if ap > pmax or pmax < 0.0:
                pmax = ap
        elif psi[j] < 0.0:
            return NUMPY                                  # cosh, sinh: numpy's own
    if n_small:
        terms = 1
        if pmax > 0.0:
            lg = np.log10(pmax)
            count = 0
            for k in range(_LIMITS.shape[0]):
                if abs(lg - _LIMITS[k]) < 1e-12:
                    return NUMPY                          # (numpy's log10 may round to the other side)
                if _LIMITS[k] <= lg:
                    count += 1
            terms = count + 1
        for j in range(m):
            p = psi[j]
            if abs(p) <= 1.0:
                s2 = _C2_SM[terms - 1]
                s3 = _C3_SM[terms - 1]
                for k in range(terms - 2, -1, -1):
                    s2 = s2 * p
                    s2 = s2 + _C2_SM[k]
                    s3 = s3 * p
                    s3 = s3 + _C3_SM[k]
                c2[j] = s2
                c3[j] = s3
    for j in range(m):
        p = psi[j]
        if not abs(p) <= 1.0:
            x = np.sqrt(abs(p))
            s = np.sin(0.5 * x)
            c2[j] = 2.0 * s * s / p
            c3[j] = (x - np.sin(x)) / (p * x)
    return DONE


@kernel
def _at_small(r0, v0, mu, sqmu, r0n, alpha, sigma0, period, chi_turn, span0, span1,
              use, a, ome, P, Q, sh0, ch0, hn, Pl, Ql, ddc, dd_ome, dt_in, guess, out_r, out_v, out_chi):
    """``Epoch.at(dt_in, guess)``'s numpy path (the arguments: ``Epoch._columns()``, then ``FOCAL_DD_OME``):
    ``out_r, out_v, out_chi``, and DONE; or NUMPY (see the module's text)."""
    n = r0.shape[0]
    iterations = 60
    tol = 4.0 * 2.220446049250313e-16
    dt = np.empty(n)
    turns = np.zeros(n)
    chi = np.empty(n)
    lo = np.empty(n)
    hi = np.empty(n)
    any_longer = False
    for i in range(n):
        if r0n[i] > 0.0 and np.isfinite(r0n[i]) and np.isfinite(alpha[i]):
            pass
        else:
            return NUMPY
        if abs(dt_in[i]) > period[i]:
            any_longer = True
    # whole periods off dt (Epoch.at), the bracket and the guess (solve_universal)
    outside = False
    for i in range(n):
        t = dt_in[i]
        if abs(t) > period[i]:
            turns[i] = np.round(t / period[i])
            t = t - period[i] * turns[i]
        dt[i] = t
        g = guess[i]
        if any_longer:
            g = g - turns[i] * chi_turn[i]
        span = (span0[i] * abs(t) + 2.0) * span1[i]
        if span != span:
            return NUMPY
        lo[i] = -span if t < 0 else 0.0
        hi[i] = 0.0 if t < 0 else span
        if not (g >= lo[i] and g <= hi[i]):
            outside = True
            # _first_guess's short-step reversion (a long step's guess needs arctan2, hypot: numpy's own)
            u = sqmu[i] * t / r0n[i]
            w = u / r0n[i]
            s0 = sigma0[i]
            g = u * (1.0 - 0.5 * s0 * w + (0.5 * s0 * s0 - r0n[i] * (1.0 - alpha[i] * r0n[i]) / 6.0) * w * w)
            if abs(alpha[i]) * g * g > 0.1 or not np.isfinite(g):
                return NUMPY
        chi[i] = g
    if outside:
        for i in range(n):
            if chi[i] < lo[i]:
                chi[i] = lo[i]
            elif chi[i] > hi[i]:
                chi[i] = hi[i]
    # solve_universal: every body while most iterate, then only those that have not converged
    o_chi = np.empty(n)
    o_psi = np.empty(n)
    o_c2 = np.empty(n)
    o_c3 = np.empty(n)
    o_fp = np.empty(n)
    act = np.arange(n)
    m = n
    all_bodies = True                                    # (numpy's idx is None)
    psi = np.empty(n)
    c2 = np.empty(n)
    c3 = np.empty(n)
    f = np.empty(n)
    fp = np.empty(n)
    one_c2 = np.empty(n)
    one_c3 = np.empty(n)
    done = np.empty(n, np.bool_)
    for it in range(iterations):
        for j in range(m):
            psi[j] = alpha[act[j]] * (chi[j] * chi[j])
        if _stumpff_set(psi, m, c2, c3) != DONE:
            return NUMPY
        n_done = 0
        for j in range(m):
            i = act[j]
            x = chi[j]
            chi2 = x * x
            one_c3[j] = 1.0 - psi[j] * c3[j]
            one_c2[j] = 1.0 - psi[j] * c2[j]
            s_chi = sigma0[i] * x
            ta = chi2 * x * c3[j]
            tb = s_chi * x * c2[j]
            tc = r0n[i] * x * one_c3[j]
            t_ = sqmu[i] * dt[i]
            f[j] = ta + tb + tc - t_
            fp[j] = chi2 * c2[j] + s_chi * one_c3[j] + r0n[i] * one_c2[j]
            d = abs(f[j]) <= tol * (abs(ta) + abs(tb) + abs(tc) + abs(t_))
            if it == iterations - 1 or not np.isfinite(f[j]):
                d = True
            done[j] = d
            n_done += d
        all_done = n_done == m
        if all_done and all_bodies:
            for j in range(m):
                o_chi[j] = chi[j]
                o_psi[j] = psi[j]
                o_c2[j] = c2[j]
                o_c3[j] = c3[j]
                o_fp[j] = fp[j]
            break
        whole = all_bodies and not all_done and n_done * 2 < n
        if whole:
            for j in range(m):
                done[j] = False
        else:
            for j in range(m):
                if done[j]:
                    i = act[j]
                    o_chi[i] = chi[j]
                    o_psi[i] = psi[j]
                    o_c2[i] = c2[j]
                    o_c3[i] = c3[j]
                    o_fp[i] = fp[j]
            if all_done:
                break
        k = 0
        for j in range(m):
            x = chi[j]
            if f[j] > 0:
                if x < hi[j]:
                    hi[j] = x
            elif x > lo[j]:
                lo[j] = x
            i = act[j]
            if it < 8:
                fpp = sigma0[i] * one_c2[j] + (1.0 - alpha[i] * r0n[i]) * x * one_c3[j]
                disc = abs(16.0 * fp[j] * fp[j] - 20.0 * f[j] * fpp)
                new = x - 5.0 * f[j] / (fp[j] + np.copysign(np.sqrt(disc), fp[j]))
            else:
                new = x - f[j] / fp[j]
            if not (new >= lo[j] and new <= hi[j]):
                if np.isfinite(hi[j]):
                    mid = 0.5 * (lo[j] + hi[j])
                else:
                    mid = max(2.0 * abs(lo[j]), 1.0)
                if not np.isfinite(lo[j]):
                    mid = min(-2.0 * abs(hi[j]), -1.0)
                new = mid
            if whole:
                chi[j] = new
            elif not done[j]:
                chi[k] = new
                lo[k] = lo[j]
                hi[k] = hi[j]
                act[k] = act[j]
                k += 1
        if not whole:
            m = k
            all_bodies = False
    # Epoch.at: the state from chi (f, g or the focal frame), dt = 0 as given, whole turns back on chi
    for i in range(n):
        x = o_chi[i]
        chi2 = x * x
        ps = o_psi[i]
        rn = o_fp[i]
        if use[i]:
            if not alpha[i] > 0.0:
                return NUMPY                             # a hyperbola's focal state: cosh, sinh
            fx, fy, vx, vy, s, c = compiled._focal1(a[i], ome[i], sh0[i], ch0[i], hn[i], mu[i], alpha[i], x)
            if ome[i] < dd_ome:
                xh, xl, yh, yl, uh, ul, wh, wl = compiled._focal_dd(a[i], ome[i], ddc[i, 0], ddc[i, 1], ddc[i, 2],
                                                                    ddc[i, 3], ddc[i, 4], ddc[i, 5], s, c)
                for k in range(3):
                    out_r[i, k] = compiled._dd_dot2(xh, xl, P[i, k], Pl[i, k], yh, yl, Q[i, k], Ql[i, k])
                    out_v[i, k] = compiled._dd_dot2(uh, ul, P[i, k], Pl[i, k], wh, wl, Q[i, k], Ql[i, k])
            else:
                for k in range(3):
                    out_r[i, k] = fx * P[i, k] + fy * Q[i, k]
                    out_v[i, k] = vx * P[i, k] + vy * Q[i, k]
        else:
            f_ = 1.0 - chi2 * o_c2[i] / r0n[i]
            g_ = (r0n[i] * x * (1.0 - ps * o_c3[i]) + sigma0[i] * chi2 * o_c2[i]) / sqmu[i]
            fd = sqmu[i] * x * (ps * o_c3[i] - 1.0) / (rn * r0n[i])
            gd = 1.0 - chi2 * o_c2[i] / rn
            for k in range(3):
                out_r[i, k] = f_ * r0[i, k] + g_ * v0[i, k]
                out_v[i, k] = fd * r0[i, k] + gd * v0[i, k]
        if dt[i] == 0.0:
            for k in range(3):
                out_r[i, k] = r0[i, k]
                out_v[i, k] = v0[i, k]
        out_chi[i] = x + turns[i] * chi_turn[i] if any_longer else x
    return DONE


@kernel
def _next_chi_small(chi, r, v, X, V, mu, step, out):
    """``kepler_universal.next_chi``'s numpy path (``r, v`` absolute, the well at ``X, V``) with its bits:
    its dot products are numpy's einsum of three products, which sums ``(p0 + p2) + p1``."""
    for i in range(r.shape[0]):
        r0, r1, r2 = r[i, 0] - X[0], r[i, 1] - X[1], r[i, 2] - X[2]
        v0, v1, v2 = v[i, 0] - V[0], v[i, 1] - V[1], v[i, 2] - V[2]
        rn2 = (r0 * r0 + r2 * r2) + r1 * r1
        rn = np.sqrt(rn2)
        rv = (r0 * v0 + r2 * v2) + r1 * v1
        d1 = np.sqrt(mu / rn2)
        dchi = step * d1 * (1.0 - 0.5 * step * rv / rn2)
        alpha = 2.0 / rn - ((v0 * v0 + v2 * v2) + v1 * v1) / mu
        out[i] = chi[i] + dchi if abs(alpha) * dchi * dchi <= 0.2 else np.nan
