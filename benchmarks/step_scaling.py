"""Movement + spin time per step against the number of bodies, vectorised vs a per-entity loop.

The vectorised path is the real thing: a ``World`` with ``MovementSystem`` and
``SpinSystem``, bodies made by bulk creation (``Transform.bulk`` etc. +
``world.create_entities``), timed through ``world.step()``. The baselines do the
same work (``x += v dt``; an exact axis-angle rotation of each body's frame)
with a per-entity esper loop, as a user would write it, in the same process:

* ``loop, component API``: reads and writes through the components' fields
  (``tf.position = tf.position + vel.linear * dt``; the new quaternion built
  with the ``math`` module and assigned to ``tf.orientation``) -- each write is
  validated, as every public setter in driftframe is;
* ``loop, lean``: the same arithmetic in plain floats, written in place into
  the component's row views (``p[:] = ...``), skipping validation -- the
  fastest per-entity loop a careful user could write with these components.

Both loops are checked to give the vectorised result (to 1e-12) before they
are timed. Every step is timed on its own, in wall and CPU time: the table gives
the median step and the worst one beside it, and the load average of the run.
Bar (issue 2): at least 30x faster than the loop at 10,000 bodies,
and cost growing linearly in N.
"""
from __future__ import annotations

import gc
import math
import os
import statistics
import time

import esper
import numpy as np

from benchmarks import common
from driftframe.components.body import AngularVelocity, Transform, Velocity
from driftframe.framework.world import World
from driftframe.systems.movement import MovementSystem
from driftframe.systems.spin import SpinSystem

DT = 1.0 / 60.0


# ---------------------------------------------------------------------------- per-entity baselines

class LoopMovement(esper.Processor):
    """Reads Velocity; writes Transform.position.  x += v dt, one entity at a time (component API)."""

    stage = "movement"

    def process(self, dt):
        for _, (tf, vel) in esper.get_components(Transform, Velocity):
            tf.position = tf.position + vel.linear * dt


class LoopSpin(esper.Processor):
    """Reads AngularVelocity; writes Transform.orientation.  q' = exp(w dt/2) q, one entity at a time."""

    stage = "spin"

    def process(self, dt):
        sqrt, sin, cos = math.sqrt, math.sin, math.cos
        for _, (tf, spin) in esper.get_components(Transform, AngularVelocity):
            wx, wy, wz = spin.angular.tolist()
            rate = sqrt(wx * wx + wy * wy + wz * wz)
            if rate == 0.0:
                continue
            half = 0.5 * rate * dt                     # rotate by rate*dt about w/rate
            k = sin(half) / rate
            ax, ay, az, aw = wx * k, wy * k, wz * k, cos(half)
            bx, by, bz, bw = tf.orientation.tolist()
            x = aw * bx + ax * bw + ay * bz - az * by
            y = aw * by - ax * bz + ay * bw + az * bx
            z = aw * bz + ax * by - ay * bx + az * bw
            w = aw * bw - ax * bx - ay * by - az * bz
            n = sqrt(x * x + y * y + z * z + w * w)
            tf.orientation = (x / n, y / n, z / n, w / n)


class LeanLoopMovement(esper.Processor):
    """Reads Velocity; writes Transform.position.  x += v dt, plain floats, one field write per body."""

    stage = "movement"

    def process(self, dt):
        for _, (tf, vel) in esper.get_components(Transform, Velocity):
            vx, vy, vz = vel.linear.tolist()
            px, py, pz = tf.position.tolist()
            tf.position = (px + vx * dt, py + vy * dt, pz + vz * dt)


class LeanLoopSpin(LoopSpin):
    """Reads AngularVelocity; writes Transform.orientation.  As LoopSpin, plain floats throughout."""

    def process(self, dt):
        sqrt, sin, cos = math.sqrt, math.sin, math.cos
        for _, (tf, spin) in esper.get_components(Transform, AngularVelocity):
            wx, wy, wz = spin.angular.tolist()
            rate = sqrt(wx * wx + wy * wy + wz * wz)
            if rate == 0.0:
                continue
            half = 0.5 * rate * dt
            k = sin(half) / rate
            ax, ay, az, aw = wx * k, wy * k, wz * k, cos(half)
            bx, by, bz, bw = tf.orientation.tolist()
            x = aw * bx + ax * bw + ay * bz - az * by
            y = aw * by - ax * bz + ay * bw + az * bx
            z = aw * bz + ax * by - ay * bx + az * bw
            w = aw * bw - ax * bx - ay * by - az * bz
            n = sqrt(x * x + y * y + z * z + w * w)
            tf.orientation = (x / n, y / n, z / n, w / n)


