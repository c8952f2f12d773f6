"""The colliders' start-of-step state, gathered from the world's columns (a compiled kernel)."""
from __future__ import annotations

import math

from driftframe.framework.kernels import kernel

_INF = math.inf


@kernel(error_model="numpy", no_cfunc_wrapper=True)
def gather_bodies(pos, vel, acc, kg, rad, rest, t_idx, v_idx, a_idx, m_idx, c_idx, dt,
                  x0, v0, a, inv, r, e, x, u, live):
    """The colliders' start-of-step state from the world's columns, in one pass (a scene of a few
    dozen bodies otherwise spends more on numpy's per-call cost than on the solve).

    Rows: ``t_idx``/``c_idx`` into the Transform/SphereCollider columns;
    ``v_idx``, ``a_idx``, ``m_idx`` into Velocity, Acceleration, Mass (-1:
    the body has none: velocity and acceleration 0, mass 1 kg, and a body
    without a Velocity is immovable: inverse mass 0). Fills ``x0, v0`` (and
    ``a`` when it has rows), ``inv = 1 / kg``, ``r``, ``e``; the solver's
    copies ``x = x0`` and ``u = v0 + a dt/2`` (the step's mean velocity);
    ``live``: valid (finite position, velocity, acceleration; radius > 0;
    restitution in [0, 1]; inverse mass finite and >= 0). Returns ``(bad, moving)``: how many
    bodies are not valid, and whether any ``u`` is non-zero.
    """
    n = x0.shape[0]
    has_a = a.shape[0] == n
    half = 0.5 * dt
    bad = 0
    moving = False
    for k in range(n):
        t = t_idx[k]
        vk = v_idx[k]
        mk = m_idx[k]
        c = c_idx[k]
        w = 1.0 / kg[mk] if mk >= 0 else 1.0
        if vk < 0:
            w = 0.0
        inv[k] = w
        r[k] = rad[c]
        e[k] = rest[c]
        ok = r[k] > 0.0 and r[k] < _INF and e[k] >= 0.0 and e[k] <= 1.0 and w >= 0.0 and w < _INF
        for d in range(3):
            p = pos[t, d]
            q = vel[vk, d] if vk >= 0 else 0.0
            x0[k, d] = p
            v0[k, d] = q
            x[k, d] = p
            s = p + q
            if has_a:
                g = acc[a_idx[k], d] if a_idx[k] >= 0 else 0.0
                a[k, d] = g
                s += g
                q = q + half * g
            u[k, d] = q
            if q != 0.0:
                moving = True
            ok = ok and (s - s == 0.0)                      # finite (nan and inf give nan)
        live[k] = ok
        if not ok:
            bad += 1
    return bad, moving

