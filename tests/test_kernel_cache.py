"""The kernel cache (framework.kernels): where it lives, what invalidates it, damage, faults, warm-up.

Each test runs its kernels in a fresh process with its own cache folder: numba keeps what it compiled
for the life of a process, and the folder is chosen when a kernel module is imported.
"""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import pytest

from driftframe.framework import kernels

ROOT = Path(__file__).resolve().parent.parent
PY = sys.executable
EXE = [PY, "-m", "driftframe"]
# a 4x4 RGBA frame through the one-kernel NV12 converter: the cheapest kernel to compile (about 1 s)
NV12 = ("import numpy as np; from driftframe.framework.yuv import rgba_to_nv12, _nv12; "
        "print(rgba_to_nv12(np.arange(64, dtype=np.uint8).reshape(4, 4, 4), 4, 4).sum(), "
        "sum(_nv12.stats.cache_misses.values()))")


def _env(**extra):
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
    env.update({k: str(v) for k, v in extra.items() if v is not None})
    return env


def _py(code, *, env, timeout=300):
    # run outside the repository: ``-c`` puts the current folder first on sys.path, where driftframe/ is
    # the source folder and not the installed package
    return subprocess.run([PY, "-c", code], capture_output=True, text=True, env=env, cwd=tempfile.gettempdir(),
                          timeout=timeout)


def _nv12(env):
    res = _py(NV12, env=env)
    assert res.returncode == 0, res.stderr
    total, compiled = res.stdout.split()
    return int(total), int(compiled), res.stderr


# -- what keys the cache ----------------------------------------------------------------------------------
def _package_sources():
    for folder in ("driftframe", "framework", "components", "systems", "demos"):
        yield from (ROOT / folder).glob("*.py")


def test_every_module_that_declares_a_kernel_is_in_the_cache_key_and_none_uses_numba_directly():
    declares = {p.stem for p in (ROOT / "framework").glob("*.py")
                if re.search(r"^@kernel\b", p.read_text(), re.M)}
    assert declares == set(kernels.KERNEL_MODULES)
    for p in _package_sources():          # njit(cache=True) would cache beside the sources, keyed by one file
        if p.name not in ("kernels.py", "kernel_cache.py"):
            assert not re.search(r"^\s*(from numba import|@(numba\.)?n?jit)", p.read_text(), re.M), p
    # a kernel module's compile-time globals from another driftframe module: that module is keyed too
    keyed = kernels.KERNEL_MODULES + kernels.KERNEL_IMPORTS
    for name in keyed:
        text = (ROOT / "framework" / f"{name}.py").read_text()
        for mod in re.findall(r"^from driftframe\.framework import (\w+)", text, re.M):
            assert mod in keyed, (name, mod)
        for mod in re.findall(r"^from driftframe\.framework\.(\w+) import", text, re.M):
            assert mod in keyed + ("kernels",), (name, mod)


def test_the_folder_is_per_user_keyed_by_version_and_sources_and_honours_numba_cache_dir(tmp_path):
    code = "from driftframe.framework import kernels; print(kernels.cache_dir())"
    key = f"{kernels.__version__}-{kernels.source_digest()}"
    xdg = _py(code, env=_env(XDG_CACHE_HOME=tmp_path / "xdg")).stdout.strip()
    assert xdg == str(tmp_path / "xdg" / "driftframe" / "kernels" / key)
    home = _py(code, env=_env(HOME=tmp_path / "home")).stdout.strip()
    assert home == str(tmp_path / "home" / ".cache" / "driftframe" / "kernels" / key)
    numba = _py(code, env=_env(NUMBA_CACHE_DIR=tmp_path / "nc", XDG_CACHE_HOME=tmp_path / "xdg")).stdout.strip()
    assert numba == str(tmp_path / "nc" / "driftframe" / key)
    # and numba's own setting is left as the user gave it
    res = _py("import numba; from driftframe.framework import yuv; print(numba.config.CACHE_DIR)",
              env=_env(NUMBA_CACHE_DIR=tmp_path / "nc"))
    assert res.stdout.strip() == str(tmp_path / "nc")


