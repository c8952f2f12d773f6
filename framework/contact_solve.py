"""The step's event loop, and the four solvers compiled from it (the method: :mod:`.contact`).

:func:`_solve` is the loop: pop the earliest contact from the heap, gather its wave, solve the wave's
islands, record its events, apply the impulses, look again at the pairs of the bodies that changed. Its
stages are written in the loop, not called: as kernels of their own (called, or pasted with
``inline="always"``) the same code ran slower (docs/design/contact.md).
"""
from __future__ import annotations

import math

import numpy as np

from driftframe.framework import sorting
from driftframe.framework.contact_again import (keep_listed, keep_nothing, keep_pairs, put_back_listed,
                                                put_back_nothing, put_back_pairs)
from driftframe.framework.contact_heap import grow_f, heap_pop, heap_push, sift_down
from driftframe.framework.contact_islands import island_dense, island_sequential, islands, kick, restitution
from driftframe.framework.contact_jam import stick_cluster
from driftframe.framework.contact_pairs import initial_heap, listed_start, listed_sweep, pair_structures
from driftframe.framework.contact_params import (APPROACH, DENSE_MAX, F_AGAIN, F_LIMIT, F_STICK, N_STATS, S_BACK,
                                                 S_CONTACTS, S_OVERLAPS, S_PAIRS, S_POPPED, S_PUSHED, S_SEQUENTIAL,
                                                 S_SWEPT, S_WAVES, S_WORST, S_WORST_I, S_WORST_J, SLACK_MAX)
from driftframe.framework.contact_toi import toi
from driftframe.framework.contact_wave import apply_wave, leaving, record_wave
from driftframe.framework.kernels import kernel, variant
from driftframe.framework.static_shapes import shape_contact, shape_push, shapes_start

_OPTS = dict(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)

# _REASSIGNED: numba keeps every variable in its own slot and copies an array variable, reference count and
# all (a struct of 7 or 9 fields unpacked: some 25 LLVM instructions), at each join of the control flow that
# its SSA form gives a variable assigned more than once. In this loop that was most of the solver's IR:
# the wave's scratch (15 arrays) and the pair structures (6) reassigned inside it, three event arrays
# growing. So the solver assigns them once where it can (an outer loop for the wave's scratch, one events
# array, the list's re-sweep only in the listed solvers, whose P can grow): its IR shrank by a third and a
# cold compile by a second or so (docs/bench/compile.md).


@kernel(**_OPTS)
def wave_scratch(cap):
    """A wave's arrays for up to ``cap`` contacts: pair, i, j, island root, island members, normal,
    normal velocity, restitution, impulse, stuck; the entries put back (time, pair, version, slack);
    right-hand side; the contacts in island order."""
    wstick = np.empty(cap, np.bool_)
    for k in range(cap):
        wstick[k] = False
    return (np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap, np.int64),
            np.empty(cap, np.int64), np.empty((cap, 3), np.float64), np.empty(cap, np.float64),
            np.empty(cap, np.float64), np.empty(cap, np.float64), wstick, np.empty(cap, np.float64),
            np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap, np.float64), np.empty(cap, np.float64),
            np.empty(cap, np.int64))


@kernel(**_OPTS)
def body_scratch(n):
    """A step's arrays per body: velocity changed; x and u as they came (for F_AGAIN); burst and count of
    contacts; the wave that last kicked it, joined it in an island, counted its contact, took it into a
    stuck cluster; union-find parents; the cluster's queue; the wave's moved bodies and their velocity
    changes. Then a dense island's scratch (A, y, sub, act: :func:`island_dense`); the events' first rows
    (``E`` in :func:`_solve`)."""
    changed = np.empty(n, np.bool_)
    burst = np.empty(n, np.int64)
    count = np.empty(n, np.int64)
    bmark = np.empty(n, np.int64)
    ustamp = np.empty(n, np.int64)
    kstamp = np.empty(n, np.int64)
    sseen = np.empty(n, np.int64)
    parent = np.empty(n, np.int64)
    dv = np.empty((n, 3), np.float64)
    for k in range(n):
        changed[k] = False
        burst[k] = count[k] = 0
        bmark[k] = ustamp[k] = kstamp[k] = sseen[k] = -1
        parent[k] = k
        dv[k, 0] = dv[k, 1] = dv[k, 2] = 0.0
    return (changed, np.empty((n, 3), np.float64), np.empty((n, 3), np.float64), burst, count, bmark, ustamp, kstamp,
            sseen, parent, np.empty(n, np.int64), np.empty(n, np.int64), dv,
            np.empty((DENSE_MAX, DENSE_MAX), np.float64), np.empty(DENSE_MAX, np.float64),
            np.empty(DENSE_MAX, np.int64), np.empty(DENSE_MAX, np.bool_), np.empty((64, 13), np.float64))


