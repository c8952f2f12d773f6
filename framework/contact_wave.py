"""A solved wave's last stages (compiled kernels): its events recorded, its impulses applied, and the moved
bodies whose new paths leave the neighbour list's cover found.

Called once a wave from :func:`.contact_solve._solve`'s inner loop. Each allocates nothing, so each is
compiled without numba's runtime (``_nrt=False``): a kernel with it counts a reference to each array argument
at entry and exit, an atomic operation a call (see :mod:`.contact_heap`).
"""
from __future__ import annotations

import math

from driftframe.framework.kernels import kernel

_OPTS = dict(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, _nrt=False)


@kernel(**_OPTS)
def record_wave(K, wi, wj, wlam, wn, x, u, r, e, t, t_c, waves, ns, kstamp, burst, t_last, count, E, ne):
    """The wave's contacts that took an impulse: each body's burst, last contact time and count of inelastic
    contacts (once per body per wave), and an event row each in ``E`` from row ``ne`` (see
    :func:`.contact_solve._events`). Bodies from ``ns`` on are static shapes (``ns`` = n without any): a
    shape keeps no burst or count, and its event point is where the sphere touches it. Returns the new ``ne``."""
    for k in range(K):
        if not (wlam[k] > 0.0):
            continue
        i, j = wi[k], wj[k]
        for b in (i, j):
            if kstamp[b] != waves and b < ns:
                kstamp[b] = waves
                burst[b] = burst[b] + 1 if t - t_last[b] <= t_c else 1
                t_last[b] = t
                if (e[j] if e[j] < e[i] else e[i]) < 1.0:
                    count[b] += 1                          # the cap is on inelastic contacts
        E[ne, 0], E[ne, 1], E[ne, 2], E[ne, 3] = i, j, t, wlam[k]
        for d in range(3):
            E[ne, 4 + d] = wn[k, d]
            E[ne, 7 + d] = x[i, d] + u[i, d] * t + r[i] * wn[k, d]
            E[ne, 10 + d] = x[j, d] + u[j, d] * t - r[j] * wn[k, d]
            if j >= ns:
                E[ne, 10 + d] = E[ne, 7 + d]
        ne += 1
    return ne


@kernel(**_OPTS)
def apply_wave(nm, moved, dv, t, x, u, spd, changed, x_in, u_in):
    """Each moved body's new velocity from time ``t`` on, ``u += dv``, with ``x -= dv t`` so that its point
    ``x + u t`` at ``t`` stays where it was; its speed; its first ``x`` and ``u`` kept (for F_AGAIN)."""
    for a in range(nm):
        b = moved[a]
        if not changed[b]:
            for d in range(3):
                x_in[b, d] = x[b, d]
                u_in[b, d] = u[b, d]
        for d in range(3):
            u[b, d] += dv[b, d]
            x[b, d] -= dv[b, d] * t
        spd[b] = math.sqrt(u[b, 0] * u[b, 0] + u[b, 1] * u[b, 1] + u[b, 2] * u[b, 2])
        changed[b] = True


@kernel(**_OPTS)
def leaving(nm, moved, t, dt, x, u, r, swept, centre, skin, blo, bhi, newlo, newhi, tosweep, ns_sweep):
    """The moved bodies whose new path from ``t`` to ``dt`` leaves their territory (a ball around the list's
    build centre: convex, so the end point decides) or, for a swept body, its swept box: appended to
    ``tosweep`` from ``ns_sweep`` on, with their new path boxes in ``newlo``/``newhi``. Returns the new count."""
    for a in range(nm):
        b = moved[a]
        if not swept[b]:
            ox = x[b, 0] + u[b, 0] * dt - centre[0, b]
            oy = x[b, 1] + u[b, 1] * dt - centre[1, b]
            oz = x[b, 2] + u[b, 2] * dt - centre[2, b]
            if ox * ox + oy * oy + oz * oz < skin[b] * skin[b]:
                continue
        inside = swept[b]
        for d in range(3):
            a0 = x[b, d] + u[b, d] * t
            a1 = x[b, d] + u[b, d] * dt
            newlo[ns_sweep, d] = min(a0, a1) - r[b]
            newhi[ns_sweep, d] = max(a0, a1) + r[b]
            if newlo[ns_sweep, d] < blo[b, d] or newhi[ns_sweep, d] > bhi[b, d]:
                inside = False
        if inside:
            continue
        tosweep[ns_sweep] = b
        ns_sweep += 1
    return ns_sweep
