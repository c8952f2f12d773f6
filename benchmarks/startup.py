"""How long until driftframe does something: cold compile, warm import, kernel load, first step, first frame?

Every figure comes from a fresh Python process started for it (``python -c``),
so nothing one measurement loads is already loaded for the next:

* *cold*: each demo with an empty kernel cache of its own (``NUMBA_CACHE_DIR``
  set to a new folder): import, build the world (:func:`driftframe.app.make_world`),
  ``world.prepare()``, then two steps. numba compiles a kernel at its first
  call, so the first step carries the compile. Three runs each (``--cold-runs``),
  in rounds (each round every demo once), each into a new empty folder; the
  median and the range (one compile's CPU varies ~5 % from run to run on a
  shared host). Then ``driftframe warm``
  into another empty folder: every kernel of every demo, as a user's first
  run after installing pays it once.
* *warm*: the same timeline with that demo's cache filled by its cold run,
  then a second world of the demo built, prepared and stepped once in the
  same process. *Kernel load*: ``prepare()`` + first step of the first
  world minus the same of the second, whose kernels are loaded already
  (numba reads and links a cached kernel at its first call, and
  ``prepare()`` calls some); beside it the first step minus the second.
  *To the first step* counts from the process's start (its CPU clock starts
  at zero with the process; wall from the parent's ``time.time()`` just
  before it started the child).
* ``import driftframe``, ``python -c pass`` (the interpreter alone), and
  ``import numpy`` then ``import numba`` (what building a world imports first).
* ``driftframe record spin --seconds 1 --size 320x180``, warm: the command
  as a user types it (off-screen GL, x264 in the process). *First frame*:
  from the process's start to the moment the first frame has been rendered,
  read back and handed to the encoder (the recorder's ``before_step`` hook
  for the step after it); *whole command*: to the process's exit, the file
  finished.
* pybullet (if installed, the ``compare`` extra), the baseline: ``import
  pybullet``, connecting (``DIRECT``) and creating 50 spheres, its first and
  second ``stepSimulation()``.

The warm measurements run in rounds, each round every measurement once in
turn (a busy spell on the machine hits them all), and the tables show the
medians; CPU is user + system time of the process (all its threads), which
other work on the machine disturbs much less than the wall time.

    python -m benchmarks.startup [--quick] [--cold-runs N]
"""
from __future__ import annotations

import json
import os
import resource
import statistics
import shutil
import subprocess
import sys
import tempfile
import time

from benchmarks.common import ROOT, figure, have_pybullet, parser, save_chart, table, write_section

NAME = "startup"
DEMOS = ("rotation", "spin", "asteroids", "billiards", "cradle", "swarm", "orbit")
QUICK_DEMOS = ("spin", "billiards")
PYBULLET_SPHERES = 50

# -- the children: each prints one JSON line last ---------------------------------------------------------
# marks are (CPU seconds since the process started, wall seconds since the parent started it)
_MARK = r"""
import json, sys, time
SPAWNED = float(sys.argv[1])
marks = {}
def mark(name):
    marks[name] = (time.process_time(), time.time() - SPAWNED)
mark("start")
"""

DEMO_CHILD = _MARK + r"""
demo = sys.argv[2]
from driftframe.app import make_world
mark("import")
world, _ = make_world(demo, seed=0)
mark("build")
world.prepare()
mark("prepare")
world.step()
mark("step1")
world.step()
mark("step2")
world.close()
# a second world of the same demo in the same process: its kernels are loaded already
world, _ = make_world(demo, seed=0)
mark("build2")
world.prepare()
world.step()
mark("step1b")
world.close()
print(json.dumps(marks))
"""

IMPORT_CHILD = _MARK + r"""
import driftframe
mark("import")
print(json.dumps(marks))
"""

PASS_CHILD = _MARK + r"""
print(json.dumps(marks))
"""

LIBS_CHILD = _MARK + r"""
import numpy
mark("numpy")
import numba
mark("numba")
print(json.dumps(marks))
"""