def _copy_package(dest: Path) -> Path:
    """driftframe/ and framework/ as an importable package under ``dest`` (enough for the kernel modules)."""
    pkg = dest / "driftframe"
    ignore = shutil.ignore_patterns("__pycache__")
    shutil.copytree(ROOT / "driftframe", pkg, ignore=ignore)
    shutil.copytree(ROOT / "framework", pkg / "framework", ignore=ignore)
    return pkg


@pytest.mark.slow
def test_editing_a_callee_in_another_file_changes_the_callers_result(tmp_path):
    # the bug: contact's kernel calls the neighbour list's; numba alone re-checks only the caller's own file
    pkg = _copy_package(tmp_path / "src")
    bp, contact = pkg / "framework" / "broadphase_list.py", pkg / "framework" / "contact_pairs.py"
    bp.write_text(bp.read_text() + "\n\n@kernel\ndef _probe_callee(x):\n    return x + 1\n")
    contact.write_text(contact.read_text() + "\n\n@kernel\ndef _probe(x):\n    return broadphase_list._probe_callee(x) * 10\n")
    env = _env(PYTHONPATH=tmp_path / "src", NUMBA_CACHE_DIR=tmp_path / "cache")
    code = ("import driftframe.framework.contact_pairs as c; assert c.__file__.startswith(%r); "
            "print(c._probe(1), sum(c._probe.stats.cache_hits.values()))" % str(tmp_path / "src"))
    first = _py(code, env=env)
    assert first.stdout.split() == ["20", "0"], first.stderr
    again = _py(code, env=env)
    assert again.stdout.split() == ["20", "1"], again.stderr          # loaded from the cache
    bp.write_text(bp.read_text().replace("return x + 1", "return x + 2"))
    edited = _py(code, env=env)
    assert edited.stdout.split() == ["30", "0"], edited.stderr        # the caller was compiled again


# -- faults -----------------------------------------------------------------------------------------------
def test_a_cache_folder_that_cannot_be_written_warns_once_and_the_run_goes_on(tmp_path):
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the cache folder would go")     # unwritable even for root
    total, compiled, err = _nv12(_env(NUMBA_CACHE_DIR=blocker))
    warm_total, _, _ = _nv12(_env(NUMBA_CACHE_DIR=tmp_path / "ok"))
    assert total == warm_total and compiled == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("driftframe: warning: cannot write the kernel cache folder "
                                                   f"{blocker}/driftframe/"), err
    assert "compiled in this process only" in lines[0]


def _cache_files(folder: Path, pattern: str) -> list[Path]:
    return sorted(folder.rglob(pattern))


@pytest.fixture(scope="module")
def nv12_cache(tmp_path_factory):
    """A cache folder holding the NV12 kernel, compiled and then loaded from it, that each damage case
    copies: one compile and one load for the four cases (each made its own: two processes, ~2 s of CPU)."""
    root = tmp_path_factory.mktemp("nv12") / "nc"
    env = _env(NUMBA_CACHE_DIR=root)
    total, compiled, _ = _nv12(env)
    assert compiled == 1 and _nv12(env)[1] == 0                      # cached, then loaded
    return root, total


