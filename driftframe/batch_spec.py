"""What one batch run is: :class:`Spec`, and the checks that run before anything runs.

Part of :mod:`driftframe.batch` (import from there). A spec is checked once,
before any run starts (:func:`check_all`): its demo or scene, every value,
the length of the run (the same bounds as ``driftframe record``), and its
output. Checking a grid costs time linear in its size: what a check looks at
besides the seed, the output and the name is the same for most runs of a
grid, so it is checked once per distinct value (a memo in :func:`check_all`).
"""
from __future__ import annotations

import dataclasses
import hashlib
import importlib
import inspect
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

#: The stats a run can collect; all of them by default.
STATS = ("energy", "momentum", "contacts", "stages")
SKIES = ("lines", "starfield")
#: Frame size of a recording when a spec gives none (pixels).
DEFAULT_SIZE = (640, 360)

class SpecError(ValueError):
    """A spec (or a batch file entry) that cannot run; the message names the entry and the bad value."""


class Interrupted(Exception):
    """A run stopped because the batch was asked to stop (Ctrl-C). Not a failure: nothing was written."""


@dataclass(frozen=True)
class Spec:
    """One run. Give ``demo`` (a name from ``driftframe list``) or ``scene`` (``"pkg.mod:func"``).

    ``scene``: a function ``func(world, rng, **overrides)`` that creates
    entities in a world that has the standard systems (no scripted input).
    ``overrides``: for a scene, keyword arguments of ``func``; for a demo, its
    module settings (upper-case names such as swarm's ``COUNT``), set only
    while the scene is built. ``seconds``: simulated length (default: the
    demo's ``SECONDS``; required for a scene). ``output``: ``None`` for a
    headless run (physics only), else a ``.mp4``/``.gif`` path or a directory
    for PNG frames, rendered at ``size`` and ``fps`` (which must divide the
    simulation rate), with ``camera`` (one of ``components.camera.MODES``;
    default: the scene's own) and ``sky`` (:data:`SKIES`; default None: the scene's own, as for
    ``driftframe record``: the starfield, the rotation demo's green lines). ``scripted``: fly the demo's scripted input (its thrust
    adds energy; False measures the solver alone). ``stats``: which of
    :data:`STATS` to collect. ``where``: how error messages name this run.
    """

    demo: str | None = None
    scene: str | None = None
    seed: int = 0
    seconds: float | None = None
    fps: float = 60.0
    size: tuple[int, int] = DEFAULT_SIZE
    camera: str | None = None
    sky: str | None = None
    overrides: dict = field(default_factory=dict)
    output: str | None = None
    stats: tuple[str, ...] = STATS
    scripted: bool = True
    where: str = ""
    #: Replace an existing output (the batch command checks outputs before any run starts).
    overwrite: bool = False

    def __hash__(self):                 # overrides is a dict: hash what it holds
        return hash((self.demo, self.scene, self.seed, self.seconds, self.fps, tuple(self.size), self.camera,
                     self.sky, repr(sorted(self.overrides.items())), self.output, tuple(self.stats), self.scripted,
                     self.overwrite))

    @property
    def label(self) -> str:
        """Short text for progress lines and tables: ``asteroids seed=3``, plus overrides."""
        what = self.demo if self.demo is not None else str(self.scene)
        extra = "".join(f" {k}={v!r}" for k, v in sorted(self.overrides.items()))
        return f"{what} seed={self.seed}{extra}"

    def _err(self, msg: str) -> SpecError:
        return SpecError(f"{self.where or self.label}: {msg}")

    def check(self, memo: dict | None = None, *, check_folder: bool = True) -> "Spec":
        """This spec with its defaults filled in (``seconds``, sizes as tuples), or a :class:`SpecError`.

        Imports the scene, checks every value, the run's length and that the
        output can be written; runs nothing. ``memo``: a dict shared by the
        checks of one batch; what does not depend on the seed, the output or
        the name is then checked once per distinct value (a grid of 10^6
        seeds imports its scene once, not 10^6 times). ``check_folder=False``:
        all but the output's folder (which may not exist yet).
        """
        key = None
        if memo is not None:
            try:
                key = (self.demo, self.scene, self.seconds, self.fps, self.size, self.camera, self.sky,
                       tuple(sorted(self.overrides.items())), self.stats, self.scripted, self.output is None)
                hash(key)
            except (TypeError, AttributeError):
                key = None
        if key is not None and key in memo:
            filled = memo[key]
        else:
            filled = self._check_values()
            if key is not None:
                memo[key] = filled
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise self._err(f"seed must be an integer >= 0, got {self.seed!r}")
        output = None
        if self.output is not None:
            output = os.fspath(self.output)
            if check_folder:                    # (its folder is not needed otherwise: 10^6 dirname calls saved)
                folder = os.path.dirname(output)
                if memo is None or ("folder", folder) not in memo:
                    _check_output(output, self._err)
                    if memo is not None:
                        memo[("folder", folder)] = True
        seconds, fps, size, stats, sky = filled
        if (seconds, fps, size, stats, sky, output) == (self.seconds, self.fps, self.size, self.stats, self.sky,
                                                        self.output) \
                and type(self.seed) is int and type(seconds) is float and type(fps) is float:
            return self                         # already in its checked form (a grid's runs): no copy
        return dataclasses.replace(self, seconds=seconds, fps=fps, size=size, stats=stats, sky=sky, output=output,
                                   seed=int(self.seed))

    def _check_values(self) -> tuple:
        """(seconds, fps, size, stats, sky) checked and filled in: everything but the seed and the output."""
        if (self.demo is None) == (self.scene is None):
            raise self._err("give exactly one of demo or scene "
                            f"(got demo={self.demo!r}, scene={self.scene!r})")
        if not isinstance(self.overrides, dict) or not all(isinstance(k, str) for k in self.overrides):
            raise self._err(f"overrides must be a table of names to values, got {self.overrides!r}")
        if self.demo is not None:
            module = _demo_module(self.demo, self._err)
            _check_demo_overrides(module, self.demo, self.overrides, self._err)
            dt = float(self.overrides.get("DT", getattr(module, "DT", 1.0 / 60.0)))
            default_seconds = self.overrides.get("SECONDS", module.SECONDS)
            scene = module
        else:
            func = _scene_function(self.scene, self._err)
            try:
                inspect.signature(func).bind(None, None, **self.overrides)
            except TypeError as e:
                raise self._err(f"overrides {sorted(self.overrides)} do not fit scene {self.scene!r} "
                                f"(func(world, rng, **overrides)): {e}") from None
            dt = 1.0 / 60.0
            default_seconds = None
            scene = None
        seconds = self.seconds if self.seconds is not None else default_seconds
        if seconds is None:
            raise self._err(f"seconds is required for scene {self.scene!r}")
        seconds = _number(seconds, "seconds", self._err)
        fps = _number(self.fps, "fps", self._err)
        k = _steps_per_frame(fps, dt, self._err)
        _check_length(seconds, fps, dt, k, self.output is not None, self._err)
        size = self.size
        from driftframe.app import parse_size
        try:
            size = parse_size(size if isinstance(size, str) else "x".join(map(str, size)))
        except (TypeError, ValueError) as e:
            raise self._err(str(e)) from None
        from driftframe.components.camera import MODES
        if self.camera is not None and self.camera not in MODES:
            raise self._err(f"camera must be one of {', '.join(MODES)} (or none), got {self.camera!r}")
        sky = self.sky
        if sky is None:                         # the scene's own, as `driftframe record` takes it
            from driftframe.rendering import default_sky
            try:
                sky = default_sky(scene)
            except ValueError as e:
                raise self._err(str(e)) from None
        if sky not in SKIES:
            raise self._err(f"sky must be one of {', '.join(SKIES)}, got {sky!r}")
        stats = (self.stats,) if isinstance(self.stats, str) else tuple(self.stats)
        bad = [s for s in stats if s not in STATS]
        if bad:
            raise self._err(f"unknown stat {bad[0]!r}; stats: {', '.join(STATS)}")
        if not isinstance(self.scripted, bool):
            raise self._err(f"scripted must be true or false, got {self.scripted!r}")
        return seconds, fps, size, stats, sky

    def content_hash(self) -> str:
        """A hash of what the run does (not of its name in error messages): a journal row matches a spec
        by it (``driftframe batch --resume``). Call it on a checked spec."""
        what = [self.demo, self.scene, int(self.seed), self.seconds, self.fps, list(self.size), self.camera,
                self.sky, sorted(self.overrides.items()), self.output, list(self.stats), self.scripted]
        text = json.dumps(what, sort_keys=True, default=repr, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:32]


