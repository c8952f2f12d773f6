"""Orbit readouts for the HUD (and for tools): apoapsis, periapsis, period, times to each, closest
approach to the target, the warp, and the predicted orbit as world points.

Pure functions of the world's current state (no GL): the HUD draws what they
return in both cameras, tests check them against closed forms. The well a body
moves about comes from the gravity system's
:class:`~driftframe.framework.orbit_state.OrbitState` resource
(``world.resources[OrbitState]``); a world without one has no orbits.
"""
from __future__ import annotations

from dataclasses import dataclass

import esper
import numpy as np

from driftframe.components.autopilot import Autopilot
from driftframe.components.body import Transform, Velocity
from driftframe.framework import kepler
from driftframe.framework.orbit_state import OrbitState, Reference
from driftframe.framework.warp import TimeWarp
from driftframe.framework.world import World


@dataclass(frozen=True)
class OrbitReadout:
    """One body's orbit about the well it moves about now. Altitudes are above the well's surface (m);
    times in s from now (inf where there is none: an open orbit has no apoapsis)."""

    well: int
    altitude: float
    apoapsis: float
    periapsis: float
    period: float
    time_to_apoapsis: float
    time_to_periapsis: float
    eccentricity: float
    #: Seconds until the body meets the surface on this orbit, inf if it does not.
    time_to_impact: float


def _reference(world: World, ent: int) -> Reference | None:
    """The well ``ent`` moves about now (:meth:`OrbitState.reference`), or None without gravity."""
    orbits = world.resources.get(OrbitState)
    return orbits.reference(ent) if orbits is not None else None


def orbit(world: World, ent: int) -> OrbitReadout | None:
    """The readout of ``ent``'s orbit, or None in a scene without wells (or for a root well)."""
    ref = _reference(world, ent)
    if ref is None:
        return None
    well, mu, radius, X, V = ref
    x = world.columns(Transform, [ent]).position[0]
    v = world.columns(Velocity, [ent]).linear[0]
    r, u = x - X, v - V
    el = kepler.elements(r, u, mu)
    impact = kepler.time_to_radius(r, u, mu, radius, np.inf)[0]
    return OrbitReadout(well=well, altitude=float(np.linalg.norm(r) - radius),
                        apoapsis=float(el.apoapsis[0] - radius), periapsis=float(el.periapsis[0] - radius),
                        period=float(el.period[0]), time_to_apoapsis=float(el.time_to_apoapsis[0]),
                        time_to_periapsis=float(el.time_to_periapsis[0]), eccentricity=float(el.e[0]),
                        time_to_impact=float(impact))


def closest_approach(world: World, ent: int, target: int, horizon: float | None = None) -> tuple[float, float]:
    """``(seconds from now, distance in m)`` of ``ent``'s closest approach to ``target``, both on their
    conics about ``ent``'s well (one orbit of ``ent``, or 2 hours on an open orbit, unless given);
    on straight lines in a scene without wells."""
    x = world.columns(Transform, [ent, target]).position
    v = world.columns(Velocity, [ent, target]).linear if esper.has_component(target, Velocity) else \
        np.vstack([world.columns(Velocity, [ent]).linear, np.zeros((1, 3))])
    ref = _reference(world, ent)
    if ref is None:
        d, w = x[1] - x[0], v[1] - v[0]
        ww = float(w @ w)
        t = max(0.0, -float(d @ w) / ww) if ww > 0 else 0.0
        if horizon is not None:
            t = min(t, horizon)
        return t, float(np.linalg.norm(d + w * t))
    _, mu, _, X, V = ref
    el = kepler.elements(x[0] - X, v[0] - V, mu)
    if horizon is None:
        horizon = float(el.period[0]) if np.isfinite(el.period[0]) else 7200.0
    return kepler.closest_approach(x[0] - X, v[0] - V, x[1] - X, v[1] - V, mu, horizon)


def predicted_orbit(world: World, ent: int, n: int = 128) -> np.ndarray | None:
    """``n`` world points (n, 3) along ``ent``'s predicted conic about its well (at the well's current
    position), or None without a well."""
    ref = _reference(world, ent)
    if ref is None:
        return None
    _, mu, radius, X, V = ref
    x = world.columns(Transform, [ent]).position[0]
    v = world.columns(Velocity, [ent]).linear[0]
    pts = kepler.orbit_points(x - X, v - V, mu, n, max_radius=max(4.0 * float(np.linalg.norm(x - X)), 4 * radius))
    return pts + X


def _t(s: float) -> str:
    if not np.isfinite(s):
        return "-"
    s = float(s)
    if abs(s) >= 3600:
        return f"{s / 3600:.2f} h"
    if abs(s) >= 60:
        return f"{s / 60:.1f} min"
    return f"{s:.1f} s"


def _km(m: float) -> str:
    return "-" if not np.isfinite(m) else f"{m / 1000:.1f} km"


def lines(world, ent: int) -> list[str]:
    """The HUD's orbit lines for ``ent`` (empty without a well): apoapsis/periapsis and their times,
    the period, an impact warning, the closest approach to the autopilot's target, the aid and the warp."""
    from driftframe.framework import warp as time_warp

    out = []
    o = orbit(world, ent)
    if o is not None:
        out.append(f"ALT     {_km(o.altitude)}   e {o.eccentricity:.3f}")
        out.append(f"APO     {_km(o.apoapsis)} in {_t(o.time_to_apoapsis)}")
        out.append(f"PERI    {_km(o.periapsis)} in {_t(o.time_to_periapsis)}")
        out.append(f"PERIOD  {_t(o.period)}")
        if np.isfinite(o.time_to_impact):
            out.append(f"IMPACT  in {_t(o.time_to_impact)}")
    ap = esper.try_component(ent, Autopilot)
    if ap is not None:
        if ap.target is not None and esper.entity_exists(ap.target) and esper.has_component(ap.target, Transform):
            t, d = closest_approach(world, ent, ap.target)
            out.append(f"CLOSEST {d:.0f} m in {_t(t)}")
        if ap.mode != "off":
            out.append(f"AUTO    {ap.status or ap.mode}")
    warp = world.resources.get(TimeWarp)
    if warp is not None and (warp.requested > 1 or warp.reason):
        line = f"WARP    x{warp.factor:,}"
        if warp.dropped:                 # asked -> held to, and why (short: the HUD keeps to a sixth of the frame)
            line = f"WARP    x{warp.requested:,}\u2192x{warp.factor:,}: {warp.reason}"
        out.append(line)
    return out
