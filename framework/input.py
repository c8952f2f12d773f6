"""Input mapping: keys -> actions -> the pilot's intent, for a keyboard or a script.

Actions are named once here. *Held* actions set a :class:`FlightInput`
channel while held; *pressed* actions fire once (switch camera, pause, ...).
The window layer translates physical keys (and gamepad axes, see
:mod:`framework.bindings`) to action names with :data:`KEYMAP`; recordings
replay a :class:`Track` of the same actions, so a scripted flight and a flown
one go through the same code. A flight flown in a window is written down by a
:class:`TrackRecorder` (one entry per run of identical steps) and saved with
:func:`save_track`; :func:`load_track` reads it back (the file format is
described there).

Sign conventions follow ``framework.frame``: positive pitch is nose *down*
(right-hand rule about right), positive yaw turns the nose towards right,
positive roll lifts the right wing. So "pitch up" is ``pitch = -1``.
"""
from __future__ import annotations

import bisect
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from driftframe.framework import validate
from driftframe.framework.inputfile import InputFileError, read_text_capped
from driftframe.framework.output import write_file

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
PRESSED = ("switch_camera", "pause", "screenshot", "quit", "fullscreen", "overlay", "warp_up", "warp_down",
           "quick_save", "quick_load")
#: Pressed actions that change the simulation (and so go into a saved track); the others act on the window.
#: (Warp changes only how many steps a frame shows, but a replayed track should warp where the flight did.)
SIM_PRESSED = ("switch_camera", "warp_up", "warp_down")

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
    "fullscreen": ("F11",),
    "overlay": ("F3",),
    "quit": ("ESCAPE",),
    "warp_up": ("PERIOD",),
    "warp_down": ("COMMA",),
    "quick_save": ("F5",),
    "quick_load": ("F9",),
}

#: What each action does, in words (``driftframe keys``, ``--help``, the README).
ACTION_HELP = {
    "thrust_forward": "thrust forward", "thrust_back": "thrust backward",
    "pitch_up": "pitch up (nose up)", "pitch_down": "pitch down", "yaw_left": "yaw left",
    "yaw_right": "yaw right", "roll_left": "roll left", "roll_right": "roll right",
    "kill_rotation": "kill rotation (hold)", "switch_camera": "switch cockpit / chase camera",
    "pause": "pause / resume", "screenshot": "screenshot (PNG)", "fullscreen": "fullscreen on / off",
    "overlay": "overlay: frame rate and the time of each stage", "quit": "quit",
    "warp_up": "time warp up (x10)", "warp_down": "time warp down (/10)",
    "quick_save": "quick-save the world (SCENE-quicksave.npz beside the screenshots)",
    "quick_load": "quick-load the last quick-save",
}


def keys_help(keymap: dict | None = None) -> str:
    """The key table as text (default :data:`KEYMAP`), for ``--help`` and the README."""
    keymap = KEYMAP if keymap is None else keymap
    width = max(len(" / ".join(k)) for k in keymap.values())
    return "\n".join(f"  {' / '.join(keys) or '-':<{width}}  {ACTION_HELP[a]}" for a, keys in keymap.items())


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

    def __init__(self, start: float, end: float, *, kill_rotation: bool = False, **channels: float) -> None:
        s = validate.scalar("Hold.start", start, nonnegative=True)
        e = validate.scalar("Hold.end", end, nonnegative=True)
        if not e > s:
            raise ValueError(f"Hold.end must be after Hold.start, got start={validate.shown(s)},"
                             f" end={validate.shown(e)}")
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
            raise ValueError(f"Press.action must be one of {PRESSED}, got {validate.shown(self.action)}")


