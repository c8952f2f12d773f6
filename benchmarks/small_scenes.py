"""Small scenes (issue 20): what does a step of 2 to 50 bodies cost, driftframe against pybullet?

Scenes (dt = 1/60 s; spheres of radius 0.5 m and 1 kg, restitution 1, unless said):

* head-on pair: 4 m apart, closing at 2 m/s (they meet after 1.5 s and part);
* touching pair: touching, moving together at 0.5 m/s (in contact at every step, nothing to resolve);
* cradle of 5: five touching balls struck by a sixth at 3 m/s (the cradle demo's bodies);
* 8 bodies: radii 0.25-0.75 m, mass r^3, at 20 % volume fraction, random velocities up to 3 m/s
  per axis (``stress_scenes.field(8, 0.2)``);
* 16-ball break: the billiards demo's rack of 15 touching balls and the cue ball at 12 m/s;
* field of 50: ``stress_scenes.field(50)`` at 5 %, as in ``collision_stress``.

driftframe: a World with ``driftframe.app.simulation_systems()`` (the standard per-step systems: input,
autopilot, control, rotation assist, gravity, movement, spin, collision, warp governor; events on), the
bodies made in bulk, then ``world.prepare()``, as a game does when a level has loaded. pybullet:
``stepSimulation()`` set up as in ``collision_scaling`` (as elastic as it goes: restitution 1,
threshold 0, no friction, no damping, no sleeping, ``contactERP = 0``; Bullet multiplies the two
bodies' restitutions, so each gets sqrt(e)).

Each round builds both anew, each one's first step timed right after its own build, then steps them in turn, a
block of steps each (driftframe first in even rounds, pybullet first in odd ones), every step timed in CPU time
of this thread and in wall time; the clock's own cost (two back-to-back reads, calibrated in the same
run) is taken off each step. Median and worst step are over the steps after the first of all rounds;
"mean, first included" is each round's mean over all its steps, the median of the rounds.

Bars (issue 20): a step of the head-on pair costs at most 3x pybullet's CPU time (goal: 1x); the
16-ball break and the field of 50 cost at most 1x pybullet's mean step, first step included.
"""
from __future__ import annotations

import os
import statistics
import sys
import time
import warnings

import numpy as np

from benchmarks import common
from benchmarks import stress_scenes as S

DT = 1.0 / 60.0
STAGE_STEPS = 3000


def head_on():
    return S.head_on()


def touching():
    x = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    v = np.array([[0.5, 0, 0], [0.5, 0, 0]])
    return x, v, np.full(2, 0.5), np.ones(2), np.ones(2)


def cradle():
    from driftframe.demos import cradle as demo
    x = np.array([(2 * demo.R * k, 0.0, 0.0) for k in range(5)] + [(-4.0, 0.0, 0.0)])
    v = np.zeros((6, 3))
    v[5] = (3.0, 0.0, 0.0)
    return x, v, np.full(6, demo.R), np.ones(6), np.ones(6)


def eight():
    return S.field(8, 0.2)


def billiard_break():
    from driftframe.demos import billiards as demo
    x = np.concatenate([demo.rack(), [(-8.0, 0.0, 0.0)]])
    v = np.zeros((16, 3))
    v[15] = (demo.SPEED, 0.0, 0.0)
    return x, v, np.full(16, demo.R), np.ones(16), np.ones(16)


def field50():
    return S.field(50)


#: (key, label, scene, steps per round)
SCENES = [("head_on", "head-on pair", head_on, 300), ("touching", "touching pair", touching, 300),
          ("cradle", "cradle of 5", cradle, 300), ("eight", "8 bodies", eight, 300),
          ("break", "16-ball break", billiard_break, 360), ("field50", "field of 50", field50, 180)]


