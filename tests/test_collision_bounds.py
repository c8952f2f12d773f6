"""Collision at any density: bounded work, exact events, per-pair tolerances, bad input, placement.

Each test builds its scene here (no benchmark code), small enough to keep the suite fast; the
full-size scenes and their timings are in benchmarks/collision_stress.py.
"""
from __future__ import annotations

import heapq
import math
import warnings

import numpy as np
import pytest

from driftframe.components.body import Acceleration, Mass, Transform, Velocity
from driftframe.components.collision import SphereCollider
from driftframe.framework import broadphase as bp
from driftframe.framework import contact, placement
from driftframe.framework.world import World
from driftframe.systems.collision import CollisionSystem
from driftframe.systems.movement import MovementSystem

DT = 1.0 / 60.0


def build(world, x, v, r, m=None, e=None, **kw):
    n = len(x)
    world.add_system(MovementSystem())
    cs = world.add_system(CollisionSystem(**kw))
    m = np.ones(n) if m is None else np.asarray(m, float)
    e = np.ones(n) if e is None else np.asarray(e, float)
    ids = world.create_entities(Transform.bulk(n, position=np.asarray(x, float)),
                                Velocity.bulk(n, linear=np.asarray(v, float)), Mass.bulk(n, kg=m),
                                SphereCollider.bulk(n, radius=np.asarray(r, float), restitution=e))
    return cs, ids


def state(world, ids):
    return world.columns(Transform, ids).position, world.columns(Velocity, ids).linear


def energy(world, ids, m):
    v = world.columns(Velocity, ids).linear
    fin = np.isfinite(m)
    return 0.5 * float((m[fin] * (v[fin] * v[fin]).sum(axis=1)).sum())


# -- the event list against an exact event-driven reference -----------------------------------

def reference_events(x, v, r, m, T):
    """Binary elastic collisions of free spheres up to time T: a priority queue over all pairs.

    Textbook event-driven hard spheres: each pair's next time of impact goes into a heap with both
    bodies' collision counts; an entry is void once either body has collided since.
    """
    n = len(r)
    p = [list(map(float, a)) for a in x]                      # path origin: position = p + u t
    u = [list(map(float, a)) for a in v]
    r = [float(a) for a in r]
    inv = [1.0 / float(a) for a in m]
    count = [0] * n
    heap = []

    def predict(i, j, t0):
        w = [u[j][k] - u[i][k] for k in range(3)]
        d = [p[j][k] - p[i][k] + w[k] * t0 for k in range(3)]
        b = sum(d[k] * w[k] for k in range(3))
        if b >= 0.0:
            return
        a = sum(w[k] * w[k] for k in range(3))
        R = r[i] + r[j]
        c = sum(d[k] * d[k] for k in range(3)) - R * R
        disc = b * b - a * c
        if disc < 0.0:
            return
        s = c / (math.sqrt(disc) - b)
        if t0 + s <= T:
            heapq.heappush(heap, (t0 + max(s, 0.0), i, j, count[i], count[j]))

    for i in range(n):
        for j in range(i + 1, n):
            predict(i, j, 0.0)
    events = []
    while heap:
        t, i, j, ci, cj = heapq.heappop(heap)
        if ci != count[i] or cj != count[j]:
            continue
        d = [p[j][k] + u[j][k] * t - p[i][k] - u[i][k] * t for k in range(3)]
        dist = math.sqrt(sum(a * a for a in d))
        nrm = [a / dist for a in d]
        vn = sum(nrm[k] * (u[j][k] - u[i][k]) for k in range(3))
        lam = -2.0 * vn / (inv[i] + inv[j])
        for k in range(3):
            du_i, du_j = -lam * inv[i] * nrm[k], lam * inv[j] * nrm[k]
            u[i][k] += du_i
            p[i][k] -= du_i * t
            u[j][k] += du_j
            p[j][k] -= du_j * t
        count[i] += 1
        count[j] += 1
        events.append((i, j, t))
        for k in range(n):
            if k != i and k != j:
                predict(min(i, k), max(i, k), t)
                predict(min(j, k), max(j, k), t)
    return events


