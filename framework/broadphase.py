"""Broad phase: which pairs of bodies can touch, without testing every pair.

Everything here works on whole arrays; no Python loop runs over pairs.

* :func:`box_pairs` returns the pairs of overlapping axis-aligned boxes
  (closed intervals on every axis) by one of four methods:

  - ``"all"``: every pair ``i < j`` tested at once (``O(n^2)`` work, no set-up);
    fastest for a few dozen boxes.
  - ``"sweep"``: sort and sweep along the axis of largest spread; the pairs
    that overlap on that axis are tested on the other two. ``O(n log n + k)``
    where ``k`` grows like ``n^2 / L`` for a field of side ``L``.
  - ``"grid"``: a uniform grid with cells as large as the largest (ordinary)
    box; a box is filed under the cell of its low corner, and a pair can only
    overlap when their cells are neighbours. Keys are ordered
    ``(x, y, z)`` so the three neighbour cells along ``z`` are one contiguous
    run of the sorted keys: 5 runs per box (a half stencil) cover all 14
    half-neighbours. ``O(n log n)`` for bounded density.
  - ``"kdtree"``: ``scipy.spatial.cKDTree.query_pairs`` on the box centres
    (Chebyshev distance), then the exact box test.

  ``benchmarks/collision_scaling.py`` measures them; ``"auto"`` picks
  ``"all"`` up to :data:`ALL_PAIRS_MAX` boxes and the grid above. Boxes much
  larger than usual (a fast body's sweep) would force huge cells, so the grid
  sets them aside and tests them against every box directly.

* :class:`NeighbourList` keeps the pairs that can touch over *several* steps
  (a Verlet list): built from sphere centres with a ``skin``, it stays valid
  while no body has moved more than ``skin / 2`` from where it was at the
  build, and is rebuilt when one has. Bodies that cross half the skin in one
  step are "fast": the list leaves them out and the caller tests them each
  step.
"""
from __future__ import annotations

import numpy as np
from driftframe.framework.kernels import kernel

#: Up to this many boxes "auto" tests every pair (measured crossover; see benchmarks/collision_scaling.py).
ALL_PAIRS_MAX = 32
METHODS = ("auto", "all", "sweep", "grid", "kdtree")

_EMPTY = np.empty(0, np.intp)
#: Pairs of small n, cached (the same n comes back every step); bounded: n <= _TRIU_CACHED only
#: (at most ~0.7 MB whatever sizes come and go).
_TRIU: dict[int, tuple[np.ndarray, np.ndarray]] = {}
_TRIU_CACHED = 64


def _triu(n: int) -> tuple[np.ndarray, np.ndarray]:
    """All pairs i < j of n items."""
    got = _TRIU.get(n)
    if got is None:
        got = tuple(a.astype(np.intp) for a in np.triu_indices(n, 1))
        if n <= _TRIU_CACHED:
            _TRIU[n] = got
    return got


def _soa(a: np.ndarray) -> np.ndarray:
    """(n, 3) -> contiguous (3, n): gathering rows of 1-D columns is several times faster."""
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64).T)


def _overlap(lo: np.ndarray, hi: np.ndarray, i: np.ndarray, j: np.ndarray, axes=(0, 1, 2)):
    """Keep the pairs (i, j) whose boxes overlap on ``axes`` (lo, hi are (3, n))."""
    for k in axes:
        if not len(i):
            break
        l, h = lo[k], hi[k]
        keep = (l[i] <= h[j]) & (l[j] <= h[i])
        i, j = i[keep], j[keep]
    return i, j


