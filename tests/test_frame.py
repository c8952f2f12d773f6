"""Frame math: quaternion and matrix forms agree; conversions round-trip at every angle."""
import numpy as np
import pytest

from driftframe.framework import frame as fr

rng = np.random.default_rng(7)
ROTVECS = rng.normal(size=(200, 3)) * rng.uniform(0, 3.2, size=(200, 1))


def test_quaternion_and_rodrigues_agree():
    angles = np.linalg.norm(ROTVECS, axis=1)
    axes = ROTVECS / angles[:, None]
    np.testing.assert_allclose(fr.quat_to_matrix(fr.quat_from_rotvec(ROTVECS)),
                               fr.axis_angle_matrix(axes, angles), atol=1e-14)


def test_matrix_to_quat_round_trips_including_near_pi():
    special = np.array([[np.pi, 0, 0], [0, np.pi - 1e-12, 0], [0, 0, 1e-9], [1, 1, 1.0]])
    q = fr.quat_from_rotvec(np.vstack([ROTVECS, special]))
    back = fr.matrix_to_quat(fr.quat_to_matrix(q))
    # q and -q are the same rotation
    same = np.minimum(np.abs(back - q).max(axis=1), np.abs(back + q).max(axis=1))
    assert same.max() < 1e-13


def test_rotate_matches_matrix_product():
    q = fr.quat_from_rotvec(ROTVECS)
    v = rng.normal(size=(200, 3))
    np.testing.assert_allclose(fr.rotate(q, v), np.einsum("nij,nj->ni", fr.quat_to_matrix(q), v), atol=1e-14)


def test_composition_order_is_world_increment_on_the_left():
    a, b = fr.quat_from_rotvec(ROTVECS[:2])
    np.testing.assert_allclose(fr.quat_to_matrix(fr.quat_multiply(a, b)),
                               fr.quat_to_matrix(a) @ fr.quat_to_matrix(b), atol=1e-14)


def test_small_angle_series_is_continuous():
    for theta in (1e-5, 9.99e-5, 1.0001e-4, 1e-3):
        q = fr.quat_from_rotvec(np.array([theta, 0, 0]))
        np.testing.assert_allclose(q, [np.sin(theta / 2), 0, 0, np.cos(theta / 2)], rtol=1e-15, atol=1e-19)


def test_local_axes_follow_the_right_hand_rule():
    yaw = fr.quat_from_axis_angle(fr.UP, 0.1)
    assert fr.rotate(yaw, fr.FORWARD)[0] > 0            # positive yaw turns the nose towards right
    pitch = fr.quat_from_axis_angle(fr.RIGHT, 0.1)
    assert fr.rotate(pitch, fr.FORWARD)[1] < 0          # positive pitch: nose down
    roll = fr.quat_from_axis_angle(fr.FORWARD, 0.1)
    assert fr.rotate(roll, fr.RIGHT)[1] > 0             # positive roll: right wing up
    np.testing.assert_array_equal(np.cross(fr.RIGHT, fr.UP), fr.FORWARD)


def test_look_rotation_points_forward_and_keeps_up_near_the_hint():
    q = fr.look_rotation([3.0, 0.0, 4.0])
    m = fr.quat_to_matrix(q)
    np.testing.assert_allclose(m[:, 2], [0.6, 0, 0.8], atol=1e-15)
    np.testing.assert_allclose(m[:, 1], [0, 1, 0], atol=1e-15)
    straight_up = fr.quat_to_matrix(fr.look_rotation([0, 1.0, 0]))
    assert fr.orthonormality_error(straight_up) < 1e-15


@pytest.mark.parametrize("axis,match", [((0, 0, 0), "non-zero length"), ((np.nan, 0, 1), "NaN"),
                                         ((np.inf, 0, 0), "finite")])
def test_bad_axis_is_rejected_naming_the_value(axis, match):
    with pytest.raises(ValueError, match=match):
        fr.quat_from_axis_angle(axis, 1.0)


def test_the_one_slerp_halves_the_angle_takes_the_short_way_and_is_exact_near_equal():
    from driftframe.framework.frame import quat_from_axis_angle, slerp

    q0 = quat_from_axis_angle((0.0, 0.0, 1.0), 0.0)
    q1 = quat_from_axis_angle((0.0, 0.0, 1.0), 1.2)
    half = slerp(q0, q1, 0.5)                                     # one pair: (4,) in, (4,) out
    assert half.shape == (4,)
    np.testing.assert_allclose(half, quat_from_axis_angle((0.0, 0.0, 1.0), 0.6), atol=1e-15)
    np.testing.assert_allclose(slerp(q0, -q1, 0.5), half, atol=1e-15)        # -q1 is q1: the short way
    rows = slerp(np.stack([q0, q1]), np.stack([q1, q0]), 0.25)                # row by row
    np.testing.assert_allclose(rows[0], quat_from_axis_angle((0.0, 0.0, 1.0), 0.3), atol=1e-15)
    np.testing.assert_allclose(rows[1], quat_from_axis_angle((0.0, 0.0, 1.0), 0.9), atol=1e-15)
    tiny = quat_from_axis_angle((1.0, 0.0, 0.0), 4e-7)                          # the lerp fallback
    np.testing.assert_allclose(slerp(q0, tiny, 0.5), quat_from_axis_angle((1.0, 0.0, 0.0), 2e-7), atol=1e-16)