def test_event_list_matches_an_exact_event_driven_reference():
    rng = np.random.default_rng(5)
    n = 300
    r = rng.uniform(0.3, 0.6, n)
    m = rng.uniform(0.5, 2.0, n)
    side = ((4 / 3 * np.pi * r ** 3).sum() / 0.2) ** (1 / 3)
    x = placement.place(rng, r, placement.in_box((0, 0, 0), (side,) * 3))
    v = rng.uniform(-4, 4, (n, 3))
    steps = 45
    ref = reference_events(x, v, r, m, steps * DT)
    with World() as w:
        cs, ids = build(w, x, v, r, m)
        index = {e: k for k, e in enumerate(ids)}
        got = []
        for _ in range(steps):
            w.step()
            got += [(index[ev.a], index[ev.b], ev.time) for ev in w.events]
    assert len(ref) > 150                                    # a busy gas, not a handful of hits
    got.sort(key=lambda g: g[2])
    assert [(i, j) for i, j, _ in got] == [(min(i, j), max(i, j)) for i, j, _ in ref]
    np.testing.assert_allclose([t for *_, t in got], [t for *_, t in ref], rtol=0, atol=1e-9)


# -- reproducible on any CPU: golden hashes ---------------------------------------------------

def _rack(r=0.5, speed=10.0):
    balls = [((-3.05, 0.0, 0.0), (speed, 0.0, 0.0))]
    for row in range(5):
        for j in range(row + 1):
            balls.append(((row * math.sqrt(3) * r, (j - row / 2) * 2 * r, 0.0), (0.0, 0.0, 0.0)))
    return np.array([b[0] for b in balls]), np.array([b[1] for b in balls]), np.full(16, r)


#: state_hash after 90 steps of the break and 30 steps of the gas. Only + - * / sqrt in a fixed
#: order go into these numbers (no LAPACK, no transcendental function), so they are the same on
#: every CPU; a change here is a change of the physics or of the stored state.
GOLDEN_BREAK = "86fd97a17b0bd338c8552f591a284d54"
GOLDEN_GAS = "6667534180e214a271f422047f390e7c"


def _gas():
    """2,000 spheres, r = 0.5 m, on a 13-sided cubic lattice of spacing 1.25 m jittered by up to
    0.1249 m (no overlap), velocities uniform in [-1, 1)^3 m/s (rng.uniform: exact arithmetic)."""
    rng = np.random.default_rng(2024)
    g = np.stack(np.meshgrid(*[np.arange(13.0)] * 3, indexing="ij"), -1).reshape(-1, 3)[:2000]
    x = g * 1.25 + rng.uniform(-0.1249, 0.1249, (2000, 3))
    v = rng.uniform(-1.0, 1.0, (2000, 3))
    return x, v, np.full(2000, 0.5)


def test_golden_state_hash_of_a_billiard_break():
    with World() as w:
        build(w, *_rack(), broadphase="all")
        w.step(90)
        assert w.state_hash() == GOLDEN_BREAK


def test_golden_state_hash_of_a_2000_sphere_gas():
    with World() as w:
        cs, _ = build(w, *_gas())
        contacts = 0
        for _ in range(30):
            w.step()
            contacts += cs.stats["contacts"]
        assert contacts > 100
        assert w.state_hash() == GOLDEN_GAS


def test_dense_solve_uses_a_basic_solution_for_dependent_contacts():
    # two identical rows (the same contact twice): rank 1, the second unknown is set to 0
    A = np.array([[2.0, 2.0], [2.0, 2.0]])
    y = np.array([4.0, 4.0])
    out = np.empty(2)
    contact.solve_psd(A.copy(), y.copy(), 2, out)
    np.testing.assert_array_equal(out, [2.0, 0.0])
    # a well-posed one against the exact answer
    A = np.array([[2.0, 0.5], [0.5, 2.0]])
    contact.solve_psd(A.copy(), np.array([1.0, 2.0]), 2, out)
    np.testing.assert_allclose(A @ out, [1.0, 2.0], rtol=1e-15)


# -- tolerances per pair ----------------------------------------------------------------------

def test_near_miss_within_the_touch_tolerance_gets_no_impulse():
    # b passes a with its closest approach 5e-10 R outside contact; at the step boundary it is
    # 1e-6 m short of that point and still closing (the old scene-wide test bounced it)
    R = 1.0
    h = R * (1 + 5e-10)
    with World() as w:
        cs, ids = build(w, [(0, 0, 0), (-1e-6, h, 0)], [(0, 0, 0), (1.0, 0, 0)], [0.5, 0.5])
        w.step(3)
        _, v = state(w, ids)
        np.testing.assert_array_equal(v, [[0, 0, 0], [1.0, 0, 0]])
        assert not w.events


