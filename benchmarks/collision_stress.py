"""Collisions at any density (issue 9): every stress scene side by side with pybullet, in one run.

Scenes (``benchmarks/stress_scenes.py``; dt = 1/60 s, 180 steps unless said):
dense gas of 2,000 spheres at 30 % and 45 % volume fraction; 200 spheres
converging on a point with restitution 0 and 0.5; touching crystals (simple
cubic 10x10x10, FCC 500) with random velocities; 10,000 and 200,000 spheres
dropped at random (overlapping); a sphere wedged between two immovable ones
among 30,000 idle bodies; fields at 5 % of 50 / 500 / 10,000 / 100,000
spheres; two bodies head on.

* driftframe: ``world.step()`` with MovementSystem + CollisionSystem
  (``events=False``: pybullet makes no Python object per contact either; the
  gas rows also give the time with events on), timed per step.
* pybullet 3.2 (the ``compare`` extra), set up as in ``collision_scaling``:
  as elastic as it goes (restitution 1, threshold 0, no friction, no damping,
  no sleeping, ``contactERP = 0``), the pair restitution set to the scene's,
  ``stepSimulation()`` timed per step.

Both run in the same process, in turn, in blocks of steps (so a change of load
hits both alike); each row gives the mean and the worst step of each, and
the ratio of the means. Energy: the largest relative rise of kinetic energy
over the run (and the change for the elastic crystals). Overlap: the deepest
overlap at a step end, as a fraction of the radius. The 200,000-sphere row
runs in a child process that reports its own peak resident memory (VmHWM). The cold start
is the first step of a child process with an empty numba cache (compilation)
and with the cache filled (loading it).
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np

from benchmarks import common
from benchmarks import stress_scenes as S

DT = 1.0 / 60.0
#: collections of Python's cyclic garbage collector so far (counted once main() has hooked _count_gc)
GC_RUNS = [0]


def _count_gc(phase: str, info: dict) -> None:
    if phase == "stop":
        GC_RUNS[0] += 1


class Drift:
    def __init__(self, scene, events=False, prewarm=True):
        from driftframe.components.body import Acceleration, Mass, Transform, Velocity
        from driftframe.components.collision import SphereCollider

        self.scene = scene
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            self.w, self.cs, self.ids = S.world_of(scene, events=events)
            if prewarm:
                # the world's one-time table sync and query build for freshly made entities (esper's cost,
                # the same for any system): done before timing, as a game does it at load
                self.w.sync()
                for types, opt in (((Transform, SphereCollider), (Velocity, Mass, Acceleration)),
                                   ((Transform, Velocity), ()), ((Transform, Velocity, Acceleration), ()),
                                   ((SphereCollider,), ())):
                    self.w.query(*types, optional=opt).refresh()
                self.w.prepare()            # the systems' packed rows and buffers, as a game builds them at load
        self.warnings = list(rec)
        self.most = 0
        self.contacts = []                  # contacts of each step
        self.m = scene[3]
        self.r = scene[2]

    def step(self):
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            g = GC_RUNS[0]
            c = time.thread_time()
            t = time.perf_counter()
            self.w.step()
            el = time.perf_counter() - t
            self.cpu = time.thread_time() - c
            self.gc = GC_RUNS[0] != g              # (whether the garbage collector ran in the step)
        self.warnings += rec
        self.contacts.append(self.cs.stats["contacts"])
        self.most = max(self.most, self.cs.stats["contacts"])
        return el

    def velocities(self):
        from driftframe.components.body import Velocity
        return self.w.columns(Velocity, self.ids).linear

    def positions(self):
        from driftframe.components.body import Transform
        return self.w.columns(Transform, self.ids).position

    def close(self):
        self.w.close()


class Bullet:
    def __init__(self, scene):
        x, v, r, m, e = scene
        self.pb, self.cid, self.ids = common.pybullet_spheres(scene, DT)
        self.m = m
        self.r = r

    def step(self):
        g = GC_RUNS[0]
        c = time.thread_time()
        t = time.perf_counter()
        self.pb.stepSimulation(physicsClientId=self.cid)
        el = time.perf_counter() - t
        self.cpu = time.thread_time() - c
        self.gc = GC_RUNS[0] != g
        return el

    def velocities(self):
        return np.array([self.pb.getBaseVelocity(b, physicsClientId=self.cid)[0] for b in self.ids])

    def positions(self):
        return np.array([self.pb.getBasePositionAndOrientation(b, physicsClientId=self.cid)[0] for b in self.ids])

    def close(self):
        self.pb.disconnect(physicsClientId=self.cid)


def kinetic(sim) -> float:
    m = sim.m
    fin = np.isfinite(m)
    v = sim.velocities()
    return 0.5 * float((m[fin] * (v[fin] * v[fin]).sum(1)).sum())


def deepest_overlap(sim) -> float:
    from driftframe.framework import broadphase as bp
    x = sim.positions()
    r = sim.r
    i, j = bp.sphere_pairs(x, r)
    if not len(i):
        return 0.0
    d = np.linalg.norm(x[j] - x[i], axis=1)
    return float(((r[i] + r[j] - d) / np.minimum(r[i], r[j])).max())


def run_scene(make, steps, *, bullet=True, block=10, energy=False, overlap=False, events=False, repeats=1):
    """Step driftframe and pybullet in turn, blocks of ``block`` steps; per-step times and checks.

    With ``repeats`` > 1 the whole run is made ``repeats`` times from a fresh scene, and each engine's
    ``mean`` is the median of its runs' means (a run that a burst of load from the shared machine hit
    does not decide the row; every run's mean still holds its neighbour-list rebuilds); ``worst_ratio``
    is the median over the runs of each run's worst step / its mean. ``cpu_*``: the thread's CPU time
    per step (what the step itself cost, without the time the scheduler gave other processes)."""
    times = {}
    cpu = {}
    means = {}
    worsts = {}
    firsts = {}
    cpu_first = {}
    cpu_next = {}                           # per run: the mean CPU time of its steps 2 to 5
    most = 0
    contacts = []                           # driftframe's contacts of each step, per run
    rise, change, over = {}, {}, {}
    gcs, cts = {}, {}                       # per step: the garbage collector ran in it; driftframe's contacts
    for rep in range(repeats):
        scene = make()
        # pybullet's world is built first, so driftframe's first step follows its world.prepare() as in a
        # game (a level loaded, then the first frame), not another engine's set-up; driftframe steps first
        peer = Bullet(scene) if bullet else None
        # the start's kinetic energy before the Drift is made, so that its first step follows its prepare()
        # at once (pybullet's reads 2,000 bodies through Python calls: it left the caches cold); driftframe's
        # from the scene's own arrays, the same numbers its world holds
        k0 = {}
        if energy:
            if peer is not None:
                k0["pybullet"] = kinetic(peer)
            fin = np.isfinite(scene[3])
            k0["driftframe"] = 0.5 * float((scene[3][fin] * (scene[1][fin] * scene[1][fin]).sum(1)).sum())
        sims = {"driftframe": Drift(scene, events=events)}
        if peer is not None:
            sims["pybullet"] = peer
        run_t = {k: [] for k in sims}
        last = dict(k0)
        done = 0
        while done < steps:
            for k, s in sims.items():
                for _ in range(min(block, steps - done)):
                    run_t[k].append(s.step())
                    cpu.setdefault(k, []).append(s.cpu)
                    gcs.setdefault(k, []).append(s.gc)      # (bools and ints: a tuple a step would start collections)
                    cts.setdefault(k, []).append(s.contacts[-1] if k == "driftframe" else -1)
                    if energy:
                        e = kinetic(s)
                        rise[k] = max(rise.get(k, 0.0), (e - last[k]) / k0[k] if k0[k] else 0.0)
                        last[k] = e
                    if overlap:
                        over[k] = max(over.get(k, 0.0), deepest_overlap(s))
            done += min(block, steps - done)
        for k, t in run_t.items():
            times.setdefault(k, []).extend(t)
            means.setdefault(k, []).append(float(np.mean(t)))
            firsts.setdefault(k, []).append(float(t[0]))
            cpu_first.setdefault(k, []).append(cpu[k][-len(t)])
            cpu_next.setdefault(k, []).append(float(np.mean(cpu[k][-len(t):][1:5])))
            worsts.setdefault(k, []).append(float(np.max(t)))
            if energy:
                ch = (kinetic(sims[k]) - k0[k]) / k0[k]
                change[k] = ch if abs(ch) > abs(change.get(k, 0.0)) else change.get(k, 0.0)
        d = sims["driftframe"]
        most = max(most, d.most)
        contacts.append(d.contacts)
        for s in sims.values():
            s.close()
    out = {k: {"mean": float(np.median(means[k])), "means": means[k], "median": float(np.median(t)),
               "worst": float(np.max(t)), "worst_med": float(np.median(worsts[k])),
               "worst_ratio": float(np.median(np.array(worsts[k]) / np.array(means[k]))),
               "p99": float(np.percentile(t, 99)), "first": float(t[0]),
               "first_med": float(np.median(firsts[k])), "first_worst": float(np.max(firsts[k])),
               "cpu_mean": float(np.mean(cpu[k])), "cpu_worst": float(np.max(cpu[k])),
               "cpu_first": float(np.median(cpu_first[k])), "cpu_median": float(np.median(cpu[k])),
               "cpu_next": float(np.median(cpu_next[k])),
               "gc_steps": sum(gcs[k]), "worst_tag": (gcs[k][int(np.argmax(cpu[k]))], cts[k][int(np.argmax(cpu[k]))])}
           for k, t in times.items()}
    for k in times:
        if energy:
            out[k]["rise"] = rise[k]
            out[k]["change"] = change[k]
        if overlap:
            out[k]["overlap"] = over[k]
    out["driftframe"]["warnings"] = sorted({str(w.message).split(";")[0][:60] for w in d.warnings
                                            if issubclass(w.category, RuntimeWarning)})
    out["driftframe"]["nwarn"] = len([w for w in d.warnings
                                      if issubclass(w.category, RuntimeWarning) and "overlap" in str(w.message)])
    out["driftframe"]["stats"] = dict(d.cs.stats)
    out["driftframe"]["max_contacts"] = most
    out["driftframe"]["contacts_first"] = float(np.median([c[0] for c in contacts]))
    out["driftframe"]["contacts_median"] = float(np.median(np.concatenate(contacts)))
    return out


def worst_cases(quick: bool) -> list:
    """(key, label, scene maker, steps) of issue 24's classes of scene (``stress_scenes``)."""
    from benchmarks.small_scenes import billiard_break
    return [("struck", f"touching FCC crystal of {4 * (5 if quick else 8) ** 3:,} at rest, struck once",
             lambda: S.struck_crystal(5 if quick else 8), 20),
            ("fast", "5 bodies at 300 m/s through a field of 2,000", lambda: S.fast_movers(2000), 40),
            ("jammed", f"jammed FCC clump of {4 * (5 if quick else 8) ** 3:,} hit at 20 m/s",
             lambda: S.jammed_clump(5 if quick else 8), 20),
            ("mixed", "radius ratio 300: one large sphere among 4,000", lambda: S.mixed_sizes(4000), 40),
            ("tunnel", "tunnel sweep: 1 fast sphere down a line of 20", S.tunnel_sweep, 60),
            ("graze", "10 grazing pairs (near misses and touches)", S.grazing_pairs, 60),
            ("break16", "16-ball break", billiard_break, 60)]


