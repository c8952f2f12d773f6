"""The gravity system's n-body bodies: close encounters of bodies on their conics about a well (the hybrid
split of framework/mercurius.py in systems/gravity/nbody.py), and NBody bodies with colliders and without
a well.

The encounter scene: a well of Earth's mu and two NBody bodies of 1e-3 of its mass that pass 0.02 of their
orbit's radius apart (0.3 Hill radii), built as tests/test_mercurius.py's scene, scaled to a 42,000 km orbit.
The reference is the adaptive integrator itself on the whole problem about the fixed well (critical radii so
large that no pull is kicked: every pull is integrated, to 1e-14 a step).
"""
import math

import numpy as np
import pytest

from driftframe import CollisionSystem, Mass, MovementSystem, SphereCollider, Transform, Velocity, World
from driftframe.components.collision import CollisionEvent
from driftframe.components.gravity import G, GravityWell, NBody
from driftframe.framework import encounters
from driftframe.framework import wisdom_holman as wh
from driftframe.systems.gravity import GravitySystem
from driftframe.systems.gravity.nbody import NBodyFlight

MU, R0, R_SURF = 3.986004418e14, 4.2e7, 6.4e6
T0 = math.sqrt(R0 ** 3 / MU)                          # s: the time unit (the inner orbit's period is 2 pi T0)


def close_pass(d=0.02):
    X = np.array([[1.0, 0.0, 0.0], [1.0 + d, 0.0, 0.3 * d]])
    V = np.array([[0.0, 1.0, 0.0], [0.2, 1.1, 0.0]])
    wh.kepler_drift(X, V, 1.0, -1.5)
    return X * R0, V * (R0 / T0)


def fly(steps, T=3.0):
    """The pass in the gravity system: (worst relative energy error over the steps, final positions)."""
    X, V = close_pass()
    gm = 1e-3 * MU
    with World(dt=T * T0 / steps) as w:
        w.add_system(GravitySystem())
        w.add_system(MovementSystem())
        w.create_entity(Transform(), GravityWell(mu=MU, radius=R_SURF))
        ents = [w.create_entity(Transform(tuple(X[k])), Velocity(tuple(V[k])), Mass(gm / G), NBody()) for k in range(2)]

        def energy():
            x = w.columns(Transform, ents).position
            v = w.columns(Velocity, ents).linear
            return (0.5 * gm * float(np.sum(v * v)) - float(np.sum(gm * MU / np.linalg.norm(x, axis=1)))
                    - gm * gm / float(np.linalg.norm(x[1] - x[0])))
        e0, worst = energy(), 0.0
        for _ in range(steps):
            w.step()
            worst = max(worst, abs(energy() / e0 - 1.0))
        return worst, w.columns(Transform, ents).position.copy()


def reference(T=3.0):
    X, V = close_pass()
    assert encounters.bulirsch_stoer(X, V, np.full(2, 1e-3 * MU), np.full(2, 1e300), MU, T * T0, 1e-14) > 0
    return X


def test_a_close_pass_of_two_nbody_bodies_about_a_well_keeps_the_energy_and_converges():
    ref = reference()
    coarse_e, coarse_x = fly(100)
    fine_e, fine_x = fly(300)
    # measured: 2.1e-6 and 2.3e-7 (without the switch: 6.5e-2 and 6.7e-3, the positions 0.67 and 0.05 R0 off)
    assert coarse_e < 1e-5 and fine_e < 1e-6
    coarse, fine = np.abs(coarse_x - ref).max() / R0, np.abs(fine_x - ref).max() / R0
    assert coarse < 1e-5 and fine < 1e-6
    assert 6.0 < coarse / fine < 12.0                   # second order: 9 at a third of the step


def test_without_the_switch_the_same_pass_loses_the_energy(monkeypatch):
    """The check above can fail: the plain kick-drift-kick on the same pass (the switch taken out)."""
    monkeypatch.setattr(NBodyFlight, "_switch", lambda self, *args: None)
    worst, x = fly(100)
    assert worst > 1e-2
    assert np.abs(x - reference()).max() / R0 > 0.1


def test_bodies_that_stay_apart_move_as_without_the_switch(monkeypatch):
    """Three NBody bodies on orbits far apart (never within reach of a critical radius): the same bits
    with the switch as without it."""
    def run():
        with World(dt=120.0) as w:
            w.add_system(GravitySystem())
            w.add_system(MovementSystem())
            w.create_entity(Transform(), GravityWell(mu=MU, radius=R_SURF))
            ents = []
            for k, r in enumerate((1.0e7, 2.0e7, 4.0e7)):
                vc = math.sqrt(MU / r)
                ents.append(w.create_entity(Transform((r * math.cos(k), r * math.sin(k), 0.0)),
                                            Velocity((-vc * math.sin(k), vc * math.cos(k), 30.0 * k)),
                                            Mass(1e20), NBody()))
            w.step(300)
            return w.columns(Transform, ents).position.copy(), w.columns(Velocity, ents).linear.copy()
    with_switch = run()
    monkeypatch.setattr(NBodyFlight, "_switch", lambda self, *args: None)
    without = run()
    assert np.array_equal(with_switch[0], without[0]) and np.array_equal(with_switch[1], without[1])


