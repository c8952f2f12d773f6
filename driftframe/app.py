"""Assembling a runnable scene: the standard systems, a demo's entities, rendering.

A demo only composes components (``demos/<name>.py``: ``build(world, rng)``
plus metadata). This module gives it a world with the standard systems in
their stages, and attaches rendering when a picture is wanted::

    world, demo = make_world("asteroids", seed=1)      # headless: physics only
    render = attach_rendering(world, size=(1280, 720)) # off-screen EGL, or a window's context

Models: a demo declares asteroid variants with
:func:`driftframe.framework.model_cache.declare_variant`
(no GL needed), and :func:`attach_rendering` puts them into the model cache,
where each is an entry sharing the base mesh's buffers plus a scale.
"""
from __future__ import annotations

import numpy as np

from driftframe.framework import validate
from driftframe.framework.model_cache import declare_model_file as declare_model_file  # re-exported (PEP 484 form)
from driftframe.framework.model_cache import ModelCache, ModelFiles, ModelVariants
from driftframe.framework.scene import SceneRecipe, Seed
from driftframe.framework.model_cache import declare_variant as declare_variant
from driftframe.framework.world import World

TYPE_CHECKING = False                # typing's constant without importing typing (this module starts the CLI)
if TYPE_CHECKING:
    from types import ModuleType
    from typing import Any

    import esper
    import moderngl

    from driftframe.framework.input import Track
    from driftframe.systems.render import RenderSystem


def simulation_systems(track: Track | None = None, *, collision: str = "continuous") -> list[esper.Processor]:
    """The standard per-step systems, one per job, for every stage up to collision."""
    from driftframe.systems.assist import RotationAssistSystem
    from driftframe.systems.autopilot import AutopilotSystem
    from driftframe.systems.collision import CollisionSystem
    from driftframe.systems.control import ControlSystem
    from driftframe.systems.gravity import GravitySystem
    from driftframe.systems.input import InputSystem
    from driftframe.systems.movement import MovementSystem
    from driftframe.systems.spin import SpinSystem
    from driftframe.systems.warp import WarpGovernorSystem

    # movement predicts every body's end of step; gravity (its Orbiting bodies) and collision (the colliders
    # a contact touched) correct it; the world's commit stage writes it (framework/step.py); without a
    # GravityWell gravity is one empty query per step; the autopilot flies through FlightInput (before
    # control); the warp governor looks ahead after the commit
    return [InputSystem(track), AutopilotSystem(), ControlSystem(), RotationAssistSystem(), GravitySystem(),
            MovementSystem(), SpinSystem(), CollisionSystem(method=collision), WarpGovernorSystem()]


class SceneError(ValueError):
    """A ``module:function`` scene that cannot be used: it does not import, is no function, or raised."""


class Scene:
    """A user's scene function ``build(world, rng)`` seen as a demo: what play, record and batch need.

    Its module may set ``TITLE``, ``SECONDS`` (default recording length,
    10 s), ``DT`` (the fixed step, 1/60 s) and ``SCRIPT`` (an input
    :class:`~framework.input.Track` that ``record`` flies); a demo module
    has the same names.
    """

    def __init__(self, path: str, func):
        module = __import__("sys").modules.get(getattr(func, "__module__", ""), None)
        self.NAME = path
        self.TITLE = getattr(module, "TITLE", path)
        self.DESCRIPTION = (func.__doc__ or "").strip().split("\n")[0] or path
        self.SECONDS = float(getattr(module, "SECONDS", 10.0))
        self.DT = float(getattr(module, "DT", 1.0 / 60.0))
        self.SCRIPT = getattr(module, "SCRIPT", None)
        self.SEEDED = getattr(module, "SEEDED", True)
        self.function = func

    def build(self, world, rng) -> None:
        try:
            self.function(world, rng)
        except Exception as e:     # noqa: BLE001 - the user's code: one line naming the scene, the error, where
            raise SceneError(f"scene {self.NAME!r} raised {type(e).__name__}: {e}{_where(e)}") from e