@pytest.mark.parametrize("far", [False, True])
def test_a_touching_pair_closing_slowly_bounces_whatever_moves_elsewhere(far):
    x = [(0, 0, 0), (1.0, 0, 0)]
    v = [(0, 0, 0), (-1e-15, 0, 0)]
    if far:                                                   # a fast body 50 m away
        x.append((50.0, 0, 0))
        v.append((0, 1.0, 0))
    with World() as w:
        cs, ids = build(w, x, v, [0.5] * len(x))
        w.step()
        _, vel = state(w, ids)
        np.testing.assert_allclose(vel[:2], [[-1e-15, 0, 0], [0, 0, 0]], rtol=0, atol=1e-30)


# -- one-way data -----------------------------------------------------------------------------

def test_collision_integrates_its_bodies_exactly_as_movement_would_when_nothing_touches():
    rng = np.random.default_rng(3)
    x = rng.uniform(-50, 50, (40, 3))
    v = rng.normal(0, 2, (40, 3))
    a = rng.normal(0, 1, (40, 3))
    with World() as w:
        build(w, x, v, np.full(40, 1e-3))
        ids = w.query(Transform, SphereCollider)
        ids.refresh()
        ents = ids.entities.tolist()
        for e, acc in zip(ents[:20], a[:20]):
            w.add_component(e, Acceleration(acc))
        twins = w.create_entities(Transform.bulk(40, position=x), Velocity.bulk(40, linear=v))
        for e, acc in zip(twins[:20], a[:20]):
            w.add_component(e, Acceleration(acc))
        w.step(10)
        xc, vc = state(w, ents)
        xt, vt = state(w, twins)
        np.testing.assert_array_equal(xc, xt)                # bit for bit: movement's own update
        np.testing.assert_array_equal(vc, vt)


def test_movement_moves_colliders_again_once_the_collision_system_is_removed():
    with World() as w:
        w.add_system(MovementSystem())
        cs = w.add_system(CollisionSystem())
        e = w.create_entity(Transform((0, 0, 0)), Velocity((1.0, 0, 0)), SphereCollider(0.5))
        w.step(3)
        w.remove_system(cs)
        w.step(3)
        np.testing.assert_allclose(w.columns(Transform, [e]).position[0], [6 * DT, 0, 0], rtol=1e-15)


def test_movement_moves_colliders_when_no_collision_system_is_present():
    with World() as w:
        w.add_system(MovementSystem())
        e = w.create_entity(Transform((0, 0, 0)), Velocity((1.0, 0, 0)), SphereCollider(0.5))
        w.step(6)
        np.testing.assert_allclose(w.columns(Transform, [e]).position[0], [6 * DT, 0, 0], rtol=1e-15)


# -- bad input --------------------------------------------------------------------------------

def test_nan_written_into_a_column_is_reported_with_entity_and_field_and_does_not_spread():
    # b sits in a's path; a user's code writes NaN into b's velocity
    with World() as w:
        cs, ids = build(w, [(0, 0, 0), (1.5, 0, 0), (5, 5, 5)], [(1.0, 0, 0), (0, 0, 0), (0, 0, 0.1)],
                        [0.5] * 3)
        w.step()
        # a system writes straight into the table (the hot path; world.columns would refuse NaN)
        table = w.table(Velocity)
        table.data["linear"][table.rows_of(np.array([ids[1]]))] = [math.nan, 0.0, 0.0]
        with pytest.warns(RuntimeWarning, match=rf"entity {ids[1]} has Velocity.linear = \[nan, 0.0, 0.0\]"):
            w.step()
        with warnings.catch_warnings():
            warnings.simplefilter("error")                    # reported once, not every step
            w.step(60)
        x, v = state(w, ids)
        assert np.isfinite(x[[0, 2]]).all() and np.isfinite(v[[0, 2]]).all()
        np.testing.assert_array_equal(v[0], [1.0, 0, 0])     # a passed through the bad body untouched
        np.testing.assert_allclose(x[0], [62 * DT, 0, 0], rtol=1e-12)
        assert cs.stats["left_out"] == 1


# -- overlaps at spawn --------------------------------------------------------------------------

