"""Static planes and boxes: exact times of impact and reflections against the analytic answer, no tunnelling,
order independence, bad input, and the billiards table they make."""
from __future__ import annotations

import math
import subprocess
import sys

import esper
import numpy as np
import pytest

from driftframe.components.body import Mass, Transform, Velocity
from driftframe.components.collision import BoxCollider, CollisionEvent, PlaneCollider, SphereCollider
from driftframe.framework import frame as fr
from driftframe.systems.collision import CollisionSystem
from driftframe.systems.movement import MovementSystem

DT = 1.0 / 60.0


def ball(world, x, v, r=0.5, e=1.0, m=1.0):
    return world.create_entity(Transform(x), Velocity(v), Mass(m), SphereCollider(r, e))


def systems(world):
    world.add_system(MovementSystem())
    world.add_system(CollisionSystem())


def hits(world):
    """The CollisionEvents of every step (the world keeps those since the last frame)."""
    out = []
    world.subscribe(CollisionEvent, out.append)
    return out


def vel(e):
    return np.array(esper.component_for_entity(e, Velocity).linear)


def pos(e):
    return np.array(esper.component_for_entity(e, Transform).position)


def test_a_sphere_meets_a_plane_at_the_exact_time_and_reflects(world):
    systems(world)
    # face y = 0.25 + 0.25 = 0.5 (Transform plus offset along the normal, given at length 2)
    plane = world.create_entity(Transform((7.0, 0.25, -3.0)), PlaneCollider(normal=(0.0, 2.0, 0.0), offset=0.25))
    b = ball(world, (0.0, 2.0, 0.0), (1.0, -2.7, 0.0))
    seen = hits(world)
    world.step(60)
    (ev,) = seen
    t = 1.0 / 2.7                                   # gap 2.0 - 0.5 - r = 1.0 m closing at 2.7 m/s
    assert (ev.a, ev.b) == (min(b, plane), max(b, plane))
    assert ev.time == pytest.approx(t, abs=1e-14)
    np.testing.assert_allclose(ev.normal, (0, -1, 0) if ev.a == b else (0, 1, 0), atol=1e-15)
    np.testing.assert_allclose(ev.point, (t, 0.5, 0.0), atol=1e-13)
    assert ev.impulse == pytest.approx(2 * 2.7, rel=1e-14)
    np.testing.assert_allclose(vel(b), (1.0, 2.7, 0.0), atol=1e-14)      # e = 1: the normal part reversed
    np.testing.assert_allclose(pos(b), (1.0, 2.0 - 2.7 * t + 2.7 * (1 - t), 0.0), atol=1e-12)


def test_a_plane_uses_the_smaller_restitution_and_the_entitys_orientation(world):
    systems(world)
    # the entity turned 90 degrees about z: its +y normal points along -x in the world
    q = fr.quat_from_axis_angle((0.0, 0.0, 1.0), math.pi / 2)
    world.create_entity(Transform((-1.0, 0.0, 0.0), q), PlaneCollider(normal=(0.0, 1.0, 0.0), restitution=0.5))
    b = ball(world, (-3.0, 0.0, 0.0), (2.0, 0.0, 1.0))
    world.step(120)
    np.testing.assert_allclose(vel(b), (-1.0, 0.0, 1.0), atol=1e-12)


@pytest.mark.parametrize("case", ["face", "edge", "corner"])
def test_a_sphere_meets_a_box_face_edge_or_corner_at_the_exact_time(world, case):
    systems(world)
    box = world.create_entity(Transform((5.0, 0.0, 0.0)), BoxCollider(half_extents=(1.0, 2.0, 3.0)))
    r = 0.5
    if case == "face":              # face x = 4 head on, off centre: the centre reaches x = 3.5 at 0.875 s
        x, v, t, n_out = (0.0, 0.3, 0.2), (4.0, 0.0, 0.0), 3.5 / 4.0, (-1.0, 0.0, 0.0)
    elif case == "edge":            # through the edge x = 4, y = 2 at 1.5 s; within r of it (1.5 s - r/|v|)
        x, v, t = (1.0, 5.0, 0.0), (2.0, -2.0, 0.0), 1.5 - r / math.sqrt(8.0)
        n_out = (-1 / math.sqrt(2), 1 / math.sqrt(2), 0.0)
    else:                           # through the corner (4, 2, 3) at 1.5 s
        x, v, t = (1.0, 5.0, 6.0), (2.0, -2.0, -2.0), 1.5 - r / math.sqrt(12.0)
        n_out = (-1 / math.sqrt(3), 1 / math.sqrt(3), 1 / math.sqrt(3))
    b = ball(world, x, v, r)
    seen = hits(world)
    world.step(150)
    (ev,) = seen
    assert ev.time == pytest.approx(t, abs=1e-13)
    n_out, v = np.array(n_out), np.array(v)
    np.testing.assert_allclose(ev.normal, -n_out if ev.a == b else n_out, atol=1e-13)
    np.testing.assert_allclose(ev.point, np.array(x) + v * t - r * n_out, atol=1e-12)    # on the box's surface
    v1 = v - 2 * (v @ n_out) * n_out
    np.testing.assert_allclose(vel(b), v1, atol=1e-13)
    assert float(vel(b) @ vel(b)) == pytest.approx(float(v @ v), rel=1e-14)             # e = 1: energy kept
    assert box in (ev.a, ev.b)


