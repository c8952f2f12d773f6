"""Batch files: a TOML grid of runs for ``driftframe batch``.

Every key takes one value or a list; each list is an axis of the grid, and
the batch is every combination (the last axis varies fastest)::

    # sweep.toml: 2 sizes x 100 seeds = 200 headless runs
    demo = "swarm"                      # or a list; or scene = "mypkg.scenes:field" (func(world, rng, **kw))
    seeds = "0..99"                     # a..b includes both ends; or 7, or [1, 5, 9]
    seconds = 5                         # default: the demo's own length (required for a scene)
    scripted = false                    # no scripted input: the solver alone (thrust adds energy)
    stats = ["energy", "momentum", "contacts", "stages"]    # the default: all of them

    [overrides]                         # a demo's settings, or the scene function's keyword arguments
    COUNT = [500, 1000]                 # a list here is an axis too

Recordings: add ``output``, a file name template relative to the output
folder (``-o DIR``), with ``size``, ``fps``, ``camera`` and ``sky``::

    output = "{demo}-{seed}.mp4"        # fields: demo (or the scene's function name), seed, seconds,
    size = "640x360"                    # fps, size, width, height, camera, sky, index, and each override
    fps = 30

Anything wrong (an unknown key, a bad range, an unknown demo or scene, an
output name that two runs share, an unwritable folder) is a
:class:`~driftframe.batch.SpecError` naming the file and the entry, raised
before any run starts.
"""
from __future__ import annotations

import contextlib
import itertools
import os
import re
import string
import tomllib
from pathlib import Path

from driftframe.batch import STATS, Spec, SpecError, check_all
from driftframe.batch_spec import _check_output

#: Keys a batch file may have, and what each is.
KEYS = {
    "demo": "a demo name, or a list of them",
    "scene": "'package.module:function', or a list",
    "seeds": "'a..b' (both ends included), an integer, or a list of integers",
    "seconds": "simulated seconds per run",
    "fps": "frames per second of a recording (must divide 60)",
    "size": "'WIDTHxHEIGHT' or [WIDTH, HEIGHT] of a recording (a list of those is an axis)",
    "camera": "'cockpit', 'chase', 'overhead' or 'frame'",
    "sky": "'starfield' or 'lines' (the green line cube); default: the demo's own (the starfield; rotation: lines)",
    "output": "file name template, relative to the output folder; none: headless",
    "stats": f"which stats to collect: any of {', '.join(STATS)}",
    "scripted": "true: fly the demo's scripted input; false: none",
    "overrides": "a table of settings (a demo's) or keyword arguments (a scene's)",
}
_RANGE = re.compile(r"^\s*(-?\d+)\s*\.\.\s*(-?\d+)\s*$")
MAX_RUNS = 1_000_000
#: Longest batch file read (bytes): a grid is a few lines; 1 MiB holds an explicit list of 10^5 seeds.
MAX_FILE_BYTES = 1 << 20


def parse_seeds(value, where: str = "seeds") -> list[int]:
    """``"0..99"`` -> [0, ..., 99] (both ends included); an int -> [it]; a list of ints as it is."""
    if isinstance(value, bool):
        raise SpecError(f"{where}: expected a range 'a..b', an integer or a list, got {value!r}")
    if isinstance(value, int):
        values = [value]
    elif isinstance(value, str):
        m = _RANGE.match(value)
        if not m:
            raise SpecError(f"{where}: bad range {value!r}; write 'a..b' with integers, e.g. '0..99' "
                            "(both ends included)")
        a, b = int(m.group(1)), int(m.group(2))
        if b < a:
            raise SpecError(f"{where}: bad range {value!r}: the end {b} is before the start {a}")
        if b - a + 1 > MAX_RUNS:
            raise SpecError(f"{where}: range {value!r} has {b - a + 1} seeds, more than {MAX_RUNS}")
        values = list(range(a, b + 1))
    elif isinstance(value, list):
        if not value:
            raise SpecError(f"{where}: the list is empty")
        values = []
        for k, v in enumerate(value):
            if isinstance(v, bool) or not isinstance(v, int):
                raise SpecError(f"{where}[{k}]: seeds must be integers, got {v!r}")
            values.append(v)
    else:
        raise SpecError(f"{where}: expected a range 'a..b', an integer or a list, got {value!r}")
    neg = [v for v in values if v < 0]
    if neg:
        raise SpecError(f"{where}: seeds must be >= 0, got {neg[0]}")
    return values


def _axis(value, where: str) -> list:
    if isinstance(value, list):
        if not value:
            raise SpecError(f"{where}: the list is empty")
        return value
    return [value]


