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


def test_a_timed_burn_on_rails_delivers_its_dv_late_in_a_run():
    # the autopilot's throttle plan assumes a dt per step; the gravity system's kicks now give exactly that
    # (with t1 - t0 the burn below came out 5.8e-10 m/s long at step 1e7, against 8.5e-13 at step 0)
    from driftframe import AngularVelocity, ControlSystem, FlightControl, FlightInput, SpinSystem
    from driftframe.components.autopilot import Autopilot
    from driftframe.framework import frame as fr
    from driftframe.systems.autopilot import AutopilotSystem

    dt, k0 = 0.1, 10**7
    w = World(dt=dt)
    for s in (AutopilotSystem(), ControlSystem(), GravitySystem(), MovementSystem(), SpinSystem()):
        w.add_system(s)
    try:
        w.create_entity(Transform(), GravityWell(mu=1e-30, radius=1.0))           # on rails, nothing pulls
        ap = Autopilot(mode="burn", dv=50.0, along="prograde", at=k0 * dt + 1.0)
        ship = w.create_entity(Transform((1e6, 0, 0), fr.look_rotation([0, 1, 0], [0, 0, 1])),
                               Velocity((0, 100.0, 0)), AngularVelocity(), Acceleration(), FlightInput(),
                               FlightControl(thrust=7.0, angular_accel=1.0), ap)
        w.step_count = k0
        w.step(200)
        assert ap.done
        speed = float(np.linalg.norm(w.columns(Velocity, [ship]).linear[0]))
        assert abs(speed - 150.0) < 1e-11
    finally:
        w.close()


def _rails_run(quiet: bool, monkeypatch):
    """100 bodies on rails (circles to e = 0.99, hyperbolas) about a moving well for 80 steps, one of them
    thrusting for a few and one moved by hand; the states after each step, and the quiet steps taken."""
    taken = []
    real, real_tables = GravitySystem._quiet, GravitySystem._quiet_from_tables

    def spy(self, step):
        took = real(self, step) if quiet else False
        taken.append(took)
        return took

    def spy_tables(self, dt):                     # (the quiet step straight from the tables, before _begin)
        step = real_tables(self, dt) if quiet else None
        if step is not None:
            taken.append(2)                       # (2: taken from the tables; 1 / True: by _quiet)
        return step
    monkeypatch.setattr(GravitySystem, "_quiet", spy)
    monkeypatch.setattr(GravitySystem, "_quiet_from_tables", spy_tables)
    rng = np.random.default_rng(4)
    n = 100
    rp = rng.uniform(1.5, 3.0, n)
    e = np.concatenate([rng.uniform(0.0, 0.99, n - 10), rng.uniform(1.1, 4.0, 10)])
    x = np.zeros((n, 3))
    x[:, 0] = rp
    v = np.zeros((n, 3))
    v[:, 1] = np.sqrt((1 + e) / rp)
    v[:, 2] = 0.01 * v[:, 1]
    X, V = np.array([1.0, -2.0, 0.5]), np.array([0.01, 0.02, -0.03])
    w = World(dt=0.05)
    w.add_system(MovementSystem())
    w.add_system(GravitySystem())
    w.create_entity(Transform(position=X), Velocity(linear=V), GravityWell(mu=1.0, radius=0.5))
    ents = w.create_entities(Transform.bulk(n, position=x + X), Velocity.bulk(n, linear=v + V))
    states = []
    try:
        for k in range(80):
            if k == 30:
                w.add_component(int(ents[3]), Acceleration(linear=np.array([1e-3, 0.0, 0.0])))
            if k == 33:
                w.remove_component(int(ents[3]), Acceleration)
            if k == 50:
                w.table(Transform).data["position"][5] += 1e-3
            w.step()
            states.append((w.table(Transform).data["position"][:n + 1].copy(),
                           w.table(Velocity).data["linear"][:n + 1].copy()))
    finally:
        w.close()
    return states, taken


def test_the_quiet_step_on_rails_gives_the_stages_bits(monkeypatch):
    # one compiled pass (the guess, the solution, the move to the well's frame) where the stages would only
    # propagate: the same bits step after step, and the stages again for a thrust and a body moved by hand
    quiet, taken = _rails_run(True, monkeypatch)
    staged, _ = _rails_run(False, monkeypatch)
    assert sum(map(bool, taken)) >= 70 and not all(taken)
    assert taken.count(2) >= 60                    # most of them straight from the tables, in one call
    for (xq, vq), (xs, vs) in zip(quiet, staged):
        assert xq.tobytes() == xs.tobytes() and vq.tobytes() == vs.tobytes()
