"""Fly a demo in a real window (glfw): keyboard and gamepad in, fixed steps under a variable frame rate.

The window's frame rate only decides how often the scene is drawn: a
:class:`~framework.loop.FixedStepLoop` on the wall clock takes whole steps of
``world.dt``, so a slow frame runs more steps, never a longer one, and the
physics is the one a recording shows. Each frame draws the poses between the
last two steps by the loop's ``alpha`` (:mod:`systems.interpolation`), so any
display rate looks smooth; when a step costs more than ``dt`` the loop drops
time and the overlay says so.

Keys (and a gamepad's buttons and axes, :mod:`framework.bindings`) go
through the same :class:`~systems.input.InputSystem` a scripted track uses;
held keys set the pilot's intent, pressed keys fire once. Every step's intent
can be written down (``save_track``) and re-rendered by ``driftframe record
--track``; ``hash_log`` writes one state hash per step.

Window keys: F11 fullscreen, F3 the overlay (frame rate, each stage's time),
F12 a screenshot, F5 / F9 quick-save / quick-load, P pause, Esc quit. Resizing keeps the picture's aspect
ratio: the scene is drawn in the largest centred rectangle of the
``size``'s aspect (black bars around it).
"""
from __future__ import annotations

import io
import json
import os
import signal
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from driftframe.framework import validate
from driftframe.framework.gl import RenderTarget
from driftframe.framework.input import HELD
from driftframe.framework.scene import seed_of
from driftframe.framework.stop_signals import StopSignals
from driftframe.framework.stop_signals import signal_name as _signal_name

if TYPE_CHECKING:
    from driftframe.framework.bindings import Bindings
    from driftframe.framework.world import World


class PlayError(Exception):
    """Playing is impossible here (no display, no window): a one-line message."""


def _glfw():
    try:
        import glfw
    except ImportError as e:  # pragma: no cover - glfw is a dependency
        raise PlayError(f"the glfw package is missing ({e}); reinstall driftframe") from None
    return glfw


