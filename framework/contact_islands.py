"""One wave's contacts: restitution, islands and their impulses (compiled kernels; see :mod:`.contact`)."""
from __future__ import annotations

import numpy as np

from driftframe.framework import sorting
from driftframe.framework.contact_params import APPROACH, F_CAP, F_JAM, F_TC, JAM
from driftframe.framework.kernels import kernel


# _nrt=False: it allocates nothing, so it counts no reference to its five arrays (see contact_heap.sift_down)
@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, _nrt=False)
def kick(b, sg, lam, c, inv, bmark, wave, dv, moved, nm, wn):
    """Add body ``b``'s share ``sg * lam * inv[b]`` of contact ``c``'s impulse along its normal to ``dv``.

    ``dv`` holds this wave's velocity changes: a body's row is zeroed and the body listed in
    ``moved`` the first time the wave touches it (``bmark``). Returns the new count of moved bodies.
    """
    if inv[b] > 0.0:
        if bmark[b] != wave:
            bmark[b] = wave
            dv[b, 0] = dv[b, 1] = dv[b, 2] = 0.0
            moved[nm] = b
            nm += 1
        g = sg * lam * inv[b]
        dv[b, 0] += g * wn[c, 0]
        dv[b, 1] += g * wn[c, 1]
        dv[b, 2] += g * wn[c, 2]
    return nm


@kernel(error_model="numpy", no_cfunc_wrapper=True, inline="always")    # pasted into island_dense, its one caller
def solve_psd(A, y, m, out):
    """Solve ``A[:m, :m] out = y[:m]`` for a symmetric positive semi-definite A (A and y are overwritten).

    Gaussian elimination with symmetric pivoting on the largest remaining
    diagonal; pivots below 1e-12 of the largest are dependent rows, whose
    unknowns are set to 0 (a basic solution of a consistent singular system).
    Only + - * /, in an order fixed by the data.
    """
    perm = np.empty(m, np.int64)
    for k in range(m):
        perm[k] = k
    top = 0.0
    for k in range(m):
        if A[k, k] > top:
            top = A[k, k]
    rank = 0
    for s in range(m):
        q = s
        for k in range(s + 1, m):
            if A[k, k] > A[q, q]:
                q = k
        if not (A[q, q] > 1e-12 * top):
            break
        if q != s:
            for k in range(m):
                A[s, k], A[q, k] = A[q, k], A[s, k]
            for k in range(m):
                A[k, s], A[k, q] = A[k, q], A[k, s]
            y[s], y[q] = y[q], y[s]
            perm[s], perm[q] = perm[q], perm[s]
        piv = A[s, s]
        for k in range(s + 1, m):
            f = A[k, s] / piv
            if f != 0.0:
                for l in range(s + 1, m):
                    A[k, l] -= f * A[s, l]
                y[k] -= f * y[s]
        rank += 1
    sol = np.empty(m, np.float64)
    for s in range(m):
        sol[s] = 0.0
    for s in range(rank - 1, -1, -1):
        acc = y[s]
        for l in range(s + 1, rank):
            acc -= A[s, l] * sol[l]
        sol[s] = acc / A[s, s]
    for s in range(m):
        out[perm[s]] = sol[s]


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def island_dense(cs, K, wi, wj, wn, rhs, inv, lam, A, y, sub, act):
    """Impulses of one island's contacts ``cs[:K]`` (indices into the wave), >= 0, into ``lam``."""
    for a in range(K):
        act[a] = True
        lam[cs[a]] = 0.0
    while True:
        m = np.int64(0)                      # see contact_params._NOT_LITERAL
        for a in range(K):
            if act[a]:
                sub[m] = a
                m += 1
        if m == 0:
            return
        for p in range(m):
            ca = cs[sub[p]]
            ia, ja = wi[ca], wj[ca]
            for q in range(m):
                cb = cs[sub[q]]
                ib, jb = wi[cb], wj[cb]
                dot = wn[ca, 0] * wn[cb, 0] + wn[ca, 1] * wn[cb, 1] + wn[ca, 2] * wn[cb, 2]
                s = 0.0
                # J row: -n at body i, +n at body j; A_ab = sum over shared bodies of sign sign inv n_a.n_b
                if ia == ib:
                    s += inv[ia]
                if ia == jb:
                    s -= inv[ia]
                if ja == ib:
                    s -= inv[ja]
                if ja == jb:
                    s += inv[ja]
                A[p, q] = s * dot
            y[p] = rhs[ca]
        sol = np.empty(m, np.float64)
        solve_psd(A, y, m, sol)
        neg = False
        for p in range(m):
            if sol[p] < 0.0:
                act[sub[p]] = False
                neg = True
        if not neg:
            for p in range(m):
                lam[cs[sub[p]]] = sol[p]
            return