class Drift:
    """The scene in a World with the standard per-step systems, prepared."""

    def __init__(self, scene):
        from driftframe.app import simulation_systems
        from driftframe.components.body import Mass, Transform, Velocity
        from driftframe.components.collision import SphereCollider
        from driftframe.framework.world import World

        x, v, r, m, e = scene
        n = len(x)
        self.w = World(dt=DT)
        for system in simulation_systems():
            self.w.add_system(system)
        self.w.create_entities(Transform.bulk(n, position=x), Velocity.bulk(n, linear=v), Mass.bulk(n, kg=m),
                               SphereCollider.bulk(n, radius=r, restitution=e))
        self.w.prepare()
        self.step = self.w.step
        from driftframe.systems.collision import CollisionSystem
        (cs,) = [s for stage in self.w.systems.values() for s in stage if isinstance(s, CollisionSystem)]
        self.contacts = lambda: cs.stats["contacts"]     # (read after a step, outside its timing)

    def close(self):
        self.w.close()


class Bullet:
    """The same bodies in pybullet (see the module docstring)."""

    def __init__(self, scene):
        self.pb, self.cid, _ = common.pybullet_spheres(scene, DT)
        step, cid = self.pb.stepSimulation, self.cid
        self.step = lambda: step(physicsClientId=cid)

    def close(self):
        self.pb.disconnect(physicsClientId=self.cid)


def clock_cost(n: int = 20000) -> tuple[int, int]:
    """Nanoseconds two back-to-back reads of each clock (thread CPU, wall) differ by: the median."""
    cpu, wall = time.thread_time_ns, time.perf_counter_ns
    c = [-(cpu() - cpu()) for _ in range(n)]
    w = [-(wall() - wall()) for _ in range(n)]
    return int(statistics.median(c)), int(statistics.median(w))


#: collections of Python's cyclic garbage collector so far (counted by _count_gc once main() has hooked it)
GC_RUNS = [0]


def _count_gc(phase: str, info: dict) -> None:
    if phase == "stop":
        GC_RUNS[0] += 1


def timed_steps(step, k: int, cpu_out: list, wall_out: list, cost: tuple[int, int], gc_out: list | None = None,
                contacts=None, contacts_out: list | None = None) -> None:
    """``k`` calls of ``step``, each one's CPU and wall nanoseconds (less the clocks' own cost) appended, to
    ``gc_out`` whether the garbage collector ran during it and to ``contacts_out`` ``contacts()`` after it
    (-1: no ``contacts``), both read outside the timed span. (Only ints and bools are kept: an object the
    collector tracks, a tuple, kept per step would itself start a collection every 700 steps.)"""
    cpu, wall = time.thread_time_ns, time.perf_counter_ns
    c0, w0 = cost
    runs = GC_RUNS
    for _ in range(k):
        g = runs[0]
        c = cpu()
        w = wall()
        step()
        w = wall() - w
        c = cpu() - c
        cpu_out.append(max(c - c0, 0))
        wall_out.append(max(w - w0, 0))
        if gc_out is not None:
            gc_out.append(runs[0] != g)
            contacts_out.append(contacts() if contacts is not None else -1)


def run_scene(make, steps: int, rounds: int, block: int, engines: list[str], cost) -> dict:
    """The rounds of one scene (see the module docstring): per engine, per-step CPU and wall (ns)."""
    out = {k: {"cpu": [], "wall": [], "gc": [], "contacts": [], "first_cpu": [], "first_wall": [], "mean_cpu": [],
               "mean_wall": []} for k in engines}
    for rnd in range(rounds):
        scene = make()
        order = engines if rnd % 2 == 0 else engines[::-1]
        sims = {}
        run = {k: ([], []) for k in order}
        gcs = {k: [] for k in order}
        cts = {k: [] for k in order}
        for k in order:            # each engine's first step right after its own build (a game's first frame)
            sims[k] = (Drift if k == "driftframe" else Bullet)(scene)
            timed_steps(sims[k].step, 1, *run[k], cost, gcs[k], getattr(sims[k], "contacts", None), cts[k])
        done = 1
        while done < steps:
            k_steps = min(block, steps - done)
            for k in order:
                timed_steps(sims[k].step, k_steps, *run[k], cost, gcs[k], getattr(sims[k], "contacts", None), cts[k])
            done += k_steps
        for k in order:
            cpu, wall = run[k]
            o = out[k]
            o["first_cpu"].append(cpu[0])
            o["first_wall"].append(wall[0])
            o["cpu"] += cpu[1:]
            o["wall"] += wall[1:]
            o["gc"] += gcs[k][1:]
            o["contacts"] += cts[k][1:]
            o["mean_cpu"].append(sum(cpu) / len(cpu))
            o["mean_wall"].append(sum(wall) / len(wall))
            sims[k].close()
    res = {}
    for k, o in out.items():
        worst = max(range(len(o["cpu"])), key=o["cpu"].__getitem__)
        res[k] = {"median_cpu": statistics.median(o["cpu"]), "worst_cpu": o["cpu"][worst],
                  "gc_steps": sum(o["gc"]), "steps": len(o["gc"]), "worst_gc": o["gc"][worst],
                  "worst_contacts": o["contacts"][worst],
                  "median_wall": statistics.median(o["wall"]), "worst_wall": max(o["wall"]),
                  "first_cpu": statistics.median(o["first_cpu"]), "first_wall": statistics.median(o["first_wall"]),
                  "mean_cpu": statistics.median(o["mean_cpu"]), "mean_wall": statistics.median(o["mean_wall"])}
    return res


