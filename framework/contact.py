"""Sphere contact kernels: times of impact, islands of simultaneous contacts, the step's event loop.

Pure functions over arrays, compiled with numba and cached (only the first
run on a machine pays the compilation; docs/bench/compile.md measures it).
The collision system (:mod:`driftframe.systems.collision`) gathers the
bodies' start-of-step state, calls a solver (:func:`solve_all_pairs`,
:func:`solve_listed`) once per step and writes the result back; nothing
here knows about entities or components.

**Paths.** Body ``k`` moves as ``p(t) = x[k] + u[k] t`` for ``0 <= t <= dt``.
An impulse at time ``t`` changes ``u`` and moves the path's origin by
``-du t``, so the body stays where it is at ``t``.

**Time of impact** of a pair: the smaller root of ``|d + w t|^2 = R^2`` (``d``
relative position, ``w`` relative velocity, ``R = r_i + r_j``), written
``t = c / (-b + sqrt(b^2 - a c))`` with ``a = w.w``, ``b = d.w``, ``c =
d.d - R^2`` so that nothing cancels, and solved once more from where the pair
is at that estimate when it starts more than ``4 R`` apart (``c`` loses
digits there). A pair counts only when it approaches, ``v_n < -APPROACH
(|u_i| + |u_j|)`` -- a threshold from the pair's *own* speeds -- and when the
exact paths meet (``c <= 0``, or a real root): a near miss is never a
contact, whatever the tolerances. Pairs that already overlap (at spawn) and
approach are in contact now; those that overlap and separate are left to
separate (no stick, no jump).

**Waves and islands.** Contacts are taken in time order from a binary heap
(one entry per pair and version; a pair's entry is void once either body's
velocity changes). At the earliest instant ``t*`` every pending pair whose
contact lies within ``TOUCH R / |v_n|`` of ``t*`` (its gap is below
``TOUCH R`` there) and that still approaches forms one *wave*. The wave is
split into *islands* (connected components over movable bodies; an
immovable body joins nothing) and each island is solved on its own:
impulses ``lambda >= 0`` with

    A lambda = -(1 + e) v_n,   A = J M^-1 J^T   (the island's contacts only)

by Gaussian elimination with symmetric (diagonal) pivoting in a fixed order,
dropping contacts whose impulse comes out negative and solving again (at
most ``K`` times). Only ``+ - * / sqrt`` are used, in a fixed order, so a
step's result is the same bit for bit on any CPU (no LAPACK, no transcendental
ufunc). Islands of more than :data:`DENSE_MAX` contacts (a crystal or a pile
hit at once) are resolved contact by contact in pair order (packed index
order: ascending entity id), each a textbook two-body impulse, which keeps
the energy of elastic contacts exactly and costs ``O(K)``. With ``e = 1``
each contact reverses its normal velocity and the energy is unchanged:
``dKE = lambda . (v_n + v_n') / 2 = 0``. The bodies that changed have their
pairs re-examined from ``t*``; contacts that now approach at ``t*`` form the
next wave, so a chain of touching balls (Newton's cradle) passes the impulse
ball by ball inside one instant, and a symmetric hit stays symmetric.

**Bounds.** Each body keeps, within the step, the time of its last contact
and a *burst*: how many waves in a row it met within ``t_c`` of the previous
one.

* *Inelastic collapse* (Luding & McNamara's TC model, Granular Matter 1,
  1998): hard spheres with ``e < 1`` can meet infinitely often in finite
  time. A contact of a body whose previous contact was less than ``t_c``
  earlier is taken as elastic (``e = 1``). Energy is never gained; it is lost
  only by contacts the model keeps inelastic.
* *Jams*: a sphere wedged between immovable ones has no elastic answer and
  bounces forever in no time. Once a body's burst exceeds :data:`JAM` waves,
  its contacts are taken with ``e = 0`` for the rest of that burst (the
  motion along the walls is kept); past ``2 JAM`` the island's touching
  cluster is given one velocity (its centre of mass's, or that of an
  immovable body it touches), so every relative velocity in it is zero,
  which ends any burst.
* *Inelastic contacts per body per step* (pairs with ``e < 1``) are capped
  the same way: past ``cap`` a body's contacts are taken with ``e = 0``,
  past ``2 cap`` its touching cluster moves as one. A clump of inelastic
  spheres comes to rest as a clump instead of chattering. Elastic pairs are
  never capped (only bursts bound them), so no energy that should be kept is
  lost.

So the work of a step is bounded by the bodies involved times these
constants: it grows with the island, not with the scene.

The ``flags`` returned say which of these engaged (for a warning).
"""
from __future__ import annotations

import math

import numpy as np
from driftframe.framework.kernels import kernel

from driftframe.framework import broadphase as bp

