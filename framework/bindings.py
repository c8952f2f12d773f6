"""Bindings: which key fires which action, and how a gamepad's axes and buttons fly the ship.

The defaults are :data:`framework.input.KEYMAP` and :data:`DEFAULT_AXES` /
:data:`DEFAULT_BUTTONS`; ``driftframe keys`` prints them as a TOML file that
``driftframe play --bindings FILE`` reads back (any table or entry left out
keeps its default)::

    version = 1

    [keys]                        # action = [GLFW key names, without GLFW_KEY_]
    thrust_forward = ["W", "UP"]

    [gamepad]
    dead_zone = 0.15              # |axis| below this reads 0
    curve = 2.0                   # response exponent: 1 linear, 2 finer near the centre
    mappings = "gamecontrollerdb.txt"   # optional SDL mappings, relative to this file

    [gamepad.axes]                # axis = { channel, scale (sign and size), dead_zone, curve }
    LEFT_Y = { channel = "pitch", scale = -1.0 }

    [gamepad.buttons]             # button = action (held or pressed)
    A = "kill_rotation"

Gamepads come through GLFW's gamepad API (``glfwGetGamepadState``): every pad
that has an SDL_GameControllerDB mapping reads as the same layout, six axes
(sticks in [-1, 1], y down; triggers -1 released .. +1 pulled) and fifteen
buttons. :func:`gamepad_channels` maps one recorded state to the pilot's
channels; it is a pure function, tested on recorded states.
"""
from __future__ import annotations

import json
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from driftframe.framework.inputfile import InputFileError, read_text_capped
from driftframe.framework.input import ACTION_HELP, CHANNELS, HELD, KEYMAP, PRESSED

#: GLFW's gamepad axes, in the order of ``GLFWgamepadstate.axes``.
AXES = ("LEFT_X", "LEFT_Y", "RIGHT_X", "RIGHT_Y", "LEFT_TRIGGER", "RIGHT_TRIGGER")
#: Triggers rest at -1; they are read as 0 (released) .. 1 (pulled).
TRIGGERS = ("LEFT_TRIGGER", "RIGHT_TRIGGER")
#: GLFW's gamepad buttons, in the order of ``GLFWgamepadstate.buttons`` (Xbox names).
BUTTONS = ("A", "B", "X", "Y", "LEFT_BUMPER", "RIGHT_BUMPER", "BACK", "START", "GUIDE", "LEFT_THUMB",
           "RIGHT_THUMB", "DPAD_UP", "DPAD_RIGHT", "DPAD_DOWN", "DPAD_LEFT")

DEAD_ZONE = 0.15
CURVE = 2.0


@dataclass(frozen=True)
class AxisBinding:
    """One gamepad axis driving one channel: ``channel += scale * shape(axis)``."""

    channel: str
    scale: float = 1.0
    #: None: the [gamepad] table's dead_zone / curve.
    dead_zone: float | None = None
    curve: float | None = None


#: Stick forward (y = -1) is nose down, as in a flight simulator; stick right rolls right (roll -1);
#: the right stick yaws; the right trigger thrusts forward, the left one backward.
DEFAULT_AXES = {
    "LEFT_X": AxisBinding("roll", -1.0),
    "LEFT_Y": AxisBinding("pitch", -1.0),
    "RIGHT_X": AxisBinding("yaw", 1.0),
    "RIGHT_TRIGGER": AxisBinding("throttle", 1.0),
    "LEFT_TRIGGER": AxisBinding("throttle", -1.0),
}
DEFAULT_BUTTONS = {"A": "kill_rotation", "Y": "switch_camera", "START": "pause", "BACK": "overlay"}