class _Plan:
    """A track compiled for one ``dt``: the intent of every run of steps, found by bisection.

    Built once per ``dt`` by a sweep over the holds' step ranges, so a flown
    track of thousands of holds costs O(log n) per step, not O(n). Within a
    run the intent is computed exactly as :meth:`Track.intent_at_step`
    defines it (holds in track order, each added then clamped).
    """

    def __init__(self, events, dt):
        holds = [(ev.steps(dt), k, ev) for k, ev in enumerate(events) if isinstance(ev, Hold)]
        cuts = sorted({r.start for r, _, _ in holds} | {r.stop for r, _, _ in holds})
        starts = sorted(holds, key=lambda h: h[0].start)
        self.bounds: list[int] = []
        self.intents: list[dict] = []
        active: list = []
        j = 0
        for c in cuts:
            while j < len(starts) and starts[j][0].start <= c:
                active.append(starts[j])
                j += 1
            active = [h for h in active if h[0].stop > c]
            out = _blank()
            for _, _, ev in sorted(active, key=lambda h: h[1]):       # track order, as intent_at_step
                for name, value in ev.channels.items():
                    out[name] = _clamp(out[name] + value)
                out["kill_rotation"] |= ev.kill_rotation
            self.bounds.append(c)
            self.intents.append(out)
        self.presses: dict[int, list[str]] = {}
        hits = sorted((ev for ev in events if isinstance(ev, Press)), key=lambda e: e.time)
        for ev in hits:
            self.presses.setdefault(step_index(ev.time, dt), []).append(ev.action)

    def intent(self, step: int) -> dict:
        i = bisect.bisect_right(self.bounds, step) - 1
        return dict(self.intents[i]) if i >= 0 else _blank()


@dataclass(frozen=True)
class Track:
    """A scripted input track: holds (may overlap; values add, then clamp to [-1, 1]) and presses.

    Times are simulated seconds; the input system asks for a *step* index, so
    every time is quantised to steps once (:func:`step_index`). ``info``
    says where a saved track was flown (``demo``, ``seed``, ``camera``,
    ``dt``, ``steps``); it does not change what the track does.
    """

    events: tuple = field(default_factory=tuple)
    info: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "events", tuple(self.events))
        for ev in self.events:
            if not isinstance(ev, (Hold, Press)):
                raise TypeError(f"Track events must be Hold or Press, got {ev!r}")
        object.__setattr__(self, "_plans", {})

    def _plan(self, dt: float) -> _Plan:
        plan = self._plans.get(dt)
        if plan is None:
            plan = self._plans[dt] = _Plan(self.events, dt)
        return plan

    def intent_at_step(self, step: int, dt: float) -> dict:
        """The pilot's intent in step ``step``: every hold with ``step`` in ``hold.steps(dt)``."""
        return self._plan(dt).intent(step)

    def presses_at_step(self, step: int, dt: float) -> list[str]:
        """Pressed actions that fire in step ``step`` (the step :func:`step_index` gives the press time)."""
        return list(self._plan(dt).presses.get(step, ()))

    @property
    def duration(self) -> float:
        ends = [ev.end if isinstance(ev, Hold) else ev.time for ev in self.events]
        return max(ends, default=0.0)


class TrackRecorder:
    """Writes down the intent and presses of every step as they are flown, as a :class:`Track`.

    ``add(step, intent, presses)`` once per step (the input system does it);
    consecutive steps with the same intent become one :class:`Hold`, so a
    keyboard flight is a few dozen entries and a gamepad flight at most one
    per step. Every hold and press lands on whole steps: ``to_track()``
    checks that each one covers exactly the steps it was recorded in.
    """

    def __init__(self, dt: float):
        self.dt = validate.scalar("dt", dt, positive=True)
        self._runs: list[list] = []          # [first step, number of steps, intent]
        self._presses: list[tuple[int, str]] = []
        #: Steps seen so far (the flight's length).
        self.steps = 0

    def add(self, step: int, intent: dict, presses=()) -> None:
        if intent["kill_rotation"] or any(intent[c] != 0.0 for c in CHANNELS):
            last = self._runs[-1] if self._runs else None
            if last is not None and last[0] + last[1] == step and last[2] == intent:
                last[1] += 1
            else:
                self._runs.append([step, 1, dict(intent)])
        for action in presses:
            self.press(step, action)
        self.steps = max(self.steps, step + 1)

    def press(self, step: int, action: str) -> None:
        """A pressed action that acted at (the start of) step ``step``."""
        if action not in SIM_PRESSED:
            raise ValueError(f"only {SIM_PRESSED} go into a track, got {action!r}")
        self._presses.append((step, action))

    def truncate(self, steps: int) -> None:
        """Forget every step from ``steps`` on: a step that never finished (it raised) is not in the flight."""
        steps = max(0, int(steps))
        runs = []
        for first, n, intent in self._runs:
            if first < steps:
                runs.append([first, min(n, steps - first), intent])
        self._runs = runs
        self._presses = [(k, a) for k, a in self._presses if k < steps]
        self.steps = min(self.steps, steps)

    def to_track(self, **info) -> Track:
        dt = self.dt
        events = []
        for first, n, intent in self._runs:
            chans = {c: intent[c] for c in CHANNELS if intent[c] != 0.0}
            hold = Hold(first * dt, (first + n) * dt, kill_rotation=intent["kill_rotation"], **chans)
            if hold.steps(dt) != range(first, first + n):      # cannot happen below ~10^6 steps
                raise ValueError(f"a hold of steps {first}..{first + n} does not round-trip at dt={validate.shown(dt)}")
            events.append(hold)
        for step, action in self._presses:
            events.append(Press(step * dt, action))
        return Track(tuple(events), info={"dt": dt, "steps": self.steps, **info})


