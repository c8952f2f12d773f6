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

TYPE_CHECKING = False   # typing.TYPE_CHECKING's meaning without importing typing; type checkers take it as True
if TYPE_CHECKING:       # what a type checker sees; at run time __getattr__ below imports each name at its first use
    from driftframe.app import (attach_rendering, declare_model_file, declare_variant, load_scene, make_world,
                                simulation_systems)
    from driftframe.components.autopilot import Autopilot, FlightPlan
    from driftframe.components.body import Acceleration, AngularVelocity, Mass, Transform, Velocity
    from driftframe.components.camera import Camera
    from driftframe.components.collision import CollisionEvent, SphereCollider
    from driftframe.components.control import FlightControl, FlightInput, Player, RotationAssist
    from driftframe.components.gravity import GravityWell, NBody, Orbiting, SurfaceContact
    from driftframe.components.render import ModelRef
    from driftframe.framework.frame import look_rotation
    from driftframe.framework.input import Hold, Press, Track, load_track, save_track
    from driftframe.framework.loop import FixedStepLoop
    from driftframe.framework.placement import in_box, in_shell, place
    from driftframe.framework.recorder import record
    from driftframe.framework.orbit_state import OrbitState
    from driftframe.framework.save import SaveError
    from driftframe.framework.scene import SceneRecipe, Seed
    from driftframe.framework.warp import TimeWarp
    from driftframe.framework.world import World
    from driftframe.systems.assist import RotationAssistSystem
    from driftframe.systems.autopilot import AutopilotSystem
    from driftframe.systems.camera import CameraSystem
    from driftframe.systems.collision import CollisionSystem
    from driftframe.systems.control import ControlSystem
    from driftframe.systems.gravity import GravitySystem
    from driftframe.systems.input import InputSystem
    from driftframe.systems.movement import MovementSystem
    from driftframe.systems.readouts import closest_approach, orbit, predicted_orbit
    from driftframe.systems.spin import SpinSystem
    from driftframe.systems.warp import WarpGovernorSystem
    from driftframe.window import play

# PEP 562: each public name is imported at its first use, so ``import driftframe`` (and the command line's
# start) costs what it uses: a warm ``import driftframe`` took 0.45-0.6 s of CPU when it imported all of them
_HOMES = {
    "World": "framework.world", "FixedStepLoop": "framework.loop",
    "Hold": "framework.input", "Press": "framework.input", "Track": "framework.input",
    "Acceleration": "components.body", "AngularVelocity": "components.body", "Mass": "components.body",
    "Transform": "components.body", "Velocity": "components.body",
    "Camera": "components.camera", "CollisionEvent": "components.collision", "SphereCollider": "components.collision",
    "PlaneCollider": "components.collision", "BoxCollider": "components.collision",
    "FlightControl": "components.control", "FlightInput": "components.control", "Player": "components.control",
    "RotationAssist": "components.control",
    "GravityWell": "components.gravity", "NBody": "components.gravity", "SurfaceContact": "components.gravity",
    "ModelRef": "components.render",
    "RotationAssistSystem": "systems.assist", "CameraSystem": "systems.camera", "CollisionSystem": "systems.collision",
    "ControlSystem": "systems.control", "GravitySystem": "systems.gravity", "InputSystem": "systems.input",
    "MovementSystem": "systems.movement", "SpinSystem": "systems.spin",
    # the first program's names: one import (docs/GUIDE.md) instead of ten lines from nine modules
    "simulation_systems": "app", "attach_rendering": "app", "make_world": "app", "load_scene": "app",
    "declare_variant": "app", "declare_model_file": "app", "play": "window", "record": "framework.recorder",
    "look_rotation": "framework.frame", "save_track": "framework.input", "load_track": "framework.input",
    "Autopilot": "components.autopilot", "FlightPlan": "components.autopilot", "Orbiting": "components.gravity",
    "AutopilotSystem": "systems.autopilot", "WarpGovernorSystem": "systems.warp",
    "orbit": "systems.readouts", "closest_approach": "systems.readouts", "predicted_orbit": "systems.readouts",
    "place": "framework.placement", "in_shell": "framework.placement", "in_box": "framework.placement",
    "SaveError": "framework.save",
    # the framework's typed resources (docs/GUIDE.md, "Resources"): world.resource(Seed) and the like
    "Seed": "framework.scene", "SceneRecipe": "framework.scene", "TimeWarp": "framework.warp",
    "OrbitState": "framework.orbit_state",
}


def __getattr__(name: str) -> object:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'driftframe' has no attribute {name!r}")
    import importlib
    value = getattr(importlib.import_module(f"driftframe.{home}"), name)
    globals()[name] = value                    # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_HOMES))


__all__ = [
    "__version__", "World", "FixedStepLoop", "Hold", "Press", "Track",
    "Transform", "Velocity", "AngularVelocity", "Acceleration", "Mass", "SphereCollider", "CollisionEvent",
    "PlaneCollider", "BoxCollider", "Camera", "ModelRef", "Player", "FlightInput", "FlightControl", "RotationAssist",
    "InputSystem", "ControlSystem", "RotationAssistSystem", "MovementSystem", "SpinSystem",
    "CollisionSystem", "CameraSystem", "GravityWell", "NBody", "SurfaceContact", "GravitySystem",
    "simulation_systems", "attach_rendering", "make_world", "load_scene", "declare_variant", "declare_model_file",
    "play", "record", "look_rotation", "save_track", "load_track", "Autopilot", "FlightPlan", "Orbiting",
    "AutopilotSystem", "WarpGovernorSystem", "orbit", "closest_approach", "predicted_orbit",
    "place", "in_shell", "in_box", "SaveError", "Seed", "SceneRecipe", "TimeWarp", "OrbitState",
]