#: Pairs whose contact is within ``TOUCH R / |v_n|`` of an instant meet at that instant (gap < TOUCH R).
TOUCH = 1e-9
#: Normal approach speeds below this fraction of the pair's own speeds (|u_i| + |u_j|) are rounding noise.
APPROACH = 1e-12
#: Centres closer than this fraction of r_i + r_j define no contact normal: such a pair is left to pass.
CENTRED = 1e-9
#: Longest time window (fraction of dt) one wave collects contacts over.
SLACK_MAX = 1e-9
#: Islands up to this many contacts are solved simultaneously; larger ones contact by contact.
DENSE_MAX = 32
#: Waves in a burst (each within t_c of the previous) before a body's contacts lose their bounce.
JAM = 256
#: Default cap on one body's contacts in one step (then e = 0; at twice this its island sticks).
CAP = 8
#: Default t_c of the TC model, as a fraction of dt.
TC = 1e-6

#: flags returned by the solvers (solve_all_pairs, solve_listed)
F_JAM = 1
F_TC = 2
F_CAP = 4
F_STICK = 8
F_LIMIT = 16
#: more bodies were swept than the list's budget: rebuild it
F_REBUILD = 32
#: the step needs the jam path: run it again with the _stick variant (the inputs are as they came)
F_AGAIN = 64

#: the solvers' stats: candidate pairs, contacts, waves, bodies swept, overlapping pairs at the start,
#: the deepest one's bodies i and j and its centres' distance / (r_i + r_j), islands solved contact by
#: contact, heap entries popped into a wave, pushed, put back
(S_PAIRS, S_CONTACTS, S_WAVES, S_SWEPT, S_OVERLAPS, S_WORST_I, S_WORST_J, S_WORST, S_SEQUENTIAL, S_POPPED,
 S_PUSHED, S_BACK) = range(12)

_INF = math.inf

# _NOT_LITERAL: a constant passed from one kernel to another (``f(0)``, or ``k = 0`` then ``f(k)``)
# is typed Literal[int](0) at first, and numba compiles the callee for it and again for int64
# once ``k`` widens (True and False each get their own, too). Constants that reach a callee are
# written np.int64(0) / np.bool_(True): one compile each. solve_all_pairs passing False and 0 had
# the solver, the largest kernel, compiled twice on a machine's first run (about 15 s more).


# Copies are loops, not slice assignments: ``b[:k] = a`` compiles numba's shape check and the string
# formatting of its error (about 1.5 s of an empty cache; docs/bench/compile.md).
@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _grow_f(a, n):
    """A (rows, cols) float array with room for ``n`` rows (at least twice as many), ``a`` copied in."""
    b = np.empty((max(n, 2 * a.shape[0]), a.shape[1]))
    for k in range(a.shape[0]):
        for d in range(a.shape[1]):
            b[k, d] = a[k, d]
    return b


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _grow_i(a, n, fill):
    """An int64 array of ``max(n, 2 len(a))`` with ``a`` copied in and ``fill`` after it."""
    b = np.empty(max(n, 2 * a.shape[0]), np.int64)
    for k in range(a.shape[0]):
        b[k] = a[k]
    for k in range(a.shape[0], b.shape[0]):
        b[k] = fill
    return b


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
    dist = math.sqrt(dd)
    if not (b < -APPROACH * speeds * dist) or not (dist > CENTRED * R):
        return -1.0, 0.0
    c = dd - R * R
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


# The heap is one (cap, 4) array of rows (time, pair, version, slack): numba counts a reference to
# every array a function call receives (an atomic operation, before and after the call), and with
# four arrays those counts were two thirds of a dense gas's solve. Pair and version are whole
# numbers held exactly in float64 (below 2^53). Order: by time, then by pair.
@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _sift_up(H, k):
    t, p, v, s = H[k, 0], H[k, 1], H[k, 2], H[k, 3]
    while k > 0:
        q = (k - 1) >> 1
        if t < H[q, 0] or (t == H[q, 0] and p < H[q, 1]):
            H[k, 0], H[k, 1], H[k, 2], H[k, 3] = H[q, 0], H[q, 1], H[q, 2], H[q, 3]
            k = q
        else:
            break
    H[k, 0], H[k, 1], H[k, 2], H[k, 3] = t, p, v, s


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _sift_down(H, k, n):
    t, p, v, s = H[k, 0], H[k, 1], H[k, 2], H[k, 3]
    while True:
        a = 2 * k + 1
        if a >= n:
            break
        b = a + 1
        if b < n and (H[b, 0] < H[a, 0] or (H[b, 0] == H[a, 0] and H[b, 1] < H[a, 1])):
            a = b
        if H[a, 0] < t or (H[a, 0] == t and H[a, 1] < p):
            H[k, 0], H[k, 1], H[k, 2], H[k, 3] = H[a, 0], H[a, 1], H[a, 2], H[a, 3]
            k = a
        else:
            break
    H[k, 0], H[k, 1], H[k, 2], H[k, 3] = t, p, v, s


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _pop(H, n):
    """Remove the root of a heap of ``n + 1`` rows (already read): the last row to the root, sifted down."""
    if n > 0:
        H[0, 0], H[0, 1], H[0, 2], H[0, 3] = H[n, 0], H[n, 1], H[n, 2], H[n, 3]
        _sift_down(H, np.int64(0), n)     # np.int64: see _NOT_LITERAL


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _push(H, n, t, p, v, s):
    """Add a row to a heap of ``n`` rows, which has room for it (the caller grows ``H`` before a loop
    of pushes: an array reassigned inside a loop is reference-counted on every pass)."""
    H[n, 0], H[n, 1], H[n, 2], H[n, 3] = t, p, v, s
    _sift_up(H, n)