def _size_axis(value, where: str) -> list:
    """``size``: ``"640x360"``, ``[640, 360]`` (one size: the natural TOML), or a list of either (an axis).
    Each becomes a (width, height) tuple where it parses; a bad one is left for the check to name."""
    from driftframe.app import parse_size

    if isinstance(value, list) and len(value) == 2 and all(isinstance(v, int) and not isinstance(v, bool)
                                                           for v in value):
        value = [value]
    out = []
    for v in _axis(value, where):
        try:
            out.append(parse_size(v if isinstance(v, str) else "x".join(map(str, v))))
        except (TypeError, ValueError):
            out.append(v)
    return out


def load(path, out_dir, *, check: bool = True, overwrite: bool = False) -> list[Spec]:
    """The runs of batch file ``path``, outputs placed in ``out_dir``; a SpecError otherwise.

    ``check``: check every run (:func:`~driftframe.batch.check_all`; the
    output folder must exist then); False only parses the grid.
    ``overwrite``: the runs may replace existing outputs.
    """
    from driftframe.framework.inputfile import InputFileError, read_text_capped

    path = Path(path)
    name = str(path)
    if not path.exists() and not path.is_symlink():
        raise SpecError(f"{name}: no such batch file")
    try:
        data = tomllib.loads(read_text_capped(path, MAX_FILE_BYTES, "batch file"))
    except InputFileError as e:
        raise SpecError(str(e)) from None
    except tomllib.TOMLDecodeError as e:
        raise SpecError(f"{name}: not valid TOML: {e}") from None
    return grid(data, out_dir, name=name, check=check, overwrite=overwrite)


def grid(data: dict, out_dir, *, name: str = "batch", check: bool = True, overwrite: bool = False) -> list[Spec]:
    """The runs of a parsed batch table (see the module docstring), checked unless ``check`` is False."""
    if "seed" in data and "seeds" not in data:
        data = {**data, "seeds": data["seed"]}
        data.pop("seed")
    unknown = [k for k in data if k not in KEYS]
    if unknown:
        raise SpecError(f"{name}: unknown key {unknown[0]!r}; keys: {', '.join(KEYS)}")
    if ("demo" in data) == ("scene" in data):
        raise SpecError(f"{name}: give demo = ... or scene = ... (exactly one of them)")
    kind = "demo" if "demo" in data else "scene"
    overrides = data.get("overrides", {})
    if not isinstance(overrides, dict):
        raise SpecError(f"{name}: overrides must be a table ([overrides]), got {overrides!r}")
    stats = data.get("stats", list(STATS))
    if isinstance(stats, str):
        stats = [stats]
    if not isinstance(stats, list) or not stats:
        raise SpecError(f"{name}: stats must be a list of names from {', '.join(STATS)}, got {stats!r}")
    for k, s in enumerate(stats):
        if s not in STATS:
            raise SpecError(f"{name}: stats[{k}]: unknown stat {s!r}; stats: {', '.join(STATS)}")
    template = data.get("output")
    if template is not None and not isinstance(template, str):
        raise SpecError(f"{name}: output must be a file name template like '{{demo}}-{{seed}}.mp4', "
                        f"got {template!r}")
    scripted = data.get("scripted", True)
    if not isinstance(scripted, bool):
        raise SpecError(f"{name}: scripted must be true or false, got {scripted!r}")

    axes = {
        kind: _axis(data[kind], f"{name}: {kind}"),
        "seed": parse_seeds(data.get("seeds", 0), f"{name}: seeds"),
        "seconds": _axis(data.get("seconds"), f"{name}: seconds"),
        "fps": _axis(data.get("fps", 60), f"{name}: fps"),
        "size": _size_axis(data.get("size", "640x360"), f"{name}: size"),
        "camera": _axis(data.get("camera"), f"{name}: camera"),
        "sky": _axis(data.get("sky"), f"{name}: sky"),
    }
    for key, value in overrides.items():
        axes[f"overrides.{key}"] = _axis(value, f"{name}: overrides.{key}")
    count = 1
    for values in axes.values():
        count *= len(values)
    if count > MAX_RUNS:
        raise SpecError(f"{name}: the grid has {count} runs, more than {MAX_RUNS}")

    out_dir = Path(out_dir)
    if template is not None:
        _check_template(template, overrides, name)
    inside = _Inside(out_dir) if template is not None else None
    # one pass, no per-run dict: a grid of 10^6 runs is built in a few seconds (each axis value was
    # parsed once above; Spec.check's memo checks each distinct combination of the rest once)
    keys = list(axes)
    ov_keys = [k.split(".", 1)[1] for k in keys[7:]]
    ov_memo: dict = {}
    fill_memo: dict = {}
    skies: dict = {}
    stats = tuple(stats)
    specs = []
    for index, combo in enumerate(itertools.product(*axes.values())):
        what, seed, seconds, fps, size, camera, sky = combo[:7]
        if sky is None:                         # the scene's own, as Spec.check fills it: a run is then built in
            sky = _known_sky(kind, what, skies)  # its checked form, which the check keeps (no copy of 10^6 runs)
        if type(fps) is int:
            fps = float(fps)
        if type(seconds) is int:
            seconds = float(seconds)
        ov_values = combo[7:]
        try:
            ov = ov_memo[ov_values]
        except (KeyError, TypeError):              # TypeError: an unhashable value (a list): its own dict
            ov = dict(zip(ov_keys, ov_values))
            with contextlib.suppress(TypeError):
                ov_memo[ov_values] = ov
        where = f"{name}: run {index} ({what}, seed {seed}" + \
            ("".join(f", {k}={v!r}" for k, v in ov.items()) if ov else "") + ")"
        output = None
        if template is not None:
            output = inside(_fill(template, combo, kind, ov, index, where, fill_memo), where)
        specs.append(Spec(**{kind: what}, seed=seed, seconds=seconds, fps=fps, size=size, camera=camera, sky=sky,
                          overrides=ov, output=output, stats=stats, scripted=scripted, where=where,
                          overwrite=overwrite and output is not None))
    return check_all(specs) if check else specs


