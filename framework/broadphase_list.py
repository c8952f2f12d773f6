"""The neighbour list (a Verlet list): the pairs of spheres that can touch over several steps.

Built from sphere centres with a skin per body; it stays valid while no body leaves its territory, and
bodies that do are *swept*: the contact solver tests their paths against the territories
(:func:`territory_query`) and each other. The one-step broad phase over boxes is :mod:`.broadphase`.
"""
from __future__ import annotations

import math

import numpy as np

from driftframe.framework import sorting
from driftframe.framework.kernels import kernel, variant

#: The cost model that sets a neighbour list's skin (see :class:`NeighbourList`), in seconds: a
#: build (fixed, per body) and one listed pair for one step (how they were measured: docs/design/broadphase.md).
BUILD_COST = (25e-6, 0.1e-6)
PAIR_COST = 0.015e-6
MAX_SKIN_SCALE = 4.0
# error_model="numpy" (a zero divisor gives inf, not a raise), as in the contact kernels: numba compiles its own
# functions (np.empty, min, ...) once for each error model of the kernels calling them
_OPTS = dict(error_model="numpy", no_cfunc_wrapper=True)
#: Up to this many bodies an ``"auto"`` build tests every pair (:func:`_all_pairs`) instead of using the grid: the
#: crossover of the two builds (``benchmarks/collision_scaling.py``, its list build table).
LIST_ALL_MAX = 80


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
    on any machine (its constants and what it gained: docs/design/broadphase.md).

    ``method``, how a build finds the pairs: ``"all"`` tests every pair of
    territories (compiled: :func:`_all_pairs`); ``"grid"`` files them in a
    grid of cells (compiled: :func:`_grid_pairs`; with up to
    ``ALL_PAIRS_MAX`` bodies not swept, numpy's every pair); ``"auto"`` is
    ``"all"`` up to :data:`LIST_ALL_MAX` bodies and ``"grid"`` above;
    ``"sweep"`` and ``"kdtree"``: :func:`~.broadphase.sphere_pairs`. The
    pairs are the same whichever finds them; a scene of up to
    ``LIST_ALL_MAX`` bodies compiles neither the grid nor the spread sort.
    """

    def __init__(self, skin_steps: float = 8.0, method: str = "auto"):
        # broadphase imports this module (it re-exports the list's names): its names are taken at the call
        from driftframe.framework.broadphase import METHODS
        if method not in METHODS:
            raise ValueError(f"broad phase method must be one of {METHODS}, got {method!r}")
        self.skin_steps = float(skin_steps)
        self.method = method
        self.i = np.empty(0, np.intp)
        self.j = np.empty(0, np.intp)
        self.centre = np.empty((3, 0))
        self.radius = np.empty(0)
        self._r_median = np.nan                          # the median of ``radius`` (see _prepare)
        self.skin = np.empty(0)
        self.reach = np.empty(0)
        self.swept = np.zeros(0, bool)
        self.budget = 2
        self.builds = 0
        self.scale = 1.0                                  # the skin's factor for the next build
        self._scratch = (np.empty(0, np.int64), np.empty(0))   # the grid build's, kept (see _grid_build)

    def build(self, centres: np.ndarray, radii: np.ndarray, step_disp: np.ndarray) -> None:
        """(Re)build from centres (3, n), radii (n,) and each body's displacement per step (n,), m."""
        from driftframe.framework.broadphase import ALL_PAIRS_MAX, sphere_pairs
        x = np.asarray(centres, np.float64).T                 # (n, 3): a view of the caller's x.T (no copy)
        if not (x.flags.c_contiguous and x.flags.writeable):  # (one layout and a writable type: one compile)
            x = np.array(x, order="C")
        r = np.ascontiguousarray(radii, np.float64)
        d = np.ascontiguousarray(step_disp, np.float64)
        n = len(r)
        # up to LIST_ALL_MAX bodies every pair is tested (faster than the grid there, and a scene that small
        # compiles neither the grid nor the spread sort: docs/bench/compile.md)
        small = self.method == "all" or (self.method == "auto" and n <= LIST_ALL_MAX)
        # one compiled pass: the centres' (3, n) copy, the radii's, the territories (medians and all), the
        # grid's cells and the x order of the territories (one call: each kernel called in a rebuild found
        # its data cold, between steps)
        (c, r, self._r_median, skin, swept, reach, n_slow, grid, self._order, self._lo_x,
         self._width) = (_prepare_small if small else _prepare)(x, r, d, self.skin_steps * self.scale, self.radius,
                                                                self._r_median)
        got = None
        if small:
            got = _collect(lambda oi, oj: _all_pairs(c, reach, swept, oi, oj), n_slow) + (self._scratch,)
        elif self.method in ("auto", "grid") and n_slow > ALL_PAIRS_MAX:
            # one compiled pass: counting sort into a dense grid, then the exact sphere test over the
            # half stencil (the same pairs as sphere_pairs; their order does not matter to the solver)
            got = _grid_build(c, reach, swept, n_slow, grid, self._scratch)
        if got is not None:
            self.i, self.j, self._scratch = got
        else:
            slow = np.flatnonzero(~swept)
            i, j = sphere_pairs(c[:, slow], reach[slow], self.method, soa=True)
            self.i, self.j = slow[i], slow[j]
        self.centre, self.radius, self.skin, self.reach, self.swept = c, r, skin, reach, swept
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



@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def territory_query(lo, hi, order, lo_x, width, centre, reach, swept):
    """Compiled :meth:`NeighbourList.territories`: listed bodies whose territory box meets ``[lo, hi]``.

    ``order``, ``lo_x``, ``width``, ``centre`` (3, n), ``reach``, ``swept``: the list's arrays
    (:meth:`NeighbourList.kernel_arrays`). Used by the contact kernel for bodies swept mid-step.
    """
    a = sorting.bisect(lo_x, lo[0] - width, np.bool_(False))     # np.bool_: see contact_params' _NOT_LITERAL
    b = sorting.bisect(lo_x, hi[0], np.bool_(True))
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


@kernel(**_OPTS)
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


def _grid_build(c, reach, swept, n_slow, grid, scratch):
    """Pairs of not-swept territories that overlap, by :func:`_grid_pairs`, and the scratch arrays it
    used; None when the scene spans too many cells for int64 keys (the caller falls back on sort and
    sweep). ``grid``: :func:`_grid_setup`'s cells; ``scratch``: ``(int64, float64)`` arrays from the last
    build, grown here when too small."""
    h, hh, bx, by, bz, nx, ny, nz = grid
    if not h > 0 or max(nx, ny, nz) > _KEY_SPAN:
        return None
    # a dense table of cells when they are few; a hash table of the occupied cells when the scene is
    # sparse: 2^bits >= 2 m buckets, and beside them a bitmap of 32 bits a bucket, so that a look at an
    # empty cell (most of a sparse scene's) reads one bit of a table the size of m int64 (the sizes
    # measured against each other: docs/design/broadphase.md)
    dense = float(nx) * float(ny) * float(nz) <= 8.0 * n_slow + 4096
    bits = max(6, (2 * n_slow - 1).bit_length())
    nt = nx * ny * nz if dense else 1 << bits
    n = reach.shape[0]
    wi, wf = scratch
    # kept from build to build: fresh memory each build cost its page faults
    need = 2 * n + nt + 1 + 2 * n_slow + (0 if dense else nt >> 1)
    if wi.shape[0] < need:
        wi = np.empty(need + n // 4, np.int64)
    if wf.shape[0] < 4 * n_slow:
        wf = np.empty(4 * n_slow + n, np.float64)
    return _collect(lambda oi, oj: _grid_pairs(c, reach, swept, h, hh, bx, by, bz, nx, ny, nz, dense, nt, 64 - bits,
                                               oi, oj, wi, wf), n_slow) + ((wi, wf),)


def _collect(pairs, n_slow):
    """The pairs ``pairs(oi, oj)`` finds (a compiled pass that writes the first ``len(oi)`` into ``oi``, ``oj`` and
    returns how many there are): ``(i, j)``, with room for ``8 n_slow + 64``, then for all of them if more."""
    cap = 8 * n_slow + 64
    while True:
        oi = np.empty(cap, np.int64)
        oj = np.empty(cap, np.int64)
        p = pairs(oi, oj)
        if p <= cap:
            return oi[:p], oj[:p]
        cap = p


def _build_start(x, r, d, skin_steps, last_r, last_median):
    """What :meth:`NeighbourList.build` needs before the pairs, in one call: the centres ``x`` (n, 3) as a
    (3, n) copy, a copy of the radii ``r`` and their median, the territories (:func:`_territories`: skin,
    swept, reach), the bodies not swept, the grid's cells (:func:`_grid_setup`; zeros in ``_prepare_small``,
    whose pairs are found by testing every pair) and the x order. The radii's median is
    ``last_median`` when they are ``last_r``'s bit for bit (the last build's: radii seldom change, and the
    selection cost a tenth of a rebuild). Compiled twice: ``_prepare`` and ``_prepare_small`` (``_GRID``)."""
    n = x.shape[0]
    c = np.empty((3, n))
    for k in range(n):
        for a in range(3):
            c[a, k] = x[k, a]
    rc = np.empty(n)
    same = last_r.shape[0] == n
    rb = r.view(np.int64)
    lb = last_r.view(np.int64)
    for k in range(n):
        rc[k] = r[k]
        if same and rb[k] != lb[k]:
            same = False
    r_median = last_median if same else sorting.median(rc)
    skin, swept, reach = _territories(rc, d, skin_steps, r_median)
    m = 0
    for k in range(n):
        if not swept[k]:
            m += 1
    # the x order: the territories' low ends in x, sorted (a stable sort), their order, and twice the largest
    # listed reach (what NeighbourList.territories and territory_query search); in O(n) by the spread sort
    # when the bodies fill a region, by the merge sort the solver compiles anyway in a small scene
    lo_x = np.empty(n)
    for k in range(n):
        lo_x[k] = c[0, k] - reach[k]
    if _GRID:
        grid = _grid_setup(c, reach, swept)
        order = sorting.argsort_spread(lo_x, n)
    else:
        grid = (0.0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0)
        order = sorting.argsort_stable(sorting.order_keys(lo_x, n), n)
    width = 0.0
    for k in range(n):
        if not swept[k]:
            width = max(width, 2.0 * reach[k])
    lo_sorted = np.empty(n)
    for k in range(n):
        lo_sorted[k] = lo_x[order[k]]
    return c, rc, r_median, skin, swept, reach, m, grid, order, lo_sorted, width


#: Cells per axis at most (with the ghost layers), so that a cell key (x * ny + y) * nz + z fits in int64.
_KEY_SPAN = 2_000_000


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
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
    r_lo, r_hi = sorting.select_middle(rs)                 # (rs is this call's own: reordered in place)
    cut = 2.0 * (r_hi if m & 1 else (r_lo + r_hi) / 2)     # twice the median
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


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, inline="always")
def _cell_index(v, base, h):
    """The cell of coordinate ``v`` along one axis: cells of side ``h`` from ``base``, after one ghost layer."""
    return int((v - base) / h) + 1


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, inline="always")
def _cell_key(ix, iy, iz, ny, nz):
    """One integer per cell (or per offset between cells), in (x, y, z) order: ``(ix ny + iy) nz + iz``."""
    return (ix * ny + iy) * nz + iz


