"""The universal-variable Kepler propagator against closed forms (framework/kepler.py)."""
import math
import numpy as np
import pytest

from driftframe.framework import kepler

MU = 3.986004418e14           # Earth, m^3/s^2


def periapsis_state(a, e, mu=MU):
    """State at periapsis of the conic (a, e) in the x-y plane, periapsis on +x."""
    rp = a * (1.0 - e)
    vp = np.sqrt(mu * (1.0 + e) / rp)
    return np.array([rp, 0.0, 0.0]), np.array([0.0, vp, 0.0])


def ellipse_at(a, e, M):
    """Closed form: position on the ellipse at mean anomaly M (Kepler's equation by Newton)."""
    E = M if e < 0.8 else np.pi
    for _ in range(100):
        E -= (E - e * np.sin(E) - M) / (1.0 - e * np.cos(E))
    return np.array([a * (np.cos(E) - e), a * np.sqrt(1.0 - e * e) * np.sin(E), 0.0])


def energy(r, v, mu=MU):
    return 0.5 * np.sum(v * v, axis=-1) - mu / np.linalg.norm(r, axis=-1)


@pytest.mark.parametrize("e", [0.0, 0.5, 0.9, 0.99])
@pytest.mark.parametrize("frac", [0.013, 0.25, 0.5, 0.77])
def test_ellipse_position_matches_keplers_equation(e, frac):
    a = 1.2e7
    r0, v0 = periapsis_state(a, e)
    P = 2 * np.pi * np.sqrt(a ** 3 / MU)
    r, v = kepler.propagate(r0, v0, MU, frac * P)
    np.testing.assert_allclose(r, ellipse_at(a, e, 2 * np.pi * frac), rtol=0, atol=2e-14 * a * 50)
    # v^2/2 - mu/r cancels by 2/(1 - e) at periapsis: that is the rounding of the energy itself
    assert abs(energy(r, v) / energy(r0, v0) - 1) < 4e-15 * (1 + 2 / (1 - e))


@pytest.mark.parametrize("e", [0.0, 0.5, 0.9, 0.99])
def test_keplers_third_law_one_period_returns_to_the_start(e):
    a = 9e6
    r0, v0 = periapsis_state(a, e)
    P = 2 * np.pi * np.sqrt(a ** 3 / MU)
    r, v = kepler.propagate(r0, v0, MU, P)
    np.testing.assert_allclose(r, r0, atol=1e-12 * a)
    # the period from the state carries the rounding of v^2/2 - mu/r (2/(1 - e) ulp at periapsis),
    # and there the velocity turns at mu/rp^2 per second
    np.testing.assert_allclose(v, v0, atol=1e-12 * np.linalg.norm(v0) + 3 * MU / r0[0] ** 2 * 2.2e-16 * P * 2 / (1 - e))
    # half a period later the body is at apoapsis a (1 + e)
    r, _ = kepler.propagate(r0, v0, MU, 0.5 * P)
    assert np.linalg.norm(r) == pytest.approx(a * (1 + e), rel=1e-13)


@pytest.mark.parametrize("e", [1.01, 1.5, 3.0, 30.0])
@pytest.mark.parametrize("t", [-2e5, 60.0, 3.6e3, 1e6])
def test_hyperbola_matches_the_hyperbolic_keplers_equation(e, t):
    rp = 7e6
    r0, v0 = periapsis_state(rp / (1 - e), e)
    a = rp / (1 - e)
    n = np.sqrt(MU / (-a) ** 3)
    M = n * t
    H = np.arcsinh(M / e)
    for _ in range(200):
        H -= (e * np.sinh(H) - H - M) / (e * np.cosh(H) - 1)
    want = np.array([a * (np.cosh(H) - e), -a * np.sqrt(e * e - 1) * np.sinh(H), 0.0])
    r, v = kepler.propagate(r0, v0, MU, t)
    np.testing.assert_allclose(r, want, rtol=0, atol=1e-12 * np.linalg.norm(want))
    assert abs(energy(r, v) / energy(r0, v0) - 1) < 1e-12


