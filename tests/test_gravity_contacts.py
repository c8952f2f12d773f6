"""Sphere-sphere contacts of bodies on rails: exact on their conics, at any step, energy and momentum kept."""
import math

import numpy as np
import pytest

from driftframe import CollisionSystem, Mass, MovementSystem, SphereCollider, Transform, Velocity, World
from driftframe.components.collision import CollisionEvent
from driftframe.components.gravity import GravityWell, SurfaceContact
from driftframe.framework import kepler
from driftframe.systems.gravity import GravitySystem

MU = 3.986004418e14
R_EARTH = 6.371e6
R_ORBIT = 7e6
V_CIRC = math.sqrt(MU / R_ORBIT)


def make(dt, collision_system=True):
    w = World(dt=dt)
    w.add_system(GravitySystem())
    w.add_system(MovementSystem())
    if collision_system:
        w.add_system(CollisionSystem())
    w.create_entity(Transform(), GravityWell(mu=MU, radius=R_EARTH))
    w.seen = []                                    # every event of every step (world.events: the last call's)
    w.subscribe(CollisionEvent, w.seen.append)
    w.subscribe(SurfaceContact, w.seen.append)
    return w


def meeting(T, v_a, v_b, where=(R_ORBIT, 0.0, 0.0)):
    """States at t = 0 of two bodies that are both at ``where`` at time T (velocities v_a, v_b there)."""
    p = np.array(where, float)
    ra, va = kepler.propagate(p, np.array(v_a, float), MU, -T)
    rb, vb = kepler.propagate(p, np.array(v_b, float), MU, -T)
    return (ra, va), (rb, vb)


def first_touch(sa, sb, reach, t_end, samples=400_000, t_start=0.0):
    """Independent check: the gap sampled densely on both exact conics, the first sign change bisected."""
    ts = np.linspace(t_start, t_end, samples + 1)
    pa, _ = kepler.propagate(np.repeat(sa[0][None], ts.size, 0), np.repeat(sa[1][None], ts.size, 0), MU, ts)
    pb, _ = kepler.propagate(np.repeat(sb[0][None], ts.size, 0), np.repeat(sb[1][None], ts.size, 0), MU, ts)
    gap = np.linalg.norm(pa - pb, axis=1) - reach
    k = int(np.flatnonzero(gap <= 0)[0])
    return bisect(lambda t: np.linalg.norm(kepler.propagate(sa[0], sa[1], MU, t)[0]
                                           - kepler.propagate(sb[0], sb[1], MU, t)[0]) - reach, ts[k - 1], ts[k])


def bisect(gap, lo, hi):
    """The time in (lo, hi] where ``gap`` (positive at lo, <= 0 at hi) reaches 0, to 1e-13 relative."""
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if gap(mid) > 0:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-13 * hi:
            break
    return 0.5 * (lo + hi)


def collisions(world):
    return [e for e in world.seen if isinstance(e, CollisionEvent)]


def run_pair(dt, T=500.3, steps=None, kg=(3.0, None), radius=(40.0, 60.0), restitution=(1.0, 1.0),
             v_b=(0, 0, V_CIRC)):
    """Two bodies on crossing orbits (one circular and equatorial, one polar) that meet near t = T."""
    sa, sb = meeting(T, (0, V_CIRC, 0), v_b)
    w = make(dt)
    ents = []
    for s, m, rad, e in zip((sa, sb), kg, radius, restitution):
        comps = [Transform(s[0]), Velocity(s[1]), SphereCollider(radius=rad, restitution=e)]
        if m is not None:
            comps.append(Mass(m))
        ents.append(w.create_entity(*comps))
    seen = []
    w.subscribe(CollisionEvent, seen.append)
    n = steps if steps is not None else int(math.ceil(2 * T / dt))
    w.step(n)
    return w, ents, (sa, sb), seen


def states(world, ents):
    return (world.columns(Transform, ents).position.copy(), world.columns(Velocity, ents).linear.copy())


