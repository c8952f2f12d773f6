"""The n-body kernels (framework/wisdom_holman.py): Wisdom–Holman about a dominant mass, leapfrog without one.

REBOUND is not imported here (it is the `compare` extra): its figures are recorded from
``benchmarks/nbody.py``'s scene, which this file rebuilds (the same elements, the same code).
"""
import math

import numpy as np
import pytest

from driftframe.framework import kepler
from driftframe.framework import wisdom_holman as wh

GK = 0.01720209895 ** 2          # G in AU^3 / (Msun day^2): the Gaussian constant squared
YEAR = 365.25
# Jupiter and Saturn at J2000: mass (Msun), a (AU), e, i, node, argument of periapsis, mean anomaly (deg)
PLANETS = ((9.547919e-4, 5.202603, 0.048498, 1.303, 100.464, 273.867, 20.020),
           (2.858859e-4, 9.554909, 0.055548, 2.489, 113.666, 339.392, 317.021))
# REBOUND 5.2.2 WHFast (Jacobi, safe_mode=0, no corrector) on this scene, dt = 5 days, 1,000 years, the
# worst |E/E0 - 1| over 100 synchronised outputs (benchmarks/nbody.sjs_run("REBOUND WHFast", 5.0, 1000, 100))
WHFAST_SJS_5D_1000Y = 1.1593450643943015e-09


def state_from_elements(mu, a, e, inc, node, peri, mean):
    M = math.radians(mean)
    E = M
    for _ in range(30):
        E -= (E - e * math.sin(E) - M) / (1.0 - e * math.cos(E))
    b = math.sqrt(1.0 - e * e)
    r = a * (1.0 - e * math.cos(E))
    p = np.array([a * (math.cos(E) - e), a * b * math.sin(E), 0.0])
    q = math.sqrt(mu * a) / r * np.array([-math.sin(E), b * math.cos(E), 0.0])
    cO, sO, ci, si, cw, sw = (f(math.radians(t)) for t in (node, inc, peri) for f in (math.cos, math.sin))
    R = np.array([[cO * cw - sO * sw * ci, -cO * sw - sO * cw * ci, sO * si],
                  [sO * cw + cO * sw * ci, -sO * sw + cO * cw * ci, -cO * si],
                  [sw * si, cw * si, ci]])
    return R @ p, R @ q


def sjs():
    m = np.array([1.0] + [p[0] for p in PLANETS])
    x = np.zeros((3, 3))
    v = np.zeros((3, 3))
    for k, (mk, *el) in enumerate(PLANETS, start=1):
        x[k], v[k] = state_from_elements(GK * (1.0 + mk), *el)
    x -= (m[:, None] * x).sum(0) / m.sum()
    v -= (m[:, None] * v).sum(0) / m.sum()
    return x, v, GK * m


def worst_energy_error(dt, years, outputs, **options):
    x, v, gm = sjs()
    E0 = wh.energy(x, v, gm)
    total = int(round(years * YEAR / dt))
    per = total // outputs
    worst = 0.0
    for _ in range(outputs):
        wh.wisdom_holman(x, v, gm, dt, per, **options)
        worst = max(worst, abs(wh.energy(x, v, gm) / E0 - 1.0))
    return worst


def test_sun_jupiter_saturn_energy_error_is_at_most_whfasts_at_the_same_step():
    plain = worst_energy_error(5.0, 1_000, 100)
    assert plain <= WHFAST_SJS_5D_1000Y                          # the same scheme: equal to 5 digits
    assert plain == pytest.approx(WHFAST_SJS_5D_1000Y, rel=1e-3)
    corrected = worst_energy_error(5.0, 1_000, 100, corrector=5)
    assert corrected <= WHFAST_SJS_5D_1000Y / 100                 # O(eps^2 dt^2): about 1e-12


def test_the_corrector_reduces_the_energy_error_at_every_order():
    plain = worst_energy_error(20.0, 200, 20)
    errors = {order: worst_energy_error(20.0, 200, 20, corrector=order) for order in (3, 5, 7, 11, 17)}
    assert all(e < plain / 30 for e in errors.values()), (plain, errors)


