"""``driftframe new NAME``: a small game folder in the usual shape of a Python project.

::

    NAME/
        pyproject.toml          the game as a package (``pip install -e .``), driftframe as its dependency
        README.md               how to play, record and test it
        NAME/__init__.py
        NAME/scene.py           build(world, rng): the scene (``driftframe play NAME.scene:build``)
        NAME/components.py      the game's own components (plain data)
        NAME/systems.py         the game's own systems (one example, scheduled by the scene)
        tests/test_scene.py     pytest: the scene builds and steps, the example system does its job

It plays, records and passes its own tests as written (tests/test_scaffold.py
checks all three). The files are the templates below with ``{name}`` filled
in; nothing is written when the folder exists or ``NAME`` is not a Python
identifier.
"""
from __future__ import annotations

import keyword
import os
from pathlib import Path

from driftframe.framework import __version__


class ScaffoldError(ValueError):
    """``driftframe new`` cannot write the folder asked for: one line naming the name or the folder."""


PYPROJECT = '''\
[build-system]
requires = ["setuptools>=68"]
build-backend = "setuptools.build_meta"

[project]
name = "{name}"
version = "0.1.0"
description = "A space-flight game built on driftframe."
requires-python = ">=3.11"
dependencies = ["driftframe>={version}"]

[project.optional-dependencies]
test = ["pytest>=8"]

[tool.setuptools]
packages = ["{name}"]

[tool.pytest.ini_options]
testpaths = ["tests"]
pythonpath = ["."]
'''

README = '''\
# {name}

A driftframe game. From this folder:

    driftframe play {name}.scene:build                  # fly it: W/S thrust, arrows turn, C camera, Esc quits
    driftframe play {name}.scene:build --save-track flight.json
    driftframe record {name}.scene:build --track flight.json -o out/flight.mp4
    driftframe record {name}.scene:build -o out/{name}.mp4     # the scene's own SCRIPT, off-screen
    python -m pytest                                           # tests/

`{name}/scene.py` builds the scene; `{name}/components.py` and
`{name}/systems.py` are your own components and systems.
'''

INIT = '''\
"""{name}: a driftframe game (`driftframe play {name}.scene:build`)."""
'''

COMPONENTS = '''\
"""{name}'s own components: plain data, no behaviour (that is in systems.py)."""
from dataclasses import dataclass


@dataclass
class Fenced:
    """Keep this body within ``radius`` metres of ``centre``: the :class:`~{name}.systems.FenceSystem`
    turns it back (reverses its outward velocity) when it crosses the fence."""

    radius: float = 60.0
    centre: tuple[float, float, float] = (0.0, 0.0, 90.0)
'''

SYSTEMS = '''\
"""{name}'s own systems. Each is an esper.Processor that says where it runs and what it touches."""
import esper
import numpy as np

import driftframe as df

from {name}.components import Fenced


class FenceSystem(esper.Processor):
    """Reads Fenced, Transform; writes Velocity.  A fenced body outside its fence that is moving outward
    gets its outward velocity reversed (an elastic bounce off the fence's sphere)."""

    reads = (Fenced, df.Transform)
    writes = (df.Velocity,)
    requires = (Fenced,)                     # not called while no entity is Fenced

    def process(self, dt: float) -> None:
        for ent, (fence, tf, vel) in esper.get_components(Fenced, df.Transform, df.Velocity):
            out = tf.position - np.asarray(fence.centre, float)
            dist = float(np.linalg.norm(out))
            if dist > fence.radius:
                n = out / dist
                v_out = float(vel.linear @ n)
                if v_out > 0:
                    vel.linear = vel.linear - 2.0 * v_out * n
'''