@dataclass(frozen=True)
class Bindings:
    """Key and gamepad bindings (see the module docstring)."""

    keys: dict = field(default_factory=lambda: dict(KEYMAP))
    axes: dict = field(default_factory=lambda: dict(DEFAULT_AXES))
    buttons: dict = field(default_factory=lambda: dict(DEFAULT_BUTTONS))
    dead_zone: float = DEAD_ZONE
    curve: float = CURVE
    #: SDL_GameControllerDB text file to add to GLFW's mappings, or None.
    mappings: Path | None = None


def shape_axis(value: float, dead_zone: float, curve: float) -> float:
    """Dead zone, then response curve: ``sign(v) ((|v| - dz) / (1 - dz)) ** curve``, 0 inside the zone.

    Continuous at the edge of the dead zone (0 there) and at full deflection
    (1 there), so the stick's whole travel is used.
    """
    v = max(-1.0, min(1.0, float(value)))
    a = abs(v)
    if a <= dead_zone:
        return 0.0
    return math.copysign(((a - dead_zone) / (1.0 - dead_zone)) ** curve, v)


def gamepad_channels(axes, bindings: Bindings | None = None) -> dict:
    """Channel -> value from one gamepad state's six ``axes`` (GLFW order); contributions add, then clamp.

    A trigger (resting at -1) is first read as ``(v + 1) / 2``. Only channels
    that some axis drives appear in the result.
    """
    b = bindings or Bindings()
    if len(axes) != len(AXES):
        raise ValueError(f"a gamepad state has {len(AXES)} axes ({', '.join(AXES)}), got {len(axes)}")
    out: dict[str, float] = {}
    for name, ab in b.axes.items():
        v = float(axes[AXES.index(name)])
        if name in TRIGGERS:
            v = (v + 1.0) * 0.5
        dz = b.dead_zone if ab.dead_zone is None else ab.dead_zone
        cv = b.curve if ab.curve is None else ab.curve
        out[ab.channel] = max(-1.0, min(1.0, out.get(ab.channel, 0.0) + ab.scale * shape_axis(v, dz, cv)))
    return out


def gamepad_actions(buttons, bindings: Bindings | None = None) -> set[str]:
    """The actions whose buttons are down in one gamepad state's fifteen ``buttons`` (GLFW order)."""
    b = bindings or Bindings()
    if len(buttons) != len(BUTTONS):
        raise ValueError(f"a gamepad state has {len(BUTTONS)} buttons, got {len(buttons)}")
    return {action for name, action in b.buttons.items() if buttons[BUTTONS.index(name)]}


# -- files ---------------------------------------------------------------------------------------
class BindingsError(ValueError):
    """A bindings file that cannot be used: the message names the file and the entry."""


def _key_names() -> set[str] | None:
    try:
        import glfw
    except ImportError:            # pragma: no cover - glfw is a dependency
        return None
    return {n[4:] for n in dir(glfw) if n.startswith("KEY_") and n != "KEY_UNKNOWN"}


#: Largest bindings file read: 1 MiB (the defaults, from ``driftframe keys``, are 1.6 KiB).
BINDINGS_CAP = 1 << 20
#: Largest gamepad mappings file read: 8 MiB (SDL_GameControllerDB's whole file is about 0.5 MiB).
MAPPINGS_CAP = 8 << 20


def _show(v) -> str:
    """A value as a message shows it: a huge integer by its digit count, anything long cut short."""
    if isinstance(v, int) and not isinstance(v, bool) and abs(v).bit_length() > 80:
        return f"an integer of about {int(abs(v).bit_length() * 0.30103) + 1} digits"
    text = repr(v)
    return text if len(text) <= 80 else text[:77] + "..."


def _number(where, v, lo, hi) -> float:
    ok = not isinstance(v, bool) and isinstance(v, (int, float))
    if ok:
        try:
            ok = math.isfinite(v) and lo <= v <= hi
        except OverflowError:                          # an int no float holds
            ok = False
    if not ok:
        raise BindingsError(f"{where} must be a number in [{lo}, {hi}], got {_show(v)}")
    return float(v)


