"""Attaching rendering to a world: the model cache, the render target, the camera system, the render
system and a sky, in one call (:func:`attach`; :func:`driftframe.attach_rendering` adds the HUD, effects and
sound on top). Here, in the application shell, because it composes several systems: no system module
imports another."""
from __future__ import annotations

import esper

from driftframe.components.camera import Camera
from driftframe.framework.gl import ContextHandle, RenderTarget, create_context, current
from driftframe.framework.model_cache import ModelCache
from driftframe.framework.schedule import access
from driftframe.framework.scene import seed_of
from driftframe.systems import camera_rig
from driftframe.systems.camera import CameraSystem
from driftframe.systems.render import RenderSystem
from driftframe.systems.skybox import FACE_TEXELS, SkyboxSystem, StarfieldSystem, fitted_face_texels


SKIES = ("lines", "starfield")


def default_sky(scene) -> str:
    """A scene's sky when none is asked for: its module's ``SKY`` (the rotation demo keeps the
    articles' green lines, which show its turns), else the starfield."""
    sky = getattr(scene, "SKY", "starfield")
    if sky not in SKIES:
        raise ValueError(f"{getattr(scene, '__name__', scene)!s}.SKY must be one of {SKIES}, got {sky!r}")
    return sky


def drawn_before(world) -> tuple[type, ...]:
    """The classes of the world's render-stage systems that draw into the frame now (``RenderTarget`` in
    their ``writes``), in running order. A system that draws over all of them (effects, a HUD) is added
    with ``after=drawn_before(world)``: the order is said, not left to the adding order, and the schedule
    warns about two drawers nothing orders (their pixels overlap)."""
    return tuple(dict.fromkeys(type(s) for s in world.systems["render"] if RenderTarget in access(s, "writes")))


def _face_texels(target: RenderTarget) -> int:
    """The starfield's face size: fitted to a fixed frame and the scene's widest lens (a window may grow:
    the largest)."""
    tans = [cam.tan_half_fov for _, cam in esper.get_component(Camera)]
    if target.is_screen or not tans:
        return FACE_TEXELS
    return fitted_face_texels(target.size[1], max(tans))


def attach(world, ctx=None, size=(1280, 720), *, target: RenderTarget | None = None, skybox=True,
           own_context: bool | None = None, **options) -> RenderSystem:
    """Set up rendering for ``world`` in one call; returns the :class:`RenderSystem`.

    ``ctx``: a ``moderngl.Context`` (None: reuse the world's ``ContextHandle`` or
    create an off-screen one with :func:`framework.gl.create_context`).
    ``size``: (width, height) of a new off-screen target; ``target``: an
    existing :class:`RenderTarget` instead (a window: ``RenderTarget.screen``).
    ``skybox``: ``True`` or ``"lines"`` adds the green line-cube skybox,
    ``"starfield"`` the procedural starfield (its texture made from
    ``world.resources[Seed]``, 0 if unset), ``False`` none. ``own_context``: release the
    context with the world (default: only if created here). Other keyword
    arguments go to :class:`RenderSystem` (``lod``, ``cull``, ``instanced``,
    ``light_direction``, ...).

    Adds :class:`~systems.camera.CameraSystem` (if the world has none),
    :class:`RenderSystem` and :class:`~systems.skybox.SkyboxSystem`, places
    the cameras, and sets the typed resources ``world.resources[ModelCache]``,
    ``[RenderTarget]`` and ``[ContextHandle]``.
    """
    sky = "lines" if skybox is True else skybox
    if sky not in (False, None) + SKIES:
        raise ValueError(f"skybox must be one of {SKIES}, True or False, got {skybox!r}")
    if RenderTarget in world.resources:
        raise ValueError("rendering is attached to this world already")
    handle = world.resources.pop(ContextHandle, None)
    if ctx is None:
        if handle is not None:
            ctx = handle.ctx
        else:
            ctx = create_context()
            own_context = True if own_context is None else own_context
    if handle is None or handle.ctx is not ctx:
        handle = ContextHandle(ctx, owned=bool(own_context))
    with current(ctx):                           # (the objects are this context's, whichever was current)
        cache = world.resources.get(ModelCache)
        if cache is None:
            cache = ModelCache(ctx)
        if target is None:
            target = RenderTarget(ctx, size)
        # release order on world.close(): cache, target, then systems and (if owned) the context
        world.resources[ModelCache] = cache
        world.resources[RenderTarget] = target
        world.resources[ContextHandle] = handle
        if world.get_system(CameraSystem) is None:
            world.add_system(CameraSystem())
        # world.close() calls release() on every system (this one, the skybox, the HUD) before the resources
        render = world.add_system(RenderSystem(ctx, cache, target, **options))
        if sky == "lines":
            world.add_system(SkyboxSystem(ctx, cache, render))
        world.activate()
        if sky == "starfield":
            world.add_system(StarfieldSystem(ctx, render, seed=seed_of(world), size=_face_texels(target)))
        if any(True for _ in esper.get_component(Camera)):
            camera_rig.update_cameras(world, snap=True)
    return render
