"""Readouts of a conic: orbital elements (:class:`Elements`), the closest approach of two bodies on
conics about one mass, and points along a conic to draw."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from driftframe.framework.kepler_universal import TWO_PI, _dot, _norm, period, propagate


@dataclass(frozen=True)
class Elements:
    """Orbit readouts of states about one mass; arrays of shape ``(n,)`` (``h``, ``e_vec``: ``(n, 3)``).

    Lengths in m, times in s, energies in J/kg. Open orbits (``e >= 1``) have
    ``apoapsis = period = time_to_apoapsis = inf``; ``time_to_periapsis`` is
    negative once a hyperbolic body is past periapsis (it will not come back).
    """

    #: Semi-major axis, m (negative for hyperbolas, inf for a parabola).
    a: np.ndarray
    #: Eccentricity (0 circle, < 1 ellipse, 1 parabola or radial, > 1 hyperbola).
    e: np.ndarray
    #: Eccentricity vector (points at periapsis), world frame.
    e_vec: np.ndarray
    #: Specific angular momentum r x v, world frame, m^2/s.
    h: np.ndarray
    #: Specific orbital energy v^2/2 - mu/r, J/kg.
    energy: np.ndarray
    #: Distances from the mass's centre, m.
    periapsis: np.ndarray
    apoapsis: np.ndarray
    #: s.
    period: np.ndarray
    time_to_periapsis: np.ndarray
    time_to_apoapsis: np.ndarray


def elements(r, v, mu) -> Elements:
    """Readouts of the conics through states ``(r, v)`` about ``mu`` (see :class:`Elements`).

    Periapsis ``p / (1 + e)`` with ``p = h^2/mu`` (exact for radial orbits too:
    ``p = 0``); times from Kepler's equation in the eccentric (or hyperbolic)
    anomaly, ``M = E - e sin E``, ``M = e sinh H - H``.
    """
    r = np.atleast_2d(np.asarray(r, dtype=np.float64))
    v = np.atleast_2d(np.asarray(v, dtype=np.float64))
    n = r.shape[0]
    mu = np.broadcast_to(np.asarray(mu, dtype=np.float64), (n,))
    rn = _norm(r)
    v2 = _dot(v, v)
    rv = _dot(r, v)
    h = np.cross(r, v)
    with np.errstate(divide="ignore", invalid="ignore"):
        e_vec = ((v2 - mu / rn)[:, None] * r - rv[:, None] * v) / mu[:, None]
        e = _norm(e_vec)
        energy = 0.5 * v2 - mu / rn
        alpha = 2.0 / rn - v2 / mu
        a = 1.0 / alpha
        p = _dot(h, h) / mu
        rp = np.where(p > 0, p / (1.0 + e), np.where(alpha > 0, a * (1.0 - e), 0.0))
        ra = np.where(alpha > 0, a * (1.0 + e), np.inf)
        per = period(alpha, mu)
        # elliptic: eccentric anomaly E from e cos E = 1 - r/a, e sin E = r.v / sqrt(mu a)
        ell = alpha > 0                            # bound (radial ones have e = 1 to rounding)
        cosE = 1.0 - rn * alpha
        sinE = rv / np.sqrt(mu * np.abs(a))
        E = np.arctan2(sinE, cosE)
        M = E - sinE                               # e sin E = sinE as defined
        nmean = np.sqrt(mu * np.abs(alpha) ** 3)
        t_peri_e = np.mod(-M, TWO_PI) / nmean
        t_apo_e = np.mod(np.pi - M, TWO_PI) / nmean
        # hyperbolic: e sinh H = r.v / sqrt(-mu a), e cosh H = 1 - r/a
        sinhH_e = rv / np.sqrt(mu * np.abs(a))
        H = np.arcsinh(sinhH_e / np.where(e > 0, e, 1.0))
        Mh = sinhH_e - H
        t_peri_h = -Mh / nmean
        # parabola (alpha = 0): Barker, D = r.v/sqrt(mu), t_p = -(p D/2 + D^3/6)... via D
        D = rv / np.sqrt(mu)
        t_peri_p = -(p * D + D ** 3 / 3.0) / (2.0 * np.sqrt(mu))
    t_peri = np.where(ell, t_peri_e, np.where(alpha < 0, t_peri_h, t_peri_p))
    t_apo = np.where(ell, t_apo_e, np.inf)
    return Elements(a=a, e=e, e_vec=e_vec, h=h, energy=energy, periapsis=rp, apoapsis=ra,
                    period=per, time_to_periapsis=t_peri, time_to_apoapsis=t_apo)



def _mean_anomaly_e(el: Elements, idx):
    """Mean anomaly now (elliptic, mod 2 pi), from the time to periapsis."""
    return -el.time_to_periapsis[idx] * (TWO_PI / el.period[idx])


def closest_approach(r1, v1, r2, v2, mu, horizon, *, samples: int = 256):
    """When and how close two bodies on conics about the same mass come, within ``[0, horizon]`` s.

    ``r1, v1`` and ``r2, v2`` are single states (3,) relative to the mass.
    The distance is sampled at ``samples`` times along both exact conics and
    the smallest sample is refined by golden-section search on its bracket
    (the distance is smooth; one bracket of 1/samples of the horizon holds one
    minimum for any sensible sample count). Returns ``(t, distance)``.
    """
    horizon = float(horizon)
    ts = np.linspace(0.0, horizon, samples + 1)
    n = ts.size
    a, _ = propagate(np.repeat(np.atleast_2d(r1), n, 0), np.repeat(np.atleast_2d(v1), n, 0), mu, ts)
    b, _ = propagate(np.repeat(np.atleast_2d(r2), n, 0), np.repeat(np.atleast_2d(v2), n, 0), mu, ts)
    d = _norm(a - b)
    k = int(np.argmin(d))
    lo, hi = ts[max(k - 1, 0)], ts[min(k + 1, n - 1)]

    def dist(t):
        pa, _ = propagate(r1, v1, mu, t)
        pb, _ = propagate(r2, v2, mu, t)
        return float(np.linalg.norm(pa - pb))

    g = (np.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1, f2 = dist(x1), dist(x2)
    for _ in range(60):
        if hi - lo <= 1e-9 * max(horizon, 1.0):
            break
        if f1 < f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - g * (hi - lo)
            f1 = dist(x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + g * (hi - lo)
            f2 = dist(x2)
    t = 0.5 * (lo + hi)
    dt_ = dist(t)
    if d[k] < dt_:
        return float(ts[k]), float(d[k])
    return float(t), dt_


def orbit_points(r, v, mu, n: int = 128, *, max_radius: float | None = None):
    """``n`` points (n, 3) along the conic through ``(r, v)``, for drawing the predicted orbit.

    Ellipses: one period at equal steps of eccentric anomaly (dense near
    periapsis, where the path bends). Open orbits: from now out to
    ``max_radius`` (default 4 x the current distance), equal steps in time.
    """
    r = np.asarray(r, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    el = elements(r, v, mu)
    if el.e[0] < 1.0 and np.isfinite(el.period[0]):
        # times of equally spaced eccentric anomalies from now
        E0 = -el.time_to_periapsis[0] * TWO_PI / el.period[0]        # mean anomaly now
        Es = np.linspace(0.0, TWO_PI, n)
        M = Es - el.e[0] * np.sin(Es)
        t = np.mod(M - E0, TWO_PI) * el.period[0] / TWO_PI
        pts, _ = propagate(np.repeat(r[None], n, 0), np.repeat(v[None], n, 0), mu, t)
        return pts
    rmax = max_radius if max_radius is not None else 4.0 * float(np.linalg.norm(r))
    # time to reach rmax outbound: bracket by doubling
    horizon = float(np.linalg.norm(r) / max(np.linalg.norm(v), 1e-12))
    for _ in range(60):
        p, _ = propagate(r, v, mu, horizon)
        if np.linalg.norm(p) >= rmax:
            break
        horizon *= 2.0
    t = np.linspace(0.0, horizon, n)
    pts, _ = propagate(np.repeat(r[None], n, 0), np.repeat(v[None], n, 0), mu, t)
    return pts

