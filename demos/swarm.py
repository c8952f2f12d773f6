"""swarm — thousands of colliding asteroids around the ship: the scale the framework holds."""
import dataclasses

import esper

from driftframe.components.camera import Camera
from driftframe.components.collision import SphereCollider
from driftframe.demos.parts import asteroid_field, chase_camera, ship
from driftframe.framework.input import Hold, Press, Track

TITLE = "Swarm"
DESCRIPTION = "3,000 colliding asteroids (four rock meshes, level of detail and culling) around the ship"
SECONDS = 12.0
COUNT = 3000

SCRIPT = Track((
    Hold(0.5, 3.0, throttle=1.0),
    Hold(3.0, 3.5, yaw=1.0), Hold(4.5, 5.0, yaw=-1.0),     # a 65-degree turn: spin up, coast, counter-spin
    Press(6.0, "switch_camera"),
    Hold(6.5, 9.0, throttle=1.0),
))


def build(world, rng):
    me = ship(world, mode="momentum")
    cam = chase_camera(world, me, mode="chase", fov=50.0, overhead_height=150.0)   # see asteroids.py
    rocks = asteroid_field(world, rng, COUNT, inner=10.0, outer=160.0, radii=(0.4, 2.5), speed=2.0)
    # from overhead (--camera overhead) the eye stands over the ship and the whole field, as asteroids.py's
    # does (the camera is made first, so the bodies' entity ids, and the physics, stay as they were)
    radii = world.columns(SphereCollider, rocks).radius
    view = esper.component_for_entity(cam, Camera)
    world.add_component(cam, dataclasses.replace(view, frame=tuple(zip(rocks, radii.tolist()))))
