"""The step's candidate pairs: every pair, or the neighbour list's plus those of swept bodies (compiled kernels).

Growable pair arrays with per-body adjacency lists (``head``/``nxt``), their versions and marks; the
pieces of a step that differ between the all-pairs and the neighbour-list solvers (see
:func:`.contact_solve._solver`).
"""
from __future__ import annotations

import math

import numpy as np

from driftframe.framework import broadphase_list
from driftframe.framework.contact_heap import grow_i
from driftframe.framework.contact_params import F_REBUILD, S_SWEPT, TOUCH
from driftframe.framework.contact_toi import toi
from driftframe.framework.kernels import kernel

_INF = math.inf


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def link_pair(p, i, j, head, nxt):
    nxt[2 * p] = head[i]
    head[i] = 2 * p
    nxt[2 * p + 1] = head[j]
    head[j] = 2 * p + 1


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def pair_structures(pi, pj, n):
    """Growable copies of the pairs, their adjacency lists (head/nxt), versions and marks."""
    P = pi.shape[0]
    cap_p = 2 * P if 2 * P > 16 else 16
    PI = np.empty(cap_p, np.int64)
    PJ = np.empty(cap_p, np.int64)
    for p in range(P):
        PI[p] = pi[p]
        PJ[p] = pj[p]
    head = np.empty(n, np.int64)
    for k in range(n):
        head[k] = -1
    nxt = np.empty(2 * cap_p, np.int64)
    for p in range(P):
        link_pair(p, PI[p], PJ[p], head, nxt)
    ver = np.empty(cap_p, np.int64)
    mark = np.empty(cap_p, np.int64)
    for p in range(cap_p):
        ver[p] = 0
        mark[p] = -1
    return P, PI, PJ, head, nxt, ver, mark


def all_pairs(n):
    """Every pair i < j of n bodies, in lexicographic order: two contiguous int64 arrays.

    numpy, not a kernel: it is called from Python when a scene's body count changes, and a kernel
    of its own cost ~0.15 s of every collision scene's cold compile (docs/bench/compile.md)."""
    n = int(n)
    i, j = np.triu_indices(n, 1)      # row by row: (0, 1), (0, 2), ..., (1, 2), ...
    return np.ascontiguousarray(i, np.int64), np.ascontiguousarray(j, np.int64)


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def initial_heap(PI, PJ, P, x, u, r, inv, live, spd, dt):
    """Every candidate pair's time of impact from t = 0, into a heap; and the overlaps at the start."""
    H = np.empty((2 * P if 2 * P > 1024 else 1024, 4), np.float64)    # room for every pair, and as many again
    hn = 0
    overlaps = 0
    worst = _INF
    wi_ = -1
    wj_ = -1
    for p in range(P):
        i, j = PI[p], PJ[p]
        if not (live[i] and live[j]) or inv[i] + inv[j] == 0.0:
            continue
        dx = x[j, 0] - x[i, 0]
        dy = x[j, 1] - x[i, 1]
        dz = x[j, 2] - x[i, 2]
        R = r[i] + r[j]
        dd = dx * dx + dy * dy + dz * dz
        Rt = R * (1.0 - TOUCH)
        if dd < Rt * Rt:
            q = math.sqrt(dd) / R
            overlaps += 1
            if q < worst:
                worst, wi_, wj_ = q, i, j
        tp, sl = toi(dx, dy, dz, u[j, 0] - u[i, 0], u[j, 1] - u[i, 1], u[j, 2] - u[i, 2],
                      R, inv[i] + inv[j], spd[i] + spd[j], 0.0, dt)
        if tp >= 0.0:
            H[hn, 0], H[hn, 1], H[hn, 2], H[hn, 3] = tp, p, 0.0, sl
            hn += 1
    return H, hn, overlaps, worst, wi_, wj_


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def has_pair(b, o, head, nxt, PI, PJ):
    node = head[b]
    while node >= 0:
        p = node >> 1
        if (PI[p] == o and PJ[p] == b) or (PI[p] == b and PJ[p] == o):
            return True
        node = nxt[node]
    return False


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def sweep_body(b, P, PI, PJ, head, nxt, ver, mark, swept, blo, bhi, centre, reach, order, lo_x, width, start):
    """Add the pairs of swept body b's path box with the listed territories and the other swept boxes."""
    n = swept.shape[0]
    found = broadphase_list.territory_query(blo[b], bhi[b], order, lo_x, width, centre, reach, swept)
    extra = np.empty(n, np.int64)
    ne = 0
    for o in range(n):
        if o != b and swept[o]:
            if start and o < b:
                continue                                  # at the start each swept pair once
            ok = True
            for d in range(3):
                if blo[b, d] > bhi[o, d] or blo[o, d] > bhi[b, d]:
                    ok = False
            if ok:
                extra[ne] = o
                ne += 1
    for q in range(found.shape[0] + ne):
        o = found[q] if q < found.shape[0] else extra[q - found.shape[0]]
        if o == b or has_pair(b, o, head, nxt, PI, PJ):
            continue
        if P == PI.shape[0]:
            z = np.int64(0)                                # see contact_params._NOT_LITERAL
            PI, PJ = grow_i(PI, 2 * P, z), grow_i(PJ, 2 * P, z)    # (all four hold P pairs, nxt 2 P)
            nxt = grow_i(nxt, 4 * P, z)
            ver = grow_i(ver, 2 * P, z)
            mark = grow_i(mark, 2 * P, np.int64(-1))
        PI[P] = min(b, o)
        PJ[P] = max(b, o)
        ver[P] = 0
        mark[P] = -1
        link_pair(P, PI[P], PJ[P], head, nxt)
        P += 1
    return P, PI, PJ, nxt, ver, mark