def _table(where, v) -> dict:
    if not isinstance(v, dict):
        raise BindingsError(f"{where} must be a table, got {_show(v)}")
    return v


def load_bindings(path) -> Bindings:
    """Read a TOML bindings file over the defaults; a :class:`BindingsError` names the file and entry.

    The file is read through :func:`~framework.inputfile.read_text_capped`
    (at most :data:`BINDINGS_CAP`, a regular file, UTF-8).
    """
    path = Path(path)
    try:
        text = read_text_capped(path, BINDINGS_CAP, "bindings file")
        doc = tomllib.loads(text)
    except InputFileError as e:
        raise BindingsError(str(e)) from None
    except tomllib.TOMLDecodeError as e:
        raise BindingsError(f"{path}: not TOML: {e}") from None
    except ValueError:            # an integer past CPython's 4,300-digit conversion limit: tomllib names no line
        m = re.search(r"^[ \t]*([^=\n]+?)[ \t]*=[ \t]*[+-]?[\d_]{4300,}", text, re.M)
        where = f"{m.group(1)} (line {text.count(chr(10), 0, m.start()) + 1})" if m else "a number"
        raise BindingsError(f"{path}: {where}: an integer of over 4,300 digits is not a number in range") from None
    w = str(path)
    if doc.get("version", 1) != 1 or isinstance(doc.get("version"), bool):
        raise BindingsError(f"{w}: bindings version {_show(doc['version'])} is not supported "
                            "(this driftframe reads 1)")
    extra = set(doc) - {"version", "keys", "gamepad"}
    if extra:
        raise BindingsError(f"{w}: unknown table(s) {', '.join(sorted(map(repr, extra)))}; known: keys, gamepad")
    keys = dict(KEYMAP)
    names = _key_names()
    for action, ks in _table(f"{w}: keys", doc.get("keys", {})).items():
        if action not in KEYMAP:
            raise BindingsError(f"{w}: keys.{action}: unknown action; actions: {', '.join(KEYMAP)}"[:400])
        if isinstance(ks, str):
            ks = [ks]
        if not isinstance(ks, list) or not all(isinstance(k, str) for k in ks):
            raise BindingsError(f"{w}: keys.{action} must be a list of key names, got {_show(ks)}")
        ks = [k.upper() for k in ks]
        for k in ks:
            if names is not None and k not in names:
                raise BindingsError(f"{w}: keys.{action}: unknown key {k!r} (GLFW key names such as "
                                    "'W', 'SPACE', 'LEFT_SHIFT', 'F5', 'KP_8')")
        keys[action] = tuple(ks)
    seen: dict[str, str] = {}
    for action, ks in keys.items():
        for k in ks:
            if k in seen and seen[k] != action:
                raise BindingsError(f"{w}: key {k!r} is bound to both {seen[k]!r} and {action!r}")
            seen[k] = action
    pad = _table(f"{w}: gamepad", doc.get("gamepad", {}))
    extra = set(pad) - {"dead_zone", "curve", "mappings", "axes", "buttons"}
    if extra:
        raise BindingsError(f"{w}: gamepad: unknown key(s) {', '.join(sorted(map(repr, extra)))}")
    dz = _number(f"{w}: gamepad.dead_zone", pad.get("dead_zone", DEAD_ZONE), 0.0, 0.95)
    cv = _number(f"{w}: gamepad.curve", pad.get("curve", CURVE), 0.2, 5.0)
    mappings = None
    if "mappings" in pad:
        if not isinstance(pad["mappings"], str):
            raise BindingsError(f"{w}: gamepad.mappings must be a file name, got {_show(pad['mappings'])}")
        mappings = (path.parent / pad["mappings"]).resolve()
        if not mappings.is_file():
            raise BindingsError(f"{w}: gamepad.mappings: no such file {str(mappings)!r}")
    axes = dict(DEFAULT_AXES) if "axes" not in pad else {}
    for name, spec in _table(f"{w}: gamepad.axes", pad.get("axes", {})).items():
        at = f"{w}: gamepad.axes.{name}"
        if name not in AXES:
            raise BindingsError(f"{at}: unknown axis; axes: {', '.join(AXES)}")
        if not isinstance(spec, dict) or not isinstance(spec.get("channel"), str) \
                or spec.get("channel") not in CHANNELS:
            raise BindingsError(f"{at} must be {{ channel = one of {', '.join(CHANNELS)}, scale = ... }}, "
                                f"got {_show(spec)}")
        extra = set(spec) - {"channel", "scale", "dead_zone", "curve"}
        if extra:
            raise BindingsError(f"{at}: unknown key(s) {', '.join(sorted(map(repr, extra)))}")
        axes[name] = AxisBinding(
            spec["channel"], _number(f"{at}.scale", spec.get("scale", 1.0), -1.0, 1.0),
            None if "dead_zone" not in spec else _number(f"{at}.dead_zone", spec["dead_zone"], 0.0, 0.95),
            None if "curve" not in spec else _number(f"{at}.curve", spec["curve"], 0.2, 5.0))
    buttons = dict(DEFAULT_BUTTONS) if "buttons" not in pad else {}
    for name, action in _table(f"{w}: gamepad.buttons", pad.get("buttons", {})).items():
        if name not in BUTTONS:
            raise BindingsError(f"{w}: gamepad.buttons.{name}: unknown button; buttons: {', '.join(BUTTONS)}")
        if not isinstance(action, str):
            raise BindingsError(f"{w}: gamepad.buttons.{name} must be an action name, got {_show(action)}")
        if action not in HELD and action not in PRESSED:
            raise BindingsError(f"{w}: gamepad.buttons.{name}: unknown action {_show(action)}")
        buttons[name] = action
    return Bindings(keys, axes, buttons, dz, cv, mappings)