def _where(e: BaseException) -> str:
    """`` (at mygame/scene.py:12)``: the innermost frame of the traceback outside driftframe, if any."""
    import os
    import traceback

    frames = traceback.extract_tb(e.__traceback__)
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    own = [f for f in frames if not os.path.abspath(f.filename).startswith(here + os.sep)] or frames
    if not own:
        return ""
    f = own[-1]
    name = os.path.relpath(f.filename) if not os.path.relpath(f.filename).startswith("..") else f.filename
    return f" (at {name}:{f.lineno})"


def is_scene_path(name) -> bool:
    """True for ``"module:function"`` (a user's scene), False for a demo name."""
    return isinstance(name, str) and ":" in name


def load_scene(name: str) -> ModuleType | Scene:
    """Demo ``name``, or the user's scene ``"package.module:function"`` as a :class:`Scene`.

    A scene is imported as ``driftframe batch`` imports one
    (:mod:`driftframe.batch_spec`); a module that does not import (whatever it
    raised), a name that is missing or not callable is a :class:`SceneError`
    saying which, in one line.
    """
    if not is_scene_path(name):
        from driftframe import demos
        try:
            return demos.load(name)
        except LookupError as e:
            raise LookupError(f"{e}; or your own scene as module:function (e.g. mygame.scene:build)") from None
    from driftframe.batch_spec import _scene_function
    try:
        func = _scene_function(name, SceneError)
    except SceneError:
        raise
    except Exception as e:         # noqa: BLE001 - a module that raised while importing (SyntaxError, NameError)
        mod = name.split(":")[0]
        raise SceneError(f"scene {name!r}: importing module {mod!r} raised {type(e).__name__}: {e}"
                         f"{_where(e)}") from None
    return Scene(name, func)


def make_world(name: str, *, seed: int = 0, scripted: bool = True, collision: str = "continuous",
               track: Track | None = None) -> tuple[World, ModuleType | Scene]:
    """A world with the standard systems and demo ``name``'s entities; returns ``(world, demo)``.

    ``name``: a demo (``driftframe list``) or a scene of your own,
    ``"package.module:function"`` (:func:`load_scene`). ``scripted``: drive
    the player with the demo's input track (recordings, tests); False leaves
    input to the keyboard. ``track``: a :class:`~framework.input.Track` to fly
    instead of the demo's (a saved flight).
    """
    demo = load_scene(name)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an int >= 0, got {validate.shown(seed)}")
    world = World(dt=getattr(demo, "DT", 1.0 / 60.0))
    try:
        script = track if track is not None else (demo.SCRIPT if scripted else None)
        for system in simulation_systems(script, collision=collision):
            world.add_system(system)
        demo.build(world, np.random.default_rng(int(seed)))
    except BaseException:
        world.close()
        raise
    world.resources[Seed] = Seed(int(seed))     # later generation steps (the starfield's texture) derive from it
    # how to build it again: a save names it, and World.load calls the builder (framework/save.py)
    world.resources[SceneRecipe] = SceneRecipe(name, int(seed), bool(scripted), collision, track is not None,
                                               f"{__name__}:make_world", demo)
    return world, demo


def load_kernels(name: str, *, seed: int = 0) -> None:
    """Load (or, on a machine's first run, compile) the numba kernels demo ``name`` steps with.

    A scratch world of the demo is built, stepped once and closed: numba
    compiles a kernel at its first call, so on an empty cache the first step
    takes tens of seconds. ``driftframe play`` and ``record`` call this before
    they open the window or start the progress bar, so that wait comes first
    (the command line says why) instead of a frozen window or a bar stuck at
    frame 0. With the kernels cached it costs what the first step would pay
    anyway (the cache load), plus the scratch world (docs/design/costs.md).

    Nothing is done for a demo when ``driftframe warm`` finished in the kernel cache folder
    (:func:`framework.kernels.is_warm`): it ran every demo, so each kernel a demo steps with loads from the
    cache at its first call, and the scene is built once. A scene of your own may bring kernels of its own:
    its scratch world is always built, so that a compile shows its progress before the window or the bar.
    """
    from driftframe.framework import kernels
    if not is_scene_path(name) and kernels.is_warm():
        return
    world, _ = make_world(name, seed=seed)
    try:
        world.step()
    finally:
        world.close()