#: Fibonacci hashing's multiplier (2^64 / golden ratio, odd), as a signed int64: a sparse scene's cell key
#: times it, top bits, picks the cell's bucket (Knuth, TAOCP 3, 6.4).
_HASH = -7046029254386353131


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, inline="always")
def _cell_slot(q, dense, shift, nt):
    """The cell lookup of :func:`_grid_pairs`: where cell key ``q``'s bodies are filed, ``(slot, word,
    bit)``. Dense: the slot is the key itself (word and bit unused). Sparse: the bucket is the top bits
    of ``q * _HASH`` (``64 - shift`` of them: ``nt`` buckets), and the cell's bit of the occupancy
    bitmap is bit ``bit`` of int64 ``word``, the 5 bits below the bucket's picking one of its 32.
    Scalars in and out, so that it costs the caller no reference counting of the table's arrays."""
    if dense:
        return q, 0, 0
    hv = q * _HASH
    bt = (hv >> (shift - 5)) & (32 * nt - 1)
    return (hv >> shift) & (nt - 1), bt >> 6, bt & 63


@kernel(**_OPTS)
def _grid_pairs(c, reach, swept, h, hh, bx, by, bz, nx, ny, nz, dense, nt, shift, oi, oj, wi, wf):
    """Pairs ``i < j`` of not-swept bodies with ``|c_i - c_j| <= reach_i + reach_j`` (``c``: (3, n)).

    Cells of side ``h > 2 hh`` by centre, so a pair of ordinary bodies (reach <= ``hh``) lies in the
    same or neighbouring cells. The bodies are filed by a counting sort, O(n + table): ``dense``, into a
    table of every cell; else (a sparse scene: far more cells than bodies) into a hash table of ``nt``
    buckets (the caller's power of two >= 2 m; m the bodies filed), a bucket holding the bodies of the
    cells that hash to it, and a bitmap of the occupied cells' hashes (32 bits a bucket: a look at an
    empty cell reads one bit). No sort, no binary search: a radius ratio of 1,000 has a million cells
    for 4,000 bodies, and a sort of their keys then a search of 14 cells per body cost several steps'
    work (docs/design/broadphase.md). Each
    ordinary body tests the later ordinary bodies of its own cell and those of the 13 cells of a half
    stencil; a body read from a bucket counts only when it is in the cell looked for, so each pair is
    found once. A large body (reach > ``hh``) tests every body in the block of cells its reach plus the
    largest can span (large-large pairs once, from the lower index).

    ``nt``: the table's size (the cells, dense; else a power of two), ``shift``: 64 minus its
    bits. ``wi``, ``wf``: int64 and float64 scratch, at least ``2 n + nt + 1 + 2 m`` (and ``nt / 2`` more
    for the bitmap, sparse) and ``4 m`` long.

    A cell's key is :func:`_cell_key` and its slot in the table (and bit of the bitmap) is
    :func:`_cell_slot`, everywhere; both take and give scalars only: a helper taking the table's
    arrays made numba count references at every call (docs/design/broadphase.md).

    Writes the pairs into ``oi``, ``oj`` as far as they hold and returns how many there are (the
    caller gives larger arrays and calls again when they did not hold them all: growing arrays
    inside the loop would cost reference counting on every iteration)."""
    n = reach.shape[0]
    m = 0
    for k in range(n):
        if not swept[k]:
            m += 1
    # the scratch (the caller's, kept from build to build): each body's cell and slot of the table, the
    # table's runs (``nt`` cells, dense, or 2^(64 - shift) buckets: bucket = top bits of key * _HASH), the
    # bodies in table order and their cells, the bitmap (sparse); their coordinates and reaches
    cell = wi[:n]
    slot = wi[n:2 * n]
    start = wi[2 * n:2 * n + nt + 1]
    body = wi[2 * n + nt + 1:2 * n + nt + 1 + m]
    sc = wi[2 * n + nt + 1 + m:2 * n + nt + 1 + 2 * m]
    occ = wi[2 * n + nt + 1 + 2 * m:2 * n + nt + 1 + 2 * m + (0 if dense else nt >> 1)]
    for q in range(occ.shape[0]):
        occ[q] = 0
    sx = wf[:m]
    sy = wf[m:2 * m]
    sz = wf[2 * m:3 * m]
    sr = wf[3 * m:4 * m]
    big = 0.0
    for k in range(n):
        cell[k] = -1
        if swept[k]:
            continue
        big = max(big, reach[k])
        cell[k] = _cell_key(_cell_index(c[0, k], bx, h), _cell_index(c[1, k], by, h), _cell_index(c[2, k], bz, h),
                            ny, nz)
    # counting sort: counts, their running sum (the end of each run), then each body placed from the
    # last, so that every run ends up at its start and holds its bodies in index order
    for q in range(nt + 1):
        start[q] = 0
    for k in range(n):
        if cell[k] >= 0:
            q, word, bit = _cell_slot(cell[k], dense, shift, nt)
            if not dense:
                occ[word] |= np.int64(1) << bit
            slot[k] = q
            start[q] += 1
    for q in range(nt):
        start[q + 1] += start[q]
    for k in range(n - 1, -1, -1):
        if cell[k] >= 0:
            q = slot[k]
            start[q] -= 1
            body[start[q]] = k
    # coordinates, reaches and cells in table order: the stencil reads them contiguously
    for s in range(m):
        k = body[s]
        sx[s] = c[0, k]
        sy[s] = c[1, k]
        sz[s] = c[2, k]
        sr[s] = reach[k]
        sc[s] = cell[k]
    # this cell, then the 13 neighbour cells after it in (x, y, z) order
    offs = np.zeros(14, np.int64)
    o = 1
    for dx in range(-1, 2):
        for dy in range(-1, 2):
            for dz in range(-1, 2):
                if dx > 0 or (dx == 0 and (dy > 0 or (dy == 0 and dz > 0))):
                    offs[o] = _cell_key(dx, dy, dz, ny, nz)
                    o += 1
    cap = oi.shape[0]
    p = 0
    for s in range(m):
        ar = sr[s]
        if ar > hh:
            continue                                      # a large body: its own search below
        a = body[s]
        q = sc[s]
        ax = sx[s]
        ay = sy[s]
        az = sz[s]
        for t in range(14):
            qq = q + offs[t]
            w0, word, bit = _cell_slot(qq, dense, shift, nt)
            if not dense and not (occ[word] >> bit) & 1:
                continue                                  # an empty cell (most, in a sparse scene)
            b0 = s + 1 if t == 0 else start[w0]           # own cell: the later bodies of its run
            b1 = start[w0 + 1]
            for u in range(b0, b1):
                if sr[u] > hh or (not dense and sc[u] != qq):
                    continue                              # found from the large body's side; another cell
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
        ix = _cell_index(ax, bx, h)
        iy = _cell_index(ay, by, h)
        iz = _cell_index(az, bz, h)
        span = 1.0                                         # the block's cells (a float: no overflow)
        for i0, nd in ((ix, nx), (iy, ny), (iz, nz)):
            span *= min(i0 + w, nd - 1) - max(i0 - w, 0) + 1
        # a body far larger than the rest (a radius ratio of hundreds) can span more cells than there are
        # bodies: then it tests every body once, as one block (O(n), not O(cells))
        flat = span > m
        gx0, gx1 = (0, 0) if flat else (max(ix - w, 0), min(ix + w, nx - 1))
        gy0, gy1 = (0, 0) if flat else (max(iy - w, 0), min(iy + w, ny - 1))
        gz0, gz1 = (0, 0) if flat else (max(iz - w, 0), min(iz + w, nz - 1))
        for gx in range(gx0, gx1 + 1):
            for gy in range(gy0, gy1 + 1):
                for gz in range(gz0, gz1 + 1):
                    qq = _cell_key(gx, gy, gz, ny, nz)
                    if flat:
                        b0 = 0
                        b1 = m
                    else:
                        w0, word, bit = _cell_slot(qq, dense, shift, nt)
                        if not dense and not (occ[word] >> bit) & 1:
                            continue                      # an empty cell
                        b0 = start[w0]
                        b1 = start[w0 + 1]
                    for u in range(b0, b1):
                        b = body[u]
                        if b == a or (sr[u] > hh and b < a) or not (flat or sc[u] == qq):
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