# -- dense solve ------------------------------------------------------------------------------

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _kick(b, sg, lam, c, inv, bmark, wave, dv, moved, nm, wn):
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


@kernel(error_model="numpy", no_cfunc_wrapper=True)
def solve_psd(A, y, m, out):
    """Solve ``A[:m, :m] out = y[:m]`` for a symmetric positive semi-definite A (A and y are overwritten).

    Gaussian elimination with symmetric pivoting on the largest remaining
    diagonal; pivots below 1e-12 of the largest are dependent rows, whose
    unknowns are set to 0 (a basic solution of a consistent singular system).
    Only + - * /, in an order fixed by the data.
    """
    perm = np.arange(m)
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
    sol = np.zeros(m)
    for s in range(rank - 1, -1, -1):
        acc = y[s]
        for l in range(s + 1, rank):
            acc -= A[s, l] * sol[l]
        sol[s] = acc / A[s, s]
    for s in range(m):
        out[perm[s]] = sol[s]


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _island_dense(cs, K, wi, wj, wn, rhs, inv, lam, A, y, sub, act):
    """Impulses of one island's contacts ``cs[:K]`` (indices into the wave), >= 0, into ``lam``."""
    for a in range(K):
        act[a] = True
        lam[cs[a]] = 0.0
    while True:
        m = np.int64(0)                      # see _NOT_LITERAL
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
        sol = np.empty(m)
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


