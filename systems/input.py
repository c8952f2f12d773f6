"""Input: the keyboard's held keys and a gamepad's axes, or a scripted track, become the pilot's intent."""
from __future__ import annotations

import esper

from driftframe.components.body import Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.control import FlightInput, Player
from driftframe.framework import validate
from driftframe.framework import warp as time_warp
from driftframe.framework.input import CHANNELS, PRESSED, SIM_PRESSED, Track, TrackRecorder, intent_from_held


def _switch_camera(world) -> None:
    from driftframe.systems.camera_rig import switch_camera
    switch_camera(world)


def _warp_up(world) -> None:
    time_warp.of(world).up()


def _warp_down(world) -> None:
    time_warp.of(world).down()


class InputSystem(esper.Processor):
    """Reads a Track (or held keys and gamepad axes); writes FlightInput of Player entities; fires presses.

    * With a ``track`` (recordings, tests) the intent is ``track.intent_at_step(step, dt)``
      and presses fire in the step the track says — the same every run.
    * Without one (a window) the intent comes from ``held`` (action names the
      window keeps up to date) plus ``axes`` (channel -> value from a gamepad,
      see :func:`framework.bindings.gamepad_channels`), added and clamped to
      [-1, 1]; presses queued in ``pressed`` fire at the next step, so key
      timing is quantised to steps, never to frames.
    * ``recorder`` (a :class:`~framework.input.TrackRecorder`, or None) writes
      down the intent and the simulation's presses of every step: the flight,
      replayable as a track.

    Pressed actions go to ``handlers[action](world)``; ``switch_camera`` is
    handled by default, the window adds ``pause``, ``screenshot``, ``quit``.
    """

    stage = "input"
    reads = (Player, Velocity)
    # FlightInput of the Player; the handlers of pressed actions may write more (switch_camera:
    # the camera's mode and its eye's Transform, placed from the target's Velocity; warp_up/down: the TimeWarp)
    writes = (FlightInput, Camera, Transform, time_warp.TimeWarp)

    def __init__(self, track: Track | None = None):
        if track is not None and not isinstance(track, Track):
            raise TypeError(f"track must be a driftframe.Track, got {validate.shown(track)}")
        self.track = track
        self.held: set[str] = set()
        #: Proportional input from a gamepad, channel -> value in [-1, 1] (set by the window each frame).
        self.axes: dict[str, float] = {}
        self.pressed: list[str] = []
        self.handlers = {"switch_camera": _switch_camera, "warp_up": _warp_up, "warp_down": _warp_down}
        self.recorder: TrackRecorder | None = None

    # a track, a recorder or a press gives the system work without any entity changing: the world is told
    # (World.wake) to read `requires` again, so a system idle without them is not visited a step
    @property
    def track(self) -> Track | None:
        return self._track

    @track.setter
    def track(self, value: Track | None) -> None:
        self._track = value
        self._wake()

    @property
    def recorder(self) -> TrackRecorder | None:
        return self._recorder

    @recorder.setter
    def recorder(self, value: TrackRecorder | None) -> None:
        self._recorder = value
        self._wake()

    @property
    def requires(self) -> tuple[type, ...]:
        """Nothing to do without a pilot (FlightInput and Player), a track, a recorder or a press."""
        if self._track is not None or self._recorder is not None or self.pressed:
            return ()
        return (FlightInput, Player)

    def _wake(self) -> None:
        world = getattr(self, "world", None)
        if world is not None:
            world.wake()

    def press(self, action: str) -> None:
        """Queue a pressed action for the next step."""
        if action not in PRESSED:
            raise ValueError(f"unknown pressed action {action!r}; known: {', '.join(PRESSED)}")
        self.pressed.append(action)
        self._wake()

    def live_intent(self) -> dict:
        """The intent of the held keys plus the gamepad's axes (each channel added, then clamped)."""
        intent = intent_from_held(self.held)
        for name, value in self.axes.items():
            if name not in CHANNELS:
                raise ValueError(f"InputSystem.axes: unknown channel {name!r}; channels: {', '.join(CHANNELS)}")
            intent[name] = max(-1.0, min(1.0, intent[name] + float(value)))
        return intent

    def prepare(self) -> None:
        """esper's cached list of the pilots, which every step asks for (see :meth:`World.prepare`)."""
        esper.get_components(FlightInput, Player)

    def process(self, dt: float) -> None:
        if self.track is None and not self.pressed and self.recorder is None \
                and not esper.get_components(FlightInput, Player):
            return                                   # no pilot, nothing pressed, nothing to record
        world = self.world
        step = world.step_count
        if self.track is not None:
            intent = self.track.intent_at_step(step, dt)
            presses = self.track.presses_at_step(step, dt)
        else:
            intent = self.live_intent()
            presses = []
        presses += self.pressed
        self.pressed.clear()
        if self.recorder is not None:
            self.recorder.add(step, intent, [a for a in presses if a in SIM_PRESSED])
        for _, (inp, _) in esper.get_components(FlightInput, Player):
            for name, value in intent.items():       # already clamped to [-1, 1]
                setattr(inp, name, value)
        for action in presses:
            handler = self.handlers.get(action)
            if handler is not None:
                handler(world)