@kernel(**_OPTS)
def _step_arrays(u):
    """The step's stats (zeros) and each body's speed ``|u|``."""
    stats = np.empty(N_STATS, np.float64)
    for k in range(N_STATS):
        stats[k] = 0.0
    spd = np.empty(u.shape[0], np.float64)
    for k in range(u.shape[0]):
        spd[k] = math.sqrt(u[k, 0] * u[k, 0] + u[k, 1] * u[k, 1] + u[k, 2] * u[k, 2])
    return stats, spd


@kernel(**_OPTS)
def _events(E, ne, n):
    """The step's events (rows ``E[:ne]``, see :func:`_solve`) as the solvers return them: ``(i, j, time,
    impulse)``, the normal, the two points; and ``changed`` all False for a step without contact (n > 0)."""
    ev = np.empty((ne, 4), np.float64)
    ev_n = np.empty((ne, 3), np.float64)
    ev_x = np.empty((ne, 6), np.float64)
    for k in range(ne):
        for d in range(4):
            ev[k, d] = E[k, d]
        for d in range(3):
            ev_n[k, d] = E[k, 4 + d]
        for d in range(6):
            ev_x[k, d] = E[k, 7 + d]
    changed = np.empty(n, np.bool_)
    for k in range(n):
        changed[k] = False
    return changed, ev, ev_n, ev_x


@kernel(**_OPTS)
def _shift(t, d):
    """``t += d`` in place, element by element (``t - now`` and ``+ now`` without two numpy calls a step)."""
    for k in range(t.shape[0]):
        t[k] += d


@kernel(**_OPTS)
def _listed_structures(n_swept, P, PI, PJ, head, nxt, ver, mark, pi, pj, n):
    """The structures ``listed_start`` made (bodies were swept), else new ones of ``pi``, ``pj`` (one call:
    the solver then assigns them once, see :func:`_solve`)."""
    if n_swept > 0:
        return P, PI, PJ, head, nxt, ver, mark
    return pair_structures(pi, pj, n)


