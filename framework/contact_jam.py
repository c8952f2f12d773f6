"""The jam path: an island's touching cluster given one velocity (compiled kernels; see :mod:`.contact`)."""
from __future__ import annotations

from driftframe.framework.contact_params import TOUCH
from driftframe.framework.kernels import kernel


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def stick_cluster(cs, m, wi, wj, wn, inv, live, u, x, r, t, wlam, dv, moved, nm, bmark, wave, head, nxt, PI, PJ,
                  seen, queue):
    """Give the touching cluster of an island's bodies one velocity: its centre of mass's, or that of an
    immovable body it touches. Every relative velocity in it becomes zero, which ends any burst.

    The cluster: the island's bodies and every movable body reached through candidate pairs whose gap at
    ``t`` is below ``TOUCH R`` (immovable bodies anchor it and are not crossed).
    """
    nq = 0
    anchor = -1
    for a in range(m):
        c = cs[a]
        for b in (wi[c], wj[c]):
            if inv[b] == 0.0:
                anchor = b
            elif seen[b] != wave:
                seen[b] = wave
                queue[nq] = b
                nq += 1
    h = 0
    while h < nq:
        b = queue[h]
        h += 1
        node = head[b]
        while node >= 0:
            p = node >> 1
            node = nxt[node]
            o = PJ[p] if PI[p] == b else PI[p]
            if seen[o] == wave or not live[o]:
                continue
            d2 = 0.0
            for d in range(3):
                q = x[o, d] + u[o, d] * t - x[b, d] - u[b, d] * t
                d2 += q * q
            R = (r[o] + r[b]) * (1.0 + TOUCH)
            if d2 > R * R:
                continue
            if inv[o] == 0.0:
                anchor = o
                continue
            seen[o] = wave
            queue[nq] = o
            nq += 1
    if nq == 0:
        return nm                                          # already moved with another island's cluster
    if anchor >= 0:
        vx, vy, vz = u[anchor, 0], u[anchor, 1], u[anchor, 2]
    else:
        mass = 0.0
        px = py = pz = 0.0
        for q in range(nq):
            b = queue[q]
            mb = 1.0 / inv[b]
            mass += mb
            px += mb * u[b, 0]
            py += mb * u[b, 1]
            pz += mb * u[b, 2]
        vx, vy, vz = px / mass, py / mass, pz / mass
    for q in range(nq):
        b = queue[q]
        if bmark[b] != wave:
            bmark[b] = wave
            moved[nm] = b
            nm += 1
        dv[b, 0] = vx - u[b, 0]
        dv[b, 1] = vy - u[b, 1]
        dv[b, 2] = vz - u[b, 2]
    for a in range(m):
        c = cs[a]
        j = wj[c]
        if inv[j] > 0.0:
            lam = (dv[j, 0] * wn[c, 0] + dv[j, 1] * wn[c, 1] + dv[j, 2] * wn[c, 2]) / inv[j]
        else:
            i = wi[c]
            lam = -(dv[i, 0] * wn[c, 0] + dv[i, 1] * wn[c, 1] + dv[i, 2] * wn[c, 2]) / inv[i]
        wlam[c] = lam if lam > 0.0 else 0.0
    return nm