def stages(steps: int) -> dict:
    """Where a step of the head-on pair goes: the median over ``steps`` steps of the wall microseconds of
    ``world.step()`` and of each line of ``World.profile`` that is not zero."""
    d = Drift(head_on())
    d.step()
    clock = time.perf_counter
    lines: dict[str, list] = {"step": []}
    for _ in range(steps):
        t = clock()
        d.step()
        lines["step"].append(clock() - t)
        for k, v in d.w.profile.items():
            if v:
                lines.setdefault(k, []).append(v)
    d.close()
    return {k: statistics.median(v) * 1e6 for k, v in lines.items()}


def empty_world(steps: int, cost) -> tuple[float, list[str]]:
    """A world with the standard per-step systems and no entity: the median CPU nanoseconds of a step
    (less the clock's cost) and the systems it calls (those with nothing to do are not called)."""
    from driftframe.app import simulation_systems
    from driftframe.framework.world import World

    w = World(dt=DT)
    for system in simulation_systems():
        w.add_system(system)
    w.prepare()
    w.step()
    cpu, wall = [], []
    timed_steps(w.step, steps, cpu, wall, cost)
    called = [k for k, v in w.profile.items() if v]
    w.close()
    return statistics.median(cpu), called


def main(argv=None) -> int:
    args = common.parser(__doc__.splitlines()[0]).parse_args(argv)
    started = time.perf_counter()
    bullet = common.have_pybullet()
    if not bullet:
        print("[small_scenes] pybullet is not installed (pip install -e '.[compare]'): its column is empty")
    engines = ["driftframe"] + (["pybullet"] if bullet else [])
    rounds = 2 if args.quick else 9
    load = [os.getloadavg()]
    import gc
    gc.callbacks.append(_count_gc)
    warnings.simplefilter("ignore", RuntimeWarning)    # (the cradle's and the rack's touching balls)
    # load every kernel a small scene runs before timing (the cold start is startup's question, not this one)
    for _, _, make, _ in SCENES:
        d = Drift(make())
        d.step()
        d.w.step(30)
        d.close()
    cost = clock_cost()
    res = {}
    for key, label, make, steps in SCENES:
        res[key] = run_scene(make, steps // 3 if args.quick else steps, rounds, 25, engines, cost)
        d = res[key]["driftframe"]
        print(f"[small_scenes] {label}: driftframe {d['median_cpu'] / 1e3:.1f} us CPU a step"
              + (f", pybullet {res[key]['pybullet']['median_cpu'] / 1e3:.1f} us" if bullet else ""), flush=True)
    res["stages"] = stages(STAGE_STEPS)
    res["empty"] = empty_world(STAGE_STEPS, cost)
    load.append(os.getloadavg())
    report(res, bullet, cost, rounds, load, args.quick, started)
    return 0


def _us(ns: float) -> str:
    return f"{ns / 1e3:.3g}"


def report(res, bullet, cost, rounds, load, quick, started) -> None:
    rows = []
    verdicts = []
    for key, label, _, steps in SCENES:
        d = res[key]["driftframe"]
        p = res[key].get("pybullet")

        def cell(x):
            return (f"{_us(x['median_cpu'])} / {_us(x['worst_cpu'])} / {_us(x['first_cpu'])} / "
                    f"{_us(x['mean_cpu'])}")
        row = [label, cell(d), cell(p) if p else "", f"{_us(d['median_wall'])} / {_us(p['median_wall'])}" if p
               else _us(d["median_wall"])]
        if p:
            med = d["median_cpu"] / p["median_cpu"]
            mean = d["mean_cpu"] / p["mean_cpu"]
            row += [f"{med:.2f}", f"{mean:.2f}", f"{d['first_cpu'] / p['first_cpu']:.2f}"]
            if key == "head_on":
                status = "met" if med <= 3 else "NOT met"
                verdicts.append(f"head-on pair, a step at most 3x pybullet's CPU time: **{status}** ({med:.2f}x; "
                                f"the goal, 1x: {'met' if med <= 1 else 'not met'})")
            if key in ("break", "field50"):
                status = "met" if mean <= 1 else "NOT met"
                verdicts.append(f"{label}, mean step with the first at most 1x pybullet's: **{status}** ({mean:.2f}x)")
        else:
            row += ["", "", ""]
        rows.append(row)
    table = common.table(["scene", "driftframe us CPU: median / worst / first / mean (first included)",
                          "pybullet us CPU: the same", "median wall us: driftframe / pybullet",
                          "CPU ratio: median", "mean (first included)", "first"], rows)
    # what each scene's worst step was (issue 24): a step with contacts or a quiet one, and whether Python's
    # cyclic garbage collector ran in it; and how many timed steps of each engine it ran in
    worst_lines = []
    for key, label, _, _ in SCENES:
        d = res[key]["driftframe"]
        p = res[key].get("pybullet")
        kind = f"a step with {d['worst_contacts']} contact{'s' if d['worst_contacts'] != 1 else ''}" \
            if d["worst_contacts"] > 0 else "a step without contact"
        worst_lines.append(f"{label}: driftframe's worst ({_us(d['worst_cpu'])} us) was {kind}"
                           f"{', with a collection' if d['worst_gc'] else ', no collection in it'}; the collector "
                           f"ran in {d['gc_steps']} of its {d['steps']} timed steps"
                           + (f", in {p['gc_steps']} of pybullet's {p['steps']}" if p else ""))
    st = dict(res["stages"])
    whole = st.pop("step")
    empty_ns, empty_called = res["empty"]
    where = ", ".join(f"{k} {v:.2g}" for k, v in st.items())
    loads = " -> ".join(", ".join(f"{x:.1f}" for x in la) for la in load)
    steps = ", ".join(f"{label} {s}" for _, label, _, s in SCENES)
    body = f"""
Per-step CPU time of this thread, in microseconds, of `world.step()` with the standard per-step systems
(`driftframe.app.simulation_systems()`, events on, after `world.prepare()`) and of pybullet's
`stepSimulation()` (the tuned elastic setup of `collision_scaling`), the same scenes in the same process,
stepped in turn in blocks of 25 steps; {rounds} rounds, each from a fresh build ({steps} steps a round).
Median and worst: over every step after the first. First: the first step of a fresh build, median of the
rounds, each engine's taken right after its own build (driftframe's after `world.prepare()`, which ends
with dry steps of the built-in stages: collision_stress.md's "First step"), before the other engine is
built; the blocks follow. Mean: each round's mean step with its first step included, median of the rounds. The clocks' own
cost ({cost[0]} ns for two reads of the thread's CPU clock, {cost[1]} ns of the wall clock, measured in the
same run) is taken off every step. Load average (1, 5, 15 min) before -> after: {loads}.
{'' if bullet else 'pybullet is not installed here: its columns are empty.'}

{table}

{chr(10).join('- ' + v for v in verdicts)}

The worst steps (issue 24's question: what is a small scene's worst step made of?):

{chr(10).join('- ' + v for v in worst_lines)}

A worst step with contacts is the scene's contact step (the solver's one call among quiet steps): its code
and data are out of the CPU's caches when it comes, after pybullet's block and many steps that do not run it.
A worst step without contact or collection runs the same code as the median step (the field of 50 also
rebuilds its neighbour list every few steps): such spikes hit pybullet's steps alike (its worst column, against
medians of 1.5-35 us): likely time the shared virtual machine charges to the thread (this VM reports steal time). In a
probe (the head-on pair's contact step, CPU time, one process): about 25 us when the same step has just run,
about 160-260 us after pybullet's 5 steps or after touching 64 MB of other data; no page fault (getrusage) and no
collection in it (gc.callbacks). That step's numpy fancy indexing (the changed bodies' end of step) and the
solver's dispatch and result records were most of the difference and are compiled calls now (quiet_step.
write_changed, the solver's entry point); the solver's own code (about 45 us cold) remains. A quiet step
costs 80-95 us after the same eviction: every step pays for cold caches, the contact step most. Python's
garbage collector: a step of these scenes keeps no object it tracks (1,000 quiet steps: 4 net container
allocations), so the collector runs in a step only when work outside the steps (building and closing the
rounds' worlds: 100-150 objects in reference cycles each; or a caller keeping a tuple a step) has filled its
first generation; that step then pays for the collection (86-284 us in a probe that kept a tuple a step).
The lines above say whether it happened in this run (this benchmark keeps only ints and bools per step).

Where a step of the head-on pair goes (wall time, us, median of {STAGE_STEPS} steps after the first):
`world.step()` {whole:.3g}, of which {where} (the profile's lines of the systems that ran: those with
nothing to do are not called; each line runs from the end of the system before, so it holds the step
loop's bookkeeping for its system too); the rest is the step's start. On a step where no pair meets (all
but a few), the collision stage is one compiled call that gathers the bodies and tests every pair, and
the Python around it; the movement stage the step context's opening and one compiled call (free flight,
framework/free_flight.py); the commit one byte copy of the positions. Both compiled calls go straight to
the kernel's entry point for the types set up in `world.prepare()` (`kernels.entry`), past numba's dispatch.

An empty world with the same standard systems (no entity) costs {empty_ns / 1e3:.2f} us CPU a step
(median of {STAGE_STEPS}); it calls {', '.join(empty_called) or 'no system'} (the systems whose
``requires`` no entity meets, the input system without a pilot, track or press and the warp governor
without a TimeWarp are not called).
"""
    chart(res, bullet)
    common.write_section("small_scenes", "Small scenes: per-step cost of 2 to 50 bodies vs pybullet", body,
                         quick=quick, started=started)


def chart(res, bullet) -> None:
    fig, ax = common.figure(figsize=(10, 4.5))
    labels = [label for _, label, _, _ in SCENES]
    xs = np.arange(len(labels))
    engines = [("driftframe", "#2ca02c")] + ([("pybullet", "#1f77b4")] if bullet else [])
    width = 0.8 / len(engines)
    for k, (eng, colour) in enumerate(engines):
        med = [res[key][eng]["median_cpu"] / 1e3 for key, _, _, _ in SCENES]
        first = [res[key][eng]["first_cpu"] / 1e3 for key, _, _, _ in SCENES]
        pos = xs + (k - (len(engines) - 1) / 2) * width
        ax.bar(pos, med, width, color=colour, label=f"{eng}: median step")
        ax.plot(pos, first, "v", color="k", ms=5, label="first step" if k == 0 else None)
    ax.set_xticks(xs)
    ax.set_xticklabels(labels)
    ax.set_yscale("log")
    ax.set_ylabel("CPU time per step (us)")
    ax.set_title("Small scenes: per-step CPU time, driftframe (standard systems) vs pybullet")
    ax.legend(fontsize=8, loc="upper center", ncol=3)
    common.save_chart(fig, "small_scenes")


if __name__ == "__main__":
    sys.exit(main())
