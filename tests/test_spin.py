"""SpinSystem: exact rotation about the world spin axis; orthonormal forever; idle bodies untouched."""
import esper
import numpy as np
import pytest

from driftframe.components.body import AngularVelocity, Transform
from driftframe.framework import frame as fr
from driftframe.systems.spin import SpinSystem


def _spin_world(world, w, q=None):
    world.add_system(SpinSystem())
    return world.create_entity(Transform(orientation=fr.IDENTITY_QUAT if q is None else q), AngularVelocity(w))


def test_rotates_by_w_dt_about_the_world_axis(world):
    e = _spin_world(world, (0.0, 2.0, 0.0))          # yaw, 2 rad/s about world up
    world.step(30)                                     # 0.5 s -> 1 rad
    tf = esper.component_for_entity(e, Transform)
    np.testing.assert_allclose(tf.forward, [np.sin(1.0), 0.0, np.cos(1.0)], atol=1e-14)
    np.testing.assert_allclose(tf.up, [0, 1, 0], atol=1e-15)


def test_axis_is_world_not_local_for_a_rotated_body(world):
    q = fr.quat_from_rotvec(np.array([np.pi / 2, 0, 0]))   # pitched 90 degrees: forward -> -y
    w = np.array([0.0, 0.0, 1.0])                            # spin about world z
    e = _spin_world(world, w, q)
    world.step(60)
    expected = fr.axis_angle_matrix(np.array([0, 0, 1.0]), 1.0) @ fr.quat_to_matrix(q)
    np.testing.assert_allclose(esper.component_for_entity(e, Transform).rotation, expected, atol=1e-14)


@pytest.mark.parametrize("angle", [np.pi - 1e-3, np.pi, 1.5 * np.pi, 5.0])
def test_exact_for_steps_larger_than_small_angle_methods_allow(world, angle):
    axis = np.array([1.0, 2.0, -2.0]) / 3.0
    world.dt = 1.0
    e = _spin_world(world, axis * angle)
    world.step()
    np.testing.assert_allclose(esper.component_for_entity(e, Transform).rotation,
                               fr.axis_angle_matrix(axis, angle), atol=1e-14)


def test_bodies_with_zero_spin_are_not_touched(world):
    world.add_system(SpinSystem())
    q = np.array([0.1, 0.2, 0.3, 0.0])
    q /= np.linalg.norm(q)
    still = world.create_entity(Transform(orientation=q), AngularVelocity((0.0, 0.0, 0.0)))
    moving = world.create_entity(Transform(orientation=q), AngularVelocity((0.0, 0.0, 1.0)))
    before = esper.component_for_entity(still, Transform).orientation.copy()
    world.step(100)
    assert esper.component_for_entity(still, Transform).orientation.tobytes() == before.tobytes()
    assert not np.allclose(esper.component_for_entity(moving, Transform).orientation, before)


@pytest.mark.slow
def test_frames_stay_orthonormal_and_headings_match_exact_rotation_over_a_long_run():
    """64 bodies, one batch through the real system: 50,000 steps of dt = 1/60 s, 3.2 million body-steps.

    Axes random; |w| from 1e-3 to 400 rad/s, so |w| dt from 1.7e-5 rad (the sin(x)/x series branch) to
    6.7 rad (above pi). The fastest body turns 3.3e5 rad, twice the 1.7e5 rad of one body at 10 rad/s for a
    million steps. Its heading error grows with the angle turned (the rounding of |w| dt, each step, adds
    up): 4.3e-11 rad here, asserted below 1e-10, so a bias of 2e-15 rad a step would fail.
    """
    from driftframe.framework.world import World

    rng = np.random.default_rng(7)
    axes = rng.normal(size=(64, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    rates = np.geomspace(1e-3, 400.0, 64)                      # rad/s
    world = World(dt=1.0 / 60.0)
    try:
        world.add_system(SpinSystem())
        ents = [world.create_entity(Transform(), AngularVelocity(a * r)) for a, r in zip(axes, rates)]
        steps, worst = 50_000, 0.0
        for _ in range(10):
            world.step(steps // 10)
            worst = max(worst, *(float(fr.orthonormality_error(esper.component_for_entity(e, Transform).rotation))
                                 for e in ents))
        assert worst < 1e-12, worst
        two_pi = 8 * np.arctan(np.longdouble(1.0))             # 2 pi to 64 bits (float64's 2 pi is off by 2.4e-16)
        for e in ents:
            w = esper.component_for_entity(e, AngularVelocity).angular.astype(np.longdouble)
            speed = np.sqrt(np.sum(w * w))
            # exact heading: one rotation by the total angle |w| dt n, reduced mod 2 pi in extended precision
            total = float(np.fmod(speed * np.longdouble(world.dt) * steps, two_pi))
            exact = fr.axis_angle_matrix((w / speed).astype(np.float64), total)
            rel = exact.T @ esper.component_for_entity(e, Transform).rotation
            # small angle from the skew part: sin(theta) = |vee(rel - rel^T)| / 2 (arccos loses digits near 1)
            skew = rel - rel.T
            err_angle = 0.5 * np.linalg.norm([skew[2, 1], skew[0, 2], skew[1, 0]])
            assert err_angle < 1e-10, (float(speed), err_angle)
    finally:
        world.close()
