"""asteroids — the ship among fifty asteroids that share one sphere mesh (Framework 0.0.5)."""
from driftframe.demos.parts import asteroid_field, chase_camera, ship
from driftframe.framework.input import Hold, Press, Track

TITLE = "Asteroids"
DESCRIPTION = "fifty scaled asteroids, elastic collisions, skybox, chase and cockpit cameras"
SECONDS = 20.0

# Into the field in the chase view; a 90-degree yaw (spin up, coast, counter-spin) while the ship
# keeps drifting the old way; switch to the cockpit and burn along the new nose (the prograde
# marker swings over); pitch up; back to the chase view; a roll that the kill-rotation assist
# takes out; a last turn and burn.
SCRIPT = Track((
    Hold(0.5, 1.1, throttle=1.0),
    Hold(2.0, 2.5, yaw=1.0), Hold(4.1, 4.6, yaw=-1.0),
    Press(5.0, "switch_camera"),
    Hold(5.5, 6.0, throttle=1.0),
    Hold(7.0, 7.5, pitch=-1.0), Hold(8.5, 9.0, pitch=1.0),
    Press(10.0, "switch_camera"),
    Hold(10.5, 11.2, roll=1.0),
    Hold(11.5, 13.5, kill_rotation=True),
    Hold(14.0, 14.5, yaw=-1.0), Hold(16.1, 16.6, yaw=1.0),
    Hold(17.0, 17.6, throttle=1.0),
))


def build(world, rng):
    me = ship(world, mode="momentum")
    chase_camera(world, me, mode="chase")
    asteroid_field(world, rng, 50, inner=12.0, outer=70.0, radii=(0.6, 3.5), speed=1.5)
