"""RotationAssistSystem: kill rotation at bounded deceleration, exactly to zero, no overshoot."""
import esper
import numpy as np
import pytest

from driftframe.components.body import AngularVelocity, Transform
from driftframe.components.control import FlightInput, RotationAssist
from driftframe.framework import frame as fr
from driftframe.systems.assist import RotationAssistSystem
from driftframe.systems.spin import SpinSystem


def _spinner(world, w, axes, decel=2.0, q=None):
    world.add_system(RotationAssistSystem())
    world.add_system(SpinSystem())
    inp = FlightInput(kill_rotation=True)
    e = world.create_entity(Transform(orientation=fr.IDENTITY_QUAT if q is None else q),
                            AngularVelocity(w), inp, RotationAssist(max_decel=decel, axes=axes))
    return e, inp


def _run(world, e, steps):
    """World spin after each step, and the same spin in the body's local axes (pitch, yaw, roll)."""
    rates, local = [], []
    for _ in range(steps):
        world.step()
        w = esper.component_for_entity(e, AngularVelocity).angular.copy()
        q = esper.component_for_entity(e, Transform).orientation
        rates.append(w)
        local.append(fr.rotate(q * np.array([-1, -1, -1, 1.0]), w))
    return np.array(rates), np.array(local)


def test_all_axes_reaches_exactly_zero_at_bounded_rate_without_overshoot(world):
    w0 = np.array([0.3, -1.2, 0.4])
    e, _ = _spinner(world, w0, "all", decel=2.0)
    rates, _ = _run(world, e, 120)
    mags = np.linalg.norm(rates, axis=1)
    # |w| falls by exactly decel*dt per step until it is smaller than that, then is exactly 0
    steps_needed = int(np.ceil(np.linalg.norm(w0) / (2.0 * world.dt)))
    assert np.all(rates[steps_needed - 1:] == 0.0)
    assert np.all(rates[steps_needed - 2] != 0.0)
    drops = -np.diff(np.r_[np.linalg.norm(w0), mags])
    assert drops.max() <= 2.0 * world.dt * (1 + 1e-12)
    # direction never flips: the spin only shrinks along itself
    nz = mags > 0
    np.testing.assert_allclose(rates[nz] / mags[nz, None], np.tile(w0 / np.linalg.norm(w0), (nz.sum(), 1)),
                               atol=1e-12)


@pytest.mark.parametrize("axis,index", [("pitch", 0), ("yaw", 1), ("roll", 2)])
def test_one_local_axis_is_removed_and_the_others_kept(world, axis, index):
    q = fr.quat_from_rotvec(np.array([0.3, -0.7, 0.2]))
    local0 = np.array([0.5, -0.8, 1.1])
    e, _ = _spinner(world, fr.rotate(q, local0), axis, decel=1.0, q=q)
    _, local = _run(world, e, 120)
    expected = local0.copy()
    expected[index] = 0.0
    np.testing.assert_allclose(local[-1], expected, atol=1e-12)
    # the braked component moved monotonically towards zero by at most decel*dt a step, never past it
    comps = np.r_[local0[index], local[:, index]] * np.sign(local0[index])
    assert np.all(comps >= -1e-14)
    steps = -np.diff(comps)
    assert np.all(steps >= -1e-14) and np.all(steps <= 1.0 * world.dt + 1e-14)


def test_sequential_brakes_roll_then_pitch_then_yaw(world):
    local0 = np.array([0.4, 0.4, 0.4])                    # pitch, yaw, roll
    e, _ = _spinner(world, local0, "sequential", decel=1.2)
    _, local = _run(world, e, 90)
    # after 1/3 s (20 steps at 1.2 rad/s^2) roll is gone while pitch and yaw are untouched
    np.testing.assert_allclose(local[19], [0.4, 0.4, 0.0], atol=1e-12)
    np.testing.assert_allclose(local[39], [0.0, 0.4, 0.0], atol=1e-12)
    np.testing.assert_allclose(local[-1], [0.0, 0.0, 0.0], atol=1e-12)


def test_assist_does_nothing_unless_engaged(world):
    e, inp = _spinner(world, (0, 1.0, 0), "all")
    inp.kill_rotation = False
    world.step(10)
    np.testing.assert_array_equal(esper.component_for_entity(e, AngularVelocity).angular, [0, 1.0, 0])


@pytest.mark.parametrize("kw,match", [({"max_decel": 0}, "max_decel"), ({"max_decel": float("inf")}, "max_decel"),
                                      ({"axes": "x"}, "'x'")])
def test_bad_assist_settings_are_rejected_by_name(kw, match):
    with pytest.raises(ValueError, match=match):
        RotationAssist(**kw)