def test_crossing_orbits_touch_at_the_time_an_independent_search_finds():
    w, (a, b), (sa, sb), seen = run_pair(dt=1.0)
    try:
        assert len(seen) == 1
        ev = seen[0]
        assert (ev.a, ev.b) == (a, b) and ev.method == "kepler"
        reach = 100.0
        t_ref = first_touch(sa, sb, reach, 510.0)
        assert abs(ev.time - t_ref) <= 1e-9 * t_ref
        assert 0.0 <= ev.step_time <= 1.0 and ev.step == int(ev.time // 1.0)
        # at the contact the centres are r_a + r_b apart, on the conics they were on
        pa, va = kepler.propagate(sa[0], sa[1], MU, ev.time)
        pb, vb = kepler.propagate(sb[0], sb[1], MU, ev.time)
        assert abs(np.linalg.norm(pb - pa) - reach) <= 1e-9 * reach
        n = (pb - pa) / np.linalg.norm(pb - pa)
        np.testing.assert_allclose(ev.normal, n, atol=1e-9)
        np.testing.assert_allclose(ev.point, pa + 40.0 * n, rtol=0, atol=1e-6)
        # the impulse reported is what an elastic contact of 3 kg and 1 kg along n gives
        vn = float((vb - va) @ n)
        assert vn < 0
        assert ev.impulse == pytest.approx(-2.0 * vn / (1 / 3.0 + 1.0), rel=1e-12)
    finally:
        w.close()


def test_the_contact_keeps_energy_and_momentum_and_the_rails_stay_exact():
    w, ents, (sa, sb), seen = run_pair(dt=1.0, T=500.3, steps=700)
    try:
        ev = seen[0]
        m = np.array([3.0, 1.0])
        x, v = states(w, ents)
        t_now = w.step_count * w.dt
        # after the contact both are on new conics through their states at the contact: back there
        back_r, back_v = kepler.propagate(x, v, MU, ev.time - t_now)
        pre_a = kepler.propagate(sa[0], sa[1], MU, ev.time)
        pre_b = kepler.propagate(sb[0], sb[1], MU, ev.time)
        np.testing.assert_allclose(back_r, [pre_a[0], pre_b[0]], rtol=0, atol=1e-6)   # positions unchanged
        p_before = m[0] * pre_a[1] + m[1] * pre_b[1]
        p_after = m[0] * back_v[0] + m[1] * back_v[1]
        assert np.linalg.norm(p_after - p_before) <= 1e-12 * np.linalg.norm(m[0] * pre_a[1])
        # the impulse along the normal is all that changed: each velocity by -+ J n / m
        n = np.array(ev.normal)
        np.testing.assert_allclose(back_v[1] - pre_b[1], ev.impulse * n / m[1], rtol=0, atol=1e-9)

        def energy(r, u):
            return float(sum(mk * (0.5 * uk @ uk - MU / np.linalg.norm(rk)) for mk, rk, uk in zip(m, r, u)))
        e0 = energy([sa[0], sb[0]], [sa[1], sb[1]])
        assert abs(energy(x, v) / e0 - 1.0) <= 1e-9
        assert abs(energy(back_r, back_v) / e0 - 1.0) <= 1e-12
        # the kinetic energy changed hands: it was a real exchange, not a miss
        ke_a_before = 0.5 * m[0] * pre_a[1] @ pre_a[1]
        assert abs(0.5 * m[0] * back_v[0] @ back_v[0] - ke_a_before) > 1e-3 * ke_a_before
    finally:
        w.close()


@pytest.mark.parametrize("dt", [0.37, 1000.0])
def test_the_same_contact_at_every_step_length_no_tunnelling(dt):
    """At 1,000 s a step covers ~7,500 km of each orbit (the spheres are 100 m): the contact is found
    all the same, at the same time, and the bodies end on the same conics."""
    T_end = 3000.0
    # b on an eccentric inclined orbit, meeting a 300 s into the long step: the separation's path
    # bends away from its chord by kilometres over the step (the bound on that is what finds it)
    kw = dict(T=300.3, v_b=(0.0, 0.4 * V_CIRC, 1.05 * V_CIRC))
    ref, ents_r, _, seen_r = run_pair(dt=1.0, steps=3000, **kw)
    w, ents, _, seen = run_pair(dt=dt, steps=int(round(T_end / dt)) if dt > 1 else None, **kw)
    try:
        if dt < 1:
            w.step(int(math.ceil((T_end - w.step_count * dt) / dt)))
        assert len(seen) == len(seen_r) == 1
        assert (seen[0].a, seen[0].b) == (seen_r[0].a, seen_r[0].b)
        assert abs(seen[0].time - seen_r[0].time) <= 1e-9 * seen_r[0].time
        assert seen[0].impulse == pytest.approx(seen_r[0].impulse, rel=1e-9)
        # compare at the same time: bring both to T_end on their conics
        for world, e in ((ref, ents_r), (w, ents)):
            x, v = states(world, e)
            world._at_end = kepler.propagate(x, v, MU, T_end - world.step_count * world.dt)
        np.testing.assert_allclose(w._at_end[0], ref._at_end[0], rtol=0, atol=1e-4)
        np.testing.assert_allclose(w._at_end[1], ref._at_end[1], rtol=0, atol=1e-7)
    finally:
        w.close()
        ref.close()


def test_a_fast_head_on_pair_that_end_of_step_checks_miss_is_found():
    """Prograde meets retrograde at 15 km/s; 1 m spheres, 10 s steps: 150 km between step ends."""
    sa, sb = meeting(1234.5, (0, V_CIRC, 0), (0, -V_CIRC, 1.0))
    w = make(10.0)
    try:
        a = w.create_entity(Transform(sa[0]), Velocity(sa[1]), SphereCollider(radius=1.0))
        b = w.create_entity(Transform(sb[0]), Velocity(sb[1]), SphereCollider(radius=1.0))
        closest = math.inf
        for _ in range(200):
            w.step()
            x, _ = states(w, [a, b])
            closest = min(closest, float(np.linalg.norm(x[1] - x[0])))
        assert closest > 1e4                       # never near at a step's end: a sampled check misses it
        hits = collisions(w)
        assert len(hits) == 1 and {hits[0].a, hits[0].b} == {a, b}
        t_ref = first_touch(sa, sb, 2.0, 1240.0, samples=200_000, t_start=1200.0)
        assert abs(hits[0].time - t_ref) <= 1e-9 * t_ref
        # head on, equal masses, elastic: they swap their velocities (the normal is along the relative
        # velocity), so each goes on along the other's old conic
        x, _ = states(w, [a, b])
        b_missed, _ = kepler.propagate(sb[0], sb[1], MU, w.time)          # where b would be with no contact
        a_missed, _ = kepler.propagate(sa[0], sa[1], MU, w.time)
        assert np.linalg.norm(x[0] - b_missed) < 1e-4 * R_ORBIT < np.linalg.norm(x[0] - a_missed)
    finally:
        w.close()


def scatter(n, seed, radius=2.0):
    """n bodies on mixed orbits spread round the planet (10,000 km and more apart at every step)."""
    rng = np.random.default_rng(seed)
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rr = R_ORBIT * (1.0 + 0.3 * rng.uniform(size=n))
    pos = np.stack([rr * np.cos(ang), rr * np.sin(ang), np.zeros(n)], axis=1)
    vel = np.stack([-np.sin(ang), np.cos(ang), np.zeros(n)], axis=1) * np.sqrt(MU / rr)[:, None]
    return pos, vel


@pytest.mark.parametrize("with_surface", [False, True])
def test_colliders_that_never_touch_leave_every_state_bit_identical(with_surface):
    """The same scene with and without SphereColliders (on a ring: all in one plane, same direction,
    never close): no contact, and bit for bit the same states, step after step."""
    pos, vel = scatter(80, seed=3)
    if with_surface:
        vel[0] = [-3000.0, 0.0, 0.0]               # body 0 falls onto the planet and bounces
    runs = []
    for colliders in (False, True):
        w = make(20.0)
        ents = []
        for k in range(len(pos)):
            comps = [Transform(pos[k]), Velocity(vel[k])]
            if colliders:
                comps.append(SphereCollider(radius=2.0))
            ents.append(w.create_entity(*comps))
        trace = []
        for _ in range(60):
            w.step()
            trace.append(states(w, ents))
        runs.append((trace, list(w.seen), w))
    try:
        (t0, ev0, _), (t1, ev1, _) = runs
        assert not [e for e in ev1 if isinstance(e, CollisionEvent)]
        assert [e for e in ev0 if isinstance(e, SurfaceContact)] == [e for e in ev1 if isinstance(e, SurfaceContact)]
        assert bool([e for e in ev1 if isinstance(e, SurfaceContact)]) == with_surface
        for (xa, va), (xb, vb) in zip(t0, t1):
            assert np.array_equal(xa, xb) and np.array_equal(va, vb)
    finally:
        for _, _, w in runs:
            w.close()


def swarm(dt, steps, spacing=800.0, seed=11):
    """27 big spheres (250 to 350 m) on a lattice 800 m apart in low orbit, stirred by up to 2 m/s:
    they meet again and again as the cloud shears along its orbit."""
    rng = np.random.default_rng(seed)
    w = make(dt)
    ents = []
    for cell in np.stack(np.meshgrid(*[np.arange(3) - 1] * 3, indexing="ij"), -1).reshape(-1, 3):
        p = np.array([R_ORBIT, 0.0, 0.0]) + spacing * cell
        u = np.array([0.0, V_CIRC, 0.0]) + rng.uniform(-2.0, 2.0, 3)
        ents.append(w.create_entity(Transform(p), Velocity(u), SphereCollider(radius=rng.uniform(250.0, 350.0)),
                                    Mass(float(rng.uniform(0.5, 4.0)))))
    kg = np.array([w.columns(Mass, [e]).kg[0] for e in ents])
    r0, v0 = states(w, ents)
    w.step(steps)
    return w, ents, kg, (r0, v0)


def test_a_swarm_has_the_same_contacts_at_a_long_and_a_short_step_and_keeps_its_energy():
    """Many contacts, some sending a body out of the box it was given for the step (re-examined), some
    chained within one step: the long-step run finds the same contacts in the same order."""
    T = 3000.0
    short, ents, kg, (r0, v0) = swarm(dt=1.0, steps=3000)
    long, _, _, _ = swarm(dt=100.0, steps=30)
    try:
        cs, cl = collisions(short), collisions(long)
        assert len(cs) >= 20
        assert any(e.step == f.step for e, f in zip(cl, cl[1:]))              # several in one long step
        # the same contacts, in the same order, at the same times (each exact: only rounding differs,
        # which the contacts after it amplify a little)
        assert [(e.a, e.b) for e in cs] == [(e.a, e.b) for e in cl]
        for e, f in zip(cs, cl):
            assert abs(e.time - f.time) <= 1e-9 * e.time

        def energy(world):
            x, v = states(world, ents)
            return float(np.sum(kg * (0.5 * np.einsum("ij,ij->i", v, v) - MU / np.linalg.norm(x, axis=1))))
        e0 = float(np.sum(kg * (0.5 * np.einsum("ij,ij->i", v0, v0) - MU / np.linalg.norm(r0, axis=1))))
        for world, events in ((short, cs), (long, cl)):
            assert abs(energy(world) / e0 - 1.0) <= 1e-9 * max(len(events), 1)
            # nobody overlaps anybody at the end of the run (nothing tunnelled into another)
            x, _ = states(world, ents)
            rad = world.columns(SphereCollider, ents).radius
            d = np.linalg.norm(x[:, None] - x[None], axis=2) + np.eye(len(ents)) * 1e9
            assert (d >= (rad[:, None] + rad[None]) * (1 - 1e-9)).all()
    finally:
        short.close()
        long.close()


def test_restitution_is_the_smaller_of_the_two_and_scales_the_normal_speed():
    w, ents, (sa, sb), seen = run_pair(dt=1.0, steps=520, restitution=(0.5, 0.8))
    try:
        ev = seen[0]
        x, v = states(w, ents)
        back_r, back_v = kepler.propagate(x, v, MU, ev.time - w.step_count * w.dt)
        pre_a = kepler.propagate(sa[0], sa[1], MU, ev.time)
        pre_b = kepler.propagate(sb[0], sb[1], MU, ev.time)
        n = np.array(ev.normal)
        before = float((pre_b[1] - pre_a[1]) @ n)
        after = float((back_v[1] - back_v[0]) @ n)
        assert before < 0 and after == pytest.approx(-0.5 * before, rel=1e-9)
    finally:
        w.close()


def test_bodies_about_a_moon_collide_on_their_conics_about_it_reported_in_the_world_frame():
    """Two bodies in a moving moon's sphere of influence: their contact is found on their conics about
    the moon, and the event's point is where the moon was at that time plus their state about it."""
    mu_moon = 4.9048695e12
    w = World(dt=5.0)
    try:
        w.add_system(GravitySystem())
        w.add_system(MovementSystem())
        planet = w.create_entity(Transform(), GravityWell(mu=MU, radius=R_EARTH))
        m0, mv0 = np.array([3.844e8, 0.0, 0.0]), np.array([0.0, 1022.0, 0.0])
        w.create_entity(Transform(m0), Velocity(mv0), GravityWell(mu=mu_moon, radius=1.737e6, parent=planet))
        seen = []
        w.subscribe(CollisionEvent, seen.append)
        r_low = 2.2e6
        v_low = math.sqrt(mu_moon / r_low)
        T = 900.0
        pa0, va0 = kepler.propagate(np.array([r_low, 0, 0.0]), np.array([0, v_low, 0.0]), mu_moon, -T)
        pb0, vb0 = kepler.propagate(np.array([r_low, 0, 0.0]), np.array([0, 0, v_low]), mu_moon, -T)
        a = w.create_entity(Transform(m0 + pa0), Velocity(mv0 + va0), SphereCollider(radius=30.0))
        b = w.create_entity(Transform(m0 + pb0), Velocity(mv0 + vb0), SphereCollider(radius=30.0))
        w.step(200)
        assert len(seen) == 1 and (seen[0].a, seen[0].b) == (a, b)
        ev = seen[0]
        assert abs(ev.time - T) < 60.0 / v_low
        moon_at, _ = kepler.propagate(m0, mv0, MU, ev.time)
        pa, _ = kepler.propagate(pa0, va0, mu_moon, ev.time)
        pb, _ = kepler.propagate(pb0, vb0, mu_moon, ev.time)
        assert abs(np.linalg.norm(pb - pa) - 60.0) <= 1e-9 * 60.0 + 1e-8
        np.testing.assert_allclose(ev.point, moon_at + pa + 30.0 * (pb - pa) / np.linalg.norm(pb - pa),
                                   rtol=0, atol=1e-3)
    finally:
        w.close()


def test_a_perfectly_inelastic_pair_rests_in_contact_with_one_impulse_a_step_at_most():
    """e = 0: they leave the contact with no normal speed; the tidal pull presses them together again,
    and that resting contact costs one small impulse per step, not a cascade (nor a warning)."""
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        w, ents, (sa, sb), seen = run_pair(dt=1.0, steps=800, restitution=(0.0, 0.3))
    try:
        first = seen[0]
        assert first.step == 500
        assert len(seen) <= 1 + (800 - 501)
        assert len({e.step for e in seen}) == len(seen)                 # one per step
        assert all(e.impulse < 1e-6 * first.impulse for e in seen[1:])  # pressing, not bouncing
        # they are still in touch at the end: not apart, and sunk into each other by no more than the
        # tidal squeeze can do within each step (3 mu d / r^3 over dt^2 / 2), step after step
        x, v = states(w, ents)
        gap = np.linalg.norm(x[1] - x[0]) - 100.0
        squeeze = 3.0 * MU * 100.0 / R_ORBIT ** 3 * 0.5 * (800 - 500)
        assert -squeeze < gap < 1.0
    finally:
        w.close()


# -- n-body colliders: exact contacts on the leapfrog's straight drift -------------------------------
def nbody_pair(dt, gap=1_000.0, speed=50.0, kg=(2.0, 5.0), restitution=1.0):
    """Two NBody colliders closing head on far from a light well (the drift is all that moves them)."""
    from driftframe.components.gravity import NBody
    w = World(dt=dt)
    w.add_system(GravitySystem())
    w.add_system(MovementSystem())
    w.add_system(CollisionSystem())
    w.create_entity(Transform((0.0, 0.0, -1e9)), GravityWell(mu=1.0, radius=1.0))
    w.seen = []
    w.subscribe(CollisionEvent, w.seen.append)
    a = w.create_entity(Transform((0.0, 0.0, 0.0)), Velocity((speed, 0.0, 0.0)), Mass(kg[0]), NBody(),
                        SphereCollider(radius=2.0, restitution=restitution))
    b = w.create_entity(Transform((gap, 0.0, 0.0)), Velocity((-speed, 0.0, 0.0)), Mass(kg[1]), NBody(),
                        SphereCollider(radius=3.0, restitution=restitution))
    return w, a, b


@pytest.mark.parametrize("dt", [0.25, 4.0, 60.0])
def test_n_body_colliders_meet_on_their_drift_at_the_exact_time_at_any_step(dt):
    w, a, b = nbody_pair(dt)
    try:
        steps = int(math.ceil(30.0 / dt))
        w.step(steps)
        hits = collisions(w)
        assert len(hits) == 1, hits                             # found even when one step jumps past
        h = hits[0]
        assert (h.a, h.b) == (a, b) and h.method == "leapfrog"
        # closing at 100 m/s from 1,000 m between centres, 5 m of radii: 9.95 s (the well's pull is ~1e-18)
        assert h.time == pytest.approx(995.0 / 100.0, rel=1e-9)
        v = w.columns(Velocity, [a, b]).linear
        # elastic, 2 kg and 5 kg at +-50 m/s: momentum -150 kg m/s kept, kinetic energy kept
        p = 2.0 * v[0, 0] + 5.0 * v[1, 0]
        assert p == pytest.approx(2.0 * 50 - 5.0 * 50, rel=1e-12)
        ke = 0.5 * (2.0 * v[0] @ v[0] + 5.0 * v[1] @ v[1])
        assert ke == pytest.approx(0.5 * 7.0 * 2500.0, rel=1e-12)
        x = w.columns(Transform, [a, b]).position
        assert x[1, 0] - x[0, 0] >= 5.0 - 1e-9                 # apart after it: no tunnelling
    finally:
        w.close()


def test_n_body_colliders_that_never_meet_are_left_as_the_leapfrog_moves_them():
    """The contact pass changes nothing when nobody touches: the same states as without colliders."""
    from driftframe.components.gravity import NBody
    out = []
    for colliders in (True, False):
        w = World(dt=10.0)
        w.add_system(GravitySystem())
        w.add_system(MovementSystem())
        w.create_entity(Transform(), GravityWell(mu=MU, radius=R_EARTH))
        # a second, far and light well keeps the bodies without colliders on the leapfrog's line as well
        # (alone about one well they would drift on their exact conics, Wisdom-Holman: systems/gravity/nbody.py)
        w.create_entity(Transform((1e13, 0.0, 0.0)), GravityWell(mu=1.0, radius=1.0))
        ents = []
        for k in range(4):
            comps = [Transform((R_ORBIT + 1e5 * k, 0.0, 0.0)), Velocity((0.0, V_CIRC, 10.0 * k)), Mass(1e3), NBody()]
            if colliders:
                comps.append(SphereCollider(radius=5.0))
            ents.append(w.create_entity(*comps))
        w.step(50)
        out.append(states(w, ents))
        w.close()
    assert np.array_equal(out[0][0], out[1][0]) and np.array_equal(out[0][1], out[1][1])


# -- a body on rails meets a collider gravity does not move (an obstacle) ---------------------------------

def first_touch_line(sa, q0, qv, reach, t_end, samples=400_000):
    """Independent check for a conic against a straight line q0 + qv t: dense samples, then bisection."""
    ts = np.linspace(0.0, t_end, samples + 1)
    pa, _ = kepler.propagate(np.repeat(sa[0][None], ts.size, 0), np.repeat(sa[1][None], ts.size, 0), MU, ts)
    gap = np.linalg.norm(pa - (q0 + qv * ts[:, None]), axis=1) - reach
    k = int(np.flatnonzero(gap <= 0)[0])
    return bisect(lambda t: np.linalg.norm(kepler.propagate(sa[0], sa[1], MU, t)[0] - (q0 + qv * t)) - reach,
                  ts[k - 1], ts[k])


def run_obstacle(dt, T=500.3, steps=None, outward=50.0, moving=None, kg=2.0, obstacle=True):
    """A 2 kg collider (radius 40) on a circular orbit and an obstacle (radius 60) placed ``outward`` m
    beyond where the body is at time T: at rest with no Velocity, or (``moving``: a velocity) Mass(inf)
    moving straight, placed so that it is there at T."""
    sa = (np.array([R_ORBIT, 0.0, 0.0]), np.array([0.0, V_CIRC, 0.0]))
    pT, _ = kepler.propagate(sa[0], sa[1], MU, T)
    qT = pT * (1.0 + outward / np.linalg.norm(pT))
    w = make(dt)
    a = w.create_entity(Transform(sa[0]), Velocity(sa[1]), SphereCollider(radius=40.0), Mass(kg))
    qv = np.zeros(3) if moving is None else np.array(moving, float)
    q0 = qT - qv * T
    b = None
    if obstacle:
        comps = [Transform(q0), SphereCollider(radius=60.0)]
        if moving is not None:
            comps += [Velocity(qv), Mass(math.inf)]
        b = w.create_entity(*comps)
    seen = []
    w.subscribe(CollisionEvent, seen.append)
    w.step(steps if steps is not None else int(math.ceil(2 * T / dt)))
    return w, (a, b), sa, (q0, qv), seen


def energy(r, v):
    return 0.5 * float(v @ v) - MU / float(np.linalg.norm(r))


@pytest.mark.parametrize("dt", [1.0, 37.0])
def test_a_body_on_rails_meets_a_fixed_obstacle_at_the_time_an_independent_search_finds(dt):
    w, (a, b), sa, (q0, qv), seen = run_obstacle(dt)
    try:
        assert len(seen) == 1
        ev = seen[0]
        assert (ev.a, ev.b) == (a, b) and ev.method == "kepler"
        t_ref = first_touch_line(sa, q0, qv, 100.0, 510.0)
        assert abs(ev.time - t_ref) <= 1e-9 * t_ref                 # the same at a 1 s and a 37 s step
        assert ev.step == int(ev.time // dt)
        pa, va = kepler.propagate(sa[0], sa[1], MU, ev.time)
        n = (q0 - pa) / np.linalg.norm(q0 - pa)
        np.testing.assert_allclose(ev.normal, n, atol=1e-9)
        np.testing.assert_allclose(ev.point, pa + 40.0 * n, rtol=0, atol=1e-6)
        # elastic against an immovable body: the body's normal velocity reversed, J = 2 m |v_n|
        assert ev.impulse == pytest.approx(-2.0 * 2.0 * float(-va @ n), rel=1e-12)
        # the obstacle was not moved (nothing moves it; no Velocity)
        np.testing.assert_array_equal(w.columns(Transform, [b]).position[0], q0)
    finally:
        w.close()


def test_the_obstacle_contact_keeps_the_orbit_energy_and_changes_momentum_by_the_impulse():
    w, (a, b), sa, (q0, qv), seen = run_obstacle(dt=1.0, steps=520)     # (it meets the surface at 592 s)
    try:
        assert len(seen) == 1 and len(w.seen) == 1
        ev = seen[0]
        x = w.columns(Transform, [a]).position[0].copy()
        v = w.columns(Velocity, [a]).linear[0].copy()
        t_now = w.step_count * w.dt
        back_r, back_v = kepler.propagate(x, v, MU, ev.time - t_now)      # the new conic, back to the contact
        pre_r, pre_v = kepler.propagate(sa[0], sa[1], MU, ev.time)
        np.testing.assert_allclose(back_r, pre_r, rtol=0, atol=1e-6)
        e0 = energy(*sa)
        assert abs(energy(x, v) - e0) <= 1e-9 * abs(e0)           # a resting obstacle: speed kept
        n = np.array(ev.normal)
        # momentum: the body's changed by -J n (it is ev.a, the obstacle pushes it back along -n)
        np.testing.assert_allclose(2.0 * (back_v - pre_v), -ev.impulse * n, rtol=0, atol=1e-9)
        assert float(back_v @ n) == pytest.approx(-float(pre_v @ n), rel=1e-9)
    finally:
        w.close()


@pytest.mark.parametrize("dt", [1.0, 29.0])
def test_a_body_on_rails_meets_a_moving_immovable_obstacle_on_its_straight_path(dt):
    qv = (-300.0, 150.0, 20.0)
    w, (a, b), sa, (q0, qv), seen = run_obstacle(dt, moving=qv, steps=int(math.ceil(520.0 / dt)))
    try:
        assert len(seen) == 1 and len(w.seen) == 1                    # (no surface contact yet)
        ev = seen[0]
        t_ref = first_touch_line(sa, q0, qv, 100.0, 510.0)
        assert abs(ev.time - t_ref) <= 1e-9 * t_ref
        # the obstacle keeps its velocity and straight path (moved once per step, by the movement system)
        t_now = w.step_count * w.dt
        np.testing.assert_array_equal(w.columns(Velocity, [b]).linear[0], qv)
        np.testing.assert_allclose(w.columns(Transform, [b]).position[0], q0 + qv * t_now, rtol=1e-13)
        # elastic in the obstacle's frame: the relative speed is kept, its normal part reversed
        x = w.columns(Transform, [a]).position[0]
        v = w.columns(Velocity, [a]).linear[0]
        _, back_v = kepler.propagate(x, v, MU, ev.time - t_now)
        _, pre_v = kepler.propagate(sa[0], sa[1], MU, ev.time)
        n = np.array(ev.normal)
        assert np.linalg.norm(back_v - qv) == pytest.approx(np.linalg.norm(pre_v - qv), rel=1e-9)
        assert float((back_v - qv) @ n) == pytest.approx(-float((pre_v - qv) @ n), rel=1e-9)
    finally:
        w.close()


def test_an_obstacle_that_is_not_touched_changes_nothing():
    # misses by a metre (outward 101 m > 100 m reach): no event, states bit-identical to no obstacle
    w, (a, _), _, _, seen = run_obstacle(dt=7.0, outward=101.0)
    w0, (a0, _), _, _, seen0 = run_obstacle(dt=7.0, obstacle=False)
    try:
        assert seen == [] and seen0 == []
        np.testing.assert_array_equal(w.columns(Transform, [a]).position, w0.columns(Transform, [a0]).position)
        np.testing.assert_array_equal(w.columns(Velocity, [a]).linear, w0.columns(Velocity, [a0]).linear)
    finally:
        w.close()
        w0.close()


@pytest.mark.parametrize("dt", [1.0, 5.0])
def test_a_body_at_rest_on_an_obstacle_does_not_sink_into_it(dt):
    # dropped from rest 1 m above a fixed obstacle, restitution 0: the well's full pull presses it on,
    # which the obstacle does not feel; one resting contact a step keeps it out (no sinking, no cascade)
    w = make(dt)
    a = w.create_entity(Transform((R_ORBIT, 0, 0)), Velocity((0, 0, 0)), SphereCollider(radius=40, restitution=0.0))
    b = w.create_entity(Transform((R_ORBIT - 81.0, 0, 0)), SphereCollider(radius=40, restitution=0.0))
    try:
        lowest = np.inf
        for _ in range(int(200 / dt)):
            w.step()
            lowest = min(lowest, float(w.columns(Transform, [a]).position[0, 0]) - (R_ORBIT - 81.0))
        assert lowest >= 80.0 - 1e-6                       # never closer than r_a + r_b
        hits = collisions(w)
        assert len(hits) >= int(200 / dt) - 1 and all((h.a, h.b) == (a, b) for h in hits)
        assert float(w.columns(Transform, [a]).position[0, 0]) - (R_ORBIT - 81.0) <= 80.0 + 9.81 * dt * dt / 8
    finally:
        w.close()


# -- straight-line (radial) orbits: h = 0, so e = 1 whatever the energy; a bound one falls back -------------
def apex_fall_time(r_max, x, one_minus_x):
    """s from rest at ``r_max`` down to ``x r_max`` on a straight line (radial Kepler free fall, closed form):
    ``t = sqrt(r_max^3 / (2 mu)) (sqrt(x (1 - x)) + arccos(sqrt(x)))``, with ``arccos(sqrt(x))`` written
    ``arcsin(sqrt(1 - x))`` and ``1 - x`` passed in, so a start just below the apex keeps its digits."""
    return math.sqrt(r_max ** 3 / (2 * MU)) * (math.sqrt(x * one_minus_x) + math.asin(math.sqrt(one_minus_x)))


def radial_contacts(r0, speed, count):
    """Times of the first ``count`` surface contacts of a body at ``r0`` moving straight out at ``speed``
    (m/s; negative: straight down), bouncing elastically: from the apex ``r_max = r0 / (1 - q/2)``,
    ``q = speed^2 r0 / mu`` (energy), where ``1 - r0/r_max = q/2`` exactly. Independent of kepler.py."""
    q = speed * speed * r0 / MU
    r_max = r0 / (1 - q / 2)
    # apex -> surface: 1 - R/r_max = (r0 - R + R q/2) / r0, its digits kept for a drop of metres
    down = apex_fall_time(r_max, R_EARTH / r_max, (r0 - R_EARTH + R_EARTH * q / 2) / r0)
    above = apex_fall_time(r_max, 1 - q / 2, q / 2)                       # apex -> r0
    first = down - above if speed < 0 else down + above
    return [first + 2 * k * down for k in range(count)]


#: (step s, release radius m): each step length with a fall of a few to thousands of steps.
RADIAL = [(1 / 60, R_EARTH + 500.0), (1.0, R_EARTH + 2e5), (60.0, 1e7), (3600.0, 1e7), (1e5, 1e8)]


@pytest.mark.parametrize("dt,r0", RADIAL)
@pytest.mark.parametrize("how", ["at rest", "straight up", "straight down"])
def test_a_body_on_a_straight_line_meets_the_surface_at_the_radial_fall_time_and_bounces(dt, r0, how):
    """A body released at rest, or thrown straight up or down, on rails: three surface contacts at the
    closed-form radial fall times (the first, then each bounce back up to the same apex and down), never
    below the surface at a step's end, its energy kept. (It fell through unseen when its e = 1 was taken
    for an escaping parabola's.)"""
    # half the speed of a fall from r0 to the surface, and under half the escape speed: bound
    fast = 0.5 * min(math.sqrt(2 * MU * (1 / R_EARTH - 1 / r0)), math.sqrt(2 * MU / r0))
    speed = {"at rest": 0.0, "straight up": fast, "straight down": -fast}[how]
    want = radial_contacts(r0, speed, 3)
    w = make(dt, collision_system=False)
    try:
        r_start, v_start = np.array([0.0, r0, 0.0]), np.array([0.0, speed, 0.0])
        body = w.create_entity(Transform(r_start), Velocity(v_start))
        lowest = np.inf
        while w.time < want[-1] + 0.5 * (want[1] - want[0]):
            w.step()
            lowest = min(lowest, float(np.linalg.norm(w.columns(Transform, [body]).position[0])))
        hits = [e for e in w.seen if isinstance(e, SurfaceContact)]
        want = radial_contacts(r0, speed, len(hits))                    # a long last step may hold a 4th
        assert len(hits) >= 3 and {h.entity for h in hits} == {body}
        # the first contact to rounding: a position is known to an ulp of R, at a slow contact (110 m/s)
        # 8e-12 s. Each bounce reflects a computed state: a rounding dv/v of its speed moves the next cycle
        # T ~ a^(3/2) by 3 (r_max/R - 1) dv/v of T (energy's conditioning), an ulp of its place a few ulp_time
        ulp_time = np.spacing(R_EARTH) / hits[0].speed
        r_max = r0 / (1 - speed * speed * r0 / MU / 2)
        per_bounce = 96 * np.finfo(float).eps * (r_max / R_EARTH - 1) * (want[1] - want[0]) + 4 * ulp_time
        for k, (h, t) in enumerate(zip(hits, want)):
            assert abs(h.time - t) <= 4e-15 * t + 1e-12 + ulp_time + k * per_bounce, (k, h.time, t, h.time - t)
            assert h.normal_speed == pytest.approx(h.speed, rel=1e-12)       # straight in
        assert lowest >= R_EARTH * (1 - 1e-12)
        r, v = w.columns(Transform, [body]).position[0], w.columns(Velocity, [body]).linear[0]
        assert abs(energy(r, v) / energy(r_start, v_start) - 1) < 1e-12
        assert abs(r[0]) + abs(r[2]) == 0.0 and abs(v[0]) + abs(v[2]) == 0.0   # still on its line
    finally:
        w.close()
