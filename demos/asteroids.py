"""asteroids — the ship flies into a cluster of fifty asteroids, scaled variants of four rock meshes (Framework 0.0.5)."""
import dataclasses

import esper
import numpy as np

from driftframe.components.camera import Camera
from driftframe.components.collision import SphereCollider

from driftframe.demos.parts import asteroid_field, balls, chase_camera, ship
from driftframe.framework.input import Hold, Press, Track
from driftframe.framework.model_cache import declare_variant

TITLE = "Asteroids"
DESCRIPTION = "fifty scaled rocks, elastic collisions, a starfield, chase and cockpit cameras"
SECONDS = 20.0
FIELD = (0.0, 0.0, 70.0)      # centre of the cluster, m: straight ahead of the ship
PEBBLE = (0.0, 0.0, 36.0)     # a small rock on the ship's path, m
DENSITY = 2000.0              # rock, kg/m^3

# A burn towards the cluster (collisions in it are in view from the start); a 90-degree yaw while
# drifting: the chase camera keeps looking where the ship goes, the ship turns side-on; yaw back;
# the cockpit view along the nose as the ship knocks the pebble into the cluster; back to the chase
# view; a roll that the kill-rotation assist takes out; a pitch and a last burn.
SCRIPT = Track((
    Hold(0.5, 1.2, throttle=1.0),
    Hold(1.5, 2.0, yaw=1.0), Hold(3.6, 4.1, yaw=-1.0),
    Hold(5.5, 6.0, yaw=-1.0), Hold(7.6, 8.1, yaw=1.0),
    Press(8.3, "switch_camera"),
    Press(11.0, "switch_camera"),
    Hold(11.5, 12.2, roll=1.0),
    Hold(12.5, 14.5, kill_rotation=True),
    Hold(15.0, 15.5, pitch=-1.0), Hold(15.9, 16.4, pitch=1.0),
    Hold(17.0, 17.6, throttle=1.0),
))


def build(world, rng):
    me = ship(world, mode="momentum")
    # a 45-degree lens (70 across at 16:9): rocks near the edges keep their shape in the cockpit view
    cam = chase_camera(world, me, mode="chase", fov=45.0, overhead_height=40.0)
    # 1.8 t against the ship's 10 t: the ship slows from 4.2 to 2.9 m/s, the pebble leaves at 7.1 m/s
    balls(world, [PEBBLE], [(0.0, 0.0, 0.0)], 0.6, mass=DENSITY * 4 / 3 * np.pi * 0.6 ** 3, colour=(0.7, 0.62, 0.5))
    # the pebble looks like a rock too; its ModelRef keeps its name, so the state hash is unchanged
    declare_variant(world, "sphere_r0.6", "rock2", scale=0.6)
    # dense enough (50 rocks in 30 m) for a collision every second or two, all in front of the ship
    rocks = asteroid_field(world, rng, 50, inner=0.0, outer=30.0, radii=(0.6, 3.5), speed=1.5, centre=FIELD,
                           density=DENSITY, keep_clear=[(PEBBLE, 3.0), ((0.0, 0.0, 0.0), 12.0)])
    # from overhead (--camera overhead) the eye stands over the ship and the field together, as high as it
    # must to see every rock (the camera is made first, so the bodies' entity ids stay as they were)
    radii = world.columns(SphereCollider, rocks).radius
    view = esper.component_for_entity(cam, Camera)
    world.add_component(cam, dataclasses.replace(view, frame=tuple(zip(rocks, radii.tolist()))))