@kernel(**_OPTS)
def step_lengths(u, dt):
    """Each body's displacement in one step, ``|u_k| dt`` (m; ``u``: (n, 3) m/s), for
    :meth:`NeighbourList.build`: ``np.sqrt((u * u).sum(axis=1)) * dt`` bit for bit (numpy sums the three
    squares left to right), in one pass instead of numpy's four (docs/design/broadphase.md)."""
    n = u.shape[0]
    out = np.empty(n)
    for k in range(n):
        out[k] = math.sqrt(u[k, 0] * u[k, 0] + u[k, 1] * u[k, 1] + u[k, 2] * u[k, 2]) * dt
    return out


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _territories(r, d, skin_steps, r_median):
    """Each body's skin, whether it is swept, and its reach ``r + skin`` (see :class:`NeighbourList`).

    Room for ``skin_steps`` steps at the body's own speed ``d`` per step (at least the median's, and at
    least 2 % of the median radius a step: a scene at rest, a crystal or a pile, gets a skin of 0.16 r,
    so the bodies an impact sets moving stay inside their territory instead of each being swept again
    in every wave of the impact); a body whose skin dwarfs the
    others' (more than 8 median skins + 4 largest radii; a bullet among asteroids) would make huge
    cells and many pairs: it is swept instead. ``r_median``: the radii's median (``sorting.median(r)``)."""
    n = r.shape[0]
    skin = np.empty(n)
    swept = np.zeros(n, np.bool_)
    reach = np.empty(n)
    if n == 0:
        return skin, swept, reach
    # the skins' middle two are those of the displacements mapped (the map never decreases): one
    # selection serves both medians, bit for bit
    d_lo, d_hi = sorting.middle(d)
    floor_ = max(d_hi if n & 1 else (d_lo + d_hi) / 2, 0.02 * r_median)
    for k in range(n):
        skin[k] = skin_steps * max(d[k], floor_)
    big = r[0]
    for k in range(n):
        big = max(big, r[k])
    s_lo = skin_steps * max(d_lo, floor_)
    s_hi = skin_steps * max(d_hi, floor_)
    limit = 8.0 * (s_hi if n & 1 else (s_lo + s_hi) / 2) + 4.0 * big
    for k in range(n):
        swept[k] = skin[k] > limit
    for k in range(n):
        reach[k] = r[k] + skin[k]
    return skin, swept, reach


