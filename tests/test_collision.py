"""Collision system: each case against its analytic answer, and the cases where simple methods fail."""
from __future__ import annotations

import math

import esper
import numpy as np
import pytest

from driftframe.components.body import Acceleration, AngularVelocity, Mass, Transform, Velocity
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.systems.collision import CollisionSystem
from driftframe.systems.movement import MovementSystem
from driftframe.systems.spin import SpinSystem

DT = 1.0 / 60.0


def scene(world, bodies, method="continuous", order=None, **kw):
    """Movement + collision; ``bodies``: dicts with x, v, r, and optional m, e. Returns entity ids
    in the order of ``bodies`` (created in ``order`` if given)."""
    world.add_system(MovementSystem())
    world.add_system(CollisionSystem(method, **kw))
    ids = [None] * len(bodies)
    for k in (order if order is not None else range(len(bodies))):
        b = bodies[k]
        comps = [Transform(b["x"]), SphereCollider(b.get("r", 0.5), b.get("e", 1.0))]
        if b.get("v") is not None:
            comps.append(Velocity(b["v"]))
        if b.get("m", 1.0) is not None:
            comps.append(Mass(b.get("m", 1.0)))
        ids[k] = world.create_entity(*comps)
    return ids


def pos(e):
    return np.array(esper.component_for_entity(e, Transform).position)


def vel(e):
    return np.array(esper.component_for_entity(e, Velocity).linear)


def energy(ids, masses):
    return sum(0.5 * m * float(vel(e) @ vel(e)) for e, m in zip(ids, masses))


def momentum(ids, masses):
    return sum(m * vel(e) for e, m in zip(ids, masses))


# -- two-body hits against the textbook ------------------------------------------------------