VARIANTS = {
    "vectorised": (MovementSystem, SpinSystem),
    "loop, component API": (LoopMovement, LoopSpin),
    "loop, lean": (LeanLoopMovement, LeanLoopSpin),
}


# ---------------------------------------------------------------------------- scenes

def scene_arrays(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Positions (m), velocities (m/s), random orientations, spins of 0.1-5 rad/s about random axes."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return {"position": rng.uniform(-1000, 1000, (n, 3)), "orientation": q,
            "velocity": rng.normal(0, 20, (n, 3)), "spin": axis * rng.uniform(0.1, 5.0, (n, 1))}


def build(n: int, variant: str, arrays=None) -> tuple[World, list[int], dict[str, float]]:
    """A World with ``n`` bodies made by bulk creation and the variant's systems; set-up timings (s)."""
    a = arrays if arrays is not None else scene_arrays(n)
    world = World(dt=DT)
    t = {}
    t0 = time.perf_counter()
    tfs = Transform.bulk(n, position=a["position"], orientation=a["orientation"])
    vels = Velocity.bulk(n, linear=a["velocity"])
    spins = AngularVelocity.bulk(n, angular=a["spin"])
    t1 = time.perf_counter()
    ents = world.create_entities(tfs, vels, spins)
    t2 = time.perf_counter()
    move, spin = VARIANTS[variant]
    world.add_system(move())
    world.add_system(spin())
    t["bulk components"] = t1 - t0
    t["create_entities"] = t2 - t1
    return world, ents, t


def state(ents) -> tuple[np.ndarray, np.ndarray]:
    pos = np.array([esper.component_for_entity(e, Transform).position for e in ents])
    q = np.array([esper.component_for_entity(e, Transform).orientation for e in ents])
    return pos, q


def check_loops_match(n: int = 500, steps: int = 20) -> float:
    """Every variant, same scene, ``steps`` steps: the largest difference from the vectorised result."""
    arrays = scene_arrays(n, seed=5)
    results = {}
    for variant in VARIANTS:
        world, ents, _ = build(n, variant, arrays)
        try:
            world.step(steps)
            results[variant] = state(ents)
        finally:
            world.close()
    ref = results["vectorised"]
    worst = 0.0
    for variant, (pos, q) in results.items():
        worst = max(worst, float(np.abs(pos - ref[0]).max()), float(np.abs(q - ref[1]).max()))
    if worst > 1e-12:
        raise AssertionError(f"per-entity loops disagree with the systems by {worst:.3g}")
    return worst


