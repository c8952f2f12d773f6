"""asteroids — the ship among fifty asteroids that share one sphere mesh (Framework 0.0.5)."""
from demos.parts import asteroid_field, chase_camera, ship
from framework.input import Hold, Press, Track

TITLE = "Asteroids"
DESCRIPTION = "fifty scaled asteroids, elastic collisions, skybox, chase and cockpit cameras"
SECONDS = 20.0

# fly out through the field, switch to the cockpit, turn, burn, back to the chase view, kill spin
SCRIPT = Track((
    Hold(0.5, 3.0, throttle=1.0),
    Hold(3.5, 4.3, yaw=0.8),
    Press(5.0, "switch_camera"),
    Hold(5.5, 6.5, pitch=-0.8),
    Hold(7.0, 9.0, throttle=1.0),
    Hold(9.5, 10.5, roll=1.0),
    Press(11.0, "switch_camera"),
    Hold(11.5, 13.5, kill_rotation=True),
    Hold(14.0, 16.0, throttle=1.0),
))


def build(world, rng):
    me = ship(world, mode="momentum")
    chase_camera(world, me, mode="chase")
    asteroid_field(world, rng, 50, inner=12.0, outer=70.0, radii=(0.6, 3.5), speed=1.5)
