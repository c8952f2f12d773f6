"""The warp governor: time warp drops before a predicted contact (with a surface or between two bodies
on rails) or a scheduled burn.

The contacts come from the :class:`~driftframe.framework.orbit_state.OrbitState` resource the gravity
system publishes (this system reads it; it never imports the gravity system)."""
from __future__ import annotations

import math

import esper

from driftframe.components.autopilot import Autopilot, FlightPlan
from driftframe.components.body import Transform, Velocity
from driftframe.components.collision import SphereCollider
from driftframe.components.control import FlightControl
from driftframe.components.gravity import Orbiting
from driftframe.framework import warp as time_warp
from driftframe.framework.orbit_state import OrbitState


class WarpGovernorSystem(esper.Processor):
    """Reads OrbitState, Orbiting, Autopilot, FlightPlan, FlightControl; writes the world's TimeWarp limit.
    Warp drops before events.

    Each step it looks for the next event the player should see at a
    watchable speed: the earliest surface contact and the earliest contact
    between two colliders on rails predicted by the gravity system
    (``world.resources[OrbitState]``: exact,
    on the bodies' conics; the second looked for as far as the warp asked
    for could reach in ``lead_frames`` frames) and the start of every scheduled
    autopilot burn, engaged or still to come in a
    :class:`~components.autopilot.FlightPlan` (1x while a burn is under way). The warp then allowed is the largest level whose frame
    of ``W`` steps leaves the event at least ``lead_frames`` frames away
    (``W dt lead_frames <= time to the event``); the reason goes to
    ``TimeWarp.reason`` for the HUD. Warp only changes how many steps a frame
    shows, never the steps, so dropping it changes nothing in the simulation.
    """

    name = "warp"
    after = ("commit",)                 # the bodies at the end of the step
    before = ("camera",)
    #: (OrbitState's answers read the bodies' Transform, Velocity and SphereCollider while this system runs)
    reads = (OrbitState, Orbiting, Autopilot, FlightPlan, FlightControl, Transform, Velocity, SphereCollider)
    writes = (time_warp.TimeWarp,)

    @property
    def requires(self) -> tuple[type, ...]:
        """Nothing to do in a world without a TimeWarp (there is no warp to govern): then it asks for an
        entity with a TimeWarp, which none has, so the world does not call it (the world reads this again
        at the start of a step when resources were published or taken away since the last)."""
        world = getattr(self, "world", None)
        return () if world is not None and time_warp.TimeWarp in world.resources else (time_warp.TimeWarp,)

    def __init__(self, lead_frames: int = 30):
        if isinstance(lead_frames, bool) or not isinstance(lead_frames, int) or lead_frames < 1:
            raise ValueError(f"lead_frames must be an int >= 1, got {lead_frames!r}")
        self.lead_frames = lead_frames

    def next_event(self, horizon: float = math.inf) -> tuple[float, str] | None:
        """``(seconds from now, what)`` of the next event to slow down for, or None. Contacts between
        bodies are looked for ``horizon`` s ahead (the surface contacts and burns are known at any
        distance)."""
        world = self.world
        now = (world.step_count + 1) * world.dt          # this step has run: the state is at its end
        best: tuple[float, str] | None = None
        orbits = world.resources.get(OrbitState)           # (None: no gravity system, no contact to predict)
        contact = orbits.next_contact() if orbits is not None else None
        if contact is not None:
            best = (contact.time - now, f"entity {contact.entity} reaches the surface of {contact.well}")
        pair = orbits.next_sphere_contact(horizon) if orbits is not None and math.isfinite(horizon) else None
        if pair is not None and (best is None or pair.time - now < best[0]):
            verb = "may touch" if pair.bound else "touch"     # (n-body: a lower bound)
            best = (pair.time - now, f"entities {pair.a} and {pair.b} {verb}")
        burns = [(ent, ap) for ent, ap in esper.get_component(Autopilot) if ap.mode == "burn" and not ap.done]
        for ent, plan in esper.get_component(FlightPlan):          # and the burns a plan has still to come
            burns += [(ent, leg) for _, leg in plan.legs[plan.next:] if leg.mode == "burn"]
        for ent, ap in burns:
            thrust = _thrust(ent)
            start = ap.at - (0.5 * ap.dv / thrust if thrust > 0 else 0.0)
            ahead = max(start - now, 0.0)             # under way: hold 1x until it is done
            if best is None or ahead < best[0]:
                best = (ahead, f"burn of {ap.dv:.1f} m/s")
        return best

    def process(self, dt: float) -> None:
        warp = self.world.resources.get(time_warp.TimeWarp)
        if warp is None or warp.requested == 1:
            if warp is not None:
                warp.limit, warp.reason = None, ""
            return
        # contacts between bodies matter only as far as the requested warp reaches in lead_frames frames
        event = self.next_event(warp.requested * dt * self.lead_frames)
        if event is None or event[0] < 0:
            warp.limit, warp.reason = None, ""
            return
        ahead, what = event
        allowed = ahead / (dt * self.lead_frames)
        limit = max([lv for lv in time_warp.LEVELS if lv <= allowed] or [1])
        warp.limit = limit
        warp.reason = f"{what} in {ahead:.0f} s" if limit < warp.requested else ""


def _thrust(ent) -> float:
    ctl = esper.try_component(ent, FlightControl)
    return ctl.thrust if ctl is not None else 0.0
