"""spin — angular momentum: spin accumulates and persists; the assist takes it out (Framework 0.0.4)."""
from driftframe.demos.parts import balls, chase_camera, ship
from driftframe.framework.input import Hold, Track

TITLE = "Spin"
DESCRIPTION = "momentum control: spin accumulates and persists until the kill-rotation assist takes it out"
SEEDED = False     # build() draws nothing from rng: every seed gives the same scene (the CLI says so)
SECONDS = 14.0

SCRIPT = Track((
    Hold(0.5, 1.5, throttle=1.0),          # drift forward
    Hold(1.5, 2.5, roll=1.0),               # start a roll ...
    Hold(3.0, 3.6, yaw=1.0),                # ... add some yaw: the spin axis tilts
    Hold(7.0, 11.0, kill_rotation=True),    # assist on: spin decays at a bounded rate to exactly zero
    Hold(11.5, 12.5, throttle=1.0),
))


def build(world, rng):
    me = ship(world, mode="momentum", assist="all", collides=False)
    chase_camera(world, me, mode="chase", chase_distance=8.0, chase_height=2.0)
    grid = [(x, y, z) for x in (-30, 30) for y in (-15, 15) for z in (10, 45, 80)]
    balls(world, grid, [(0, 0, 0)] * len(grid), 1.2, mass=float("inf"), colour=(0.3, 0.6, 0.95))