# Pieces of a wave, each its own small kernel: called once per wave (their arrays' reference counts cost
# nothing next to the wave), they keep _solve's body, which numba types as a whole, smaller (see
# docs/bench/compile.md).

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, inline="always")
def _restitution(K, wi, wj, e, t, t_last, burst, count, cap, t_c, same, wstick, we):
    """Each contact's restitution ``we``: the pair's, or the TC model's / the bounds'; ``wstick``: the
    contacts whose island sticks. Returns the flags raised and whether any island sticks."""
    flags = 0
    stick_any = False
    for k in range(K):
        i, j = wi[k], wj[k]
        ee = min(e[i], e[j])
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
def _islands(K, wi, wj, inv, parent, ustamp, waves, wroot):
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
def _island_sequential(cs, m, wi, wj, wn, we, u, dv, bmark, waves, spd, inv, wlam, moved, nm):
    """An island of more than DENSE_MAX contacts, contact by contact in pair order, each on the bodies'
    current velocities. Returns the new count of moved bodies."""
    n = u.shape[0]
    keys = np.empty(m, np.int64)
    for a in range(m):
        keys[a] = wi[cs[a]] * n + wj[cs[a]]
    ko = bp.argsort_stable(keys, m)
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
        nm = _kick(i, -1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
        nm = _kick(j, 1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
    return nm


# -- the step ---------------------------------------------------------------------------------

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _wave_scratch(cap):
    """A wave's arrays for up to ``cap`` contacts: pair, i, j, island root, island members, normal,
    normal velocity, restitution, impulse, stuck; the entries put back (time, pair, version, slack);
    right-hand side."""
    return (np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap, np.int64),
            np.empty(cap, np.int64), np.empty((cap, 3)), np.empty(cap), np.empty(cap), np.empty(cap),
            np.zeros(cap, np.bool_), np.empty(cap), np.empty(cap, np.int64), np.empty(cap, np.int64),
            np.empty(cap), np.empty(cap))


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _link(p, i, j, head, nxt):
    nxt[2 * p] = head[i]
    head[i] = 2 * p
    nxt[2 * p + 1] = head[j]
    head[j] = 2 * p + 1


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _pair_structures(pi, pj, n):
    """Growable copies of the pairs, their adjacency lists (head/nxt), versions and marks."""
    P = pi.shape[0]
    cap_p = max(2 * P, 16)
    PI = np.empty(cap_p, np.int64)
    PJ = np.empty(cap_p, np.int64)
    for p in range(P):
        PI[p] = pi[p]
        PJ[p] = pj[p]
    head = np.full(n, -1, np.int64)
    nxt = np.empty(2 * cap_p, np.int64)
    for p in range(P):
        _link(p, PI[p], PJ[p], head, nxt)
    ver = np.zeros(cap_p, np.int64)
    mark = np.full(cap_p, -1, np.int64)
    return P, PI, PJ, head, nxt, ver, mark


@kernel(error_model="numpy", no_cfunc_wrapper=True)
def all_pairs(n):
    """Every pair i < j of n bodies, in lexicographic order."""
    P = n * (n - 1) // 2
    pi = np.empty(P, np.int64)
    pj = np.empty(P, np.int64)
    k = 0
    for i in range(n):
        for j in range(i + 1, n):
            pi[k] = i
            pj[k] = j
            k += 1
    return pi, pj


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _initial(PI, PJ, P, x, u, r, inv, live, spd, dt):
    """Every candidate pair's time of impact from t = 0, into a heap; and the overlaps at the start."""
    H = np.empty((max(2 * P, 1024), 4))                   # room for every pair, and as many again
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
def _shift(t, d):
    """``t += d`` in place, element by element (``t - now`` and ``+ now`` without two numpy calls a step)."""
    for k in range(t.shape[0]):
        t[k] += d


def _solve(x, u, r, inv, e, live, t_last, now, pi, pj, dt, t_c, cap, lst):
    """The step's event loop: the body of every solver (:func:`solve_all_pairs`, :func:`solve_listed`
    and their ``_stick`` variants), each compiled from it with its own pieces (see :func:`_solver`)."""
    keep = _keep(x, u, t_last, lst)
    _shift(t_last, -now)
    n = x.shape[0]
    stats = np.zeros(12)
    flags = 0
    # the pair structures (adjacency, versions) are made only when needed: a quiet step makes none
    n_swept, P, PI, PJ, head, nxt, ver, mark = _start(lst, pi, pj, x, u, r, live, dt)
    early = n_swept > 0
    stats[3] = n_swept
    spd = np.empty(n)
    for k in range(n):
        spd[k] = math.sqrt(u[k, 0] * u[k, 0] + u[k, 1] * u[k, 1] + u[k, 2] * u[k, 2])

    # -- heap of pending contacts --
    H, hn, overlaps, worst, wi_, wj_ = _initial(PI, PJ, P, x, u, r, inv, live, spd, dt)
    for k in range((hn >> 1) - 1, -1, -1):
        _sift_down(H, k, hn)
    stats[4] = overlaps
    stats[5], stats[6], stats[7] = wi_, wj_, worst
    if hn == 0:                                            # no contact this step
        stats[0] = P
        _shift(t_last, now)
        return np.zeros(n, np.bool_), np.empty((0, 4)), np.empty((0, 3)), np.empty((0, 6)), stats, flags
    if not early:
        P, PI, PJ, head, nxt, ver, mark = _pair_structures(pi, pj, n)

    # -- per body bookkeeping --
    changed = np.zeros(n, np.bool_)
    x_in = np.empty((n, 3))
    u_in = np.empty((n, 3))
    burst = np.zeros(n, np.int64)
    count = np.zeros(n, np.int64)
    bmark = np.full(n, -1, np.int64)
    parent = np.arange(n)
    ustamp = np.full(n, -1, np.int64)
    kstamp = np.full(n, -1, np.int64)
    sseen = np.full(n, -1, np.int64)
    squeue = np.empty(n, np.int64)
    same = SLACK_MAX * dt
    # wave scratch, per wave (a wave holds at most one valid entry per pair and per heap entry: it is
    # made large enough before each wave, never inside the loops that fill it, where an array that
    # may be replaced is reference-counted on every pass)
    wcap = np.int64(64)                  # see _NOT_LITERAL
    wp, wi, wj, wroot, cs, wn, wvn, we, wlam, wstick, back_t, back_p, back_v, back_s, rhs = _wave_scratch(wcap)
    A = np.empty((DENSE_MAX, DENSE_MAX))
    y = np.empty(DENSE_MAX)
    sub = np.empty(DENSE_MAX, np.int64)
    act = np.empty(DENSE_MAX, np.bool_)
    one = np.zeros(1, np.int64)
    moved = np.empty(n, np.int64)
    dv = np.zeros((n, 3))
    # events
    ev = np.empty((64, 4))
    ev_n = np.empty((64, 3))
    ev_x = np.empty((64, 6))
    ne = 0

    waves = 0
    limit = 64 * (n + P) + 100_000
    while hn > 0:
        # -- pop the earliest valid entry --
        t0 = H[0, 0]
        p0 = int(H[0, 1])
        v0 = int(H[0, 2])
        hn -= 1
        _pop(H, hn)
        if v0 != ver[p0]:
            continue
        if waves >= limit:
            flags |= F_LIMIT
            break
        # -- the wave: every valid entry within its own slack of t0 --
        need = min(P, hn) + 1                              # entries it can take (valid ones: one per pair)
        if need > wcap:
            wcap = max(2 * wcap, need)
            wp, wi, wj, wroot, cs, wn, wvn, we, wlam, wstick, back_t, back_p, back_v, back_s, rhs = \
                _wave_scratch(wcap)
        K = np.int64(0)                                    # see _NOT_LITERAL
        nb = 0
        horizon = t0 + SLACK_MAX * dt
        cand_p = p0
        cand_ok = True
        while True:
            if cand_ok:
                i, j = PI[cand_p], PJ[cand_p]
                wx = u[j, 0] - u[i, 0]
                wy = u[j, 1] - u[i, 1]
                wz = u[j, 2] - u[i, 2]
                dx = x[j, 0] - x[i, 0] + wx * t0
                dy = x[j, 1] - x[i, 1] + wy * t0
                dz = x[j, 2] - x[i, 2] + wz * t0
                dist = math.sqrt(dx * dx + dy * dy + dz * dz)
                if dist > 0.0:
                    nx, ny, nz = dx / dist, dy / dist, dz / dist
                    vn = nx * wx + ny * wy + nz * wz
                else:
                    nx = ny = nz = vn = 0.0
                if vn < -APPROACH * (spd[i] + spd[j]):
                    wp[K], wi[K], wj[K] = cand_p, i, j
                    wn[K, 0], wn[K, 1], wn[K, 2] = nx, ny, nz
                    wvn[K] = vn
                    K += 1
            if hn == 0 or H[0, 0] > horizon:
                break
            tp, pp, vv, ss = H[0, 0], int(H[0, 1]), int(H[0, 2]), H[0, 3]
            stats[9] += 1
            hn -= 1
            _pop(H, hn)
            if vv != ver[pp]:
                cand_ok = False
                continue
            if tp - t0 <= ss:
                cand_p = pp
                cand_ok = True
                ver[pp] += 1                               # taken: its entry is void from now on
            else:
                back_t[nb], back_p[nb], back_v[nb], back_s[nb] = tp, pp, vv, ss
                nb += 1
                cand_ok = False
        ver[p0] += 1
        stats[11] += nb
        if hn + nb > H.shape[0]:
            H = _grow_f(H, hn + nb)
        for b in range(nb):                                # not this instant: back into the heap
            _push(H, hn, back_t[b], back_p[b], back_v[b], back_s[b])
            hn += 1
        if K == 0:
            continue
        waves += 1
        t = t0
        # -- restitution of each contact: the pair's, or the TC model / the bounds; islands --
        fl, stick_any = _restitution(K, wi, wj, e, t, t_last, burst, count, cap, t_c, same, wstick, we)
        flags |= fl
        _islands(K, wi, wj, inv, parent, ustamp, waves, wroot)
        for k in range(K):
            rhs[k] = -(1.0 + we[k]) * wvn[k]
            wlam[k] = 0.0
        if K == 1:
            ordk = one                                     # a lone contact (most waves): nothing to sort
        else:
            ordk = bp.argsort_stable(wroot, K)             # islands together, wave order inside
        nm = np.int64(0)                 # see _NOT_LITERAL
        s = 0
        while s < K:
            root = wroot[ordk[s]]
            f = s
            while f < K and wroot[ordk[f]] == root:
                f += 1
            m = f - s
            for a in range(m):
                cs[a] = ordk[s + a]
            stick = False
            if stick_any:
                for a in range(m):
                    if wstick[cs[a]]:
                        stick = True
            if stick:
                nm = _stick_fn(cs, m, wi, wj, wn, inv, live, u, x, r, t, wlam, dv, moved, nm, bmark, waves, head,
                               nxt, PI, PJ, sseen, squeue)
                if nm < 0:
                    break                                  # _no_stick: this driver cannot; F_AGAIN below
                flags |= F_STICK
            elif m == 1:
                c = cs[0]
                i, j = wi[c], wj[c]
                lam = rhs[c] / (inv[i] + inv[j])
                wlam[c] = lam
                nm = _kick(i, -1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
                nm = _kick(j, 1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
            elif m <= DENSE_MAX:
                _island_dense(cs, m, wi, wj, wn, rhs, inv, wlam, A, y, sub, act)
                for a in range(m):
                    c = cs[a]
                    lam = wlam[c]
                    if lam == 0.0:
                        continue
                    nm = _kick(wi[c], -1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
                    nm = _kick(wj[c], 1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
            else:
                stats[8] += 1
                nm = _island_sequential(cs, m, wi, wj, wn, we, u, dv, bmark, waves, spd, inv, wlam, moved, nm)
            s = f
        if nm < 0:
            flags |= F_AGAIN
            break
        # -- bookkeeping of the bodies that took an impulse; events --
        if ne + K > ev.shape[0]:
            ev, ev_n, ev_x = _grow_f(ev, ne + K), _grow_f(ev_n, ne + K), _grow_f(ev_x, ne + K)
        for k in range(K):
            if not (wlam[k] > 0.0):
                continue
            i, j = wi[k], wj[k]
            for b in (i, j):
                if kstamp[b] != waves:
                    kstamp[b] = waves                      # once per body per wave
                    burst[b] = burst[b] + 1 if t - t_last[b] <= t_c else 1
                    t_last[b] = t
                    if min(e[i], e[j]) < 1.0:
                        count[b] += 1                      # the cap is on inelastic contacts
            ev[ne, 0], ev[ne, 1], ev[ne, 2], ev[ne, 3] = i, j, t, wlam[k]
            for d in range(3):
                ev_n[ne, d] = wn[k, d]
                ev_x[ne, d] = x[i, d] + u[i, d] * t + r[i] * wn[k, d]
                ev_x[ne, 3 + d] = x[j, d] + u[j, d] * t - r[j] * wn[k, d]
            ne += 1
        # -- apply: new velocity from t on; p(t) = x + u t stays where it was --
        for a in range(nm):
            b = moved[a]
            if not changed[b]:                             # its x and u as they came (for F_AGAIN)
                for d in range(3):
                    x_in[b, d] = x[b, d]
                    u_in[b, d] = u[b, d]
            for d in range(3):
                u[b, d] += dv[b, d]
                x[b, d] -= dv[b, d] * t
            spd[b] = math.sqrt(u[b, 0] * u[b, 0] + u[b, 1] * u[b, 1] + u[b, 2] * u[b, 2])
            changed[b] = True
        # -- bodies whose new path leaves their cover: sweep them, add their new pairs --
        P, PI, PJ, nxt, ver, mark, n_swept, flags = _resweep(lst, moved, nm, x, u, r, t, dt, P, PI, PJ, head, nxt,
                                                             ver, mark, n_swept, stats, flags)
        # -- re-examine every pair of the bodies that changed, from t on (each pushed at most once) --
        if hn + P > H.shape[0]:
            H = _grow_f(H, hn + P)
        for a in range(nm):
            b = moved[a]
            node = head[b]
            while node >= 0:
                p = node >> 1
                node = nxt[node]
                if mark[p] == waves:
                    continue
                mark[p] = waves
                ver[p] += 1
                i, j = PI[p], PJ[p]
                if not (live[i] and live[j]):
                    continue
                tp, sl = toi(x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2],
                              u[j, 0] - u[i, 0], u[j, 1] - u[i, 1], u[j, 2] - u[i, 2],
                              r[i] + r[j], inv[i] + inv[j], spd[i] + spd[j], t, dt)
                if tp >= 0.0:
                    _push(H, hn, tp, p, ver[p], sl)
                    hn += 1
                    stats[10] += 1
    stats[0] = P
    stats[1] = ne
    stats[2] = waves
    _shift(t_last, now)
    if flags & F_AGAIN:
        _put_back(keep, x, u, t_last, lst, changed, x_in, u_in)
    return changed, ev[:ne], ev_n[:ne], ev_x[:ne], stats, flags


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _stick(cs, m, wi, wj, wn, inv, live, u, x, r, t, wlam, dv, moved, nm, bmark, wave, head, nxt, PI, PJ, seen,
           queue):
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


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _has_pair(b, o, head, nxt, PI, PJ):
    node = head[b]
    while node >= 0:
        p = node >> 1
        if (PI[p] == o and PJ[p] == b) or (PI[p] == b and PJ[p] == o):
            return True
        node = nxt[node]
    return False


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _sweep(b, P, PI, PJ, head, nxt, ver, mark, swept, blo, bhi, centre, reach, order, lo_x, width, start):
    """Add the pairs of swept body b's path box with the listed territories and the other swept boxes."""
    n = swept.shape[0]
    found = bp.territory_query(blo[b], bhi[b], order, lo_x, width, centre, reach, swept)
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
        if o == b or _has_pair(b, o, head, nxt, PI, PJ):
            continue
        if P == PI.shape[0]:
            z = np.int64(0)                                # see _NOT_LITERAL
            PI, PJ = _grow_i(PI, 2 * P, z), _grow_i(PJ, 2 * P, z)    # (all four hold P pairs, nxt 2 P)
            nxt = _grow_i(nxt, 4 * P, z)
            ver = _grow_i(ver, 2 * P, z)
            mark = _grow_i(mark, 2 * P, np.int64(-1))
        PI[P] = min(b, o)
        PJ[P] = max(b, o)
        ver[P] = 0
        mark[P] = -1
        _link(P, PI[P], PJ[P], head, nxt)
        P += 1
    return P, PI, PJ, nxt, ver, mark


# -- the neighbour list's part of a step, and the drivers -----------------------------------------

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _listed_start(lst, pi, pj, x, u, r, live, dt):
    """Bodies swept at the start: their whole path against the territories and each other. Returns the
    count of swept bodies, and the pair structures when there are any (else ``pi``, ``pj`` stand in)."""
    swept, blo, bhi, centre, skin, reach, order, lo_x, width, budget, tosweep, newlo, newhi = lst
    n = x.shape[0]
    n_swept = np.int64(0)                # see _NOT_LITERAL
    for k in range(n):
        if swept[k] and live[k]:
            n_swept += 1
    if n_swept == 0:
        return n_swept, pi.shape[0], pi, pj, pi, pi, pi, pi
    P, PI, PJ, head, nxt, ver, mark = _pair_structures(pi, pj, n)
    for k in range(n):
        if swept[k] and live[k]:
            for d in range(3):
                a0 = x[k, d]
                a1 = x[k, d] + u[k, d] * dt
                blo[k, d] = min(a0, a1) - r[k]
                bhi[k, d] = max(a0, a1) + r[k]
    for k in range(n):
        if swept[k] and live[k]:
            P, PI, PJ, nxt, ver, mark = _sweep(k, P, PI, PJ, head, nxt, ver, mark, swept, blo, bhi,
                                               centre, reach, order, lo_x, width, np.bool_(True))
    return n_swept, P, PI, PJ, head, nxt, ver, mark


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _unlisted_start(lst, pi, pj, x, u, r, live, dt):
    """Every pair a candidate: nobody swept (``pi`` stands in for the pair structures, made later)."""
    return np.int64(0), pi.shape[0], pi, pj, pi, pi, pi, pi


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, inline="always")
def _listed_resweep(lst, moved, nm, x, u, r, t, dt, P, PI, PJ, head, nxt, ver, mark, n_swept, stats, flags):
    """The moved bodies whose new path leaves their territory (or their swept box) are swept: their new
    pairs are added. Returns the pair structures, the count of swept bodies and the flags."""
    swept, blo, bhi, centre, skin, reach, order, lo_x, width, budget, tosweep, newlo, newhi = lst
    # first which (the loop that may replace the pair arrays runs only over those: see _push)
    ns = 0
    for a in range(nm):
        b = moved[a]
        if not swept[b]:
            ox = x[b, 0] + u[b, 0] * dt - centre[0, b]
            oy = x[b, 1] + u[b, 1] * dt - centre[1, b]
            oz = x[b, 2] + u[b, 2] * dt - centre[2, b]
            if ox * ox + oy * oy + oz * oz < skin[b] * skin[b]:
                continue                                   # still inside its territory (a ball: convex)
        inside = swept[b]
        for d in range(3):
            a0 = x[b, d] + u[b, d] * t
            a1 = x[b, d] + u[b, d] * dt
            newlo[ns, d] = min(a0, a1) - r[b]
            newhi[ns, d] = max(a0, a1) + r[b]
            if newlo[ns, d] < blo[b, d] or newhi[ns, d] > bhi[b, d]:
                inside = False
        if inside:
            continue                                       # swept: still inside its box
        tosweep[ns] = b
        ns += 1
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
        stats[3] += 1
        P, PI, PJ, nxt, ver, mark = _sweep(b, P, PI, PJ, head, nxt, ver, mark, swept, blo, bhi,
                                           centre, reach, order, lo_x, width, np.bool_(False))
    return P, PI, PJ, nxt, ver, mark, n_swept, flags


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, inline="always")
def _unlisted_resweep(lst, moved, nm, x, u, r, t, dt, P, PI, PJ, head, nxt, ver, mark, n_swept, stats, flags):
    """Every pair a candidate: nothing to add."""
    return P, PI, PJ, nxt, ver, mark, n_swept, flags


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _no_stick(cs, m, wi, wj, wn, inv, live, u, x, r, t, wlam, dv, moved, nm, bmark, wave, head, nxt, PI, PJ, seen,
              queue):
    """:func:`_stick`'s stand-in in the drivers without it: -1, the step is to be run again with it."""
    return np.int64(-1)


# F_AGAIN: a step is run again from its inputs as they came. What it changes: x and u of the bodies it
# moved (_solve keeps their rows before it first changes them: O(moved), not O(n) a step), t_last (shifted
# in place: (t - now) + now is not t in every bit, so a copy) and, with the list, swept. blo and bhi need
# none: the rows of bodies swept at the start are made again from x and u, the others are not read.

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _put_rows(x, u, changed, x_in, u_in):
    for b in range(changed.shape[0]):
        if changed[b]:
            for d in range(3):
                x[b, d] = x_in[b, d]
                u[b, d] = u_in[b, d]


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _keep_pairs(x, u, t_last, lst):
    return t_last.copy()


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _put_back_pairs(keep, x, u, t_last, lst, changed, x_in, u_in):
    _put_rows(x, u, changed, x_in, u_in)
    for k in range(t_last.shape[0]):
        t_last[k] = keep[k]


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _keep_listed(x, u, t_last, lst):
    return t_last.copy(), lst[0].copy()


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _put_back_listed(keep, x, u, t_last, lst, changed, x_in, u_in):
    _put_rows(x, u, changed, x_in, u_in)
    for k in range(t_last.shape[0]):
        t_last[k] = keep[0][k]
        lst[0][k] = keep[1][k]


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _keep_nothing(x, u, t_last, lst):
    """The variants with the jam path never end a step with F_AGAIN."""
    return None


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _put_back_nothing(keep, x, u, t_last, lst, changed, x_in, u_in):
    pass


def _solver(name, doc, **pieces):
    """A solver compiled from :func:`_solve` with ``pieces`` for its names ``_start``, ``_resweep``,
    ``_stick_fn``, ``_keep``, ``_put_back``: one compiled unit each, holding only the code its scenes run
    (numba compiles whatever a kernel can call, and pasting the body into drivers with inline="always"
    copies its IR block by block, which cost more than it saved: docs/bench/compile.md)."""
    import types
    scope = dict(globals(), **pieces)
    f = types.FunctionType(_solve.__code__, scope, name)
    f.__qualname__ = name
    f.__doc__ = doc
    f.__module__ = __name__
    return kernel(error_model="numpy")(f)


_LISTED_DOC = """One step of contacts for bodies on paths ``x + u t`` (``x``, ``u``: (n, 3), changed in place).

    ``r``, ``inv``, ``e``: radius, inverse mass (0 = immovable), restitution
    per body; ``live``: bodies taking part (False: a body with non-finite
    state, left out); ``t_last``: each body's last contact time in absolute
    seconds (-inf: none), updated in place (the TC model looks back across
    steps); ``now``: the step's start, s (inside, times are relative to it).
    ``pi``, ``pj``: candidate pairs, from a
    :class:`~driftframe.framework.broadphase.NeighbourList` whose arrays
    ``lst`` holds: ``(swept, blo, bhi, centre, skin, reach, order, lo_x, width,
    budget, tosweep, newlo, newhi)`` (``blo``/``bhi``: (n, 3) path boxes of
    swept bodies; ``centre`` (3, n); ``budget``: swept bodies before
    F_REBUILD; the last three: scratch of n, (n, 3), (n, 3)); ``swept``,
    ``blo``, ``bhi`` are changed in place for bodies whose path leaves their
    territory: they are swept against the others and their new pairs added.

    Returns ``(changed, events, ev_n, ev_point, stats, flags)``: which bodies'
    velocity changed; per contact ``(i, j, time, impulse)``, the normal (i to j)
    and the contact points on i's and on j's surface (6 numbers); ``stats``
    (indexed by the S_* constants); ``flags`` (F_* bits). With F_AGAIN the
    step needs the jam path: every input is as it came; run
    :func:`solve_listed_stick` with them.
    """

# The solvers. A scene of few bodies compiles no neighbour-list code, and no scene compiles the jam path
# (_stick) until one jams: a step that needs it ends with F_AGAIN and its inputs as they came, and the
# caller runs it again with the _stick variant (the same result, bit for bit, as that variant alone).
solve_listed = _solver("solve_listed", _LISTED_DOC, _start=_listed_start, _resweep=_listed_resweep,
                       _stick_fn=_no_stick, _keep=_keep_listed, _put_back=_put_back_listed)
solve_listed_stick = _solver("solve_listed_stick", ":func:`solve_listed` with the jam path (:func:`_stick`).",
                             _start=_listed_start, _resweep=_listed_resweep, _stick_fn=_stick,
                             _keep=_keep_nothing, _put_back=_put_back_nothing)
solve_all_pairs = _solver("solve_all_pairs", """:func:`solve_listed` with every pair a candidate (few bodies)
    and ``lst`` None; with F_AGAIN run :func:`solve_all_pairs_stick`.""",
                          _start=_unlisted_start, _resweep=_unlisted_resweep, _stick_fn=_no_stick,
                          _keep=_keep_pairs, _put_back=_put_back_pairs)
solve_all_pairs_stick = _solver("solve_all_pairs_stick", ":func:`solve_all_pairs` with the jam path.",
                                _start=_unlisted_start, _resweep=_unlisted_resweep, _stick_fn=_stick,
                                _keep=_keep_nothing, _put_back=_put_back_nothing)


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


@kernel(error_model="numpy", no_cfunc_wrapper=True)
def scatter_bodies(pos, vel, t_idx, v_idx, x0, v0, a, x, u, changed, dt):
    """Write the end of the step into the columns: a body whose velocity the solver changed ends at
    ``x + u dt`` with ``u`` (plus the second ``a dt/2``), any other at ``x0 + v0 dt + a dt^2/2`` with
    ``v0 + a dt``, as the movement system would move it. Bodies without a Velocity are not written."""
    n = x0.shape[0]
    has_a = a.shape[0] == n
    half = 0.5 * dt
    half2 = 0.5 * dt * dt
    for k in range(n):
        vk = v_idx[k]
        if vk < 0:
            continue
        t = t_idx[k]
        for d in range(3):
            if changed[k]:
                p = x[k, d] + u[k, d] * dt
                q = u[k, d]
                if has_a:
                    q = q + half * a[k, d]
            else:
                p = x0[k, d] + v0[k, d] * dt
                q = v0[k, d]
                if has_a:
                    p = p + half2 * a[k, d]
                    q = v0[k, d] + dt * a[k, d]
            pos[t, d] = p
            vel[vk, d] = q