def _expand(start: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Concatenated ranges ``start[k] .. start[k] + count[k] - 1`` without a loop."""
    total = int(count.sum())
    if total == 0:
        return _EMPTY
    offsets = np.cumsum(count) - count
    return np.repeat(start - offsets, count) + np.arange(total)


def _ordered(i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.minimum(i, j), np.maximum(i, j)


def _all(lo, hi):
    i, j = _triu(lo.shape[1])
    return _overlap(lo, hi, i, j)


def _sweep(lo, hi):
    n = lo.shape[1]
    ax = int(np.argmax(hi.max(axis=1) - lo.min(axis=1)))
    order = np.argsort(lo[ax], kind="stable")
    slo, shi = lo[:, order], hi[:, order]
    # sorted by low end: box p overlaps box q > p on this axis iff lo[q] <= hi[p]
    end = np.searchsorted(slo[ax], shi[ax], side="right")
    start = np.arange(1, n + 1)
    count = np.maximum(end - start, 0)
    i = np.repeat(np.arange(n), count)
    j = _expand(start, count)
    i, j = _overlap(slo, shi, i, j, axes=[k for k in range(3) if k != ax])
    return _ordered(order[i], order[j])


def _grid_regular(lo, hi, exact: bool = True):
    """Grid pairs among boxes no larger than one cell (the caller sets large ones aside).

    ``exact=False`` returns the stencil's candidates without the final box test (a superset, for
    a caller that applies its own exact test)."""
    n = lo.shape[1]
    h = float((hi - lo).max())
    if not h > 0:
        h = 1.0
    base = lo.min(axis=1)
    span = (lo.max(axis=1) - base) / h
    if float(np.log2(span + 3.0).sum()) > 62.0:     # a scene too sparse for int64 keys: sort and sweep
        return _sweep(lo, hi)
    # cell of the low corner, shifted by 1 so that a neighbour at -1 never wraps into another column
    cx, cy, cz = (np.floor((lo[k] - base[k]) / h).astype(np.int64) + 1 for k in range(3))
    nx, ny, nz = int(cx.max()) + 2, int(cy.max()) + 2, int(cz.max()) + 2
    cells = float(nx) * ny * nz
    key = (cx * ny + cy) * nz + cz
    order = np.argsort(key, kind="stable")
    sk = key[order]
    if cells <= 8 * n + 4096:
        # dense table: first sorted position of every cell (a gather instead of a binary search)
        first = np.zeros(int(cells) + 1, np.intp)
        np.cumsum(np.bincount(sk, minlength=int(cells)), out=first[1:])
        left = first.__getitem__
        right = lambda k: first[k + 1]
    else:
        left = lambda k: np.searchsorted(sk, k, side="left")
        right = lambda k: np.searchsorted(sk, k, side="right")
    # own column: the rest of my cell and the next cell in z (one run); then 4 columns, z-1..z+1 each
    starts = [np.arange(1, n + 1)]
    ends = [right(sk + 1)]
    for dx, dy in ((0, 1), (1, -1), (1, 0), (1, 1)):
        centre = sk + (dx * ny + dy) * nz
        starts.append(left(centre - 1))
        ends.append(right(centre + 1))
    start = np.concatenate(starts)
    count = np.maximum(np.concatenate(ends) - start, 0)
    i = np.repeat(np.tile(np.arange(n), 5), count)
    j = _expand(start, count)
    i, j = order[i], order[j]
    if exact:
        i, j = _overlap(lo, hi, i, j)
    return _ordered(i, j)


def _grid(lo, hi):
    n = lo.shape[1]
    ext = (hi - lo).max(axis=0)
    # boxes much larger than usual would force huge cells: set them aside, test them against all
    big = ext > 4.0 * float(np.median(ext)) if n > 8 else np.zeros(n, bool)
    nbig = int(big.sum())
    if nbig == 0:
        return _grid_regular(lo, hi)
    if nbig * 8 > n:                          # many large boxes: cells of the largest size are fine
        return _grid_regular(lo, hi)
    small = np.flatnonzero(~big)
    i, j = _grid_regular(lo[:, small], hi[:, small])
    out_i, out_j = [small[i]], [small[j]]
    for b in np.flatnonzero(big):
        others = np.arange(n)
        others = others[(others != b) & (~big | (others > b))]    # each big-big pair once
        bi = np.full(len(others), b)
        bi, bj = _overlap(lo, hi, bi, others)
        out_i.append(bi)
        out_j.append(bj)
    return _ordered(np.concatenate(out_i), np.concatenate(out_j))


def _kdtree(lo, hi):
    from scipy.spatial import cKDTree

    centre = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo)
    tree = cKDTree(centre.T)
    pairs = tree.query_pairs(2.0 * float(half.max()), p=np.inf, output_type="ndarray")
    i, j = _overlap(lo, hi, pairs[:, 0].astype(np.intp), pairs[:, 1].astype(np.intp))
    return _ordered(i, j)


_IMPL = {"all": _all, "sweep": _sweep, "grid": _grid, "kdtree": _kdtree}


def box_pairs(lo, hi, method: str = "auto", *, soa: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``(i, j)``, ``i < j``, of overlapping boxes ``[lo, hi]`` (closed), in no set order.

    ``lo`` and ``hi`` are ``(n, 3)`` arrays (or ``(3, n)`` with ``soa=True``).
    """
    if method not in METHODS:
        raise ValueError(f"broad phase method must be one of {METHODS}, got {method!r}")
    lo = np.asarray(lo, np.float64) if soa else _soa(lo)
    hi = np.asarray(hi, np.float64) if soa else _soa(hi)
    if lo.shape != hi.shape or lo.ndim != 2 or lo.shape[0] != 3:
        raise ValueError(f"box_pairs: lo and hi must both be (n, 3), got {lo.shape} and {hi.shape}")
    n = lo.shape[1]
    if n < 2:
        return _EMPTY, _EMPTY
    if method == "auto":
        method = "all" if n <= ALL_PAIRS_MAX else "grid"
    return _IMPL[method](lo, hi)


