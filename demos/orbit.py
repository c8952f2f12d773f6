"""orbit — a ship in low orbit, a planet with a moon, a station higher up: transfer and rendezvous."""
import math

from driftframe.components.autopilot import Autopilot, FlightPlan
from driftframe.components.body import Transform, Velocity
from driftframe.components.gravity import GravityWell
from driftframe.components.render import ModelRef
from driftframe.demos.parts import chase_camera, ship
from driftframe.framework.input import Press, Track
from driftframe.framework.model_cache import declare_variant

TITLE = "Orbit"
DESCRIPTION = "Hohmann transfer to a station and a rendezvous, flown by the autopilot, with time warp"
SEEDED = False     # build() draws nothing from rng: every seed gives the same scene (the CLI says so)
SECONDS = 80.0

# A game-sized planet (1 km, low orbit 100 m up: 58 m/s, 2 minutes a lap), a moon, a station at 1.6 km.
MU, R, R1, R2 = 3.75e6, 1000.0, 1100.0, 1600.0
V1, V2 = math.sqrt(MU / R1), math.sqrt(MU / R2)
DV1 = V1 * (math.sqrt(2 * R2 / (R1 + R2)) - 1)              # Hohmann, closed form
DV2 = V2 * (1 - math.sqrt(2 * R1 / (R1 + R2)))
T_TRANSFER = math.pi * math.sqrt(((R1 + R2) / 2) ** 3 / MU)
BURN1 = 12.0
BURN2 = BURN1 + T_TRANSFER
# how far the station must lead at the first burn to be 60 m ahead of the ship at apoapsis
LEAD = math.pi - T_TRANSFER * V2 / R2 + 60.0 / R2

# Point prograde; warp x10 for the coast (the governor drops it before the second burn and says so);
# circularise, back to x1, match the station's velocity, then flip and burn to stop 30 m short of it.
SCRIPT = Track((Press(BURN1 + 4.0, "warp_up"), Press(BURN2 + 2.0, "warp_down"), Press(BURN2 + 16.0, "switch_camera")))


def _at(radius, angle, speed):
    """Position and velocity on a circle in the x-z plane, anticlockwise seen from +y."""
    c, s = math.cos(angle), math.sin(angle)
    return (radius * c, 0.0, -radius * s), (-speed * s, 0.0, -speed * c)


def build(world, rng):
    planet = world.create_entity(Transform(), GravityWell(mu=MU, radius=R),
                                 ModelRef(declare_variant(world, "planet", "sphere", scale=R, colour=(0.3, 0.5, 0.8))))
    x, v = _at(5000.0, 2.0, math.sqrt(MU / 5000.0))
    world.create_entity(Transform(x), Velocity(v), GravityWell(mu=1e5, radius=150.0, parent=planet),
                        ModelRef(declare_variant(world, "moon", "sphere", scale=150.0, colour=(0.6, 0.6, 0.55))))
    phase = -BURN1 * V2 / R2 + (BURN1 * V1 / R1 + LEAD)      # so the station leads by LEAD at BURN1
    x, v = _at(R2, phase, V2)
    station = world.create_entity(Transform(x), Velocity(v),
                                  ModelRef(declare_variant(world, "station", "sphere", scale=8.0, colour=(0.9, 0.8, 0.3))))
    x, v = _at(R1, 0.0, V1)
    me = ship(world, position=x, velocity=v, forward=v, thrust=2.0, collides=False)
    world.add_component(me, Autopilot(mode="prograde"))
    world.add_component(me, FlightPlan([
        (BURN1 - 8.0, Autopilot(mode="burn", dv=DV1, along="prograde", at=BURN1, target=station)),
        (BURN2 - 20.0, Autopilot(mode="burn", dv=DV2, along="prograde", at=BURN2, target=station)),
        (BURN2 + 5.0, Autopilot(mode="match_velocity", target=station, tolerance=0.02)),
        (BURN2 + 15.0, Autopilot(mode="flip_and_burn", target=station, standoff=30.0, tolerance=0.02)),
    ]))
    # the planet, the ship and the station in one picture, from above and behind the ship's travel;
    # the script's switch then goes to the cockpit for the approach (then the chase view)
    chase_camera(world, me, mode="frame", frame=((planet, R), (station, 8.0)),
                 cycle=("frame", "cockpit", "chase"), far=20_000.0, chase_distance=60.0, chase_height=25.0)
