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

* :class:`NeighbourList` (in :mod:`.broadphase_list`, its names re-exported
  here) keeps the pairs that can touch over *several* steps (a Verlet list):
  each body gets a territory, and the list stays valid while no body leaves
  its own. Bodies that do are "swept": the caller tests their paths each
  step.
"""
from __future__ import annotations

import numpy as np

from driftframe.framework.broadphase_list import LIST_ALL_MAX, NeighbourList, mark_strays, step_lengths, territory_query

__all__ = ["ALL_PAIRS_MAX", "LIST_ALL_MAX", "METHODS", "box_pairs", "sphere_pairs", "boxes_against_all",
           "NeighbourList", "mark_strays", "step_lengths", "territory_query"]

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
