"""The close-encounter integrator of the hybrid n-body step (:mod:`framework.mercurius`): an adaptive
Gragg–Bulirsch–Stoer extrapolation on the bodies in an encounter, about a fixed central mass.

**What it integrates.** The hybrid step (Chambers 1999; Rein et al. 2019, REBOUND's MERCURIUS) splits each
pair's pull with a smooth changeover function ``L(r)`` (:func:`changeover`; 1 far away, 0 close): the
fraction ``L`` is kicked with the Wisdom–Holman interaction kick, the fraction ``1 - L`` goes with the
Kepler drift. For bodies whose pair comes within its critical radius in a step that drift is no longer a
sum of two-body problems, so those bodies (heliocentric positions ``X``, barycentric velocities ``V``, the
democratic-heliocentric drift's variables) are moved over the drift by this integrator, on

    ``X_i' = V_i``,   ``V_i' = -G m_0 X_i/|X_i|^3 + sum_j G m_j (1 - L(r_ij)) (X_j - X_i)/r_ij^3``,

with ``L`` on the force (as REBOUND's MERCURIUS applies it), ``r_ij = |X_j - X_i|`` and ``L``'s radius the
larger of the pair's two critical radii.

**Method** (Hairer, Nørsett & Wanner, *Solving ODEs I*, II.9): Gragg's modified midpoint rule over a
step ``H`` with ``n_k = 2, 4, ..., 16`` substeps, ``z_1 = z_0 + h f(z_0)``, ``z_{m+1} = z_{m-1} + 2 h f(z_m)``
(``h = H/n_k``), whose error is a series in ``h^2``; the results ``T_k1`` are extrapolated to ``h -> 0``
by Aitken–Neville, ``T_kj = T_k,j-1 + (T_k,j-1 - T_k-1,j-1)/((n_k/n_k-j)^2 - 1)`` (order ``2j``).
The first rows share ``f(z_0)``: a full step of 8 rows is 65 pulls.

**Error control.** After row ``k >= 2`` the step is accepted when ``err = max |T_kk - T_k,k-1| / s <= 1``,
``s`` per body and per part: ``tolerance * |X_i|`` for a position, ``tolerance * |V_i|`` for a velocity
(the larger of the step's start and end; so ``tolerance`` is a relative error per step, 1e-13 by
default, near the double rounding of a position). The next step is ``H * min(4, max(0.2, 0.94 (0.65 /
err)^(1/(2k+1))))`` (the estimate is of order ``2k+1`` in ``H``), never past the drift's end; a step not
accepted by row 8 is tried again at that factor (below 1). The integration starts at an eighth of the
drift and reports a failure (a step below 1e-14 of the drift, or a non-finite state) rather than looping.

Units: any consistent set (``gm`` = G m). Arrays changed in place; sums in a fixed order (same bits for
the same input).
"""
from __future__ import annotations

import numpy as np

from driftframe.framework.kernels import kernel

#: Rows of the extrapolation table (substeps 2, 4, ..., 2 ROWS).
ROWS = 8


@kernel(error_model="numpy")
def changeover(r, rc):
    """Mercury's changeover function (Chambers 1999; REBOUND's ``L_mercury``): ``y = (r - 0.1 rc)/(0.9 rc)``,
    ``L = 0`` for ``y <= 0``, ``1`` for ``y >= 1``, ``10 y^3 - 15 y^4 + 6 y^5`` between (twice continuously
    differentiable). ``rc``: the pair's critical radius (m)."""
    if r >= rc:
        return 1.0
    y = (r - 0.1 * rc) / (0.9 * rc)
    if y <= 0.0:
        return 0.0
    return y * y * y * (10.0 + y * (-15.0 + 6.0 * y))


def changeover_array(r, rc):
    """:func:`changeover` on arrays (numpy; the same formula): ``r``, ``rc`` broadcast together."""
    r, rc = np.broadcast_arrays(np.asarray(r, np.float64), np.asarray(rc, np.float64))
    y = np.clip((r - 0.1 * rc) / (0.9 * rc), 0.0, 1.0)
    out = y * y * y * (10.0 + y * (-15.0 + 6.0 * y))
    return np.where(r >= rc, 1.0, out)


@kernel(error_model="numpy")
def _accel(X, gm, dc, gm0, a):
    """The drift's accelerations of the encounter bodies (module docstring), each pair once."""
    m = X.shape[0]
    for i in range(m):
        r2 = X[i, 0] * X[i, 0] + X[i, 1] * X[i, 1] + X[i, 2] * X[i, 2]
        k = -gm0 / (r2 * np.sqrt(r2))
        a[i, 0] = k * X[i, 0]
        a[i, 1] = k * X[i, 1]
        a[i, 2] = k * X[i, 2]
    for i in range(m):
        for j in range(i + 1, m):
            d0 = X[j, 0] - X[i, 0]
            d1 = X[j, 1] - X[i, 1]
            d2 = X[j, 2] - X[i, 2]
            r2 = d0 * d0 + d1 * d1 + d2 * d2
            r = np.sqrt(r2)
            w = 1.0 - changeover(r, max(dc[i], dc[j]))
            if w == 0.0:
                continue
            w /= r2 * r
            a[i, 0] += gm[j] * w * d0
            a[i, 1] += gm[j] * w * d1
            a[i, 2] += gm[j] * w * d2
            a[j, 0] -= gm[i] * w * d0
            a[j, 1] -= gm[i] * w * d1
            a[j, 2] -= gm[i] * w * d2


