"""driftframe installs like a library: a pure-Python wheel, a non-editable install that runs read-only, and
an uninstall that leaves nothing behind."""
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PY = sys.executable


def _run(cmd, **kw):
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300, **kw)
    assert res.returncode == 0, (cmd, res.stdout[-2000:], res.stderr[-2000:])
    return res


def _source(tmp: Path) -> Path:
    """The files git tracks, copied as a fresh clone has them: setuptools builds in the tree's build/, and a
    build/lib left there by an earlier build (of modules since moved or deleted) would go into the wheel."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                            capture_output=True, timeout=60)
    if listed.returncode != 0:
        return ROOT                                     # not a git checkout (an unpacked sdist): as it is
    src = tmp / "src"
    for name in listed.stdout.decode().split("\0"):
        if name and (ROOT / name).is_file():
            dest = src / name
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, dest)
    return src


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheel")
    src = _source(tmp_path_factory.mktemp("tree"))
    # no build isolation: setuptools from the test extra, so the build needs no network
    _run([PY, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "--disable-pip-version-check",
          "-w", str(out), str(src)], cwd=out)
    (whl,) = out.glob("driftframe-*.whl")
    return whl


def test_the_wheel_is_pure_python_and_holds_the_package_and_nothing_else(wheel):
    assert wheel.name.endswith("-py3-none-any.whl"), wheel.name          # pure Python: one wheel for all
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        meta = next(n for n in names if n.endswith(".dist-info/METADATA"))
        metadata = z.read(meta).decode()
        entry = z.read(next(n for n in names if n.endswith(".dist-info/entry_points.txt"))).decode()
    files = [n for n in names if ".dist-info/" not in n]
    assert "driftframe/py.typed" in files                                    # PEP 561: annotations are read
    # every module of the package's five folders is in the wheel, and nothing else from the repository
    expected = {f"driftframe/{p.name}" for p in (ROOT / "driftframe").glob("*.py")}
    for sub in ("framework", "components", "systems", "demos"):         # the folders mapped to subpackages
        expected |= {f"driftframe/{sub}/{p.relative_to(ROOT / sub).as_posix()}" for p in (ROOT / sub).rglob("*.py")}
    assert expected <= set(files), sorted(expected - set(files))[:5]
    assert set(files) - expected == {"driftframe/py.typed", "driftframe/framework/fonts/DejaVuSans-HUD.ttf",
                                     "driftframe/framework/fonts/LICENSE.txt"}, sorted(set(files) - expected)[:5]
    assert not [n for n in names if "__pycache__" in n or n.endswith((".pyc", ".so"))
                or n.split("/")[0] in ("tests", "benchmarks", "docs")]
    assert "Requires-Dist: numba" in metadata and "Requires-Python: >=3.11" in metadata
    assert "driftframe = driftframe.__main__:run" in entry


@pytest.mark.gl
@pytest.mark.slow
def test_a_non_editable_install_records_read_only_and_uninstalls_without_a_trace(wheel, tmp_path):
    venv = tmp_path / "venv"
    # a fresh venv without pip (fast); the installed dependencies come from this venv's site-packages
    # through a .pth, appended after the new venv's own site-packages, so the test needs no network
    _run([PY, "-m", "venv", "--without-pip", str(venv)])
    vpy = venv / "bin" / "python"
    site = Path(_run([str(vpy), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"]).stdout.strip())
    (site / "deps.pth").write_text(sysconfig.get_path("purelib") + "\n")
    pip = [PY, "-m", "pip", "--python", str(vpy), "--disable-pip-version-check"]
    _run(pip + ["install", "-q", "--no-deps", "--no-index", str(wheel)])
    pkg = site / "driftframe"
    assert (pkg / "py.typed").is_file() and (pkg / "framework" / "world.py").is_file()
    before = sorted(p for p in site.rglob("*") if "driftframe" in p.relative_to(site).parts[0])
    home = tmp_path / "home"
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME", "PYTHONPATH", "VIRTUAL_ENV")}
    env.update(HOME=str(home), PYTHONDONTWRITEBYTECODE="1")
    for p in [pkg, *pkg.rglob("*")]:
        p.chmod(p.stat().st_mode & ~0o222)                                 # read-only (root may still write)
    try:
        out = tmp_path / "spin.gif"
        res = _run([str(venv / "bin" / "driftframe"), "record", "spin", "--seconds", "0.5", "--size", "160x90",
                    "--quiet", "-o", str(out)], env=env, cwd=tmp_path)
        assert out.stat().st_size > 0, res.stderr
        where = _run([str(vpy), "-c", "import driftframe; print(driftframe.__file__)"], env=env, cwd=tmp_path)
        assert where.stdout.strip() == str(pkg / "__init__.py")           # the installed copy, not the clone
        # nothing written into the package (root ignores the mode bits: compared file by file); the
        # compiled kernels went to the per-user cache under HOME
        assert sorted(p for p in site.rglob("*") if "driftframe" in p.relative_to(site).parts[0]) == before
        assert list((home / ".cache" / "driftframe" / "kernels").rglob("*.nbi"))
    finally:
        for p in [pkg, *pkg.rglob("*")]:
            p.chmod(p.stat().st_mode | 0o200)
    _run(pip + ["uninstall", "-q", "-y", "driftframe"])
    left = [p.name for p in site.iterdir() if "driftframe" in p.name.lower()]
    assert left == [] and not (venv / "bin" / "driftframe").exists(), left
    shutil.rmtree(venv)