def check_display() -> None:
    """PlayError when no display is set (DISPLAY or WAYLAND_DISPLAY): cheap, so callers check first."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise PlayError("no display: `driftframe play` needs a window (set DISPLAY, e.g. run under Xvfb), "
                        "or record the demo off-screen with `driftframe record`")


def open_window(glfw, size, title):
    """A visible window with a current OpenGL 3.3 core context; PlayError when there is no display."""
    check_display()
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


def key_table(glfw, keymap) -> dict[int, str]:
    """GLFW key code -> action name, from a keymap (action -> key names)."""
    table = {}
    for action, keys in keymap.items():
        for k in keys:
            table[getattr(glfw, f"KEY_{k}")] = action
    return table


def letterbox(window_size, aspect: float) -> tuple[int, int, int, int]:
    """``(x, y, w, h)``: the largest rectangle of ``aspect`` (w / h) centred in ``window_size``, pixels.

    Bars go left and right when the window is wider than ``aspect``, above and
    below when it is taller; the picture is never stretched.
    """
    W, H = int(window_size[0]), int(window_size[1])
    if W < 1 or H < 1:
        raise ValueError(f"window size must be positive, got {validate.shown(window_size)}")
    if W / H > aspect:
        w, h = max(1, round(H * aspect)), H
    else:
        w, h = W, max(1, round(W / aspect))
    return (W - w) // 2, (H - h) // 2, w, h


class LetterboxTarget(RenderTarget):
    """A window's screen, drawn into a centred rectangle of a fixed aspect ratio.

    ``size`` is the picture's size (what the render system and HUD see),
    ``viewport`` its place in the window (GL's bottom-left origin).
    """

    @classmethod
    def for_window(cls, ctx, window_size, aspect: float) -> "LetterboxTarget":
        self = cls.screen(ctx, window_size)
        self.aspect_lock = float(aspect)
        self.window_size = tuple(window_size)
        self.fit(window_size)
        return self

    def fit(self, window_size) -> None:
        x, y, w, h = letterbox(window_size, self.aspect_lock)
        self.window_size = (int(window_size[0]), int(window_size[1]))
        self.offset = (x, y)
        self.size = (w, h)

    @property
    def viewport(self) -> tuple[int, int, int, int]:
        return (*self.offset, *self.size)


class Gamepads:
    """The first connected gamepad, read through GLFW's gamepad API (SDL_GameControllerDB mappings)."""

    def __init__(self, glfw, mappings: Path | None = None):
        self.glfw = glfw
        text = os.environ.get("SDL_GAMECONTROLLERCONFIG", "")
        if mappings is not None:
            from driftframe.framework.bindings import MAPPINGS_CAP
            from driftframe.framework.inputfile import InputFileError, read_text_capped
            try:
                text = read_text_capped(mappings, MAPPINGS_CAP, "gamepad mappings file") + "\n" + text
            except InputFileError as e:
                raise PlayError(str(e)) from None
        if text.strip() and not glfw.update_gamepad_mappings(text):
            raise PlayError("the gamepad mappings (SDL_GAMECONTROLLERCONFIG or the bindings' gamepad.mappings) "
                            "could not be parsed")
        self.name: str | None = None

    def state(self):
        """``(axes, buttons)`` of the first gamepad (6 floats, 15 ints), or None when there is none."""
        glfw = self.glfw
        for jid in range(glfw.JOYSTICK_1, glfw.JOYSTICK_LAST + 1):
            if glfw.joystick_is_gamepad(jid):
                st = glfw.get_gamepad_state(jid)
                if st is None:
                    continue
                if self.name is None:
                    self.name = glfw.get_gamepad_name(jid) or f"gamepad {jid}"
                    print(f"gamepad: {self.name}", file=sys.stderr)
                return tuple(st.axes), tuple(st.buttons)
        return None


def state_summary(world) -> dict:
    """The player's state and the camera mode, as plain JSON-able values."""
    import esper

    from driftframe.app import player
    from driftframe.components.body import AngularVelocity, Transform, Velocity
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


def overlay_lines(stats, loop) -> list[str]:
    """The F3 overlay: frame rate, steps, what was dropped, and each stage's time."""
    out = [f"FPS     {stats.fps:6.1f}  (worst {stats.worst_ms:5.1f} ms)",
           f"STEP    {loop.step_cost * 1e3:6.2f} ms of {loop.world.dt * 1e3:.2f}  speed {loop.speed:4.2f}x",
           f"DROPPED {loop.dropped_steps} steps" + ("  (slow motion)" if loop.behind else "")]
    for stage, ms in stats.stage_ms.items():
        if ms > 0:
            out.append(f"  {stage:<9} {ms:6.2f} ms")
    return out


def play(name: str | World, *, size: tuple[int, int] = (1280, 720), seed: int = 0, camera: str | None = None,
         state_out: str | None = None, screenshot_dir: str = ".", bindings: Bindings | None = None,
         save_track: str | None = None, hash_log: str | None = None, frames: int | None = None,
         overlay: bool = False, interpolate: bool = True, loop_options: dict[str, Any] | None = None,
         setup: Callable[[World], object] | None = None, quiet: bool = False, sky: str | None = None,
         overwrite: bool = False, handle_signals: bool = True, sound: bool = True) -> int:
    """Open a window and fly ``name`` until Esc, the window is closed, or ``frames`` frames.

    ``name``: a demo (``"asteroids"``), your scene as ``"module:function"``
    (built here with the standard systems and ``seed``), or a
    :class:`~framework.world.World` you built yourself (``df.play(world)``:
    its own systems, with an :class:`~systems.input.InputSystem` added if it
    has none; rendering is attached here, and the world is closed at the end).

    Returns the exit status: 0; 128 + the signal's number when Ctrl-C,
    SIGTERM or SIGHUP ended the flight (``handle_signals``, main thread
    only); 1 when an output could not be written. However the flight ends
    (a signal, an exception, the X server gone: exit status 1 from inside
    Xlib), the track and the hash log are written, complete up to the last
    whole step, and stderr says where. Outputs follow
    :mod:`framework.output` (an existing file is refused unless ``overwrite``).

    ``sky``: ``"starfield"`` or ``"lines"``; None: the demo's (see :func:`driftframe.app.attach_rendering`).
    ``sound``: play the impacts and the engine (:mod:`driftframe.speaker`; no output device: one
    line on stderr, and the flight goes on silently); False: muted.
    ``bindings``: a :class:`~framework.bindings.Bindings` (default: the
    defaults). ``save_track``: on quit, write the flight as a track file.
    ``hash_log``: one ``STEP HASH`` line per step. ``frames``: quit after so
    many frames (benchmarks, tests). ``overlay``: start with the F3 overlay
    shown. ``interpolate``: draw poses between steps (False: the state after
    the last step). ``loop_options``: keyword arguments for
    :class:`~framework.loop.FixedStepLoop`. ``setup(world)``: called once the
    world is built (a benchmark adds a load there). The last line on stderr
    is a summary of the frame rate; the figures are also in ``play.last_run``.
    """
    from driftframe.framework.bindings import Bindings

    from driftframe.app import load_scene
    from driftframe.framework.world import World
    from driftframe.rendering import default_sky

    bindings = bindings or Bindings()
    if isinstance(name, World):
        if name.closed:
            raise ValueError("play: the world is closed")
        if RenderTarget in name.resources:
            raise ValueError("play: the world has rendering attached already; play attaches its own "
                             "(call play(world) on a world without attach_rendering)")
        demo = _OwnWorld(name)
        sky = default_sky(None) if sky is None else sky
        info = dict(seed=seed_of(name, seed), camera=camera, sky=str(sky))
    else:
        if not isinstance(name, str):
            raise TypeError(f"play: give a demo name, 'module:function' or a World, got {type(name).__name__}")
        demo = load_scene(name)
        sky = default_sky(demo) if sky is None else sky
        info = dict(demo=name, seed=int(seed), camera=camera, sky=str(sky))
    glfw = _glfw()
    flight = _Flight(save_track, overwrite, info)
    with StopSignals(handle_signals) as stop:
        stopped = _play(glfw, demo, flight, stop, name=name, size=size, seed=seed, camera=camera,
                        state_out=state_out, screenshot_dir=screenshot_dir, bindings=bindings,
                        save_track=save_track, hash_log=hash_log, frames=frames, overlay=overlay,
                        interpolate=interpolate, loop_options=loop_options, setup=setup, quiet=quiet, sky=sky,
                        overwrite=overwrite, sound=sound)
    if flight.errors:
        for line in flight.errors:
            print(f"driftframe: error: {line}", file=sys.stderr)
    if stopped is not None:
        return 128 + stopped
    return 1 if flight.errors else 0


class _OwnWorld:
    """A world the caller built, standing where a demo module would (``play(world)``)."""

    NAME = "world"
    TITLE = "your world"

    def __init__(self, world):
        self.world = world


class _Flight:
    """What ``play`` keeps however it ends: the track and the hash log, complete to the last whole step."""

    def __init__(self, save_track, overwrite, info):
        self.save_track = save_track
        self.overwrite = overwrite
        self.info = info
        self.recorder = None
        self.log = None
        self.world = None
        self.kept = False
        #: "the track flight.json (912 steps)", ... once kept.
        self.notes: list[str] = []
        #: Outputs that could not be written, in words (each names its file).
        self.errors: list[str] = []

    def keep(self) -> list[str]:
        """Write the track and finish the hash log (once); never raises for a failed write."""
        if self.kept:
            return self.notes
        self.kept = True
        from driftframe.framework.input import save_track as write_track
        if self.recorder is not None:
            if self.world is not None:               # a step cut short by an exception is not flown
                self.recorder.truncate(self.world.step_count)
            try:
                write_track(self.recorder.to_track(**self.info), self.save_track, overwrite=self.overwrite)
                self.notes.append(f"the track {self.save_track} ({self.recorder.steps} steps)")
            except (OSError, ValueError) as e:
                self.errors.append(f"the track {self.save_track!r} was not written: {e}")
        if self.log is not None:
            self.log.release()
            if self.log.error is not None:
                self.errors.append(str(self.log.error))
            else:
                self.notes.append(f"the hash log {self.log.path} ({self.log.lines} steps)")
        return self.notes

    def where(self) -> str:
        return f"wrote {' and '.join(self.notes)}" if self.notes else "nothing to write"


def _on_lost_display(glfw, flight):
    """Keep the flight when the X server goes away; returns a function that removes the handler.

    Xlib's default handler for a lost connection prints ``XIO: fatal IO
    error`` and calls ``exit()`` from inside whatever GLFW call noticed it,
    so no Python code runs after it. This handler, called from inside that
    GLFW call (between two frames, so every step is whole), writes the track
    and the hash log and ends the process with status 1; it cannot return,
    as Xlib would then exit anyway.
    """
    platform = getattr(glfw, "get_platform", lambda: None)()
    if not os.environ.get("DISPLAY") or platform not in (None, getattr(glfw, "PLATFORM_X11", None)):
        return lambda: None
    import ctypes
    try:
        x11 = ctypes.CDLL("libX11.so.6")          # the copy GLFW loaded (one per process)
    except OSError:
        return lambda: None
    display = os.environ.get("DISPLAY")

    def handler(_conn):
        try:
            flight.keep()
            print(f"driftframe: error: lost the display {display!r} (the X server closed the connection); "
                  f"{flight.where()}", file=sys.stderr)
            for line in flight.errors:
                print(f"driftframe: error: {line}", file=sys.stderr)
            sys.stderr.flush()
        finally:
            os._exit(1)
        return 0

    callback = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)(handler)
    x11.XSetIOErrorHandler.restype = ctypes.c_void_p
    x11.XSetIOErrorHandler.argtypes = [ctypes.c_void_p]
    old = x11.XSetIOErrorHandler(ctypes.cast(callback, ctypes.c_void_p))

    def restore():
        x11.XSetIOErrorHandler(old)
        restore.callback = None                   # (kept alive until here: Xlib holds a pointer to it)
    restore.callback = callback
    return restore


