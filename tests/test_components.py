"""Body components: validation names the bad value; the frame is exposed as right/up/forward."""
import math

import numpy as np
import pytest

from driftframe.components.body import AngularVelocity, Mass, Transform, Velocity
from driftframe.framework import frame as fr


def test_transform_from_frame_vectors_round_trips():
    r, u, f = fr.quat_to_matrix(fr.quat_from_rotvec(np.array([0.2, -1.0, 0.5]))).T
    t = Transform((1, 2, 3), right=r, up=u, forward=f)
    np.testing.assert_allclose(t.right, r, atol=1e-15)
    np.testing.assert_allclose(t.up, u, atol=1e-15)
    np.testing.assert_allclose(t.forward, f, atol=1e-15)
    np.testing.assert_allclose(np.cross(t.right, t.up), t.forward, atol=1e-15)


def test_default_transform_is_the_identity_frame():
    t = Transform()
    np.testing.assert_array_equal(t.right, [1, 0, 0])
    np.testing.assert_array_equal(t.up, [0, 1, 0])
    np.testing.assert_array_equal(t.forward, [0, 0, 1])


@pytest.mark.parametrize("kw,match", [
    ({"right": (1, 0, 0), "up": (0, 1, 0), "forward": (0, 0.5, 1)}, "not orthonormal"),
    ({"right": (1, 0, 0), "up": (0, 1, 0), "forward": (0, 0, -1)}, "left-handed"),
    ({"right": (1, 0, 0), "up": (0, 1, 0)}, "all three"),
    ({"orientation": (0, 0, 0, 2.0)}, "unit quaternion"),
    ({"orientation": (0, 0, 0, 0.0)}, "unit quaternion"),
    ({"position": (0, float("nan"), 0)}, r"Transform.position must not contain NaN"),
    ({"position": (0, 0, float("inf"))}, r"Transform.position must be finite"),
])
def test_bad_transform_is_rejected_naming_the_value(kw, match):
    with pytest.raises(ValueError, match=match):
        Transform(**kw)


def test_setting_a_non_orthonormal_rotation_is_rejected():
    t = Transform()
    with pytest.raises(ValueError, match="not orthonormal"):
        t.rotation = np.diag([1.0, 2.0, 1.0])
    np.testing.assert_array_equal(t.orientation, fr.IDENTITY_QUAT)   # unchanged


@pytest.mark.parametrize("value", [0.0, -3.0, float("nan")])
def test_bad_mass_is_rejected_naming_the_value(value):
    with pytest.raises(ValueError, match=r"Mass.kg"):
        Mass(value)


def test_infinite_mass_is_an_immovable_body():
    assert Mass(math.inf).inverse == 0.0
    assert Mass(4.0).inverse == 0.25


@pytest.mark.parametrize("cls", [Velocity, AngularVelocity])
def test_non_finite_vectors_are_rejected(cls):
    with pytest.raises(ValueError, match=r"must be finite"):
        cls((0.0, float("-inf"), 0.0))
    obj = cls((1.0, 2.0, 3.0))
    with pytest.raises(ValueError, match=r"NaN"):
        setattr(obj, next(iter(cls._fields)), (float("nan"), 0, 0))


def test_look_rotation_rejects_a_zero_length_axis():
    with pytest.raises(ValueError, match=r"non-zero"):
        fr.look_rotation([0.0, 0.0, 0.0])