# -- the neighbour list's part of a step, and the drivers -----------------------------------------

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def listed_start(lst, pi, pj, x, u, r, live, dt):
    """Bodies swept at the start: their whole path against the territories and each other. Returns the
    count of swept bodies, and the pair structures when there are any (else ``pi``, ``pj`` stand in)."""
    swept, blo, bhi, centre, skin, reach, order, lo_x, width, budget, tosweep, newlo, newhi = lst
    n = x.shape[0]
    n_swept = np.int64(0)                # see contact_params._NOT_LITERAL
    for k in range(n):
        if swept[k] and live[k]:
            n_swept += 1
    if n_swept == 0:
        return n_swept, pi.shape[0], pi, pj, pi, pi, pi, pi
    P, PI, PJ, head, nxt, ver, mark = pair_structures(pi, pj, n)
    for k in range(n):
        if swept[k] and live[k]:
            for d in range(3):
                a0 = x[k, d]
                a1 = x[k, d] + u[k, d] * dt
                blo[k, d] = min(a0, a1) - r[k]
                bhi[k, d] = max(a0, a1) + r[k]
    for k in range(n):
        if swept[k] and live[k]:
            P, PI, PJ, nxt, ver, mark = sweep_body(k, P, PI, PJ, head, nxt, ver, mark, swept, blo, bhi,
                                               centre, reach, order, lo_x, width, np.bool_(True))
    return n_swept, P, PI, PJ, head, nxt, ver, mark


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, inline="always")
def listed_sweep(lst, ns, P, PI, PJ, head, nxt, ver, mark, n_swept, stats, flags):
    """Sweep the ``ns`` bodies in ``tosweep`` (their new boxes in ``newlo``/``newhi``: the solver found that
    their new paths leave their territory or box) and add their new pairs. Returns the pair structures,
    the count of swept bodies and the flags."""
    swept, blo, bhi, centre, skin, reach, order, lo_x, width, budget, tosweep, newlo, newhi = lst
    for q in range(ns):
        b = tosweep[q]
        if not swept[b]:
            swept[b] = True
            n_swept += 1
            if n_swept > budget:
                flags |= F_REBUILD
        for d in range(3):
            blo[b, d] = newlo[q, d]
            bhi[b, d] = newhi[q, d]
        stats[S_SWEPT] += 1
        P, PI, PJ, nxt, ver, mark = sweep_body(b, P, PI, PJ, head, nxt, ver, mark, swept, blo, bhi,
                                           centre, reach, order, lo_x, width, np.bool_(False))
    return P, PI, PJ, nxt, ver, mark, n_swept, flags