# -- checks ----------------------------------------------------------------------------------------
def _check_length(seconds: float, fps: float, dt: float, k: int, recording: bool, err) -> None:
    """The same bounds as ``driftframe record`` (``cli.MAX_FRAMES``, ``cli.MAX_STEPS``): a run of
    ``seconds = 1e300`` is refused here instead of running for ever."""
    from driftframe.cli import MAX_FRAMES, MAX_STEPS
    if recording:
        frames = seconds * fps                  # a float: 1e308 * 60 is inf, never an OverflowError
        if not frames <= MAX_FRAMES or max(1, round(frames)) * k > MAX_STEPS:
            raise err(f"seconds {seconds:g} at {fps:g} fps is {frames:.3g} frames; a recording may have at most "
                      f"{MAX_FRAMES:,} frames and {MAX_STEPS:,} steps (as for driftframe record)")
    else:
        steps = seconds / dt
        if not steps <= MAX_STEPS:
            raise err(f"seconds {seconds:g} is {steps:.3g} fixed steps of {dt:g} s; a run may have at most "
                      f"{MAX_STEPS:,} steps (as for driftframe record)")


def _number(value, name, err) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value <= 0:
        raise err(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def _steps_per_frame(fps: float, dt: float, err=SpecError) -> int:
    """Whole simulation steps per recorded frame (:func:`driftframe.framework.recorder.steps_per_frame`)."""
    from driftframe.framework.recorder import steps_per_frame
    try:
        return steps_per_frame(fps, dt)
    except ValueError as e:
        raise err(str(e)) from None


def _demo_module(name, err):
    from driftframe import demos
    try:
        return demos.load(name)
    except LookupError as e:
        raise err(str(e)) from None


def _settings(module) -> dict:
    """A demo's overridable settings: its upper-case module constants that are plain numbers."""
    return {k: v for k, v in vars(module).items()
            if k.isupper() and isinstance(v, (int, float)) and not isinstance(v, bool)}


def _check_demo_overrides(module, name, overrides, err) -> None:
    settings = _settings(module)
    for key, value in overrides.items():
        if key not in settings:
            known = ", ".join(sorted(settings)) or "none"
            raise err(f"overrides: demo {name!r} has no setting {key!r}; its settings: {known}")
        old = settings[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                (isinstance(old, int) and not isinstance(value, int)):
            raise err(f"overrides.{key} must be {'an integer' if isinstance(old, int) else 'a number'} "
                      f"like {old!r}, got {value!r}")
        if not math.isfinite(value) or value <= 0:
            raise err(f"overrides.{key} must be > 0, got {value!r}")


def _scene_function(path, err) -> Callable:
    if not isinstance(path, str) or path.count(":") != 1 or not all(path.split(":")):
        raise err(f"scene must be an import path 'package.module:function', got {path!r}")
    mod_name, func_name = path.split(":")
    try:
        module = importlib.import_module(mod_name)
    except ImportError as e:
        raise err(f"scene {path!r}: cannot import module {mod_name!r} ({e})") from None
    func = getattr(module, func_name, None)
    if func is None:
        raise err(f"scene {path!r}: module {mod_name!r} has no {func_name!r}")
    if not callable(func):
        raise err(f"scene {path!r}: {func_name!r} is not a function")
    return func


def _check_output(output: str, err) -> None:
    from driftframe.framework.recorder import output_format
    try:
        output_format(output)
    except ValueError as e:
        raise err(f"output: {e}") from None
    parent = Path(output).parent
    if not parent.is_dir():
        raise err(f"output {output!r}: directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise err(f"output {output!r}: directory {str(parent)!r} is not writable")


def check_output_names(specs) -> None:
    """Each output's name has a known format and no two runs write the same one (no file system used)."""
    from driftframe.framework.recorder import output_format

    seen: dict[str, Spec] = {}
    plain = (".mp4", ".gif")                    # names the format check would pass: no Path, no stat
    for spec in specs:
        if spec.output is None:
            continue
        text = os.fspath(spec.output)
        if not text.lower().endswith(plain):   # (a folder of that name, if one is there: PNG frames, as record)
            try:
                output_format(text)
            except ValueError as e:
                raise spec._err(f"output: {e}") from None
        key = text if os.path.isabs(text) and "/." not in text and "//" not in text and not text.endswith("/") \
            else os.path.abspath(text)          # (abspath is a third of the time of 10^6 runs)
        if key in seen:
            raise spec._err(f"output {spec.output!r} is also written by {seen[key].where or seen[key].label}; "
                            "each run needs its own output (put {seed} or another varying field in the name)")
        seen[key] = spec


def check_all(specs, *, outputs: bool = True, names: bool = True) -> list[Spec]:
    """Every spec checked (:meth:`Spec.check`), and no two writing the same output; before anything runs.

    ``outputs=False``: not the outputs' folders (which may not exist yet); ``names=False``: not the
    outputs' names (checked before). Each part is linear in the number of runs (10^6 runs: seconds).
    """
    specs = list(specs)
    for i, spec in enumerate(specs):
        if not isinstance(spec, Spec):
            raise SpecError(f"run {i}: expected a driftframe.batch.Spec, got {spec!r}")
    if names:
        check_output_names(specs)
    memo: dict = {}
    return [spec.check(memo, check_folder=outputs) for spec in specs]