SCENE = '''\
"""{name}'s scene: a ship drifting at 5 m/s towards forty rocks held in by a fence.

    driftframe play {name}.scene:build          fly it with the keyboard
    driftframe record {name}.scene:build        record SECONDS of it, flown by SCRIPT
"""
import numpy as np

import driftframe as df

from {name}.components import Fenced
from {name}.systems import FenceSystem

TITLE = "{name}"
SECONDS = 10.0                              # `driftframe record`'s default length, s
# what `driftframe record` flies (play takes the keyboard instead): a burn, a turn and back
SCRIPT = df.Track((df.Hold(1.0, 2.0, throttle=1.0), df.Hold(3.0, 3.5, yaw=1.0), df.Hold(5.0, 5.5, yaw=-1.0)))


def build(world: df.World, rng: np.random.Generator) -> int:
    """The ship, a chase camera and forty fenced rocks; ``world`` has the standard systems already."""
    ship = world.create_entity(
        df.Player(), df.Transform((0, 0, 0), df.look_rotation((0, 0, 1))), df.Velocity((0, 0, 5.0)),
        df.AngularVelocity(), df.Acceleration(), df.Mass(10_000.0), df.SphereCollider(radius=1.0),
        df.ModelRef("ship"), df.FlightInput(), df.FlightControl(mode="momentum", thrust=6.0),
        df.RotationAssist(max_decel=2.0))
    world.create_entity(df.Camera(target=ship, mode="chase"))
    n = 40
    r = rng.uniform(0.5, 3.0, n)
    names = [df.declare_variant(world, f"rock_{{i}}", "sphere", scale=float(r[i])) for i in range(n)]
    world.create_entities(
        df.Transform.bulk(n, position=df.place(rng, r, df.in_shell(0.0, 40.0, centre=(0, 0, 90)), gap=0.5)),
        df.Velocity.bulk(n, linear=rng.normal(0, 1.5, (n, 3))),
        df.Mass.bulk(n, kg=2000 * 4 / 3 * np.pi * r**3),
        df.SphereCollider.bulk(n, radius=r),
        [df.ModelRef(name) for name in names],
        [Fenced(radius=60.0, centre=(0, 0, 90)) for _ in range(n)])
    world.add_system(FenceSystem(), after="commit")
    return ship
'''

TEST = '''\
"""{name}'s tests: run them with `python -m pytest` in this folder."""
import numpy as np

import driftframe as df

from {name}.components import Fenced
from {name}.scene import build
from {name}.systems import FenceSystem


def new_world() -> df.World:
    world = df.World(dt=1 / 60)
    for system in df.simulation_systems():
        world.add_system(system)
    return world


def test_the_scene_builds_and_steps() -> None:
    world = new_world()
    ship = build(world, np.random.default_rng(1))
    world.step(60)                                      # one simulated second
    z = world.columns(df.Transform, [ship]).position[0, 2]
    assert 4.9 < z < 5.1                                # drifting at 5 m/s, no input
    world.close()


def test_the_fence_turns_a_body_back() -> None:
    world = df.World(dt=0.1)
    world.add_system(df.MovementSystem())
    world.add_system(FenceSystem(), after="commit")
    rock = world.create_entity(df.Transform((0, 0, 0)), df.Velocity((10.0, 0, 0)),
                               Fenced(radius=20.0, centre=(0, 0, 0)))
    world.step(100)                                     # 10 s at 10 m/s: it would be 100 m out
    x = world.columns(df.Transform, [rock]).position[0, 0]
    assert abs(x) <= 21.0                               # turned back at the fence (one step's travel past it)
    world.close()
'''

#: path (with ``{name}``) -> template
FILES = {
    "pyproject.toml": PYPROJECT,
    "README.md": README,
    "{name}/__init__.py": INIT,
    "{name}/components.py": COMPONENTS,
    "{name}/systems.py": SYSTEMS,
    "{name}/scene.py": SCENE,
    "tests/test_scene.py": TEST,
}


def check_name(name: str) -> None:
    """A ScaffoldError unless ``name`` can be a Python package's name (an identifier, not a keyword, not
    one that would hide a module the game imports)."""
    if not isinstance(name, str) or not name.isidentifier() or not name.isascii():
        raise ScaffoldError(f"{name!r} is not a valid Python identifier (letters, digits and _, not starting "
                            "with a digit): the game's package is named after it")
    if keyword.iskeyword(name):
        raise ScaffoldError(f"{name!r} is a Python keyword; choose another name")
    if name in ("driftframe", "esper", "numpy", "numba", "moderngl", "glfw", "av", "tests", "test"):
        raise ScaffoldError(f"{name!r} would hide the module of that name; choose another name")


def new(name: str, where: str | os.PathLike = ".") -> Path:
    """Write the game folder ``where/name``; returns its path. Refuses an existing path (file or folder)."""
    check_name(name)
    root = Path(where) / name
    if os.path.lexists(root):
        raise ScaffoldError(f"{str(root)!r} exists already; `driftframe new` writes a new folder only")
    if not Path(where).is_dir():
        raise ScaffoldError(f"{str(where)!r} is not a folder")
    root.mkdir()
    for rel, text in FILES.items():
        path = root / rel.format(name=name)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text.format(name=name, version=__version__))
    return root
