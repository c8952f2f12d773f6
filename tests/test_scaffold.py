"""`driftframe new NAME` (issue 23): a game folder that plays, records and passes its own tests as written."""
import os
import subprocess
import sys

import pytest

from driftframe.scaffold import FILES


def _cli(cwd, *args, timeout=600):
    return subprocess.run([sys.executable, "-m", "driftframe", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, env=os.environ.copy())


@pytest.mark.gl
@pytest.mark.slow
def test_new_writes_a_game_that_tests_and_records_at_once(tmp_path):
    r = _cli(tmp_path, "new", "rockfield")
    assert r.returncode == 0, r.stderr
    game = tmp_path / "rockfield"
    written = sorted(str(p.relative_to(game)) for p in game.rglob("*") if p.is_file())
    assert written == sorted(k.format(name="rockfield") for k in FILES)
    for must in ("pyproject.toml", "rockfield/scene.py", "rockfield/components.py", "rockfield/systems.py",
                 "tests/test_scene.py"):
        assert (game / must).stat().st_size > 0
    assert 'name = "rockfield"' in (game / "pyproject.toml").read_text()
    # its own tests, with pytest, in a process of their own
    t = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"], cwd=game,
                       capture_output=True, text=True, timeout=600)
    assert t.returncode == 0, t.stdout[-3000:] + t.stderr[-2000:]
    assert "2 passed" in t.stdout
    # one second of it, flown by its SCRIPT
    r = _cli(game, "record", "rockfield.scene:build", "--seconds", "1", "--size", "320x180", "-o", "one.mp4",
             "--quiet")
    assert r.returncode == 0, r.stderr
    assert "60 frames" in r.stdout and (game / "one.mp4").stat().st_size > 1000


def test_new_refuses_an_existing_folder_and_a_bad_name(tmp_path):
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "mine.txt").write_text("keep")
    r = _cli(tmp_path, "new", "taken")
    assert r.returncode == 2
    assert r.stderr.strip() == "driftframe: error: 'taken' exists already; `driftframe new` writes a new folder only"
    assert os.listdir(tmp_path / "taken") == ["mine.txt"]
    for bad, why in (("my-game", "is not a valid Python identifier"), ("2fast", "is not a valid Python identifier"),
                     ("class", "is a Python keyword"), ("numpy", "would hide the module")):
        r = _cli(tmp_path, "new", bad)
        assert r.returncode == 2 and r.stderr.startswith(f"driftframe: error: {bad!r} ") and why in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1
        assert not (tmp_path / bad).exists()
