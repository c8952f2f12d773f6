"""Saves: a running world written to one file and read back, continuing bit-identically.

``world.save("slot.dfsave")`` writes, and ``World.load("slot.dfsave")`` reads, a
numpy ``.npz`` (a zip of ``.npy`` arrays, stored uncompressed, no pickle: it is
read with ``allow_pickle=False``) holding

* ``manifest.json``: ``format`` (``"driftframe-save"``), ``format_version``
  (:data:`FORMAT_VERSION`, separate from the package version), the driftframe
  version that wrote it, the scene (``make_world``'s demo or ``module:function``,
  seed, collision method, scripted), ``dt``, ``step_count``, the time, the
  entity ids and esper's next id, each columnar component's field layout, the
  plain (dataclass) components, the resources (``resources``: those keyed by
  name; ``typed_resources``: those keyed by their type, by ``module:Class``;
  ``rebuilt_resources``: the names of those a load makes again, see below),
  the state of each system that has one and the event subscriptions (as
  names, see below);
* ``columns/<Class>/<field>.npy`` and ``columns/<Class>/entities.npy``: every
  columnar field of every entity, exact bytes (a float is the same 64 bits).

Plain values (dataclass components, resources, system state) are JSON with
tags for what JSON lacks, so nothing changes type on the way back (a tuple
stays a tuple, ``np.float64`` stays ``np.float64``, an array keeps its dtype
and bytes, +-inf and NaN survive): ``{"$tuple": [...]}``, ``{"$f": hex}``,
``{"$np": dtype, "v": ...}``, ``{"$array": dtype, "shape": ..., "b64": ...}``,
``{"$dc": "module:Class", ...}`` (a dataclass), ``{"$obj": ...}`` (an object's
``__dict__``), ``{"$rng": ...}`` (a ``numpy.random.Generator``'s bit generator
state). A class is looked up among the modules this process has imported
(the scene's build imports them). The only modules a load imports are
driftframe's ``make_world`` (named in the save by ``make_world`` itself)
and, through it, the scene the save names, as ``driftframe play SCENE``
would; with ``build=``, none.

**What is not in a save, and how loading gets it back.** Systems and
callbacks are code, not data. :func:`load` (``World.load``) first rebuilds the
world the way it was made (``make_world(scene, seed=...)``, or your own
``build()`` that returns a world with its systems: ``World.load(path,
build=my_build)``), so the scene's systems, subscriptions and the resources
it makes (the demo module, GL handles) are back; then it deletes the
rebuilt entities and puts the saved ones in their place (same ids), with the
step count, the saved resources and each system's ``restore(state)``. The
subscriptions the save names (event type and callback) must be those the
rebuild made, else the load is refused naming them.

A system keeps state between steps that the components do not hold (the
gravity system's epochs on rails, the collision system's last contact times)
by a ``state()`` returning plain values and a ``restore(state)`` taking them
back: :func:`save` calls every scheduled system's ``state()``, :func:`load`
every ``restore()``.

Errors: a file that is missing, too long (:data:`SAVE_CAP`), not a zip,
truncated, with a byte changed (each member has a CRC-32), edited so a field
is missing, renamed or of the wrong shape, foreign (another zip, another
program's .npz), or of another format version is a :class:`SaveError` of one
line naming the file and the member or field.
"""
from __future__ import annotations

import base64
import dataclasses
import enum
import importlib
import io
import json
import math
import os
import sys
import zipfile

import esper
import numpy as np

from driftframe.framework import __version__
from driftframe.framework import esper_adapter as ea
from driftframe.framework import validate
from driftframe.framework.inputfile import read_bytes_capped
from driftframe.framework.output import PartFile
from driftframe.framework.scene import SceneRecipe, Seed
from driftframe.framework.store import Columnar