RECORD_CHILD = _MARK + r"""
out = sys.argv[2]
from driftframe.framework import recorder
real = recorder.record

def record(world, path, **kw):
    # the first frame is handed to the encoder just before the step after it: the step numbered k
    k = kw.get("steps_per_frame", 1)
    first = world.step_count + k
    theirs = kw.get("before_step")

    def before_step(w, i):
        if i == first and "frame1" not in marks:
            mark("frame1")
        if theirs is not None:
            theirs(w, i)

    kw["before_step"] = before_step
    return real(world, path, **kw)

recorder.record = record
from driftframe.cli import main
rc = main(["record", "spin", "--seconds", "1", "--size", "320x180", "-o", out, "--overwrite", "--quiet"])
mark("done")
print(json.dumps(dict(marks, rc=rc)))
"""

PYBULLET_CHILD = _MARK + r"""
n = int(sys.argv[2])
import pybullet as pb
mark("import")
cid = pb.connect(pb.DIRECT)
pb.setGravity(0, 0, 0, physicsClientId=cid)
pb.setPhysicsEngineParameter(fixedTimeStep=1 / 60, numSubSteps=0, physicsClientId=cid)
side = 40.0
for k in range(n):
    shape = pb.createCollisionShape(pb.GEOM_SPHERE, radius=1.0, physicsClientId=cid)
    body = pb.createMultiBody(baseMass=1.0, baseCollisionShapeIndex=shape,
                              basePosition=[(k % 5) * 8.0 - 16.0, (k // 5 % 5) * 8.0 - 16.0, (k // 25) * 8.0],
                              useMaximalCoordinates=True, physicsClientId=cid)
    pb.resetBaseVelocity(body, [((k * 7) % 5 - 2) * 0.5, ((k * 3) % 5 - 2) * 0.5, 0.0], [0.0, 0.0, 0.3],
                         physicsClientId=cid)
mark("build")
pb.stepSimulation(physicsClientId=cid)
mark("step1")
pb.stepSimulation(physicsClientId=cid)
mark("step2")
pb.disconnect(physicsClientId=cid)
print(json.dumps(marks))
"""


def child(code: str, *args: str, cache: str | None = None, check: bool = True) -> dict:
    """Run ``code`` in a fresh interpreter; its marks, plus its whole CPU (rusage) and wall as ``proc``."""
    env = dict(os.environ)
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = cache
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    spawned = time.time()
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code, repr(spawned), *args], cwd=ROOT, env=env,
                          capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        if not check:
            return {"failed": done.stderr.strip().splitlines()[-1:] or [f"exit status {done.returncode}"]}
        raise SystemExit(f"[{NAME}] a child failed (exit status {done.returncode}):\n{done.stderr[-3000:]}")
    marks = json.loads(done.stdout.strip().splitlines()[-1])
    marks["proc"] = (after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, wall)
    return marks


def span(m: dict, a: str, b: str) -> tuple[float, float]:
    """(CPU, wall) seconds from mark ``a`` to mark ``b``."""
    return m[b][0] - m[a][0], m[b][1] - m[a][1]


def med(runs: list[dict], fn) -> tuple[float, float]:
    """Medians of (CPU, wall) of ``fn(run)`` over the runs."""
    pairs = [fn(r) for r in runs]
    return statistics.median(p[0] for p in pairs), statistics.median(p[1] for p in pairs)


def _ms(seconds: float) -> str:
    """Milliseconds to 3 significant digits, whole numbers from 100 up (no exponent)."""
    v = seconds * 1e3
    return f"{v:,.0f}" if abs(v) >= 100 else f"{v:.3g}"


def ms(pair: tuple[float, float]) -> list[str]:
    return [_ms(pair[0]), _ms(pair[1])]


