"""The hybrid n-body step for close encounters (framework/mercurius.py) and its adaptive integrator
(framework/encounters.py).

The scene: a star (G m = 1) and two planets of G m = 1e-3 that pass 0.02 apart (0.3 Hill radii) about
1.5 time units in (placed there, then taken back along their Kepler orbits; G = 1, the inner orbit's
period 2 pi). REBOUND (the ``compare`` extra) is the reference where it is installed.
"""
import numpy as np
import pytest

from driftframe.framework import encounters
from driftframe.framework import mercurius as me
from driftframe.framework import wisdom_holman as wh


def close_pass(d=0.02):
    gm = np.array([1.0, 1e-3, 1e-3])
    X = np.array([[1.0, 0.0, 0.0], [1.0 + d, 0.0, 0.3 * d]])
    V = np.array([[0.0, 1.0, 0.0], [0.2, 1.1, 0.0]])
    wh.kepler_drift(X, V, 1.0, -1.5)
    x = np.vstack([[0.0, 0.0, 0.0], X])
    v = np.vstack([[0.0, 0.0, 0.0], V])
    x -= (gm[:, None] * x).sum(0) / gm.sum()
    v -= (gm[:, None] * v).sum(0) / gm.sum()
    return x, v, gm


def rebound_run(x, v, gm, integrator, t_end, dt=None, steps=None):
    import rebound                                        # the test extra installs it (pyproject.toml)
    sim = rebound.Simulation()
    sim.G = 1.0
    for k in range(len(gm)):
        sim.add(m=gm[k], x=x[k, 0], y=x[k, 1], z=x[k, 2], vx=v[k, 0], vy=v[k, 1], vz=v[k, 2])
    sim.integrator = integrator
    if steps is None:
        sim.integrate(t_end, exact_finish_time=1)
    else:
        sim.dt = dt
        sim.steps(steps)
        sim.synchronize()
    return (np.array([[p.x, p.y, p.z] for p in sim.particles]), np.array([[p.vx, p.vy, p.vz] for p in sim.particles]),
            sim)


def rel_energy_error(x, v, gm, E0):
    return abs(wh.energy(x, v, gm) / E0 - 1.0)


def test_a_close_pass_keeps_the_energy_where_plain_wisdom_holman_loses_it():
    x, v, gm = close_pass()
    E0 = wh.energy(x, v, gm)
    xw, vw = x.copy(), v.copy()
    wh.wisdom_holman(xw, vw, gm, 0.03, 100, coordinates="democratic")
    xm, vm = x.copy(), v.copy()
    got = me.mercurius(xm, vm, gm, 0.03, 100)
    assert got > 0                                      # the pass was seen
    assert rel_energy_error(xw, vw, gm, E0) > 1e-2      # measured 2.3e-2
    assert rel_energy_error(xm, vm, gm, E0) < 1e-6      # measured 2.5e-7
    # the momentum is kept to rounding by both (every pull is a pair's, both ends kicked)
    p = (gm[:, None] * vm).sum(0)
    assert np.abs(p - (gm[:, None] * v).sum(0)).max() < 1e-15


@pytest.mark.parametrize("steps, tol", [(100, 2e-5), (300, 2e-6)])
def test_a_close_pass_ends_where_rebounds_ias15_does_and_converges_as_dt_squared(steps, tol):
    x, v, gm = close_pass()
    xi, vi, _ = rebound_run(x, v, gm, "ias15", 3.0)
    xm, vm = x.copy(), v.copy()
    me.mercurius(xm, vm, gm, 3.0 / steps, steps)
    xw, vw = x.copy(), v.copy()
    wh.wisdom_holman(xw, vw, gm, 3.0 / steps, steps, coordinates="democratic")
    assert np.abs(xm - xi).max() < tol                  # measured 8.0e-6 and 9.1e-7
    assert np.abs(xw - xi).max() > 1000 * tol           # plain WH: 0.18 and 0.041


def test_the_energy_error_is_rebound_mercurius_own_at_the_same_step():
    x, v, gm = close_pass()
    E0 = wh.energy(x, v, gm)
    xr, vr, sim = rebound_run(x, v, gm, "mercurius", None, dt=0.03, steps=100)
    xm, vm = x.copy(), v.copy()
    me.mercurius(xm, vm, gm, 0.03, 100)
    ours = rel_energy_error(xm, vm, gm, E0)
    theirs = rel_energy_error(xr, vr, gm, E0)
    assert ours == pytest.approx(theirs, rel=1e-3)
    assert np.abs(xm - xr).max() < 1e-6