#: The save format's version: bumped when a reader of the old format would misread the new. A save of
#: another format version is refused naming both versions; another package version of the same format loads.
FORMAT_VERSION = 1
FORMAT = "driftframe-save"
#: The largest save file read, bytes (256 MiB: ~1 million bodies at ~200 bytes of columns each).
SAVE_CAP = 256 << 20
MANIFEST = "manifest.json"
#: Resources a world's rebuild makes again, never taken from a save: the scene's module and how it was made,
#: rendering handles. A system adds the names of those it makes in its ``rebuilt_resources``.
REBUILT_RESOURCES = ("demo", "gl", "model_cache", "render_target", "make_world")   # (names of older saves)


class SaveError(ValueError):
    """A save that cannot be written or read: one line naming the file and the member or field."""


# -- plain values <-> JSON ---------------------------------------------------------------------------

class _Unsavable(TypeError):
    pass


def _class_path(cls) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


def _find_class(path: str, where: str):
    """The class ``module:qualname`` among the imported modules (a class name in a save imports nothing)."""
    mod_name, _, qual = path.partition(":")
    mod = sys.modules.get(mod_name)
    if mod is None or not qual:
        raise SaveError(f"{where}: class {path!r} is not known here (its module is not imported by the scene)")
    obj = mod
    for part in qual.split("."):
        obj = getattr(obj, part, None)
        if obj is None:
            raise SaveError(f"{where}: module {mod_name!r} has no class {qual!r}")
    if not isinstance(obj, type):
        raise SaveError(f"{where}: {path!r} is not a class")
    return obj


def encode(value, where: str = "value"):
    """``value`` as JSON-ready data with tags (see the module's text); an unsavable value raises naming ``where``."""
    if isinstance(value, enum.Enum):
        return {"$enum": _class_path(type(value)), "name": value.name}
    if value is None or isinstance(value, (bool, str)):
        return value
    if type(value) is int:
        return value
    if type(value) is float:
        return value if math.isfinite(value) else {"$f": value.hex()}
    if isinstance(value, np.generic):
        if value.dtype.kind not in "biuf":
            raise _Unsavable(f"{where}: numpy scalar of dtype {value.dtype} cannot be saved")
        return {"$np": value.dtype.str, "v": encode(value.item(), where)}
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biuf":
            raise _Unsavable(f"{where}: array of dtype {value.dtype} cannot be saved")
        return {"$array": value.dtype.str, "shape": list(value.shape),
                "b64": base64.b64encode(np.ascontiguousarray(value).tobytes()).decode()}
    if isinstance(value, tuple) and not hasattr(value, "_fields"):
        return {"$tuple": [encode(v, f"{where}[{k}]") for k, v in enumerate(value)]}
    if isinstance(value, list):
        return [encode(v, f"{where}[{k}]") for k, v in enumerate(value)]
    if isinstance(value, (set, frozenset)):
        return {"$set" if isinstance(value, set) else "$frozenset":
                [encode(v, f"{where}{{}}") for v in sorted(value, key=repr)]}
    if isinstance(value, dict) and type(value) is dict:
        return {"$dict": [[encode(k, f"{where} key"), encode(v, f"{where}[{k!r}]")] for k, v in value.items()]}
    if isinstance(value, np.random.Generator):
        bg = value.bit_generator
        return {"$rng": _class_path(type(bg)), "state": encode(bg.state, f"{where} state")}
    if isinstance(value, Columnar):
        return {"$col": _class_path(type(value)),
                "values": {n: encode(v, f"{where}.{n}") for n, v in value.values().items()}}
    cls = type(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"$dc": _class_path(cls),
                "fields": {f.name: encode(getattr(value, f.name), f"{where}.{f.name}")
                           for f in dataclasses.fields(value)}}
    if isinstance(value, type) or callable(value) or type(value).__module__ in ("builtins", "types"):
        raise _Unsavable(f"{where}: {type(value).__name__} {value!r:.60} cannot be saved")
    state = getattr(value, "__dict__", None)
    if state is None or getattr(cls, "__slots__", None):
        raise _Unsavable(f"{where}: {cls.__name__} has no __dict__ to save")
    return {"$obj": _class_path(cls), "state": {k: encode(v, f"{where}.{k}") for k, v in state.items()}}