def rebuilds(ratio: float, n: int = 4000, steps: int = 40, runs: int = 3, bullet: bool = True) -> dict:
    """Mixed sizes (issue 24): the neighbour list's rebuilds in steps of one large sphere ``ratio`` times the
    radius of ``n`` small ones (``stress_scenes.mixed_sizes``), against the median step; CPU time of the
    thread, in blocks of 5 steps interleaved with pybullet's as the worst-case rows are. A rebuild is the
    collision system's whole ``_build_list`` (displacements, territories, grid, x order, the step's
    scratch); prepare()'s own build is not counted."""
    build, step = [], []
    for _ in range(runs):
        scene = S.mixed_sizes(n, ratio=ratio)
        peer = Bullet(scene) if bullet else None
        d = Drift(scene)
        cs, inner = d.cs, d.cs._build_list

        def timed(*a, **k):
            c = time.thread_time()
            inner(*a, **k)
            build.append(time.thread_time() - c)
        cs._build_list = timed                           # (an instance attribute: _continuous calls it)
        for k in range(steps):
            d.step()
            step.append(d.cpu)
            if peer is not None and k % 5 == 4:
                for _ in range(5):
                    peer.step()
        d.close()
        if peer is not None:
            peer.close()
    return {"build_median": float(np.median(build)), "build_worst": float(np.max(build)), "builds": len(build),
            "step_median": float(np.median(step))}