def test_without_an_encounter_the_switch_changes_nothing():
    """Pairs that never come within reach of their critical radius: the same bits as with no critical
    radius at all (every pull kicked, nothing redone: kick-drift-kick democratic Wisdom-Holman), and an
    energy error as the drift-kick-drift Wisdom-Holman's (the same order, the halves the other way)."""
    gm = np.array([1.0, 1e-3, 3e-4])
    x = np.array([[0.0, 0.0, 0.0], [5.2, 0.0, 0.0], [0.0, 9.5, 0.1]])
    v = np.array([[0.0, 0.0, 0.0], [0.0, 1.0 / np.sqrt(5.2), 0.0], [-1.0 / np.sqrt(9.5), 0.0, 0.0]])
    E0 = wh.energy(x, v, gm)
    xm, vm = x.copy(), v.copy()
    assert me.mercurius(xm, vm, gm, 0.5, 400) == 0
    x0, v0 = x.copy(), v.copy()
    assert me.mercurius(x0, v0, gm, 0.5, 400, dcrit=np.zeros(3)) == 0
    assert np.array_equal(xm, x0) and np.array_equal(vm, v0)
    xw, vw = x.copy(), v.copy()
    wh.wisdom_holman(xw, vw, gm, 0.5, 400, coordinates="democratic")
    ours, dkd = rel_energy_error(xm, vm, gm, E0), rel_energy_error(xw, vw, gm, E0)
    assert 0.2 < ours / dkd < 5.0


def test_many_steps_in_one_call_agree_with_one_step_at_a_time():
    x, v, gm = close_pass()
    dc = me.critical_radii(x, v, gm, 0.03)
    xa, va = x.copy(), v.copy()
    me.mercurius(xa, va, gm, 0.03, 60, dcrit=dc)
    xb, vb = x.copy(), v.copy()
    for _ in range(60):
        me.mercurius(xb, vb, gm, 0.03, 1, dcrit=dc)
    assert np.abs(xa - xb).max() < 1e-12


def test_the_changeover_is_zero_close_one_far_and_smooth_at_both_ends():
    rc = 2.0
    L = encounters.changeover
    assert L(0.0, rc) == 0.0 and L(0.1 * rc, rc) == 0.0 and L(rc, rc) == 1.0 and L(5 * rc, rc) == 1.0
    r = np.linspace(0.1 * rc, rc, 1001)
    vals = np.array([L(q, rc) for q in r])
    assert np.all(np.diff(vals) > 0.0)
    h = 1e-6
    for end in (0.1 * rc, rc):                          # value, slope and curvature continuous there
        slope = (L(end + h, rc) - L(end - h, rc)) / (2 * h)
        assert abs(slope) < 1e-5
    assert L(0.55 * rc, rc) == pytest.approx(0.5)


def test_the_adaptive_integrator_follows_an_exact_kepler_orbit():
    rng = np.random.default_rng(5)
    for e in (0.0, 0.5, 0.9):
        X = np.array([[1.0 - e, 0.0, 0.0], [0.0, 2.0, 0.3]])
        V = np.array([[0.0, np.sqrt((1 + e) / (1 - e)), 0.0], [-0.6, 0.1, 0.05]])
        X += rng.normal(0, 1e-3, X.shape)
        Xe, Ve = X.copy(), V.copy()
        wh.kepler_drift(Xe, Ve, 1.0, 7.0)
        # two bodies far from each other (critical radii 0): each on its own conic about the centre
        steps = encounters.bulirsch_stoer(X, V, np.array([1e-3, 1e-3]), np.zeros(2), 1.0, 7.0, 1e-13)
        assert steps > 0
        assert np.abs(X - Xe).max() < 1e-11 and np.abs(V - Ve).max() < 1e-11


