"""The contact solver's heap of pending contacts, and growable arrays (compiled kernels)."""
from __future__ import annotations

import numpy as np

from driftframe.framework.kernels import kernel


# Copies are loops, not slice assignments: ``b[:k] = a`` compiles numba's shape check and the string
# formatting of its error (about 1.5 s of an empty cache; docs/bench/compile.md).
@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def grow_f(a, n):
    """A (rows, cols) float array with room for ``n`` rows (at least twice as many), ``a`` copied in."""
    m = 2 * a.shape[0]
    b = np.empty((n if n > m else m, a.shape[1]), np.float64)
    for k in range(a.shape[0]):
        for d in range(a.shape[1]):
            b[k, d] = a[k, d]
    return b


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def grow_i(a, n, fill):
    """An int64 array of ``max(n, 2 len(a))`` with ``a`` copied in and ``fill`` after it."""
    m = 2 * a.shape[0]
    b = np.empty(n if n > m else m, np.int64)
    for k in range(a.shape[0]):
        b[k] = a[k]
    for k in range(a.shape[0], b.shape[0]):
        b[k] = fill
    return b


# The heap is one (cap, 4) array of rows (time, pair, version, slack): numba counts a reference to
# every array a function call receives (an atomic operation, before and after the call), and with
# four arrays those counts were two thirds of a dense gas's solve. Pair and version are whole
# numbers held exactly in float64 (below 2^53). Order: by time, then by pair.
# _nrt=False (numba's runtime off): a kernel compiled with the runtime counts a reference to each array
# argument on entry and drops it on every exit (an atomic operation and a call each, which numba's pruning
# leaves wherever the body branches). These three allocate nothing, so they need no runtime and count
# nothing; the solver calls them once or twice a wave (docs/bench/collision_stress.md, first steps).
@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, _nrt=False)
def sift_down(H, k, n):
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


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, _nrt=False)
def heap_pop(H, n):
    """Remove the root of a heap of ``n + 1`` rows (already read): the last row to the root, sifted down."""
    if n > 0:
        H[0, 0], H[0, 1], H[0, 2], H[0, 3] = H[n, 0], H[n, 1], H[n, 2], H[n, 3]
        sift_down(H, np.int64(0), n)     # np.int64: see contact_params._NOT_LITERAL


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, _nrt=False)
def heap_push(H, n, t, p, v, s):
    """Add a row to a heap of ``n`` rows, which has room for it (the caller grows ``H`` before a loop
    of pushes: an array reassigned inside a loop is reference-counted on every pass)."""
    k = n
    while k > 0:
        q = (k - 1) >> 1
        if t < H[q, 0] or (t == H[q, 0] and p < H[q, 1]):
            H[k, 0], H[k, 1], H[k, 2], H[k, 3] = H[q, 0], H[q, 1], H[q, 2], H[q, 3]
            k = q
        else:
            break
    H[k, 0], H[k, 1], H[k, 2], H[k, 3] = t, p, v, s