def main(argv=None) -> None:
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--cold-runs", type=int, default=3, metavar="N",
                   help="cold runs of each demo, each with an empty cache (default 3; --quick: 1)")
    args = p.parse_args(argv)
    if args.cold_runs < 1:
        p.error(f"--cold-runs must be at least 1, got {args.cold_runs}")
    cold_runs = 1 if args.quick else args.cold_runs
    started = time.perf_counter()
    demos = QUICK_DEMOS if args.quick else DEMOS
    rounds = 1 if args.quick else 5
    bullet = have_pybullet()
    if not bullet:
        print(f"[{NAME}] pybullet is not installed (pip install -e '.[compare]'): its rows are skipped")
    load = [os.getloadavg()[0]]
    with tempfile.TemporaryDirectory(prefix="driftframe-startup-") as tmp:
        cold, warm = {d: [] for d in demos}, {d: [] for d in demos}
        for k in range(cold_runs):            # rounds of every demo, each run into an empty folder; the first
            for d in demos:                   # round's folder is then that demo's warm one
                folder = os.path.join(tmp, f"cache-{d}" if k == 0 else f"cold-{d}-{k}")
                cold[d].append(child(DEMO_CHILD, d, cache=folder))
                if k:
                    shutil.rmtree(folder, ignore_errors=True)
                c = span(cold[d][-1], "start", "step1")
                print(f"[{NAME}] {d:>9} cold {k + 1} of {cold_runs}: {c[0]:6.1f} s CPU to the first step "
                      f"({c[1]:.1f} s wall)", flush=True)
        warm_all = None
        if not args.quick:
            # every kernel at once, as `driftframe warm` after installing; then again, with them all cached
            runs = []
            for _ in range(2):
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = time.perf_counter()
                done = subprocess.run([sys.executable, "-m", "driftframe", "warm", "--quiet"], cwd=ROOT,
                                      env=dict(os.environ, NUMBA_CACHE_DIR=os.path.join(tmp, "cache-all")),
                                      capture_output=True, text=True)
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                runs.append((after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime,
                             time.perf_counter() - t0))
                if done.returncode != 0:          # an older tree without the command: its rows are left out
                    print(f"[{NAME}] driftframe warm failed (exit status {done.returncode}), its rows are left "
                          f"out: {done.stderr.strip().splitlines()[-1:]}", flush=True)
                    break
            else:
                warm_all = runs
            if warm_all:
                print(f"[{NAME}] driftframe warm: {warm_all[0][0]:.1f} s CPU on an empty cache, "
                      f"{warm_all[1][0]:.2f} s CPU again", flush=True)
        interp, imports, libs, records, bullets = [], [], [], [], []
        for k in range(rounds):
            interp.append(child(PASS_CHILD))
            imports.append(child(IMPORT_CHILD))
            libs.append(child(LIBS_CHILD))
            for d in demos:
                warm[d].append(child(DEMO_CHILD, d, cache=os.path.join(tmp, f"cache-{d}")))
            spin_cache = os.path.join(tmp, "cache-spin")
            records.append(child(RECORD_CHILD, os.path.join(tmp, "spin.mp4"), cache=spin_cache))
            if bullet:
                bullets.append(child(PYBULLET_CHILD, str(PYBULLET_SPHERES)))
            print(f"[{NAME}] warm round {k + 1} of {rounds} done", flush=True)
    load.append(os.getloadavg()[0])

    # -- tables ---------------------------------------------------------------------------------------------
    demo_rows, chart_cold, chart_warm = [], {}, {}
    for d in demos:
        c_first = med(cold[d], lambda m: span(m, "start", "step1"))
        c_cpu = sorted(span(m, "start", "step1")[0] for m in cold[d])
        w = warm[d]
        imp = med(w, lambda m: span(m, "start", "import"))
        build = med(w, lambda m: span(m, "import", "build"))
        prep = med(w, lambda m: span(m, "build", "prepare"))
        s1 = med(w, lambda m: span(m, "prepare", "step1"))
        s2 = med(w, lambda m: span(m, "step1", "step2"))
        s12 = med(w, lambda m: tuple(a - b for a, b in zip(span(m, "prepare", "step1"), span(m, "step1", "step2"))))
        kl = med(w, lambda m: tuple(a - b for a, b in zip(span(m, "build", "step1"), span(m, "build2", "step1b"))))
        to_first = med(w, lambda m: tuple(m["step1"]))                 # marks count from the start
        compile_cpu = c_first[0] - to_first[0]
        chart_cold[d] = c_first
        chart_warm[d] = (to_first, kl)
        demo_rows.append([d, f"{c_first[0]:.1f}", f"{c_cpu[0]:.1f}-{c_cpu[-1]:.1f}", f"{c_first[1]:.1f}",
                          f"{compile_cpu:.1f}",
                          f"{(imp[0] + build[0]) * 1e3:.0f}", f"{prep[0] * 1e3:.1f}", f"{s1[0] * 1e3:.1f}",
                          f"{s2[0] * 1e3:.2f}", f"{s12[0] * 1e3:.1f}", f"{kl[0] * 1e3:.0f}", *ms(to_first)])

    py = med(interp, lambda m: m["proc"])
    imp = med(imports, lambda m: span(m, "start", "import"))
    imp_proc = med(imports, lambda m: m["proc"])
    np_imp = med(libs, lambda m: span(m, "start", "numpy"))
    nb_imp = med(libs, lambda m: span(m, "numpy", "numba"))
    rec_first = med(records, lambda m: tuple(m["frame1"]))
    rec_done = med(records, lambda m: m["proc"])
    other = [["`python -c pass` (the interpreter alone, whole process)", *ms(py)],
             ["`import driftframe` (in the process)", *ms(imp)],
             ["`import driftframe`, whole process", *ms(imp_proc)],
             ["`import numpy` (in the process)", *ms(np_imp)],
             ["`import numba` after it (in the process)", *ms(nb_imp)],
             ["`driftframe record spin --seconds 1 --size 320x180`: first frame handed to the encoder, "
              "from the process's start", *ms(rec_first)],
             ["the same: whole command (60 frames, file finished)", *ms(rec_done)]]
    bullet_first = None
    if bullets:
        b_imp = med(bullets, lambda m: span(m, "start", "import"))
        b_build = med(bullets, lambda m: span(m, "import", "build"))
        b_s1 = med(bullets, lambda m: span(m, "build", "step1"))
        b_s2 = med(bullets, lambda m: span(m, "step1", "step2"))
        bullet_first = med(bullets, lambda m: (m["step1"][0], m["step1"][1]))
        other += [["pybullet: `import pybullet` (in the process)", *ms(b_imp)],
                  [f"pybullet: connect (DIRECT) + {PYBULLET_SPHERES} spheres", *ms(b_build)],
                  ["pybullet: first `stepSimulation()`", *ms(b_s1)],
                  ["pybullet: second `stepSimulation()`", *ms(b_s2)],
                  ["pybullet: to the first step done, from the process's start", *ms(bullet_first)]]
    if warm_all:
        other += [["`driftframe warm` on an empty cache (every kernel compiled), whole process",
                   *ms(warm_all[0][:2])],
                  ["`driftframe warm` again (every kernel loaded from the cache), whole process",
                   *ms(warm_all[1][:2])]]

    # -- chart ------------------------------------------------------------------------------------------------
    fig, (ax, bx) = figure(1, 2, figsize=(12, 5.2))
    cold_bars = {d: chart_cold[d] for d in demos}
    if warm_all:
        cold_bars["driftframe warm:\nevery kernel"] = warm_all[0][:2]
    y = range(len(cold_bars))
    ax.barh([i - 0.2 for i in y], [v[0] for v in cold_bars.values()], 0.4, label="CPU", color="C3")
    ax.barh([i + 0.2 for i in y], [v[1] for v in cold_bars.values()], 0.4, label="wall", color="C3", alpha=0.4)
    for i, v in enumerate(cold_bars.values()):
        ax.text(v[0], i - 0.2, f" {v[0]:.1f}", va="center", fontsize=7)
    ax.set_yticks(list(y), list(cold_bars), fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("seconds from the process's start to the first step done (warm: to its exit)")
    ax.set_title("Cold: an empty kernel cache (one run each)", fontsize=10)
    ax.legend(fontsize=8, loc="upper right")
    labels = [f"{d}: to the first step" for d in demos] + ["record spin: first frame"]
    cpu = [chart_warm[d][0][0] for d in demos] + [rec_first[0]]
    wall = [chart_warm[d][0][1] for d in demos] + [rec_first[1]]
    colors = ["C0"] * len(demos) + ["C2"]
    if bullet_first is not None:
        labels.append(f"pybullet: import + {PYBULLET_SPHERES} spheres + first step")
        cpu.append(bullet_first[0])
        wall.append(bullet_first[1])
        colors.append("grey")
    yy = range(len(labels))
    bx.barh(list(yy), cpu, 0.6, color=colors, label="CPU")
    bx.plot(wall, list(yy), "k|", ms=12, label="wall")
    kl = [chart_warm[d][1][0] for d in demos]
    bx.barh(list(range(len(demos))), kl, 0.6, color="C1", label="of which kernel load (CPU)")
    for i, v in enumerate(cpu):
        bx.text(v, i, f" {v * 1e3:.0f} ms", va="center", fontsize=7)
    bx.set_yticks(list(yy), labels, fontsize=8)
    bx.invert_yaxis()
    bx.set_xlabel(f"seconds from the process's start (median of {rounds})")
    bx.set_title("Warm: kernels cached", fontsize=10)
    bx.set_xlim(0, 1.2 * max(max(cpu), max(wall)))
    bx.legend(fontsize=7, loc="lower right")
    save_chart(fig, NAME)

    # -- text -------------------------------------------------------------------------------------------------
    cold_cpu = [chart_cold[d][0] for d in demos]
    warm_first = [chart_warm[d][0][0] for d in demos]
    lines = [
        "Each figure is from a fresh Python process (see the script's docstring for what each row times). "
        f"*Cold*: {cold_runs} run{'s' if cold_runs > 1 else ''} per demo (in rounds), each with an empty kernel "
        "cache of its own, so every demo pays the compile of "
        "all the kernels it calls, including those another demo compiled first; *warm*: the same demo's "
        f"cache filled, the median of {rounds} rounds, each round every measurement once. CPU is user + system "
        "time of the process, all its threads; wall counts from the parent starting the child. The 2 cores "
        f"were shared with other work (load average {load[0]:.1f} at the start, {load[1]:.1f} at the end), "
        "which stretches the wall times more than the CPU.",
        "",
        "**Per demo.** *Cold, to the first step*: CPU (the median of the cold runs, and their range) and wall "
        "from the process's start to its first step "
        "done, the compile included; *compile*: that median CPU minus the warm one (the last columns). Warm: "
        "*import + build* (`from driftframe.app import make_world`, `make_world(demo)`), `prepare()`, the "
        "first and second step after it and their difference, *kernel load*: `prepare()` + first step of "
        "this world minus the same of a second world of the demo built next in the same process (numba "
        "loads a cached kernel at its first call, and `prepare()` already calls some: the collision "
        "system's gather and pair list), and the CPU and wall from the process's start to the first step "
        "done. All warm columns are CPU.",
        "",
        table(["demo", "cold: to 1st step, CPU s", "range, s", "wall s", "compile, CPU s", "warm: import + build, CPU ms",
               "prepare, ms", "1st step, ms", "2nd step, ms", "1st - 2nd step, ms", "kernel load, ms",
               "to 1st step, CPU ms", "wall ms"], demo_rows),
        "",
        "**Commands and the baseline** (warm cache; medians):",
        "",
        table(["measurement", "CPU ms", "wall ms"], other),
        "",
        f"A demo's first run on a machine costs {min(cold_cpu):.1f}-{max(cold_cpu):.1f} s of CPU to its first step "
        "(the compile included); "
        f"once its kernels are cached, {min(warm_first) * 1e3:.0f}-{max(warm_first) * 1e3:.0f} ms from the "
        "process's start to the first step done",
    ]
    if bullet_first is not None:
        lines[-1] += (f", against pybullet's {bullet_first[0] * 1e3:.0f} ms (import, {PYBULLET_SPHERES} "
                      f"spheres, first step), {min(warm_first) / bullet_first[0]:.1f}-"
                      f"{max(warm_first) / bullet_first[0]:.1f}x, in the same run")
    lines[-1] += "."
    loads = [chart_warm[d][1][0] for d in demos]
    lines[-1] += (f" Of the warm figure, `import numba` is {nb_imp[0] * 1e3:.0f} ms and loading the cached "
                  f"kernels {min(loads) * 1e3:.0f}-{max(loads) * 1e3:.0f} ms; the rest is the interpreter, "
                  "numpy, esper, the systems' modules and building the scene. `driftframe record spin` hands "
                  f"its first frame to the encoder {rec_first[0] * 1e3:.0f} ms of CPU after it starts "
                  f"({rec_first[1] * 1e3:.0f} ms wall).")
    if warm_all:
        lines[-1] += (f" `driftframe warm` compiles every kernel in {warm_all[0][0]:.1f} s of CPU, once per "
                      "machine and driftframe version; the demos' cold figures overlap (each compiles the "
                      "kernels it shares with others again).")
    write_section(NAME, "Start-up: compile, import, kernel load, first step, first frame", "\n".join(lines),
                  quick=args.quick, started=started)


if __name__ == "__main__":
    main()