class _Inside:
    """Where an output name goes, after every substitution: a path inside the output folder, or a
    SpecError. Refused: an absolute name, a ``..`` part, a folder that resolves (through a symbolic
    link) outside the output folder, a name part longer than the file system allows. The resolved
    folders are remembered: each is looked at once."""

    def __init__(self, out_dir: Path):
        self.out_dir = out_dir
        self.real = os.path.realpath(out_dir)
        probe = out_dir
        while not probe.exists() and probe != probe.parent:
            probe = probe.parent
        try:
            self.name_max = os.pathconf(probe, "PC_NAME_MAX")
        except (OSError, ValueError):
            self.name_max = 255
        self.folders: dict[str, bool] = {}
        self.base = os.path.join(out_dir, "")

    def __call__(self, filled: str, where: str) -> str:
        if "/" not in filled and os.sep not in filled and "\0" not in filled and filled not in (".", "..") \
                and filled.strip() and (len(filled) if filled.isascii() else len(os.fsencode(filled))) <= self.name_max:
            return self.base + filled           # a plain name in the output folder (10^6 runs: the usual case)
        if "\0" in filled or not filled.strip():
            raise SpecError(f"{where}: output name {filled!r} is not a usable file name")
        parts = filled.replace(os.sep, "/").split("/")
        if os.path.isabs(filled) or ".." in parts:
            raise SpecError(f"{where}: output {filled!r} leaves the output folder {str(self.out_dir)!r} "
                            "(an absolute path or '..' after the fields were filled in)")
        for part in parts:
            if len(os.fsencode(part)) > self.name_max:      # (the part file's name is cut to fit)
                raise SpecError(f"{where}: output name part {part[:40]!r}... is {len(os.fsencode(part))} bytes; "
                                f"the file system here allows {self.name_max}")
        full = os.path.join(self.out_dir, filled)
        folder = os.path.dirname(full)
        ok = self.folders.get(folder)
        if ok is None:
            real = os.path.realpath(folder)
            ok = self.folders[folder] = real == self.real or real.startswith(self.real.rstrip(os.sep) + os.sep)
        if not ok:
            raise SpecError(f"{where}: output {filled!r} leaves the output folder {str(self.out_dir)!r} "
                            f"(its folder resolves to {os.path.realpath(folder)!r})")
        return full