def test_nbody_colliders_without_a_well_fall_together_collide_and_keep_momentum():
    """No well: two NBody spheres released at rest pull each other together (the gravity system's
    leapfrog) and the collision system meets them (elastic): they touch, bounce, and the momentum stays 0."""
    m, d = 1e12, 10.0
    with World(dt=0.05) as w:
        w.add_system(GravitySystem())
        w.add_system(MovementSystem())
        w.add_system(CollisionSystem())
        seen = []
        w.subscribe(CollisionEvent, seen.append)
        a = w.create_entity(Transform((-d, 0.0, 0.0)), Velocity(), Mass(m), NBody(), SphereCollider(radius=1.0))
        b = w.create_entity(Transform((d, 0.0, 0.0)), Velocity(), Mass(m), NBody(), SphereCollider(radius=1.0))
        # free fall from 20 m to 2 m between centres: t = sqrt(r0^3/(2 G M)) (acos(sqrt(x)) + sqrt(x (1 - x))),
        # x = r/r0, M the total mass
        r0, x = 2 * d, 2.0 / (2 * d)
        t_hit = math.sqrt(r0 ** 3 / (2 * G * 2 * m)) * (math.acos(math.sqrt(x)) + math.sqrt(x * (1 - x)))
        w.step(int(t_hit / 0.05) + 40)
        assert seen and {seen[0].a, seen[0].b} == {a, b}
        assert seen[0].time == pytest.approx(t_hit, rel=2e-3)       # the leapfrog's error at this step
        v = w.columns(Velocity, [a, b]).linear
        np.testing.assert_allclose(v.sum(0), 0.0, atol=1e-12)
        x_now = w.columns(Transform, [a, b]).position
        assert x_now[1, 0] - x_now[0, 0] >= 2.0 - 1e-9              # never inside each other
        assert v[0, 0] < 0.0 < v[1, 0]                               # bounced: moving apart


@pytest.mark.parametrize("dt", [10.0, 600.0])
def test_a_lone_nbody_collider_about_a_well_drifts_on_its_exact_conic(dt):
    """An NBody body with a collider and nothing to meet (no other collider, no obstacle; its conic clears
    the surface): on its exact conic, as one without a collider, beside a body on rails."""
    mu, r0 = 3.986004418e14, 7.0e6
    v0 = (0.0, math.sqrt(mu / r0) * 1.1, 300.0)
    with World(dt=dt) as w:
        w.add_system(GravitySystem())
        w.add_system(MovementSystem())
        w.add_system(CollisionSystem())
        w.create_entity(Transform(), GravityWell(mu=mu, radius=6.371e6))
        a = w.create_entity(Transform((r0, 0.0, 0.0)), Velocity(v0), Mass(1e3), NBody(), SphereCollider(radius=5.0))
        b = w.create_entity(Transform((r0, 0.0, 0.0)), Velocity(v0))           # on rails: exact Kepler
        w.step(20)
        x = w.columns(Transform, [a, b]).position
        v = w.columns(Velocity, [a, b]).linear
        assert np.linalg.norm(x[0] - x[1]) <= 1e-9 * r0
        assert np.linalg.norm(v[0] - v[1]) <= 1e-9 * np.linalg.norm(v0)


def test_nbody_colliders_that_may_meet_drift_on_the_leapfrogs_line():
    """Two NBody colliders about a well (a contact pass every step): each drifts on the straight line where
    the pass finds contacts exactly, so a lone pair's orbit is the leapfrog's, not the exact conic (its
    error shrinks as dt^2); the same bodies without colliders are on their conics."""
    mu, r0 = 3.986004418e14, 7.0e6
    vc = math.sqrt(mu / r0)

    def gap(dt, colliders):
        with World(dt=dt) as w:
            w.add_system(GravitySystem())
            w.add_system(MovementSystem())
            w.add_system(CollisionSystem())
            w.create_entity(Transform(), GravityWell(mu=mu, radius=6.371e6))
            def extra():
                return (SphereCollider(radius=5.0),) if colliders else ()
            a = w.create_entity(Transform((r0, 0.0, 0.0)), Velocity((0.0, vc, 0.0)), Mass(1.0), NBody(), *extra())
            w.create_entity(Transform((-r0, 0.0, 0.0)), Velocity((0.0, -vc, 0.0)), Mass(1.0), NBody(), *extra())
            rails = w.create_entity(Transform((r0, 0.0, 0.0)), Velocity((0.0, vc, 0.0)))
            w.step(int(round(600.0 / dt)))
            x = w.columns(Transform, [a, rails]).position
            return float(np.linalg.norm(x[0] - x[1]))
    coarse, fine = gap(20.0, True), gap(10.0, True)
    assert coarse > 1.0 and 3.5 < coarse / fine < 4.5
    assert gap(20.0, False) < 1e-6
