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

import itertools
import os
import re
import string
import tomllib
from pathlib import Path

from driftframe.batch import STATS, Spec, SpecError, check_all, check_output_names

#: Keys a batch file may have, and what each is.
KEYS = {
    "demo": "a demo name, or a list of them",
    "scene": "'package.module:function', or a list",
    "seeds": "'a..b' (both ends included), an integer, or a list of integers",
    "seconds": "simulated seconds per run",
    "fps": "frames per second of a recording (must divide 60)",
    "size": "'WIDTHxHEIGHT' of a recording",
    "camera": "'cockpit', 'chase' or 'overhead'",
    "sky": "'lines' (the green line cube) or 'starfield'",
    "output": "file name template, relative to the output folder; none: headless",
    "stats": f"which stats to collect: any of {', '.join(STATS)}",
    "scripted": "true: fly the demo's scripted input; false: none",
    "overrides": "a table of settings (a demo's) or keyword arguments (a scene's)",
}
_RANGE = re.compile(r"^\s*(-?\d+)\s*\.\.\s*(-?\d+)\s*$")
MAX_RUNS = 1_000_000


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


def load(path, out_dir, *, check: bool = True) -> list[Spec]:
    """The runs of batch file ``path``, outputs placed in ``out_dir``; a SpecError otherwise.

    ``check``: check every run (:func:`~driftframe.batch.check_all`; the
    output folder must exist then); False only parses the grid.
    """
    path = Path(path)
    name = str(path)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise SpecError(f"{name}: no such batch file") from None
    except IsADirectoryError:
        raise SpecError(f"{name}: is a directory, not a batch file") from None
    except tomllib.TOMLDecodeError as e:
        raise SpecError(f"{name}: not valid TOML: {e}") from None
    except OSError as e:
        raise SpecError(f"{name}: cannot read: {e.strerror or e}") from None
    return grid(data, out_dir, name=name, check=check)


def grid(data: dict, out_dir, *, name: str = "batch", check: bool = True) -> list[Spec]:
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
        "size": _axis(data.get("size", "640x360"), f"{name}: size"),
        "camera": _axis(data.get("camera"), f"{name}: camera"),
        "sky": _axis(data.get("sky", "lines"), f"{name}: sky"),
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
    specs = []
    keys = list(axes)
    for index, combo in enumerate(itertools.product(*axes.values())):
        point = dict(zip(keys, combo))
        ov = {k.split(".", 1)[1]: v for k, v in point.items() if k.startswith("overrides.")}
        where = f"{name}: run {index} ({point[kind]}, seed {point['seed']}" + \
            "".join(f", {k}={v!r}" for k, v in ov.items()) + ")"
        output = None
        if template is not None:
            output = str(out_dir / _fill(template, point, kind, ov, index, where))
        specs.append(Spec(**{kind: point[kind]}, seed=point["seed"], seconds=point["seconds"], fps=point["fps"],
                          size=point["size"], camera=point["camera"], sky=point["sky"], overrides=ov, output=output,
                          stats=tuple(stats), scripted=scripted, where=where))
    return check_all(specs) if check else specs


def without_outputs(specs) -> list[Spec]:
    """The same runs, headless: to check everything but the outputs before any folder exists."""
    import dataclasses
    return [dataclasses.replace(s, output=None) for s in specs]


def prepare(specs, out_dir, *, overwrite: bool = False) -> list[Spec]:
    """Check the runs, then the output folder, then the outputs in it: errors before anything runs.

    Everything but the outputs is checked first, so a bad entry creates no
    folder; then ``out_dir`` (created if needed, proven writable) and any
    sub-folder an output template names. Outputs that exist already are an
    error naming the first (and how many) unless ``overwrite``; with it the
    runs replace them.
    """
    import dataclasses

    existing = [s.output for s in specs if s.output is not None and Path(s.output).exists()]
    if existing and not overwrite:
        more = f" and {len(existing) - 1} more" if len(existing) > 1 else ""
        raise SpecError(f"output {existing[0]!r}{more} exists already; pass --overwrite to replace")
    if overwrite:
        specs = [dataclasses.replace(s, overwrite=True) for s in specs]
    check_all(without_outputs(specs))
    check_output_names(specs)
    out_dir = check_out_dir(out_dir)
    for s in specs:
        if s.output is not None:
            parent = Path(s.output).parent
            if not parent.exists():
                try:
                    parent.mkdir(parents=True, exist_ok=True)
                except OSError as e:
                    raise SpecError(f"{s.where}: cannot create folder {str(parent)!r}: {e.strerror or e}") from None
    return check_all(specs)


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


def _fill(template, point, kind, ov, index, where) -> str:
    size = point["size"]
    w, h = (size.lower().split("x") + ["", ""])[:2] if isinstance(size, str) else (list(size) + ["", ""])[:2]
    value = point[kind]
    label = value.split(":")[-1] if kind == "scene" and isinstance(value, str) else value
    fields = {"demo": label, "scene": label, "seed": point["seed"], "seconds": point["seconds"],
              "fps": point["fps"], "size": size if isinstance(size, str) else f"{w}x{h}", "width": w,
              "height": h, "camera": point["camera"] or "default", "sky": point["sky"], "index": index, **ov}
    try:
        return template.format(**fields)
    except (ValueError, TypeError, KeyError, IndexError) as e:
        raise SpecError(f"{where}: output {template!r}: {e}") from None


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