def decode(data, where: str = "value"):
    """The value :func:`encode` made ``data`` from (a SaveError naming ``where`` if it is not such data)."""
    if data is None or isinstance(data, (bool, int, float, str)):
        return data
    if isinstance(data, list):
        return [decode(v, f"{where}[{k}]") for k, v in enumerate(data)]
    if not isinstance(data, dict) or len(data) < 1:
        raise SaveError(f"{where}: unexpected {type(data).__name__}")
    try:
        if "$f" in data:
            return float.fromhex(data["$f"])
        if "$enum" in data:
            return _find_class(data["$enum"], where)[data["name"]]
        if "$np" in data:
            return np.dtype(data["$np"]).type(decode(data["v"], where))
        if "$array" in data:
            dt = np.dtype(data["$array"])
            if dt.kind not in "biuf":
                raise ValueError(f"dtype {dt}")
            raw = base64.b64decode(data["b64"], validate=True)
            return np.frombuffer(raw, dt).reshape(data["shape"]).copy()
        if "$tuple" in data:
            return tuple(decode(v, f"{where}[{k}]") for k, v in enumerate(data["$tuple"]))
        if "$set" in data:
            return {decode(v, where) for v in data["$set"]}
        if "$frozenset" in data:
            return frozenset(decode(v, where) for v in data["$frozenset"])
        if "$dict" in data:
            return {decode(k, f"{where} key"): decode(v, f"{where}[{k!r}]") for k, v in data["$dict"]}
        if "$rng" in data:
            bg = _find_class(data["$rng"], where)()
            bg.state = decode(data["state"], f"{where} state")
            return np.random.Generator(bg)
        if "$col" in data:
            cls = _find_class(data["$col"], where)
            return cls._from_values({n: decode(v, f"{where}.{n}") for n, v in data["values"].items()})
        if "$dc" in data:
            cls = _find_class(data["$dc"], where)
            if not dataclasses.is_dataclass(cls):
                raise SaveError(f"{where}: {data['$dc']!r} is not a dataclass")
            names = [f.name for f in dataclasses.fields(cls)]
            got = data["fields"]
            if set(got) != set(names):
                odd = sorted(set(got) ^ set(names))
                raise SaveError(f"{where}: {cls.__name__} has fields {names}, the save has {sorted(got)} "
                                f"(field {odd[0]!r})")
            obj = object.__new__(cls)
            for n in names:
                object.__setattr__(obj, n, decode(got[n], f"{where}.{n}"))
            return obj
        if "$obj" in data:
            cls = _find_class(data["$obj"], where)
            obj = object.__new__(cls)
            obj.__dict__.update({k: decode(v, f"{where}.{k}") for k, v in data["state"].items()})
            return obj
    except SaveError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise SaveError(f"{where}: malformed value ({type(e).__name__}: {e})") from None
    raise SaveError(f"{where}: unknown tag {sorted(data)[0]!r}")


# -- writing -------------------------------------------------------------------------------------------

def _subscriptions(world) -> list:
    return sorted([_class_path(t), getattr(fn, "__qualname__", type(fn).__qualname__)]
                  for t, fns in world._subscribers.items() for fn in fns)


def _systems(world):
    for phase in ("step", "frame"):
        for e in world._order[phase]:
            yield e.name, e.system


def _recipe(world) -> dict | None:
    """How ``world`` was made (its :class:`~framework.scene.SceneRecipe`, the save's ``scene`` field), or None."""
    recipe = world.resources.get(SceneRecipe)
    return recipe.manifest() if recipe is not None else None


