"""Flight aids: every hold and task converges, with bounded angular acceleration, without overshoot."""
import math

import numpy as np
import pytest

from driftframe import (Acceleration, AngularVelocity, ControlSystem, FlightControl, FlightInput, MovementSystem,
                        SpinSystem, Transform, Velocity, World)
from driftframe.components.autopilot import Autopilot
from driftframe.components.gravity import GravityWell
from driftframe.framework import frame as fr
from driftframe.framework import kepler
from driftframe.systems.autopilot import AutopilotSystem, stopping_rate
from driftframe.systems.gravity import GravitySystem

MU = 3.986004418e14
R_EARTH = 6.371e6
ACCEL = 2.0          # rad/s^2


def make(dt=1 / 60):
    w = World(dt=dt)
    for s in (AutopilotSystem(), ControlSystem(), GravitySystem(), MovementSystem(), SpinSystem()):
        w.add_system(s)
    return w


def ship(world, ap, x=(7e6, 0, 0), v=(0, 7.546e3, 0), q=None, w=(0.0, 0.0, 0.0), thrust=10.0):
    q = fr.quat_from_axis_angle([0.3, 1.0, 0.2], 2.0) if q is None else q
    return world.create_entity(Transform(x, q), Velocity(v), AngularVelocity(w), Acceleration(),
                               FlightInput(), FlightControl(thrust=thrust, angular_accel=ACCEL), ap)


def nose(world, e):
    return fr.rotate(world.columns(Transform, [e]).orientation[0], fr.FORWARD)


def spin(world, e):
    return world.columns(AngularVelocity, [e]).angular[0]


def state(world, e):
    return world.columns(Transform, [e]).position[0], world.columns(Velocity, [e]).linear[0]


def test_stopping_rate_lands_exactly_in_whole_steps():
    a, dt = 2.0, 0.1
    for n in (1, 2, 5, 17):
        angle = a * dt * dt * n * (n + 1) / 2
        assert stopping_rate(angle, a, dt) == pytest.approx(a * dt * n, rel=1e-12)
    assert stopping_rate(0.0, a, dt) == 0.0


def run_hold(world, e, want, steps):
    """Step and record the pointing error to ``want()`` and the spin change per step."""
    errs, dws = [], []
    w_prev = spin(world, e)
    for _ in range(steps):
        q_prev = world.columns(Transform, [e]).orientation[0]       # the control acts in this frame
        world.step()
        f, d = nose(world, e), want()
        errs.append(math.atan2(np.linalg.norm(np.cross(f, d)), f @ d))
        w = spin(world, e)
        dws.append(np.abs(fr.rotate(q_prev * [-1, -1, -1, 1], w - w_prev)))
        w_prev = w
    return np.array(errs), np.array(dws)


@pytest.mark.parametrize("mode", ["prograde", "retrograde", "normal", "antinormal", "radial_out", "radial_in"])
def test_orbit_holds_converge_without_overshoot_or_jitter(mode):
    world = make()
    try:
        world.create_entity(Transform(), GravityWell(mu=MU, radius=R_EARTH))
        e = ship(world, Autopilot(mode=mode))
        ap = world.get_system(AutopilotSystem)

        def want():
            x, v = state(world, e)
            return ap.direction(e, mode, None, x, v)
        errs, dws = run_hold(world, e, want, 600)
        assert errs[-1] < 1e-6                                      # there, and ...
        assert np.all(errs[-200:] < 1e-6)                           # ... held (no jitter)
        settle = int(np.argmax(errs < 1e-6))
        assert np.all(np.diff(errs[:settle]) <= 1e-9)              # never turns back: no overshoot
        assert np.all(dws <= ACCEL * world.dt * (1 + 1e-9))         # bounded angular acceleration, per axis
    finally:
        world.close()


def test_target_hold_tracks_a_moving_target_and_anti_target():
    world = make()
    try:
        other = world.create_entity(Transform((100.0, 50.0, -30.0)), Velocity((3.0, -1.0, 2.0)))
        for mode in ("target", "anti_target"):
            e = ship(world, Autopilot(mode=mode, target=other), x=(0, 0, 0), v=(0, 0, 0))
            sign = 1 if mode == "target" else -1

            def want():
                d = state(world, other)[0] - state(world, e)[0]
                return sign * d / np.linalg.norm(d)
            errs, dws = run_hold(world, e, want, 400)
            assert np.all(errs[-100:] < 1e-5)
            settle = int(np.argmax(errs < 1e-5))
            assert np.all(np.diff(errs[:settle]) <= 1e-9)
            assert np.all(dws <= ACCEL * world.dt * (1 + 1e-9))
            world.delete_entity(e)
    finally:
        world.close()


