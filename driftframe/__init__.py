"""driftframe: an entity-component-system framework for Newtonian space-flight games and simulations.

One import package. Its layers, from the ground up (no layer imports one above it)::

    driftframe.framework    the core: world and schedule, fixed-step loop, columnar storage,
                            frame math, GL context, meshes and model cache, broad phase, recorder
    driftframe.components   plain data: Transform, Velocity, AngularVelocity, Mass, SphereCollider, ...
    driftframe.systems      esper processors, one job each
    driftframe.demos        one scene per module
    driftframe.app / cli / window / batch
                            the application shell: assembling a scene, the command line, play

``import driftframe`` gives the public API below.
"""
from driftframe.framework import __version__
from driftframe.framework.loop import FixedStepLoop
from driftframe.framework.input import Hold, Press, Track
from driftframe.framework.world import World
from driftframe.components.body import Acceleration, AngularVelocity, Mass, Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.components.control import FlightControl, FlightInput, Player, RotationAssist
from driftframe.components.gravity import GravityWell, NBody, SurfaceContact
from driftframe.components.render import ModelRef
from driftframe.systems.assist import RotationAssistSystem
from driftframe.systems.camera import CameraSystem
from driftframe.systems.collision import CollisionSystem
from driftframe.systems.control import ControlSystem
from driftframe.systems.gravity import GravitySystem
from driftframe.systems.input import InputSystem
from driftframe.systems.movement import MovementSystem
from driftframe.systems.spin import SpinSystem

__all__ = [
    "__version__", "World", "FixedStepLoop", "Hold", "Press", "Track",
    "Transform", "Velocity", "AngularVelocity", "Acceleration", "Mass", "SphereCollider", "CollisionEvent",
    "Camera", "ModelRef", "Player", "FlightInput", "FlightControl", "RotationAssist",
    "InputSystem", "ControlSystem", "RotationAssistSystem", "MovementSystem", "SpinSystem",
    "CollisionSystem", "CameraSystem", "GravityWell", "NBody", "SurfaceContact", "GravitySystem",
]
