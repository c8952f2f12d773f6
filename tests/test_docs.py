"""The API reference: generated from the docstrings by ``./run docs`` (mkdocs + mkdocstrings), without a warning."""
import ast
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import driftframe

ROOT = Path(__file__).resolve().parent.parent


def _homes() -> dict[str, str]:
    tree = ast.parse((ROOT / "driftframe" / "__init__.py").read_text())
    (homes,) = [ast.literal_eval(n.value) for n in tree.body
                if isinstance(n, ast.Assign) and getattr(n.targets[0], "id", None) == "_HOMES"]
    return homes


def test_every_public_name_has_one_entry_in_the_api_pages_at_its_home():
    entries = [m for page in sorted((ROOT / "docs" / "api").glob("*.md"))
               for m in re.findall(r"^::: (\S+)$", page.read_text(), re.M)]
    want = sorted(f"driftframe.{home}.{name}" for name, home in _homes().items())
    assert sorted(entries) == want
    assert set(_homes()) == set(driftframe.__all__) - {"__version__"}


def test_the_reference_builds_strict_without_a_warning(tmp_path):
    # as on a fresh clone: no source tree from an earlier build (the hook must lay it out before mkdocstrings
    # reads its paths; with a stale one left here, a fresh clone's first build failed and this test passed)
    shutil.rmtree(ROOT / "build" / "docs-src", ignore_errors=True)
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
                         cwd=ROOT, capture_output=True, text=True, timeout=120, env=env)
    log = res.stdout + res.stderr
    assert res.returncode == 0, log[-3000:]
    assert "WARNING" not in log and "ERROR" not in log, log[-3000:]
    # every public name got its own section (mkdocstrings' anchor is the full path), with its docstring
    html = "".join(p.read_text() for p in (tmp_path / "site" / "api").rglob("index.html"))
    missing = [f"{home}.{name}" for name, home in _homes().items() if f'id="driftframe.{home}.{name}"' not in html]
    assert missing == []
    assert 'id="driftframe.framework.world.World.add_system"' in html                # methods too
    assert "Centre of mass, world frame, m." in html                  # Transform.position's Field(doc)
    assert "Position of the centre of mass and the body" in html      # Transform's docstring