# -- track files -------------------------------------------------------------------------------
#: The version of the track file format that :func:`save_track` writes and :func:`load_track` reads.
TRACK_VERSION = 1
_TRACK_FORMAT = "driftframe track"
_INFO_KEYS = {"demo": str, "seed": int, "camera": (str, type(None)), "sky": str, "dt": float, "steps": int}


class TrackFileError(ValueError):
    """A track file that cannot be read: the message names the file and the entry."""


def save_track(track: Track, path: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
    """Write ``track`` to ``path`` as JSON (format below); atomically: a complete file or none.

    Written under :mod:`framework.output`'s discipline: an existing ``path``
    is refused unless ``overwrite``; the file gets the umask's permissions.

    The format, version 1 (every time in simulated seconds, on whole steps of
    ``dt`` for a flown track)::

        {"format": "driftframe track", "version": 1,
         "demo": "asteroids", "seed": 0, "camera": null, "sky": "lines", "dt": 0.016666666666666666,
         "steps": 912,
         "holds": [{"start": 0.5, "end": 1.1, "throttle": 1.0},
                   {"start": 2.0, "end": 2.5, "yaw": -0.42, "kill_rotation": true}],
         "presses": [{"time": 3.0, "action": "switch_camera"}]}

    ``demo`` ... ``steps`` (from ``track.info``: where it was flown, with which
    starting camera and sky, the step and the flight's length) are optional; a hold lists
    only its non-zero channels (:data:`CHANNELS`) and ``kill_rotation``
    when set. Numbers are written with ``repr``, so they read back exactly.
    """
    if not isinstance(track, Track):
        raise TypeError(f"save_track needs a Track, got {track!r}")
    path = Path(path)
    doc = {"format": _TRACK_FORMAT, "version": TRACK_VERSION}
    doc.update({k: track.info[k] for k in _INFO_KEYS if k in track.info})
    holds, presses = [], []
    for ev in track.events:
        if isinstance(ev, Hold):
            h = {"start": ev.start, "end": ev.end, **ev.channels}
            if ev.kill_rotation:
                h["kill_rotation"] = True
            holds.append(h)
        else:
            presses.append({"time": ev.time, "action": ev.action})
    doc["holds"], doc["presses"] = holds, presses
    # one entry per line: a long flight stays readable and diffs line by line
    lines = [f'  {json.dumps(k)}: {json.dumps(v)},' for k, v in doc.items() if k not in ("holds", "presses")]
    for key, items in (("holds", holds), ("presses", presses)):
        body = ",\n".join(f"    {json.dumps(it)}" for it in items)
        lines.append(f'  "{key}": [\n{body}\n  ],' if items else f'  "{key}": [],')
    text = "{\n" + "\n".join(lines)[:-1] + "\n}\n"
    return write_file(path, text, overwrite=overwrite, what="track")


#: Largest track file read: 32 MiB. A flown hold is about 60-90 bytes, so this is over 350,000 entries: a
#: gamepad flight (at most one entry a step) of 1.6 h at 60 steps/s (what a far larger one cost: docs/design/costs.md).
TRACK_CAP = 32 << 20
#: Deepest JSON nesting read. A track is 3 levels deep; JSON nested ~100,000 deep hit Python's recursion limit.
_TRACK_DEPTH = 8


class _Huge:
    """A number in a track too large for a float (``1e400``, 400 digits): kept as text to be refused by name."""

    def __init__(self, text: str):
        self.text = text

    def __repr__(self) -> str:
        digits = self.text.lstrip("-")
        return self.text if len(digits) <= 24 else f"{self.text[:12]}... ({len(digits)} digits)"


def _json_int(text: str):
    # past 308 digits no float holds it; past 4,300 int() itself refuses (CPython's conversion limit)
    return int(text) if len(text) <= 308 else _Huge(text)


def _json_float(text: str):
    v = float(text)
    return v if math.isfinite(v) else _Huge(text)


def _json_constant(text: str):
    return _Huge(text)                           # NaN, Infinity, -Infinity: not JSON, refused by name


def _check_doc(where: str, doc) -> None:
    """Refuse nesting deeper than a track has, and numbers no float holds, naming the entry."""
    stack = [(doc, "", 0)]
    while stack:
        v, at, depth = stack.pop()
        if isinstance(v, _Huge):
            raise TrackFileError(f"{where}: {at or 'the file'}: {v!r} is not a finite number a float can hold")
        if depth > _TRACK_DEPTH:
            raise TrackFileError(f"{where}: {at}: nested deeper than a track is ({_TRACK_DEPTH} levels)")
        if isinstance(v, dict):
            stack.extend((x, f"{at}.{k}" if at else str(k), depth + 1) for k, x in v.items())
        elif isinstance(v, list):
            stack.extend((x, f"{at}[{i}]", depth + 1) for i, x in enumerate(v))


def load_track(path: str | os.PathLike[str]) -> Track:
    """Read a track file written by :func:`save_track` (or by hand, in the same format).

    Every problem is a :class:`TrackFileError` naming the file and the entry,
    e.g. ``flight.json: holds[3]: FlightInput.yaw must be in [-1.0, 1.0], got 2.0``.
    """
    path = Path(path)
    where = str(path)
    try:
        text = read_text_capped(path, TRACK_CAP, "track")
    except InputFileError as e:
        raise TrackFileError(str(e)) from None
    try:
        doc = json.loads(text, parse_int=_json_int, parse_float=_json_float, parse_constant=_json_constant)
    except json.JSONDecodeError as e:
        raise TrackFileError(f"{where}: not JSON: {e.msg} at line {e.lineno} column {e.colno}") from None
    except RecursionError:
        raise TrackFileError(f"{where}: not a driftframe track: its JSON is nested too deeply") from None
    _check_doc(where, doc)
    if not isinstance(doc, dict) or doc.get("format") != _TRACK_FORMAT:
        raise TrackFileError(f'{where}: not a driftframe track (expected "format": "{_TRACK_FORMAT}")')
    version = doc.get("version")
    if version != TRACK_VERSION:
        raise TrackFileError(f"{where}: track version {version!r} is not supported "
                             f"(this driftframe reads version {TRACK_VERSION})")
    unknown = set(doc) - {"format", "version", "holds", "presses", *_INFO_KEYS}
    if unknown:
        raise TrackFileError(f"{where}: unknown key(s) {', '.join(sorted(map(repr, unknown)))}")
    info = {}
    for key, kind in _INFO_KEYS.items():
        if key in doc:
            v = doc[key]
            ok = isinstance(v, kind) and not isinstance(v, bool)
            if kind is float:
                ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0
            if key in ("seed", "steps") and ok:
                ok = v >= 0
            if not ok:
                raise TrackFileError(f"{where}: {key} has a bad value {v!r}"[:300])
            info[key] = float(v) if kind is float else v
    events = []
    for key, make in (("holds", _hold_entry), ("presses", _press_entry)):
        items = doc.get(key, [])
        if not isinstance(items, list):
            raise TrackFileError(f"{where}: {key} must be a list, got {type(items).__name__}")
        for i, item in enumerate(items):
            if not isinstance(item, dict):
                raise TrackFileError(f"{where}: {key}[{i}] must be an object, got {item!r}")
            try:
                events.append(make(item))
            except (TypeError, ValueError) as e:
                raise TrackFileError(f"{where}: {key}[{i}]: {e}") from None
    return Track(tuple(events), info=info)


def _hold_entry(item: dict) -> Hold:
    item = dict(item)
    for k in ("start", "end"):
        if k not in item:
            raise ValueError(f"missing {k!r}")
    start, end = item.pop("start"), item.pop("end")
    kill = item.pop("kill_rotation", False)
    if not isinstance(kill, bool):
        raise TypeError(f"kill_rotation must be true or false, got {kill!r}")
    return Hold(start, end, kill_rotation=kill, **item)


def _press_entry(item: dict) -> Press:
    if set(item) != {"time", "action"}:
        raise ValueError(f"a press has exactly the keys 'time' and 'action', got {sorted(item)}")
    return Press(item["time"], item["action"])