def _play(glfw, demo, flight, stop, *, name, size, seed, camera, state_out, screenshot_dir, bindings, save_track,
          hash_log, frames, overlay, interpolate, loop_options, setup, quiet, sky, overwrite, sound):
    """:func:`play`'s body, under its signal handlers; returns the signal that stopped it, or None."""
    from driftframe.app import attach_rendering, make_world
    from driftframe.framework.audio import RATE
    from driftframe.framework.gl import wrap_current_context
    from driftframe.framework.hashlog import attach_hash_log
    from driftframe.framework.input import TrackRecorder
    from driftframe.framework.loop import FixedStepLoop, FrameStats
    from driftframe.framework.output import write_file
    from driftframe.systems.hud import HudSystem
    from driftframe.systems.input import InputSystem
    from driftframe.systems.interpolation import attach_interpolation

    label = demo.NAME if isinstance(demo, _OwnWorld) else name
    win = open_window(glfw, size, f"driftframe - {demo.TITLE}")
    restore_x = _on_lost_display(glfw, flight)
    world = None
    speaker = None
    stopped = None
    shots: list[str] = []
    try:
        pads = Gamepads(glfw, bindings.mappings)
        ctx = wrap_current_context()
        if isinstance(demo, _OwnWorld):
            world = demo.world
            if world.get_system(InputSystem) is None:     # the keys reach the pilot through it
                world.add_system(InputSystem())
        else:
            world, demo = make_world(name, seed=seed, scripted=False)
        target = LetterboxTarget.for_window(ctx, glfw.get_framebuffer_size(win), size[0] / size[1])
        render = attach_rendering(world, ctx, target=target, camera=camera, sky=sky, sound=False)
        soundtrack = None
        if sound:
            from driftframe.speaker import open_speaker
            from driftframe.systems.sound import attach as attach_sound
            speaker = open_speaker(quiet=quiet)
            if speaker is not None:             # (no device: no cues either)
                soundtrack = attach_sound(world)
        hud = world.get_system(HudSystem)
        inputs = world.get_system(InputSystem)
        interp = attach_interpolation(world, render) if interpolate else None
        recorder = None
        flight.world = world
        if save_track:
            recorder = flight.recorder = inputs.recorder = TrackRecorder(world.dt)
        if hash_log:
            flight.log = attach_hash_log(world, hash_log, overwrite=overwrite)
        if setup is not None:
            setup(world)
        loop = FixedStepLoop(world, time.perf_counter, **(loop_options or {}))
        ui = {"screenshot": False, "overlay": bool(overlay), "fullscreen": False, "windowed": None,
              "told_behind": False}
        controls = _Controls(glfw, win, world, loop, inputs, bindings, pads, ui, target, recorder=recorder,
                             interp=interp, slot=os.path.join(screenshot_dir, f"{label.replace(':', '-')}-quicksave.npz"),
                             writing_down=bool(save_track or hash_log))
        glfw.set_key_callback(win, controls.on_key)
        glfw.set_framebuffer_size_callback(win, controls.on_resize)
        if not quiet:
            print(f"playing {label}: Esc quits, P pauses, C switches camera, F11 fullscreen, F3 overlay "
                  "(`driftframe keys` lists them all)", file=sys.stderr)
        stats = FrameStats()
        frame_times = []
        t_prev = t_start = time.perf_counter()
        cpu_start = time.process_time()
        try:
            while not glfw.window_should_close(win) and stop.requested is None:
                glfw.poll_events()
                controls.poll_gamepad()
                inputs.held = controls.key_held | controls.pad_held
                if loop.tick() and controls.release_later:
                    controls.key_held.difference_update(controls.release_later)
                    controls.release_later.clear()
                if loop.behind and not ui["told_behind"]:
                    ui["told_behind"] = True
                    n = loop.step_limit
                    print(f"driftframe: the simulation cannot keep real time here (a step takes "
                          f"{loop.step_cost * 1e3:.1f} ms of wall time for {world.dt * 1e3:.1f} ms simulated): "
                          f"dropping time to keep the frame rate, at most {n} step{'s' * (n > 1)} a frame "
                          "(F3 shows the speed)", file=sys.stderr)
                if interp is not None:
                    interp.alpha = loop.alpha
                if ui["overlay"]:
                    hud.overlay = overlay_lines(stats, loop)
                elif loop.behind:
                    hud.overlay = [f"SLOW MOTION {loop.speed:4.2f}x (a step takes {loop.step_cost * 1e3:.1f} ms)"]
                else:
                    hud.overlay = None
                world.render()
                if soundtrack is not None:          # the frame's sounds, as many samples as wall time has passed
                    due = round((time.perf_counter() - t_start) * RATE)
                    speaker.feed(soundtrack.take(due - soundtrack.samples, world.time))
                if ui["screenshot"]:
                    ui["screenshot"] = False
                    shots.append(_screenshot(render, label.replace(":", "-"), world.step_count, screenshot_dir))
                glfw.swap_buffers(win)
                now = time.perf_counter()
                stats.frame(now, world)
                frame_times.append(now - t_prev)
                t_prev = now
                if frames is not None and len(frame_times) >= frames:
                    break
        except KeyboardInterrupt as e:          # a second signal, in the middle of a frame: stop at once
            stopped = getattr(e, "signum", signal.SIGINT)
        if stopped is None:
            stopped = stop.requested
        stop.finish()                               # a second signal now must not cut the files being written
        wall = time.perf_counter() - t_start
        summary = _summary(frame_times, wall, world, loop)
        summary["cpu_ms"] = 1e3 * (time.process_time() - cpu_start) / max(1, len(frame_times))
        play.last_run = summary
        print(summary["line"], file=sys.stderr)
        flight.keep()
        if stopped is None:
            stopped = stop.requested                # it came while the flight was being written
        if stopped is None and save_track and flight.recorder is not None and not flight.errors:
            print(f"track: {save_track} ({recorder.steps} steps)", file=sys.stderr)
        if stopped is not None:
            print(f"driftframe: interrupted ({_signal_name(stopped)}) after {world.step_count} steps; "
                  f"{flight.where()}", file=sys.stderr)
        if state_out:
            out = state_summary(world)
            out.update(screenshots=shots, fullscreen=ui["fullscreen"], picture=list(target.size),
                       viewport=list(target.viewport), window=list(target.window_size),
                       overlay=hud.last.get("overlay"), frames=summary["frames"], fps=summary["fps"],
                       dropped_steps=loop.dropped_steps)
            try:
                write_file(state_out, json.dumps(out, indent=2), overwrite=overwrite, what="state")
            except OSError as e:
                flight.errors.append(f"the state {state_out!r} was not written: {e}")
    except BaseException as e:
        if not flight.kept:                         # whatever went wrong, the flight so far is kept
            stop.finish()
            flight.keep()
            why = f"interrupted ({_signal_name(e.signum)})" if isinstance(e, KeyboardInterrupt) and \
                hasattr(e, "signum") else "stopped by an error"
            if flight.notes:
                print(f"driftframe: {why} after {world.step_count if world else 0} steps; {flight.where()}",
                      file=sys.stderr)
        raise
    finally:
        if speaker is not None:
            speaker.close()
        if world is not None:
            world.close()
        glfw.destroy_window(win)
        glfw.terminate()
        restore_x()
    return stopped


