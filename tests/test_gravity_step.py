"""The gravity system's step context: the step's length is the dt the world gives, at any step count."""
import numpy as np
import pytest

from driftframe import Acceleration, MovementSystem, Transform, Velocity, World
from driftframe.components.gravity import GravityWell
from driftframe.systems.gravity import GravitySystem

DT = 1.0 / 60.0
LATE = 10**8          # 1e8 steps of 1/60 s (19 days at 100,000x warp): (k + 1) dt - k dt is 3.7e-9 off dt


def _burn(step_count: int, a: float = 2.0):
    """One thrusting step on rails about a well too weak to matter (mu 1e-30: the flow is free flight
    to the last bit), taken at ``step_count``; returns the world and the ship."""
    w = World(dt=DT)
    w.add_system(MovementSystem())
    w.add_system(GravitySystem())
    w.create_entity(Transform(position=np.zeros(3)), GravityWell(mu=1e-30, radius=1.0))
    ship = w.create_entity(Transform(position=np.array([1.0e6, 0.0, 0.0])), Velocity(linear=np.zeros(3)),
                           Acceleration(linear=np.array([0.0, 0.0, a])))
    w.step_count = step_count
    w.step()
    return w, ship


@pytest.mark.parametrize("step_count", [0, 7, LATE])
def test_a_burn_on_rails_adds_exactly_a_dt_at_any_step_count(step_count):
    # the two half kicks are a dt / 2 each with the step's own dt: t1 - t0 would give a (t1 - t0), which
    # at LATE differs from a dt in the 9th digit
    w, ship = _burn(step_count)
    try:
        v = w.columns(Velocity, [ship]).linear[0]
        assert v[2] == 2.0 * DT
        t0, t1 = step_count * DT, (step_count + 1) * DT
        if step_count == LATE:
            assert t1 - t0 != DT                      # (the case the context exists for: this test can fail)
    finally:
        w.close()


def test_the_step_context_holds_the_times_and_the_dt_as_given():
    w, _ = _burn(LATE)
    try:
        step = w.get_system(GravitySystem)._last_step
        assert (step.t0, step.t1, step.dt) == (LATE * DT, (LATE + 1) * DT, DT)
    finally:
        w.close()
