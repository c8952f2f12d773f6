"""One import package, layered floors, and a user's game with its own components.py / systems.py."""
import ast
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: Floors, bottom up: a module may import its own floor or those below, never one above.
FLOORS = {"framework": 0, "components": 1, "systems": 2, "demos": 3, "shell": 4}
FOLDERS = {"framework": "framework", "components": "components", "systems": "systems", "demos": "demos",
           "shell": "driftframe"}


def _floor_of_import(name: str):
    parts = name.split(".")
    if parts[0] in FLOORS and parts[0] != "shell":
        return "bare:" + parts[0]                       # a generic top-level name: never allowed
    if parts[0] != "driftframe":
        return None
    if len(parts) == 1:
        return "shell"
    return parts[1] if parts[1] in FLOORS else "shell"


def _imports(path: Path):
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):                         # lazy imports inside functions count too
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.lineno, node.module
            if node.module == "driftframe":
                for a in node.names:
                    yield node.lineno, f"driftframe.{a.name}"


def test_no_module_imports_a_floor_above_its_own():
    bad = []
    for floor, folder in FOLDERS.items():
        for path in sorted((ROOT / folder).glob("*.py")):
            for line, name in _imports(path):
                target = _floor_of_import(name)
                if target is None:
                    continue
                if target.startswith("bare:"):
                    bad.append(f"{path.relative_to(ROOT)}:{line} imports the bare name {name!r}")
                elif FLOORS[target] > FLOORS[floor]:
                    bad.append(f"{path.relative_to(ROOT)}:{line} ({floor}) imports {name} ({target})")
    assert bad == []


@pytest.mark.slow
def test_the_built_wheel_installs_one_top_level_package(tmp_path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(tmp_path), str(ROOT)],
                   check=True, capture_output=True, timeout=300)
    wheel = next(tmp_path.glob("driftframe-*.whl"))
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        top = {n.split("/")[0] for n in names if not n.split("/")[0].endswith((".dist-info", ".data"))}
        top_level = [n for n in names if n.endswith("top_level.txt")]
        listed = z.read(top_level[0]).decode().split() if top_level else sorted(top)
    assert top == {"driftframe"} and listed == ["driftframe"]
    for sub in ("framework/world.py", "components/body.py", "systems/collision.py", "demos/asteroids.py",
                "cli.py"):
        assert f"driftframe/{sub}" in names


GAME = {
    "components.py": '''
        from dataclasses import dataclass

        @dataclass
        class Health:
            points: int = 3
    ''',
    "systems.py": '''
        import esper
        from driftframe import CollisionEvent
        from components import Health

        class DamageSystem(esper.Processor):
            reads = (Health,)
            writes = (Health,)

            def __init__(self):
                self.hits = []

            def process(self, dt):
                for ev in self.world.events:
                    if isinstance(ev, CollisionEvent) and ev.step == self.world.step_count:
                        for e in (ev.a, ev.b):
                            esper.component_for_entity(e, Health).points -= 1
                            self.hits.append(e)
    ''',
    "framework.py": '''
        GAME_NAME = "shadowing test"
    ''',
    "main.py": '''
        import sys
        import framework, components, systems            # the game's own modules, not driftframe's
        from driftframe import (Camera, CollisionSystem, ModelRef, MovementSystem, SphereCollider,
                                Transform, Velocity, World)
        from driftframe.app import attach_rendering
        from driftframe.framework.recorder import record

        world = World()
        world.add_system(MovementSystem())
        world.add_system(CollisionSystem())
        damage = world.add_system(systems.DamageSystem(), after="collision")
        a = world.create_entity(Transform((-3, 0, 0)), Velocity((2, 0, 0)), SphereCollider(1.0),
                                ModelRef("sphere"), components.Health())
        b = world.create_entity(Transform((3, 0, 0)), Velocity((-2, 0, 0)), SphereCollider(1.0),
                                ModelRef("sphere"), components.Health())
        world.create_entity(Camera(target=a, mode="chase", chase_distance=12.0))
        attach_rendering(world, size=(64, 48), hud=False)
        res = record(world, sys.argv[1], frames=90, fps=60, steps_per_frame=1, progress=False)
        import esper
        print(framework.GAME_NAME, res.frames, sorted(damage.hits),
              esper.component_for_entity(a, components.Health).points)
    ''',
}


@pytest.mark.gl
@pytest.mark.slow
def test_a_game_with_its_own_components_systems_and_framework_modules_runs(tmp_path):
    game = tmp_path / "game"
    game.mkdir()
    for name, src in GAME.items():
        (game / name).write_text(textwrap.dedent(src))
    out = tmp_path / "clip.gif"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([sys.executable, "main.py", str(out)], cwd=game, capture_output=True, text=True,
                          timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["shadowing", "test", "90", "[1,", "2]", "2"]
    assert out.stat().st_size > 0
