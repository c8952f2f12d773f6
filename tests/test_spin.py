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
def test_frame_stays_orthonormal_for_a_million_steps_and_heading_matches_exact():
    """|w| = 10 rad/s, dt = 1/60, 1,000,000 steps through the real system (one body).

    The whole loop runs the system's process() directly to keep the test near 30 s.
    """
    from driftframe.framework.world import World

    world = World(dt=1.0 / 60.0)
    try:
        axis = np.array([0.48, -0.6, 0.64])
        w = 10.0 * axis
        e = _spin_world(world, w)
        system = world.systems["spin"][0]
        dt = world.dt
        worst = 0.0
        for chunk in range(10):
            for _ in range(100_000):
                system.process(dt)
            m = esper.component_for_entity(e, Transform).rotation
            worst = max(worst, float(fr.orthonormality_error(m)))
        assert worst < 1e-12, worst
        steps = 1_000_000
        # exact heading: one rotation by the total angle (reduced mod 2 pi in extended precision)
        total = float(np.fmod(np.longdouble(10.0) * steps / np.longdouble(60.0), 2 * np.pi))
        exact = fr.axis_angle_matrix(axis, total)
        rel = exact.T @ esper.component_for_entity(e, Transform).rotation
        # small angle from the skew part: sin(theta) = |vee(rel - rel^T)| / 2 (arccos loses digits near 1)
        skew = rel - rel.T
        err_angle = 0.5 * np.linalg.norm([skew[2, 1], skew[0, 2], skew[1, 0]])
        assert err_angle < 1e-9, err_angle
    finally:
        world.close()