def test_overlaps_at_spawn_are_reported_once_and_resolved_without_jump_or_energy_gain():
    rng = np.random.default_rng(8)
    n = 3000
    side = (n * 4 / 3 * np.pi * 0.125 / 0.05) ** (1 / 3)
    x = rng.uniform(0, side, (n, 3))
    v = rng.uniform(-1, 1, (n, 3))
    i, j = bp.sphere_pairs(x, np.full(n, 0.5))
    d = np.linalg.norm(x[j] - x[i], axis=1)
    worst = int(np.argmin(d))
    with World() as w:
        cs, ids = build(w, x, v, np.full(n, 0.5))
        m = np.ones(n)
        k0 = energy(w, ids, m)
        with pytest.warns(RuntimeWarning) as rec:
            w.step()
        text = [str(r.message) for r in rec if "overlap" in str(r.message)]
        assert len(text) == 1
        assert f"{len(i)} pairs of spheres overlap" in text[0]
        assert f"entities {ids[i[worst]]} and {ids[j[worst]]}" in text[0]
        assert cs.stats["waves"] < 50 * len(i)               # bounded: no endless loop over the overlaps
        before = w.columns(Transform, ids).position
        with warnings.catch_warnings():
            warnings.simplefilter("error")                    # once
            for _ in range(30):
                w.step()
                after = w.columns(Transform, ids).position
                speed = np.sqrt(2 * k0)                       # nobody can move faster than all the energy
                assert np.linalg.norm(after - before, axis=1).max() <= speed * DT * (1 + 1e-9)
                before = after
                assert energy(w, ids, m) <= k0 * (1 + 1e-12)


# -- dense scenes: bounded, exact ---------------------------------------------------------------

