"""The articles' collision method, kept as a labelled baseline (``CollisionSystem(method="articles")``).

After the step, for every pair in turn (a Python double loop, in entity
order), if the spheres overlap, move both back along their velocities until
the centres are ``r_a + r_b`` apart, and reflect each velocity about the
contact normal in the centre-of-mass frame (``v' = v - 2 n (n.v)``). As
written there: it only sees overlaps at the end of a step (fast spheres pass
through each other), the remaining time of the step is not re-advanced, pairs
are handled one after another (so a break depends on the order of entities),
and it does not ask whether an overlapping pair approaches: a pair that
overlaps while separating (spawned so, or left so by rounding) is "moved
back" through each other to the far side, a jump.

It works on the end of the step (the bodies' free flight,
:func:`driftframe.framework.step.advance`), as the articles did after their
movement pass, and the collision system writes what it returns into the
step context (see :mod:`driftframe.systems.collision`).
"""
from __future__ import annotations

import math

import numpy as np



def articles_step(st, lay, dt: float, t0: float, events: bool):
    """The end-of-step ``(x, v)`` (n, 3) of the colliders in ``st`` and its contacts, a list of
    ``(a, b, time, step_time, point, normal, impulse)`` (a ``CollisionEvent``'s fields, made by the
    collision system: this layer knows no component)."""
    x1, v1 = st.end_of_step(dt)
    x = x1.tolist()
    v = v1.tolist()
    inv = st.inv.tolist()
    r = st.r.tolist()
    ents = lay.entities.tolist()
    n = lay.n
    out = []
    for i in range(n):
        xi, ri = x[i], r[i]
        for j in range(i + 1, n):
            xj = x[j]
            dx, dy, dz = xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]
            R = ri + r[j]
            if dx * dx + dy * dy + dz * dz >= R * R:
                continue
            if inv[i] == 0.0 and inv[j] == 0.0:
                continue
            vi, vj = v[i], v[j]
            # move both back along their velocities until |d - w s| = R (the positive root s)
            wx, wy, wz = vj[0] - vi[0], vj[1] - vi[1], vj[2] - vi[2]
            a = wx * wx + wy * wy + wz * wz
            s = 0.0
            if a > 0.0:
                b = dx * wx + dy * wy + dz * wz
                c = dx * dx + dy * dy + dz * dz - R * R
                s = (b + math.sqrt(max(b * b - a * c, 0.0))) / a
            for p, q in ((xi, vi), (xj, vj)):
                p[0] -= q[0] * s
                p[1] -= q[1] * s
                p[2] -= q[2] * s
            dx, dy, dz = xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]
            dist = math.sqrt(dx * dx + dy * dy + dz * dz) or 1.0
            nx, ny, nz = dx / dist, dy / dist, dz / dist
            impulse = 2.0 * abs(wx * nx + wy * ny + wz * nz) / (inv[i] + inv[j])   # |m_j dv_j|, N s
            # centre-of-mass velocity, weights m_i/(m_i+m_j) = inv_j/(inv_i+inv_j) (an immovable
            # body is the centre-of-mass frame)
            ki, kj = inv[j], inv[i]
            tot = ki + kj
            cm = [(ki * vi[k] + kj * vj[k]) / tot for k in range(3)]
            for q in (vi, vj):
                rel = [q[k] - cm[k] for k in range(3)]
                dot = rel[0] * nx + rel[1] * ny + rel[2] * nz
                q[0] = cm[0] + rel[0] - 2.0 * nx * dot
                q[1] = cm[1] + rel[1] - 2.0 * ny * dot
                q[2] = cm[2] + rel[2] - 2.0 * nz * dot
            if events:
                a_, b_, sign = (i, j, 1.0) if ents[i] < ents[j] else (j, i, -1.0)
                nn = (sign * nx, sign * ny, sign * nz)
                pa = x[a_]
                out.append((ents[a_], ents[b_], t0 + dt - s, dt - s,
                            (pa[0] + r[a_] * nn[0], pa[1] + r[a_] * nn[1], pa[2] + r[a_] * nn[2]), nn, impulse))
    return np.array(x).reshape(n, 3), np.array(v).reshape(n, 3), out
