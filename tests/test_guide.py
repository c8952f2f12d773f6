"""docs/GUIDE.md runs as printed: every Python block, pasted as a user would, in an empty folder, twice.

Each section's blocks run in order as one program (a block may use the names an earlier block of its
section defined), in a new folder that holds what the guide tells the user to make first: ``first.py``,
the first program (``Composing a scene``; its own run, twice, and its command line are
``tests/test_own_scene.py``'s). A block whose first line is ``# path/to/file.py`` is a file the user
saves there, not a program. A section that opens a window runs under Xvfb, and the test presses Esc
once the window is up, as the user would. The second run must pass too: a rerun is what a user does
after editing a line, and an example that refuses its own earlier output fails it.
"""
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / "docs" / "GUIDE.md"
FIRST = "Composing a scene"


def sections() -> dict[str, list[str]]:
    """Section title -> its Python blocks, in order (sections without one left out)."""
    out: dict[str, list[str]] = {}
    title = None
    for m in re.finditer(r"^## ([^\n]+)$|^```python\n(.*?)^```$", GUIDE.read_text(), re.M | re.S):
        if m.group(1):
            title = m.group(1).strip()
        else:
            out.setdefault(title, []).append(m.group(2))
    return out


SECTIONS = sections()
RUNNABLE = [t for t in SECTIONS if t != FIRST]


def test_the_guide_has_the_blocks_this_test_runs():
    assert FIRST in SECTIONS and len(SECTIONS[FIRST]) == 1
    assert sum(len(SECTIONS[t]) for t in RUNNABLE) >= 15       # every other block runs below


def _folder(tmp_path: Path, title: str) -> tuple[Path, str]:
    """The user's folder for a section: first.py, the section's files, and its program."""
    (tmp_path / "first.py").write_text(SECTIONS[FIRST][0])
    program = []
    for block in SECTIONS[title]:
        head = block.splitlines()[0]
        path = re.fullmatch(r"# ([\w/]+\.py)", head.strip())
        if path:
            dest = tmp_path / path.group(1)
            dest.parent.mkdir(parents=True, exist_ok=True)
            dest.write_text(block)
        else:
            program.append(block)
    if "assets/rock.glb" in "".join(program):                  # the user's own model file
        trimesh = pytest.importorskip("trimesh", reason="the assets extra (./run tests installs it)")
        (tmp_path / "assets").mkdir()
        trimesh.creation.icosphere(subdivisions=2, radius=1.0).export(tmp_path / "assets" / "rock.glb")
    return tmp_path, "\n\n".join(program)


def _press_esc_when_the_window_is_up(proc, display):
    def xdo(*args):
        return subprocess.run(["xdotool", *args], env={**os.environ, "DISPLAY": display}, capture_output=True,
                              text=True, timeout=30)
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:
        wid = xdo("search", "--name", "driftframe").stdout.split()
        if wid:
            time.sleep(1.0)                                      # it flies a moment
            xdo("windowfocus", "--sync", wid[0])
            xdo("key", "--window", wid[0], "Escape")
            return
        time.sleep(0.2)


@pytest.mark.gl
@pytest.mark.parametrize("title", RUNNABLE)
def test_every_block_of_the_section_runs_as_printed_twice(title, tmp_path):
    cwd, program = _folder(tmp_path, title)
    (cwd / "section.py").write_text(program)
    window = "df.play(" in program
    env = dict(os.environ)
    server = None
    if window:
        if not (shutil.which("Xvfb") and shutil.which("xdotool")):
            pytest.fail("window tests need Xvfb and xdotool: `./run tests` installs them")
        from driftframe.xvfb import virtual_display
        server = virtual_display((1280, 720))
        env["DISPLAY"] = server.__enter__()
    try:
        for run in (1, 2):
            proc = subprocess.Popen([sys.executable, "section.py"], cwd=cwd, env=env, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True)
            if window:
                _press_esc_when_the_window_is_up(proc, env["DISPLAY"])
            out, err = proc.communicate(timeout=300)
            assert proc.returncode == 0, f"run {run} of '{title}':\n{err[-3000:]}"
            assert "Traceback" not in err, err[-3000:]
    finally:
        if server is not None:
            server.__exit__(None, None, None)