def _toml_str(s: str) -> str:
    """``s`` as a TOML basic string. JSON's escapes are TOML's (\\" \\\\ \\n \\uXXXX ...), except that TOML also
    wants DEL escaped; non-ASCII text stays as it is (JSON's \\u surrogate pairs are not TOML)."""
    return json.dumps(s, ensure_ascii=False).replace("\x7f", "\\u007f")


def bindings_toml(b: Bindings | None = None) -> str:
    """The bindings as a TOML file that :func:`load_bindings` reads back (``driftframe keys``)."""
    b = b or Bindings()
    out = ["# driftframe bindings: save as a file and pass it to `driftframe play --bindings FILE`.",
           "# Any entry left out keeps its default.", "version = 1", "", "[keys]"]
    width = max(map(len, b.keys))
    values = {a: "[" + ", ".join(map(_toml_str, ks)) + "]" for a, ks in b.keys.items()}
    vwidth = max(map(len, values.values()))
    for action, v in values.items():
        out.append(f"{action:<{width}} = {v:<{vwidth}}   # {ACTION_HELP[action]}")
    out += ["", "[gamepad]", f"dead_zone = {b.dead_zone!r}   # |axis| below this reads 0",
            f"curve = {b.curve!r}       # response exponent: 1 linear, 2 finer near the centre"]
    if b.mappings is not None:
        out.append(f"mappings = {_toml_str(str(b.mappings))}")
    out += ["", "[gamepad.axes]   # sticks: -1 left/up .. +1 right/down; triggers: 0 released .. 1 pulled"]
    for name, ab in b.axes.items():
        extra = "".join(f", {k} = {getattr(ab, k)!r}" for k in ("dead_zone", "curve") if getattr(ab, k) is not None)
        out.append(f'{name} = {{ channel = {_toml_str(ab.channel)}, scale = {ab.scale!r}{extra} }}')
    out += ["", "[gamepad.buttons]"]
    for name, action in b.buttons.items():
        out.append(f"{name} = {_toml_str(action)}")
    return "\n".join(out) + "\n"
