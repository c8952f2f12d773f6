"""Run every benchmark, then assemble docs/BENCHMARKS.md from their tables.

    python -m benchmarks.all            # the full runs (a few minutes each)
    python -m benchmarks.all --quick    # a smoke run of each
    python -m benchmarks.all --only spin_accuracy step_scaling

Each benchmark runs in its own process (``python -m benchmarks.<name>``), so a
crash, a GL context or the memory of one cannot touch the next, and writes
``docs/img/<name>.png`` and ``docs/bench/<name>.md``. A benchmark whose module
does not exist yet is listed as not yet available; one that fails is reported
and makes the exit status non-zero, and the others still run. Finally
docs/BENCHMARKS.md = an introduction + every docs/bench/*.md, in the order of
:data:`ORDER` (then any others, by name).
"""
from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import time

from benchmarks import common

#: The benchmarks, in the order they run and appear in docs/BENCHMARKS.md.
ORDER = ["spin_accuracy", "thrust_accuracy", "step_scaling", "collision_accuracy", "collision_scaling",
         "collision_stress", "small_scenes", "orbit_accuracy", "orbit_contacts", "nbody", "render_lod",
         "record_throughput", "dark_video", "play_rate", "batch_scaling", "startup"]

INTRO = """# driftframe benchmarks

Speed and accuracy, charted: each section below is written by one script in
`benchmarks/` (`python -m benchmarks.<name>`, `--quick` for a smoke run) and
regenerated, all together, by `./run bench` (`python -m benchmarks.all`).
Times are medians over repeats; ratios are against a baseline measured in the
same process. Figures are from the machine named in each section: compare
ratios, not absolute times, across machines.
"""


def available(name: str) -> bool:
    return importlib.util.find_spec(f"benchmarks.{name}") is not None


def run(name: str, quick: bool) -> tuple[int, float]:
    """Run one benchmark in a child process; (exit status, seconds)."""
    cmd = [sys.executable, "-m", f"benchmarks.{name}"] + (["--quick"] if quick else [])
    t0 = time.perf_counter()
    rc = subprocess.call(cmd, cwd=common.ROOT)
    return rc, time.perf_counter() - t0


def _anchor(title: str) -> str:
    """GitHub's heading anchor: lower case, punctuation dropped, spaces to hyphens."""
    kept = "".join(ch for ch in title.lower() if ch.isalnum() or ch in " -_")
    return kept.replace(" ", "-")


def assemble(status: dict[str, str]) -> str:
    """docs/BENCHMARKS.md: the introduction, a status list, then every section in ORDER."""
    parts = [INTRO.strip(), ""]
    sections = {p.stem: p for p in common.TABLES.glob("*.md")} if common.TABLES.exists() else {}
    listed = []
    for name in ORDER:
        note = status.get(name, "")
        note = f" — {note}" if note.startswith(("FAILED", "not yet")) else ""
        if name in sections:
            title = sections[name].read_text().splitlines()[0].lstrip("#").strip()
            listed.append(f"- [{title}](#{_anchor(title)}) (`{name}`){note}")
        else:
            listed.append(f"- `{name}`{note or ' — no table yet'}")
    parts += ["## Contents", "", *listed, ""]
    for name in ORDER + sorted(set(sections) - set(ORDER)):
        if name in sections:
            parts += [sections[name].read_text().strip(), ""]
    return "\n".join(parts)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="pass --quick to every benchmark (a smoke run)")
    p.add_argument("--only", nargs="+", metavar="NAME", choices=ORDER, help="run only these (others keep their tables)")
    args = p.parse_args(argv)
    names = args.only or ORDER
    status: dict[str, str] = {}
    failed = []
    for name in ORDER:
        if not available(name):
            status[name] = "not yet available"
            print(f"[all] {name}: not yet available (no benchmarks/{name}.py)")
            continue
        if name not in names:
            status[name] = "not run this time (table from an earlier run, if any)"
            continue
        print(f"[all] {name}{' --quick' if args.quick else ''} ...", flush=True)
        rc, took = run(name, args.quick)
        if rc == 0:
            status[name] = f"ran{' (quick)' if args.quick else ''} in {took:.0f} s"
        else:
            status[name] = f"FAILED (exit status {rc}); any table below is from an earlier run"
            failed.append(name)
        print(f"[all] {name}: {status[name]}", flush=True)
    out = common.ROOT / "docs" / "BENCHMARKS.md"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(assemble(status))
    print(f"[all] wrote {out.relative_to(common.ROOT)}" + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