@kernel(error_model="numpy")
def _midpoint(X0, V0, a0, H, nsub, gm, dc, gm0, out, za, zb, a):
    """Gragg's modified midpoint over ``H`` in ``nsub`` substeps from ``(X0, V0)`` (``a0``: the pull there):
    the end into ``out`` (``(m, 6)``: position, velocity). ``za, zb, a``: scratch."""
    m = X0.shape[0]
    h = H / nsub
    for i in range(m):
        for k in range(3):
            za[i, k] = X0[i, k]
            za[i, 3 + k] = V0[i, k]
            zb[i, k] = X0[i, k] + h * V0[i, k]
            zb[i, 3 + k] = V0[i, k] + h * a0[i, k]
    for _ in range(nsub - 1):
        _accel(zb[:, :3], gm, dc, gm0, a)
        for i in range(m):
            for k in range(3):
                xn = za[i, k] + 2.0 * h * zb[i, 3 + k]
                vn = za[i, 3 + k] + 2.0 * h * a[i, k]
                za[i, k] = zb[i, k]
                za[i, 3 + k] = zb[i, 3 + k]
                zb[i, k] = xn
                zb[i, 3 + k] = vn
    for i in range(m):
        for k in range(6):
            out[i, k] = zb[i, k]


@kernel(error_model="numpy")
def _scaled_error(T, k, X0, V0, tolerance):
    """``max |T_kk - T_k,k-1| / s`` (module docstring), ``inf`` for a non-finite row."""
    err = 0.0
    for i in range(X0.shape[0]):
        for part in range(2):
            s0 = 0.0
            s1 = 0.0
            for c in range(3):
                q = X0[i, c] if part == 0 else V0[i, c]
                s0 += q * q
                s1 += T[k, k, i, 3 * part + c] * T[k, k, i, 3 * part + c]
            s = tolerance * np.sqrt(max(s0, s1))
            for c in range(3):
                e = abs(T[k, k, i, 3 * part + c] - T[k, k - 1, i, 3 * part + c])
                if not e < np.inf:
                    return np.inf
                if e > 0.0:
                    err = max(err, e / s if s > 0.0 else np.inf)
    return err


@kernel(error_model="numpy")
def bulirsch_stoer(X, V, gm, dc, gm0, t, tolerance):
    """Move the encounter bodies ``X, V`` (``(m, 3)``, heliocentric positions, barycentric velocities) over
    ``t`` on the drift's equations (module docstring), in place. ``gm``: their G m; ``dc``: their critical
    radii; ``gm0``: the central G m. Returns the number of accepted steps, or -1 (a failure: the state is
    left where the last accepted step put it)."""
    m = X.shape[0]
    T = np.empty((ROWS, ROWS, m, 6))
    a0 = np.empty((m, 3))
    za = np.empty((m, 6))
    zb = np.empty((m, 6))
    a = np.empty((m, 3))
    done = 0.0
    H = 0.125 * t
    steps = 0
    for _ in range(100_000):
        if abs(t - done) <= 0.0:
            return steps
        if abs(H) < 1e-14 * abs(t):
            return -1
        last = abs(H) >= abs(t - done)
        if last:
            H = t - done
        _accel(X, gm, dc, gm0, a0)
        accepted = False
        fac = 0.2
        for k in range(ROWS):
            _midpoint(X, V, a0, H, 2 * (k + 1), gm, dc, gm0, T[k, 0], za, zb, a)
            for j in range(1, k + 1):
                r = (k + 1.0) / (k + 1.0 - j)             # n_k / n_{k-j}
                den = r * r - 1.0
                for i in range(m):
                    for c in range(6):
                        T[k, j, i, c] = T[k, j - 1, i, c] + (T[k, j - 1, i, c] - T[k - 1, j - 1, i, c]) / den
            if k >= 2:
                err = _scaled_error(T, k, X, V, tolerance)
                fac = 0.2 if not err < np.inf else (4.0 if err == 0.0 else
                                                     min(4.0, max(0.2, 0.94 * (0.65 / err) ** (1.0 / (2 * k + 1)))))
                if err <= 1.0:
                    accepted = True
                    for i in range(m):
                        for c in range(3):
                            X[i, c] = T[k, k, i, c]
                            V[i, c] = T[k, k, i, 3 + c]
                    break
        if accepted:
            steps += 1
            if last:
                return steps
            done += H
        H *= fac
    return -1