def test_a_turned_box_reflects_about_its_own_face(world):
    systems(world)
    q = fr.quat_from_axis_angle((0.0, 1.0, 0.0), math.radians(30.0))
    world.create_entity(Transform((0.0, 0.0, 0.0), q), BoxCollider(half_extents=(1.0, 1.0, 1.0)))
    n = np.array(fr.rotate(q, (1.0, 0.0, 0.0)))       # the face the ball comes at
    b = ball(world, 4.0 * n, -3.0 * n + (0.0, 0.7, 0.0), 0.25)
    seen = hits(world)
    world.step(90)
    (ev,) = seen
    assert ev.time == pytest.approx((4.0 - 1.0 - 0.25) / 3.0, abs=1e-13)
    np.testing.assert_allclose(vel(b), 3.0 * n + (0.0, 0.7, 0.0), atol=1e-13)


def test_a_fast_sphere_does_not_tunnel_through_a_thin_box(world):
    systems(world)
    world.create_entity(Transform((0.0, 0.0, 0.0)), BoxCollider(half_extents=(1e-3, 5.0, 5.0)))
    b = ball(world, (-5.0, 0.0, 0.0), (1000.0, 0.0, 0.0), r=0.1)     # 16.7 m a step, 2 mm of wall
    world.step(1)
    assert pos(b)[0] < -0.101 and vel(b)[0] == -1000.0
    world.step(59)
    assert pos(b)[0] < -0.101


def _pool(world, order, statics_order):
    """Balls in a walled box (four planes, two boxes standing in it), made in the given orders; returns
    the balls' ids in their logical order."""
    systems(world)
    rng = np.random.default_rng(7)
    xs = np.array([(x, 0.0, z) for x in np.linspace(-4, 4, 5) for z in np.linspace(-2.5, 2.5, 4)])
    vs = rng.uniform(-6, 6, (len(xs), 3)) * (1, 0, 1)
    shapes = [lambda: world.create_entity(Transform((-6.0, 0, 0)), PlaneCollider(normal=(1, 0, 0))),
              lambda: world.create_entity(Transform((6.0, 0, 0)), PlaneCollider(normal=(-1, 0, 0))),
              lambda: world.create_entity(Transform((0, 0, -4.0)), PlaneCollider(normal=(0, 0, 1), restitution=0.9)),
              lambda: world.create_entity(Transform((0, 0, 4.0)), PlaneCollider(normal=(0, 0, -1))),
              lambda: world.create_entity(Transform((-2.0, 0, 0.3)), BoxCollider(half_extents=(0.2, 1, 0.2))),
              lambda: world.create_entity(Transform((2.0, 0, -0.3)), BoxCollider(half_extents=(0.2, 1, 0.2)))]
    ids = [None] * len(xs)
    made = 0
    for k in order:
        ids[k] = ball(world, xs[k] * 1.3, vs[k], r=0.3)
        if made < len(statics_order) and k % 3 == 0:
            shapes[statics_order[made]]()
            made += 1
    for s in statics_order[made:]:
        shapes[s]()
    return ids


def test_shuffled_entity_order_gives_the_same_bits():
    from driftframe.framework.world import World

    runs = []
    for seed in (0, 1, 2):
        rng = np.random.default_rng(seed)
        order = rng.permutation(20) if seed else np.arange(20)
        statics = rng.permutation(6) if seed else np.arange(6)
        world = World()
        ids = _pool(world, order, statics)
        world.step(240)
        runs.append(np.array([np.concatenate([pos(e), vel(e)]) for e in ids]))
        world.close()
    assert np.array_equal(runs[0], runs[1]) and np.array_equal(runs[0], runs[2])
    assert np.all(np.abs(runs[0][:, 0]) <= 6.0 - 0.3 + 1e-9) and np.all(np.abs(runs[0][:, 2]) <= 4.0 - 0.3 + 1e-9)


def test_bad_shapes_are_refused_naming_the_value():
    with pytest.raises(ValueError, match=r"PlaneCollider\.normal must be a non-zero vector, got \[0\.0, 0\.0, 0\.0\]"):
        PlaneCollider(normal=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError,
                       match=r"BoxCollider\.half_extents must be three numbers > 0.*got \[1\.0, -2\.0, 1\.0\]"):
        BoxCollider(half_extents=(1.0, -2.0, 1.0))
    with pytest.raises(ValueError,
                       match=r"BoxCollider\.half_extents\[1\] must be three numbers > 0.*\[1\.0, 0\.0, 1\.0\]"):
        BoxCollider.bulk(2, half_extents=[(1.0, 1.0, 1.0), (1.0, 0.0, 1.0)])
    with pytest.raises(ValueError, match=r"PlaneCollider\.restitution must be in \[0, 1\], got 1\.5"):
        PlaneCollider(restitution=1.5)
    with pytest.raises(ValueError, match=r"PlaneCollider\.normal"):
        PlaneCollider(normal=(0.0, math.nan, 1.0))