def test_critical_radii_are_the_largest_of_rebounds_criteria():
    x, v, gm = close_pass()
    dc = me.critical_radii(x, v, gm, 0.03)
    assert dc[0] == 0.0
    r = np.linalg.norm(x[1:] - x[0], axis=1)
    w2 = np.sum((v[1:] - v[0]) ** 2, axis=1)
    a = 1.001 * r / (2.0 * 1.001 - r * w2)              # vis-viva about G (m_0 + m_i)
    assert dc[1:] == pytest.approx(3.0 * a * np.cbrt(1e-3 / 3.0), rel=1e-12)     # three Hill radii
    big_dt = me.critical_radii(x, v, gm, 30.0)          # a long step: the distance a step moves the body
    assert big_dt[1] == pytest.approx(0.4 * 30.0 * np.linalg.norm(v[1] - v[0]), rel=0.05)


def test_bad_input_is_a_clear_error():
    x, v, gm = close_pass()
    with pytest.raises(ValueError, match="dcrit"):
        me.mercurius(x, v, gm, 0.03, dcrit=np.ones(2))
    with pytest.raises(ValueError, match="dcrit"):
        me.mercurius(x, v, gm, 0.03, dcrit=np.array([0.0, -1.0, 1.0]))
    with pytest.raises(ValueError, match="tolerance"):
        me.mercurius(x, v, gm, 0.03, tolerance=0.0)
    with pytest.raises(ValueError, match="hill"):
        me.mercurius(x, v, gm, 0.03, hill=float("nan"))
    with pytest.raises(ValueError, match="dominant"):
        me.mercurius(x, v, np.array([0.0, 1.0, 1.0]), 0.03)
    with pytest.raises(ValueError, match="dt"):
        me.mercurius(x, v, gm, 0.0)


def test_the_array_changeover_is_the_kernels():
    rc = np.array([1.0, 2.0, 3.0])
    r = np.linspace(0.0, 4.0, 97)
    got = encounters.changeover_array(r[:, None], rc[None, :])
    want = np.array([[encounters.changeover(a, b) for b in rc] for a in r])
    assert np.array_equal(got, want)


def test_the_encounter_set_is_the_bodies_of_pairs_that_come_within_reach():
    """Three bodies on straight lines over a drift of 1: a and b pass 0.5 apart in mid-step (both ends 2.1
    apart: only the cubic through the ends' rates sees it), c stays 10 away."""
    x0 = np.array([[-1.0, 0.25, 0.0], [1.0, -0.25, 0.0], [0.0, 10.0, 0.0]])
    v0 = np.array([[2.0, 0.0, 0.0], [-2.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    x1 = x0 + v0
    mask = me.encounter_set(x0, v0, x1, v0, np.array([0.5, 0.5, 0.5]), 1.0)      # reach 0.55 > 0.5
    assert mask.tolist() == [True, True, False]
    mask = me.encounter_set(x0, v0, x1, v0, np.array([0.4, 0.4, 0.4]), 1.0)      # reach 0.44 < 0.5
    assert mask.tolist() == [False, False, False]


def test_near_pairs_are_the_pairs_inside_the_larger_critical_radius():
    rng = np.random.default_rng(2)
    x = rng.uniform(0.0, 10.0, (60, 3))
    dc = rng.uniform(0.0, 2.0, 60)
    ii, jj = me.near_pairs(x, dc)
    want = [(i, j) for i in range(60) for j in range(i + 1, 60)
            if np.linalg.norm(x[j] - x[i]) < max(dc[i], dc[j])]
    assert list(zip(ii.tolist(), jj.tolist())) == want and len(want) > 10


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_cheap_bound_never_drops_a_pair_the_cubic_flags(sign):
    """The prediction's first test (a lower bound of the cubic) only skips pairs the cubic itself would not
    flag: random drifts, forwards and backwards, flagged alike with and without it."""
    rng = np.random.default_rng(11)
    for _ in range(200):
        x0 = rng.normal(0.0, 1.0, (6, 3))
        v0 = rng.normal(0.0, 1.0, (6, 3))
        x1 = x0 + sign * 0.5 * v0 + rng.normal(0.0, 0.05, (6, 3))
        v1 = v0 + rng.normal(0.0, 0.2, (6, 3))
        dc = rng.uniform(0.0, 0.8, 6)
        got = me.encounter_set(x0, v0, x1, v1, dc, sign * 0.5)
        want = np.zeros(6, bool)
        for i in range(6):
            for j in range(i + 1, 6):
                rc = 1.1 * max(dc[i], dc[j])
                if me._closest_squared(x0, v0, x1, v1, i, j, sign * 0.5) < rc * rc:
                    want[i] = want[j] = True
        assert np.array_equal(got, want)
