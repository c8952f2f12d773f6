"""Time warp: the same states at every warp, and the warp drops before a contact or a burn."""
import math

import numpy as np
import pytest

from driftframe import (Acceleration, AngularVelocity, ControlSystem, FixedStepLoop, FlightControl, FlightInput,
                        MovementSystem, SpinSystem, Transform, Velocity, World)
from driftframe.components.autopilot import Autopilot
from driftframe.components.gravity import GravityWell, SurfaceContact
from driftframe.framework import kepler
from driftframe.framework import warp as time_warp
from driftframe.systems.autopilot import AutopilotSystem
from driftframe.systems.gravity import GravitySystem
from driftframe.systems.input import InputSystem
from driftframe.systems.warp import WarpGovernorSystem

MU = 3.986004418e14
R = 6.371e6


def scene(dt=1.0):
    w = World(dt=dt)
    for s in (InputSystem(), AutopilotSystem(), ControlSystem(), GravitySystem(), MovementSystem(), SpinSystem(),
              WarpGovernorSystem(lead_frames=3)):
        w.add_system(s)
    w.create_entity(Transform(), GravityWell(mu=MU, radius=R))
    # a ship that burns retrograde at t = 1,500 s, and a rock on its way down
    ship = w.create_entity(Transform((7e6, 0, 0)), Velocity((0, 7.6e3, 100.0)), AngularVelocity(), Acceleration(),
                           FlightInput(), FlightControl(thrust=20.0),
                           Autopilot(mode="burn", dv=60.0, along="retrograde", at=1500.0))
    rock = w.create_entity(Transform((2e7, 1e6, 0)), Velocity((-6e3, 0, 0)))
    hits = []
    w.subscribe(SurfaceContact, hits.append)
    return w, ship, rock, hits


def fly(w, request, until):
    """Step ``w`` at warp ``request`` (the governor caps it) up to ``until`` s; every contact and each
    step's ``(time, warp in force, reason)``."""
    from driftframe.components.collision import CollisionEvent

    hits = []
    w.subscribe(CollisionEvent, hits.append)
    warp = time_warp.of(w)
    warp.request(request)
    seen = []
    while w.time < until:
        w.step()
        seen.append((w.time, warp.factor, warp.reason))
    return seen, hits


def assert_no_frame_runs_into(seen, times, lead_frames=3, dt=1.0):
    """No step of ``seen`` (from :func:`fly`) had a warp whose ``lead_frames`` frames of ``warp * dt`` reach
    the next of ``times`` (contacts) from where it was: the governor dropped the warp in time."""
    for t, f, _ in seen:
        nxt = min((c for c in times if c > t), default=math.inf)
        assert f * dt * lead_frames <= max(nxt - t, lead_frames * dt) + 1e-9, (t, f)


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_levels_and_requests():
    warp = time_warp.TimeWarp()
    assert warp.factor == 1
    for want in (10, 100, 1_000, 10_000, 100_000, 100_000):
        warp.up()
        assert warp.requested == want
    warp.limit = 100
    assert warp.factor == 100 and warp.dropped
    with pytest.raises(ValueError, match=r"warp factor must be one of .* got 7"):
        warp.request(7)


def test_states_after_T_are_the_same_at_1x_and_10000x():
    """The loop at 10,000x takes the same fixed steps as at 1x: bit-identical states and contacts."""
    runs = []
    for factor in (1, 10_000):
        w, ship, rock, hits = scene()
        try:
            time_warp.of(w).request(factor)
            w.step()                                  # one step at 1x: the governor has looked ahead
            clock = Clock()
            loop = FixedStepLoop(w, clock)
            factors = []
            while w.step_count < 3000:
                clock.t += w.dt                       # one owed step per frame
                loop.tick()
                factors.append(time_warp.factor(w))
            n = w.step_count
            runs.append((n, w, hits, factors, rock))
        except BaseException:
            w.close()
            raise
    (n1, w1, h1, f1, rock), (n2, w2, h2, f2, _) = runs
    try:
        assert max(f1) == 1 and max(f2) > 1                      # it did warp ...
        assert n2 >= 3000
        w1.step(n2 - n1)                                          # ... and the 1x run is brought level
        assert w1.step_count == w2.step_count
        assert w1.state_hash() == w2.state_hash()
        assert [(h.entity, h.time) for h in h1] == [(h.entity, h.time) for h in h2]
        assert [h.entity for h in h1] == [rock]                   # the rock's impact, in both
    finally:
        w1.close()
        w2.close()