def _kernels_called(demo: str) -> list[int]:
    """How many signatures each of the all-pairs and static solvers and the quiet-step kernels has after demo
    ``demo`` is prepared and stepped 120 times in a fresh process (a kernel never called has none)."""
    code = ("from driftframe.app import make_world\n"
            "from driftframe.framework import contact_solve as cs, quiet_step as q\n"
            f"w, _ = make_world({demo!r}, seed=0); w.prepare(); w.step(120)\n"
            "print(*(len(k.signatures) for k in (cs.solve_all_pairs, cs.solve_static, q.gather_quiet)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    return [int(v) for v in out]


def test_a_scene_without_shapes_never_compiles_the_static_solver():
    assert _kernels_called("cradle") == [1, 0, 1]


def test_a_scene_with_shapes_never_calls_the_quiet_step_kernel():
    # no step of a scene with shapes takes the shortest path (its quiet test sees spheres only), so neither
    # prepare() nor a step calls it: billiards' cold compile has no quiet-step kernel in it
    assert _kernels_called("billiards") == [0, 1, 0]


def test_billiards_cushions_keep_every_ball_on_the_table_for_30_s():
    from driftframe.app import make_world
    from driftframe.demos import billiards as table

    world, _ = make_world("billiards", seed=0)
    try:
        cushions = {e for e, _ in esper.get_component(BoxCollider)}
        assert len(cushions) == 4 and not esper.get_component(PlaneCollider)
        seen = hits(world)
        balls = sorted(e for e, _ in esper.get_component(Velocity))
        v0 = np.array([vel(e) for e in balls])
        lo = np.array([table.CENTRE[0] - table.TABLE[0] / 2, table.CENTRE[1] - table.TABLE[1] / 2]) + table.R
        hi = np.array([table.CENTRE[0] + table.TABLE[0] / 2, table.CENTRE[1] + table.TABLE[1] / 2]) - table.R
        worst = -math.inf
        for _ in range(30 * 4):
            world.step(15)
            p = np.array([pos(e) for e in balls])
            worst = max(worst, float(np.max(p[:, [0, 2]] - hi)), float(np.max(lo - p[:, [0, 2]])))
        assert worst <= 1e-9                            # flat cushions: no ball past the felt's edge
        v = np.array([vel(e) for e in balls])
        e0, e1 = 0.5 * (v0 ** 2).sum(), 0.5 * (v ** 2).sum()
        assert abs(e1 - e0) <= 1e-12 * e0               # e = 1 on the cushions and between balls
        off_cushions = [ev for ev in seen if {ev.a, ev.b} & cushions]
        assert len(off_cushions) >= 50                  # the balls do meet the cushions, many times
        assert all(ev.impulse > 0 for ev in off_cushions)
    finally:
        world.close()


def test_a_shape_moved_between_steps_is_met_where_it_is_now(world):
    systems(world)
    wall = world.create_entity(Transform((10.0, 0.0, 0.0)), PlaneCollider(normal=(-1.0, 0.0, 0.0)))
    b = ball(world, (0.0, 0.0, 0.0), (6.0, 0.0, 0.0))
    seen = hits(world)
    world.step(30)                                  # at x = 3 at 0.5 s
    esper.component_for_entity(wall, Transform).position = (4.0, 0.0, 0.0)
    world.step(30)
    (ev,) = seen
    assert ev.time == pytest.approx(0.5 + 0.5 / 6.0, abs=1e-13)    # the face now at x = 4: the centre at 3.5
    assert vel(b)[0] == -6.0


def test_prepare_loads_the_static_solver_and_changes_nothing():
    from driftframe.framework import contact_solve
    from driftframe.framework.world import World

    hashes = []
    for prepare in (False, True):
        world = World()
        systems(world)
        world.create_entity(Transform((0.0, 0.0, 0.0)), BoxCollider(half_extents=(0.2, 3.0, 3.0)))
        world.create_entity(Transform((3.0, 0.0, 0.0)), PlaneCollider(normal=(-1.0, 0.0, 0.0)))
        for k in range(4):
            ball(world, (1.0 + 0.4 * k, 0.1 * k, 0.0), (5.0 - 3.0 * k, 0.5, 0.0), r=0.15, e=0.8)
        if prepare:
            world.prepare()
            assert contact_solve.solve_static.signatures and contact_solve.solve_static_stick.signatures
        world.step(90)
        hashes.append(world.state_hash())
        world.close()
    assert hashes[0] == hashes[1]
