"""rotation — the ship turns only while a key is held and thrusts along its nose (Framework 0.0.2)."""
from driftframe.demos.parts import balls, chase_camera, ship
from driftframe.framework.input import Hold, Track

TITLE = "Rotation"
DESCRIPTION = "direct control: the ship turns only while a key is held; velocity persists"
SEEDED = False     # build() draws nothing from rng: every seed gives the same scene (the CLI says so)
SECONDS = 12.0
SKY = "lines"      # the articles' green line cube: its grid shows every turn of the ship

# yaw right, burn, pitch up while drifting, burn again, roll, brake by thrusting backwards
SCRIPT = Track((
    Hold(0.5, 1.8, yaw=1.0),
    Hold(2.0, 4.0, throttle=1.0),
    Hold(4.5, 5.5, pitch=-1.0),
    Hold(6.0, 7.5, throttle=1.0),
    Hold(8.0, 9.5, roll=1.0),
    Hold(10.0, 11.5, throttle=-1.0),
))


def build(world, rng):
    me = ship(world, mode="direct", collides=False)
    chase_camera(world, me, mode="chase", chase_distance=9.0, chase_height=2.5)
    # a lattice of beacons 40 m apart all round the flight (about 100 m), so turning and drifting
    # always show against something
    grid = [(x, y, z) for x in range(-120, 121, 40) for y in range(-80, 81, 40) for z in range(-120, 121, 40)
            if (x, y, z) != (0, 0, 0)]
    balls(world, grid, [(0, 0, 0)] * len(grid), 1.5, mass=float("inf"), colour=(0.9, 0.55, 0.2))
