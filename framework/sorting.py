"""Compiled search and order statistics: binary search, a stable argsort (and one in O(n) for values
spread evenly), the median.

numba's own ``searchsorted``, ``argsort`` and ``median`` compile comparisons or partitions for every
dtype, complex included; these compile a fraction of that (docs/bench/compile.md). Used by the
neighbour list and the contact solver, which are kernels: none has a CPython wrapper, so none has
machine code of its own made (each caller carries its copy; framework/kernel_shortcuts.py), and tests
call them through a compiled caller. error_model="numpy" as their callers: numba compiles its own functions
(np.empty, min, ...) once for each error model of the kernels that call them.
"""
from __future__ import annotations

import numpy as np

from driftframe.framework.kernels import kernel


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def bisect(a, v, right):
    """``np.searchsorted(a, v, side="right" if right else "left")`` for a sorted 1-d array (NaN last):
    the first index whose element is above ``v`` (right) or not below it (left). numba's searchsorted
    compiles comparisons for every dtype, complex included (docs/bench/compile.md)."""
    lo = 0
    hi = a.shape[0]
    while lo < hi:
        m = (lo + hi) >> 1
        if a[m] < v or (right and a[m] == v):
            lo = m + 1
        else:
            hi = m
    return lo


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def argsort_stable(a, m):
    """The order that sorts ``a[:m]`` ascending, ties in index order: what ``np.argsort(a[:m],
    kind="stable")`` gives (NaN last). Merge sort of insertion-sorted runs of 16; its compile costs a
    fraction of numba's argsort (see docs/bench/compile.md)."""
    idx = np.empty(m, np.int64)
    for k in range(m):
        idx[k] = k
    for s in range(0, m, 16):
        f = s + 16 if s + 16 < m else m
        for k in range(s + 1, f):
            v = idx[k]
            key = a[v]
            q = k - 1
            while q >= s:
                w = a[idx[q]]
                if not (key < w or (w != w and key == key)):     # key < w, NaN last
                    break
                idx[q + 1] = idx[q]
                q -= 1
            idx[q + 1] = v
    tmp = np.empty(m, np.int64)
    width = 16
    while width < m:
        for s in range(0, m, 2 * width):
            mid = s + width if s + width < m else m
            f = s + 2 * width if s + 2 * width < m else m
            i = s
            j = mid
            k = s
            while i < mid and j < f:
                x = a[idx[j]]
                y = a[idx[i]]
                if x < y or (y != y and x == x):                  # the right one only when smaller: stable
                    tmp[k] = idx[j]
                    j += 1
                else:
                    tmp[k] = idx[i]
                    i += 1
                k += 1
            while i < mid:
                tmp[k] = idx[i]
                i += 1
                k += 1
            while j < f:
                tmp[k] = idx[j]
                j += 1
                k += 1
        idx, tmp = tmp, idx
        width *= 2
    return idx


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def order_keys(a, m):
    """int64 keys that sort as the floats ``a[:m]`` do, ties included: ``-0.0`` is ``0.0``'s key, every NaN
    the largest key (NaN last, in index order, as :func:`argsort_stable` puts them). IEEE 754 bits read as
    an int64 order the non-negative floats; a negative one's bits with all but the sign flipped
    (``b ^ 0x7fff_ffff_ffff_ffff``) order the negative ones below them. So :func:`argsort_spread` falls back
    on the int64 instance of the merge sort, the one the contact solver compiles anyway, rather than
    compiling a float64 one as well (~0.3 s of a cold compile, docs/bench/compile.md)."""
    c = np.empty(m, np.float64)
    for k in range(m):
        c[k] = a[k] + 0.0                                   # -0.0 + 0.0 = +0.0: equal floats, one key
    bits = c.view(np.int64)
    keys = np.empty(m, np.int64)
    for k in range(m):
        if c[k] != c[k]:
            keys[k] = 0x7FFF_FFFF_FFFF_FFFF
        elif bits[k] < 0:
            keys[k] = bits[k] ^ 0x7FFF_FFFF_FFFF_FFFF
        else:
            keys[k] = bits[k]
    return keys


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def argsort_spread(a, m):
    """The order :func:`argsort_stable` gives for ``a[:m]`` (floats), in O(m) when the values are spread
    about evenly (the neighbour list's territories along x, rebuilt every few steps): a counting sort
    into ``m`` buckets of equal width from the least value to the largest, then an insertion sort, which
    moves each value only within its bucket (a strict comparison: ties stay in index order). Values
    bunched into a few buckets would make that O(m^2): past ``8 m + 64`` moves, or with a value that
    is not finite, it returns :func:`argsort_stable`'s merge sort of :func:`order_keys` instead. The same
    order either way."""
    idx = np.empty(m, np.int64)
    if m < 2:
        for k in range(m):
            idx[k] = k
        return idx
    lo = a[0]
    hi = a[0]
    for k in range(m):
        v = a[k]
        if not abs(v) < np.inf:
            return argsort_stable(order_keys(a, m), m)
        lo = min(lo, v)
        hi = max(hi, v)
    scale = m / (hi - lo) if hi > lo else 0.0          # buckets per unit of value (0: all equal)
    if not scale < 1e18:
        return argsort_stable(order_keys(a, m), m)    # a spread too small to divide (no int overflows)
    # bucket b = floor((v - lo) m / (hi - lo)), monotone in v; the largest value into the last bucket
    end = np.zeros(m, np.int64)
    bucket = np.empty(m, np.int64)
    for k in range(m):
        b = min(int((a[k] - lo) * scale), m - 1)
        bucket[k] = b
        end[b] += 1
    for b in range(1, m):
        end[b] += end[b - 1]
    for k in range(m - 1, -1, -1):                    # from the last: each bucket in index order
        b = bucket[k]
        end[b] -= 1
        idx[end[b]] = k
    moves = 0
    budget = 8 * m + 64
    for k in range(1, m):
        v = idx[k]
        key = a[v]
        q = k - 1
        while q >= 0 and key < a[idx[q]]:
            idx[q + 1] = idx[q]
            q -= 1
        moves += k - 1 - q
        idx[q + 1] = v
        if moves > budget:
            return argsort_stable(order_keys(a, m), m)
    return idx


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def select_middle(w):
    """:func:`middle` in place: reorders ``w`` (a scratch copy the caller owns) instead of copying it."""
    n = w.shape[0]
    h = n >> 1
    lo = 0
    hi = n - 1
    while lo < hi:                     # Wirth: w[h] the h-th smallest, w[:h] <= w[h] <= w[h + 1:]
        x = w[h]
        i = lo
        j = hi
        while i <= j:
            while w[i] < x:
                i += 1
            while x < w[j]:
                j -= 1
            if i <= j:
                w[i], w[j] = w[j], w[i]
                i += 1
                j -= 1
        if j < h:
            lo = i
        if h < i:
            hi = j
    if n & 1:
        return w[h], w[h]
    below = w[0]
    for k in range(1, h):
        below = max(below, w[k])
    return below, w[h]


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def middle(a):
    """The two middle order statistics of a non-empty 1-d float array without NaN: ``(lower, upper)``,
    the ``(n - 1) // 2``-th and the ``n // 2``-th smallest (the same value for an odd count), by Wirth's
    selection on a copy, O(n). :func:`median` is ``upper`` for an odd count, else ``(lower + upper) / 2``;
    so is the median of ``f(a)`` for any ``f`` that never decreases (the neighbour list's skins from
    displacements)."""
    return select_middle(a.copy())


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def median(a):
    """``np.median`` of a 1-d float array without NaN (the mean of the middle two for an even count; NaN
    when empty) by Wirth's selection (:func:`middle`), O(n): numba's median compiles a partition for every
    dtype, complex included (see docs/bench/compile.md). The order statistics are unique, so the bits are
    numpy's."""
    n = a.shape[0]
    if n == 0:
        return np.nan
    below, upper = middle(a)
    if n & 1:
        return upper
    return (below + upper) / 2
