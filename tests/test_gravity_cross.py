"""Sphere contacts across frames: bodies on rails about different wells, rails against n-body, obstacles
against bodies about a moon, n-body against obstacles; nothing changed where nothing touches; a well's
own collider.

Every expected time comes from an independent search here (the world-frame gap sampled densely on the
exact conics -- :func:`framework.kepler.propagate` -- or on the leapfrog's straight drift replayed step
by step, then bisected), never from the system's own search; ``test_the_reference_searches_*`` check
those searches on their own.
"""
import functools
import math
import re
import warnings

import numpy as np
import pytest

from driftframe import CollisionSystem, Mass, MovementSystem, SphereCollider, Transform, Velocity, World
from driftframe.components.collision import CollisionEvent
from driftframe.components.gravity import GravityWell, NBody, SurfaceContact
from driftframe.framework import kepler
from driftframe.systems.gravity import GravitySystem
from test_gravity_contacts import bisect as contacts_bisect, collisions, states   # the same references

MU = 3.986004418e14
R_EARTH = 6.371e6
MU_MOON = 4.9048695e12
R_MOON = 1.7374e6
D_MOON = 3.844e8
M0 = np.array([D_MOON, 0.0, 0.0])                       # the moon at t = 0, on a circular orbit
MV0 = np.array([0.0, math.sqrt(MU / D_MOON), 0.0])
SOI = D_MOON * (MU_MOON / MU) ** 0.4                    # Laplace's sphere of influence, ~6.62e7 m


# -- worlds -----------------------------------------------------------------------------------------
def make(dt, moon=False, planet_collider=None, moon_collider=None):
    """Gravity + movement + collision, a planet at the origin (and its moon); every event kept."""
    w = World(dt=dt)
    w.add_system(GravitySystem())
    w.add_system(MovementSystem())
    w.add_system(CollisionSystem())
    comps = [Transform(), GravityWell(mu=MU, radius=R_EARTH)]
    if planet_collider is not None:
        comps.append(SphereCollider(radius=planet_collider))
    w.planet = w.create_entity(*comps)
    w.moon = None
    if moon:
        comps = [Transform(M0), Velocity(MV0), GravityWell(mu=MU_MOON, radius=R_MOON, parent=w.planet)]
        if moon_collider is not None:
            comps.append(SphereCollider(radius=moon_collider))
        w.moon = w.create_entity(*comps)
    w.seen = []
    w.subscribe(CollisionEvent, w.seen.append)
    w.subscribe(SurfaceContact, w.seen.append)
    return w


def body(w, x, v, radius, kg=None, nbody=False):
    comps = [Transform(x), Velocity(v), SphereCollider(radius=radius)]
    if kg is not None:
        comps.append(Mass(kg))
    if nbody:
        comps.append(NBody())
    return w.create_entity(*comps)


def obstacle(w, q0, qv, radius):
    """A collider gravity does not move: fixed (no Velocity) when ``qv`` is None, else Mass(inf)."""
    if qv is None:
        return w.create_entity(Transform(q0), SphereCollider(radius=radius))
    return w.create_entity(Transform(q0), Velocity(qv), Mass(math.inf), SphereCollider(radius=radius))