@pytest.mark.parametrize("e", [1.0 - 1e-9, 1.0 + 1e-9])
def test_near_parabolic_orbits_are_time_reversible(e):
    """Where Kepler's equation in E or H loses its digits, the universal form does not."""
    rp = 7e6
    r0, v0 = periapsis_state(rp / (1 - e), e)
    r0 = kepler.propagate(r0, v0, MU, -4e3)
    r, v = kepler.propagate(r0[0], r0[1], MU, 9e4)
    back, bv = kepler.propagate(r, v, MU, -9e4)
    np.testing.assert_allclose(back, r0[0], rtol=1e-12)
    np.testing.assert_allclose(bv, r0[1], rtol=1e-11)
    assert abs(energy(r, v) - energy(*r0)) < 1e-14 * MU / rp


def test_parabola_and_radial_orbits_keep_their_energy():
    rp = 7e6
    r, v = kepler.propagate([rp, 0, 0], [0, np.sqrt(2 * MU / rp), 0], MU, 5e4)     # parabola: energy 0
    assert abs(energy(r, v)) < 1e-15 * MU / rp
    r0, v0 = np.array([7e6, 0, 0.0]), np.array([3000.0, 0, 0])                    # radial, outbound
    r, v = kepler.propagate(r0, v0, MU, 700.0)
    assert r[1] == r[2] == v[1] == v[2] == 0.0
    assert abs(energy(r, v) / energy(r0, v0) - 1) < 1e-14
    # a radial body thrown up comes back down through its start with the speed reversed
    el = kepler.elements(r0, v0, MU)
    back = 2 * (el.time_to_apoapsis[0])
    r, v = kepler.propagate(r0, v0, MU, back)
    np.testing.assert_allclose(r, r0, rtol=1e-10)
    np.testing.assert_allclose(v, -v0, rtol=1e-8)