def test_democratic_heliocentric_keeps_the_energy_as_well():
    jacobi = worst_energy_error(5.0, 200, 20)
    dh = worst_energy_error(5.0, 200, 20, coordinates="democratic")
    assert jacobi < 2e-9 and dh < 2e-8          # DH's error is larger for SJS (the indirect terms), bounded


def test_two_bodies_follow_the_exact_kepler_solution():
    """Two bodies: the interaction is empty, so WH is the exact two-body motion for any dt (to rounding)."""
    gm = np.array([1.0, 1e-3])
    r0, v0 = state_from_elements(gm.sum(), 1.3, 0.6, 20.0, 40.0, 60.0, 10.0)
    x = np.array([[0.0, 0.0, 0.0], r0])
    v = np.array([[0.0, 0.0, 0.0], v0])
    com_x, com_v = (gm[:, None] * x).sum(0) / gm.sum(), (gm[:, None] * v).sum(0) / gm.sum()
    dt, n = 0.37, 100                       # 4.5 orbits, 22 steps per orbit (rounding grows as sqrt(n))
    wh.wisdom_holman(x, v, gm, dt, n)
    r_exact, v_exact = kepler.propagate(r0[None], v0[None], gm.sum(), dt * n)
    np.testing.assert_allclose(x[1] - x[0], r_exact[0], rtol=0, atol=1e-12 * np.linalg.norm(r_exact))
    np.testing.assert_allclose(v[1] - v[0], v_exact[0], rtol=0, atol=1e-12 * np.linalg.norm(v_exact))
    np.testing.assert_allclose((gm[:, None] * x).sum(0) / gm.sum(), com_x + com_v * dt * n, atol=1e-14)


@pytest.mark.parametrize("case", ["ellipse", "many orbits", "hyperbola", "backwards", "radial"])
def test_the_kepler_drift_matches_the_projects_propagator(case):
    mu = 3.986e14
    r = np.array([[7.0e6, 1.0e5, -2.0e5]])
    speed = {"ellipse": 8.0e3, "many orbits": 8.0e3, "hyperbola": 12.0e3, "backwards": 9.0e3, "radial": 0.0}[case]
    v = np.array([[0.0, speed, 1.0e3 if case != "radial" else 0.0]])
    t = {"ellipse": 1234.5, "many orbits": 5.3e5, "hyperbola": 3.0e4, "backwards": -2.0e3, "radial": 300.0}[case]
    x1, v1 = wh.kepler_drift(r.copy(), v.copy(), mu, t)
    r_exact, v_exact = kepler.propagate(r, v, mu, t)
    np.testing.assert_allclose(x1, r_exact, rtol=1e-11 if case == "many orbits" else 1e-12)
    np.testing.assert_allclose(v1, v_exact, rtol=1e-11 if case == "many orbits" else 1e-12,
                               atol=1e-12 * np.linalg.norm(v_exact))


@pytest.mark.parametrize("method", ["jacobi", "jacobi + corrector", "democratic", "fixed", "leapfrog"])
def test_time_reversal_returns_to_the_start(method):
    x0, v0, gm = sjs()
    x, v = x0.copy(), v0.copy()

    def run(dt):
        if method == "leapfrog":
            wh.leapfrog(x, v, gm, dt, 2_000)
        else:
            coords = method.split()[0]
            wh.wisdom_holman(x, v, gm, dt, 2_000, coordinates=coords, corrector=5 if "corrector" in method else 0)
    run(10.0)
    assert np.linalg.norm(x - x0) > 1.0                           # it went somewhere
    run(-10.0)
    np.testing.assert_allclose(x, x0, rtol=0, atol=1e-11)        # AU: rounding only
    np.testing.assert_allclose(v, v0, rtol=0, atol=1e-13)


def test_a_test_particle_about_a_fixed_well_is_on_its_exact_conic():
    gm = np.array([1.0, 0.0, 0.0])
    x = np.array([[1.0, 2.0, 3.0], [1.5, 2.0, 3.0], [1.0, 4.0, 3.0]])
    v = np.array([[0.1, 0.0, 0.0], [0.1, 1.2, 0.3], [-0.5, 0.1, 0.0]])
    x0, v0 = x.copy(), v.copy()
    wh.wisdom_holman(x, v, gm, 0.05, 300, coordinates="fixed")
    np.testing.assert_array_equal(v[0], v0[0])                    # the well keeps its velocity
    np.testing.assert_allclose(x[0], x0[0] + v0[0] * 15.0, atol=1e-14)
    r_exact, v_exact = kepler.propagate(x0[1:] - x0[0], v0[1:] - v0[0], 1.0, 15.0)
    np.testing.assert_allclose(x[1:] - x[0], r_exact, atol=1e-12)
    np.testing.assert_allclose(v[1:] - v[0], v_exact, atol=1e-12)


