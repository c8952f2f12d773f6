"""kepler_small: Epoch.at's numpy path for a few bodies, compiled, gives the numpy path's bits."""
import numpy as np
import pytest

from driftframe.framework import kepler_small
from driftframe.framework import kepler_universal as ku


def _cases(seed, count):
    """Epochs of 1-5 bodies (circles, ellipses up to e ~ 1, hyperbolas), times up to 30 periods either way,
    guesses near the solution (as next_chi's), off it, or NaN."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        n = int(rng.integers(1, 6))
        mu = float(10 ** rng.uniform(0, 15))
        rr = 10 ** rng.uniform(0, 7, n)
        dirs = rng.normal(size=(n, 3))
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        vd = rng.normal(size=(n, 3))
        vd /= np.linalg.norm(vd, axis=1)[:, None]
        v0 = vd * (np.sqrt(mu / rr) * rng.uniform(0.01, 1.6, n))[:, None]
        ep = ku.Epoch(dirs * rr[:, None], v0, mu)
        per = np.where(np.isfinite(ep.period), ep.period, rr / np.sqrt(mu / rr))
        dt = per * 10 ** rng.uniform(-4, 1.5, n) * rng.choice([1.0, 1.0, 1.0, -1.0], n)
        if rng.random() < 0.1:
            dt[0] = 0.0
        guess = ep.at(dt)[2] * (1 + rng.normal(size=n) * 10 ** rng.uniform(-16, -1))
        if rng.random() < 0.2:
            guess[rng.integers(0, n)] = np.nan
        yield ep, dt, guess


def test_a_few_bodies_get_the_numpy_paths_bits_from_the_kernel(monkeypatch):
    taken = []

    def kernel(*args):
        taken.append(kepler_small._at_small(*args))
        return taken[-1]

    for ep, dt, guess in _cases(3, 400):
        monkeypatch.setattr(ku, "_at_small", kernel)
        fast = ep.at(dt, guess)
        monkeypatch.setattr(ku, "_at_small", lambda *args: kepler_small.NUMPY)
        slow = ep.at(dt, guess)
        for a, b in zip(fast, slow):
            assert a.tobytes() == b.tobytes(), (ep.r0, ep.v0, dt, guess)
    # most cases take the kernel; hyperbolas far out (cosh, sinh) and long-step first guesses take numpy
    assert 0.5 * len(taken) < taken.count(kepler_small.DONE) < len(taken)


def test_what_needs_numpys_own_functions_is_left_to_numpy():
    # a hyperbola 1e4 s out: psi < -1 needs cosh and sinh, which numpy computes with its own SIMD code
    ep = ku.Epoch(np.array([[7e6, 0.0, 0.0]]), np.array([[0.0, 1.5e4, 0.0]]), 3.986e14)
    assert ep.alpha[0] < 0
    out = [np.empty((1, 3)), np.empty((1, 3)), np.empty(1)]
    assert kepler_small._at_small(*ep._columns(), ku.FOCAL_DD_OME, np.array([1e4]), np.array([np.nan]),
                                  *out) == kepler_small.NUMPY
    r, v, chi = ep.at(1e4, np.array([np.nan]))                   # (the numpy path then answers)
    assert np.isfinite(r).all() and np.isfinite(chi).all()


@pytest.mark.parametrize("dt", [1.0, 100.0])
def test_the_kernel_answers_a_circle(dt):
    ep = ku.Epoch(np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]), 1.0)
    r, v, chi = ep.at(dt, np.array([dt]))
    assert np.allclose(r[0], [np.cos(dt), np.sin(dt), 0.0], atol=1e-12)
    assert np.allclose(v[0], [-np.sin(dt), np.cos(dt), 0.0], atol=1e-12)


def test_next_chi_for_a_few_bodies_gets_the_numpy_lines_bits(monkeypatch):
    rng = np.random.default_rng(5)
    for _ in range(300):
        n = int(rng.integers(1, 6))
        mu, step = 10 ** rng.uniform(0, 15), 10 ** rng.uniform(-2, 3)
        r, v = rng.normal(size=(n, 3)) * 10 ** rng.uniform(0, 7), rng.normal(size=(n, 3)) * 10 ** rng.uniform(-2, 4)
        X, V = rng.normal(size=3) * 10 ** rng.uniform(0, 7), rng.normal(size=3) * 10 ** rng.uniform(-2, 4)
        chi = rng.normal(size=n) * 100
        fast = ku.next_chi(chi, r, v, mu, step, origin=(X, V))
        # next_chi's numpy lines (kepler_universal._dot is numpy's einsum)
        rr, vv = r - X, v - V
        rn2 = ku._dot(rr, rr)
        dchi = step * np.sqrt(mu / rn2) * (1.0 - 0.5 * step * ku._dot(rr, vv) / rn2)
        alpha = 2.0 / np.sqrt(rn2) - ku._dot(vv, vv) / mu
        slow = np.where(np.abs(alpha) * dchi * dchi <= 0.2, chi + dchi, np.nan)
        assert fast.tobytes() == slow.tobytes()
