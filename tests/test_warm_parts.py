"""The warm-up's parts shared between two processes: each part claimed by one of them (framework.kernels.claim)."""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile

from driftframe.framework import kernels

# Parts that compile nothing but log who ran them and when (while the parts are claimed, or in the first
# process's last pass). The helper's first part waits until the first process has claimed the last one, so
# that both take some whatever the timing. The folder is cold (no kernel compiled): a helper starts.
_PARTS = '''
import os, time
from driftframe import warmup
from driftframe.framework import kernels

def _log(name):
    phase = "claims" if (kernels._claims or os.environ.get(kernels.CLAIMS_ENV)) else "final"
    with open(os.environ["PARTS_LOG"], "a") as f:
        f.write(f"{os.getpid()} {name} {phase}\\n")

def first():
    _log("first")

@warmup.claimed
def second():
    _log("second")
    folder = os.environ.get(kernels.CLAIMS_ENV)
    deadline = time.monotonic() + 60
    while folder and not os.path.exists(os.path.join(folder, "fourth")) and time.monotonic() < deadline:
        time.sleep(0.05)

@warmup.claimed
def third():
    _log("third")

@warmup.claimed
def fourth():
    _log("fourth")
'''


def test_claim_gives_a_part_to_the_first_process_that_asks(tmp_path, monkeypatch):
    monkeypatch.delenv(kernels.CLAIMS_ENV, raising=False)
    assert kernels.claim("x") and kernels.claim("x")              # no warm-up with a helper: always run
    monkeypatch.setenv(kernels.CLAIMS_ENV, str(tmp_path))
    assert kernels.claim("x") is True
    assert kernels.claim("x") is False                           # the other process took it
    assert kernels.claim("y") is True
    monkeypatch.setenv(kernels.CLAIMS_ENV, str(tmp_path / "gone"))
    assert kernels.claim("x") is True                            # the warm-up's folder gone: run it


def test_each_part_runs_in_one_process_then_loads_in_the_first(tmp_path):
    (tmp_path / "parts_here.py").write_text(_PARTS)
    log = tmp_path / "log.txt"
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", kernels.CLAIMS_ENV)}
    env.update(NUMBA_CACHE_DIR=str(tmp_path / "nc"), PYTHONPATH=str(tmp_path), PARTS_LOG=str(log))
    code = ("import os, parts_here; from driftframe import warmup; from driftframe.framework import kernels; "
            "missing = kernels.warm((parts_here.first, parts_here.second, parts_here.third, parts_here.fourth)); "
            "print(os.getpid(), kernels.CLAIMS_ENV in os.environ, (kernels.cache_dir() / 'warm.claims').exists())")
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300,
                         cwd=tempfile.gettempdir())
    assert res.returncode == 0, res.stderr[-2000:]
    me, leaked, left = res.stdout.split()
    assert leaked == "False" and left == "False"                 # the environment and the claims folder cleaned
    rows = [ln.split() for ln in log.read_text().splitlines()]
    claimed = [(pid, name) for pid, name, phase in rows if phase == "claims" and name != "first"]
    final = [name for pid, name, phase in rows if phase == "final" and pid == me]
    if len(os.sched_getaffinity(0)) > 1:
        assert sorted(n for _, n in claimed) == ["fourth", "second", "third"]   # each once, in one process
        (helper,) = {p for p, _ in claimed} - {me}
        assert (helper, "second") in claimed                     # the helper starts with the first of them
        assert (me, "fourth") in claimed                         # this process takes them from the far end
        assert final == ["second", "third", "fourth"]            # then runs them again here (loading)
    else:                                                        # one core: no helper, each part once here
        assert not claimed and final == ["first", "second", "third", "fourth"]
