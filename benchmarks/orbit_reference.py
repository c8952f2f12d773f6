"""Reference states for :mod:`benchmarks.orbit_accuracy`'s every-step errors, in extended precision.

The *double-rounding floor*: the exact state, rounded to doubles, already misses the orbit's
energy by up to ``~2/(1 - e)`` ulp at periapsis (``v^2/2`` and ``mu/r`` cancel). It is measured
here by computing the exact state in ``np.longdouble`` (x87 80-bit: 64-bit mantissa, 1e-19) on
the ellipse through the double starting state, rounding it to float64 and taking its energy.
Energies and angular momenta of double states are evaluated in long double too, so the figures are
the states' errors, not the evaluation's. Where ``np.longdouble`` is only a double (Windows, some
ARM builds), :data:`EXTENDED` is False and the floor is not reported.
"""
from __future__ import annotations

import numpy as np

LD = np.longdouble
EXTENDED = np.finfo(LD).eps < 1e-18


def energy(r, v, mu=1.0):
    """``v^2/2 - mu/|r|`` of double (or long double) states, in long double."""
    r = np.asarray(r, dtype=LD)
    v = np.asarray(v, dtype=LD)
    return 0.5 * np.einsum("ij,ij->i", v, v) - LD(mu) / np.sqrt(np.einsum("ij,ij->i", r, r))


def ang_mom(r, v):
    """``|r x v|`` in long double."""
    h = np.cross(np.asarray(r, dtype=LD), np.asarray(v, dtype=LD))
    return np.sqrt(np.einsum("ij,ij->i", h, h))


def ellipse_states(r0, v0, times, mu=1.0):
    """Long-double states at ``times`` (s, ``(n,)``) on the ellipse through ``(r0, v0)`` (3-vectors, about
    ``mu``), from Kepler's equation in the eccentric anomaly (Newton to convergence) and the focal frame.
    ``r = a (1 - e) + 2 a e sin^2(E/2)`` and ``cos E - e = (1 - e) - 2 sin^2(E/2)``: no cancellation at
    periapsis. A nearly circular orbit (``e < 1e-9``) is taken as circular from ``r0``."""
    r0 = np.asarray(r0, dtype=LD)
    v0 = np.asarray(v0, dtype=LD)
    mu = LD(mu)
    rn = np.sqrt(r0 @ r0)
    vv = v0 @ v0
    rv = r0 @ v0
    a = LD(1) / (LD(2) / rn - vv / mu)
    evec = ((vv - mu / rn) * r0 - rv * v0) / mu
    e = np.sqrt(evec @ evec)
    hv = np.cross(r0, v0)
    hh = hv / np.sqrt(hv @ hv)
    if e < 1e-9:
        e, P, E0 = LD(0), r0 / rn, LD(0)
    else:
        P = evec / e
        E0 = np.arctan2(rv / np.sqrt(mu * a), LD(1) - rn / a)
    Q = np.cross(hh, P)
    M = E0 - e * np.sin(E0) + np.sqrt(mu / a ** 3) * np.asarray(times, dtype=LD)
    pi = LD(np.pi)
    M = np.remainder(M + pi, 2 * pi) - pi
    E = M + LD(0.85) * e * np.sign(np.sin(M))
    for _ in range(60):
        E = E - (E - e * np.sin(E) - M) / (1 - e * np.cos(E))
    s2 = np.sin(E / 2) ** 2
    om = np.sqrt((1 - e) * (1 + e))
    x = a * ((1 - e) - 2 * s2)
    y = a * om * np.sin(E)
    r = a * ((1 - e) + 2 * e * s2)
    k = np.sqrt(mu * a) / r
    return (x[:, None] * P + y[:, None] * Q,
            (-k * np.sin(E))[:, None] * P + (k * om * np.cos(E))[:, None] * Q)


def hyperbola_states(r0, v0, times, mu):
    """Long-double states at ``times`` (s) on the hyperbola through ``(r0, v0)`` (3-vectors, about ``mu``):
    Kepler's hyperbolic equation ``e sinh H - H = M`` (Newton from asinh(M/e)) and the focal frame."""
    r0 = np.asarray(r0, dtype=LD)
    v0 = np.asarray(v0, dtype=LD)
    mu = LD(mu)
    rn = np.sqrt(r0 @ r0)
    vv = v0 @ v0
    rv = r0 @ v0
    A = -LD(1) / (LD(2) / rn - vv / mu)                   # -a > 0
    evec = ((vv - mu / rn) * r0 - rv * v0) / mu
    e = np.sqrt(evec @ evec)
    P = evec / e
    hv = np.cross(r0, v0)
    Q = np.cross(hv / np.sqrt(hv @ hv), P)
    H0 = np.arcsinh(rv / np.sqrt(mu * A) / e)
    M = e * np.sinh(H0) - H0 + np.sqrt(mu / A ** 3) * np.asarray(times, dtype=LD)
    H = np.arcsinh(M / e)
    for _ in range(100):
        H = H - (e * np.sinh(H) - H - M) / (e * np.cosh(H) - 1)
    om = np.sqrt((e - 1) * (e + 1))
    r = A * (e * np.cosh(H) - 1)
    k = np.sqrt(mu * A) / r
    x, y = A * (e - np.cosh(H)), A * om * np.sinh(H)
    return (x[:, None] * P + y[:, None] * Q,
            (-k * np.sinh(H))[:, None] * P + (k * om * np.cosh(H))[:, None] * Q)
