"""Broad phase: every method finds exactly the overlapping pairs; the neighbour list misses none."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from driftframe.framework import broadphase as bp
from driftframe.framework import broadphase_list, sorting


def through(k):
    """Kernel ``k`` (no CPython wrapper: only kernels call it) called from Python through a compiled caller."""
    import numba
    return numba.njit(lambda *args: k(*args))


METHODS = ["all", "sweep", "grid", "kdtree", "auto"]


def brute(lo, hi):
    lo, hi = np.asarray(lo), np.asarray(hi)
    n = len(lo)
    out = set()
    for i in range(n):
        for j in range(i + 1, n):
            if np.all(lo[i] <= hi[j]) and np.all(lo[j] <= hi[i]):
                out.add((i, j))
    return out


def as_set(i, j):
    assert np.all(i < j), "pairs come as i < j"
    pairs = list(zip(i.tolist(), j.tolist()))
    assert len(pairs) == len(set(pairs)), "each pair once"
    return set(pairs)


@st.composite
def boxes(draw):
    n = draw(st.integers(0, 70))
    seed = draw(st.integers(0, 2 ** 32 - 1))
    rng = np.random.default_rng(seed)
    side = draw(st.sampled_from([1.0, 10.0, 100.0]))
    c = rng.uniform(0, side, (n, 3))
    half = rng.uniform(0.0, 1.0, (n, 3))
    if n and draw(st.booleans()):                     # a few huge boxes (fast bodies' sweeps)
        big = rng.choice(n, size=min(n, 3), replace=False)
        half[big] *= 40.0
    if n > 1 and draw(st.booleans()):                 # exactly touching faces count as overlap
        c[1] = c[0] + [half[0, 0] + half[1, 0], 0, 0]
    return c - half, c + half


@pytest.mark.parametrize("method", METHODS)
@settings(max_examples=60, deadline=None)
@given(b=boxes())
def test_box_pairs_finds_exactly_the_overlapping_boxes(method, b):
    if method == "kdtree":
        pytest.importorskip("scipy.spatial")             # scipy comes with the bench extra only
    lo, hi = b
    assert as_set(*bp.box_pairs(lo, hi, method)) == brute(lo, hi)


@pytest.mark.parametrize("method", ["grid", "sweep", "kdtree"])
def test_box_pairs_on_a_large_field_matches_all_pairs(method):
    if method == "kdtree":
        pytest.importorskip("scipy.spatial")
    rng = np.random.default_rng(3)
    c = rng.uniform(0, 30, (2000, 3))
    r = rng.uniform(0.25, 0.75, (2000, 1))
    ref = as_set(*bp.box_pairs(c - r, c + r, "all"))
    assert len(ref) > 100
    assert as_set(*bp.box_pairs(c - r, c + r, method)) == ref


def test_grid_copes_with_a_scene_too_sparse_for_its_keys():
    c = np.array([[0, 0, 0], [1e300, 0, 0], [1e300, 1e300, 1e300], [0.5, 0, 0]], float)
    lo, hi = c - 1.0, c + 1.0
    assert as_set(*bp.box_pairs(lo, hi, "grid")) == {(0, 3)}


def test_sphere_pairs_uses_the_distance_not_the_box():
    c = np.array([[0, 0, 0], [1.5, 1.5, 0], [2.0, 0, 0], [0, 0, 2.1]], float)
    r = np.ones(4)
    # (0,1): boxes overlap but |d| = 2.12 > 2; (0,2): touching exactly; (0,3): apart
    assert as_set(*bp.sphere_pairs(c, r)) == {(0, 2), (1, 2)}


def test_boxes_against_all_tests_only_the_given_boxes_each_pair_once():
    rng = np.random.default_rng(5)
    c = rng.uniform(0, 5, (40, 3))
    lo, hi = c - 0.8, c + 0.8
    which = [3, 17, 20]
    ref = {p for p in brute(lo, hi) if p[0] in which or p[1] in which}
    got = as_set(*bp.boxes_against_all(lo.T.copy(), hi.T.copy(), which))
    assert got == ref


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), steps=st.floats(1.0, 20.0))
def test_neighbour_list_holds_every_pair_that_can_touch_inside_the_skins(seed, steps):
    rng = np.random.default_rng(seed)
    n = 300
    c = rng.uniform(0, 15, (n, 3))
    r = rng.uniform(0.2, 0.6, n)
    disp = rng.uniform(0, 0.05, n)
    nl = bp.NeighbourList(skin_steps=steps)
    nl.build(c.T, r, disp)
    listed = set(zip(nl.i.tolist(), nl.j.tolist()))
    # move every listed body anywhere inside its skin: all touching pairs must be listed
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    moved = c + u * (nl.skin * rng.uniform(0, 0.999, n))[:, None]
    assert not nl.strays(moved.T).any()
    i, j = bp.sphere_pairs(moved, r)
    slow = ~nl.swept
    touching = {(a, b) for a, b in zip(i.tolist(), j.tolist()) if slow[a] and slow[b]}
    assert touching <= listed
    # and a body pushed out of its skin is reported
    moved[7] = c[7] + nl.skin[7] * 1.01 * u[7]
    assert nl.strays(moved.T)[7] or nl.swept[7]


def test_neighbour_list_sweeps_a_body_far_faster_than_the_rest():
    rng = np.random.default_rng(1)
    n = 400
    c = rng.uniform(0, 20, (n, 3))
    r = np.full(n, 0.5)
    disp = np.full(n, 0.02)
    disp[9] = 50.0                                    # a bullet
    nl = bp.NeighbourList()
    nl.build(c.T, r, disp)
    assert nl.swept[9] and nl.swept.sum() == 1
    assert 9 not in nl.i and 9 not in nl.j


def test_territories_finds_every_listed_body_whose_territory_box_meets_the_query():
    rng = np.random.default_rng(2)
    n = 500
    c = rng.uniform(0, 20, (n, 3))
    r = rng.uniform(0.2, 0.7, n)
    nl = bp.NeighbourList()
    nl.build(c.T, r, rng.uniform(0, 0.03, n))
    lo, hi = np.array([4.0, 5.0, 6.0]), np.array([9.0, 6.0, 8.0])
    reach = nl.reach[:, None]
    ref = np.flatnonzero(np.all((c - reach <= hi) & (c + reach >= lo), axis=1) & ~nl.swept)
    np.testing.assert_array_equal(np.sort(nl.territories(lo, hi)), ref)


def test_unknown_method_is_rejected_with_its_name():
    with pytest.raises(ValueError, match="'octree'"):
        bp.box_pairs(np.zeros((2, 3)), np.ones((2, 3)), "octree")
    with pytest.raises(ValueError, match="'octree'"):
        bp.NeighbourList(method="octree")
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        bp.box_pairs(np.zeros((2, 3)), np.ones((3, 3)))


def _brute(c, reach, swept):
    """Every pair i < j of not-swept bodies with |c_i - c_j| <= reach_i + reach_j, by testing all."""
    k = np.flatnonzero(~swept)
    i, j = np.triu_indices(len(k), 1)
    i, j = k[i], k[j]
    d2 = ((c[:, j] - c[:, i]) ** 2).sum(axis=0)
    keep = d2 <= (reach[i] + reach[j]) ** 2
    return set(zip(i[keep].tolist(), j[keep].tolist()))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_grid_build_lists_the_same_pairs_with_a_few_fast_bodies_among_slow_ones(seed):
    # bodies made fast by collisions have reaches several times the median: they search a wider block
    # of cells instead of inflating every cell; the pairs must be exactly those of testing every pair
    rng = np.random.default_rng(seed)
    n = 1500
    c = rng.uniform(0, 30, (n, 3))
    r = rng.uniform(0.25, 0.75, n)
    d = rng.uniform(0.0, 0.05, n)
    d[rng.choice(n, 40, replace=False)] *= rng.uniform(4, 12, 40)
    nl = bp.NeighbourList()
    nl.build(c.T, r, d)
    assert (nl.reach > 2 * np.median(nl.reach)).sum() > 0           # the wide-search path runs
    got = list(zip(nl.i.tolist(), nl.j.tolist()))
    assert all(a < b for a, b in got) and len(set(got)) == len(got)   # ordered, each pair once
    assert set(got) == _brute(nl.centre, nl.reach, nl.swept)


def test_compiled_grid_build_grows_its_output_for_a_crowd():
    # 300 spheres in a ball of their own size: ~n^2/2 pairs, far more than the first guess of 8 per body
    rng = np.random.default_rng(5)
    c = rng.normal(0, 0.3, (300, 3))
    nl = bp.NeighbourList()
    nl.build(c.T, np.full(300, 0.5), np.full(300, 0.01))
    assert len(nl.i) > 8 * 300 + 64
    assert set(zip(nl.i.tolist(), nl.j.tolist())) == _brute(nl.centre, nl.reach, nl.swept)


def test_compiled_grid_build_on_a_sparse_scene_uses_sorted_cells_and_finds_the_same_pairs():
    # clusters a kilometre apart: far more cells than bodies, so the cells are found in a hash table
    rng = np.random.default_rng(7)
    c = np.concatenate([rng.uniform(0, 6, (100, 3)) + off for off in ((0, 0, 0), (1000, 0, 0), (0, 900, 700))])
    r = rng.uniform(0.25, 0.75, len(c))
    nl = bp.NeighbourList()
    nl.build(c.T, r, np.full(len(c), 0.02))
    h, hh, *_, nx, ny, nz = through(broadphase_list._grid_setup)(nl.centre, nl.reach, nl.swept)
    assert nx * ny * nz > 8 * len(c) + 4096                           # the sparse path
    want = _brute(nl.centre, nl.reach, nl.swept)
    assert len(want) > 100 and set(zip(nl.i.tolist(), nl.j.tolist())) == want


def test_compiled_grid_build_with_one_sphere_a_thousand_times_larger_tests_every_body_once():
    # its block of cells would be far more cells than there are bodies: it tests every body instead (the
    # large body's pairs, and every other pair, exactly those of testing every pair)
    rng = np.random.default_rng(11)
    n = 800
    c = rng.uniform(0, 40, (n, 3))
    r = np.full(n, 0.1)
    r[0] = 100.0                                                        # reaches past the whole field
    c[0] = (20.0, 20.0, 20.0)
    nl = bp.NeighbourList()
    nl.build(c.T, r, np.full(n, 0.01))
    got = set(zip(nl.i.tolist(), nl.j.tolist()))
    assert sum(1 for a, b in got if a == 0) == n - 1                   # the large one meets every body
    assert got == _brute(nl.centre, nl.reach, nl.swept)


@pytest.mark.parametrize("n", [2, 40, 80, 300])
def test_a_list_that_tests_every_pair_builds_the_grids_list(n):
    # "auto" tests every pair up to LIST_ALL_MAX bodies ("all" at any size): the same pairs as the grid's and
    # numpy's, and the same territories and x order bit for bit (the merge sort of the int64 keys against
    # the spread sort), with a few bodies swept among them
    rng = np.random.default_rng(n)
    c = rng.uniform(0, 1.2 * n ** (1 / 3), (n, 3))
    r = rng.uniform(0.25, 0.75, n)
    d = rng.uniform(0.0, 0.05, n)
    d[: n // 20] = 5.0                                                 # swept: they dwarf the others' skins
    small = bp.NeighbourList(method="auto" if n <= bp.LIST_ALL_MAX else "all")
    grid = bp.NeighbourList(method="grid")
    small.build(c.T, r, d)
    grid.build(c.T, r, d)
    assert small.swept.sum() == n // 20
    pairs = list(zip(small.i.tolist(), small.j.tolist()))
    assert pairs == sorted(set(pairs)) and all(a < b for a, b in pairs)          # each pair once, in order
    assert set(pairs) == set(zip(grid.i.tolist(), grid.j.tolist())) == _brute(small.centre, small.reach,
                                                                              small.swept)
    assert len(pairs) > (0 if n < 40 else n // 2)
    for a, b in [(small.centre, grid.centre), (small.reach, grid.reach), (small.skin, grid.skin),
                 (small._order, grid._order), (small._lo_x, grid._lo_x)]:
        assert a.tobytes() == b.tobytes()
    assert small._width == grid._width


def test_a_small_scenes_list_compiles_neither_the_grid_nor_the_spread_sort(tmp_path):
    # numba compiles whatever a kernel can call: a 52-body list build (the asteroids demo's) on an empty
    # cache must reach only the every-pair test and the merge sort the contact solver shares
    code = ("import numpy as np\n"
            "from driftframe.framework import broadphase_list as bl, sorting\n"
            "rng = np.random.default_rng(0)\n"
            "nl = bl.NeighbourList()\n"
            "nl.build(rng.uniform(0, 30, (3, 52)), rng.uniform(0.6, 3.5, 52), np.full(52, 0.02))\n"
            "print([len(k.signatures) for k in (bl._prepare_small, bl._all_pairs, sorting.argsort_stable, bl._prepare,"
            " bl._grid_setup, bl._grid_pairs, sorting.argsort_spread)], len(nl.i))\n")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout
    assert out.split("]")[0] == "[1, 1, 1, 0, 0, 0, 0" and int(out.split("]")[1]) > 0


def test_step_lengths_and_territories_are_numpys_formulas_bit_for_bit():
    # |u| dt in one compiled pass, and the skins from one selection serving two medians (the skins'
    # middle two are the displacements' mapped): the same bits as numpy's formulas, odd and even counts
    rng = np.random.default_rng(12)
    for n in (1, 2, 5, 400, 1001):
        u = rng.normal(0, 3, (n, 3)) * rng.uniform(0, 10, (n, 1))
        d = broadphase_list.step_lengths(u, 1.0 / 60.0)
        assert d.tobytes() == (np.sqrt((u * u).sum(axis=1)) * (1.0 / 60.0)).tobytes()
        d[: n // 3] = 0.0                                    # bodies at rest: the floor of 2 % of a radius
        r = rng.uniform(0.1, 1.0, n)
        # as NeighbourList.build's compiled pass calls them (so the kernels load from the warm cache)
        skin, swept, reach = through(broadphase_list._territories)(r, d, 8.0, through(sorting.median)(r))
        want = 8.0 * np.maximum(d, max(np.median(d), 0.02 * np.median(r)))
        assert skin.tobytes() == want.tobytes() and reach.tobytes() == (r + want).tobytes()
        assert np.array_equal(swept, want > 8.0 * np.median(want) + 4.0 * r.max())