play.last_run = None


class _Controls:
    """``play``'s keys and gamepads: held actions for the InputSystem, presses fired (pause, screenshot,
    overlay, fullscreen, quick save/load, a camera switch while paused), the window's resizes."""

    def __init__(self, glfw, win, world, loop, inputs, bindings, pads, ui, target, *, recorder, interp, slot,
                 writing_down):
        self.glfw, self.win, self.world, self.loop, self.inputs = glfw, win, world, loop, inputs
        self.bindings, self.pads, self.ui, self.target = bindings, pads, ui, target
        self.recorder, self.interp, self.slot, self.writing_down = recorder, interp, slot, writing_down
        self.keys = key_table(glfw, bindings.keys)
        self.key_held: set[str] = set()
        self.pressed_at: dict[str, int] = {}     # held action -> world.step_count when its key went down
        self.release_later: set[str] = set()     # tapped between two steps: released after the next step
        self.pad_held: set[str] = set()
        self.pad_down: set[str] = set()

    def fire(self, action):
        from driftframe.systems.camera import switch_camera

        glfw, loop, ui, world = self.glfw, self.loop, self.ui, self.world
        if action == "quit":
            glfw.set_window_should_close(self.win, True)
        elif action == "pause":
            loop.paused = not loop.paused
        elif action == "screenshot":
            ui["screenshot"] = True
        elif action == "overlay":
            ui["overlay"] = not ui["overlay"]
        elif action == "fullscreen":
            self.toggle_fullscreen()
        elif action in ("quick_save", "quick_load"):   # between two steps (keys are polled between ticks)
            self.quick(action)
        elif loop.paused and action == "switch_camera":   # while paused: at once, written down for the replay
            switch_camera(world)
            if self.recorder is not None:
                self.recorder.press(world.step_count, action)
            if self.interp is not None:
                self.interp.snapshot.take()      # no blending across the jump
        else:                      # otherwise at the next fixed step
            self.inputs.press(action)

    def quick(self, action):
        """F5: the world into the slot (replacing the last); F9: the slot into the world. A quick-load
        would rewind a flight being written down, so it is refused then (one line says why)."""
        from driftframe.framework.inputfile import InputFileError
        from driftframe.framework.save import SaveError
        world, slot = self.world, self.slot
        try:
            if action == "quick_save":
                world.save(slot, overwrite=True)
                print(f"quick-save: {slot} (step {world.step_count})", file=sys.stderr)
            elif self.writing_down:
                print("quick-load is off while --save-track or --hash-log writes the flight down",
                      file=sys.stderr)
            else:
                world.restore(slot)
                if self.interp is not None:
                    self.interp.snapshot.take()        # no blending across the jump
                print(f"quick-load: {slot} (step {world.step_count})", file=sys.stderr)
        except (SaveError, InputFileError, OSError) as e:
            print(f"driftframe: {action.replace('_', '-')}: {e}", file=sys.stderr)

    def toggle_fullscreen(self):
        glfw, win, ui = self.glfw, self.win, self.ui
        if glfw.get_window_monitor(win):
            x, y, w, h = ui["windowed"]
            glfw.set_window_monitor(win, None, x, y, w, h, 0)
            ui["fullscreen"] = False
        else:
            ui["windowed"] = (*glfw.get_window_pos(win), *glfw.get_window_size(win))
            mon = glfw.get_primary_monitor()
            mode = glfw.get_video_mode(mon)
            glfw.set_window_monitor(win, mon, 0, 0, mode.size.width, mode.size.height, mode.refresh_rate)
            ui["fullscreen"] = True

    def on_key(self, _win, key, _scancode, action, _mods):
        name_ = self.keys.get(key)
        if name_ is None:
            return
        if name_ in HELD:
            if action == self.glfw.PRESS:
                self.key_held.add(name_)
                self.release_later.discard(name_)
                self.pressed_at[name_] = self.world.step_count
            elif action == self.glfw.RELEASE:
                if self.pressed_at.get(name_) == self.world.step_count and not self.loop.paused:
                    self.release_later.add(name_)      # a tap shorter than a step still acts for one step
                else:
                    self.key_held.discard(name_)
        elif action == self.glfw.PRESS:
            self.fire(name_)

    def on_resize(self, _win, w, h):
        if w > 0 and h > 0:           # 0 x 0 while minimised: keep the last picture size
            self.target.fit((w, h))

    def poll_gamepad(self):
        from driftframe.framework.bindings import gamepad_actions, gamepad_channels

        st = self.pads.state()
        if st is None:
            self.inputs.axes = {}
            self.pad_held.clear()
            return
        axes, buttons = st
        self.inputs.axes = gamepad_channels(axes, self.bindings)
        down = gamepad_actions(buttons, self.bindings)
        self.pad_held.clear()
        self.pad_held.update(a for a in down if a in HELD)
        for a in sorted(down - self.pad_down - set(HELD)):
            self.fire(a)
        self.pad_down.clear()
        self.pad_down.update(down)