class _GcClock:
    """CPU seconds spent in Python's garbage collector so far (``gc.callbacks``), to tell a worst step
    that a collection landed in from one the step's own work made slow."""

    def __init__(self):
        self.total = 0.0
        self._t0 = 0.0

    def __call__(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._t0 = time.process_time()
        else:
            self.total += time.process_time() - self._t0


GC_CLOCK = _GcClock()


def _sample(world: World, number: int) -> tuple[float, ...]:
    """``number`` steps, each timed on its own: the mean seconds per step in wall and CPU time
    (``time.process_time``), the movement and spin stages' mean share (world.profile, wall), the
    worst single step in wall and in CPU time, and the CPU time the garbage collector took inside that
    worst CPU step. Each step's two clock reads (~0.35 us) are inside."""
    wall, cpu = time.perf_counter, time.process_time
    m = s = 0.0
    worst_w = worst_c = worst_gc = 0.0
    w_start, c_start = wall(), cpu()
    w0, c0 = w_start, c_start
    for _ in range(number):
        g0 = GC_CLOCK.total
        world.step()
        w1, c1 = wall(), cpu()
        worst_w = max(worst_w, w1 - w0)
        if c1 - c0 > worst_c:
            worst_c, worst_gc = c1 - c0, GC_CLOCK.total - g0
        w0, c0 = w1, c1
        m += world.profile["movement"]
        s += world.profile["spin"]
    return ((w0 - w_start) / number, (c0 - c_start) / number, m / number, s / number, worst_w, worst_c,
            worst_gc)


#: What :func:`time_interleaved` gives for each variant, by name.
FIELDS = ("wall", "cpu", "movement", "spin", "worst_wall", "worst_cpu", "worst_cpu_gc")


def time_interleaved(worlds: dict[str, World], repeats: dict[str, int], min_sample: float = 0.05):
    """Seconds per ``world.step()`` of each world, samples taken in turn (A, B, C, A, B, C, ...)
    so that a change in machine load hits every variant alike and the ratios stay fair.

    Each sample runs enough steps to last about ``min_sample`` seconds (at least one), as long as a warm
    step took; the two steps before (the first warms, the second is timed for that) are not counted.
    Returns {variant: {field: seconds}} with the fields of :data:`FIELDS`: the median over the samples
    of each sample's mean step (wall, CPU, and the movement and spin stages), the worst single step of
    all samples (wall, CPU) and the garbage collector's CPU time inside the worst CPU step.
    """
    number = {}
    for v, world in worlds.items():
        world.step()                                   # warm: caches built, code paths hot
        t0 = time.perf_counter()
        world.step()                                   # the sample's length from a warm step
        number[v] = max(1, int(min_sample / max(time.perf_counter() - t0, 1e-6)))
    samples = {v: [] for v in worlds}
    for r in range(max(repeats.values())):
        for v, world in worlds.items():
            if r < repeats[v]:
                samples[v].append(_sample(world, number[v]))
    out = {}
    for v in worlds:
        got = {f: statistics.median(x[i] for x in samples[v]) for i, f in enumerate(FIELDS[:4])}
        got["worst_wall"] = max(x[4] for x in samples[v])
        worst = max(samples[v], key=lambda x: x[5])      # the worst CPU step, and the collector's part in it
        got["worst_cpu"], got["worst_cpu_gc"] = worst[5], worst[6]
        got["steps"] = number[v] * len(samples[v])
        out[v] = got
    return out


def setup_timings(n: int, repeats: int) -> dict[str, float]:
    """Medians (s) of bulk creation, create_entities and the first step for ``n`` bodies."""
    arrays = scene_arrays(n, seed=9)
    rows = []
    for _ in range(repeats):
        gc.collect()
        world, ents, t = build(n, "vectorised", arrays)
        try:
            t0 = time.perf_counter()
            world.step()
            t["first step"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            world.step()
            t["second step"] = time.perf_counter() - t0
        finally:
            world.close()
            del world, ents
        rows.append(t)
    return {k: statistics.median(r[k] for r in rows) for k in rows[0]}


def per_entity_creation(n: int) -> float:
    """Seconds to create ``n`` bodies one at a time with the components' constructors."""
    a = scene_arrays(n, seed=9)
    world = World(dt=DT)
    try:
        t0 = time.perf_counter()
        for i in range(n):
            world.create_entity(Transform(a["position"][i], a["orientation"][i]),
                                Velocity(a["velocity"][i]), AngularVelocity(a["spin"][i]))
        return time.perf_counter() - t0
    finally:
        world.close()


def main(argv=None) -> int:
    args = common.parser(__doc__.splitlines()[0]).parse_args(argv)
    quick = args.quick
    sizes = [50, 1_000, 10_000] if quick else [50, 1_000, 10_000, 100_000]
    repeats = 3 if quick else 15
    loop_repeats = {50: repeats, 1_000: repeats, 10_000: 3 if quick else 5, 100_000: 3}
    setup_n = 10_000 if quick else 100_000
    t_start = time.perf_counter()
    load0 = os.getloadavg()
    gc.callbacks.append(GC_CLOCK)

    worst = check_loops_match()
    print(f"[step_scaling] per-entity loops match the systems to {worst:.1e}")

    per_step = {v: {} for v in VARIANTS}          # median wall s/step
    got = {v: {} for v in VARIANTS}               # every field of time_interleaved, by n
    for n in sizes:
        arrays = scene_arrays(n)
        gc.collect()
        worlds = {v: build(n, v, arrays)[0] for v in VARIANTS}
        try:
            res = time_interleaved(worlds, {v: repeats if v == "vectorised" else loop_repeats[n] for v in VARIANTS})
        finally:
            for world in worlds.values():
                world.close()
        for v, r in res.items():
            per_step[v][n] = r["wall"]
            got[v][n] = r
            print(f"[step_scaling] N={n:>7,} {v:<20} {r['wall'] * 1e3:9.3f} ms/step (CPU {r['cpu'] * 1e3:.3f}), "
                  f"worst {r['worst_wall'] * 1e3:.3f} (CPU {r['worst_cpu'] * 1e3:.3f}, of it GC "
                  f"{r['worst_cpu_gc'] * 1e3:.3f}) of {r['steps']} steps",
                  flush=True)

    setup = setup_timings(setup_n, 3)
    one_by_one = per_entity_creation(setup_n if not quick else 2_000)
    one_by_one_n = setup_n if not quick else 2_000
    print(f"[step_scaling] set-up of {setup_n:,}: {setup}; one by one: {one_by_one:.2f} s for {one_by_one_n:,}")
    load1 = os.getloadavg()
    gc.callbacks.remove(GC_CLOCK)

    # ------------------------------------------------------------------ chart
    fig, (ax1, ax2) = common.figure(1, 2, figsize=(12, 4.8))
    styles = {"vectorised": ("o-", "#2ca02c"), "loop, component API": ("s--", "#d62728"),
              "loop, lean": ("^--", "#ff7f0e")}
    for variant, (style, color) in styles.items():
        ns = sorted(per_step[variant])
        ax1.plot(ns, [per_step[variant][n] * 1e3 for n in ns], style, color=color, label=variant)
    ns = sorted(per_step["vectorised"])
    ax1.plot(ns, [got["vectorised"][n]["worst_wall"] * 1e3 for n in ns], "o:", color="#2ca02c", alpha=0.5,
             mfc="none", label="vectorised, worst step")
    ref_n = ns[-1]
    ax1.plot(ns, [per_step["vectorised"][ref_n] * 1e3 * n / ref_n for n in ns], ":", color="grey",
             label="linear in N (through the largest vectorised point)")
    ax1.set_xscale("log")
    ax1.set_yscale("log")
    ax1.set_xlabel("bodies (Transform, Velocity, AngularVelocity)")
    ax1.set_ylabel("ms per step (movement + spin)")
    ax1.set_title("time per step, median (worst step dotted)", fontsize=10)
    ax1.legend(fontsize=8)
    for variant, (style, color) in styles.items():
        if variant == "vectorised":
            continue
        common_ns = [n for n in ns if n in per_step[variant]]
        ax2.plot(common_ns, [per_step[variant][n] / per_step["vectorised"][n] for n in common_ns], style,
                 color=color, label=f"vectorised vs {variant}")
    ax2.axhline(30, color="k", lw=0.8, ls=":", label="bar: 30x")
    ax2.set_xscale("log")
    ax2.set_yscale("log")
    ax2.set_xlabel("bodies")
    ax2.set_ylabel("speed-up (loop time / vectorised time)")
    ax2.set_title("speed-up over a per-entity esper loop, same process", fontsize=10)
    ax2.legend(fontsize=8)
    common.save_chart(fig, "step_scaling")

    # ------------------------------------------------------------------ table
    loads = " -> ".join(", ".join(f"{x:.1f}" for x in la) for la in (load0, load1))
    L = [f"Movement + spin per step through `World.step()` (all bodies spinning). Each sample is enough "
         f"steps to last about 50 ms (two warm steps before, not counted), each step timed on its own in wall "
         f"time and in CPU time (`time.process_time`); samples of the variants taken in turn. Median: the "
         f"median of {repeats} samples' mean step (per-entity loops: of {loop_repeats[10_000]}, "
         f"{loop_repeats[sizes[-1]]} at {sizes[-1]:,}). Worst: the slowest single step of all samples "
         f"(steps counted in the last column), and the CPU time Python's garbage collector took inside the "
         f"worst CPU step (`gc.callbacks`). The two clock reads of each step (~0.35 us) are inside every "
         f"figure. A wall worst far above the CPU worst is time in which the process was not running (the "
         f"other processes on the shared cores), not work of the step. The loops were first checked to give "
         f"the systems' result (largest difference "
         f"{worst:.1e}). Load average (1, 5, 15 min) at the start -> at the end: {loads} "
         f"({os.cpu_count()} cores, shared).", ""]
    rows = []

    def ms(x: float) -> str:
        return f"{x * 1e3:.3g}"
    for n in sizes:
        g = got["vectorised"][n]
        v = g["wall"]
        r = [f"{n:,}", f"{ms(v)} / {ms(g['worst_wall'])}", f"{ms(g['cpu'])} / {ms(g['worst_cpu'])}",
             ms(g["worst_cpu_gc"]),
             f"{g['worst_wall'] / v:.1f} / {g['worst_cpu'] / g['cpu']:.1f}", f"{v / n * 1e9:.0f}",
             f"{ms(g['movement'])} / {ms(g['spin'])}"]
        for variant in ("loop, component API", "loop, lean"):
            lg = got[variant].get(n)
            r += ["-", "-"] if lg is None else [f"{ms(lg['wall'])} / {ms(lg['cpu'])}", f"{lg['wall'] / v:.0f}x"]
        r.append(f"{g['steps']:,}")
        rows.append(r)
    L.append(common.table(["bodies", "vectorised ms/step, wall: median / worst", "CPU: median / worst",
                           "garbage collector in the worst CPU step, ms",
                           "worst / median, wall / CPU", "ns per body-step", "movement / spin ms",
                           "loop (API) ms/step, wall / CPU", "speed-up", "loop (lean) ms/step, wall / CPU",
                           "speed-up", "steps timed (vectorised)"], rows))
    L.append("")
    # growth in CPU time: on a shared machine a wall median also holds time the process was not running
    cpu_step = {n: got["vectorised"][n]["cpu"] for n in sizes}
    slopes = []
    for a, b in zip(sizes, sizes[1:]):
        s = math.log(cpu_step[b] / cpu_step[a]) / math.log(b / a)
        slopes.append(f"{a:,} -> {b:,}: {s:.2f}")
    big = [n for n in sizes if n >= 1_000]
    top = math.log(cpu_step[big[-1]] / cpu_step[big[-2]]) / math.log(big[-1] / big[-2])
    at10k = per_step["vectorised"].get(10_000)
    r_api = per_step["loop, component API"][10_000] / at10k
    r_lean = per_step["loop, lean"][10_000] / at10k
    cpu10k = got["vectorised"][10_000]["cpu"]
    r_api_cpu = got["loop, component API"][10_000]["cpu"] / cpu10k
    r_lean_cpu = got["loop, lean"][10_000]["cpu"] / cpu10k
    fit_n = np.array(big, dtype=float)
    fit_t = np.array([cpu_step[n] for n in big])
    b_fit, a_fit = np.polyfit(fit_n, fit_t, 1, w=1.0 / fit_t)     # least relative squares
    resid = float(np.max(np.abs(a_fit + b_fit * fit_n - fit_t) / fit_t))
    L.append(f"Growth exponent of the vectorised step's median CPU time (log-log slope; 1 = linear; CPU "
             f"time because a wall median on a shared machine also holds time the process was not running): "
             f"{'; '.join(slopes)}. "
             f"A straight line t = a + b N through the points from 1,000 bodies up gives a = "
             f"{a_fit * 1e6:.0f} us per step (esper's cached query, the systems' few dozen numpy calls) and "
             f"b = {b_fit * 1e9:.0f} ns per body (fitted in relative terms), within {resid:.0%} of every "
             f"point: below about a thousand bodies the fixed part dominates, above it time grows in "
             f"proportion to N.")
    L.append("")
    bar_ok = r_lean >= 30 and r_api >= 30
    per_body = [cpu_step[n] / n for n in big]
    # linear (not worse): the cost per body never rises with N (15% allowed for timing noise),
    # and time does grow with N once the fixed per-step cost is amortised
    lin_ok = all(b2 <= 1.15 * b1 for b1, b2 in zip(per_body, per_body[1:])) and top >= 0.7
    L.append(f"**Bar: {'met' if bar_ok else 'NOT met'}** -- at 10,000 bodies the systems are {r_api:.0f}x faster "
             f"than the component-API loop and {r_lean:.0f}x faster than the lean loop (bar 30x; in CPU time "
             f"{r_api_cpu:.0f}x and {r_lean_cpu:.0f}x). "
             f"**Linear growth: {'yes' if lin_ok else 'NO'}**: the CPU time per body-step "
             f"{'never rises' if lin_ok else 'rises'} with N "
             f"({' -> '.join(f'{b * 1e9:.0f}' for b in per_body)} ns from {big[0]:,} to {big[-1]:,} bodies), "
             f"and the log-log slope between {big[-2]:,} and {big[-1]:,} bodies is {top:.2f} (1 once the "
             f"fixed part is negligible).")
    L.append("")
    L.append(f"Set-up of {setup_n:,} bodies (median of 3): `Transform.bulk` + `Velocity.bulk` + "
             f"`AngularVelocity.bulk` {setup['bulk components'] * 1e3:.0f} ms, `world.create_entities` "
             f"{setup['create_entities'] * 1e3:.0f} ms, first step {setup['first step'] * 1e3:.0f} ms (esper "
             f"builds its query cache and the systems their row indices), then "
             f"{setup['second step'] * 1e3:.0f} ms for the next: "
             f"{(setup['bulk components'] + setup['create_entities'] + setup['first step']):.2f} s from arrays "
             f"to the first step taken. For comparison, creating {one_by_one_n:,} bodies one at a time with "
             f"the components' constructors took {one_by_one:.2f} s "
             f"({one_by_one / one_by_one_n * 1e6:.0f} us per body against "
             f"{(setup['bulk components'] + setup['create_entities']) / setup_n * 1e6:.1f} us in bulk).")
    common.write_section("step_scaling", "Step scaling: vectorised systems vs a per-entity loop",
                         "\n".join(L), quick=quick, started=t_start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