def test_warp_drops_before_the_burn_and_the_contact_and_says_why():
    w, ship, rock, hits = scene()
    try:
        warp = time_warp.of(w)
        warp.request(100_000)
        t_hit = kepler.time_to_radius([2e7, 1e6, 0], [-6e3, 0, 0], MU, R, 1e9)[0]
        burn = (1500.0 - 1.5, 1500.0 + 1.5)                     # 60 m/s at 20 m/s^2, centred on 1,500 s
        seen = []
        while w.time < 1900.0:
            w.step()
            seen.append((w.time, warp.factor, warp.reason))
        # a frame at the warp in force never runs into the next event (lead: 3 frames); 1x while burning
        for t, f, why in seen:
            if burn[0] <= t <= burn[1]:
                assert f == 1
                continue
            nxt = min((x for x in (t_hit, burn[0]) if x > t), default=math.inf)
            assert f * w.dt * 3 <= max(nxt - t, w.dt * 3) + 1e-9
        assert any("burn" in why for _, _, why in seen)
        assert any("surface" in why for _, _, why in seen)
        assert seen[-1][1] == 100_000                            # nothing ahead: back to the request
        assert len(hits) == 1
    finally:
        w.close()


def test_warp_drops_before_two_bodies_on_rails_touch_and_the_contact_is_the_same():
    """The governor also sees contacts between colliders on rails (predicted on their conics)."""
    from driftframe import SphereCollider

    T = 900.0
    where = np.array([7e6, 0.0, 0.0])
    vc = math.sqrt(MU / 7e6)

    def run(request):
        w = World(dt=1.0)
        for s in (GravitySystem(), MovementSystem(), WarpGovernorSystem(lead_frames=3)):
            w.add_system(s)
        w.create_entity(Transform(), GravityWell(mu=MU, radius=R))
        ents = []
        for v in ((0, vc, 0), (0, 0, vc)):                     # equatorial and polar: they meet at T
            r0, v0 = kepler.propagate(where, np.array(v, float), MU, -T)
            ents.append(w.create_entity(Transform(r0), Velocity(v0), SphereCollider(radius=50.0)))
        try:
            # to 4,000 s: past their second meeting (3,814 s), the last before 6,000 s, where this flew to
            seen, hits = fly(w, request, 4000.0)
            return seen, hits, w.columns(Velocity, ents).linear.copy()
        finally:
            w.close()

    seen, hits, v_end = run(10_000)
    # they meet at T, bounce, and (their orbits still cross) meet again and again: each one seen coming
    assert len(hits) >= 2
    assert abs(hits[0].time - T) < 1.0
    assert_no_frame_runs_into(seen, [h.time for h in hits])   # no frame at the warp in force runs into one
    assert sum("touch" in why for _, _, why in seen) >= 2
    assert max(f for _, f, _ in seen) >= 100                   # between contacts: as fast as the next allows
    _, hits1, v1 = run(1)
    assert [h.time for h in hits1] == [h.time for h in hits] and np.array_equal(v1, v_end)


def test_warp_drops_before_a_body_on_rails_meets_an_obstacle_and_the_contact_is_the_same():
    """The governor also sees a collider on rails coming to a collider gravity does not move."""
    from driftframe import SphereCollider

    T = 900.0
    vc = math.sqrt(MU / 7e6)
    r0, v0 = np.array([7e6, 0.0, 0.0]), np.array([0.0, vc, 0.0])
    pT, _ = kepler.propagate(r0, v0, MU, T)

    def run(request):
        w = World(dt=1.0)
        for s in (GravitySystem(), MovementSystem(), WarpGovernorSystem(lead_frames=3)):
            w.add_system(s)
        w.create_entity(Transform(), GravityWell(mu=MU, radius=R))
        body = w.create_entity(Transform(r0), Velocity(v0), SphereCollider(radius=50.0))
        w.create_entity(Transform(pT * (1.0 + 30.0 / np.linalg.norm(pT))), SphereCollider(radius=50.0))
        try:
            seen, hits = fly(w, request, 1000.0)          # (the contact is at 900 s; this flew to 1,500 s)
            return seen, hits, w.columns(Velocity, [body]).linear.copy()
        finally:
            w.close()

    seen, hits, v_end = run(10_000)
    assert len(hits) >= 1 and abs(hits[0].time - T) < 1.0
    assert_no_frame_runs_into(seen, [h.time for h in hits])   # no frame at the warp in force runs into it
    assert any("touch" in why for _, _, why in seen)
    _, hits1, v1 = run(1)
    assert [h.time for h in hits1] == [h.time for h in hits] and np.array_equal(v1, v_end)