def prepare(specs, out_dir, *, overwrite: bool = False, done=frozenset(), checked: bool = False) -> list[Spec]:
    """Check the runs, then the output folder, then the outputs in it: errors before anything runs.

    Everything but the outputs is checked first (``checked``: the caller did,
    with ``check_all(specs, outputs=False)``), so a bad entry creates no
    folder; then ``out_dir`` (created if needed, proven writable) and any
    sub-folder an output template names. Outputs that exist already are an
    error naming the first (and how many) unless ``overwrite``; with it the
    runs replace them. ``done``: indices of runs a resumed batch skips (the
    journal holds them): their outputs are theirs. An existing output that
    resolves outside the output folder (a symbolic link) is refused always.
    """
    import dataclasses

    real = os.path.realpath(out_dir)
    existing = []
    listed: dict[str, set] = {}             # each folder listed once: 10^6 outputs, not 10^6 stat calls
    for i, s in enumerate(specs):
        if s.output is None or i in done:
            continue
        folder, name = os.path.split(os.fspath(s.output))
        names = listed.get(folder)
        if names is None:
            try:
                names = listed[folder] = set(os.listdir(folder or "."))
            except OSError:
                names = listed[folder] = set()  # (no folder yet: nothing in it exists)
        if name and name not in names:
            continue
        if not os.path.lexists(s.output):
            continue
        target = os.path.realpath(s.output)
        if not target.startswith(real.rstrip(os.sep) + os.sep):
            raise SpecError(f"{s.where}: output {s.output!r} is a link to {target!r}, outside the output folder")
        existing.append(s.output)
    if existing and not overwrite:
        more = f" and {len(existing) - 1} more" if len(existing) > 1 else ""
        raise SpecError(f"output {existing[0]!r}{more} exists already; pass --overwrite to replace it "
                        "(or --resume to continue the batch that wrote it)")
    if overwrite:                           # (load(overwrite=True) made them so: no copy of 10^6 runs)
        specs = [s if s.output is None or s.overwrite else dataclasses.replace(s, overwrite=True) for s in specs]
    if not checked:
        specs = check_all(specs, outputs=False)
    out_dir = check_out_dir(out_dir)
    made: dict[str, Spec] = {}
    for s in specs:
        if s.output is not None:
            parent = os.path.dirname(s.output)
            if parent in made:
                continue
            made[parent] = s
            if not os.path.isdir(parent):
                try:
                    os.makedirs(parent, exist_ok=True)
                except OSError as e:
                    raise SpecError(f"{s.where}: cannot create folder {parent!r}: {e.strerror or e}") from None
    for s in made.values():                 # each output folder: exists, is writable (once a folder)
        _check_output(os.fspath(s.output), s._err)
    return specs


def _fields(overrides) -> set[str]:
    return {"demo", "scene", "seed", "seconds", "fps", "size", "width", "height", "camera", "sky", "index",
            *overrides}


def _check_template(template: str, overrides, name: str) -> None:
    try:
        parsed = list(string.Formatter().parse(template))
    except ValueError as e:
        raise SpecError(f"{name}: output {template!r}: {e}") from None
    known = _fields(overrides)
    for _, field, _, _ in parsed:
        if field is None:
            continue
        if field not in known:
            raise SpecError(f"{name}: output {template!r}: unknown field {{{field}}}; "
                            f"fields: {', '.join(sorted(known))}")
    if os.path.isabs(template) or ".." in Path(template).parts:
        raise SpecError(f"{name}: output {template!r} must be a relative name inside the output folder")


def _fill(template, combo, kind, ov, index, where, memo: dict) -> str:
    """The output name of the run at grid point ``combo`` (what, seed, seconds, fps, size, camera, sky,
    overrides...). The fields but the seed and the index are made once per distinct rest (``memo``)."""
    what, seed, seconds, fps, size, camera, sky = combo[:7]
    key = combo[:1] + combo[2:]
    try:
        fields = memo[key]
    except (KeyError, TypeError):               # TypeError: an unhashable override value (a list)
        w, h = (size.lower().split("x") + ["", ""])[:2] if isinstance(size, str) else (list(size) + ["", ""])[:2]
        label = what.split(":")[-1] if kind == "scene" and isinstance(what, str) else what
        fields = {"demo": label, "scene": label, "seconds": seconds, "fps": fps,
                  "size": size if isinstance(size, str) else f"{w}x{h}", "width": w, "height": h,
                  "camera": camera or "default", "sky": sky or _own_sky(kind, what), **ov}
        with contextlib.suppress(TypeError):
            memo[key] = fields
    try:
        return template.format_map({**fields, "seed": seed, "index": index})
    except (ValueError, TypeError, KeyError, IndexError) as e:
        raise SpecError(f"{where}: output {template!r}: {e}") from None


def _own_sky(kind, what) -> str:
    """The sky a run without one records (the scene's own: :func:`driftframe.rendering.default_sky`), for its
    output name; "default" where the demo is unknown (the run's check then names it)."""
    from driftframe import demos
    from driftframe.rendering import default_sky
    if kind != "demo":
        return default_sky(None)
    try:
        return default_sky(demos.load(what))
    except (LookupError, ValueError, TypeError):
        return "default"


def _known_sky(kind, what, memo: dict) -> str | None:
    """:func:`_own_sky` once per demo (``memo``); None where it is not known (the run's check names why)."""
    try:
        sky = memo[what] if what in memo else memo.setdefault(what, _own_sky(kind, what))
    except TypeError:                           # an unhashable demo value: the check names it
        return None
    return None if sky == "default" else sky


def check_out_dir(out_dir) -> Path:
    """Create the output folder if needed and prove it is writable; a SpecError naming it otherwise."""
    import tempfile

    p = Path(out_dir)
    if p.exists() and not p.is_dir():
        raise SpecError(f"output folder {str(p)!r} exists and is not a folder")
    try:
        p.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".driftframe-probe-", dir=p)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise SpecError(f"output folder {str(p)!r} is not writable: {e.strerror or e}") from None
    return p