# Pieces of a wave, each its own small kernel, pasted into the step's loop (inline="always").

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, inline="always")
def restitution(K, wi, wj, e, t, t_last, burst, count, cap, t_c, same, wstick, we):
    """Each contact's restitution ``we``: the pair's, or the TC model's / the bounds'; ``wstick``: the
    contacts whose island sticks. Returns the flags raised and whether any island sticks."""
    flags = 0
    stick_any = False
    for k in range(K):
        i, j = wi[k], wj[k]
        ee = e[j] if e[j] < e[i] else e[i]                 # min(e[i], e[j]), as Python's min gives it
        gi = t - t_last[i]
        gj = t - t_last[j]
        bi = burst[i] + 1 if gi <= t_c else 1
        bj = burst[j] + 1 if gj <= t_c else 1
        # TC: a repeat within t_c, but not the same instant (a wave chain is bounded by the burst)
        rapid = (same < gi <= t_c) or (same < gj <= t_c)
        worn = ee < 1.0 and (count[i] >= cap or count[j] >= cap)
        wstick[k] = bi > 2 * JAM or bj > 2 * JAM or (ee < 1.0 and (count[i] >= 2 * cap or count[j] >= 2 * cap))
        if wstick[k]:
            stick_any = True
            ee = 0.0
        elif bi > JAM or bj > JAM:
            ee = 0.0
            flags |= F_JAM
        elif worn:
            ee = 0.0
            flags |= F_CAP
        elif ee < 1.0 and rapid:
            ee = 1.0                                   # TC model: a rapid repeat is elastic
            flags |= F_TC
        we[k] = ee
    return flags, stick_any


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, inline="always")
def islands(K, wi, wj, inv, parent, ustamp, waves, wroot):
    """Union-find over the movable bodies of the wave: each contact's island root into ``wroot``."""
    for k in range(K):
        for b in (wi[k], wj[k]):
            if ustamp[b] != waves:
                ustamp[b] = waves
                parent[b] = b
    for k in range(K):
        i, j = wi[k], wj[k]
        if inv[i] > 0.0 and inv[j] > 0.0:
            a = i
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            b = j
            while parent[b] != b:
                parent[b] = parent[parent[b]]
                b = parent[b]
            if a != b:
                if a < b:
                    parent[b] = a
                else:
                    parent[a] = b
    for k in range(K):
        a = wi[k] if inv[wi[k]] > 0.0 else wj[k]
        while parent[a] != a:
            a = parent[a]
        wroot[k] = a


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def island_sequential(cs, m, wi, wj, wn, we, u, dv, bmark, waves, spd, inv, wlam, moved, nm):
    """An island of more than DENSE_MAX contacts, contact by contact in pair order, each on the bodies'
    current velocities. Returns the new count of moved bodies."""
    n = u.shape[0]
    keys = np.empty(m, np.int64)
    for a in range(m):
        keys[a] = wi[cs[a]] * n + wj[cs[a]]
    ko = sorting.argsort_stable(keys, m)
    for a in range(m):
        c = cs[ko[a]]
        i, j = wi[c], wj[c]
        vn = 0.0
        for d in range(3):
            ud = u[j, d] - u[i, d]
            if bmark[j] == waves:
                ud += dv[j, d]
            if bmark[i] == waves:
                ud -= dv[i, d]
            vn += wn[c, d] * ud
        if not (vn < -APPROACH * (spd[i] + spd[j])):
            continue
        lam = -(1.0 + we[c]) * vn / (inv[i] + inv[j])
        wlam[c] = lam
        nm = kick(i, -1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
        nm = kick(j, 1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
    return nm