def test_stumpff_is_continuous_where_the_series_meets_the_closed_forms():
    for p in (1.0, -1.0):
        c2, c3 = kepler.stumpff(np.array([p * (1 - 1e-15), p * (1 + 1e-15)]))   # series | closed form
        assert abs(c2[0] - c2[1]) < 3e-16 and abs(c3[0] - c3[1]) < 3e-16
    # identities: 1 - psi c2 = cos sqrt(psi), 1 - psi c3 = sin(x)/x
    psi = np.array([-30.0, -1.5, -0.3, 1e-9, 0.4, 2.0, 39.0])
    c2, c3 = kepler.stumpff(psi)
    x = np.sqrt(np.abs(psi))
    cos = np.where(psi > 0, np.cos(x), np.cosh(x))
    sinc = np.where(psi > 0, np.sin(x) / x, np.sinh(x) / x)
    np.testing.assert_allclose(1 - psi * c2, cos, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(1 - psi * c3, sinc, rtol=1e-14, atol=1e-15)
    c2, c3 = kepler.stumpff(np.array([0.0]))
    assert c2[0] == 0.5 and c3[0] == pytest.approx(1 / 6, rel=1e-16)


def test_vectorised_over_mixed_conics_is_the_same_as_one_at_a_time():
    rng = np.random.default_rng(3)
    n = 40
    r0 = rng.normal(size=(n, 3)) * 8e6
    v0 = rng.normal(size=(n, 3)) * 9e3
    dt = rng.uniform(-3e3, 3e4, n)
    r, v = kepler.propagate(r0, v0, MU, dt)
    for k in range(n):
        rk, vk = kepler.propagate(r0[k], v0[k], MU, dt[k])
        np.testing.assert_allclose(r[k], rk, rtol=1e-13, atol=1e-6)
        np.testing.assert_allclose(v[k], vk, rtol=1e-13, atol=1e-9)


SHORT_STEPS_E = (0.0, 0.5, 0.9, 0.99)


@pytest.fixture(scope="module")
def many_short_steps():
    """The four orbits of the test below (4 rows each, a = 1e7 m: one period P), stepped together in one
    batch: (start, end) states. Each row is propagated on its own (the same drift, within a rounding or two
    of a batch of its own), in a quarter of the calls (3,000 instead of 12,000: 8 s of CPU -> 3.4 s)."""
    a = 1e7
    start = [np.vstack([np.repeat(s[None], 4, 0) for s in periapsis_state(a, e)]) for e in SHORT_STEPS_E]
    r = np.vstack([s[:4] for s in start])
    v = np.vstack([s[4:] for s in start])
    r0, v0 = r.copy(), v.copy()
    P = 2 * np.pi * np.sqrt(a ** 3 / MU)
    for _ in range(3_000):
        r, v = kepler.propagate(r, v, MU, P / 10)
    return (r0, v0), (r, v)


@pytest.mark.parametrize("e, bound", [(0.0, 1e-12), (0.5, 1e-12), (0.9, 1e-10), (0.99, 1e-8)])
def test_energy_and_angular_momentum_kept_in_many_short_steps(e, bound, many_short_steps):
    """300 orbits at 10 steps per orbit, each step from the last (as a thrusting body goes):
    the drift is the rounding of the state, repeated at the same phases every orbit (v^2/2 and
    mu/r cancel by 2/(1 - e) at periapsis). On rails the gravity system propagates from an epoch
    instead, which keeps a single rounding however long it runs (test_gravity.py)."""
    rows = slice(4 * SHORT_STEPS_E.index(e), 4 * SHORT_STEPS_E.index(e) + 4)
    (r0, v0), (r, v) = ((x[rows] for x in pair) for pair in many_short_steps)
    assert np.array_equal(r0, np.repeat(periapsis_state(1e7, e)[0][None], 4, 0))     # this e's orbit
    E0, h0 = energy(r0, v0), np.linalg.norm(np.cross(r0, v0), axis=1)
    assert np.max(np.abs(energy(r, v) / E0 - 1)) < bound
    assert np.max(np.abs(np.linalg.norm(np.cross(r, v), axis=1) / h0 - 1)) < bound


def test_elements_readouts_against_closed_forms():
    a, e = 1.1e7, 0.6
    r0, v0 = periapsis_state(a, e)
    P = 2 * np.pi * np.sqrt(a ** 3 / MU)
    r, v = kepler.propagate(r0, v0, MU, 0.3 * P)
    el = kepler.elements(r, v, MU)
    assert el.a[0] == pytest.approx(a, rel=1e-13)
    assert el.e[0] == pytest.approx(e, rel=1e-13)
    assert el.periapsis[0] == pytest.approx(a * (1 - e), rel=1e-13)
    assert el.apoapsis[0] == pytest.approx(a * (1 + e), rel=1e-13)
    assert el.period[0] == pytest.approx(P, rel=1e-13)
    assert el.time_to_periapsis[0] == pytest.approx(0.7 * P, rel=1e-12)
    assert el.time_to_apoapsis[0] == pytest.approx(0.2 * P, rel=1e-12)
    # hyperbola: open, periapsis ahead then behind
    r0, v0 = periapsis_state(7e6 / (1 - 2.0), 2.0)
    r, v = kepler.propagate(r0, v0, MU, -500.0)
    el = kepler.elements(r, v, MU)
    assert el.time_to_periapsis[0] == pytest.approx(500.0, rel=1e-10)
    assert el.periapsis[0] == pytest.approx(7e6, rel=1e-13)
    assert np.isinf(el.apoapsis[0]) and np.isinf(el.period[0]) and np.isinf(el.time_to_apoapsis[0])


def test_hohmann_transfer_dv_reaches_the_closed_form_apoapsis():
    r1, r2 = 7e6, 4.2164e7
    dv1 = np.sqrt(MU / r1) * (np.sqrt(2 * r2 / (r1 + r2)) - 1)
    dv2 = np.sqrt(MU / r2) * (1 - np.sqrt(2 * r1 / (r1 + r2)))
    r, v = np.array([r1, 0, 0.0]), np.array([0, np.sqrt(MU / r1) + dv1, 0.0])
    el = kepler.elements(r, v, MU)
    assert el.apoapsis[0] == pytest.approx(r2, rel=1e-12)
    t_half = np.pi * np.sqrt(((r1 + r2) / 2) ** 3 / MU)
    assert el.time_to_apoapsis[0] == pytest.approx(t_half, rel=1e-12)
    r, v = kepler.propagate(r, v, MU, t_half)
    v = v + dv2 * v / np.linalg.norm(v)
    el = kepler.elements(r, v, MU)
    assert el.e[0] < 1e-11
    assert np.linalg.norm(r) == pytest.approx(r2, rel=1e-12)


def test_time_to_radius_finds_the_surface_crossing_exactly():
    R = 6.371e6
    # a steep fall at 10 km/s from 20,000 km: the crossing is on the conic, whatever the horizon
    r0, v0 = np.array([2e7, 0.0, 1e6]), np.array([-1e4, 0.0, 0.0])
    t = kepler.time_to_radius(r0, v0, MU, R, 1e9)[0]
    assert np.isfinite(t)
    r, _ = kepler.propagate(r0, v0, MU, t)
    assert np.linalg.norm(r) == pytest.approx(R, rel=1e-12)
    ts = np.linspace(0, t, 200)[:-1]
    rs, _ = kepler.propagate(np.repeat(r0[None], ts.size, 0), np.repeat(v0[None], ts.size, 0), MU, ts)
    assert np.all(np.linalg.norm(rs, axis=1) > R)
    # beyond the horizon: none; an orbit above the surface: none; a hyperbola going away: none
    assert np.isinf(kepler.time_to_radius(r0, v0, MU, R, 0.5 * t)[0])
    rc, vc = periapsis_state(7e6, 0.0)
    assert np.isinf(kepler.time_to_radius(rc, vc, MU, R, 1e9)[0])
    assert np.isinf(kepler.time_to_radius(r0, -v0 * 3, MU, R, 1e9)[0])
    # an ellipse that dips under the surface later, after apoapsis: found on the way in
    r1, v1 = np.array([7e6, 0, 0.0]), np.array([100.0, 7000.0, 0])
    t = kepler.time_to_radius(r1, v1, MU, R, 1e9)[0]
    r, v = kepler.propagate(r1, v1, MU, t)
    assert np.linalg.norm(r) == pytest.approx(R, rel=1e-12) and r @ v < 0


def test_closest_approach_of_two_orbits():
    # two circular orbits in one plane, 1 degree apart in phase: they never come closer than now,
    # but a crossing ellipse meets the circle at a known point
    r1, v1 = np.array([7e6, 0, 0.0]), np.array([0, np.sqrt(MU / 7e6), 0.0])
    rp, vp = periapsis_state(8e6, 0.125)          # periapsis 7e6 on +x: same point, faster
    t, d = kepler.closest_approach(r1, v1, rp, vp, MU, 3000.0)
    assert t == pytest.approx(0.0, abs=1e-6) and d == pytest.approx(0.0, abs=1e-6)
    P = 2 * np.pi * np.sqrt(7e6 ** 3 / MU)
    back1, bv1 = kepler.propagate(r1, v1, MU, -0.1 * P)
    backp, bvp = kepler.propagate(rp, vp, MU, -0.1 * P)
    t, d = kepler.closest_approach(back1, bv1, backp, bvp, MU, 0.3 * P)
    assert t == pytest.approx(0.1 * P, rel=1e-6) and d < 1e-2


def test_orbit_points_lie_on_the_conic():
    a, e = 1e7, 0.7
    r0, v0 = periapsis_state(a, e)
    pts = kepler.orbit_points(r0, v0, MU, 64)
    rr = np.linalg.norm(pts, axis=1)
    assert rr.min() == pytest.approx(a * (1 - e), rel=1e-9)
    assert rr.max() == pytest.approx(a * (1 + e), rel=1e-3)
    assert np.all(np.abs(pts[:, 2]) < 1e-6)


def test_the_compiled_path_gives_the_numpy_paths_states():
    """Epoch.at with a guess for many bodies runs a compiled loop: same formulas, same states."""
    rng = np.random.default_rng(11)
    n = 2 * kepler.COMPILED_MIN
    e = np.concatenate([rng.uniform(0, 0.99, n // 2), rng.uniform(1.01, 3.0, n // 2)])
    rp = rng.uniform(7e6, 2e7, n)
    r0 = np.zeros((n, 3))
    r0[:, 0] = rp
    v0 = np.zeros((n, 3))
    v0[:, 1] = np.sqrt(MU * (1 + e) / rp)
    ep = kepler.Epoch(r0, v0, MU)
    r, v, chi = r0, v0, np.zeros(n)
    for k in range(1, 40):
        t = k * 977.0
        guess = kepler.next_chi(chi, r, v, MU, 977.0)
        r, v, chi = ep.at(t, guess)                                  # compiled
        want_r, want_v = kepler.propagate(r0, v0, MU, t)              # numpy, no guess
        np.testing.assert_allclose(r, want_r, rtol=1e-11, atol=1e-6)
        np.testing.assert_allclose(v, want_v, rtol=1e-11, atol=1e-9)
    E0 = energy(r0, v0)
    assert np.max(np.abs(energy(r, v) / E0 - 1)) < 1e-12


def test_next_chi_compiled_and_numpy_paths_agree_and_origin_is_subtracted():
    # from COMPILED_MIN bodies one compiled pass; below, numpy: the same formulas
    rng = np.random.default_rng(3)
    n = kepler.COMPILED_MIN
    r = rng.uniform(-2e7, 2e7, (n, 3)) + np.array([7e6, 0.0, 0.0])
    v = rng.uniform(-5e3, 5e3, (n, 3))
    chi = rng.uniform(0.0, 1e3, n)
    X, V = np.array([1e6, -2e6, 3e5]), np.array([10.0, -20.0, 5.0])
    nans = 0
    for step in (30.0, 3000.0):
        big = kepler.next_chi(chi, r + X, v + V, MU, step, origin=(X, V))
        small = np.concatenate([kepler.next_chi(chi[k:k + 1], r[k:k + 1], v[k:k + 1], MU, step)
                                for k in range(n)])
        np.testing.assert_array_equal(np.isnan(big), np.isnan(small))   # coarse steps past periapsis: NaN
        nans += int(np.isnan(small).sum())
        ok = np.isfinite(small)
        assert ok.sum() > n // 4
        np.testing.assert_allclose(big[ok], small[ok], rtol=1e-13)
    assert nans > 0


def _random_conics(n, seed):
    """Mixed conics about mu = 1: near-circular, eccentric (e to 0.99), hyperbolic, nearly radial."""
    rng = np.random.default_rng(seed)
    r = rng.normal(size=(n, 3))
    r *= (rng.uniform(1.0, 3.0, n) / np.linalg.norm(r, axis=1))[:, None]
    v = rng.normal(size=(n, 3))
    v *= (rng.uniform(0.05, 1.6, n) / np.linalg.norm(v, axis=1) / np.sqrt(np.linalg.norm(r, axis=1)))[:, None]
    v[: n // 8] = -0.5 * r[: n // 8] / np.linalg.norm(r[: n // 8], axis=1)[:, None] ** 1.5   # (nearly) radial
    v[: n // 8] += 1e-6 * rng.normal(size=(n // 8, 3))
    return r, v


@pytest.mark.parametrize("span", [0.01, 0.5, 3.0, 20.0])
def test_arc_boxes_hold_the_whole_arc_and_bound_its_distance_and_pull(span):
    """Sampled densely along the exact conic, every point lies in its box, no nearer the mass than
    rho, and pulled no harder than accel; where the surface is reached within the span the box is
    the reachable cube, which holds the bounced path too."""
    r, v = _random_conics(400, seed=5)
    surface = 0.05
    ts = np.linspace(0.0, span, 257)
    n = len(r)
    hit = kepler.time_to_radius(r, v, 1.0, surface, span) <= span
    pe, we = kepler.propagate(r, v, 1.0, span)
    lo, hi, accel, rho = kepler.arc_boxes(r, v, pe, we, span, 1.0, surface, hit, np.full(n, 1e-3))
    for t in ts:
        p, _ = kepler.propagate(r, v, 1.0, t)
        ok = ~hit
        assert ((p[ok] >= lo[ok]) & (p[ok] <= hi[ok])).all()
        d = np.linalg.norm(p[ok], axis=1)
        assert (d >= rho[ok] * (1 - 1e-12)).all()
        assert (1.0 / d ** 2 <= accel[ok] * (1 + 1e-12)).all()
    # the reachable cube of a body that reaches the surface holds its path at full speed both ways
    k = np.flatnonzero(hit)
    if k.size:
        vmax = np.sqrt(2 * (0.5 * np.einsum("ij,ij->i", v[k], v[k]) - 1 / np.linalg.norm(r[k], axis=1)
                            + 1 / rho[k]))
        assert (hi[k] - r[k] >= vmax[:, None] * span).all() and (r[k] - lo[k] >= vmax[:, None] * span).all()
    # and the boxes are tight enough to be of use: short arcs are barely wider than their chords
    if span <= 0.01:
        chord = np.abs(pe - r).max(axis=1)
        assert np.median((hi - lo - 2e-3).max(axis=1)[~hit] / chord[~hit]) < 1.01


def test_time_to_touch_finds_the_first_touch_with_and_without_the_tidal_bound():
    """Pairs on random nearby conics: the first time they come within reach while closing, against a
    dense sampling of the gap bisected; the tidal bound changes how fast it gets there, not where."""
    rng = np.random.default_rng(9)
    n = 40
    ra = np.tile([1.0, 0.0, 0.0], (n, 1)) + rng.uniform(-0.01, 0.01, (n, 3))
    va = np.tile([0.0, 1.0, 0.0], (n, 1)) + rng.uniform(-0.01, 0.01, (n, 3))
    rb = np.tile([1.0, 0.0, 0.0], (n, 1)) + rng.uniform(-0.01, 0.01, (n, 3))
    vb = np.tile([0.0, 1.0, 0.0], (n, 1)) + rng.uniform(-0.01, 0.01, (n, 3))
    reach = np.full(n, 4e-3)
    horizon = 3.0
    pe_a, we_a = kepler.propagate(ra, va, 1.0, horizon)
    pe_b, we_b = kepler.propagate(rb, vb, 1.0, horizon)
    _, _, acc_a, rho_a = kepler.arc_boxes(ra, va, pe_a, we_a, horizon, 1.0, 0.5, np.zeros(n, bool))
    _, _, acc_b, rho_b = kepler.arc_boxes(rb, vb, pe_b, we_b, horizon, 1.0, 0.5, np.zeros(n, bool))
    plain, s1 = kepler.time_to_touch(ra, va, 0.0, rb, vb, 0.0, 1.0, reach, 0.0, horizon, acc_a + acc_b)
    tidal, s2 = kepler.time_to_touch(ra, va, 0.0, rb, vb, 0.0, 1.0, reach, 0.0, horizon, acc_a + acc_b,
                                     np.minimum(rho_a, rho_b))
    assert not s1.any() and not s2.any()
    ts = np.linspace(0.0, horizon, 30_001)
    found = 0
    for k in range(n):
        pa, _ = kepler.propagate(np.repeat(ra[k:k + 1], ts.size, 0), np.repeat(va[k:k + 1], ts.size, 0), 1.0, ts)
        pb, _ = kepler.propagate(np.repeat(rb[k:k + 1], ts.size, 0), np.repeat(vb[k:k + 1], ts.size, 0), 1.0, ts)
        gap = np.linalg.norm(pb - pa, axis=1) - reach[k]
        inside = np.flatnonzero(gap <= 0)
        if not inside.size:
            assert plain[k] == np.inf and tidal[k] == np.inf
            continue
        found += 1
        j = inside[0]
        lo, hi = ts[max(j - 1, 0)], ts[j]
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            a_, _ = kepler.propagate(ra[k], va[k], 1.0, mid)
            b_, _ = kepler.propagate(rb[k], vb[k], 1.0, mid)
            lo, hi = (mid, hi) if np.linalg.norm(b_ - a_) > reach[k] else (lo, mid)
        assert plain[k] == pytest.approx(hi, abs=1e-9)
        assert tidal[k] == pytest.approx(hi, abs=1e-9)
    assert found >= 3


@pytest.mark.parametrize("speed", [0.9, 1.3])          # of the escape speed: an ellipse past r, a hyperbola
def test_time_to_radius_outward_is_the_first_crossing_outwards(speed):
    mu, r0 = 4.9e12, 2e6
    r, v = np.array([r0, 0, 0.0]), np.array([0, speed * np.sqrt(2 * mu / r0), 0.0])
    R = 3e6 if speed < 1 else 6.6e7
    t = kepler.time_to_radius(r, v, mu, R, 1e9, outward=True)[0]
    ts = np.linspace(0.0, 1.5 * t, 30001)
    rs, vs = kepler.propagate(np.tile(r, (ts.size, 1)), np.tile(v, (ts.size, 1)), mu, ts)
    first = ts[int(np.argmax(np.linalg.norm(rs, axis=1) > R))]
    assert first - 2 * ts[1] <= t <= first + 1e-9 * t
    at, vt = kepler.propagate(r, v, mu, t)
    assert np.linalg.norm(at) == pytest.approx(R, rel=1e-12) and at @ vt > 0
    # from outside the radius, or on an orbit that never reaches it: no crossing
    assert kepler.time_to_radius(at * 1.01, vt, mu, R, 1e9, outward=True)[0] == np.inf
    circ = np.array([0, np.sqrt(mu / r0), 0.0])
    assert kepler.time_to_radius(r, circ, mu, R, 1e9, outward=True)[0] == np.inf


@pytest.mark.parametrize("speed", [0.0, 2000.0, -2000.0])
def test_time_to_radius_on_a_straight_line_is_the_radial_fall_time(speed):
    """h = 0 gives e = 1 whatever the energy: a bound straight-line orbit falls back (it was taken for an
    escaping parabola's, so a body released at rest or thrown up never met the surface), and one that
    turns back inside a sphere does not leave it."""
    R, r0 = 6.371e6, 1e7
    q = speed * speed * r0 / MU                                # apex r_max = r0 / (1 - q/2), energy kept
    r_max = r0 / (1 - q / 2)

    def fall(omx):                                             # closed form, apex -> (1 - omx) r_max
        return math.sqrt(r_max ** 3 / (2 * MU)) * (math.sqrt((1 - omx) * omx) + math.asin(math.sqrt(omx)))

    want = fall(1 - R / r_max) + math.copysign(fall(q / 2), speed)
    for axis in range(3):
        r, v = np.zeros(3), np.zeros(3)
        r[axis], v[axis] = r0, speed
        t = kepler.time_to_radius(r, v, MU, R, 1e9)[0]
        assert t == pytest.approx(want, abs=1e-11)
        assert kepler.time_to_radius(r, v, MU, 1.01 * r_max, 1e9, outward=True)[0] == np.inf
        assert kepler.time_to_radius(r, v, MU, 0.99 * r_max, 1e9, outward=True)[0] < np.inf or speed <= 0