def test_many_steps_in_one_call_agree_with_one_step_at_a_time():
    xa, va, gm = sjs()
    xb, vb = xa.copy(), va.copy()
    wh.wisdom_holman(xa, va, gm, 5.0, 400, corrector=3)
    for _ in range(400):
        wh.wisdom_holman(xb, vb, gm, 5.0, 1, corrector=3)
    np.testing.assert_allclose(xa, xb, rtol=0, atol=1e-12)        # the joined drifts: the same map, rounded
    np.testing.assert_allclose(va, vb, rtol=0, atol=1e-14)


def figure_eight_distance(steps):
    T = 6.32591398
    x0 = np.array([[-0.97000436, 0.24308753, 0.0], [0.0, 0.0, 0.0], [0.97000436, -0.24308753, 0.0]])
    v0 = np.array([[0.4662036850, 0.4323657300, 0.0], [-0.93240737, -0.86473146, 0.0],
                   [0.4662036850, 0.4323657300, 0.0]])
    x, v = x0.copy(), v0.copy()
    wh.leapfrog(x, v, np.ones(3), T / steps, steps)
    return float(np.max(np.linalg.norm(x - x0, axis=1))), x, v


def test_the_figure_eight_returns_to_its_start():
    far, x, v = figure_eight_distance(3_000)
    assert far < 3e-5
    np.testing.assert_allclose(v.sum(0), 0.0, atol=1e-14)        # momentum: exactly zero at the start
    near, _, _ = figure_eight_distance(6_000)
    assert 3.5 < far / near < 4.5                                  # second order: half the step, a quarter


def test_bad_input_is_a_clear_error():
    x, v, gm = sjs()
    with pytest.raises(ValueError, match="corrector must be one of"):
        wh.wisdom_holman(x, v, gm, 1.0, corrector=4)
    with pytest.raises(ValueError, match="needs Jacobi"):
        wh.wisdom_holman(x, v, gm, 1.0, coordinates="democratic", corrector=3)
    with pytest.raises(ValueError, match="coordinates must be one of"):
        wh.wisdom_holman(x, v, gm, 1.0, coordinates="heliocentric")
    with pytest.raises(ValueError, match="n_steps"):
        wh.wisdom_holman(x, v, gm, 1.0, 0)
    with pytest.raises(ValueError, match="dt must be finite"):
        wh.leapfrog(x, v, gm, float("nan"))
    with pytest.raises(TypeError, match=r"shape \(n, 3\)"):
        wh.leapfrog(x[:, :2].copy(), v, gm, 1.0)
    with pytest.raises(ValueError, match="gm must be finite and >= 0"):
        wh.leapfrog(x, v, -gm, 1.0)
    bad = x.copy()
    bad[1, 1] = np.inf
    with pytest.raises(ValueError, match="must be finite"):
        wh.wisdom_holman(bad, v, gm, 1.0)
    with pytest.raises(ValueError, match="dominant mass"):
        wh.wisdom_holman(x, v, np.array([0.0, 1.0, 1.0]), 1.0)


def test_the_kepler_drift_agrees_with_the_projects_propagator_on_random_orbits():
    """Ellipses, hyperbolas, near-radial paths, forwards and back, from a thousandth of a time unit to a
    thousand (many orbits, far out on a hyperbola): the bracketed Laguerre solve always converges."""
    rng = np.random.default_rng(0)
    r = rng.normal(size=(400, 3))
    v = rng.normal(size=(400, 3)) * rng.uniform(0.1, 2.0, (400, 1))
    t = 10.0 ** rng.uniform(-3.0, 3.0, 400) * rng.choice([-1.0, 1.0], 400)
    for k in range(400):
        x1, v1 = wh.kepler_drift(r[k:k + 1].copy(), v[k:k + 1].copy(), 1.0, t[k])
        r_exact, v_exact = kepler.propagate(r[k:k + 1], v[k:k + 1], 1.0, t[k])
        assert np.linalg.norm(x1 - r_exact) <= 1e-10 * np.linalg.norm(r_exact), k
        assert np.linalg.norm(v1 - v_exact) <= 1e-10 * np.linalg.norm(v_exact), k


