"""Flight aids: what the autopilot is asked to do (cold data, one per assisted ship).

The autopilot flies through the same controls as the pilot: it writes the
ship's :class:`~components.control.FlightInput` (pitch, yaw, roll, throttle
in [-1, 1]), so its angular acceleration is bounded by the ship's
:class:`~components.control.FlightControl` ``angular_accel`` and its thrust by
``thrust``, exactly as a player's would be.

Directions (world frame, evaluated each step):

* ``prograde`` / ``retrograde``: along / against the velocity relative to the
  well the ship moves about (the world frame without wells);
* ``normal`` / ``antinormal``: along / against the orbit's angular momentum
  ``r x v`` about that well;
* ``radial_out`` / ``radial_in``: away from / towards the well's centre, in the
  orbit plane, perpendicular to the velocity;
* ``target`` / ``anti_target``: towards / away from the ``target`` entity.

Tasks that thrust:

* ``match_velocity``: burn until the velocity relative to ``target`` is zero;
* ``burn``: a timed burn of ``dv`` (m/s) along ``along`` (one of the
  directions above), centred on the time ``at`` (s, simulated), delivering
  exactly ``dv``;
* ``flip_and_burn``: accelerate towards ``target`` (an entity) or ``point``
  (world frame, m), flip, and brake to stop there (``standoff`` m short of
  it); then keep station there.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from driftframe.framework import validate

DIRECTIONS = ("prograde", "retrograde", "normal", "antinormal", "radial_out", "radial_in",
              "target", "anti_target")
TASKS = ("match_velocity", "burn", "flip_and_burn")
MODES = ("off",) + DIRECTIONS + TASKS


@dataclass
class Autopilot:
    """The aid engaged on this ship, its parameters, and its progress (written by the system)."""

    #: One of :data:`MODES`.
    mode: str = "off"
    #: Entity id of the target (target holds, match_velocity, flip_and_burn), or None.
    target: int | None = None
    #: flip_and_burn without a target: the point to stop at, world frame, m.
    point: tuple | None = None
    #: burn: the velocity change, m/s (> 0).
    dv: float = 0.0
    #: burn: the direction to burn along (one of DIRECTIONS).
    along: str = "prograde"
    #: burn: the time the burn is centred on, s since the world's start.
    at: float = 0.0
    #: Pointing error below which the engine may fire, rad.
    aim: float = 0.01
    #: Largest turn rate the aid commands, rad/s.
    max_rate: float = 1.0
    #: Relative speed at which match_velocity / flip_and_burn count as done, m/s.
    tolerance: float = 0.01
    #: flip_and_burn: stop this far short of the target or point, m (>= 0).
    standoff: float = 0.0
    #: Written by the system: the Δv delivered by this task so far, m/s.
    delivered: float = field(default=0.0, compare=False)
    #: Written by the system: True once the task is complete (holds never finish).
    done: bool = field(default=False, compare=False)
    #: Written by the system: one line for the HUD.
    status: str = field(default="", compare=False)

    def __post_init__(self):
        validate.choice("Autopilot.mode", self.mode, MODES)
        validate.choice("Autopilot.along", self.along, DIRECTIONS)
        self.target = validate.entity_id("Autopilot.target", self.target, optional=True)
        if self.point is not None:
            self.point = tuple(validate.vector("Autopilot.point", self.point).tolist())
        needs_target = self.mode in ("target", "anti_target", "match_velocity") or \
            (self.mode == "burn" and self.along in ("target", "anti_target"))
        if needs_target and self.target is None:
            raise ValueError(f"Autopilot mode {self.mode!r} needs a target entity, got target=None")
        if self.mode == "flip_and_burn" and (self.target is None) == (self.point is None):
            raise ValueError("Autopilot flip_and_burn needs exactly one of target (an entity) or point (x, y, z), "
                             f"got target={validate.shown(self.target)}, point={validate.shown(self.point)}")
        self.dv = validate.scalar("Autopilot.dv", self.dv, nonnegative=True)
        if self.mode == "burn" and not self.dv > 0:
            raise ValueError(f"Autopilot burn needs dv > 0 m/s, got {validate.shown(self.dv)}")
        self.at = validate.scalar("Autopilot.at", self.at)
        self.aim = validate.scalar("Autopilot.aim", self.aim, positive=True, hi=math.pi)
        self.max_rate = validate.scalar("Autopilot.max_rate", self.max_rate, positive=True)
        self.tolerance = validate.scalar("Autopilot.tolerance", self.tolerance, positive=True)
        self.standoff = validate.scalar("Autopilot.standoff", self.standoff, nonnegative=True)


@dataclass
class FlightPlan:
    """A script for the autopilot: at each time (s, simulated) engage the given :class:`Autopilot`
    settings (the autopilot system copies them onto the ship's Autopilot when the time comes).
    ``legs``: ``[(time, Autopilot(...)), ...]`` in increasing time."""

    legs: list = field(default_factory=list)
    #: Written by the system: how many legs have been engaged.
    next: int = field(default=0, compare=False)

    def __post_init__(self):
        last = -math.inf
        legs = []
        for k, leg in enumerate(self.legs):
            if not (isinstance(leg, (tuple, list)) and len(leg) == 2 and isinstance(leg[1], Autopilot)):
                raise TypeError(f"FlightPlan.legs[{k}] must be (time, Autopilot(...)), got {validate.shown(leg)}")
            t = validate.scalar(f"FlightPlan.legs[{k}] time", leg[0], nonnegative=True)
            if t < last:
                raise ValueError(f"FlightPlan.legs[{k}] time {validate.shown(t)} "
                                 f"is before the leg before it ({validate.shown(last)})")
            last = t
            legs.append((t, leg[1]))
        self.legs = legs