def first_step(make, *, bullet=True):
    """The first step of a fresh scene (driftframe: also its collision stage alone)."""
    scene = make()
    d = Drift(scene)
    t = d.step()
    out = {"driftframe": {"first": t, "collision": d.w.profile["collision"], "stats": dict(d.cs.stats),
                          "warnings": len([w for w in d.warnings if "overlap" in str(w.message)]),
                          "all_warnings": sorted({str(w.message)[:70] for w in d.warnings})}}
    d.close()
    if bullet:
        b = Bullet(scene)
        out["pybullet"] = {"first": b.step()}
        b.close()
    return out


# Peak memory is this process image's own high-water mark, VmHWM in /proc/self/status. Not
# getrusage's ru_maxrss: Linux carries that across fork + exec, so a child started from this
# benchmark's parent (which by then holds pybullet's 100,000-body field) reports the parent's peak.
CHILD_BIG = r"""
import json, sys, time, warnings
sys.path.insert(0, {root!r})

def hwm():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024

start = hwm()
from benchmarks import stress_scenes as S
from benchmarks.collision_stress import Drift
warnings.simplefilter("ignore")
imported = hwm()
t = time.perf_counter()
d = Drift(S.random_overlapping({n}))
made = time.perf_counter() - t
before = hwm()
times = [d.step() for _ in range({steps})]
print(json.dumps({{"made": made, "times": times, "stats": d.cs.stats, "imported": imported, "before": before,
                  "rss": hwm()}}))
"""

CHILD_COLD = r"""
import json, sys, time
t0 = time.perf_counter()
sys.path.insert(0, {root!r})
from benchmarks import stress_scenes as S
w, cs, ids = S.world_of(S.gas(100, 0.3))
t = time.perf_counter(); w.step(); first = time.perf_counter() - t
w2, cs2, _ = S.world_of(S.head_on())
t = time.perf_counter(); w2.step(); first_small = time.perf_counter() - t
print(json.dumps({{"first": first, "first_small": first_small, "total": time.perf_counter() - t0}}))
"""


