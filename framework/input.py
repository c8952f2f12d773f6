"""Input mapping: keys -> actions -> the pilot's intent, for a keyboard or a script.

Actions are named once here. *Held* actions set a :class:`FlightInput`
channel while held; *pressed* actions fire once (switch camera, pause, ...).
The window layer translates physical keys to action names with
:data:`KEYMAP`; recordings replay a :class:`Track` of the same actions, so a
scripted flight and a flown one go through the same code.

Sign conventions follow ``framework.frame``: positive pitch is nose *down*
(right-hand rule about right), positive yaw turns the nose towards right,
positive roll lifts the right wing. So "pitch up" is ``pitch = -1``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from driftframe.framework import validate

#: The proportional channels of a pilot's intent (``FlightInput``), each in [-1, 1].
CHANNELS = ("throttle", "roll", "pitch", "yaw")

#: Held actions: (FlightInput field, value while held).
HELD = {
    "thrust_forward": ("throttle", +1.0),
    "thrust_back": ("throttle", -1.0),
    "pitch_up": ("pitch", -1.0),
    "pitch_down": ("pitch", +1.0),
    "yaw_left": ("yaw", -1.0),
    "yaw_right": ("yaw", +1.0),
    "roll_left": ("roll", +1.0),
    "roll_right": ("roll", -1.0),
    "kill_rotation": ("kill_rotation", True),
}
#: Pressed actions, fired once per press.
PRESSED = ("switch_camera", "pause", "screenshot", "quit")

#: Default keyboard layout: action -> key names (GLFW key names without the GLFW_KEY_ prefix).
KEYMAP = {
    "thrust_forward": ("W",),
    "thrust_back": ("S",),
    "pitch_up": ("DOWN",),
    "pitch_down": ("UP",),
    "yaw_left": ("A", "LEFT"),
    "yaw_right": ("D", "RIGHT"),
    "roll_left": ("Q",),
    "roll_right": ("E",),
    "kill_rotation": ("X",),
    "switch_camera": ("C",),
    "pause": ("P",),
    "screenshot": ("F12",),
    "quit": ("ESCAPE",),
}


def keys_help() -> str:
    """The key table as text, for ``--help`` and the README."""
    names = {
        "thrust_forward": "thrust forward", "thrust_back": "thrust backward",
        "pitch_up": "pitch up (nose up)", "pitch_down": "pitch down", "yaw_left": "yaw left",
        "yaw_right": "yaw right", "roll_left": "roll left", "roll_right": "roll right",
        "kill_rotation": "kill rotation (hold)", "switch_camera": "switch cockpit / chase camera",
        "pause": "pause / resume", "screenshot": "screenshot (PNG)", "quit": "quit",
    }
    width = max(len(" / ".join(k)) for k in KEYMAP.values())
    return "\n".join(f"  {' / '.join(keys):<{width}}  {names[a]}" for a, keys in KEYMAP.items())


def _blank() -> dict:
    return {**dict.fromkeys(CHANNELS, 0.0), "kill_rotation": False}


def _clamp(x: float) -> float:
    return max(-1.0, min(1.0, x))


def intent_from_held(held) -> dict:
    """FlightInput field values for a set of held action names (opposite keys cancel)."""
    out = _blank()
    for action in held:
        if action not in HELD:
            raise ValueError(f"unknown held action {action!r}; known: {', '.join(HELD)}")
        name, value = HELD[action]
        if name == "kill_rotation":
            out[name] = True
        else:
            out[name] = _clamp(out[name] + value)
    return out


def step_index(t: float, dt: float) -> int:
    """The first step whose start time ``k * dt`` reaches ``t`` (with a hair of tolerance).

    Every track time becomes a step index once, here: ``1.5 s`` at 1/100 s is
    step 150 however ``150 * 0.01`` rounds, so a hold covers the same steps at
    any dt, and a press fires exactly once.
    """
    return max(0, math.ceil(t / dt - 1e-9))


@dataclass(frozen=True, init=False)
class Hold:
    """From ``start`` to ``end`` seconds (simulated time), hold a pilot's input.

    ``Hold(2.0, 3.5, throttle=1.0, yaw=-0.5)``: the keyword arguments are the
    pilot's channels (:data:`CHANNELS`, each in [-1, 1]) and
    ``kill_rotation``. At time step ``dt`` the hold covers
    ``round((end - start) / dt)`` steps (at least one) from
    ``step_index(start)``: the same number of steps wherever it starts.
    """

    start: float
    end: float
    #: Channel values while held (only the given ones), e.g. ``{"throttle": 1.0}``.
    channels: dict
    kill_rotation: bool

    def __init__(self, start: float, end: float, *, kill_rotation: bool = False, **channels):
        s = validate.scalar("Hold.start", start, nonnegative=True)
        e = validate.scalar("Hold.end", end, nonnegative=True)
        if not e > s:
            raise ValueError(f"Hold.end must be after Hold.start, got start={s!r}, end={e!r}")
        for name, value in channels.items():
            if name not in CHANNELS:
                raise TypeError(f"Hold got an unknown channel {name!r}; channels: {', '.join(CHANNELS)}, "
                                "kill_rotation")
            channels[name] = validate.scalar(f"FlightInput.{name}", value, lo=-1.0, hi=1.0)
        object.__setattr__(self, "start", s)
        object.__setattr__(self, "end", e)
        object.__setattr__(self, "channels", dict(channels))
        object.__setattr__(self, "kill_rotation", bool(kill_rotation))

    def steps(self, dt: float) -> range:
        """The step indices this hold covers at time step ``dt``."""
        first = step_index(self.start, dt)
        return range(first, first + max(1, round((self.end - self.start) / dt)))


@dataclass(frozen=True)
class Press:
    """At ``time`` seconds (simulated), fire a pressed action once (e.g. ``"switch_camera"``)."""

    time: float
    action: str

    def __post_init__(self):
        validate.scalar("Press.time", self.time, nonnegative=True)
        if self.action not in PRESSED:
            raise ValueError(f"Press.action must be one of {PRESSED}, got {self.action!r}")


@dataclass(frozen=True)
class Track:
    """A scripted input track: holds (may overlap; values add, then clamp to [-1, 1]) and presses.

    Times are simulated seconds; the input system asks for a *step* index, so
    every time is quantised to steps once (:func:`step_index`).
    """

    events: tuple = field(default_factory=tuple)

    def __post_init__(self):
        for ev in self.events:
            if not isinstance(ev, (Hold, Press)):
                raise TypeError(f"Track events must be Hold or Press, got {ev!r}")

    def intent_at_step(self, step: int, dt: float) -> dict:
        """The pilot's intent in step ``step``: every hold with ``step`` in ``hold.steps(dt)``."""
        out = _blank()
        for ev in self.events:
            if isinstance(ev, Hold) and step in ev.steps(dt):
                for name, value in ev.channels.items():
                    out[name] = _clamp(out[name] + value)
                out["kill_rotation"] |= ev.kill_rotation
        return out

    def presses_at_step(self, step: int, dt: float) -> list[str]:
        """Pressed actions that fire in step ``step`` (the step :func:`step_index` gives the press time)."""
        hits = [ev for ev in self.events if isinstance(ev, Press) and step_index(ev.time, dt) == step]
        return [ev.action for ev in sorted(hits, key=lambda e: e.time)]

    @property
    def duration(self) -> float:
        ends = [ev.end if isinstance(ev, Hold) else ev.time for ev in self.events]
        return max(ends, default=0.0)