def attach_rendering(world: World, ctx: moderngl.Context | None = None, size: tuple[int, int] | str = (1280, 720), *,
                     camera: str | None = None, hud: bool = True, sky: str | bool | None = None,
                     sound: bool = True, effects: bool = True, **options: Any) -> RenderSystem:
    """Attach rendering (model cache, cameras, skybox, render system, HUD) to a built world.

    ``camera``: start in ``"cockpit"``, ``"chase"`` or ``"overhead"`` (default: as the demo
    built it). ``sky``: ``"starfield"`` (a star cube map made from the world's seed),
    ``"lines"`` (the articles' green line cube), False for none, or None (the default):
    the demo's ``SKY``, else the starfield. ``sound``: add the sound cues of impacts and thrust
    (:mod:`systems.sound`: an MP4 recording gets a sound track, ``play`` plays them). ``effects``: sparks
    and a flash at every contact, the engine's plume (:mod:`systems.effects`). Returns the
    :class:`~systems.render.RenderSystem`.
    """
    from driftframe.systems import camera as camera_sys
    from driftframe.rendering import attach, default_sky, drawn_before

    if sky is None:
        recipe = world.resources.get(SceneRecipe)
        sky = default_sky(recipe.scene if recipe is not None else None)

    size = parse_size(size) if isinstance(size, str) else size
    from driftframe.framework.gl import current

    render = attach(world, ctx, size, skybox=sky, **options)
    cache = world.resource(ModelCache)
    with current(render.ctx):                      # (the meshes and the HUD's objects are this context's)
        for mname, (path, colour, shading) in world.resources.get(ModelFiles, {}).items():
            if mname not in cache:          # before the variants, which may scale them
                cache.load(mname, path, shading=shading, **({} if colour is None else {"colour": colour}))
        for vname, (base, scale, colour) in world.resources.get(ModelVariants, {}).items():
            if vname not in cache:
                cache.variant(vname, base, scale=scale, colour=colour)
        if effects:
            from driftframe.systems.effects import EffectsSystem
            world.add_system(EffectsSystem(render), after=drawn_before(world))    # over the models and sky
        if hud:
            from driftframe.systems.hud import HudSystem
            world.add_system(HudSystem(render), after=drawn_before(world))        # over everything
    if sound:
        from driftframe.systems.sound import attach as attach_sound
        attach_sound(world)
    if camera is not None:
        camera_sys.switch_camera(world, camera)
    return render


def parse_size(text: str) -> tuple[int, int]:
    """``"1280x720"`` -> (1280, 720); a clear error for anything else."""
    parts = str(text).lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise ValueError(f"size must look like WIDTHxHEIGHT (e.g. 1280x720), got {text!r}")
    w, h = (int(p) for p in parts)
    for label, v in (("width", w), ("height", h)):
        if not 16 <= v <= 7680:
            raise ValueError(f"size {label} must be between 16 and 7680 pixels, got {v} in {text!r}")
    if w % 2 or h % 2:
        raise ValueError(f"size must have even width and height (H.264 needs it), got {text!r}")
    return w, h


def player(world) -> int | None:
    """Entity id of the (lowest-numbered) Player, or None."""
    import esper

    from driftframe.components.control import Player

    world.activate()
    ents = sorted(e for e, _ in esper.get_component(Player))
    return ents[0] if ents else None