def snapshot(world) -> tuple[dict, dict]:
    """``(manifest, arrays)`` of ``world`` now: what :func:`save` writes."""
    world._check_whole("save")
    world.activate()
    world.sync()
    ents = ea.live_entities()
    manifest = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "driftframe_version": __version__,
        "scene": _recipe(world),
        "dt": encode(world.dt), "step_count": int(world.step_count), "time": encode(world.time),
        "next_entity": ea.next_entity(), "entities": ents,
        "columnar": {}, "plain": {}, "resources": {}, "typed_resources": {}, "rebuilt_resources": [],
        "systems": {}, "subscriptions": _subscriptions(world),
    }
    arrays = {"entities": np.asarray(ents, np.int64)}
    live = set(ents)
    for cls in sorted(ea.component_types(), key=_class_path):
        holders = sorted(e for e in ea.holders(cls) if e in live)
        if not holders:
            continue
        path = _class_path(cls)
        if issubclass(cls, Columnar):
            key = f"columns/{path}"
            table = world._table(cls)
            rows = table.rows_of(np.asarray(holders, np.int64))
            arrays[f"{key}/entities"] = np.asarray(holders, np.int64)
            layout = {}
            for name, f in cls._fields.items():
                arrays[f"{key}/{name}"] = np.ascontiguousarray(table.data[name][rows])
                layout[name] = {"dtype": f.dtype.str, "shape": list(f.shape)}
            manifest["columnar"][path] = layout
        else:
            try:
                manifest["plain"][path] = [[e, encode(esper.component_for_entity(e, cls),
                                                      f"{cls.__name__} of entity {e}")] for e in holders]
            except _Unsavable as err:
                raise SaveError(f"cannot save component {err}") from None
    # what the systems say they make again (a handle, a table of claims by object ids)
    rebuilt = set(REBUILT_RESOURCES)
    for _, system in _systems(world):
        rebuilt.update(getattr(system, "rebuilt_resources", ()))
    for key, value in world.resources.items():
        if isinstance(key, type):
            # a resource keyed by its type: under "typed_resources", by class path; one whose class says
            # saved = False (a handle, what the scene's build makes again) or a system rebuilds: by name only
            path = _class_path(key)
            if key in rebuilt or getattr(key, "saved", True) is False:
                manifest["rebuilt_resources"].append(path)
                continue
            try:
                manifest["typed_resources"][path] = encode(value, f"resource {key.__name__}")
            except _Unsavable:
                manifest["rebuilt_resources"].append(path)   # code or a handle, as a named one below: rebuilt
            continue
        if key in rebuilt:
            manifest["rebuilt_resources"].append(key)
            continue
        if not isinstance(key, str):
            raise SaveError(f"cannot save resource key {key!r}: resources are keyed by their type or a name")
        try:
            manifest["resources"][key] = encode(value, f"resource {key!r}")
        except _Unsavable:
            manifest["rebuilt_resources"].append(key)     # code or a handle (a module, a GL context): rebuilt
    for name, system in _systems(world):
        state = getattr(system, "state", None)
        if callable(state) and callable(getattr(system, "restore", None)):
            try:
                manifest["systems"][name] = encode(state(), f"system {name!r} state")
            except _Unsavable as err:
                raise SaveError(f"cannot save {err}") from None
    return manifest, arrays


def save(world, path, *, overwrite: bool = False) -> str:
    """Write ``world`` to ``path`` (an ``.npz``; see the module's text), atomically: a complete file or
    none. An existing ``path`` is refused unless ``overwrite``. Returns the path."""
    manifest, arrays = snapshot(world)
    where = os.fspath(path)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as z:
        z.writestr(MANIFEST, json.dumps(manifest, indent=1, allow_nan=False))
        for name, arr in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, arr, allow_pickle=False)
            z.writestr(f"{name}.npy", member.getvalue())
    data = buf.getvalue()
    if len(data) > SAVE_CAP:
        raise SaveError(f"{where}: the save would be {len(data)} bytes, over the {SAVE_CAP >> 20} MiB cap")
    with PartFile(where, overwrite=overwrite, what="save", mode="wb") as f:
        f.write(data)
    return where


