"""Orbit readouts (systems/readouts.py) against closed forms; the HUD draws them (test_hud.py)."""
import math

import numpy as np
import pytest

from driftframe import MovementSystem, Transform, Velocity, World
from driftframe.components.autopilot import Autopilot
from driftframe.components.gravity import GravityWell
from driftframe.framework import warp as time_warp
from driftframe.systems import readouts
from driftframe.systems.gravity import GravitySystem

MU = 3.986004418e14
R = 6.371e6


@pytest.fixture
def world():
    w = World(dt=1.0)
    w.add_system(GravitySystem())
    w.add_system(MovementSystem())
    yield w
    w.close()


def test_apoapsis_periapsis_period_and_times_match_the_closed_form(world):
    well = world.create_entity(Transform((1e3, 0, 0)), GravityWell(mu=MU, radius=R))
    a, e = 1.0e7, 0.25
    rp = a * (1 - e)
    ship = world.create_entity(Transform((1e3 + rp, 0, 0)), Velocity((0, math.sqrt(MU * (1 + e) / rp), 0)))
    world.step(1)
    o = readouts.orbit(world, ship)
    P = 2 * math.pi * math.sqrt(a ** 3 / MU)
    assert o.well == well
    assert o.periapsis == pytest.approx(rp - R, rel=1e-9)
    assert o.apoapsis == pytest.approx(a * (1 + e) - R, rel=1e-9)
    assert o.period == pytest.approx(P, rel=1e-12)
    assert o.time_to_periapsis == pytest.approx(P - 1.0, rel=1e-9)
    assert o.time_to_apoapsis == pytest.approx(P / 2 - 1.0, rel=1e-9)
    assert math.isinf(o.time_to_impact)
    text = readouts.lines(world, ship)
    assert any(t.startswith("APO") and "km" in t for t in text)
    assert any(t.startswith("PERIOD") for t in text)


def test_impact_warning_and_closest_approach_to_the_target(world):
    world.create_entity(Transform(), GravityWell(mu=MU, radius=R))
    from driftframe.framework import kepler
    r1 = 7e6
    vc = math.sqrt(MU / r1)
    P = 2 * math.pi * math.sqrt(r1 ** 3 / MU)
    # the station on a circle, the ship on an ellipse touching it at periapsis; both set back by 0.1 P
    rs, vs = kepler.propagate([r1, 0, 0], [0, vc, 0], MU, -0.1 * P - 1.0)
    rq, vq = kepler.propagate([r1, 0, 0], [0, vc * 1.05, 0], MU, -0.1 * P - 1.0)
    station = world.create_entity(Transform(rs), Velocity(vs))
    ship = world.create_entity(Transform(rq), Velocity(vq), Autopilot(mode="target", target=station))
    world.step(1)
    t, d = readouts.closest_approach(world, ship, station)
    assert t == pytest.approx(0.1 * P, rel=1e-6)
    assert d < 1e-2
    text = readouts.lines(world, ship)
    assert any(line.startswith("CLOSEST") for line in text)
    faller = world.create_entity(Transform((2e7, 0, 0)), Velocity((-5e3, 100.0, 0)))
    world.step(1)
    o = readouts.orbit(world, faller)
    assert np.isfinite(o.time_to_impact) and o.time_to_impact > 0
    assert any(line.startswith("IMPACT") for line in readouts.lines(world, faller))


def test_predicted_orbit_is_the_conic_about_the_well(world):
    world.create_entity(Transform((0, 0, 5e6)), GravityWell(mu=MU, radius=R))
    ship = world.create_entity(Transform((8e6, 0, 5e6)), Velocity((0, 8e3, 0)))
    world.step(1)
    pts = readouts.predicted_orbit(world, ship, 64)
    el = readouts.orbit(world, ship)
    d = np.linalg.norm(pts - [0, 0, 5e6], axis=1)
    assert d.min() >= el.periapsis + R - 1.0 and d.max() <= el.apoapsis + R + 1.0


def test_without_a_well_there_are_no_orbit_lines(world):
    ship = world.create_entity(Transform(), Velocity((1, 0, 0)))
    world.step(1)
    assert readouts.orbit(world, ship) is None
    assert readouts.predicted_orbit(world, ship) is None
    assert readouts.lines(world, ship) == []


def test_the_warp_line_says_why_it_dropped(world):
    ship = world.create_entity(Transform(), Velocity((1, 0, 0)))
    warp = time_warp.of(world)
    warp.request(10_000)
    warp.limit, warp.reason = 10, "burn of 5.0 m/s in 40 s"
    assert readouts.lines(world, ship) == ["WARP    x10,000\u2192x10: burn of 5.0 m/s in 40 s"]