@pytest.mark.parametrize("damage", ["flip a byte", "truncate", "empty", "garbage index"])
def test_a_damaged_cache_file_is_compiled_again_never_loaded(tmp_path, damage, nv12_cache):
    cached, total = nv12_cache
    shutil.copytree(cached, tmp_path / "nc")
    env = _env(NUMBA_CACHE_DIR=tmp_path / "nc")
    (data,) = _cache_files(tmp_path / "nc", "yuv._nv12-*.nbc")
    (index,) = _cache_files(tmp_path / "nc", "yuv._nv12-*.nbi")
    blob = data.read_bytes()
    if damage == "flip a byte":
        i = len(blob) // 2
        data.write_bytes(blob[:i] + bytes([blob[i] ^ 0x40]) + blob[i + 1:])
    elif damage == "truncate":
        data.write_bytes(blob[: len(blob) // 3])
    elif damage == "empty":
        data.write_bytes(b"")
    else:
        index.write_bytes(b"\x80\x04not a pickle at all")
    again_total, again_compiled, err = _nv12(env)
    assert (again_total, again_compiled) == (total, 1), err
    assert "Traceback" not in err
    assert _nv12(env)[1] == 0                                        # and the repaired entry is used


def test_numbas_runtime_helpers_load_from_the_cache_and_a_damaged_copy_is_made_again(tmp_path, nv12_cache):
    # numba builds its runtime's helpers (NRT) with LLVM in each process; they are cached beside the kernels
    # (kernel_cache.nrt_functions). Counted here: how often this process built them (create_nrt_module)
    cached, total = nv12_cache
    shutil.copytree(cached, tmp_path / "nc")
    env = _env(NUMBA_CACHE_DIR=tmp_path / "nc")
    (nrt,) = _cache_files(tmp_path / "nc", "nrt-*.bin")
    count = ("from numba.core.runtime import nrtdynmod; made = []; real = nrtdynmod.create_nrt_module; "
             "nrtdynmod.create_nrt_module = lambda ctx: made.append(1) or real(ctx); ")
    compile_one = ("; from driftframe.framework.kepler import _stumpff1 as f; "
                   "print(repr(f(np.float64(0.5))[0]), sum(f.stats.cache_misses.values()))")

    def run(extra=""):
        res = _py(count + NV12 + extra + "; print(len(made))", env=env)
        assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr
        return res.stdout.split()

    assert run() == [str(total), "0", "0"]                   # the kernel and the runtime, both from the cache
    # a kernel compiled in a process whose runtime came from the cache links it as a built one
    loaded = run(compile_one)
    assert loaded[:2] == [str(total), "0"] and loaded[3:] == ["1", "0"]
    shutil.rmtree(tmp_path / "nc")
    built = subprocess.run([PY, "-c", count + "import numpy as np" + compile_one + "; print(len(made))"],
                           capture_output=True, text=True, env=_env(NUMBA_CACHE_DIR=tmp_path / "fresh"),
                           cwd=tempfile.gettempdir(), timeout=300).stdout.split()
    assert built == [loaded[2], "1", "1"]                     # the same result with a runtime built here
    shutil.copytree(cached, tmp_path / "nc")
    blob = nrt.read_bytes()
    i = len(blob) // 2
    nrt.write_bytes(blob[:i] + bytes([blob[i] ^ 0x40]) + blob[i + 1:])
    assert run() == [str(total), "0", "1"]                   # a damaged copy: built as numba does, saved
    assert run() == [str(total), "0", "0"]                   # and the new copy is the one used


def test_an_entry_saved_under_another_key_is_not_loaded(tmp_path):
    # two processes numbering their entries alike (numba issue 4807): the index names a data file that
    # holds another signature's code. The entry keeps its own key, which must match.
    env = _env(NUMBA_CACHE_DIR=tmp_path / "nc")
    code = ("import numpy as np; from driftframe.framework.kepler import _stumpff1 as f; "
            "print(repr(f(np.float64(0.5))[0]), sum(f.stats.cache_misses.values()))")
    code_f32 = code.replace("np.float64(0.5)", "np.float32(0.5)")
    first = _py(code, env=env)
    assert first.returncode == 0 and first.stdout.split()[1] == "1", first.stderr
    second = _py(code_f32, env=env)                                    # a second signature: entry 2
    assert second.returncode == 0 and second.stdout.split()[1] == "1", second.stderr
    one, two = _cache_files(tmp_path / "nc", "kepler_kernels._stumpff1-*.nbc")
    one.write_bytes(two.read_bytes())                                 # entry 1 now holds entry 2's code
    again = _py(code, env=env)
    assert again.returncode == 0 and again.stdout.split() == [first.stdout.split()[0], "1"], again.stderr


def test_a_kernel_that_fails_to_compile_is_named(tmp_path):
    mod = tmp_path / "broken_kernels.py"
    mod.write_text("from driftframe.framework.kernels import kernel\n\n"
                   "@kernel\ndef helper(x):\n    return x.no_such_attribute\n\n"
                   "@kernel\ndef outer(x):\n    return helper(x) + 1\n")
    code = ("from driftframe.framework.kernels import CompileWatch, KernelCompileError\n"
            "import broken_kernels\n"
            "try:\n    with CompileWatch():\n        broken_kernels.outer(1.0)\n"
            "except KernelCompileError as e:\n    print(e)\n")
    res = _py(code, env=_env(NUMBA_CACHE_DIR=tmp_path / "nc", PYTHONPATH=tmp_path))
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("compiling kernel broken_kernels.helper failed: "), res.stdout


# -- installs ---------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_a_read_only_install_runs_and_uninstalling_leaves_nothing_in_site_packages(tmp_path):
    target = tmp_path / "site"
    res = subprocess.run([PY, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                          "--disable-pip-version-check", "--target", str(target), str(ROOT)],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    installed = {p for p in target.rglob("*") if p.is_file()}
    for p in [target, *target.rglob("*")]:
        p.chmod(p.stat().st_mode & ~0o222)                           # read-only (root still may write: checked below)
    try:
        env = _env(PYTHONPATH=target, XDG_CACHE_HOME=tmp_path / "xdg", PYTHONDONTWRITEBYTECODE=1)
        code = "import driftframe; assert driftframe.__file__.startswith(%r); " % str(target) + NV12
        res = _py(code, env=env)
        assert res.returncode == 0 and res.stdout.split()[1] == "1", res.stderr
        assert {p for p in target.rglob("*") if p.is_file()} == installed       # nothing written there
        assert _cache_files(tmp_path / "xdg" / "driftframe" / "kernels", "yuv._nv12-*.nbi")
        assert _py(code, env=env).stdout.split()[1] == "0"          # and the next run loads it
    finally:
        for p in [target, *target.rglob("*")]:
            p.chmod(p.stat().st_mode | 0o200)
    # what pip uninstall removes: the files listed in RECORD (and the .pyc of each listed .py)
    (record,) = target.glob("driftframe-*.dist-info/RECORD")
    listed = {(target / line.split(",")[0]).resolve() for line in record.read_text().splitlines() if line}
    left = [p for p in (target / "driftframe").rglob("*") if p.is_file() and p.resolve() not in listed]
    assert not left, left[:5]


def uncalled_kernels() -> list[str]:
    """Kernels named nowhere in the package but in their own ``def`` (no warm-up can reach them)."""
    # one pass over the sources, not two regular-expression searches per kernel (7 s of CPU): a name
    # counted as a whole word (what \bname\b finds) and as the word after 'def ' (\bdef name\b)
    text = "\n".join(p.read_text() for p in _package_sources())
    words, defined = Counter(re.findall(r"\w+", text)), Counter(re.findall(r"\bdef (\w+)", text))
    return [kernels.kernel_name(d) for d in kernels.registry()
            if words[d.py_func.__name__] <= defined[d.py_func.__name__]]


# -- driftframe warm --------------------------------------------------------------------------------------
def _seed_cache(root: Path, *leave: str) -> None:
    """This run's warm kernel cache copied into cache folder ``root``, less the kernels whose file names
    start with one of ``leave`` and the warm mark; nothing when this run has no warm cache."""
    warm = kernels.cache_dir()
    if warm.is_dir() and (warm / kernels.WARM_MARK).exists():
        seeded = root / "driftframe" / warm.name
        shutil.copytree(warm, seeded)
        for f in list(seeded.iterdir()):
            if f.name.startswith(leave) or f.name == kernels.WARM_MARK:
                f.unlink()


@pytest.mark.slow
def test_ctrl_c_during_warm_leaves_a_cache_the_next_warm_completes_and_uses(tmp_path):
    env = _env(NUMBA_CACHE_DIR=tmp_path / "nc")
    # a cache that lacks only the all-pairs solver (seconds to compile) and a small kernel, so that the
    # Ctrl-C lands in a compile without compiling every kernel twice (CPU time the whole suite pays)
    _seed_cache(tmp_path / "nc", "contact_solve.solve_all_pairs-", "contact_solve._shift-")
    proc = subprocess.Popen(EXE + ["warm"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    first = proc.stderr.readline()
    assert first.startswith("driftframe: compiling the physics kernels"), first
    # the Ctrl-C once the progress line shows a solver compiling (seconds of it; a fixed sleep could land
    # after the compile on a quiet machine): the line names the kernel numba is in, written as it begins
    seen = [first]
    while not re.search(r"compiling \d+ of \d+ kernels, \d+ s: .*contact_solve\.solve_", seen[-1]):
        seen.append(proc.stderr.readline())
        assert seen[-1].startswith("driftframe: compiling "), seen         # (not the end of the compile)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "s of compiling kernels" in err and "Traceback" not in err
    saved_before = len(_cache_files(tmp_path / "nc", "*.nbi"))
    total = len(kernels.registry())
    done = subprocess.run(EXE + ["warm"], capture_output=True, text=True, env=env, timeout=900)
    assert done.returncode == 0, done.stderr
    dead = uncalled_kernels()
    assert done.stdout.startswith(f"{total - len(dead)} of {total} kernels ready in "), (done.stdout, dead)
    if dead:
        assert f"did not reach {len(dead)} of {total} kernels ({', '.join(dead)})" in done.stderr
    progress = re.findall(r"compiling (\d+) of (\d+) kernels", done.stderr)
    n, m_ = map(int, progress[-1])
    # m: every kernel with nothing cached (those cached were loaded, not counted); n: those compiled
    assert n + len(dead) == m_ <= total - saved_before + 1, (progress[-1], saved_before, dead)
    assert not _cache_files(tmp_path / "nc", "*.tmp.*")
    again = subprocess.run(EXE + ["warm"], capture_output=True, text=True, env=env, timeout=300)
    assert again.returncode == 0 and "driftframe: compiling" not in again.stderr, again.stderr


# two warm-up parts in a module of their own (a helper process imports its part by name)
_PARTS = """
import numpy as np


def first():
    from driftframe.framework import yuv
    yuv.rgba_to_nv12(np.zeros((4, 4, 4), np.uint8), 4, 4)


def second():
    from driftframe.framework import broadphase_list
    broadphase_list.step_lengths(np.ones((5, 3)), 0.1)


def both():
    first()
    second()
"""


def _parts_env(tmp_path, cache):
    (tmp_path / "parts_here.py").write_text(_PARTS)
    return _env(NUMBA_CACHE_DIR=tmp_path / cache, PYTHONPATH=str(tmp_path))


def test_a_second_warm_up_part_compiles_in_a_helper_process_and_counts_in_the_progress(tmp_path):
    # on two cores the second part compiles in a helper process at the same time; this process then loads
    # its kernels, and the progress line counts them as one process would
    code = ("import sys, parts_here; from driftframe import cli, warmup; "
            "from driftframe.framework import broadphase_list; "
            "warmup.PARTS = {parts}; rc = cli.main(['warm']); k = broadphase_list.step_lengths; "
            "print(rc, sum(k.stats.cache_misses.values()), sum(k.stats.cache_hits.values()))")
    two = _py(code.format(parts="(parts_here.first, parts_here.second)"), env=_parts_env(tmp_path, "two"))
    one = _py(code.format(parts="(parts_here.both,)"), env=_parts_env(tmp_path, "one"))
    assert two.returncode == 0 and one.returncode == 0, (two.stderr, one.stderr)
    compiled = [re.search(r"compiled (\d+) kernels in", r.stderr) for r in (two, one)]
    assert all(compiled) and compiled[0].group(1) == compiled[1].group(1), (two.stderr, one.stderr)
    if len(os.sched_getaffinity(0)) > 1:
        assert two.stdout.split()[-3:] == ["0", "0", "1"], two.stdout    # compiled by the helper, loaded here
    assert one.stdout.split()[-3:] == ["0", "1", "0"], one.stdout          # (one part: compiled here)


def test_a_warm_up_helper_ends_with_its_parent_even_a_killed_one(tmp_path):
    # the parent SIGKILLed while its helper compiles: the helper sees its stdin close and ends at once; the
    # cache lock it shared is then free, and the next warm completes
    env = _parts_env(tmp_path, "nc")
    (tmp_path / "parts_here.py").write_text(_PARTS + "\n\ndef slow():\n    import time\n    time.sleep(60)\n")
    code = ("import parts_here; from driftframe import cli, warmup; "
            "warmup.PARTS = (parts_here.slow, parts_here.slow); cli.main(['warm'])")
    proc = subprocess.Popen([PY, "-c", code], env=env, cwd=tempfile.gettempdir(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)

    def helpers():
        found = []
        for pid in os.listdir("/proc"):
            try:
                cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
            except (OSError, ValueError):
                continue
            if b"warm_helper" in cmd and b"parts_here:slow" in cmd:
                found.append(pid)
        return found

    deadline = time.monotonic() + 60
    while not helpers() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.1)
    assert helpers(), "no helper process started"
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 10
    while helpers() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not helpers(), "the helper outlived its parent"
    done = _py("import parts_here; from driftframe import cli, warmup; "
               "warmup.PARTS = (parts_here.first, parts_here.second); raise SystemExit(cli.main(['warm']))",
               env=env, timeout=120)
    assert done.returncode == 0, done.stderr


def test_warm_once_takes_the_lock_and_skips_a_warm_folder(tmp_path):
    # a worker finding the folder warm loads nothing and compiles nothing
    env = _env(NUMBA_CACHE_DIR=tmp_path / "nc")
    code = ("import sys; from driftframe import warmup; from driftframe.framework import kernels; "
            "d = kernels.cache_dir(); d.mkdir(parents=True); (d / kernels.WARM_MARK).write_text('x'); "
            "warmup.warm_once(); "
            "print('numba' in sys.modules)")
    res = _py(code, env=env)
    assert res.returncode == 0 and res.stdout.strip() == "False", res.stderr


# -- a cheap start ----------------------------------------------------------------------------------------
def test_import_driftframe_imports_none_of_the_heavy_libraries():
    code = ("import sys, driftframe; driftframe.__version__; "
            "print(sorted(m for m in ('numba', 'moderngl', 'av', 'PIL', 'tqdm', 'scipy', 'esper', 'glfw', "
            "'matplotlib') if m in sys.modules))")
    res = _py(code, env=_env())
    assert res.returncode == 0 and res.stdout.strip() == "[]", (res.stdout, res.stderr)
    res = _py("import driftframe; print(driftframe.World.__module__, set(driftframe.__all__) <= set(dir(driftframe)))",
              env=_env())
    assert res.stdout.split() == ["driftframe.framework.world", "True"], res.stderr
    res = _py("import driftframe; driftframe.NoSuchName", env=_env())
    assert "module 'driftframe' has no attribute 'NoSuchName'" in res.stderr


def test_a_cached_kernel_loads_without_numbas_compiler_and_a_compile_after_it_still_types_numpy(tmp_path):
    # the NV12 kernel compiled into a fresh folder, then loaded in a second process: the load sets up numba's
    # runtime only (no registry imported, no scipy.linalg), and a user's own kernel compiled after it is typed with
    # numba's NumPy support as usual (np.sum of an array, np.empty, math)
    env = _env(NUMBA_CACHE_DIR=tmp_path / "nc")
    assert _nv12(env)[1] == 1
    code = (NV12 + "; import sys; "
            "print(sorted(m for m in ('numba.np.arraymath', 'numba.np.npyimpl', 'numba.typed.typeddict', "
            "'numba.experimental.jitclass.base', 'scipy.linalg') if m in sys.modules)); "
            "import numba, numpy as np, math\n"
            "@numba.njit\ndef mine(a):\n    b = np.empty(a.size)\n    b[:] = a * 2.0\n    return np.sum(b) + math.sqrt(4.0)\n"
            "print(mine(np.arange(4.0)), 'numba.np.arraymath' in sys.modules, "
            "sum(_nv12.stats.cache_misses.values()))")
    res = _py(code, env=env)
    assert res.returncode == 0, res.stderr
    loaded, imported, compiled = res.stdout.split("\n")[:3]
    assert loaded.split() == [str(_nv12(env)[0]), "0"]           # loaded, same result, nothing compiled
    assert imported == "[]", imported
    assert compiled.split() == ["14.0", "True", "0"], compiled


def test_a_cached_kernel_that_calls_numbas_arraymath_loads_without_scipy_linalg(tmp_path):
    # np.round's numba implementation lives in numba.np.arraymath (the Kepler kernels call it): a cached kernel
    # names that module in its environment, and unpickling it imports the module, which imports scipy.linalg
    # (0.3 s) unless driftframe imports it first without it
    (tmp_path / "rounding.py").write_text(
        "import numpy as np\nfrom driftframe.framework.kernels import kernel\n\n"
        "@kernel\ndef turns(t, period):\n    return np.round(t / period)\n")
    env = _env(NUMBA_CACHE_DIR=tmp_path / "nc", PYTHONPATH=tmp_path)
    code = ("import sys, rounding; print(rounding.turns(7.5, 3.0), sum(rounding.turns.stats.cache_misses.values()), "
            "'numba.np.arraymath' in sys.modules, 'scipy.linalg' in sys.modules)")
    first, second = _py(code, env=env), _py(code, env=env)
    assert first.returncode == 0 and second.returncode == 0, (first.stderr, second.stderr)
    assert first.stdout.split() == ["2.0", "1", "True", "False"], first.stdout        # compiled (2.5 -> even)
    assert second.stdout.split() == ["2.0", "0", "True", "False"], second.stdout      # loaded, without scipy.linalg


# warm's own work swapped for one kernel (a second): what is tested here is the lock and the order
_CHEAP = ("import numpy as np; from driftframe import warmup; from driftframe.framework import kernels, yuv; "
          "warmup.PARTS = (lambda: yuv.rgba_to_nv12(np.zeros((4, 4, 4), np.uint8), 4, 4),); ")


def test_warm_once_in_two_processes_at_once_compiles_in_one_and_the_other_waits_and_loads(tmp_path):
    env = _env(NUMBA_CACHE_DIR=tmp_path / "nc")
    code = (_CHEAP + "import time; warmup.warm_once(); "
            "print(sum(yuv._nv12.stats.cache_misses.values()), time.time())")
    procs = [subprocess.Popen([PY, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env=env, cwd=tempfile.gettempdir()) for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    compiled = sorted(int(out.split()[0]) for out, _ in outs)
    # one compiled; the other found the folder warm once it had the lock and compiled nothing
    assert compiled == [0, 1], outs
    assert kernels.WARM_MARK in os.listdir(next((tmp_path / "nc" / "driftframe").iterdir()))


def test_batch_on_several_processes_warms_the_cache_once_before_the_workers_start(tmp_path):
    spec = tmp_path / "b.toml"
    spec.write_text('demo = "spin"\nseeds = "0..1"\nseconds = 0.05\n')
    code = (_CHEAP + "import sys; from driftframe import cli; "
            f"sys.exit(cli.main(['batch', {str(spec)!r}, '-j', '2', '-o', {str(tmp_path / 'o')!r}]))")
    env = _env(NUMBA_CACHE_DIR=tmp_path / "nc")
    # every kernel but the cheap warm-up's, as a warm-up of them all leaves it: the workers load spin's
    # kernels instead of compiling them, both at once (3.5 s of CPU), which the cheap warm-up alone left them
    _seed_cache(tmp_path / "nc", "yuv._nv12-")
    res = subprocess.run([PY, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                         cwd=tempfile.gettempdir(), timeout=600)
    assert res.returncode == 0, res.stdout
    out = res.stdout
    assert out.count("driftframe: compiling the physics kernels") == 1, out
    assert out.index("driftframe: compiled 1 kernels") < out.index("batch:"), out    # before the batch's bar
    again = subprocess.run([PY, "-c", code.replace("'-o'", "'--overwrite', '-o'")], stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True, env=env, cwd=tempfile.gettempdir(), timeout=600)
    assert again.returncode == 0 and "driftframe: compiling" not in again.stdout, again.stdout   # warm: skipped


def test_warm_keeps_three_other_cache_folders_the_last_warmed_and_removes_the_rest(tmp_path):
    # upgrades and edited sources each make a folder: warm keeps this one and the 3 last warmed beside it
    root = tmp_path / "nc" / "driftframe"
    for k in range(5):
        d = root / f"0.0.{k}-{k:016x}"
        d.mkdir(parents=True)
        (d / "x.nbi").write_bytes(b"old")
        (d / kernels.WARM_MARK).write_text("x")
        os.utime(d / kernels.WARM_MARK, (1e9 + k, 1e9 + k))      # 0.0.4 the last warmed
    (root / "mine").mkdir()                                       # not a cache key: never touched
    res = _py(_CHEAP + "from driftframe import cli; raise SystemExit(cli.main(['warm']))",
              env=_env(NUMBA_CACHE_DIR=tmp_path / "nc"))
    assert res.returncode == 0, res.stderr
    left = sorted(p.name for p in root.iterdir())
    this = [n for n in left if n.startswith(kernels.__version__ + "-")]
    assert len(this) == 1 and (root / this[0] / kernels.WARM_MARK).exists()
    assert sorted(set(left) - set(this)) == ["0.0.2-0000000000000002", "0.0.3-0000000000000003",
                                              "0.0.4-0000000000000004", "mine"], left