# -- reading -------------------------------------------------------------------------------------------

class SaveFile:
    """A save read and checked: ``manifest`` (dict) and ``array(name)``; every error names ``path``."""

    def __init__(self, path):
        self.path = os.fspath(path)
        raw = read_bytes_capped(self.path, SAVE_CAP, "save")
        try:
            self._zip = zipfile.ZipFile(io.BytesIO(raw))
            infos = self._zip.infolist()
        except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, EOFError) as e:
            raise SaveError(f"{self.path}: not a driftframe save (not a complete zip file: {e})") from None
        if sum(i.file_size for i in infos) > SAVE_CAP:
            raise SaveError(f"{self.path}: its members unpack to more than the {SAVE_CAP >> 20} MiB cap")
        self.members = {i.filename for i in infos}
        if MANIFEST not in self.members:
            raise SaveError(f"{self.path}: not a driftframe save (no {MANIFEST} member; members: "
                            f"{', '.join(sorted(self.members)[:5]) or 'none'})")
        try:
            m = json.loads(self._read(MANIFEST).decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            raise SaveError(f"{self.path}: member {MANIFEST} is not JSON ({e})") from None
        if not isinstance(m, dict) or m.get("format") != FORMAT:
            raise SaveError(f"{self.path}: field 'format' is {m.get('format') if isinstance(m, dict) else m!r}, "
                            f"not {FORMAT!r}: not a driftframe save")
        if m.get("format_version") != FORMAT_VERSION:
            raise SaveError(f"{self.path}: field 'format_version': save format {m.get('format_version')!r} "
                            f"written by driftframe {m.get('driftframe_version')}; this is driftframe "
                            f"{__version__}, which reads save format {FORMAT_VERSION}")
        self.manifest = m
        need = {"dt": (dict, float, int), "step_count": int, "next_entity": int, "entities": list,
                "columnar": dict, "plain": dict, "resources": dict, "systems": dict, "subscriptions": list}
        for key, kind in need.items():
            if key not in m:
                raise SaveError(f"{self.path}: field {key!r} is missing from {MANIFEST}")
            if not isinstance(m[key], kind) or isinstance(m[key], bool):
                raise SaveError(f"{self.path}: field {key!r} is a {type(m[key]).__name__}, not what a save holds")

    def _read(self, member: str) -> bytes:
        try:
            return self._zip.read(member)
        except KeyError:
            raise SaveError(f"{self.path}: member {member!r} is missing") from None
        except (zipfile.BadZipFile, EOFError, ValueError, OSError) as e:
            raise SaveError(f"{self.path}: member {member!r} is damaged ({e})") from None

    def array(self, name: str, dtype=None, shape=None) -> np.ndarray:
        """Array member ``name`` (``.npy``, no pickle), checked against ``dtype`` and per-row ``shape``."""
        raw = self._read(f"{name}.npy")
        try:
            arr = np.lib.format.read_array(io.BytesIO(raw), allow_pickle=False)
        except (ValueError, EOFError, OSError) as e:
            raise SaveError(f"{self.path}: member {name + '.npy'!r} is not a numpy array ({e})") from None
        if dtype is not None and arr.dtype != np.dtype(dtype):
            raise SaveError(f"{self.path}: field {name!r} has dtype {arr.dtype}, expected {np.dtype(dtype)}")
        if shape is not None and arr.shape[1:] != tuple(shape):
            raise SaveError(f"{self.path}: field {name!r} has rows of shape {arr.shape[1:]}, expected {tuple(shape)}")
        return arr


def _scene_build(save: SaveFile):
    scene = save.manifest.get("scene")
    if not isinstance(scene, dict) or not isinstance(scene.get("name"), str):
        raise SaveError(f"{save.path}: field 'scene' names no scene to rebuild (a world not made by make_world): "
                        "pass build= (a function returning the world with its systems)")
    if scene.get("track"):
        raise SaveError(f"{save.path}: field 'scene': the world flew its own track; pass build= to rebuild it")

    # the builder is the shell's make_world, named in the save by make_world itself (the framework does not
    # import the floors above it); only driftframe's own functions are called from a file
    mod_name, _, func = str(scene.get("builder", "")).partition(":")
    if not (mod_name == "driftframe" or mod_name.startswith("driftframe.")) or not func:
        raise SaveError(f"{save.path}: field 'scene': builder {scene.get('builder')!r} is not one of driftframe's; "
                        "pass build=")
    try:
        make = getattr(importlib.import_module(mod_name), func)
    except (ImportError, AttributeError) as e:
        raise SaveError(f"{save.path}: field 'scene': builder {scene['builder']!r} not found ({e})") from None

    def build():
        made = make(scene["name"], seed=int(scene.get("seed", 0)), scripted=bool(scene.get("scripted", True)),
                    collision=scene.get("collision", "continuous"))
        return made[0] if isinstance(made, tuple) else made
    return build


def load(path, build=None):
    """The world saved in ``path``, rebuilt and restored (see the module's text): ``build()`` returns the
    world with its systems (default: ``make_world`` of the scene the save names)."""
    save = SaveFile(path)
    if build is None:
        build = _scene_build(save)
    world = build()
    try:
        restore(world, save)
    except BaseException:
        world.close()
        raise
    return world


def restore(world, save) -> None:
    """Replace ``world``'s entities, step count, resources and systems' state with those of ``save`` (a
    path or a :class:`SaveFile`). ``world`` has the scene's systems (a rebuild, or the world a window
    plays: quick-load)."""
    if not isinstance(save, SaveFile):
        save = SaveFile(save)
    m, where = save.manifest, save.path
    dt = decode(m["dt"], f"{where}: field 'dt'")
    if dt != world.dt:
        raise SaveError(f"{where}: field 'dt' is {validate.shown(dt)} s;"
                        f" the rebuilt world steps {validate.shown(world.dt)} s")
    mine, theirs = _recipe(world), m.get("scene")
    if isinstance(mine, dict) and isinstance(theirs, dict) and mine.get("name") != theirs.get("name"):
        raise SaveError(f"{where}: field 'scene' is {theirs.get('name')!r}; this world is {mine.get('name')!r}")
    subs = _subscriptions(world)
    if [list(s) for s in m["subscriptions"]] != subs:
        raise SaveError(f"{where}: field 'subscriptions' names {m['subscriptions']}; the rebuilt world has {subs}")
    systems = dict(_systems(world))
    for name in m["systems"]:
        if name not in systems or not callable(getattr(systems[name], "restore", None)):
            raise SaveError(f"{where}: field 'systems': the save has the state of system {name!r}, which the "
                            f"rebuilt world lacks (systems: {', '.join(systems)})")
    for name, system in systems.items():
        if callable(getattr(system, "state", None)) and callable(getattr(system, "restore", None)) \
                and name not in m["systems"]:
            raise SaveError(f"{where}: field 'systems': no state of system {name!r}")
    ents = m["entities"]
    if not all(type(e) is int and e > 0 for e in ents) or len(set(ents)) != len(ents):
        raise SaveError(f"{where}: field 'entities' must be distinct positive entity ids")
    if m["next_entity"] <= max(ents, default=0):
        raise SaveError(f"{where}: field 'next_entity' ({m['next_entity']}) is not above every entity id")
    saved_ents = save.array("entities", np.int64)
    if saved_ents.tolist() != ents:
        raise SaveError(f"{where}: field 'entities' differs between {MANIFEST} and entities.npy")
    per_entity: dict[int, list] = {e: [] for e in ents}

    def _owner(e, field):
        if e not in per_entity:
            raise SaveError(f"{where}: field {field!r} names entity {e}, which is not in field 'entities'")
        return per_entity[e]

    # columnar components: one validated block per class (the error names the field and the first bad row)
    for path, layout in m["columnar"].items():
        cls = _find_class(path, f"{where}: field 'columnar/{path}'")
        if not issubclass(cls, Columnar):
            raise SaveError(f"{where}: field 'columnar/{path}' is not a columnar component class")
        if not isinstance(layout, dict) or set(layout) != set(cls._fields):
            got = sorted(layout) if isinstance(layout, dict) else layout
            odd = sorted(set(got) ^ set(cls._fields)) if isinstance(layout, dict) else ["?"]
            raise SaveError(f"{where}: field 'columnar/{path}': {cls.__name__} has fields {list(cls._fields)}, "
                            f"the save has {got} (field {odd[0]!r})")
        key = f"columns/{path}"
        holders = save.array(f"{key}/entities", np.int64, ())
        cols = {}
        for name, f in cls._fields.items():
            spec = layout[name]
            if spec != {"dtype": f.dtype.str, "shape": list(f.shape)}:
                raise SaveError(f"{where}: field '{key}/{name}' is {spec}, {cls.__name__}.{name} is "
                                f"{{'dtype': {f.dtype.str!r}, 'shape': {list(f.shape)}}}")
            col = save.array(f"{key}/{name}", f.dtype, f.shape)
            if len(col) != len(holders):
                raise SaveError(f"{where}: field '{key}/{name}' has {len(col)} rows for {len(holders)} entities")
            cols[name] = col
        try:
            comps = cls.bulk(len(holders), **cols)
        except (ValueError, TypeError) as e:
            raise SaveError(f"{where}: field '{key}': {e}") from None
        for e, c in zip(holders.tolist(), comps):
            _owner(e, f"{key}/entities").append(c)
    for path, rows in m["plain"].items():
        for k, row in enumerate(rows if isinstance(rows, list) else [None]):
            if not (isinstance(row, list) and len(row) == 2 and type(row[0]) is int):
                raise SaveError(f"{where}: field 'plain/{path}' row {k} is not [entity, value]")
            comp = decode(row[1], f"{where}: field 'plain/{path}' of entity {row[0]}")
            if _class_path(type(comp)) != path:
                raise SaveError(f"{where}: field 'plain/{path}' of entity {row[0]} holds a {_class_path(type(comp))}")
            _owner(row[0], f"plain/{path}").append(comp)
    resources = {k: decode(v, f"{where}: field 'resources/{k}'") for k, v in m["resources"].items()}
    if isinstance(resources.get("seed"), int):      # a save from before Seed was a type: its "seed" is a Seed
        resources[Seed] = Seed(resources.pop("seed"))
    typed = m.get("typed_resources", {})            # (absent in the saves written before type keys: none)
    if not isinstance(typed, dict):
        raise SaveError(f"{where}: field 'typed_resources' is a {type(typed).__name__}, not what a save holds")
    for path, v in typed.items():
        key = _find_class(path, f"{where}: field 'typed_resources/{path}'")
        value = decode(v, f"{where}: field 'typed_resources/{path}'")
        if not isinstance(value, key):
            raise SaveError(f"{where}: field 'typed_resources/{path}' holds a {_class_path(type(value))}")
        resources[key] = value
    states = {k: decode(v, f"{where}: field 'systems/{k}'") for k, v in m["systems"].items()}

    # all read and checked: now the world changes (the rebuilt entities go, the saved ones come with their ids)
    world.activate()
    world.sync()
    for table in world._tables.values():          # every row freed at once (one by one: 0.4 s of 3000 bodies)
        table.detach_all()
    ea.delete_all_entities()
    world._own_change()
    ea.create_with_ids(((e, per_entity[e]) for e in ents), m["next_entity"])
    world.sync()
    world.step_count = m["step_count"]
    world.events, world.previous_events = [], []
    world.resources.update(resources)
    for name, state in states.items():
        systems[name].restore(state)
    world.epoch += 1
    world.broken = world._broken_by = None           # whole again: the saved state replaced the half-stepped one