def sphere_pairs(centres, radii, method: str = "auto", *, soa: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``i < j`` of spheres that touch or overlap: ``|c_i - c_j| <= r_i + r_j``.

    ``centres`` is ``(n, 3)`` (or ``(3, n)`` with ``soa=True``).
    """
    c = np.asarray(centres, np.float64) if soa else _soa(centres)
    r = np.asarray(radii, np.float64)
    i, j = box_pairs(c - r, c + r, method, soa=True)
    dist2 = (c[0][j] - c[0][i]) ** 2 + (c[1][j] - c[1][i]) ** 2 + (c[2][j] - c[2][i]) ** 2
    keep = dist2 <= (r[i] + r[j]) ** 2
    return i[keep], j[keep]


def boxes_against_all(lo: np.ndarray, hi: np.ndarray, which) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``i < j`` of overlapping boxes with at least one of them in ``which``, each once.

    ``lo``, ``hi`` are ``(3, n)``. For the few boxes that the grid or a
    neighbour list cannot hold (a fast body's sweep): one vectorised test per
    box in ``which`` against all ``n``.
    """
    n = lo.shape[1]
    which = np.asarray(which, np.intp)
    member = np.zeros(n, bool)
    member[which] = True
    everyone = np.arange(n)
    out_i, out_j = [_EMPTY], [_EMPTY]
    for b in which:
        others = everyone[(everyone != b) & (~member | (everyone > b))]   # pairs inside `which` once
        i, j = _overlap(lo, hi, np.full(len(others), b, np.intp), others)
        out_i.append(i)
        out_j.append(j)
    return _ordered(np.concatenate(out_i), np.concatenate(out_j))


#: The cost model that sets a neighbour list's skin (see :class:`NeighbourList`), in seconds: a
#: build (fixed, per body) and one listed pair for one step; measured on the 2-core dev machine.
BUILD_COST = (25e-6, 0.1e-6)
PAIR_COST = 0.015e-6
MAX_SKIN_SCALE = 4.0


class NeighbourList:
    """Pairs of spheres that can touch while no body strays out of its territory (a Verlet list).

    Each body gets a *territory*: the ball of radius ``r_i + s_i`` about its
    position ``c_i`` at the build, where its skin ``s_i`` is ``skin_steps``
    times its displacement per step (at least the median body's, so bodies at
    rest get room too). A pair is listed when the territories overlap,
    ``|c_i - c_j| <= r_i + r_j + s_i + s_j``; while both bodies stay within
    ``s`` of their ``c``, two bodies not listed together cannot touch. So the
    list lasts about ``skin_steps`` steps whatever the speeds.

    A body that leaves its territory (or whose skin would be far larger than
    the others', e.g. a bullet among asteroids) is marked ``swept``: the list
    no longer speaks for it, and the caller tests its actual path box against
    the others' territories (:meth:`territories`, a binary search on the
    build's x order) and against the other swept bodies. The caller rebuilds
    when more than ``budget`` bodies are swept. Positions are ``(3, n)`` arrays.

    The skin's length trades builds against pairs: a build costs about
    ``BUILD_COST`` (a fixed part, then per body), each listed pair
    ``PAIR_COST`` a step, and doubling the skin halves the builds for about
    three times the pairs. So when a build finds that the pairs cost less
    than an eighth of what the builds cost per step, the next build gets
    twice the skin (up to ``MAX_SKIN_SCALE`` times ``skin_steps``); when they
    cost more than twice as much, it goes back to ``skin_steps``. The model
    reads counts only, never timings: the same scene builds the same lists
    on any machine. (Its constants were measured here; a field of 50 at 5 %
    took about 7 % less time a step, fields of 500 and more keep their skin.)
    """

    def __init__(self, skin_steps: float = 8.0, method: str = "auto"):
        if method not in METHODS:
            raise ValueError(f"broad phase method must be one of {METHODS}, got {method!r}")
        self.skin_steps = float(skin_steps)
        self.method = method
        self.i = _EMPTY
        self.j = _EMPTY
        self.centre = np.empty((3, 0))
        self.radius = np.empty(0)
        self.skin = np.empty(0)
        self.reach = np.empty(0)
        self.swept = np.zeros(0, bool)
        self.budget = 2
        self.builds = 0
        self.scale = 1.0                                  # the skin's factor for the next build

    def build(self, centres: np.ndarray, radii: np.ndarray, step_disp: np.ndarray) -> None:
        """(Re)build from centres (3, n), radii (n,) and each body's displacement per step (n,), m."""
        c = np.array(centres, np.float64, order="C")      # C order: the compiled kernels take one layout
        r = np.array(radii, np.float64)
        d = np.asarray(step_disp, np.float64)
        n = len(r)
        skin, swept, reach = _territory(r, d, self.skin_steps * self.scale)   # one compiled pass (medians and all)
        n_slow = n - int(np.count_nonzero(swept))
        got = None
        if self.method in ("auto", "grid") and n_slow > ALL_PAIRS_MAX:
            # one compiled pass: counting sort into a dense grid, then the exact sphere test over the
            # half stencil (the same pairs as sphere_pairs; their order does not matter to the solver)
            got = _grid_build(c, reach, swept, n_slow)
        if got is not None:
            self.i, self.j = got
        else:
            slow = np.flatnonzero(~swept)
            i, j = sphere_pairs(c[:, slow], reach[slow], self.method, soa=True)
            self.i, self.j = slow[i], slow[j]
        self.centre, self.radius, self.skin, self.reach, self.swept = c, r, skin, reach, swept
        # x order of the territories' low ends, for territories()
        self._order, self._lo_x, self._width = _x_order(c, reach, swept)
        # each swept body costs a query per step, a build ~n log n: allow a few
        self.budget = 2 + n // 128
        self.builds += 1
        lasts = self.skin_steps * self.scale                       # steps, about
        builds = (BUILD_COST[0] + BUILD_COST[1] * n) / lasts        # s per step
        pairs = PAIR_COST * len(self.i)
        if 8.0 * pairs < builds:
            self.scale = min(2.0 * self.scale, MAX_SKIN_SCALE)
        elif pairs > 2.0 * builds:
            self.scale = 1.0

    def strays(self, *points: np.ndarray, which=None) -> np.ndarray:
        """Which listed (not swept) bodies are at their skin's distance or more from their build
        centre at any of ``points`` (each ``(3, n)``, or ``(3, len(which))`` for the bodies ``which``)."""
        if which is None:
            c, skin, swept = self.centre, self.skin, self.swept
        else:
            c, skin, swept = self.centre[:, which], self.skin[which], self.swept[which]
        far2 = None
        for p in points:
            off = p - c
            d2 = off[0] * off[0] + off[1] * off[1] + off[2] * off[2]
            far2 = d2 if far2 is None else np.maximum(far2, d2)
        return (far2 >= skin * skin) & ~swept

    def kernel_arrays(self):
        """The arrays :func:`territory_query` reads: ``(centre, skin, reach, order, lo_x, width)``."""
        return (self.centre, self.skin, self.reach, self._order.astype(np.int64, copy=False), self._lo_x, self._width)

    def territories(self, lo, hi) -> np.ndarray:
        """Listed (not swept) bodies whose territory box overlaps the box ``[lo, hi]`` (3-vectors)."""
        a = np.searchsorted(self._lo_x, lo[0] - self._width, side="left")
        b = np.searchsorted(self._lo_x, hi[0], side="right")
        cand = self._order[a:b]
        c = self.centre[:, cand]
        rr = self.reach[cand]
        keep = ~self.swept[cand]
        for k in range(3):
            keep &= (c[k] - rr <= hi[k]) & (c[k] + rr >= lo[k])
        return cand[keep]


@kernel(no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _bisect(a, v, right):
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


@kernel(no_cfunc_wrapper=True)
def argsort_stable(a, m):
    """The order that sorts ``a[:m]`` ascending, ties in index order: what ``np.argsort(a[:m],
    kind="stable")`` gives (NaN last). Merge sort of insertion-sorted runs of 16; its compile costs a
    fraction of numba's argsort (see docs/bench/compile.md)."""
    idx = np.empty(m, np.int64)
    for k in range(m):
        idx[k] = k
    for s in range(0, m, 16):
        f = min(s + 16, m)
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
            mid = min(s + width, m)
            f = min(s + 2 * width, m)
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


@kernel(no_cfunc_wrapper=True)
def median(a):
    """``np.median`` of a 1-d float array without NaN (the mean of the middle two for an even count; NaN
    when empty) by Wirth's selection, O(n): numba's median compiles a partition for every dtype, complex
    included (see docs/bench/compile.md). The order statistics are unique, so the bits are numpy's."""
    n = a.shape[0]
    if n == 0:
        return np.nan
    w = a.copy()
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
        return w[h]
    below = w[0]
    for k in range(1, h):
        below = max(below, w[k])
    return (below + w[h]) / 2


@kernel(no_cpython_wrapper=True, no_cfunc_wrapper=True)
def territory_query(lo, hi, order, lo_x, width, centre, reach, swept):
    """Compiled :meth:`NeighbourList.territories`: listed bodies whose territory box meets ``[lo, hi]``.

    ``order``, ``lo_x``, ``width``, ``centre`` (3, n), ``reach``, ``swept``: the list's arrays
    (:meth:`NeighbourList.kernel_arrays`). Used by the contact kernel for bodies swept mid-step.
    """
    a = _bisect(lo_x, lo[0] - width, np.bool_(False))     # np.bool_: see contact's _NOT_LITERAL
    b = _bisect(lo_x, hi[0], np.bool_(True))
    out = np.empty(max(b - a, 0), np.int64)
    m = 0
    for q in range(a, b):
        k = order[q]
        if swept[k]:
            continue
        rr = reach[k]
        ok = True
        for d in range(3):
            if centre[d, k] - rr > hi[d] or centre[d, k] + rr < lo[d]:
                ok = False
                break
        if ok:
            out[m] = k
            m += 1
    return out[:m]


@kernel(no_cfunc_wrapper=True)
def mark_strays(x, u, dt, centre, skin, swept, r, built_r):
    """Mark as swept every listed body whose path ``x + u t``, 0 <= t <= dt, leaves its territory
    (either end at its skin's distance or more from its build centre; a ball is convex).
    ``x``, ``u``: (n, 3); ``centre``: (3, n). Returns ``(newly swept, swept now)``, or ``(-1, -1)``
    and marks nothing when the radii ``r`` are not those of the build (``built_r``): rebuild."""
    if r.shape[0] != built_r.shape[0]:
        return -1, -1
    for k in range(r.shape[0]):
        if r[k] != built_r[k]:
            return -1, -1
    total = 0
    new = 0
    for k in range(x.shape[0]):
        if not swept[k]:
            s2 = skin[k] * skin[k]
            a = 0.0
            b = 0.0
            for d in range(3):
                o = x[k, d] - centre[d, k]
                a += o * o
                o2 = x[k, d] + u[k, d] * dt - centre[d, k]
                b += o2 * o2
            if a >= s2 or b >= s2:
                swept[k] = True
                new += 1
        if swept[k]:
            total += 1
    return new, total


def _grid_build(c, reach, swept, n_slow):
    """Pairs of not-swept territories that overlap, by :func:`_grid_pairs`; None when the scene spans
    too many cells for int64 keys (the caller falls back on sort and sweep)."""
    h, hh, bx, by, bz, nx, ny, nz = _grid_setup(c, reach, swept)
    if not h > 0 or max(nx, ny, nz) > _KEY_SPAN:
        return None
    # a dense table of cells when they are few; sorted keys and binary searches when the scene is sparse
    dense = float(nx) * float(ny) * float(nz) <= 8.0 * n_slow + 4096
    cap = 8 * n_slow + 64
    while True:
        oi = np.empty(cap, np.int64)
        oj = np.empty(cap, np.int64)
        p = _grid_pairs(c, reach, swept, h, hh, bx, by, bz, nx, ny, nz, dense, oi, oj)
        if p <= cap:
            return oi[:p], oj[:p]
        cap = p


#: Cells per axis at most (with the ghost layers), so that a cell key (x * ny + y) * nz + z fits in int64.
_KEY_SPAN = 2_000_000


@kernel(no_cfunc_wrapper=True)
def _grid_setup(c, reach, swept):
    """Cell side ``h``, the largest ordinary reach ``hh``, low corner and cells per axis.

    Ordinary bodies have a reach of at most twice the median's; ``h`` is a hair over twice the largest
    of those (so rounding in a cell index never separates an ordinary pair by two cells). A few bodies
    made fast by collisions must not inflate every cell: they search a wider block of cells instead
    (:func:`_grid_pairs`). A ghost layer each side spares the stencil its bounds tests."""
    m = 0
    for k in range(reach.shape[0]):
        if not swept[k]:
            m += 1
    if m == 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0
    rs = np.empty(m)
    m = 0
    for k in range(reach.shape[0]):
        if not swept[k]:
            rs[m] = reach[k]
            m += 1
    cut = 2.0 * median(rs)
    hh = 0.0
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for k in range(reach.shape[0]):
        if swept[k]:
            continue
        if reach[k] <= cut:
            hh = max(hh, reach[k])
        for d in range(3):
            lo[d] = min(lo[d], c[d, k])
            hi[d] = max(hi[d], c[d, k])
    h = 2.0 * hh * (1.0 + 1e-9)
    if not h > 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0
    dims = np.empty(3, np.int64)
    for d in range(3):
        dims[d] = int(min(np.floor((hi[d] - lo[d]) / h), 4e6)) + 3     # capped: the int never overflows
    return h, hh, lo[0], lo[1], lo[2], dims[0], dims[1], dims[2]


@kernel(no_cfunc_wrapper=True)
def _grid_pairs(c, reach, swept, h, hh, bx, by, bz, nx, ny, nz, dense, oi, oj):
    """Pairs ``i < j`` of not-swept bodies with ``|c_i - c_j| <= reach_i + reach_j`` (``c``: (3, n)).

    Cells of side ``h > 2 hh`` by centre, so a pair of ordinary bodies (reach <= ``hh``) lies in the
    same or neighbouring cells. The bodies are filed by cell (``dense``: a counting sort into a table of
    all cells, O(n + cells); else a sort of the occupied cells' keys, found by binary search), and each
    ordinary body tests the later ordinary bodies of its own cell and those of the 13 cells of a half
    stencil. A large body (reach > ``hh``) tests every body in the block of cells its reach plus the
    largest can span (large-large pairs once, from the lower index).

    Writes the pairs into ``oi``, ``oj`` as far as they hold and returns how many there are (the
    caller gives larger arrays and calls again when they did not hold them all: growing arrays
    inside the loop would cost reference counting on every iteration)."""
    n = reach.shape[0]
    cell = np.full(n, -1, np.int64)
    big = 0.0
    m = 0
    for k in range(n):
        if swept[k]:
            continue
        big = max(big, reach[k])
        ix = int((c[0, k] - bx) / h) + 1
        iy = int((c[1, k] - by) / h) + 1
        iz = int((c[2, k] - bz) / h) + 1
        cell[k] = (ix * ny + iy) * nz + iz
        m += 1
    body = np.empty(m, np.int64)
    if dense:
        ncell = nx * ny * nz
        start = np.zeros(ncell + 1, np.int64)
        for k in range(n):
            if cell[k] >= 0:
                start[cell[k] + 1] += 1
        for q in range(ncell):
            start[q + 1] += start[q]
        fill = np.empty(ncell, np.int64)
        for q in range(ncell):
            fill[q] = start[q]
        for k in range(n):
            q = cell[k]
            if q >= 0:
                body[fill[q]] = k
                fill[q] += 1
        ukey = np.empty(0, np.int64)
        ustart = np.empty(0, np.int64)
        nu = 0
    else:
        start = np.empty(0, np.int64)
        keys = np.empty(m, np.int64)
        idx = np.empty(m, np.int64)
        j = 0
        for k in range(n):
            if cell[k] >= 0:
                keys[j] = cell[k]
                idx[j] = k
                j += 1
        order = argsort_stable(keys, keys.shape[0])     # (not m: see contact._NOT_LITERAL)
        nu = 0
        for s in range(m):
            body[s] = idx[order[s]]
            if s == 0 or keys[order[s]] != keys[order[s - 1]]:
                nu += 1
        ukey = np.empty(nu, np.int64)
        ustart = np.empty(nu + 1, np.int64)
        nu = 0
        for s in range(m):
            if s == 0 or keys[order[s]] != keys[order[s - 1]]:
                ukey[nu] = keys[order[s]]
                ustart[nu] = s
                nu += 1
        ustart[nu] = m
    # coordinates and reaches in cell order: the stencil reads them contiguously
    sx = np.empty(m)
    sy = np.empty(m)
    sz = np.empty(m)
    sr = np.empty(m)
    for s in range(m):
        k = body[s]
        sx[s] = c[0, k]
        sy[s] = c[1, k]
        sz[s] = c[2, k]
        sr[s] = reach[k]
    # the 13 neighbour cells after this one in (x, y, z) order
    offs = np.empty(13, np.int64)
    o = 0
    for dx in range(-1, 2):
        for dy in range(-1, 2):
            for dz in range(-1, 2):
                if dx > 0 or (dx == 0 and (dy > 0 or (dy == 0 and dz > 0))):
                    offs[o] = (dx * ny + dy) * nz + dz
                    o += 1
    cap = oi.shape[0]
    p = 0
    a1 = 0
    for s in range(m):
        a = body[s]
        q = cell[a]
        if s >= a1:                                       # the first body of its cell: where the cell ends
            if dense:
                b0 = start[q]
                b1 = start[q + 1]
            else:
                b0 = 0
                b1 = 0
                kk = _bisect(ukey, q, np.bool_(False))
                if kk < nu and ukey[kk] == q:
                    b0 = ustart[kk]
                    b1 = ustart[kk + 1]
            a1 = b1
        ax = sx[s]
        ay = sy[s]
        az = sz[s]
        ar = sr[s]
        if ar > hh:
            continue                                      # a large body: its own search below
        for t in range(-1, 13):
            if t < 0:
                b0 = s + 1
                b1 = a1
            else:
                qq = q + offs[t]
                if dense:
                    b0 = start[qq]
                    b1 = start[qq + 1]
                else:
                    b0 = 0
                    b1 = 0
                    kk = _bisect(ukey, qq, np.bool_(False))
                    if kk < nu and ukey[kk] == qq:
                        b0 = ustart[kk]
                        b1 = ustart[kk + 1]
            for u in range(b0, b1):
                if sr[u] > hh:
                    continue                              # found from the large body's side
                dx_ = sx[u] - ax
                dy_ = sy[u] - ay
                dz_ = sz[u] - az
                R = ar + sr[u]
                if dx_ * dx_ + dy_ * dy_ + dz_ * dz_ <= R * R:
                    if p < cap:
                        b = body[u]
                        oi[p] = min(a, b)
                        oj[p] = max(a, b)
                    p += 1
    for s in range(m):
        ar = sr[s]
        if ar <= hh:
            continue
        a = body[s]
        ax = sx[s]
        ay = sy[s]
        az = sz[s]
        w = int((ar + big) / h) + 2
        ix = int((ax - bx) / h) + 1
        iy = int((ay - by) / h) + 1
        iz = int((az - bz) / h) + 1
        span = 1.0                                         # the block's cells (a float: no overflow)
        for i0, nd in ((ix, nx), (iy, ny), (iz, nz)):
            span *= min(i0 + w, nd - 1) - max(i0 - w, 0) + 1
        if span > m:
            # a body far larger than the rest (a radius ratio of hundreds) spans more cells than there
            # are bodies: test every body once instead of visiting the cells (O(n), not O(cells))
            for u in range(m):
                b = body[u]
                if b == a or (sr[u] > hh and b < a):
                    continue
                dx_ = sx[u] - ax
                dy_ = sy[u] - ay
                dz_ = sz[u] - az
                R = ar + sr[u]
                if dx_ * dx_ + dy_ * dy_ + dz_ * dz_ <= R * R:
                    if p < cap:
                        oi[p] = min(a, b)
                        oj[p] = max(a, b)
                    p += 1
            continue
        for gx in range(max(ix - w, 0), min(ix + w, nx - 1) + 1):
            for gy in range(max(iy - w, 0), min(iy + w, ny - 1) + 1):
                for gz in range(max(iz - w, 0), min(iz + w, nz - 1) + 1):
                    qq = (gx * ny + gy) * nz + gz
                    if dense:
                        b0 = start[qq]
                        b1 = start[qq + 1]
                    else:
                        b0 = 0
                        b1 = 0
                        kk = _bisect(ukey, qq, np.bool_(False))
                        if kk < nu and ukey[kk] == qq:
                            b0 = ustart[kk]
                            b1 = ustart[kk + 1]
                    for u in range(b0, b1):
                        b = body[u]
                        if b == a or (sr[u] > hh and b < a):
                            continue
                        dx_ = sx[u] - ax
                        dy_ = sy[u] - ay
                        dz_ = sz[u] - az
                        R = ar + sr[u]
                        if dx_ * dx_ + dy_ * dy_ + dz_ * dz_ <= R * R:
                            if p < cap:
                                oi[p] = min(a, b)
                                oj[p] = max(a, b)
                            p += 1
    return p


@kernel(no_cfunc_wrapper=True)
def _territory(r, d, skin_steps):
    """Each body's skin, whether it is swept, and its reach ``r + skin`` (see :class:`NeighbourList`).

    Room for ``skin_steps`` steps at the body's own speed ``d`` per step (at least the median's, and at
    least 2 % of the median radius a step: a scene at rest, a crystal or a pile, gets a skin of 0.16 r,
    so the bodies an impact sets moving stay inside their territory instead of each being swept again
    in every wave of the impact); a body whose skin dwarfs the
    others' (more than 8 median skins + 4 largest radii; a bullet among asteroids) would make huge
    cells and many pairs: it is swept instead."""
    n = r.shape[0]
    skin = np.empty(n)
    swept = np.zeros(n, np.bool_)
    reach = np.empty(n)
    if n == 0:
        return skin, swept, reach
    floor_ = max(median(d), 0.02 * median(r))
    for k in range(n):
        skin[k] = skin_steps * max(d[k], floor_)
    big = r[0]
    for k in range(n):
        big = max(big, r[k])
    limit = 8.0 * median(skin) + 4.0 * big
    for k in range(n):
        swept[k] = skin[k] > limit
    for k in range(n):
        reach[k] = r[k] + skin[k]
    return skin, swept, reach


@kernel(no_cfunc_wrapper=True)
def _x_order(c, reach, swept):
    """The territories' low ends in x, sorted (a stable sort), their order, and twice the largest
    listed reach: what :meth:`NeighbourList.territories` and :func:`territory_query` search."""
    n = reach.shape[0]
    lo_x = np.empty(n)
    for k in range(n):
        lo_x[k] = c[0, k] - reach[k]
    order = argsort_stable(lo_x, lo_x.shape[0])
    width = 0.0
    for k in range(reach.shape[0]):
        if not swept[k]:
            width = max(width, 2.0 * reach[k])
    lo_sorted = np.empty(n)
    for k in range(n):
        lo_sorted[k] = lo_x[order[k]]
    return order, lo_sorted, width