@pytest.mark.parametrize("dt", [10.0, 600.0, 20_000.0])
def test_a_lone_nbody_body_about_a_well_drifts_on_its_exact_conic_in_the_gravity_system(dt):
    """The gravity system's n-body path: about one root well, an NBody body without a collider whose conic
    clears the surface drifts on the conic (its kicks hold only the other bodies' pulls): alone it follows
    the body on rails beside it at any step, a step of several orbits included."""
    from driftframe import Mass, MovementSystem, Transform, Velocity, World
    from driftframe.components.gravity import GravityWell, NBody
    from driftframe.systems.gravity import GravitySystem
    mu, r0 = 3.986004418e14, 7.0e6
    v0 = (0.0, math.sqrt(mu / r0) * 1.1, 300.0)
    with World(dt=dt) as w:
        w.add_system(GravitySystem())
        w.add_system(MovementSystem())
        w.create_entity(Transform(), GravityWell(mu=mu, radius=6.371e6))
        a = w.create_entity(Transform((r0, 0.0, 0.0)), Velocity(v0), Mass(1e3), NBody())
        b = w.create_entity(Transform((r0, 0.0, 0.0)), Velocity(v0))           # on rails: exact Kepler
        w.step(20)
        x = w.columns(Transform, [a, b]).position
        v = w.columns(Velocity, [a, b]).linear
        assert np.linalg.norm(x[0] - x[1]) <= 1e-9 * r0
        assert np.linalg.norm(v[0] - v[1]) <= 1e-9 * np.linalg.norm(v0)


def test_nbody_bodies_without_a_well_are_a_second_order_leapfrog_in_the_gravity_system():
    """No well: the gravity system's drift-kick-drift on the mutual pulls. Over one orbit of an eccentric
    binary (e ~ 0.5) the worst energy error is a quarter at half the step (second order; the symplectic
    Euler this replaced: 0.28 at 100 steps an orbit, halving)."""
    from driftframe import Mass, MovementSystem, Transform, Velocity, World
    from driftframe.components.gravity import G, NBody
    from driftframe.systems.gravity import GravitySystem
    m, d = 1e12, 10.0                                   # two 10^12 kg bodies 20 m apart
    v_rel = 0.7 * math.sqrt(G * 2 * m / (2 * d))        # 0.7 of circular speed: apoapsis here, e ~ 0.5
    period = 2 * math.pi * 2 * d / v_rel                # a time scale; the step count sets dt

    def worst_energy_error(steps):
        with World(dt=period / steps) as w:
            w.add_system(GravitySystem())
            w.add_system(MovementSystem())
            a = w.create_entity(Transform((-d, 0.0, 0.0)), Velocity((0.0, -v_rel / 2, 0.0)), Mass(m), NBody())
            b = w.create_entity(Transform((d, 0.0, 0.0)), Velocity((0.0, v_rel / 2, 0.0)), Mass(m), NBody())

            def energy():
                x = w.columns(Transform, [a, b]).position
                v = w.columns(Velocity, [a, b]).linear
                return 0.5 * m * float(np.sum(v * v)) - G * m * m / float(np.linalg.norm(x[1] - x[0]))
            e0, worst = energy(), 0.0
            for _ in range(steps):
                w.step()
                worst = max(worst, abs(energy() / e0 - 1.0))
            np.testing.assert_allclose(w.columns(Velocity, [a, b]).linear.sum(0), 0.0, atol=1e-14)  # momentum
            return worst

    coarse, fine = worst_energy_error(100), worst_energy_error(200)
    assert coarse < 0.03
    assert 3.3 < coarse / fine < 4.5


def test_two_bodies_at_one_point_pull_each_other_not_at_all():
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    a = wh.pair_accel(x, np.array([2.0, 1.0, 1.0]))
    np.testing.assert_allclose(a, [[2.0, 0.0, 0.0], [-2.0, 0.0, 0.0], [-2.0, 0.0, 0.0]])