def _summary(frame_times, wall, world, loop) -> dict:
    """Frame-rate figures of a session (the first frame, with the start-up, left out)."""
    ft = frame_times[1:] or frame_times
    med = statistics.median(ft) if ft else float("nan")
    worst = max(ft) if ft else float("nan")
    fps = len(ft) / sum(ft) if ft and sum(ft) > 0 else 0.0
    out = {"frames": len(frame_times), "seconds": wall, "fps": fps, "median_ms": med * 1e3,
           "worst_ms": worst * 1e3, "steps": world.step_count, "dropped_steps": loop.dropped_steps,
           "speed": world.time / wall if wall > 0 else 0.0}
    out["line"] = (f"played {out['frames']} frames in {wall:.1f} s: {fps:.1f} fps (median frame "
                   f"{out['median_ms']:.1f} ms, worst {out['worst_ms']:.1f} ms); {out['steps']} steps, "
                   f"{out['dropped_steps']} dropped, simulation at {out['speed']:.2f}x real time")
    return out


def _screenshot(render, name: str, step: int, folder: str) -> str:
    from PIL import Image

    from driftframe.framework.output import OutputExistsError, write_file

    rgba = render.read_rgba()          # RenderTarget clears the window's pending read error itself
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgba[:, :, :3])).save(buf, format="PNG")
    # through framework.output: whole files only, never over an existing one (a second F12 in the same
    # step, or an earlier session's picture, gets the next free name)
    for k in range(1, 1000):
        path = Path(folder) / f"driftframe-{name}-{step:06d}{'' if k == 1 else f'-{k}'}.png"
        try:
            write_file(path, buf.getvalue(), what="screenshot")
            break
        except OutputExistsError:
            continue
    print(f"screenshot: {path}", file=sys.stderr)
    return str(path)
