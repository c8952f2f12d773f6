"""Fly a demo in a real window (glfw): keyboard in, fixed steps under a variable frame rate.

The window's frame rate only decides how often the scene is drawn: a
:class:`~framework.loop.FixedStepLoop` on the wall clock takes whole steps of
``world.dt``, so a slow frame runs more steps, never a longer one, and the
physics is the one a recording shows. Keys go through the same
:class:`~systems.input.InputSystem` a scripted track uses; held keys set the
pilot's intent, pressed keys fire once (see :data:`framework.input.KEYMAP`).
"""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from driftframe.framework.input import HELD, KEYMAP


class PlayError(Exception):
    """Playing is impossible here (no display, no window): a one-line message."""


def _glfw():
    try:
        import glfw
    except ImportError as e:  # pragma: no cover - glfw is a dependency
        raise PlayError(f"the glfw package is missing ({e}); reinstall driftframe") from None
    return glfw


def open_window(glfw, size, title):
    """A visible window with a current OpenGL 3.3 core context; PlayError when there is no display."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise PlayError("no display: `driftframe play` needs a window (set DISPLAY, e.g. run under Xvfb), "
                        "or record the demo off-screen with `driftframe record`")
    errors = []
    glfw.set_error_callback(lambda code, msg: errors.append(msg.decode() if isinstance(msg, bytes) else str(msg)))
    if not glfw.init():
        raise PlayError(f"could not open the display {os.environ.get('DISPLAY', '')!r}: "
                        f"{errors[-1] if errors else 'GLFW failed to initialise'}")
    glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
    glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
    glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
    glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
    win = glfw.create_window(size[0], size[1], title, None, None)
    if not win:
        glfw.terminate()
        raise PlayError(f"could not create an OpenGL 3.3 window: {errors[-1] if errors else 'unknown GLFW error'}")
    glfw.make_context_current(win)
    glfw.swap_interval(1)
    return win


def key_table(glfw) -> dict[int, str]:
    """GLFW key code -> action name, from :data:`KEYMAP`."""
    table = {}
    for action, keys in KEYMAP.items():
        for k in keys:
            table[getattr(glfw, f"KEY_{k}")] = action
    return table


def state_summary(world) -> dict:
    """The player's state and the camera mode, as plain JSON-able values."""
    import esper

    from driftframe.components.body import AngularVelocity, Transform, Velocity
    from driftframe.app import player
    from driftframe.systems.camera import active_camera

    world.activate()
    out = {"steps": world.step_count, "time": world.time}
    try:
        out["camera"] = active_camera(world)[1].mode
    except LookupError:
        out["camera"] = None
    me = player(world)
    if me is not None:
        tf = esper.component_for_entity(me, Transform)
        out["player"] = {
            "position": tf.position.tolist(), "forward": tf.forward.tolist(),
            "velocity": esper.component_for_entity(me, Velocity).linear.tolist(),
            "angular": esper.component_for_entity(me, AngularVelocity).angular.tolist(),
        }
    return out


def play(name: str, *, size=(1280, 720), seed: int = 0, camera: str | None = None,
         state_out: str | None = None, screenshot_dir: str = ".", sky: str = "lines") -> int:
    """Open a window and fly demo ``name`` until Esc or the window is closed. Returns an exit code."""
    from driftframe.app import attach_rendering, make_world
    from driftframe.framework.gl import RenderTarget, wrap_current_context
    from driftframe.framework.loop import FixedStepLoop
    from driftframe.systems.camera import switch_camera
    from driftframe.systems.input import InputSystem

    glfw = _glfw()
    from driftframe import demos
    demo = demos.load(name)
    win = open_window(glfw, size, f"driftframe - {demo.TITLE}")
    world = None
    shots: list[str] = []
    try:
        ctx = wrap_current_context()
        world, demo = make_world(name, seed=seed, scripted=False)
        fb = glfw.get_framebuffer_size(win)
        target = RenderTarget.screen(ctx, fb)
        render = attach_rendering(world, ctx, target=target, camera=camera, sky=sky)
        inputs = world.get_system(InputSystem)
        loop = FixedStepLoop(world, time.perf_counter)
        keys = key_table(glfw)
        pending = {"screenshot": False}

        def on_key(_win, key, _scancode, action, _mods):
            name_ = keys.get(key)
            if name_ is None:
                return
            if name_ in HELD:
                if action == glfw.PRESS:
                    inputs.held.add(name_)
                elif action == glfw.RELEASE:
                    inputs.held.discard(name_)
            elif action == glfw.PRESS:
                if name_ == "quit":
                    glfw.set_window_should_close(win, True)
                elif name_ == "pause":
                    loop.paused = not loop.paused
                elif name_ == "screenshot":
                    pending["screenshot"] = True
                elif loop.paused:          # switch_camera while paused: at once
                    switch_camera(world)
                else:                      # otherwise at the next fixed step
                    inputs.press(name_)

        def on_resize(_win, w, h):
            if w > 0 and h > 0:
                target.size = (w, h)

        glfw.set_key_callback(win, on_key)
        glfw.set_framebuffer_size_callback(win, on_resize)
        print(f"playing {name}: Esc quits, P pauses, C switches camera (driftframe play --help lists the keys)",
              file=sys.stderr)
        while not glfw.window_should_close(win):
            glfw.poll_events()
            loop.tick()
            world.render()
            if pending["screenshot"]:
                pending["screenshot"] = False
                shots.append(_screenshot(render, ctx, name, world.step_count, screenshot_dir))
            glfw.swap_buffers(win)
        if state_out:
            summary = state_summary(world)
            summary["screenshots"] = shots
            Path(state_out).write_text(json.dumps(summary, indent=2))
    finally:
        if world is not None:
            world.close()
        glfw.destroy_window(win)
        glfw.terminate()
    return 0


def _screenshot(render, ctx, name: str, step: int, folder: str) -> str:
    from PIL import Image

    rgba = render.read_rgba()
    _ = ctx.error          # reading the window's back buffer leaves a pending GL error on Mesa: clear it
    path = Path(folder) / f"driftframe-{name}-{step:06d}.png"
    Image.fromarray(np.ascontiguousarray(rgba[:, :, :3])).save(path)
    print(f"screenshot: {path}", file=sys.stderr)
    return str(path)