def test_head_on_equal_masses_swap_velocities(world):
    # gap 2.11 m closing at 2 m/s: contact at t_c = 1.055 s (inside step 64), centres at 0.945, 1.945
    a, b = scene(world, [dict(x=(-0.11, 0, 0), v=(1, 0, 0)), dict(x=(3.0, 0, 0), v=(-1, 0, 0))])
    world.step(120)                                   # 2 s
    np.testing.assert_allclose(vel(a), [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(vel(b), [1, 0, 0], atol=1e-12)
    # then 2 - 1.055 = 0.945 s back out
    np.testing.assert_allclose(pos(a), [0.945 - 0.945, 0, 0], atol=1e-12)
    np.testing.assert_allclose(pos(b), [1.945 + 0.945, 0, 0], atol=1e-12)


def test_glancing_hit_equal_masses_one_at_rest_leave_at_right_angles(world):
    v, h, R = 3.0, 0.6, 1.0                           # impact parameter h, r_a + r_b = R
    a, b = scene(world, [dict(x=(-2.05, -h, 0), v=(v, 0, 0)), dict(x=(0, 0, 0), v=(0, 0, 0))])
    world.step(60)
    va, vb = vel(a), vel(b)
    assert abs(va @ vb) < 1e-12                       # right angle
    np.testing.assert_allclose(np.linalg.norm(va), v * h / R, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(vb), v * math.sqrt(1 - (h / R) ** 2), rtol=1e-12)
    # the struck ball leaves along the line of centres at contact: (sqrt(R^2 - h^2), h) / R
    np.testing.assert_allclose(vb / np.linalg.norm(vb), [0.8, 0.6, 0], atol=1e-12)


def test_head_on_mass_ratio_1_to_10_gives_the_1d_elastic_result(world):
    m1, m2, v1, v2 = 1.0, 10.0, 3.0, -1.0
    a, b = scene(world, [dict(x=(0, 0, 0), v=(v1, 0, 0), m=m1), dict(x=(2.5, 0, 0), v=(v2, 0, 0), m=m2)])
    world.step(60)
    np.testing.assert_allclose(vel(a)[0], ((m1 - m2) * v1 + 2 * m2 * v2) / (m1 + m2), rtol=1e-12)
    np.testing.assert_allclose(vel(b)[0], ((m2 - m1) * v2 + 2 * m1 * v1) / (m1 + m2), rtol=1e-12)
    np.testing.assert_allclose(momentum([a, b], [m1, m2]), [m1 * v1 + m2 * v2, 0, 0], rtol=1e-12)


def test_bounce_off_immovable_sphere_reflects_velocity_about_the_normal(world):
    v = np.array([2.0, 1.0, 0.5])
    p0 = np.array([-3.0, -1.2, -0.4])
    a, wall = scene(world, [dict(x=p0, v=v, r=0.5), dict(x=(0, 0, 0), v=(0, 0, 0), r=1.0, m=math.inf)])
    world.step(120)
    # independent answer: first t with |p0 + v t| = 1.5, normal at contact, v' = v - 2 (v.n) n
    a2, b2, c2 = v @ v, p0 @ v, p0 @ p0 - 1.5 ** 2
    tc = (-b2 - math.sqrt(b2 * b2 - a2 * c2)) / a2
    n = -(p0 + v * tc) / 1.5                          # from the ball to the wall's centre
    expect = v - 2 * (v @ n) * n
    np.testing.assert_allclose(vel(a), expect, atol=1e-12)
    np.testing.assert_allclose(vel(wall), [0, 0, 0], atol=0)
    np.testing.assert_allclose(pos(wall), [0, 0, 0], atol=0)
    np.testing.assert_allclose(pos(a), p0 + v * tc + expect * (2.0 - tc), atol=1e-12)


# -- tunnelling ------------------------------------------------------------------------------

@pytest.mark.parametrize("closing", [30.0, 10_000.0])
def test_fast_spheres_do_not_tunnel(world, closing):
    # r = 0.1 m each: closing * dt is more than the combined diameter (0.4 m), and the step
    # boundaries straddle the contact: |d| is never below 0.2 m at the end of a step
    step = closing * DT
    d0 = 0.25 + 2 * step
    a, b = scene(world, [dict(x=(0, 0, 0), v=(closing / 2, 0, 0), r=0.1),
                         dict(x=(d0, 0, 0), v=(-closing / 2, 0, 0), r=0.1)])
    ends = []
    for _ in range(4):
        world.step()
        ends.append(abs(pos(b)[0] - pos(a)[0]))
    assert min(ends) > 0.2                            # never overlapping at a step boundary
    np.testing.assert_allclose(vel(a), [-closing / 2, 0, 0], rtol=1e-12)
    np.testing.assert_allclose(vel(b), [closing / 2, 0, 0], rtol=1e-12)
    assert pos(a)[0] < pos(b)[0]                      # bounced back: still in their original order


def test_articles_method_lets_fast_spheres_pass_through(world):
    closing = 30.0
    a, b = scene(world, [dict(x=(0, 0, 0), v=(15, 0, 0), r=0.1), dict(x=(1.25, 0, 0), v=(-15, 0, 0), r=0.1)],
                 method="articles")
    world.step(4)
    np.testing.assert_allclose(vel(a), [closing / 2, 0, 0])      # untouched: the hit was missed
    assert pos(a)[0] > pos(b)[0]                                 # they passed through each other


def test_articles_method_resolves_a_slow_hit_and_reports_it(world):
    # slow enough to be seen overlapping: the baseline gets the velocities right (not the positions)
    m1, m2, v1, v2 = 1.0, 3.0, 1.0, -1.0
    a, b = scene(world, [dict(x=(0, 0, 0), v=(v1, 0, 0), m=m1), dict(x=(1.5, 0, 0), v=(v2, 0, 0), m=m2)],
                 method="articles")
    seen = []
    for _ in range(30):
        world.step()
        seen += world.events
    np.testing.assert_allclose(vel(a)[0], ((m1 - m2) * v1 + 2 * m2 * v2) / (m1 + m2), rtol=1e-12)
    np.testing.assert_allclose(vel(b)[0], ((m2 - m1) * v2 + 2 * m1 * v1) / (m1 + m2), atol=1e-12)
    assert len(seen) == 1 and seen[0].method == "articles" and (seen[0].a, seen[0].b) == (a, b)
    np.testing.assert_allclose(seen[0].impulse, m2 * abs(vel(b)[0] - v2), rtol=1e-12)
    np.testing.assert_allclose(seen[0].normal, [1, 0, 0], atol=1e-12)


# -- many contacts in one step -----------------------------------------------------------------

@pytest.mark.parametrize("broadphase", ["all", "grid"])
@pytest.mark.parametrize("order", [None, [5, 3, 0, 4, 1, 2], [2, 4, 1, 5, 0, 3]])
def test_newtons_cradle_passes_the_strikers_speed_to_the_last_ball(world, order, broadphase):
    r, v, x_s = 0.1, 1.0, -0.41                        # striker touches ball 1 at t_c = 0.21 s
    balls = [dict(x=(x_s, 0, 0), v=(v, 0, 0), r=r)] + [dict(x=(0.2 * i, 0, 0), v=(0, 0, 0), r=r)
                                                       for i in range(5)]
    ids = scene(world, balls, order=order, broadphase=broadphase)
    e0 = energy(ids, [1] * 6)
    world.step(60)
    t_c, T = 0.21, 60 * DT
    for e in ids[:-1]:
        np.testing.assert_allclose(vel(e), 0.0, atol=1e-9)
    np.testing.assert_allclose(vel(ids[-1]), [v, 0, 0], atol=1e-9)
    np.testing.assert_allclose(pos(ids[0]), [-0.2, 0, 0], atol=1e-9)
    for i in range(1, 5):
        np.testing.assert_allclose(pos(ids[i]), [0.2 * (i - 1), 0, 0], atol=1e-9)
    np.testing.assert_allclose(pos(ids[-1]), [0.8 + v * (T - t_c), 0, 0], atol=1e-9)
    np.testing.assert_allclose(energy(ids, [1] * 6), e0, rtol=1e-12)


def _rack(r=0.5, cue=(-3.05, 0.0, 0.0), speed=10.0):
    """A cue ball on the x axis and a 15-ball triangle of touching balls, symmetric about y = 0."""
    balls = [dict(x=cue, v=(speed, 0, 0), r=r)]
    for row in range(5):
        for j in range(row + 1):
            balls.append(dict(x=(row * math.sqrt(3) * r, (j - row / 2) * 2 * r, 0.0), v=(0, 0, 0), r=r))
    return balls


@pytest.mark.parametrize("broadphase", ["all", "grid"])
@pytest.mark.parametrize("order", [None, list(np.random.default_rng(7).permutation(16))])
def test_billiard_break_keeps_energy_momentum_and_mirror_symmetry(world, order, broadphase):
    balls = _rack()
    ids = scene(world, balls, order=order, broadphase=broadphase)
    R, speed = 1.0, 10.0
    e0, p0 = energy(ids, [1] * 16), momentum(ids, [1] * 16)
    before = np.array([pos(e) for e in ids])
    hits = 0
    for _ in range(90):
        world.step()
        hits += len(world.events)
        after = np.array([pos(e) for e in ids])
        # no jump: nobody moves faster than the energy allows (sqrt(2 KE / m) = the cue's speed)
        assert np.linalg.norm(after - before, axis=1).max() <= speed * DT * (1 + 1e-9)
        before = after
        np.testing.assert_allclose(energy(ids, [1] * 16), e0, rtol=1e-12)
        np.testing.assert_allclose(momentum(ids, [1] * 16), p0, rtol=0, atol=1e-12 * speed)
    assert hits > 15                                  # the rack did break up
    x = np.array([pos(e) for e in ids])
    v = np.array([vel(e) for e in ids])
    # mirror partner of each ball: the ball whose start is its start mirrored in y
    start = np.array([b["x"] for b in balls])
    mirror = [int(np.argmin(np.linalg.norm(start - s * [1, -1, 1], axis=1))) for s in start]
    np.testing.assert_allclose(x[mirror], x * [1, -1, 1], atol=1e-9)
    np.testing.assert_allclose(v[mirror], v * [1, -1, 1], atol=1e-9)
    d = np.linalg.norm(x[:, None] - x[None], axis=2) + np.eye(16) * 10
    assert d.min() >= R * (1 - 1e-9)                  # no overlap left


def test_symmetric_hit_does_not_depend_on_creation_order(world):
    # a ball strikes two touching balls placed symmetrically about its line of motion
    s = math.sqrt(3) / 2
    balls = [dict(x=(-2.03, 0, 0), v=(4, 0, 0)), dict(x=(s, 0.5, 0), v=(0, 0, 0)),
             dict(x=(s, -0.5, 0), v=(0, 0, 0))]
    results = []
    for order in ([0, 1, 2], [2, 1, 0], [1, 2, 0]):
        from driftframe.framework.world import World
        with World() as w:
            ids = scene(w, balls, order=order)
            w.step(60)
            results.append(np.array([np.r_[pos(e), vel(e)] for e in ids]))
    for res in results:
        x, v = res[:, :3], res[:, 3:]
        np.testing.assert_allclose(x[1] * [1, -1, 1], x[2], atol=1e-9)
        np.testing.assert_allclose(v[1] * [1, -1, 1], v[2], atol=1e-9)
        np.testing.assert_allclose(res, results[0], atol=1e-12)
    v = results[0][:, 3:]
    # both contacts in one wave: A = [[2, 1/2], [1/2, 2]], lambda = 8 s / 2.5 each (s = sqrt(3)/2)
    lam = 8 * s / 2.5
    np.testing.assert_allclose(v[0], [4 - 2 * lam * s, 0, 0], atol=1e-12)
    np.testing.assert_allclose(v[1], lam * np.array([s, 0.5, 0]), atol=1e-12)
    np.testing.assert_allclose((v * v).sum(), 16, rtol=1e-12)


# -- robustness ------------------------------------------------------------------------------

def test_overlapping_spheres_that_separate_do_not_stick_or_jump(world):
    # spawned overlapping by 0.2 m, moving apart slowly
    a, b = scene(world, [dict(x=(0, 0, 0), v=(-0.1, 0, 0)), dict(x=(0.8, 0, 0), v=(0.1, 0, 0))])
    world.step(120)
    np.testing.assert_allclose(vel(a), [-0.1, 0, 0], atol=0)
    np.testing.assert_allclose(pos(a), [-0.2, 0, 0], atol=1e-12)   # moved by v t only
    np.testing.assert_allclose(pos(b), [1.0, 0, 0], atol=1e-12)
    assert world.events == []


def test_articles_method_makes_separating_overlapping_spheres_jump(world):
    # the baseline does not ask whether an overlapping pair approaches: "moving back until the
    # centres are r_a + r_b apart" puts a separating pair on the far side of each other
    a, b = scene(world, [dict(x=(0, 0, 0), v=(-0.1, 0, 0)), dict(x=(0.8, 0, 0), v=(0.1, 0, 0))],
                 method="articles")
    world.step()
    assert abs(pos(a)[0]) > 100 * 0.1 * DT            # far more than v dt: a teleport
    assert pos(a)[0] > pos(b)[0]                      # they swapped sides


def test_overlapping_spheres_that_approach_bounce_once_without_jumping(world):
    a, b = scene(world, [dict(x=(0, 0, 0), v=(0.5, 0, 0)), dict(x=(0.9, 0, 0), v=(-0.5, 0, 0))])
    world.step()
    np.testing.assert_allclose(vel(a), [-0.5, 0, 0], atol=1e-15)
    np.testing.assert_allclose(vel(b), [0.5, 0, 0], atol=1e-15)
    # resolved at the start of the step: each moved back out by v dt, no teleport
    np.testing.assert_allclose(pos(a), [-0.5 * DT, 0, 0], atol=1e-15)
    np.testing.assert_allclose(pos(b), [0.9 + 0.5 * DT, 0, 0], atol=1e-15)
    assert len(world.events) == 1
    world.step(60)
    assert len(world.events) == 0
    np.testing.assert_allclose(vel(a), [-0.5, 0, 0], atol=1e-15)


def test_touching_spheres_at_rest_stay_put(world):
    ids = scene(world, [dict(x=(0.2 * i, 0, 0), v=(0, 0, 0), r=0.1) for i in range(4)]
                + [dict(x=(5, 0, 0), v=(1, 0, 0))])
    before = [pos(e) for e in ids[:4]]
    world.step(30)
    for e, p in zip(ids[:4], before):
        np.testing.assert_allclose(pos(e), p, atol=0)
        np.testing.assert_allclose(vel(e), 0, atol=0)


def test_sphere_jammed_between_immovable_spheres_stops_instead_of_looping(world):
    # touching both walls, moving along the line of centres: no elastic answer exists
    ids = scene(world, [dict(x=(-1.0, 0, 0), v=(0, 0, 0), m=math.inf),
                        dict(x=(0.0, 0, 0), v=(1.0, 0.5, 0)),
                        dict(x=(1.0, 0, 0), v=(0, 0, 0), m=math.inf)])
    with pytest.warns(RuntimeWarning, match="jammed"):
        world.step()
    np.testing.assert_allclose(vel(ids[1]), [0, 0.5, 0], atol=1e-12)     # the part along the walls stays
    world.step(10)
    np.testing.assert_allclose(pos(ids[1])[0], 0.0, atol=1e-12)


@pytest.mark.parametrize("ea, eb, e", [(0.5, 1.0, 0.5), (0.3, 0.8, 0.3), (0.0, 1.0, 0.0)])
def test_restitution_scales_the_normal_speed_by_the_smaller_coefficient(world, ea, eb, e):
    m1, m2, v1, v2 = 1.0, 3.0, 2.0, -1.0
    a, b = scene(world, [dict(x=(0, 0, 0), v=(v1, 0, 0), m=m1, e=ea),
                         dict(x=(2.5, 0, 0), v=(v2, 0, 0), m=m2, e=eb)])
    world.step(90)
    np.testing.assert_allclose(vel(b)[0] - vel(a)[0], -e * (v2 - v1), atol=1e-12)
    np.testing.assert_allclose(m1 * vel(a)[0] + m2 * vel(b)[0], m1 * v1 + m2 * v2, rtol=1e-12)


def test_events_report_entities_time_point_normal_and_impulse(world):
    # created first, so a has the lower id; contact at t = 1.055 s, a's centre at 1.945, b's at 0.945
    a, b = scene(world, [dict(x=(3.0, 0, 0), v=(-1, 0, 0), m=2.0), dict(x=(-0.11, 0, 0), v=(1, 0, 0), m=2.0)])
    seen = []
    for _ in range(90):
        world.step()
        seen += world.events
    assert len(seen) == 1
    ev = seen[0]
    assert isinstance(ev, CollisionEvent)
    assert (ev.a, ev.b) == (a, b) and a < b
    np.testing.assert_allclose(ev.time, 1.055, atol=1e-12)
    np.testing.assert_allclose((ev.time - ev.step_time) / DT, 63, atol=1e-9)   # inside step 64
    np.testing.assert_allclose(ev.normal, [-1, 0, 0], atol=1e-12)              # from a to b
    np.testing.assert_allclose(ev.point, [1.445, 0, 0], atol=1e-12)            # on a's surface
    np.testing.assert_allclose(ev.impulse, 2.0 * 2.0, rtol=1e-12)   # m |dv| = 2 kg * 2 m/s
    with pytest.raises(AttributeError):
        ev.impulse = 0.0                              # frozen


def test_sphere_without_mass_weighs_one_kilogram(world):
    a, b = scene(world, [dict(x=(0, 0, 0), v=(3, 0, 0), m=None), dict(x=(2.5, 0, 0), v=(0, 0, 0), m=2.0)])
    world.step(60)
    np.testing.assert_allclose(vel(a)[0], (1 - 2) * 3 / 3, rtol=1e-12)
    np.testing.assert_allclose(vel(b)[0], 2 * 1 * 3 / 3, rtol=1e-12)


def test_collider_without_velocity_is_a_fixed_obstacle(world):
    a, post = scene(world, [dict(x=(0, 0, 0), v=(2, 0, 0)), dict(x=(2.5, 0, 0), v=None, m=1.0)])
    world.step(60)
    np.testing.assert_allclose(vel(a), [-2, 0, 0], rtol=1e-12)
    np.testing.assert_allclose(pos(post), [2.5, 0, 0], atol=0)


def test_two_immovable_spheres_pass_through_each_other(world):
    a, b = scene(world, [dict(x=(0, 0, 0), v=(1, 0, 0), m=math.inf), dict(x=(2.5, 0, 0), v=(-1, 0, 0), m=math.inf)])
    world.step(120)
    np.testing.assert_allclose(vel(a), [1, 0, 0])
    np.testing.assert_allclose(pos(a), [2, 0, 0], atol=1e-12)


def test_components_added_or_removed_between_steps_are_seen(world):
    a, b = scene(world, [dict(x=(0, 0, 0), v=(2, 0, 0), m=None), dict(x=(2.5, 0, 0), v=(0, 0, 0), m=None)])
    world.step()
    esper.add_component(b, Mass(math.inf))            # b becomes immovable after the first step
    world.step(59)
    np.testing.assert_allclose(vel(a), [-2, 0, 0], rtol=1e-12)
    np.testing.assert_allclose(vel(b), [0, 0, 0], atol=0)
    esper.remove_component(b, SphereCollider)         # and then stops colliding at all
    esper.component_for_entity(a, Velocity).linear = (2.0, 0.0, 0.0)
    world.step(60)
    assert pos(a)[0] > pos(b)[0]                      # passed straight through


def test_spin_is_not_touched(world):
    world.add_system(SpinSystem())
    a, b = scene(world, [dict(x=(0, 0, 0), v=(2, 0, 0)), dict(x=(2.5, 0.3, 0), v=(0, 0, 0))])
    esper.add_component(a, AngularVelocity((0.0, 0.0, 3.0)))
    world.step(60)
    assert vel(b)[0] > 0
    np.testing.assert_allclose(esper.component_for_entity(a, AngularVelocity).angular, [0, 0, 3.0], atol=0)


def test_thrusting_body_keeps_momentum_and_its_thrust(world):
    # a body under constant thrust hits a free one: the impulse acts on the average velocity over
    # the step and the thrust's a dt is kept; momentum changes by exactly m a t
    a, b = scene(world, [dict(x=(0, 0, 0), v=(1, 0, 0)), dict(x=(2.5, 0, 0), v=(0, 0, 0))])
    esper.add_component(a, Acceleration((2.0, 0.0, 0.0)))
    p0 = momentum([a, b], [1, 1])
    world.step(60)
    assert vel(b)[0] > 1.0
    np.testing.assert_allclose(momentum([a, b], [1, 1]), p0 + np.array([2.0, 0, 0]) * 60 * DT, rtol=1e-12)
    assert pos(b)[0] - pos(a)[0] >= 1.0 - 1e-9


# -- broad phase inside the system -------------------------------------------------------------

def _field(world, n, seed, broadphase, fast=0):
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.25, 0.75, n)
    side = ((4 / 3 * np.pi * r ** 3).sum() / 0.05) ** (1 / 3)
    x = rng.uniform(0, side, (n, 3))
    from driftframe.framework.broadphase import sphere_pairs
    for _ in range(200):                              # no overlaps at spawn
        i, j = sphere_pairs(x, r)
        if not len(i):
            break
        x[np.unique(j)] = rng.uniform(0, side, (len(np.unique(j)), 3))
    v = rng.normal(0, 3.0, (n, 3))
    v[:fast] *= 100.0                                 # a few bullets among them
    world.add_system(MovementSystem())
    cs = world.add_system(CollisionSystem(broadphase=broadphase))
    ids = world.create_entities(Transform.bulk(n, position=x), Velocity.bulk(n, linear=v),
                                Mass.bulk(n, kg=r ** 3), SphereCollider.bulk(n, radius=r))
    return ids, cs


@pytest.mark.parametrize("fast", [0, 3])
def test_neighbour_list_finds_the_same_contacts_as_all_pairs(fast):
    from driftframe.framework.world import World
    runs = []
    for broadphase in ("all", "grid"):
        with World() as w:
            ids, cs = _field(w, 150, 11, broadphase, fast)
            events, builds, swept = [], 0, 0
            for _ in range(40):
                w.step()
                events += sorted((e.a, e.b, round(e.time, 9)) for e in w.events)
                builds += cs.stats["builds"]
                swept += cs.stats["swept"]
            state = np.array([np.r_[pos(e), vel(e)] for e in ids])
            runs.append((events, state, builds, swept))
    (ev_all, st_all, _, _), (ev_list, st_list, builds, swept) = runs
    assert len(ev_all) > 20
    assert ev_list == ev_all
    np.testing.assert_allclose(st_list, st_all, rtol=0, atol=1e-9)
    assert 1 <= builds < 40                           # the list is reused across steps
    assert swept > 0                                  # bodies that left their territory were swept


# -- bad input -------------------------------------------------------------------------------

@pytest.mark.parametrize("radius, words", [(0.0, "> 0, got 0.0"), (-1.0, "> 0, got -1.0"),
                                           (math.nan, "NaN"), (math.inf, "finite, got inf")])
def test_bad_radius_is_rejected_with_its_value(radius, words):
    with pytest.raises(ValueError, match="SphereCollider.radius") as err:
        SphereCollider(radius)
    assert words in str(err.value)


@pytest.mark.parametrize("e", [-0.1, 1.5, math.nan, math.inf])
def test_bad_restitution_is_rejected_with_its_value(e):
    with pytest.raises(ValueError, match="SphereCollider.restitution") as err:
        SphereCollider(1.0, e)
    assert repr(e) in str(err.value) or "nan" in str(err.value)


def test_bad_bulk_radius_names_the_row():
    with pytest.raises(ValueError, match=r"SphereCollider.radius\[2\] must be > 0, got -0.5"):
        SphereCollider.bulk(3, radius=[1.0, 2.0, -0.5])
    with pytest.raises(ValueError, match=r"SphereCollider.restitution\[1\] must be in \[0, 1\], got 2.0"):
        SphereCollider.bulk(2, radius=[1.0, 1.0], restitution=[1.0, 2.0])


def test_collision_system_rejects_unknown_options():
    with pytest.raises(ValueError, match="'exact'"):
        CollisionSystem("exact")
    with pytest.raises(ValueError, match="'octree'"):
        CollisionSystem(broadphase="octree")
    with pytest.raises(ValueError, match="skin_steps"):
        CollisionSystem(skin_steps=0)