def child(code: str, env=None, timeout=900) -> dict:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=common.ROOT,
                         env=env, timeout=timeout)
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def timed_rows(q: bool, bullet: bool) -> dict:
    """Each timed row's key and the call that measures it (``--only`` runs some of them)."""
    steps = 30 if q else 180
    R = 1 if q else 3                   # interleaved repeats of each row (medians over them: a shared machine)
    rows = {}
    for frac in (0.30, 0.45):
        rows[f"gas{frac}"] = lambda frac=frac: run_scene(lambda: S.gas(2000, frac), steps, bullet=bullet, energy=True,
                                                         repeats=R)
    for e in (0.0, 0.5):
        rows[f"conv{e}"] = lambda e=e: run_scene(lambda: S.converging(200, e), steps, bullet=bullet, energy=True,
                                                 overlap=True, repeats=R)
    for n in (50, 500, 10_000) + (() if q else (100_000,)):
        st = steps if n <= 500 else (steps // 3 if n <= 10_000 else 20)
        rows[f"field{n}"] = lambda n=n, st=st: run_scene(lambda: S.field(n), st, bullet=bullet,
                                                         block=max(2, min(10, st // 4)),
                                                         repeats=5 * R if n <= 500 else (R if n <= 10_000 else 1))
    # (5 runs from a fresh scene: the first step, a few microseconds, is the median of 5 samples)
    rows["head_on"] = lambda: run_scene(S.head_on, 400 if not q else 300, bullet=bullet, block=100,
                                        repeats=5 if not q else 1)
    # the worst cases of issue 24: each one's worst step against pybullet's in the same run
    for key, _, make, n_steps in worst_cases(q):
        rows[key] = lambda make=make, n_steps=n_steps: run_scene(make, n_steps, bullet=bullet, block=5, repeats=R)
    rows["rebuild1000"] = lambda: rebuilds(1000.0, runs=R, bullet=bullet)
    return rows


def warm_up() -> None:
    """Load every compiled kernel before timing (the cold start is measured apart): both solver entry
    points, and enough steps of list scenes that the list is rebuilt, bodies stray and sparse cells are
    filed (and an inelastic scene, whose steps take the TC model's and the jam path's code: the first such
    step of a process runs every line of it for the first time, a once-per-process cost measured apart)."""
    for make, n_steps in ((S.head_on, 3), (lambda: S.gas(200, 0.3), 30), (lambda: S.field(50), 60),
                          (lambda: S.converging(50, 0.0), 40), (lambda: S.mixed_sizes(500, ratio=300.0), 30)):
        d = Drift(make())
        for _ in range(n_steps):
            d.step()
        d.close()


def only(keys: list, rows: dict) -> int:
    """Run some timed rows and print their figures (no report is written)."""
    bad = [k for k in keys if k not in rows]
    if bad:
        raise SystemExit(f"collision_stress --only: unknown row {bad[0]!r}; the rows: {', '.join(rows)}")
    warm_up()
    for key in keys:
        r = rows[key]()
        if key.startswith("rebuild"):
            print(f"{key}: rebuild median {_ms(r['build_median'])} ms (worst {_ms(r['build_worst'])}, "
                  f"{r['builds']} rebuilds), median step {_ms(r['step_median'])} ms: "
                  f"{r['build_median'] / r['step_median']:.2f}x (CPU)")
            continue
        d, p = r["driftframe"], r.get("pybullet", {})
        print(f"{key}: median {_ms(d['median'])} ms, mean {_ms(d['mean'])}, first {_ms(d['first_med'])} "
              f"({d['first_med'] / d['median']:.2f}x the median; CPU {_ms(d['cpu_first'])} = "
              f"{d['cpu_first'] / d['cpu_median']:.2f}x the CPU median, {d['cpu_first'] / d['cpu_next']:.2f}x "
              f"steps 2-5; contacts {d['contacts_first']:g} against "
              f"{d['contacts_median']:g}), worst CPU {_ms(d['cpu_worst'])} ({_tag(d['worst_tag'])}); pybullet mean "
              f"{_ms(p.get('mean', math.nan))}, worst CPU {_ms(p.get('cpu_worst', math.nan))}: worst "
              f"{d['cpu_worst'] / p.get('cpu_worst', math.nan):.2f}x pybullet's")
    return 0


def main(argv=None) -> int:
    parser = common.parser(__doc__.splitlines()[0])
    parser.add_argument("--only", metavar="ROWS", help="run only these timed rows, comma-separated, and print them "
                        "(no report): gas0.3, gas0.45, conv0.0, conv0.5, field50 ... field100000, head_on, struck, "
                        "fast, jammed, mixed, tunnel, graze, break16, rebuild1000")
    args = parser.parse_args(argv)
    import gc
    gc.callbacks.append(_count_gc)
    q = args.quick
    started = time.perf_counter()
    bullet = common.have_pybullet()
    if not bullet:
        print("[collision_stress] pybullet is not installed (pip install -e '.[compare]'): its column is empty")
    rows = timed_rows(q, bullet)
    if args.only:
        return only([k.strip() for k in args.only.split(",") if k.strip()], rows)
    steps = 30 if q else 180
    R = 1 if q else 3
    res = {}
    warm_up()
    for key, measure in rows.items():
        res[key] = measure()
        if key.startswith("gas"):
            res[f"{key}_events"] = run_scene(lambda: S.gas(2000, float(key[3:])), steps // 3, bullet=False,
                                             events=True)
    d = Drift(S.head_on())
    d.step()
    stage = []
    for _ in range(500):
        d.step()
        stage.append(d.w.profile["collision"])
    res["head_on_stage"] = float(np.median(stage))
    d.close()
    # -- first steps --
    res["sc"] = run_scene(lambda: S.crystal("sc", 10), 30 if not q else 5, bullet=bullet, energy=True, block=5)
    res["fcc"] = run_scene(lambda: S.crystal("fcc", 5), 30 if not q else 5, bullet=bullet, energy=True, block=5)
    res["rand10k"] = first_step(lambda: S.random_overlapping(10_000), bullet=bullet)
    res["wedged"] = first_step(lambda: S.wedged(30_000), bullet=False)
    res["wedged"]["driftframe"]["waves"] = res["wedged"]["driftframe"]["stats"]["waves"]
    big = 20_000 if q else 200_000
    res["rand200k"] = child(CHILD_BIG.format(root=str(common.ROOT), n=big, steps=3))
    # -- cold start: empty numba cache (compiles) vs filled --
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NUMBA_CACHE_DIR=tmp)
        res["cold"] = child(CHILD_COLD.format(root=str(common.ROOT)), env=env)
        res["warm"] = child(CHILD_COLD.format(root=str(common.ROOT)), env=env)
    res["load"] = os.getloadavg()
    res["repeats"] = R
    report(res, q, bullet, started)
    return 0


def _ms(x):
    return f"{x * 1e3:.3g}"


def _tag(tag) -> str:
    """A step's ``(collector ran, contacts)`` (run_scene's ``worst_tag``) in words."""
    ran, contacts = tag
    what = "" if contacts < 0 else (f"{contacts} contact{'s' if contacts != 1 else ''}" if contacts else "no contact")
    return ", ".join(x for x in (what, "a collection in it" if ran else "no collection") if x)


def _gas_and_converging_rows(res, bullet, pb, bar) -> list:
    """The main table's rows of the dense gases and the converging scenes (``pb(key, field)``: pybullet's
    figure; ``bar(name, ok, text)`` records each verdict)."""
    rows = []
    for frac in (0.30, 0.45):
        d = res[f"gas{frac}"]["driftframe"]
        ratio = d["mean"] / pb(f"gas{frac}", "mean")
        rmed = d["median"] / pb(f"gas{frac}")
        ev = res[f"gas{frac}_events"]["driftframe"]["median"]
        wr = d["worst_ratio"]
        ok = ratio <= 0.5 and wr <= 5
        noise = res[f"gas{frac}"]["pybullet"]["worst_ratio"] if bullet else float("nan")
        cpu_wr = d["cpu_worst"] / d["cpu_mean"]
        rows.append([f"dense gas 2,000 at {frac:.0%}", f"{_ms(d['median'])} ({_ms(d['mean'])}) / {_ms(d['worst'])}, "
                     f"p99 {_ms(d['p99'])} (events on: {_ms(ev)})",
                     f"{_ms(pb(f'gas{frac}'))} ({_ms(pb(f'gas{frac}', 'mean'))}) / {_ms(pb(f'gas{frac}', 'worst'))}",
                     f"{ratio:.2f} ({rmed:.2f})",
                     f"energy rise {d['rise']:.1e}; worst/mean {wr:.2f} (median of the runs; pybullet's: {noise:.2f}); "
                     f"in CPU time worst {_ms(d['cpu_worst'])} / mean {_ms(d['cpu_mean'])} = {cpu_wr:.2f}",
                     "mean <= 0.5x, worst <= 5x mean",
                     bar(f"gas {frac:.0%}", ok, f"ratio {ratio:.2f}, worst/mean {wr:.2f}, pybullet's worst/mean "
                                               f"{noise:.2f}, in CPU time {cpu_wr:.2f}")])
    for e in (0.0, 0.5):
        d = res[f"conv{e}"]["driftframe"]
        ratio = d["mean"] / pb(f"conv{e}", "mean")
        rmed = d["median"] / pb(f"conv{e}")
        ok = ratio <= 2 and d["worst"] <= 0.020 and d["rise"] <= 1e-12 and d["overlap"] <= 1e-9
        p = res[f"conv{e}"].get("pybullet", {})
        rows.append([f"200 converging, e = {e}", f"{_ms(d['median'])} ({_ms(d['mean'])}) / {_ms(d['worst'])}, "
                     f"p99 {_ms(d['p99'])}, most contacts in a step {d['max_contacts']}",
                     f"{_ms(pb(f'conv{e}'))} ({_ms(pb(f'conv{e}', 'mean'))}) / {_ms(pb(f'conv{e}', 'worst'))}",
                     f"{ratio:.2f} ({rmed:.2f})",
                     f"rise {d['rise']:.1e}, overlap {d['overlap']:.1e} r "
                     f"(pybullet: rise {p.get('rise', math.nan):.1e}, "
                     f"overlap {p.get('overlap', math.nan):.1e} r); warnings: {'; '.join(d['warnings']) or 'none'}",
                     "mean <= 2x, worst <= 20 ms, energy never rises, overlap <= 1e-9 r",
                     bar(f"converging e={e}", ok, f"ratio {ratio:.2f}, worst {_ms(d['worst'])} ms, "
                                                   f"rise {d['rise']:.1e}, "
                                                   f"overlap {d['overlap']:.1e}")])
    return rows


def _first_table(res, limits, bar) -> str:
    """The first step after world.prepare() against the scene's median step (issue 20: at most 2x), a table;
    ``bar(name, ok, text)`` records each verdict."""
    first_rows = []
    named = [(f"gas{f}", f"dense gas 2,000 at {f:.0%}") for f in (0.30, 0.45)] + \
        [(f"conv{e}", f"200 converging, e = {e}") for e in (0.0, 0.5)] + \
        [(f"field{n}", f"field of {n:,} at 5 %") for n in limits if f"field{n}" in res] + \
        [("head_on", "two bodies head on")]

    def first_row(name, d, status):
        ratio = d["cpu_first"] / d["cpu_median"]
        return [name, f"{_ms(d['cpu_first'])} / {_ms(d['first_med'])}", _ms(d["first_worst"]),
                f"{_ms(d['cpu_median'])} / {_ms(d['median'])}", f"{ratio:.2f} ({d['first_med'] / d['median']:.2f})",
                f"{d['cpu_first'] / d['cpu_next']:.2f}", f"{d['contacts_first']:g} / {d['contacts_median']:g}",
                status if status else bar(f"first step {name}", ratio <= 2.0,
                                          f"first {_ms(d['cpu_first'])} ms CPU = {ratio:.2f}x median")]
    for key, name in named:
        first_rows.append(first_row(name, res[key]["driftframe"], None))
    for key, name in (("sc", "touching simple cubic 10x10x10"), ("fcc", "touching FCC 500")):
        first_rows.append(first_row(name, res[key]["driftframe"], "the scene's event (every contact is in step 1): "
                                                                  "its bar is first step <= 50 ms, above"))
    return common.table(["scene", "first step ms, CPU / wall (median of the runs)", "worst first step, wall",
                        "median step ms, CPU / wall", "first / median, CPU (wall)", "first / steps 2-5, CPU",
                        "contacts: first step / median step", "first <= 2x median (CPU)"], first_rows)


def _worst_table(res, quick, bar) -> str:
    """Issue 24: every class's worst step at most 2x pybullet's worst step (CPU time, same run), a table;
    ``bar(name, ok, text)`` records each verdict."""
    worst_rows = []
    for key, name, _, n_steps in worst_cases(quick) + [("conv0.0", "200 converging, e = 0", None, 0)]:
        if key not in res:
            continue
        d, p = res[key]["driftframe"], res[key].get("pybullet", {})
        ratio = d["cpu_worst"] / p.get("cpu_worst", math.nan)
        text = f"worst {_ms(d['cpu_worst'])} ms CPU = {ratio:.2f}x pybullet's"
        row = [name, f"{_ms(d['cpu_worst'])} / {_ms(d['worst'])}", f"{_ms(d['cpu_mean'])} / {_ms(d['mean'])}",
               _ms(d["cpu_first"]), f"{_ms(p.get('cpu_worst', math.nan))} / {_ms(p.get('worst', math.nan))}",
               f"{_ms(p.get('cpu_mean', math.nan))} / {_ms(p.get('mean', math.nan))}",
               _ms(p.get("cpu_first", math.nan)), f"{ratio:.2f}",
               f"{_tag(d['worst_tag'])}; {d['gc_steps']} / {p.get('gc_steps', 0)}",
               bar(f"worst step {name}", ratio <= 2.0, text)]
        if key == "jammed":                        # first contact steps: at most 2x pybullet's first step
            fr = d["cpu_first"] / p.get("cpu_first", math.nan)
            row[-1] += "; first step " + bar("first step of the jammed clump", fr <= 2.0,
                                             f"first {_ms(d['cpu_first'])} ms CPU = {fr:.2f}x pybullet's")
        worst_rows.append(row)
    return common.table(["scene", "driftframe worst ms: CPU / wall", "mean: CPU / wall", "first, CPU",
                        "pybullet worst: CPU / wall", "mean: CPU / wall", "first, CPU",
                        "worst / pybullet's worst (CPU)",
                        "driftframe's worst step; steps with a collection: driftframe / pybullet",
                        "worst <= 2x pybullet's"], worst_rows)


def report(res, quick, bullet, started):
    load = ", ".join(f"{x:.1f}" for x in res.get("load", ()))
    reps = res.get("repeats", 1)
    rows = []
    verdicts = []

    def pb(key, field="median"):
        p = res[key].get("pybullet")
        return p[field] if p else float("nan")

    def bar(name, ok, text):
        verdicts.append((name, "met" if ok else "NOT met", text))
        return "met" if ok else "**not met**"

    rows += _gas_and_converging_rows(res, bullet, pb, bar)
    for key, name in (("sc", "touching simple cubic 10x10x10"), ("fcc", "touching FCC 500")):
        d = res[key]["driftframe"]
        p = res[key].get("pybullet", {})
        ok = d["first"] <= 0.050 and abs(d["change"]) <= 1e-12
        rows.append([name, f"first {_ms(d['first'])}, then {_ms(d['median'])}",
                     f"first {_ms(p.get('first', math.nan))}", f"{d['first'] / p.get('first', math.nan):.2f} (first)",
                     f"energy change {d['change']:.1e} (pybullet {p.get('change', math.nan):+.1e})",
                     "first step <= 50 ms, energy exact to 1e-12",
                     bar(name, ok, f"first {_ms(d['first'])} ms, energy {d['change']:.1e}")])
    d = res["rand10k"]["driftframe"]
    p = res["rand10k"].get("pybullet", {})
    ok = d["first"] <= 0.100 and d["warnings"] == 1
    rows.append(["10,000 at random, overlapping", f"first {_ms(d['first'])} (collision {_ms(d['collision'])})",
                 f"first {_ms(p.get('first', math.nan))}", "", f"{d['stats']['overlaps']} overlapping pairs, "
                 f"{d['warnings']} warning", "first step <= 100 ms, one warning",
                 bar("10k overlapping", ok, f"first {_ms(d['first'])} ms, {d['warnings']} warning")])
    b = res["rand200k"]
    gib = b["rss"] / 2 ** 30
    grew = (b["rss"] - b["before"]) / 2 ** 30
    ok = gib <= 2.0
    rows.append([f"{b['stats'].get('pairs', 0) and ''}{'20,000' if quick else '200,000'} at random, overlapping",
                 f"steps {', '.join(_ms(t) for t in b['times'])}", "", "",
                 f"peak memory {gib:.2f} GiB (the child process's own high-water mark: {b['imported'] / 2 ** 30:.2f} "
                 f"GiB after imports, {b['before'] / 2 ** 30:.2f} GiB with the entities made; the steps added "
                 f"{grew:.2f} GiB); {b['stats']['overlaps']} overlapping pairs; made in {b['made']:.1f} s",
                 "runs; peak memory <= 2 GiB", bar("200k overlapping", ok, f"peak {gib:.2f} GiB")])
    d = res["wedged"]["driftframe"]
    ok = d["first"] <= 0.050
    rows.append(["wedged sphere + 30,000 idle",
                 f"that step {_ms(d['first'])} (collision {_ms(d['collision'])})", "", "",
                 f"{d['waves']} waves; {'; '.join(d['all_warnings'])}", "that step <= 50 ms",
                 bar("wedged", ok, f"step {_ms(d['first'])} ms, {d['waves']} waves")])
    limits = {50: 1.0, 500: 0.25, 10_000: 0.1, 100_000: 0.1}
    for n, lim in limits.items():
        if f"field{n}" not in res:
            continue
        d = res[f"field{n}"]["driftframe"]
        ratio = d["mean"] / pb(f"field{n}", "mean")
        rmed = d["median"] / pb(f"field{n}")
        rows.append([f"field of {n:,} at 5 %", f"{_ms(d['median'])} ({_ms(d['mean'])}) / {_ms(d['worst'])}",
                     f"{_ms(pb(f'field{n}'))} ({_ms(pb(f'field{n}', 'mean'))}) / {_ms(pb(f'field{n}', 'worst'))}",
                     f"{ratio:.2f} ({rmed:.2f})", "",
                     f"mean <= {lim:g}x pybullet", bar(f"field {n}", ratio <= lim, f"ratio {ratio:.2f}")])
    d = res["head_on"]["driftframe"]
    ok = d["median"] <= 30e-6
    rows.append(["two bodies head on", f"{d['median'] * 1e6:.1f} us median (collision stage "
                 f"{res['head_on_stage'] * 1e6:.1f} us) / {d['worst'] * 1e6:.0f} us worst",
                 f"{pb('head_on', 'median') * 1e6:.1f} us", f"{d['median'] / pb('head_on', 'median'):.1f}", "",
                 "<= 30 us per step", bar("head on", ok, f"{d['median'] * 1e6:.1f} us")])
    cold, warm = res["cold"], res["warm"]
    table = common.table(["scene", "driftframe ms: median (mean) / worst", "pybullet ms: median (mean) / worst",
                          "ratio of means (of medians)", "checks",
                          "bar", "status"], rows)
    first_table = _first_table(res, limits, bar)
    rb = res["rebuild1000"]
    rb_ratio = rb["build_median"] / rb["step_median"]
    rebuild_text = (f"{_ms(rb['build_median'])} ms CPU, the median of {rb['builds']} rebuilds (the worst "
                    f"{_ms(rb['build_worst'])}), against a median step of {_ms(rb['step_median'])} ms: "
                    f"{rb_ratio:.2f}x; " + bar("rebuild at a radius ratio of 1,000", rb_ratio <= 2.0,
                                              f"rebuild {rb_ratio:.2f}x the median step"))
    worst_table = _worst_table(res, quick, bar)
    met = sum(v[1] == "met" for v in verdicts)
    missed = ", ".join(f"{n} ({t})" for n, s, t in verdicts if s != "met") or "none"
    body = f"""
Each row: the same scene in driftframe (`world.step()`, movement + collision, events off unless said) and in
pybullet (`stepSimulation()`, as elastic as it goes), in the same process, in turn, in blocks of steps; 180
steps unless the row says otherwise (fields of 10,000: 60 steps; 100,000: 20; crystals: 30, the first step is
the bar). Times in ms: median (mean) / worst step. Ratio: driftframe mean / pybullet mean (the bars are on
means: a neighbour-list rebuild every ~8 steps is in the mean, not the median), with the ratio of medians in
brackets. The machine is shared and noisy (2 cores; load average at the end {load}): single steps of
either engine spike when the scheduler runs another process (a time slice, ~4-5 ms here). So the gas and
converging rows are run {reps} times from a fresh scene, the fields of 50 and 500 {5 * reps} times and of
10,000 {reps} times (100,000: once), each run interleaving both engines, and "mean" is the median over the
runs of each run's mean; the gas rows' worst/mean is the median over the runs of each run's worst step / its
mean, the worst column the worst of all runs. Beside it, the same in CPU time of the stepping thread (what
the step itself cost).
{'' if bullet else 'pybullet is not installed here: its column is empty.'}

{table}

The worst cases (issue 24): scenes of each class the outside measurement found slow, each run
{reps} times interleaved with pybullet; worst and mean step over all the runs, the first step the median
of the runs. The bar is on the worst step in CPU time (the machine is shared). Beside it, what driftframe's
worst step was (its contacts, and whether Python's cyclic garbage collector ran in it) and in how many
steps of each engine the collector ran (gc.callbacks, read outside the timed span). The small rows' worst
step is their contact step, the solver's one call among quiet steps, run with its code and data out of the
CPU's caches (after pybullet's block); small_scenes.md gives the probe's figures. The tunnel sweep's is its
first contact step (step 2, 3 contacts): in a probe, 77-85 us CPU against 24-28 us for the contact steps after
it; 2-8 page faults of the solver's first allocations and a cold solver (its call 33 us against 10) were most
of it. prepare() now runs the solver once on copies also when the first step is quiet (the faults go there):
45-58 us. What is left is the all-pairs solver's machine code (a 600 KB object in the kernel cache) fetched
cold, and the Python around its call (about 6 us over a warm step's).

{worst_table}

Mixed sizes (issue 24): the neighbour list's rebuild at a radius ratio of 1,000 (one sphere of 100 m among
4,000 of 0.1 m, `stress_scenes.mixed_sizes(4000, ratio=1000)`; 40 steps, {reps} runs, in blocks of 5
interleaved with pybullet), the collision system's whole rebuild in CPU time: {rebuild_text}. The large
body tests every body as one block (its block of cells would be more cells than there are bodies); the
sparse grid's cells are found in a hash table with a bitmap of occupied cells, no sort and no copies.

First step after `world.prepare()` (issue 20): the first step of each run from a fresh scene (the world
prepared as a game does when a level has loaded, then stepped at once), the median over the runs, against the
scene's median step, in CPU time of the stepping thread (the bar: what the step itself cost, as the worst-case
bar above; on this shared machine a wall-clock first step is one sample that a time slice of another process
can multiply) and in wall time. prepare() builds the list and its solver's arrays, loads the kernels, runs the
solver once on copies (also where the first step is quiet: its first allocations' page faults are taken
there, not in the first contact step) and then runs the step's built-in stages dry, up to 12 times
(`World._rehearse`: the movement system, the collision system where the coming step is quiet, the commit
writing back the bytes the tables hold; through `World.step` and the systems' own `process`, no other
system, no change of state). What a slow first step was made of, before the dry steps: the same calls as the
later steps (sys.setprofile), no page fault (getrusage), no collection; the step's code and data out of the
CPU's caches, its branches untrained, after the load's other work (the head-on pair: 18-23 us CPU against
4-5 us; with a step of another fresh world of the same scene just before it 8-10 us, after 64 MB of other
data 84-95 us), and in a fresh process the interpreter itself: CPython 3.11 quickens a code object after 8
calls and then specialises it (the head-on pair's first step in a fresh process with its kernels cached:
58 us without the dry steps, 11-14 us after 12). Dry steps of stand-ins that called the systems' code
left the first step at 2.0x its median, dry steps of the systems themselves 1.6-1.9x; a world's second step
is itself 1.2-1.4x: what is left is what the caches and branch predictors need beyond a few passes. The
column "first / steps 2-5" tells set-up work from the scene's own: a gas at 45 % starts with its busiest
steps (648 contacts in the first, 1,200-1,300 in each of the next three, which cost more than the first: its
excess over the median step is its contacts, at no more than the cost per contact of the steps after it, and
no set-up work is left in it to remove; its bar, read as written, is not met; what a contact costs there:
`docs/bench/dense_contacts.md`).

{first_table}

**Bars met: {met} of {len(verdicts)}.** Not met: {missed}.

Cold start (numba compiles the contact kernels on the first run on a machine and caches them in the
per-user kernel cache): first step of a fresh process with an empty cache {cold['first']:.1f} s
(the whole process {cold['total']:.1f} s); with the cache filled {warm['first'] * 1e3:.0f} ms
(a 2-body scene after it: {warm['first_small'] * 1e3:.1f} ms).

First steps (the wedged row, the crystals, the overlapping fields) are timed after the world's one-time
work for freshly made entities: the table sync and query build (esper's cost, which any system pays once
at load) and `World.prepare()` (each system's packed rows and buffers, which a game builds when a level has
loaded). They include the neighbour list's first build, which needs the step's own state.
"""
    chart(res, rows, verdicts)
    common.write_section("collision_stress", "Collisions at any density: stress scenes vs pybullet", body,
                         quick=quick, started=started)
    print("\n".join(f"[collision_stress] {n}: {s} ({t})" for n, s, t in verdicts))


def chart(res, rows, verdicts):
    fig, ax = common.figure(figsize=(10, 5))
    names, ratios, colours = [], [], []
    for key, label in (("gas0.3", "gas 30 %"), ("gas0.45", "gas 45 %"), ("conv0.0", "conv e=0"),
                       ("conv0.5", "conv e=0.5"), ("field50", "field 50"), ("field500", "field 500"),
                       ("field10000", "field 10k"), ("field100000", "field 100k"), ("head_on", "head on")):
        if key in res and "pybullet" in res[key]:
            d, p = res[key]["driftframe"], res[key]["pybullet"]
            names.append(label)
            ratios.append(d["mean"] / p["mean"])
    bars = {"gas 30 %": 0.5, "gas 45 %": 0.5, "conv e=0": 2, "conv e=0.5": 2, "field 50": 1, "field 500": 0.25,
            "field 10k": 0.1, "field 100k": 0.1, "head on": None}
    for nm, r in zip(names, ratios):
        b = bars.get(nm)
        colours.append("#2ca02c" if b is None or r <= b else "#d62728")
    ax.bar(names, ratios, color=colours)
    for k, nm in enumerate(names):
        b = bars.get(nm)
        if b:
            ax.plot([k - 0.4, k + 0.4], [b, b], "k--", lw=1)
    ax.axhline(1.0, color="grey", lw=0.8)
    ax.set_yscale("log")
    ax.set_ylabel("driftframe mean step / pybullet mean step")
    ax.set_title("Stress scenes: time per step relative to pybullet (dashed: the bar; green: met)")
    common.save_chart(fig, "collision_stress")


if __name__ == "__main__":
    sys.exit(main())