@pytest.mark.parametrize("kind", ["sc", "fcc"])
def test_touching_crystal_hit_at_random_resolves_in_one_step_keeping_energy(kind):
    rng = np.random.default_rng(4)
    g = np.stack(np.meshgrid(*[np.arange(6.0 if kind == "sc" else 4.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    if kind == "sc":
        x = g * 1.0
    else:
        basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
        x = ((g[:, None, :] + basis[None]) * math.sqrt(2)).reshape(-1, 3)
    n = len(x)
    v = rng.uniform(-1, 1, (n, 3))
    with World() as w:
        cs, ids = build(w, x, v, np.full(n, 0.5))
        m = np.ones(n)
        k0 = energy(w, ids, m)
        w.step()
        assert cs.stats["contacts"] > n                       # the whole crystal took part
        assert cs.stats["waves"] < 100
        np.testing.assert_allclose(energy(w, ids, m), k0, rtol=1e-12)
        w.step(5)
        np.testing.assert_allclose(energy(w, ids, m), k0, rtol=1e-12)
        xs = w.columns(Transform, ids).position
        i, j = bp.sphere_pairs(xs, np.full(n, 0.5 * (1 - 1e-9)))
        assert not len(i)                                     # nothing ends a step overlapping


@pytest.mark.parametrize("e", [0.0, 0.5])
def test_converging_inelastic_spheres_are_bounded_lose_energy_never_gain_it_and_do_not_overlap(e):
    rng = np.random.default_rng(6)
    n = 120
    r = np.full(n, 0.5)
    x = placement.place(rng, r, placement.in_shell(0.0, (n * 1.1 ** 3) ** (1 / 3)), gap=0.02)
    v = -5.0 * x / np.linalg.norm(x, axis=1, keepdims=True)
    with World() as w:
        cs, ids = build(w, x, v, r, e=np.full(n, e))
        m = np.ones(n)
        k = energy(w, ids, m)
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            for _ in range(90):
                w.step()
                k1 = energy(w, ids, m)
                assert k1 <= k * (1 + 1e-12)
                k = k1
                # bounded: inelastic contacts per body per step are capped (then the cluster moves as one)
                assert cs.stats["contacts"] <= 4 * contact.CAP * n + 4 * contact.JAM
                xs = w.columns(Transform, ids).position
                i, j = bp.sphere_pairs(xs, r * (1 - 1e-9))
                assert not len(i)
        assert k < 0.5 * 0.5 * n * 25                         # the clump did lose energy
        kinds = [str(x.message).split(":")[1] for x in rec if "collision" in str(x.message)]
        assert len(kinds) == len(set(kinds))                  # each remedy warns once


def test_tc_model_takes_a_rapid_repeat_contact_as_elastic():
    # a (e = 0.5) hits b, which hits c 0.05 s later. With t_c = 0.1 s that second contact is a
    # rapid repeat for b: elastic. With t_c = 0.01 s it keeps e = 0.5.
    def run(tc):
        with World() as w:
            cs, ids = build(w, [(-1.1, 0, 0), (0, 0, 0), (1.05, 0, 0)], [(1.0, 0, 0), (0, 0, 0), (0, 0, 0)],
                            [0.5] * 3, e=[0.5] * 3, contact_time=tc)
            with warnings.catch_warnings(record=True) as rec:
                warnings.simplefilter("always")
                w.step(30)
            return state(w, ids)[1][:, 0], [str(x.message) for x in rec]
    # first contact (t = 0.1 s): a 0.25, b 0.75 m/s; b meets c 0.05/0.75 s later
    v_slow, msgs_slow = run(0.01)
    np.testing.assert_allclose(v_slow, [0.25, 0.75 * 0.25, 0.75 * 0.75], rtol=1e-12)
    assert not any("TC model" in m for m in msgs_slow)
    v_fast, msgs = run(0.1)
    # b-c elastic (b stops, c takes 0.75); a (0.25) then catches b 0.133 s later, past t_c: e = 0.5
    np.testing.assert_allclose(v_fast, [0.25 * 0.25, 0.25 * 0.75, 0.75], atol=1e-12)
    assert sum("TC model" in m for m in msgs) == 1


def test_jam_bound_does_not_grow_with_idle_bodies_elsewhere():
    waves = []
    for idle in (0, 4000):
        x = [(-1.0, 0, 0), (0.0, 0, 0), (1.0, 0, 0)]
        v = [(0, 0, 0), (1.0, 0.5, 0), (0, 0, 0)]
        m = [math.inf, 1.0, math.inf]
        if idle:
            g = np.stack(np.meshgrid(*[np.arange(16.0)] * 3, indexing="ij"), -1).reshape(-1, 3)[:idle]
            x = np.concatenate([x, 20.0 + 2.5 * g])
            v = np.concatenate([v, np.zeros((idle, 3))])
            m = np.concatenate([m, np.ones(idle)])
        with World() as w:
            cs, ids = build(w, x, v, np.full(len(x), 0.5), m=m)
            with pytest.warns(RuntimeWarning, match="jammed"):
                w.step()
            waves.append(cs.stats["waves"])
            np.testing.assert_allclose(state(w, ids)[1][1], [0, 0.5, 0], atol=1e-12)
    assert waves[0] == waves[1] <= 2 * contact.JAM + 2


# -- placement --------------------------------------------------------------------------------

def test_placement_makes_a_field_without_overlaps_and_keeps_the_gap():
    rng = np.random.default_rng(1)
    r = rng.uniform(0.5, 3.0, 3000)
    x = placement.place(rng, r, placement.in_shell(100.0, 400.0), gap=0.1)
    i, j = bp.sphere_pairs(x, r + 0.05)
    assert not len(i)
    d = np.linalg.norm(x, axis=1)
    assert d.min() >= 100.0 and d.max() <= 400.0
    # spheres already there (a ship) are kept clear too
    ship, ship_r = np.array([[0.0, 0.0, 150.0]]), np.array([20.0])
    y = placement.place(np.random.default_rng(2), r[:500], placement.in_shell(100.0, 200.0), gap=0.1,
                        avoid=(ship, ship_r))
    assert (np.linalg.norm(y - ship, axis=1) - r[:500] >= ship_r[0] + 0.1 - 1e-9).all()


def test_placement_is_deterministic_and_says_when_the_region_is_too_full():
    r = np.full(500, 0.5)
    a = placement.place(np.random.default_rng(2), r, placement.in_box((0, 0, 0), (20, 20, 20)))
    b = placement.place(np.random.default_rng(2), r, placement.in_box((0, 0, 0), (20, 20, 20)))
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match=r"of 500 spheres found no free position"):
        placement.place(np.random.default_rng(2), r, placement.in_box((0, 0, 0), (4, 4, 4)), tries=20)
    with pytest.raises(ValueError, match="radii"):
        placement.place(np.random.default_rng(2), [1.0, -1.0], placement.in_box((0, 0, 0), (4, 4, 4)))
    with pytest.raises(ValueError, match="inner < outer"):
        placement.in_shell(5.0, 1.0)


def test_no_module_level_pair_cache_grows_with_the_sizes_seen():
    for n in range(2, 300, 7):
        bp.box_pairs(np.zeros((n, 3)), np.ones((n, 3)), "all")
    assert all(k <= bp._TRIU_CACHED for k in bp._TRIU)
