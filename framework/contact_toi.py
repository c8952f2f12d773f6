"""A pair's time of impact on straight paths (a compiled kernel; the derivation is in :mod:`.contact`)."""
from __future__ import annotations

import math

from driftframe.framework.contact_params import APPROACH, CENTRED, SLACK_MAX, TOUCH
from driftframe.framework.kernels import kernel


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def toi(ex, ey, ez, wx, wy, wz, R, inv_sum, speeds, t, dt):
    """Earliest time of impact in [t, dt] of bodies i, j on paths ``x + u t'``; (-1, 0) when none.

    ``e``: ``x_j - x_i``; ``w``: ``u_j - u_i``; ``R = r_i + r_j``; ``inv_sum =
    inv_i + inv_j``; ``speeds = |u_i| + |u_j|``. Returns ``(time, slack)``;
    ``slack`` is how long before ``time`` the gap is already below ``TOUCH R``
    (capped at ``SLACK_MAX dt``). Scalars only: numba counts a reference to
    every array an inlined function receives (an atomic operation), which
    in the solver's loops cost more than the arithmetic.
    """
    if inv_sum == 0.0:
        return -1.0, 0.0                                   # two immovable bodies pass through
    dx = ex + wx * t
    dy = ey + wy * t
    dz = ez + wz * t
    b = dx * wx + dy * wy + dz * wz                        # |d| times the normal relative velocity
    if not (b < 0.0):
        return -1.0, 0.0                                   # separating (or at rest): most pairs end here
    dd = dx * dx + dy * dy + dz * dz
    c = dd - R * R
    T = dt - t
    # Too late, told without a square root (a third of a dense gas's pairs): the contact is the smaller root
    # h = c / (sqrt(b^2 - a c) - b) >= c / (2 |b|), also as computed (the root <= |b| (1 + 2 eps), the
    # refinement below moves h by rounding only), so c > 2 |b| T (1 + 1e-3) gives t + h > dt in floating
    # point wherever T > 1e-3 dt: the same (-1, 0) as the full test below, found sooner.
    if T > 1e-3 * dt and c > -2.0 * b * T * (1.0 + 1e-3):
        return -1.0, 0.0
    dist = math.sqrt(dd)
    if not (b < -APPROACH * speeds * dist) or not (dist > CENTRED * R):
        return -1.0, 0.0
    a = wx * wx + wy * wy + wz * wz
    if c <= 0.0:
        tc = t                                             # touching or overlapping, approaching: now
    else:
        disc = b * b - a * c
        if disc < 0.0:
            return -1.0, 0.0                               # a near miss: the exact paths never meet
        h = c / (math.sqrt(disc) - b)
        if dist > 4.0 * R:
            # c keeps ~eps |d|^2 / R^2 of relative error: solve once more from the estimate
            fx = dx + wx * h
            fy = dy + wy * h
            fz = dz + wz * h
            c2 = fx * fx + fy * fy + fz * fz - R * R
            b2 = fx * wx + fy * wy + fz * wz
            disc2 = b2 * b2 - a * c2
            if disc2 < 0.0:
                disc2 = 0.0
            den = math.sqrt(disc2) - b2
            if den > 0.0:
                h += c2 / den
        tc = t + h
        if tc < t:
            tc = t
    if tc > dt:
        return -1.0, 0.0
    slack = TOUCH * R * dist / -b
    if slack > SLACK_MAX * dt:
        slack = SLACK_MAX * dt
    return tc, slack