@kernel(**_OPTS)
def _all_pairs(c, reach, swept, oi, oj):
    """Pairs ``i < j`` of not-swept territories that overlap, ``|c_i - c_j| <= reach_i + reach_j`` (the test of
    :func:`_grid_pairs` and ``sphere_pairs``), every pair tested, in ``(i, j)`` order: the first ``len(oi)``
    written to ``oi``, ``oj``; returns how many there are. ``c``: (3, n)."""
    n = reach.shape[0]
    cap = oi.shape[0]
    p = 0
    for a in range(n):
        if swept[a]:
            continue
        ax = c[0, a]
        ay = c[1, a]
        az = c[2, a]
        ar = reach[a]
        for b in range(a + 1, n):
            if swept[b]:
                continue
            dx = c[0, b] - ax
            dy = c[1, b] - ay
            dz = c[2, b] - az
            R = ar + reach[b]
            if dx * dx + dy * dy + dz * dz <= R * R:
                if p < cap:
                    oi[p] = a
                    oj[p] = b
                p += 1
    return p


# NeighbourList.build's first pass, with the grid's cells and the spread sort, and without (every pair tested)
_prepare = kernel(**_OPTS)(variant(_build_start, "_prepare", _GRID=True))
_prepare_small = kernel(**_OPTS)(variant(_build_start, "_prepare_small", _GRID=False))
