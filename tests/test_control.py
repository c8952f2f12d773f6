"""ControlSystem: thrust along the nose; local spin input becomes world spin; direct vs momentum."""
import esper
import numpy as np
import pytest

from driftframe.components.body import Acceleration, AngularVelocity, Transform, Velocity
from driftframe.components.control import FlightControl, FlightInput
from driftframe.framework import frame as fr
from driftframe.systems.control import ControlSystem
from driftframe.systems.movement import MovementSystem
from driftframe.systems.spin import SpinSystem


def _ship(world, mode="momentum", q=None, **ctl):
    for s in (ControlSystem(), MovementSystem(), SpinSystem()):
        world.add_system(s)
    inp = FlightInput()
    e = world.create_entity(Transform(orientation=fr.IDENTITY_QUAT if q is None else q), Velocity(),
                            AngularVelocity(), Acceleration(), inp, FlightControl(mode=mode, **ctl))
    return e, inp


def test_throttle_thrusts_along_the_nose_and_velocity_persists(world):
    q = fr.look_rotation([1.0, 1.0, 0.0])
    e, inp = _ship(world, q=q, thrust=4.0)
    inp.throttle = 1.0
    world.step(60)
    inp.throttle = 0.0
    world.step(60)
    nose = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    np.testing.assert_allclose(esper.component_for_entity(e, Velocity).linear, 4.0 * nose, atol=1e-12)
    # 1 s of thrust (a t^2/2 = 2 m) then 1 s of drifting at 4 m/s
    np.testing.assert_allclose(esper.component_for_entity(e, Transform).position, 6.0 * nose, atol=1e-12)


def test_local_spin_input_is_converted_to_world_for_a_rotated_body(world):
    # body yawed 90 degrees: its forward is world +x, its right is world -z
    q = fr.quat_from_rotvec(np.array([0.0, np.pi / 2, 0.0]))
    e, inp = _ship(world, q=q, angular_accel=2.0)
    inp.roll = 1.0                       # about local forward = world +x
    world.systems["control"][0].process(world.dt)
    np.testing.assert_allclose(esper.component_for_entity(e, AngularVelocity).angular,
                               [2.0 * world.dt, 0, 0], atol=1e-15)
    inp.roll, inp.pitch = 0.0, 1.0       # about local right = world -z
    world.systems["control"][0].process(world.dt)
    np.testing.assert_allclose(esper.component_for_entity(e, AngularVelocity).angular,
                               [2.0 * world.dt, 0, -2.0 * world.dt], atol=1e-15)


def test_momentum_mode_spin_accumulates_and_persists(world):
    e, inp = _ship(world, "momentum", angular_accel=1.0)
    inp.yaw = 1.0
    world.step(30)
    inp.yaw = 0.0
    world.step(30)
    np.testing.assert_allclose(esper.component_for_entity(e, AngularVelocity).angular, [0, 0.5, 0], atol=1e-14)


def test_direct_mode_turns_only_while_input_is_held(world):
    e, inp = _ship(world, "direct", turn_rate=1.5)
    inp.yaw = 1.0
    world.step(60)                        # turns 1.5 rad
    inp.yaw = 0.0
    world.step(60)                        # and stops
    np.testing.assert_allclose(esper.component_for_entity(e, AngularVelocity).angular, 0.0, atol=0)
    np.testing.assert_allclose(esper.component_for_entity(e, Transform).forward,
                               [np.sin(1.5), 0, np.cos(1.5)], atol=1e-13)


@pytest.mark.parametrize("field,value", [("throttle", 1.5), ("roll", float("nan")), ("yaw", -2)])
def test_input_out_of_range_is_rejected_by_name(field, value):
    with pytest.raises(ValueError, match=f"FlightInput.{field}"):
        FlightInput(**{field: value})


def test_unknown_mode_is_rejected_by_name():
    with pytest.raises(ValueError, match="'warp'"):
        FlightControl(mode="warp")


def _turning_burn_error(dt, seconds=4.0, rate=1.0, thrust=5.0):
    """Full thrust while yawing at a constant rate; distance from the continuous solution."""
    from driftframe.framework.world import World
    world = World(dt=dt)
    try:
        e, inp = _ship(world, "direct", turn_rate=rate, thrust=thrust)
        inp.throttle, inp.yaw = 1.0, 1.0
        world.step(round(seconds / dt))
        t, w = seconds, rate
        # nose(t) = (sin wt, 0, cos wt); x(t) = a/w * (t - sin(wt)/w, 0, (1 - cos wt)/w)
        exact = thrust / w * np.array([t - np.sin(w * t) / w, 0.0, (1 - np.cos(w * t)) / w])
        return np.linalg.norm(esper.component_for_entity(e, Transform).position - exact)
    finally:
        world.close()


def test_thrust_while_turning_is_second_order_in_dt():
    coarse, fine = _turning_burn_error(1 / 30), _turning_burn_error(1 / 60)
    assert fine < 2e-3
    assert 3.5 < coarse / fine < 4.5          # halving dt quarters the error


def test_no_throttle_means_no_acceleration(world):
    e, inp = _ship(world, thrust=4.0)
    inp.throttle = 1.0
    world.step()
    inp.throttle = 0.0
    world.step()
    np.testing.assert_array_equal(esper.component_for_entity(e, Acceleration).linear, 0.0)