def _solve(x, u, r, inv, e, live, t_last, now, pi, pj, dt, t_c, cap, lst):
    """The step's event loop: the body of every solver (:func:`solve_all_pairs`, :func:`solve_listed`
    and their ``_stick`` variants), each compiled from it with its own pieces (see :func:`_solver`)."""
    keep = _keep(x, u, t_last, lst)
    _shift(t_last, -now)
    n = x.shape[0]
    stats, spd = _step_arrays(u)
    flags = np.int64(0)                  # see contact_params._NOT_LITERAL
    # the pair structures (adjacency, versions) are made only when needed: a quiet step makes none
    if _LISTED:
        n_swept, P0, PI0, PJ0, head0, nxt0, ver0, mark0 = listed_start(lst, pi, pj, x, u, r, live, dt)
        swept, blo, bhi, centre, skin, _r, _o, _l, _w, _b, tosweep, newlo, newhi = lst
    else:
        n_swept, P0, PI0, PJ0 = np.int64(0), pi.shape[0], pi, pj
    stats[S_SWEPT] = n_swept
    # -- heap of pending contacts --
    H, hn, overlaps, worst, wi_, wj_ = initial_heap(PI0, PJ0, P0, x, u, r, inv, live, spd, dt)
    ns = n
    if _STATIC:                                            # shapes: bodies ns.., lst their table
        ns, hn = shapes_start(H, hn, PI0, PJ0, P0, x, u, r, live, spd, dt, lst, n)
    for k in range((hn >> 1) - 1, -1, -1):
        sift_down(H, k, hn)
    stats[S_OVERLAPS] = overlaps
    stats[S_WORST_I], stats[S_WORST_J], stats[S_WORST] = wi_, wj_, worst
    if hn == 0:                                            # no contact this step
        stats[S_PAIRS] = P0
        _shift(t_last, now)
        changed, ev, ev_n, ev_x = _events(H, np.int64(0), n)
        return changed, ev, ev_n, ev_x, stats, flags
    if _LISTED:
        P, PI, PJ, head, nxt, ver, mark = _listed_structures(n_swept, P0, PI0, PJ0, head0, nxt0, ver0, mark0, pi,
                                                             pj, n)
    else:
        P, PI, PJ, head, nxt, ver, mark = pair_structures(pi, pj, n)
    # -- per body bookkeeping --
    (changed, x_in, u_in, burst, count, bmark, ustamp, kstamp, sseen, parent, squeue, moved, dv, A, y, sub, act,
     E) = body_scratch(n)                             # E: the events, a row each (see _events)
    same = SLACK_MAX * dt
    ne = np.int64(0)                     # see contact_params._NOT_LITERAL
    waves = 0
    limit = 64 * (n + P) + 100_000
    # The inner loop (one pass a wave) assigns no array: an array variable that a loop assigns is copied at
    # each join of its control flow, with an atomic increment and decrement of its reference count (a
    # call each: ~45 a wave, a fifth of a dense gas's solve, docs/bench/collision_stress.md; and compile
    # time, see _REASSIGNED). What replaces an array (a larger heap, events or wave scratch, new pairs of a
    # swept body) is done in the outer loop, which the inner one leaves for it; a wave's moved bodies are
    # looked at again (pend, from time tw) at the top of the next pass, after the outer loop's work.
    wcap = np.int64(64)                  # see contact_params._NOT_LITERAL
    pend = np.int64(0)
    tw = 0.0
    ns_sweep = np.int64(0)
    more = True
    while more:
        more = False
        if _LISTED:
            if ns_sweep > 0:               # bodies whose new path leaves their cover: sweep them, add their pairs
                P, PI, PJ, nxt, ver, mark, n_swept, flags = listed_sweep(lst, ns_sweep, P, PI, PJ, head, nxt, ver,
                                                                         mark, n_swept, stats, flags)
                ns_sweep = np.int64(0)
        if hn + P > H.shape[0]:
            H = grow_f(H, hn + P)
        if ne + wcap > E.shape[0]:
            E = grow_f(E, ne + wcap)
        wp, wi, wj, wroot, cs, wn, wvn, we, wlam, wstick, back_t, back_p, back_v, back_s, rhs, ordk = wave_scratch(
            wcap)
        while True:
            # -- look again at every pair of the last wave's moved bodies, from tw on (each pushed at most once) --
            if pend > 0:
                if hn + P > H.shape[0]:
                    more = True
                    break
                for a in range(pend):
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
                        if _STATIC and j >= ns:
                            hn = shape_push(H, hn, p, ver[p], x, u, r, spd, live, lst, i, j - ns, tw, dt, stats)
                            continue
                        if not (live[i] and live[j]):
                            continue
                        tp, sl = toi(x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2],
                                      u[j, 0] - u[i, 0], u[j, 1] - u[i, 1], u[j, 2] - u[i, 2],
                                      r[i] + r[j], inv[i] + inv[j], spd[i] + spd[j], tw, dt)
                        if tp >= 0.0:
                            heap_push(H, hn, tp, p, ver[p], sl)
                            hn += 1
                            stats[S_PUSHED] += 1
                pend = np.int64(0)
            if hn == 0:
                break
            need = (hn if hn < P else P) + 1               # at most one valid entry per pair and per heap entry
            if need > wcap:
                wcap = need if need > 2 * wcap else 2 * wcap
                more = True
                break
            if ne + wcap > E.shape[0]:                     # a wave has fewer than wcap contacts
                more = True
                break
            # -- pop the earliest valid entry --
            t0, p0, v0 = H[0, 0], np.int64(H[0, 1]), np.int64(H[0, 2])
            hn -= 1
            heap_pop(H, hn)
            if v0 != ver[p0]:
                continue
            if waves >= limit:
                flags |= F_LIMIT
                break
            # -- the wave: every valid entry within its own slack of t0 --
            K = np.int64(0)                                    # see contact_params._NOT_LITERAL
            nb = 0
            horizon = t0 + SLACK_MAX * dt
            cand_p, cand_ok = p0, True
            while True:
                if cand_ok:
                    i, j = PI[cand_p], PJ[cand_p]
                    if _STATIC and j >= ns:
                        nx, ny, nz, vn = shape_contact(lst, j - ns, x, u, i, t0)
                    else:
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
                tp, pp, vv, ss = H[0, 0], np.int64(H[0, 1]), np.int64(H[0, 2]), H[0, 3]
                stats[S_POPPED] += 1
                hn -= 1
                heap_pop(H, hn)
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
            stats[S_BACK] += nb
            for b in range(nb):                                # not this instant: back into the heap
                heap_push(H, hn, back_t[b], back_p[b], back_v[b], back_s[b])
                hn += 1
            if K == 0:
                continue
            waves += 1
            t = t0
            # -- restitution of each contact: the pair's, or the TC model / the bounds; islands --
            fl, stick_any = restitution(K, wi, wj, e, t, t_last, burst, count, cap, t_c, same, wstick, we)
            flags |= fl
            islands(K, wi, wj, inv, parent, ustamp, waves, wroot)
            for k in range(K):
                rhs[k] = -(1.0 + we[k]) * wvn[k]
                wlam[k] = 0.0
            if K == 1:
                ordk[0] = 0                                    # a lone contact (most waves): nothing to sort
            else:
                srt = sorting.argsort_stable(wroot, K)              # islands together, wave order inside
                for k in range(K):
                    ordk[k] = srt[k]
            nm = np.int64(0)                 # see contact_params._NOT_LITERAL
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
                    if _STICK:
                        nm = stick_cluster(cs, m, wi, wj, wn, inv, live, u, x, r, t, wlam, dv, moved, nm, bmark,
                                           waves, head, nxt, PI, PJ, sseen, squeue)
                        flags |= F_STICK
                    else:
                        nm = np.int64(-1)                      # no jam path in this driver: F_AGAIN below
                        break
                elif m == 1:
                    c = cs[0]
                    i, j = wi[c], wj[c]
                    lam = rhs[c] / (inv[i] + inv[j])
                    wlam[c] = lam
                    nm = kick(i, -1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
                    nm = kick(j, 1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
                elif m <= DENSE_MAX:
                    island_dense(cs, m, wi, wj, wn, rhs, inv, wlam, A, y, sub, act)
                    for a in range(m):
                        c = cs[a]
                        lam = wlam[c]
                        if lam == 0.0:
                            continue
                        nm = kick(wi[c], -1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
                        nm = kick(wj[c], 1.0, lam, c, inv, bmark, waves, dv, moved, nm, wn)
                elif _STICK:
                    stats[S_SEQUENTIAL] += 1
                    nm = island_sequential(cs, m, wi, wj, wn, we, u, dv, bmark, waves, spd, inv, wlam, moved, nm)
                else:
                    nm = np.int64(-1)                          # an island past DENSE_MAX: F_AGAIN, as for a jam
                    break
                s = f
            if nm < 0:
                flags |= F_AGAIN
                break
            # -- bookkeeping of the bodies that took an impulse; events; apply: new velocities from t on --
            ne = record_wave(K, wi, wj, wlam, wn, x, u, r, e, t, t_c, waves, ns, kstamp, burst, t_last, count, E, ne)
            apply_wave(nm, moved, dv, t, x, u, spd, changed, x_in, u_in)
            pend, tw = nm, t
            # -- bodies whose new path leaves their territory (or their swept box): swept in the outer loop --
            if _LISTED:                                    # (pruned from the all-pairs solvers: P is fixed there)
                ns_sweep = leaving(nm, moved, t, dt, x, u, r, swept, centre, skin, blo, bhi, newlo, newhi, tosweep,
                                   ns_sweep)
                if ns_sweep > 0:
                    more = True
                    break
    stats[S_PAIRS] = P
    stats[S_CONTACTS] = ne
    stats[S_WAVES] = waves
    _shift(t_last, now)
    if flags & F_AGAIN:
        _put_back(keep, x, u, t_last, lst, changed, x_in, u_in)
    _, ev, ev_n, ev_x = _events(E, ne, np.int64(0))
    return changed, ev, ev_n, ev_x, stats, flags


def _solver(name, doc, listed, stick, shapes):
    """A solver compiled from :func:`_solve`: with the neighbour list's code (``listed``) or every pair a
    candidate, with the jam path (:func:`stick_cluster`) and the big islands' solve (:func:`island_sequential`,
    past DENSE_MAX contacts) (``stick``) or F_AGAIN in their place, with the static shapes (``shapes``) or
    without. The three flags are constants in its globals: numba prunes the
    branches they rule out before it types the code, so each solver compiles only what its scenes run
    (numba compiles whatever a kernel can call, and pasting the body into drivers with inline="always"
    copies its IR block by block, which cost more than it saved: docs/bench/compile.md)."""
    keep = ((keep_nothing, put_back_nothing) if stick else
            (keep_listed, put_back_listed) if listed else (keep_pairs, put_back_pairs))
    f = variant(_solve, name, doc, _LISTED=listed, _STICK=stick, _STATIC=shapes, _keep=keep[0], _put_back=keep[1])
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
    step needs the jam path or an island past DENSE_MAX contacts: every
    input is as it came; run :func:`solve_listed_stick` with them.
    """

# The solvers. A scene of few bodies compiles no neighbour-list code, and no scene compiles the jam path
# (stick_cluster) until one jams, nor the big islands' solve (island_sequential) until an island of more than
# DENSE_MAX contacts comes (no demo has one): a step that needs either ends with F_AGAIN and its inputs as they
# came, and the caller runs it again with the _stick variant (the same result, bit for bit, as that variant
# alone). Each rare path cost every solver's cold compile ~0.25 s or more (docs/bench/compile.md).
solve_listed = _solver("solve_listed", _LISTED_DOC, listed=True, stick=False, shapes=False)
solve_listed_stick = _solver("solve_listed_stick", ":func:`solve_listed` with the jam path (:func:`stick_cluster`).",
                             listed=True, stick=True, shapes=False)
solve_all_pairs = _solver("solve_all_pairs", """:func:`solve_listed` with every pair a candidate (few bodies)
    and ``lst`` None; with F_AGAIN run :func:`solve_all_pairs_stick`.""", listed=False, stick=False, shapes=False)
solve_all_pairs_stick = _solver("solve_all_pairs_stick", ":func:`solve_all_pairs` with the jam path.",
                                listed=False, stick=True, shapes=False)


# The static-shape variants (planes, boxes: :mod:`.static_shapes`): every pair a candidate, the shapes the
# last bodies (immovable, not live) and ``lst`` their table. Compiled only for a scene that has shapes.
solve_static = _solver("solve_static", """:func:`solve_all_pairs` with static shapes: ``lst`` is their
    ``(m, SHAPE_COLS)`` table and they are the last ``m`` bodies (:mod:`driftframe.systems.static_step` arranges it); with
    F_AGAIN run :func:`solve_static_stick`.""", listed=False, stick=False, shapes=True)
solve_static_stick = _solver("solve_static_stick", ":func:`solve_static` with the jam path.",
                             listed=False, stick=True, shapes=True)
