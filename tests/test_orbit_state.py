"""The OrbitState resource: the gravity system publishes what it knows of the orbits, keyed by the type,
and the flight aids, the warp governor and the readouts read it instead of importing the gravity system."""
import ast
import math
from pathlib import Path

import numpy as np
import pytest

from driftframe import MovementSystem, Transform, Velocity, World
from driftframe.components.gravity import GravityWell
from driftframe.framework import warp as time_warp
from driftframe.framework.orbit_state import ContactAhead, OrbitState, Reference, SurfaceAhead
from driftframe.systems import readouts
from driftframe.systems.autopilot import AutopilotSystem
from driftframe.systems.gravity import GravitySystem
from driftframe.systems.warp import WarpGovernorSystem

ROOT = Path(__file__).resolve().parent.parent
MU = 3.986004418e14
R = 6.371e6


def test_the_gravity_system_publishes_its_orbit_state_when_added_and_takes_it_back_when_removed():
    w = World(dt=1.0)
    try:
        assert OrbitState not in w.resources
        g = w.add_system(GravitySystem())
        orbits = w.resources[OrbitState]
        assert isinstance(orbits, OrbitState)
        w.remove_system(g)
        assert OrbitState not in w.resources
    finally:
        w.close()


def test_the_reference_is_the_moving_well_before_the_first_step_and_after_it():
    # the flight aids run before gravity in the step: the resource answers from the wells' components
    w = World(dt=1.0)
    try:
        w.add_system(MovementSystem())
        w.add_system(GravitySystem())
        planet = w.create_entity(Transform((1e3, 2e3, 3e3)), Velocity((10.0, 0.0, 0.0)), GravityWell(mu=MU, radius=R))
        ship = w.create_entity(Transform((7e6, 0.0, 0.0)), Velocity((0.0, 7.5e3, 0.0)))
        orbits = w.resources[OrbitState]
        for _ in range(2):
            ref = orbits.reference(ship)
            x = w.columns(Transform, [planet]).position[0]
            assert isinstance(ref, Reference)
            assert (ref.well, ref.mu, ref.radius) == (planet, MU, R)
            assert np.array_equal(ref.position, x) and np.array_equal(ref.velocity, [10.0, 0.0, 0.0])
            assert orbits.reference(planet) is None                       # a root well moves about nothing
            w.step()
    finally:
        w.close()


def test_the_next_surface_contact_is_the_one_the_step_then_finds():
    w = World(dt=10.0)
    try:
        w.add_system(MovementSystem())
        w.add_system(GravitySystem())
        planet = w.create_entity(Transform(), GravityWell(mu=MU, radius=R))
        rock = w.create_entity(Transform((2e7, 0.0, 0.0)), Velocity((-3e3, 0.0, 0.0)))
        w.step()
        ahead = w.resources[OrbitState].next_contact()
        assert isinstance(ahead, SurfaceAhead) and (ahead.entity, ahead.well) == (rock, planet)
        from driftframe.components.gravity import SurfaceContact
        hits = []
        w.subscribe(SurfaceContact, hits.append)
        while not hits:
            w.step()
        assert hits[0].time == pytest.approx(ahead.time, rel=1e-12)
    finally:
        w.close()


class _Stub(OrbitState):
    """An OrbitState that is not the gravity system's: what the readers need is the resource, nothing more."""

    def __init__(self, well_at: np.ndarray, contact_at: float) -> None:
        self.well_at, self.contact_at = well_at, contact_at

    def reference(self, entity: int) -> Reference | None:
        return Reference(99, MU, R, self.well_at, np.zeros(3))

    def next_contact(self) -> SurfaceAhead | None:
        return SurfaceAhead(self.contact_at, 7, 99)

    def next_sphere_contact(self, horizon: float) -> ContactAhead | None:
        return ContactAhead(self.contact_at - 1.0, 3, 4, bound=True)


def test_the_warp_governor_and_the_readouts_read_the_resource_not_a_system():
    w = World(dt=1.0)
    try:
        w.add_system(WarpGovernorSystem(lead_frames=3))
        w.resources[OrbitState] = _Stub(np.array([1e7, 0.0, 0.0]), contact_at=100.0)
        ship = w.create_entity(Transform((1e7 + 7e6, 0.0, 0.0)), Velocity((0.0, 7.5e3, 0.0)))
        warp = time_warp.of(w)
        warp.request(1000)
        w.step()
        # now = 1 s: the stub's pair "may touch" at 99 s comes first; frames of 3 steps at 32x reach 96 s
        assert warp.limit is not None and warp.limit * 3 <= 98.0
        assert "entities 3 and 4 may touch" in warp.reason
        o = readouts.orbit(w, ship)
        assert o is not None and o.well == 99
        assert o.altitude == pytest.approx(7e6 - R)
    finally:
        w.close()


def test_the_autopilot_flies_prograde_relative_to_the_resources_well():
    from driftframe.components.autopilot import Autopilot

    w = World(dt=1.0)
    try:
        ap = w.add_system(AutopilotSystem())
        w.resources[OrbitState] = _Stub(np.array([0.0, 0.0, 0.0]), contact_at=math.inf)
        ship = w.create_entity(Transform((7e6, 0.0, 0.0)), Velocity((0.0, 7.5e3, 0.0)))
        x, v = np.array([7e6, 0.0, 0.0]), np.array([0.0, 7.5e3, 0.0])
        d = ap.direction(ship, "prograde", Autopilot(), x, v)
        assert np.allclose(d, [0.0, 1.0, 0.0])
        w.resources[OrbitState] = _Stub(np.array([0.0, 0.0, 0.0]), contact_at=math.inf)
        w.resources[OrbitState].reference = lambda e: Reference(99, MU, R, np.zeros(3), np.array([0.0, 7.5e3, 1.0]))
        d = ap.direction(ship, "prograde", Autopilot(), x, v)              # relative to a well moving with it
        assert np.allclose(d, [0.0, 0.0, -1.0])
    finally:
        w.close()


@pytest.mark.parametrize("path", ["systems/autopilot.py", "systems/warp.py", "systems/readouts.py"])
def test_the_readers_of_the_orbits_import_no_system(path):
    tree = ast.parse((ROOT / path).read_text())
    imported = [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module] + \
               [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert [m for m in imported if m.startswith("driftframe.systems")] == []