def test_warp_drops_before_n_body_colliders_could_touch():
    """n-body paths are not known beyond their step: the governor slows down from a lower bound on when
    two n-body colliders could first touch (the gap at their speed plus the most the pulls can add), so
    no frame at the warp in force runs into the contact, and the contact is the one 1x finds."""
    from driftframe import Mass, SphereCollider
    from driftframe.components.gravity import NBody

    def run(request):
        w = World(dt=1.0)
        for s in (GravitySystem(), MovementSystem(), WarpGovernorSystem(lead_frames=3)):
            w.add_system(s)
        w.create_entity(Transform(), GravityWell(mu=MU, radius=R))
        # falling together far out (0.16 m/s^2), closing at 10 m/s from 20 km: they touch after ~2,000 s
        ents = [w.create_entity(Transform((5e7, 0.0, 0.0)), Velocity((0.0, 5.0, 0.0)), Mass(10.0), NBody(),
                                SphereCollider(radius=20.0)),
                w.create_entity(Transform((5e7, 2.0e4, 0.0)), Velocity((0.0, -5.0, 0.0)), Mass(10.0), NBody(),
                                SphereCollider(radius=20.0))]
        try:
            # to 2,100 s: 110 s past the contact (1,988 s), whose aftermath is compared; 2 ms of CPU a step
            seen, hits = fly(w, request, 2100.0)
            return seen, hits, w.columns(Transform, ents).position.copy()
        finally:
            w.close()

    seen, hits, x_end = run(10_000)
    assert hits and hits[0].method == "leapfrog"
    first = hits[0].time
    assert_no_frame_runs_into(seen, [first])                   # up to the first contact
    assert any("may touch" in why for _, _, why in seen)       # (a lower bound, and it says so)
    assert max(f for t, f, _ in seen if t < first) >= 10       # far apart: faster than 1x
    _, hits1, x1 = run(1)
    assert [h.time for h in hits1] == [h.time for h in hits] and np.array_equal(x1, x_end)


@pytest.mark.parametrize("speed", [0.0, 3000.0], ids=["released at rest", "engine cut going straight up"])
def test_warp_drops_before_a_body_on_a_straight_line_meets_the_surface(speed):
    """A ship that lifts off vertically and cuts its engine (or hangs at rest) falls straight back: the
    governor sees that contact (a straight-line orbit's e = 1 was taken for an escaping parabola's, and
    warp stayed at 100,000x while the ship fell through the planet)."""
    w = World(dt=1.0)
    for s in (GravitySystem(), MovementSystem(), WarpGovernorSystem(lead_frames=3)):
        w.add_system(s)
    w.create_entity(Transform(), GravityWell(mu=MU, radius=R))
    ship = w.create_entity(Transform((0.0, 0.0, 1e7)), Velocity((0.0, 0.0, speed)))
    hits = []
    w.subscribe(SurfaceContact, hits.append)
    # radial Kepler fall from the apex r_max = r0 / (1 - q/2), q = v^2 r0 / mu, to R, plus the rise to it
    q = speed * speed * 1e7 / MU
    r_max = 1e7 / (1 - q / 2)

    def fall(omx):                                     # apex -> (1 - omx) r_max, closed form
        return math.sqrt(r_max ** 3 / (2 * MU)) * (math.sqrt((1 - omx) * omx) + math.asin(math.sqrt(omx)))

    t_hit = fall(1 - R / r_max) + fall(q / 2)
    try:
        seen, _ = fly(w, 100_000, t_hit + 10.0)
        assert [h.entity for h in hits] == [ship] and hits[0].time == pytest.approx(t_hit, abs=1e-9)
        assert_no_frame_runs_into(seen, [t_hit])
        assert any("surface" in why for _, _, why in seen)
        assert np.linalg.norm(w.columns(Transform, [ship]).position[0]) >= R
    finally:
        w.close()