def check_event(ev, dt, method):
    """What every CollisionEvent holds: a < b, the method, a unit normal, the step and the time in it."""
    assert ev.a < ev.b and ev.method == method
    assert abs(np.linalg.norm(ev.normal) - 1.0) <= 1e-12
    assert 0.0 <= ev.step_time <= dt
    assert ev.step == int(ev.time // dt)
    assert abs(ev.step * dt + ev.step_time - ev.time) <= 1e-9 * max(ev.time, 1.0)


# -- exact paths and the independent searches -------------------------------------------------------
def unit(x):
    return np.asarray(x, float) / np.linalg.norm(x)


def conic(r0, v0, mu, t):
    """Positions and velocities on the exact two-body conic at the times ``t`` (an array)."""
    t = np.atleast_1d(np.asarray(t, float))
    return kepler.propagate(np.repeat(np.asarray(r0, float)[None], t.size, 0),
                            np.repeat(np.asarray(v0, float)[None], t.size, 0), mu, t)


def moon_at(t):
    return conic(M0, MV0, MU, t)


def about_moon(rel0, t):
    """World position and velocity of a body on rails about the moon (the moon's conic + its own)."""
    X, V = moon_at(t)
    r, v = conic(rel0[0], rel0[1], MU_MOON, t)
    return X + r, V + v


def bisect(gap, lo, hi):
    """The time in (lo, hi] where ``gap`` (positive at lo, <= 0 at hi) reaches 0; the bracket is checked."""
    assert gap(lo) > 0 >= gap(hi)
    return contacts_bisect(gap, lo, hi)


def first_touch(gap, t_end, samples=300_000):
    """First zero of a vectorised ``gap(ts)`` on [0, t_end]: dense samples, then bisection."""
    ts = np.linspace(0.0, t_end, samples + 1)
    g = gap(ts)
    k = int(np.flatnonzero(g <= 0)[0])
    assert k > 0
    return bisect(lambda t: float(gap(np.array([t]))[0]), ts[k - 1], ts[k])


def acc_planet(x):
    return -MU * x / np.linalg.norm(x) ** 3


def leapfrog(x0, v0, dt, n):
    """The n-body kick-drift-kick replayed (one planet fixed at the origin): each step's drift start
    and drift velocity ``u = v + dt/2 a(x)``; the drift is ``p + u s`` for s in [0, dt]."""
    P, U = np.empty((n, 3)), np.empty((n, 3))
    x, v = np.array(x0, float), np.array(v0, float)
    for k in range(n):
        u = v + 0.5 * dt * acc_planet(x)
        P[k], U[k] = x, u
        x = x + u * dt
        v = u + 0.5 * dt * acc_planet(x)
    return P, U


def first_touch_drift(P, U, dt, other, reach, samples=240_000):
    """First contact of the drift lines (P, U) with a path ``other(ts) -> positions``: each step sampled
    densely on its own line, the first sign change bisected on that step's line."""
    n = len(P)
    m = max(64, samples // n)
    s = np.linspace(0.0, dt, m + 1)
    steps = np.repeat(np.arange(n), m + 1)
    ss = np.tile(s, n)
    t = steps * dt + ss
    g = np.linalg.norm(other(t) - (P[steps] + U[steps] * ss[:, None]), axis=1) - reach
    k = int(np.flatnonzero(g <= 0)[0])
    assert k > 0 and steps[k] == steps[k - 1]
    j = int(steps[k])

    def gap(sj):                                   # (the same operations as the samples: the same values)
        return float(np.linalg.norm(other(np.array([j * dt + sj]))[0] - (P[j] + U[j] * sj)) - reach)
    return j * dt + bisect(gap, ss[k - 1], ss[k]), j


def first_touch_line(P, U, dt, q0, qv, reach):
    """First contact of the drift lines (P, U) with a sphere moving on q0 + qv t: closed-form quadratic
    per step, the smaller root of the first step where the pair closes and touches within [0, dt]."""
    t0 = np.arange(len(P)) * dt
    d0 = P - (q0 + qv * t0[:, None])
    w = U - qv
    a = np.einsum("ij,ij->i", w, w)
    b = np.einsum("ij,ij->i", d0, w)
    c = np.einsum("ij,ij->i", d0, d0) - reach * reach
    disc = b * b - a * c
    s = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
    ok = (b < 0) & (disc >= 0) & (c > 0) & (s <= dt)
    j = int(np.flatnonzero(ok)[0])
    return float(t0[j] + s[j]), j


def tilt(w_hat, away, angle_deg):
    """The unit vector ``angle_deg`` from ``w_hat`` towards ``away`` (an off-centre contact normal)."""
    k = np.asarray(away, float) - (np.asarray(away, float) @ w_hat) * w_hat
    a = math.radians(angle_deg)
    return unit(math.cos(a) * w_hat + math.sin(a) * unit(k))


def elastic_impulse(ma, mb, va, vb, n, e=1.0):
    """J = (1+e) m_a m_b / (m_a+m_b) * closing normal speed (n from a to b)."""
    return (1.0 + e) * ma * mb / (ma + mb) * float(-(vb - va) @ n)


# -- scene 1: a station on rails about the moon, a ship on rails about the planet -------------------
T1 = 1523.7137
R1 = 500.0                                  # both colliders: 1,000 m between centres at contact
KG_STATION, KG_SHIP = 4e4, 1e4


@functools.lru_cache(maxsize=None)
def scene1():
    """Initial world states (station, ship) that put the station 300 m inside the moon's sphere and the
    ship 700 m outside it, 1,000 m apart along the moon's radial ``c`` and closing at 50 m/s, at T1.
    Untouched, the ship's conic would enter the moon's sphere ~14 s after T1 (in the 50 s and 3,000 s
    steps the contact and that crossing fall in one step: the contact comes first and sends it out)."""
    MT, VT = (a[0] for a in moon_at(T1))
    c = unit([0.3, -1.0, 0.25])
    t_hat = unit(np.cross([0.0, 0.0, 1.0], c))
    t2 = np.cross(c, t_hat)
    rs = (SOI - 300.0) * c
    vs = math.sqrt(MU_MOON / np.linalg.norm(rs)) * t_hat              # circular about the moon
    ship_T = MT + (SOI + 700.0) * c
    ship_vT = VT + vs - 50.0 * c + 100.0 * t2
    r0, v0 = (a[0] for a in conic(rs, vs, MU_MOON, -T1))
    station = (M0 + r0, MV0 + v0)
    ship = tuple(a[0] for a in conic(ship_T, ship_vT, MU, -T1))
    return station, ship


def station_rel0():
    station, _ = scene1()
    return station[0] - M0, station[1] - MV0      # (the subtraction the system makes at its first epoch)


def gap1(ts):
    station, ship = scene1()
    ps, _ = about_moon(station_rel0(), ts)
    pp, _ = conic(ship[0], ship[1], MU, ts)
    return np.linalg.norm(pp - ps, axis=1) - 2 * R1


@functools.lru_cache(maxsize=None)
def ref1():
    return first_touch(gap1, T1 + 20.0)


def pre1(t):
    """World states of (station, ship) on their reference paths at time t."""
    station, ship = scene1()
    ps, vs = about_moon(station_rel0(), t)
    pp, vp = conic(ship[0], ship[1], MU, t)
    return (ps[0], vs[0]), (pp[0], vp[0])


def run1(dt):
    station, ship = scene1()
    w = make(dt, moon=True)
    a = body(w, *station, R1, KG_STATION)
    b = body(w, *ship, R1, KG_SHIP)
    w.step(int(math.ceil((T1 + 10.0) / dt)))
    return w, a, b


# -- scene 2/4: an n-body body in low orbit (leapfrog), met by a body on rails or an obstacle -------------
NB0 = (np.array([9e6, 0.0, 0.0]), np.array([0.0, 7000.0, 2000.0]))
T2, T4 = 612.3137, 433.3071
R2_RAILS, R2_NB, KG2_RAILS, KG2_NB = 300.0, 200.0, 3e3, 1e3
R4_NB, R4_OB, KG4 = 50.0, 150.0, 5.0


@functools.lru_cache(maxsize=None)
def scene2(dt):
    """The n-body path for this dt, and a body on rails placed to touch its drift at T2, off centre."""
    k = int(T2 // dt)
    P, U = leapfrog(*NB0, dt, k + 1)
    p, u = P[k] + U[k] * (T2 - k * dt), U[k]
    v_r = math.sqrt(MU / np.linalg.norm(p)) * unit(np.cross(p, [0.0, 1.0, 1.0]))
    e_hat = tilt(unit(u - v_r), [0.0, 0.0, 1.0], 25.0)                   # from the n-body body to the rails
    rails = tuple(a[0] for a in conic(p + (R2_RAILS + R2_NB) * e_hat, v_r, MU, -T2))
    t_ref, j = first_touch_drift(P, U, dt, lambda t: conic(*rails, MU, t)[0], R2_RAILS + R2_NB)
    return rails, P, U, t_ref, j


@functools.lru_cache(maxsize=None)
def scene4(dt, moving):
    """The n-body path for this dt and an obstacle placed to touch its drift at T4, off centre."""
    k = int(T4 // dt)
    P, U = leapfrog(*NB0, dt, k + 1)
    p, u = P[k] + U[k] * (T4 - k * dt), U[k]
    qv = np.array([-300.0, 150.0, 20.0]) if moving else np.zeros(3)
    e_hat = tilt(unit(u - qv), [1.0, 0.0, 0.0], 25.0)                    # from the n-body body to the obstacle
    q0 = p + (R4_NB + R4_OB) * e_hat - qv * T4
    t_ref, j = first_touch_line(P, U, dt, q0, qv, R4_NB + R4_OB)
    return q0, qv, P, U, t_ref, j


# -- scene 3: a body on rails about the moon against an obstacle -----------------------------------------
T3 = 987.6071
R3_BODY, R3_OB, KG3 = 40.0, 60.0, 2.0


@functools.lru_cache(maxsize=None)
def scene3(moving):
    """A body in a polar circular orbit 2,200 km from the moon's centre, and an obstacle 100 m from it at
    T3 (off centre, on the moon's side, so the bounce sends it outward, clear of the surface)."""
    MT, VT = (a[0] for a in moon_at(T3))
    r_rel = np.array([2.2e6, 0.0, 0.0])
    v_rel = np.array([0.0, 0.0, math.sqrt(MU_MOON / 2.2e6)])
    qv = np.array([-300.0, 150.0, 20.0]) if moving else np.zeros(3)
    e_hat = tilt(unit(VT + v_rel - qv), [-1.0, 0.0, 0.0], 25.0)        # from the body to the obstacle
    q0 = MT + r_rel + (R3_BODY + R3_OB) * e_hat - qv * T3
    r0, v0 = (a[0] for a in conic(r_rel, v_rel, MU_MOON, -T3))
    x0, u0 = M0 + r0, MV0 + v0
    rel0 = (x0 - M0, u0 - MV0)

    def gap(ts):
        pb, _ = about_moon(rel0, ts)
        return np.linalg.norm(pb - (q0 + qv * ts[:, None]), axis=1) - (R3_BODY + R3_OB)
    return (x0, u0), rel0, q0, qv, first_touch(gap, T3 + 20.0), gap


# -- the reference searches, checked on their own --------------------------------------------------------
def test_the_reference_search_across_the_moons_sphere_is_right_and_the_scene_is_as_described():
    """The gap is 0 at the reference time (= the constructed T1), positive before, closing; the station
    stays inside the moon's sphere and the ship outside it until the contact."""
    t = ref1()
    assert abs(t - T1) <= 1e-9 * T1
    assert abs(gap1(np.array([t]))[0]) <= 1e-6
    assert gap1(np.array([t - 1e-3]))[0] > 0 > gap1(np.array([t + 1e-3]))[0]
    ts = np.linspace(0.0, t, 20_001)
    assert (gap1(ts[:-1]) > 0).all()
    station, ship = scene1()
    ps, _ = about_moon(station_rel0(), ts)
    pp, _ = conic(ship[0], ship[1], MU, ts)
    X, _ = moon_at(ts)
    assert (np.linalg.norm(ps - X, axis=1) < SOI).all()
    assert (np.linalg.norm(pp - X, axis=1) > SOI).all()
    assert np.linalg.norm(pp[0] - X[0]) > SOI + 10e3                   # well outside at the start
    (_, vs), (_, vp) = pre1(t)
    n = unit(pre1(t)[1][0] - pre1(t)[0][0])
    assert float((vp - vs) @ n) == pytest.approx(-50.0, rel=1e-3)


@pytest.mark.parametrize("dt", [1.0, 10.0, 120.0])
def test_the_reference_searches_on_the_drift_are_right(dt):
    """Rails vs drift and line vs drift: the gap is 0 at the reference time and positive just before,
    the constructed contact time is what the searches find."""
    rails, P, U, t_ref, j = scene2(dt)
    assert abs(t_ref - T2) <= 1e-9 * T2 and j == int(T2 // dt)

    def g2(t):
        return float(np.linalg.norm(conic(*rails, MU, t)[0][0] - (P[j] + U[j] * (t - j * dt)))) - 500.0
    assert abs(g2(t_ref)) <= 1e-6 and g2(t_ref - 1e-4) > 0 > g2(t_ref + 1e-4)
    rr, _ = conic(*rails, MU, np.linspace(0, T2 + 100, 2001))
    assert (np.linalg.norm(rr, axis=1) > R_EARTH + 1e5).all()         # no surface contact on the way
    for moving in (False, True):
        q0, qv, P4, U4, t4, j4 = scene4(dt, moving)
        assert abs(t4 - T4) <= 1e-9 * T4 and j4 == int(T4 // dt)

        def g4(t):
            return float(np.linalg.norm(P4[j4] + U4[j4] * (t - j4 * dt) - (q0 + qv * t))) - 200.0
        assert abs(g4(t4)) <= 1e-6 and g4(t4 - 1e-4) > 0 > g4(t4 + 1e-4)
        # and the dense search on the drift agrees with the closed form
        t_dense, _ = first_touch_drift(P4, U4, dt, lambda t: q0 + qv * t[:, None], 200.0)
        assert abs(t_dense - t4) <= 1e-9 * t4


@pytest.mark.parametrize("moving", [False, True])
def test_the_reference_search_about_the_moon_against_an_obstacle_is_right(moving):
    """The body's world path (moon's conic + its own) is 100 m from the obstacle at T3, not before."""
    _, _, _, _, t_ref, gap = scene3(moving)
    assert abs(t_ref - T3) <= 1e-9 * T3
    assert abs(gap(np.array([t_ref]))[0]) <= 1e-6
    assert gap(np.array([t_ref - 1e-4]))[0] > 0 > gap(np.array([t_ref + 1e-4]))[0]


# -- 1. bodies on rails about different wells ---------------------------------------------------------
@pytest.mark.parametrize("dt", [1.0, 50.0, 3000.0])
def test_a_body_about_the_moon_and_one_about_the_planet_touch_at_the_reference_time(dt):
    """Across the moon's sphere: one event at the independent time at any step (one 3,000 s step too),
    elastic in the world frame (energy and momentum kept), impulse as the formula gives."""
    w, a, b = run1(dt)
    try:
        hits = collisions(w)
        assert len(hits) == 1, hits
        (xs, xp), (us, up) = states(w, [a, b])
        (xm,), (um,) = states(w, [w.moon])
        verify1(dt, hits[0], a, b, w.step_count * dt, xs, us, xp, up, xm, um)
    finally:
        w.close()


def verify1(dt, ev, a, b, t_now, xs, us, xp, up, xm, um):
    """Test 1's checks of the event and of the end-of-run states (station xs, us; ship xp, up; moon)."""
    check_event(ev, dt, "kepler")
    assert (ev.a, ev.b) == (a, b)
    t_ref = ref1()
    assert abs(ev.time - t_ref) <= 1e-9 * t_ref
    (pa, va), (pb, vb) = pre1(ev.time)
    n = unit(pb - pa)
    np.testing.assert_allclose(ev.normal, n, atol=1e-9)
    np.testing.assert_allclose(ev.point, pa + R1 * n, rtol=0, atol=1e-5)
    assert ev.impulse == pytest.approx(elastic_impulse(KG_STATION, KG_SHIP, va, vb, n), rel=1e-9)
    # after it: each body back along its own conic from the end of the run to the contact
    assert np.linalg.norm(xs - xm) < SOI < np.linalg.norm(xp - xm)          # still in their frames
    rs, ws = (q[0] for q in conic(xs - xm, us - um, MU_MOON, ev.time - t_now))
    X, V = (q[0] for q in moon_at(ev.time))
    rp, wp = (q[0] for q in conic(xp, up, MU, ev.time - t_now))
    np.testing.assert_allclose(X + rs, pa, rtol=0, atol=1e-3)
    np.testing.assert_allclose(rp, pb, rtol=0, atol=1e-3)
    va2, vb2 = V + ws, wp
    p0 = KG_STATION * va + KG_SHIP * vb
    p1 = KG_STATION * va2 + KG_SHIP * vb2
    assert np.linalg.norm(p1 - p0) <= 1e-12 * (KG_STATION * np.linalg.norm(va) + KG_SHIP * np.linalg.norm(vb))
    ke0 = 0.5 * (KG_STATION * va @ va + KG_SHIP * vb @ vb)
    ke1 = 0.5 * (KG_STATION * va2 @ va2 + KG_SHIP * vb2 @ vb2)
    assert abs(ke1 / ke0 - 1.0) <= 1e-9
    np.testing.assert_allclose(vb2 - vb, ev.impulse * n / KG_SHIP, rtol=0, atol=1e-8)
    assert float((vb2 - va2) @ n) == pytest.approx(-float((vb - va) @ n), rel=1e-9)


# -- 2. a body on rails against an n-body body ----------------------------------------------------------
@pytest.mark.parametrize("dt", [1.0, 10.0, 120.0])
def test_a_body_on_rails_meets_an_n_body_body_on_its_drift(dt):
    """Rails conic vs the leapfrog's drift line: one event at the reference time, the elastic impulse
    from the conic velocity and the drift velocity, momentum kept, apart afterwards."""
    rails, P, U, t_ref, j = scene2(dt)
    w = make(dt)
    try:
        nb = body(w, *NB0, R2_NB, KG2_NB, nbody=True)
        r = body(w, *rails, R2_RAILS, KG2_RAILS)
        w.step(j + 1)                                                 # to the end of the contact step
        hits = collisions(w)
        assert len(hits) == 1, hits
        (xn, xr), (vn1, vr1) = states(w, [nb, r])
        verify2(dt, hits[0], nb, r, w.step_count * dt, xn, vn1, xr, vr1)
        # apart afterwards: at the end of this step and of each of the next ones
        for _ in range(6):
            x, _ = states(w, [nb, r])
            assert np.linalg.norm(x[1] - x[0]) >= (R2_NB + R2_RAILS) * (1 - 1e-9)
            w.step()
        assert len(collisions(w)) == 1
    finally:
        w.close()


def verify2(dt, ev, nb, r, t_now, xn, vn1, xr, vr1):
    """Test 2's checks of the event and of the states at the end of the contact step."""
    rails, P, U, t_ref, j = scene2(dt)
    check_event(ev, dt, "kepler")
    assert (ev.a, ev.b) == (nb, r)
    assert abs(ev.time - t_ref) <= 1e-9 * t_ref
    pr, vr = (q[0] for q in conic(*rails, MU, ev.time))
    pn, un = P[j] + U[j] * (ev.time - j * dt), U[j]
    n = unit(pr - pn)                                                 # from a (the n-body body) to b
    np.testing.assert_allclose(ev.normal, n, atol=1e-8)
    np.testing.assert_allclose(ev.point, pn + R2_NB * n, rtol=0, atol=1e-3)
    assert ev.impulse == pytest.approx(elastic_impulse(KG2_NB, KG2_RAILS, un, vr, n), rel=1e-9)
    # momentum: the rails body back on its new conic, the n-body body's drift velocity after the
    # contact (its end-of-step velocity less the closing half kick)
    _, vr_post = (q[0] for q in conic(xr, vr1, MU, ev.time - t_now))
    un_post = vn1 - 0.5 * dt * acc_planet(xn)
    p0 = KG2_NB * un + KG2_RAILS * vr
    p1 = KG2_NB * un_post + KG2_RAILS * vr_post
    assert np.linalg.norm(p1 - p0) <= 1e-9 * np.linalg.norm(KG2_RAILS * vr)
    assert float((vr_post - un_post) @ n) == pytest.approx(-float((vr - un) @ n), rel=1e-9)


# -- 3. an obstacle against a body on rails about a moon -----------------------------------------------
@pytest.mark.parametrize("moving", [False, True], ids=["fixed", "moving"])
@pytest.mark.parametrize("dt", [1.0, 37.0, 1500.0])
def test_a_body_on_rails_about_the_moon_meets_an_obstacle(dt, moving):
    """The body's world path (moon's conic + its own) against the obstacle's line: one event at the
    reference time at any step, the obstacle unmoved by it, the relative normal velocity reversed."""
    (x0, u0), rel0, q0, qv, t_ref, _ = scene3(moving)
    w = make(dt, moon=True)
    try:
        a = body(w, x0, u0, R3_BODY, KG3)
        o = obstacle(w, q0, qv if moving else None, R3_OB)
        w.step(int(math.ceil((T3 + 5.0) / dt)))
        assert not [e for e in w.seen if isinstance(e, SurfaceContact)]
        hits = collisions(w)
        assert len(hits) == 1, hits
        (x,), (v,) = states(w, [a])
        (xm,), (vm,) = states(w, [w.moon])
        xo = w.columns(Transform, [o]).position[0].copy()
        vo = w.columns(Velocity, [o]).linear[0].copy() if moving else None
        verify3(dt, moving, hits[0], a, o, w.step_count * dt, x, v, xm, vm, xo, vo)
    finally:
        w.close()


def check_obstacle_contact(ev, p, u, radius, kg, q0, qv, moving, t_now, xo, vo):
    """A body of ``radius`` and ``kg`` at ``p`` with velocity ``u`` at the contact, against an obstacle on
    ``q0 + qv t`` (``qv`` zero when it is fixed): the event's normal, point and elastic impulse (the
    obstacle's inverse mass is 0), and the obstacle's own state at ``t_now``, untouched. Returns the normal."""
    n = unit(q0 + qv * ev.time - p)
    np.testing.assert_allclose(ev.normal, n, atol=1e-8)
    np.testing.assert_allclose(ev.point, p + radius * n, rtol=0, atol=1e-3)
    assert ev.impulse == pytest.approx(2.0 * kg * float((u - qv) @ n), rel=1e-9)
    if moving:
        np.testing.assert_array_equal(vo, qv)
        np.testing.assert_allclose(xo, q0 + qv * t_now, rtol=1e-13)
    else:
        np.testing.assert_array_equal(xo, q0)
    return n


def verify3(dt, moving, ev, a, o, t_now, x, v, xm, vm, xo, vo):
    """Test 3's checks of the event and of the end-of-run states (body x, v; moon; obstacle)."""
    (x0, u0), rel0, q0, qv, t_ref, _ = scene3(moving)
    check_event(ev, dt, "kepler")
    assert (ev.a, ev.b) == (a, o)
    assert abs(ev.time - t_ref) <= 1e-9 * t_ref
    pb, vb = (q[0] for q in about_moon(rel0, ev.time))
    n = check_obstacle_contact(ev, pb, vb, R3_BODY, KG3, q0, qv, moving, t_now, xo, vo)
    # the body after it, back on its conic about the moon to the contact, in the world frame
    assert np.linalg.norm(x - xm) < SOI
    r_back, v_back = (q[0] for q in conic(x - xm, v - vm, MU_MOON, ev.time - t_now))
    X, V = (q[0] for q in moon_at(ev.time))
    np.testing.assert_allclose(X + r_back, pb, rtol=0, atol=1e-3)
    v_post = V + v_back
    assert float((v_post - qv) @ n) == pytest.approx(-float((vb - qv) @ n), rel=1e-9)
    assert np.linalg.norm(v_post - qv) == pytest.approx(np.linalg.norm(vb - qv), rel=1e-9)


# -- 4. an n-body body against an obstacle ------------------------------------------------------------------
@pytest.mark.parametrize("moving", [False, True], ids=["fixed", "moving"])
@pytest.mark.parametrize("dt", [1.0, 10.0, 120.0])
def test_an_n_body_body_meets_an_obstacle_on_its_drift(dt, moving):
    """The drift line of the contact step against the obstacle's line (a quadratic): the time, the
    obstacle's velocity unchanged, the n-body body's normal velocity relative to it reversed."""
    q0, qv, P, U, t_ref, j = scene4(dt, moving)
    w = make(dt)
    try:
        nb = body(w, *NB0, R4_NB, KG4, nbody=True)
        o = obstacle(w, q0, qv if moving else None, R4_OB)
        w.step(j + 1)
        hits = collisions(w)
        assert len(hits) == 1, hits
        (x,), (v,) = states(w, [nb])
        xo = w.columns(Transform, [o]).position[0].copy()
        vo = w.columns(Velocity, [o]).linear[0].copy() if moving else None
        verify4(dt, moving, hits[0], nb, o, w.step_count * dt, x, v, xo, vo)
        for _ in range(5):                                            # and apart afterwards
            w.step()
            xo = w.columns(Transform, [o]).position[0]
            assert np.linalg.norm(w.columns(Transform, [nb]).position[0] - xo) >= (R4_NB + R4_OB) * (1 - 1e-9)
        assert len(collisions(w)) == 1
    finally:
        w.close()


def verify4(dt, moving, ev, nb, o, t_now, x, v, xo, vo):
    """Test 4's checks of the event and of the states at the end of the contact step."""
    q0, qv, P, U, t_ref, j = scene4(dt, moving)
    check_event(ev, dt, "leapfrog")
    assert (ev.a, ev.b) == (nb, o)
    assert abs(ev.time - t_ref) <= 1e-9 * t_ref
    pn, un = P[j] + U[j] * (ev.time - j * dt), U[j]
    n = check_obstacle_contact(ev, pn, un, R4_NB, KG4, q0, qv, moving, t_now, xo, vo)
    # the drift after the contact: the end-of-step velocity less the closing half kick; straight on
    # from the contact point to the step's end
    u_post = v - 0.5 * dt * acc_planet(x)
    assert float((u_post - qv) @ n) == pytest.approx(-float((un - qv) @ n), rel=1e-9)
    tang = (un - qv) - float((un - qv) @ n) * n
    np.testing.assert_allclose((u_post - qv) - float((u_post - qv) @ n) * n, tang, rtol=0, atol=1e-6)
    np.testing.assert_allclose(x, pn + u_post * (t_now - ev.time), rtol=0, atol=1e-2)


# -- 5. nothing is changed where nothing touches ------------------------------------------------------------
def mixed_scene(colliders):
    """Two wells, bodies on rails about each, two n-body bodies, a fixed and a moving obstacle, all
    thousands of km apart for the whole run."""
    w = make(20.0, moon=True)
    sc = (lambda r: [SphereCollider(radius=r)]) if colliders else (lambda r: [])
    ents = []
    for k in range(4):                                                # about the planet
        ang = 0.5 * math.pi * k
        r = 7e6 + 4e5 * k
        x = r * np.array([math.cos(ang), math.sin(ang), 0.0])
        v = math.sqrt(MU / r) * np.array([-math.sin(ang), math.cos(ang), 0.0])
        ents.append(w.create_entity(Transform(x), Velocity(v), Mass(10.0 + k), *sc(300.0)))
    for k in range(3):                                                # about the moon
        ang = 2 * math.pi * k / 3
        r = 2.5e6 + 2e5 * k
        x = r * np.array([math.cos(ang), 0.0, math.sin(ang)])
        v = math.sqrt(MU_MOON / r) * np.array([-math.sin(ang), 0.0, math.cos(ang)])
        ents.append(w.create_entity(Transform(M0 + x), Velocity(MV0 + v), Mass(5.0), *sc(300.0)))
    for k in range(2):                                                # n-body, far out
        r = 3e7 + 5e6 * k
        ents.append(w.create_entity(Transform((0.0, -r, 0.0)), Velocity((math.sqrt(MU / r), 0.0, 100.0 * k)),
                                    Mass(1e3), NBody(), *sc(300.0)))
    ents.append(w.create_entity(Transform((-6e7, 0.0, 0.0)), Velocity((0.0, 50.0, 0.0)), Mass(math.inf),
                                *sc(500.0)))                                                   # moving
    ents.append(w.moon)
    fixed = w.create_entity(Transform((0.0, 6e7, 0.0)), *sc(500.0))
    return w, ents, fixed


def test_colliders_of_every_kind_that_never_touch_change_nothing():
    """The same mixed scene with and without SphereColliders: no event, bit-identical states each step."""
    runs = [mixed_scene(c) for c in (False, True)]
    try:
        for _ in range(60):
            out = []
            for w, ents, fixed in runs:
                w.step()
                out.append(states(w, ents) + (w.columns(Transform, [fixed]).position.copy(),))
            (x0, v0, f0), (x1, v1, f1) = out
            assert np.array_equal(x0, x1) and np.array_equal(v0, v1) and np.array_equal(f0, f1)
        assert not collisions(runs[1][0]) and not collisions(runs[0][0])
        assert runs[0][0].seen == runs[1][0].seen
    finally:
        for w, _, _ in runs:
            w.close()


# -- 6. a well's own SphereCollider -----------------------------------------------------------------------
def mentions(text, x):
    """``text`` gives the length ``x`` (m) in one of the usual renderings (repr, %g, whole metres, km)."""
    forms = {repr(float(x)), f"{x:g}", f"{x:.6g}", f"{x:.0f}", f"{x:,.0f}", f"{x / 1e3:g}", f"{x / 1e3:.6g}"}
    return any(f in text for f in forms)


def fall_scene(dt, on_moon, collider_radius):
    """A body dropped towards the planet (or the moon) whose well carries a SphereCollider."""
    w = make(dt, moon=True, planet_collider=None if on_moon else collider_radius,
             moon_collider=collider_radius if on_moon else None)
    if on_moon:
        rel0 = (np.array([0.0, 0.0, 2.5e6]), np.array([300.0, 0.0, -900.0]))
        x0, v0 = M0 + rel0[0], MV0 + rel0[1]
    else:
        rel0 = (np.array([0.0, 0.0, 8e6]), np.array([1000.0, 0.0, -2000.0]))
        x0, v0 = rel0
    b = body(w, x0, v0, 40.0)
    return w, b, (x0 - M0, v0 - MV0) if on_moon else rel0


@pytest.mark.parametrize("on_moon", [False, True], ids=["planet", "moon"])
def test_a_wells_own_collider_of_another_radius_is_not_used_and_warned_of_once(on_moon):
    """Bodies meet the well's surface (GravityWell.radius) at the independent time, no CollisionEvent,
    and one RuntimeWarning naming the well and both radii."""
    R = R_MOON if on_moon else R_EARTH
    mu = MU_MOON if on_moon else MU
    big = 1.25 * R
    w, b, rel0 = fall_scene(5.0, on_moon, big)
    try:
        well = w.moon if on_moon else w.planet
        with pytest.warns(RuntimeWarning, match="SphereCollider") as rec:
            w.step(400)
        ours = [r for r in rec if issubclass(r.category, RuntimeWarning) and "SphereCollider" in str(r.message)]
        assert len(ours) == 1
        msg = str(ours[0].message)
        assert re.search(rf"(entity|well)\s+{well}\b", msg, re.I), msg
        assert mentions(msg, R) and mentions(msg, big), msg
        assert re.search(r"not used|unused|ignored|no effect|not applied", msg, re.I), msg
        assert not collisions(w)
        touch = [e for e in w.seen if isinstance(e, SurfaceContact)]
        assert touch and touch[0].entity == b and touch[0].well == well
        t_ref = first_touch(lambda ts: np.linalg.norm(conic(*rel0, mu, ts)[0], axis=1) - R, 2000.0)
        assert abs(touch[0].time - t_ref) <= 1e-9 * t_ref
    finally:
        w.close()


@pytest.mark.parametrize("on_moon", [False, True], ids=["planet", "moon"])
def test_a_wells_own_collider_of_its_own_radius_gives_no_warning(on_moon):
    """A SphereCollider of the well's radius: silent, and the surface met as without it."""
    R = R_MOON if on_moon else R_EARTH
    w, b, _ = fall_scene(5.0, on_moon, R)
    w0, b0, _ = fall_scene(5.0, on_moon, None)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            w.step(400)
        w0.step(400)
        touch = [e for e in w.seen if isinstance(e, SurfaceContact)]
        assert touch and touch == [e for e in w0.seen if isinstance(e, SurfaceContact)]
        assert not collisions(w)
        np.testing.assert_array_equal(states(w, [b])[0], states(w0, [b0])[0])
    finally:
        w.close()
        w0.close()


# -- the checks themselves accept the exact outcome ----------------------------------------------------------
def _event(a, b, tc, dt, pa, n, ra, J, method):
    k = int(tc // dt)
    return CollisionEvent(a, b, float(tc), float(tc - k * dt), tuple(pa + ra * n), tuple(n), float(J), method, k)


@pytest.mark.parametrize("dt", [1.0, 3000.0])
def test_the_checks_pass_for_the_exact_outcome(dt):
    """verify1..4 fed the exact outcome (the elastic impulse at the reference time, each body on from it
    on its conic or drift): their tolerances are met by the references, so a failure is the system's."""
    # 1: station (a) and ship (b) across the moon's sphere
    tc = ref1()
    (pa, va), (pb, vb) = pre1(tc)
    n = unit(pb - pa)
    J = elastic_impulse(KG_STATION, KG_SHIP, va, vb, n)
    t_now = math.ceil((T1 + 10.0) / dt) * dt
    X, V = (q[0] for q in moon_at(tc))
    xm, um = (q[0] for q in moon_at(t_now))
    rs, ws = (q[0] for q in conic(pa - X, va - J * n / KG_STATION - V, MU_MOON, t_now - tc))
    xp, up = (q[0] for q in conic(pb, vb + J * n / KG_SHIP, MU, t_now - tc))
    verify1(dt, _event(3, 4, tc, dt, pa, n, R1, J, "kepler"), 3, 4, t_now, xm + rs, um + ws, xp, up, xm, um)
    # 3: a body about the moon (a) and an obstacle (b)
    for moving in (False, True):
        _, rel0, q0, qv, tc, _ = scene3(moving)
        pb, vb = (q[0] for q in about_moon(rel0, tc))
        n = unit(q0 + qv * tc - pb)
        J = 2.0 * KG3 * float((vb - qv) @ n)
        t_now = math.ceil((T3 + 5.0) / dt) * dt
        X, V = (q[0] for q in moon_at(tc))
        xm, vm = (q[0] for q in moon_at(t_now))
        r, u = (q[0] for q in conic(pb - X, vb - J * n / KG3 - V, MU_MOON, t_now - tc))
        verify3(dt, moving, _event(3, 4, tc, dt, pb, n, R3_BODY, J, "kepler"), 3, 4, t_now, xm + r, vm + u, xm, vm,
                q0 + qv * t_now if moving else q0.copy(), qv.copy() if moving else None)
    dt = min(dt, 120.0)
    # 2: an n-body body (a) and a body on rails (b)
    rails, P, U, tc, j = scene2(dt)
    pr, vr = (q[0] for q in conic(*rails, MU, tc))
    pn, un = P[j] + U[j] * (tc - j * dt), U[j]
    n = unit(pr - pn)
    J = elastic_impulse(KG2_NB, KG2_RAILS, un, vr, n)
    t_now = (j + 1) * dt
    u2 = un - J * n / KG2_NB
    xn = pn + u2 * (t_now - tc)
    xr, vr1 = (q[0] for q in conic(pr, vr + J * n / KG2_RAILS, MU, t_now - tc))
    verify2(dt, _event(2, 3, tc, dt, pn, n, R2_NB, J, "kepler"), 2, 3, t_now, xn,
            u2 + 0.5 * dt * acc_planet(xn), xr, vr1)
    # 4: an n-body body (a) and an obstacle (b)
    for moving in (False, True):
        q0, qv, P, U, tc, j = scene4(dt, moving)
        pn, un = P[j] + U[j] * (tc - j * dt), U[j]
        n = unit(q0 + qv * tc - pn)
        J = 2.0 * KG4 * float((un - qv) @ n)
        u2 = un - J * n / KG4
        t_now = (j + 1) * dt
        x = pn + u2 * (t_now - tc)
        verify4(dt, moving, _event(2, 3, tc, dt, pn, n, R4_NB, J, "leapfrog"), 2, 3, t_now, x,
                u2 + 0.5 * dt * acc_planet(x), q0 + qv * t_now if moving else q0.copy(), qv.copy() if moving else None)


@pytest.mark.parametrize("dt", [1.0, 50.0])
def test_the_warp_look_ahead_predicts_the_contact_across_the_moons_sphere(dt):
    """GravitySystem.next_sphere_contact (what the warp governor slows down for) sees the contact of a
    body about the moon with one about the planet ahead of time, at the time the step then finds."""
    station, ship = scene1()
    w = make(dt, moon=True)
    try:
        a = body(w, *station, R1, KG_STATION)
        b = body(w, *ship, R1, KG_SHIP)
        w.step(1)
        from driftframe.systems.gravity import GravitySystem
        g = w.get_system(GravitySystem)
        ahead = g.next_sphere_contact(2 * T1)
        assert ahead is not None and (ahead.a, ahead.b) == tuple(sorted((a, b))) and not ahead.bound
        assert ahead[0] == pytest.approx(ref1(), rel=1e-9)
        assert g.next_sphere_contact(0.5 * (ref1() - dt)) is None      # not within a shorter horizon
    finally:
        w.close()


@pytest.mark.parametrize("dt", [1.0, 600.0])
def test_an_n_body_body_meets_a_moons_surface_on_the_moons_conic(dt):
    """The drift against a moon: the moon on its conic during the step (not its chord), the hit found at
    a long step too, elastic relative to the moon, and the body never inside the surface at a step's end."""
    from driftframe.components.gravity import SurfaceContact
    w = make(dt, moon=True)
    try:
        moon = int(w.moon)
        b = body(w, np.array([D_MOON, -3e7, 0.0]), np.array([0.0, math.sqrt(MU / D_MOON) + 1.5e4, 0.0]),
                 1.0, 10.0, nbody=True)
        hits = []
        w.subscribe(SurfaceContact, hits.append)
        inside = []
        for _ in range(int(3000.0 / dt)):
            w.step()
            x = states(w, [b, moon])[0]
            inside.append(np.linalg.norm(x[0] - x[1]) < R_MOON)
        assert [(h.entity, h.well) for h in hits] == [(b, moon)]
        assert hits[0].time == pytest.approx(1881.4, abs=1.0)          # the leapfrog's path: within a second
        assert hits[0].normal_speed > 0 and not any(inside)
    finally:
        w.close()


@pytest.mark.parametrize("dt", [0.5, 10.0])
def test_an_n_body_collider_that_bounces_off_a_surface_meets_what_is_on_its_new_path_in_the_same_step(dt):
    """The drift's surface contact and its sphere contacts in one time order: a body that bounces off a
    well and then reaches an obstacle on the reflected path meets it, even when one step holds both
    (swept after the sphere contacts, the obstacle was missed and the body went through it)."""
    from driftframe.components.gravity import SurfaceContact
    w = World(dt=dt)
    w.add_system(GravitySystem())
    w.add_system(MovementSystem())
    well = w.create_entity(Transform(), GravityWell(mu=1e-6, radius=1000.0))     # (a pull of 1e-12 m/s^2)
    x0, v0 = np.array([1500.0, 0.0, 0.0]), np.array([-100.0, 50.0, 0.0])
    # straight to the surface: |x0 + v0 t| = 1000, the smaller root; reflected about the normal there
    a_, b_, c_ = v0 @ v0, 2 * x0 @ v0, x0 @ x0 - 1000.0 ** 2
    t_s = (-b_ - math.sqrt(b_ * b_ - 4 * a_ * c_)) / (2 * a_)
    xs = x0 + v0 * t_s
    n = xs / np.linalg.norm(xs)
    v1 = v0 - 2 * (v0 @ n) * n
    q = xs + v1 * 3.0                                             # an obstacle 3 s along the new path
    body_ = w.create_entity(Transform(x0), Velocity(v0), Mass(1.0), NBody(), SphereCollider(radius=5.0))
    ob = w.create_entity(Transform(q), SphereCollider(radius=20.0))
    seen = []
    w.subscribe(SurfaceContact, seen.append)
    w.subscribe(CollisionEvent, seen.append)
    try:
        w.step(int(round(10.0 / dt)))                            # (it comes back to the surface at 10.9 s)
        assert [type(e).__name__ for e in seen] == ["SurfaceContact", "CollisionEvent"], seen
        assert (seen[0].entity, seen[0].well) == (body_, well)
        assert seen[0].time == pytest.approx(t_s, abs=1e-9)
        # the obstacle's surface is 25 m short of q along the reflected path
        assert seen[1].time == pytest.approx(t_s + 3.0 - 25.0 / np.linalg.norm(v1), abs=1e-9)
        assert (seen[1].a, seen[1].b) == (body_, ob) and seen[1].method == "leapfrog"
        x = w.columns(Transform, [body_]).position[0]
        assert np.linalg.norm(x - q) > 25.0 and np.linalg.norm(x) > 1000.0
    finally:
        w.close()