def test_match_velocity_with_a_target():
    world = make()
    try:
        other = world.create_entity(Transform((500.0, 0, 0)), Velocity((12.0, -4.0, 3.0)))
        e = ship(world, Autopilot(mode="match_velocity", target=other, tolerance=0.01), x=(0, 0, 0), v=(0, 0, 0))
        rel = []
        for _ in range(60 * 12):
            world.step()
            rel.append(np.linalg.norm(state(world, e)[1] - state(world, other)[1]))
        ap = world.columns  # noqa: F841
        rel = np.array(rel)
        assert rel[-1] <= 0.01
        assert np.all(np.diff(rel) <= 1e-9)                         # the gap only closes
        assert world.get_system(AutopilotSystem) is not None
    finally:
        world.close()


def test_timed_burn_delivers_its_dv_and_makes_the_hohmann_transfer():
    """A prograde burn of the closed-form Hohmann dv1 raises apoapsis to r2 (finite burn: 1e-3)."""
    r1, r2 = 7e6, 1.2e7
    dv1 = math.sqrt(MU / r1) * (math.sqrt(2 * r2 / (r1 + r2)) - 1)
    world = make(dt=0.1)
    try:
        world.create_entity(Transform(), GravityWell(mu=MU, radius=R_EARTH))
        q = fr.look_rotation([0, 1, 0], [0, 0, 1])
        ap = Autopilot(mode="burn", dv=dv1, along="prograde", at=30.0)
        e = ship(world, ap, x=(r1, 0, 0), v=(0, math.sqrt(MU / r1), 0), q=q, thrust=100.0)
        world.step(int(60 / 0.1))
        assert ap.done
        assert ap.delivered == pytest.approx(dv1, rel=1e-12)
        x, v = state(world, e)
        el = kepler.elements(x, v, MU)
        assert el.apoapsis[0] == pytest.approx(r2, rel=1e-3)
        assert el.periapsis[0] == pytest.approx(r1, rel=1e-3)
    finally:
        world.close()


def test_flip_and_burn_stops_at_the_point_without_passing_it():
    world = make(dt=1 / 30)
    try:
        point = np.array([2000.0, 0, 0])
        ap = Autopilot(mode="flip_and_burn", point=tuple(point), tolerance=0.05)
        e = ship(world, ap, x=(0, 0, 0), v=(0, 3.0, 0), thrust=5.0)
        along = []
        for _ in range(30 * 200):
            world.step()
            along.append(state(world, e)[0][0])
            if ap.done:
                break
        assert ap.done, ap.status
        x, v = state(world, e)
        assert np.linalg.norm(x - point) <= 0.5
        assert np.linalg.norm(v) <= 0.05
        assert max(along) <= point[0] + 0.5                          # never flew past the point
    finally:
        world.close()


# -- bad input ------------------------------------------------------------------------------------
def test_unreachable_targets_are_named():
    world = make()
    try:
        ship(world, Autopilot(mode="target", target=12345))
        with pytest.raises(ValueError, match=r"entity 12345 does not exist.*unreachable"):
            world.step()
    finally:
        world.close()
    world = make()
    try:
        other = world.create_entity(Transform((1.0, 0, 0)), Velocity((1.0, 0, 0)))
        ship(world, Autopilot(mode="match_velocity", target=other), thrust=0.0)
        with pytest.raises(ValueError, match=r"thrust is 0.0.*unreachable"):
            world.step()
    finally:
        world.close()


@pytest.mark.parametrize("kw, match", [
    (dict(mode="sideways"), r"Autopilot.mode must be one of .* got 'sideways'"),
    (dict(mode="target"), r"needs a target entity, got target=None"),
    (dict(mode="burn", dv=0.0), r"burn needs dv > 0 m/s, got 0.0"),
    (dict(mode="burn", dv=-5.0), r"Autopilot.dv must be >= 0, got -5.0"),
    (dict(mode="flip_and_burn"), r"exactly one of target .* or point"),
    (dict(mode="prograde", aim=0.0), r"Autopilot.aim must be > 0"),
    (dict(mode="prograde", point=(1, float("nan"), 0)), r"Autopilot.point must not contain NaN"),
])
def test_bad_autopilot_values_are_named(kw, match):
    with pytest.raises((ValueError, TypeError), match=match):
        Autopilot(**kw)
