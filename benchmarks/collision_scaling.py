"""How does a full step with collisions grow with the number of spheres?  Continuous vs the articles vs pybullet.

The scene (issue 3): a field of N spheres, radii uniform in 0.25-0.75 m, mass
proportional to r^3 (1000 kg/m^3), placed without overlap at a 5 % volume
fraction in a cube, velocities ~1 m/s (normal, 1/sqrt(3) m/s per axis),
seeded, no walls, dt = 1/60 s. A *full step* is ``world.step()`` with
MovementSystem + SpinSystem + CollisionSystem. The issue's field does not
spin, so the spin system finds nothing to turn; one extra run at 500 spheres
gives every sphere a tumble (~0.5 rad/s) to show what spinning adds to both
driftframe methods.

* ``continuous``: ``CollisionSystem()`` (the default: exact times of impact,
  waves of simultaneous contacts, neighbour-list broad phase);
* ``articles``: ``CollisionSystem("articles")``, the articles' method (a Python
  double loop over pairs, discrete overlap check), run the same way;
* ``pybullet`` (if installed: ``pip install -e '.[compare]'``): the same
  spheres as rigid bodies (maximal coordinates), ``stepSimulation()`` per step,
  made as elastic as it goes: restitution 1 on every body (Bullet multiplies
  the pair's), ``restitutionVelocityThreshold = 0`` (restitution at any speed),
  no friction (lateral, spinning, rolling), no damping (pybullet's default is
  0.04), no gravity, sleeping disabled, and ``contactERP = 0`` (no Baumgarte
  position correction: with the default it *added* 2.3 % kinetic energy over
  200 steps of 2,000 spheres; with 0 the drift is ~1e-8).

All three advance the same field in the same process, in turn, a block of
steps each (20 continuous, 5 pybullet, 1 articles, 20 continuous, ...), so a
change of load on the machine hits all alike; every step is timed, and the
ratios are between the medians of those individual step times. Energy drift: the largest relative change
of total kinetic energy (translation + spin) over all steps of the run.

A second part measures the broad-phase methods of ``framework/broadphase.py``
on the same field (the swept boxes of one step) and, for small N, the
collision stage with every pair tested each step vs the neighbour list: the
crossover sets ``ALL_PAIRS_MAX``.

Bars (issue 3): >= 100x faster than the articles' method at N = 500; at
10,000 spheres a full step in under half of pybullet's time; energy drift
<= 1e-12 relative.
"""
from __future__ import annotations

import gc
import statistics
import time

import numpy as np

from benchmarks import common
from driftframe.components.body import AngularVelocity, Mass, Transform, Velocity
from driftframe.components.collision import SphereCollider
from driftframe.framework import broadphase as bp
from driftframe.framework.world import World
from driftframe.systems.collision import CollisionSystem
from driftframe.systems.movement import MovementSystem
from driftframe.systems.spin import SpinSystem

DT = 1.0 / 60.0
DENSITY = 1000.0          # kg/m^3


def field(n: int, seed: int = 0, tumble: bool = False) -> dict[str, np.ndarray]:
    """The issue's field: non-overlapping spheres at 5 % volume fraction, ~1 m/s; spinning if ``tumble``."""
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.25, 0.75, n)
    side = ((4.0 / 3.0 * np.pi * r ** 3).sum() / 0.05) ** (1.0 / 3.0)
    x = rng.uniform(0.0, side, (n, 3))
    for _ in range(1000):                                   # re-draw the later sphere of any overlap
        i, j = bp.sphere_pairs(x, r)
        if not len(i):
            break
        bad = np.unique(j)
        x[bad] = rng.uniform(0.0, side, (len(bad), 3))
    return {"radius": r, "position": x, "velocity": rng.normal(0.0, 1.0 / np.sqrt(3.0), (n, 3)),
            "spin": rng.normal(0.0, 0.5, (n, 3)) if tumble else np.zeros((n, 3)), "mass": DENSITY * 4.0 / 3.0 * np.pi * r ** 3, "side": side}


def inertia(f) -> np.ndarray:
    """Moment of inertia of solid spheres, 2/5 m r^2 (kg m^2): for the spin part of the energy."""
    return 0.4 * f["mass"] * f["radius"] ** 2


class Ours:
    """A driftframe World on the field; ``energy()`` reads the columns directly."""

    def __init__(self, f, method: str, **kw):
        n = len(f["radius"])
        self.world = World(dt=DT)
        self.world.add_system(MovementSystem())
        self.world.add_system(SpinSystem())
        self.system = self.world.add_system(CollisionSystem(method, **kw))
        vel = Velocity.bulk(n, linear=f["velocity"])
        # a body with no spin carries no AngularVelocity (the spin system then has nothing to do)
        spin = AngularVelocity.bulk(n, angular=f["spin"]) if f["spin"].any() else None
        self.ents = self.world.create_entities(Transform.bulk(n, position=f["position"]), vel, spin,
                                               Mass.bulk(n, kg=f["mass"]),
                                               SphereCollider.bulk(n, radius=f["radius"]))
        self.spinning = spin is not None
        self.m, self.inertia = f["mass"], inertia(f)
        self.contacts = 0
        self.builds = 0

    def step(self) -> None:
        self.world.step()
        self.contacts += self.system.stats["contacts"]
        self.builds += self.system.stats["builds"]

    def energy(self) -> float:
        v = self.world.columns(Velocity, self.ents).linear
        e = float(self.m @ (v * v).sum(1))
        if self.spinning:
            w = self.world.columns(AngularVelocity, self.ents).angular
            e += float(self.inertia @ (w * w).sum(1))
        return 0.5 * e

    def close(self) -> None:
        self.world.close()


class Bullet:
    """The same field in pybullet, as elastic as pybullet goes (see the module docstring)."""

    def __init__(self, f):
        import pybullet as pb

        self.pb = pb
        self.cid = pb.connect(pb.DIRECT)
        pb.setGravity(0, 0, 0, physicsClientId=self.cid)
        pb.setPhysicsEngineParameter(fixedTimeStep=DT, numSubSteps=0, restitutionVelocityThreshold=0.0,
                                     contactERP=0.0, physicsClientId=self.cid)
        self.ids = []
        for r, m, x, v, w in zip(f["radius"], f["mass"], f["position"], f["velocity"], f["spin"]):
            shape = pb.createCollisionShape(pb.GEOM_SPHERE, radius=float(r), physicsClientId=self.cid)
            b = pb.createMultiBody(baseMass=float(m), baseCollisionShapeIndex=shape, basePosition=x.tolist(),
                                   useMaximalCoordinates=True, physicsClientId=self.cid)
            pb.changeDynamics(b, -1, restitution=1.0, lateralFriction=0.0, spinningFriction=0.0,
                              rollingFriction=0.0, linearDamping=0.0, angularDamping=0.0,
                              activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=self.cid)
            pb.resetBaseVelocity(b, v.tolist(), w.tolist(), physicsClientId=self.cid)
            self.ids.append(b)
        self.m, self.inertia = f["mass"], inertia(f)

    def step(self) -> None:
        self.pb.stepSimulation(physicsClientId=self.cid)

    def energy(self) -> float:
        vw = [self.pb.getBaseVelocity(b, physicsClientId=self.cid) for b in self.ids]
        v = np.array([a for a, _ in vw])
        w = np.array([b for _, b in vw])
        return 0.5 * float(self.m @ (v * v).sum(1) + self.inertia @ (w * w).sum(1))

    def close(self) -> None:
        self.pb.disconnect(physicsClientId=self.cid)


def run_size(n: int, steps: dict[str, int], block: dict[str, int], energy_every: int,
             tumble: bool = False) -> dict:
    """Step the simulators in turn, a block of steps each (continuous 20, pybullet 5, articles 1, ...),
    timing every step; per-step times and the energy drift of each. The garbage collector is off while
    timing (as in ``timeit``), for all alike."""
    f = field(n, tumble=tumble)
    sims = {"continuous": Ours(f, "continuous")}
    if steps.get("pybullet"):
        sims["pybullet"] = Bullet(f)
    if steps.get("articles"):
        sims["articles"] = Ours(f, "articles")
    try:
        times = {k: [] for k in sims}
        e0 = {k: s.energy() for k, s in sims.items()}
        drift = {k: 0.0 for k in sims}
        for s in sims.values():                               # first step: caches and lists are built
            s.step()
        clock = time.perf_counter
        gc.collect()
        gc.disable()
        try:
            while any(len(times[k]) < steps[k] for k in sims):
                for k, s in sims.items():
                    for _ in range(min(block[k], steps[k] - len(times[k]))):
                        t0 = clock()
                        s.step()
                        times[k].append(clock() - t0)
                        if k == "pybullet" and len(times[k]) % energy_every:
                            continue                          # pybullet's energy costs a call per body
                        drift[k] = max(drift[k], abs(s.energy() / e0[k] - 1.0))
        finally:
            gc.enable()
        for k, s in sims.items():
            drift[k] = max(drift[k], abs(s.energy() / e0[k] - 1.0))
        out = {"n": n, "side": f["side"], "drift": drift,
               "median": {k: statistics.median(t) for k, t in times.items()},
               "mean": {k: statistics.fmean(t) for k, t in times.items()},
               "steps": {k: len(t) + 1 for k, t in times.items()}}
        c = sims["continuous"]
        out["contacts"] = c.contacts / out["steps"]["continuous"]
        out["builds"] = c.builds / out["steps"]["continuous"]
        return out
    finally:
        for s in sims.values():
            s.close()


def broadphase_times(sizes, repeats: int) -> dict:
    """Seconds for one box_pairs call per method on the field's swept boxes of one step."""
    out = {m: {} for m in ("all", "sweep", "grid", "kdtree")}
    for n in sizes:
        f = field(n, seed=1)
        x1 = f["position"] + f["velocity"] * DT
        lo = np.minimum(f["position"], x1) - f["radius"][:, None]
        hi = np.maximum(f["position"], x1) + f["radius"][:, None]
        ref = None
        for m in out:
            if m == "all" and n > 2000 or m == "sweep" and n > 10000:
                continue
            i, j = bp.box_pairs(lo, hi, m)
            got = set(zip(np.minimum(i, j).tolist(), np.maximum(i, j).tolist()))
            if ref is None:
                ref = got
            elif got != ref:
                raise AssertionError(f"broad phase {m} disagrees at N={n}")
            out[m][n] = common.median_time(lambda: bp.box_pairs(lo, hi, m), repeats=repeats, number=3)
    return out


def list_build_times(sizes, repeats: int) -> dict:
    """Seconds for one NeighbourList build per method (territories: radius + 8 steps of travel); every pair
    tested ("all") up to 2,000 spheres."""
    out = {m: {} for m in ("all", "grid", "sweep", "kdtree")}
    for n in sizes:
        f = field(n, seed=1)
        c = np.ascontiguousarray(f["position"].T)
        disp = np.linalg.norm(f["velocity"], axis=1) * DT
        for m in out:
            if m == "all" and n > 2_000:
                continue
            nl = bp.NeighbourList(8.0, m)
            out[m][n] = common.median_time(lambda: nl.build(c, f["radius"], disp), repeats=repeats, number=3)
    return out


def crossover(sizes, steps: int) -> dict:
    """Median collision-stage seconds per step: every pair each step vs the neighbour list.

    Both run the same field side by side, 10 steps each in turn, so load changes hit both alike.
    """
    out = {"all pairs": {}, "neighbour list": {}}
    for n in sizes:
        f = field(n, seed=2)
        sims = {"all pairs": Ours(f, "continuous", broadphase="all"),
                "neighbour list": Ours(f, "continuous", broadphase="grid")}
        t = {k: [] for k in sims}
        try:
            for sim in sims.values():
                sim.step()
            gc.disable()
            for _ in range(steps // 10):
                for k, sim in sims.items():
                    for _ in range(10):
                        sim.step()
                        t[k].append(sim.world.profile["collision"])
        finally:
            gc.enable()
            for sim in sims.values():
                sim.close()
        for k in sims:
            out[k][n] = statistics.median(t[k])
    return out


def main(argv=None) -> int:
    args = common.parser(__doc__.splitlines()[0]).parse_args(argv)
    quick = args.quick
    t_start = time.perf_counter()
    sizes = [50, 500, 2_000] if quick else [50, 500, 2_000, 10_000]
    bullet = common.have_pybullet()
    if not bullet:
        print("[collision_scaling] pybullet is not installed: its column is skipped "
              "(pip install -e '.[compare]' to include it)")
    plan = {50: (600, 200), 500: (600, 100), 2_000: (400, 5), 10_000: (300, 2)}
    if quick:
        plan = {50: (60, 20), 500: (60, 10), 2_000: (30, 2)}
    block = {"continuous": 20, "pybullet": 5, "articles": 1}
    results = {}
    for n in sizes:
        ours, art = plan[n]
        steps = {"continuous": ours, "articles": art, "pybullet": ours if bullet else 0}
        res = results[n] = run_size(n, steps, block, energy_every=20 if n >= 2_000 else 1)
        line = "  ".join(f"{k} {v * 1e3:.3f} ms" for k, v in res["median"].items())
        print(f"[collision_scaling] N={n:>6,}: {line}; drift {res['drift']}", flush=True)

    tumbling = run_size(500, {"continuous": plan[500][0] // 2, "articles": plan[500][1] // 2, "pybullet": 0},
                        block, energy_every=1, tumble=True)
    print(f"[collision_scaling] N=500 tumbling: {tumbling['median']}", flush=True)

    bp_sizes = [16, 48, 128, 500, 2_000] if quick else [16, 48, 128, 500, 2_000, 10_000]
    bpt = broadphase_times(bp_sizes, 3 if quick else 7)
    lbt = list_build_times([48, 64, 96] + bp_sizes[2:], 3 if quick else 7)
    xs = [8, 24, 48, 96] if quick else [8, 16, 24, 32, 40, 48, 64, 96]
    cross = crossover(xs, 40 if quick else 600)

    # ------------------------------------------------------------------ chart
    fig, (ax1, ax2, ax3) = common.figure(1, 3, figsize=(16, 4.8))
    styles = {"continuous": ("o-", "#2ca02c"), "articles": ("s--", "#d62728"), "pybullet": ("^-", "#1f77b4")}
    for k, (style, color) in styles.items():
        ns = [n for n in sizes if k in results[n]["median"]]
        if ns:
            label = {"continuous": "driftframe, continuous (default)", "articles": "driftframe, articles' method",
                     "pybullet": "pybullet (elastic settings)"}[k]
            ax1.plot(ns, [results[n]["median"][k] * 1e3 for n in ns], style, color=color, label=label)
    ax1.set_xscale("log")
    ax1.set_yscale("log")
    ax1.set_xlabel("spheres (5 % volume fraction)")
    ax1.set_ylabel("ms per full step (movement + spin + collision)")
    ax1.set_title("full step, median", fontsize=10)
    ax1.legend(fontsize=8)
    for m, (style, color) in {"all": ("s--", "#d62728"), "sweep": ("v-", "#9467bd"), "grid": ("o-", "#2ca02c"),
                              "kdtree": ("^-", "#1f77b4")}.items():
        ns = sorted(bpt[m])
        ax2.plot(ns, [bpt[m][n] * 1e3 for n in ns], style, color=color, label=m)
    ax2.set_xscale("log")
    ax2.set_yscale("log")
    ax2.set_xlabel("spheres")
    ax2.set_ylabel("ms per call")
    ax2.set_title("broad phase alone: box_pairs on one step's swept boxes", fontsize=10)
    ax2.legend(fontsize=8)
    for label, (style, color) in {"all pairs": ("s--", "#d62728"), "neighbour list": ("o-", "#2ca02c")}.items():
        ax3.plot(xs, [cross[label][n] * 1e6 for n in xs], style, color=color, label=label)
    ax3.axvline(bp.ALL_PAIRS_MAX, color="k", ls=":", lw=0.8, label=f"ALL_PAIRS_MAX = {bp.ALL_PAIRS_MAX}")
    ax3.set_xlabel("spheres")
    ax3.set_ylabel("us per step, collision stage (median)")
    ax3.set_title("small scenes: test every pair, or keep a list?", fontsize=10)
    ax3.legend(fontsize=8)
    common.save_chart(fig, "collision_scaling")

    # ------------------------------------------------------------------ table
    L = ["Median time per full step (`world.step()`: movement + spin + collision; pybullet: `stepSimulation()`), "
         "individual steps taken in turn in one process; mean in brackets (the neighbour list is rebuilt every "
         "few steps, so the mean sits above the median). Continuous and pybullet run "
         + ", ".join(f"{plan[n][0]} steps at {n:,}" for n in sizes)
         + " (the field has no walls, so it slowly spreads out and the contacts per step fall with time; "
           "every run starts from the same seeded field); the articles' method runs the number of steps in "
           "its column.", ""]
    rows = []
    for n in sizes:
        res = results[n]
        med, mean, st = res["median"], res["mean"], res["steps"]
        c = med["continuous"]
        row = [f"{n:,}", f"{c * 1e3:.3g} ({mean['continuous'] * 1e3:.3g})", f"{res['contacts']:.2g}",
               f"{res['builds'] * 100:.3g}"]
        if "articles" in med:
            row += [f"{med['articles'] * 1e3:.3g} ({st['articles']} steps)", f"{med['articles'] / c:.0f}x"]
        else:
            row += ["-", "-"]
        if "pybullet" in med:
            row += [f"{med['pybullet'] * 1e3:.3g} ({mean['pybullet'] * 1e3:.3g})", f"{c / med['pybullet']:.2f}"]
        else:
            row += ["not installed", "-"]
        row += [f"{res['drift']['continuous']:.1e}", f"{res['drift'].get('articles', float('nan')):.1e}",
                f"{res['drift'].get('pybullet', float('nan')):.1e}"]
        rows.append(row)
    L.append(common.table(["spheres", "continuous ms", "contacts / step", "list builds / 100 steps",
                           "articles ms", "articles / continuous", "pybullet ms", "continuous / pybullet",
                           "energy drift, continuous", "articles", "pybullet"], rows))
    L.append("")
    r500 = results[500]["median"]
    ratio = r500["articles"] / r500["continuous"] if "articles" in r500 else float("nan")
    drift = max(res["drift"]["continuous"] for res in results.values())
    L.append(f"**Bar, >= 100x the articles' method at 500 spheres: {'met' if ratio >= 100 else 'NOT met'}** "
             f"({ratio:.0f}x: {r500['continuous'] * 1e3:.3g} ms against {r500['articles'] * 1e3:.3g} ms).")
    if 10_000 in results and "pybullet" in results[10_000]["median"]:
        m = results[10_000]["median"]
        share = m["continuous"] / m["pybullet"]
        L.append(f"**Bar, under half of pybullet's step at 10,000 spheres: {'met' if share < 0.5 else 'NOT met'}** "
                 f"({m['continuous'] * 1e3:.3g} ms against {m['pybullet'] * 1e3:.3g} ms, {share:.2f} of it; "
                 f"mean {results[10_000]['mean']['continuous'] * 1e3:.3g} against "
                 f"{results[10_000]['mean']['pybullet'] * 1e3:.3g} ms).")
    elif 10_000 in results:
        L.append("Bar at 10,000 spheres against pybullet: not measured (pybullet is not installed).")
    else:
        L.append("Bar at 10,000 spheres: not measured in a quick run.")
    tm = tumbling["median"]
    L.append(f"With every sphere tumbling (~0.5 rad/s; not part of the issue's field) the spin system turns "
             f"500 quaternions each step in both worlds: continuous {tm['continuous'] * 1e3:.3g} ms, articles "
             f"{tm['articles'] * 1e3:.3g} ms per full step, {tm['articles'] / tm['continuous']:.0f}x.")
    L.append(f"**Bar, energy drift <= 1e-12 over the run: {'met' if drift <= 1e-12 else 'NOT met'}** "
             f"(largest relative change of kinetic energy over any step of any run: {drift:.1e}; the "
             f"articles' method {max(r['drift'].get('articles', 0.0) for r in results.values()):.1e}, each "
             f"of its reflections being elastic; pybullet with the settings above "
             f"{max(r['drift'].get('pybullet', 0.0) for r in results.values()):.1e}).")
    L.append("")
    L.append("Broad phase alone, one `box_pairs` call on one step's swept boxes (median ms):")
    L.append("")
    L.append(common.table(["spheres"] + list(bpt),
                          [[f"{n:,}"] + [f"{bpt[m][n] * 1e3:.3g}" if n in bpt[m] else "-" for m in bpt]
                           for n in bp_sizes]))
    L.append("")
    best = {n: min((m for m in bpt if n in bpt[m]), key=lambda m: bpt[m][n]) for n in bp_sizes}
    big = [n for n in bp_sizes if n >= 2_000]
    slope = {m: np.log(bpt[m][big[-1]] / bpt[m][big[0]]) / np.log(big[-1] / big[0])
             for m in bpt if big[0] in bpt[m] and big[-1] in bpt[m]} if len(big) > 1 else {}
    cross_at = [n for n in xs if cross["neighbour list"][n] < cross["all pairs"][n]]
    L.append("Fastest broad phase by size: " + ", ".join(f"{n:,}: {best[n]}" for n in bp_sizes) + ". "
             + (("Growth from " + f"{big[0]:,} to {big[-1]:,} spheres (log-log slope; 1 = linear): "
                 + ", ".join(f"{m} {v:.2f}" for m, v in slope.items()) + ". ") if slope else "")
             + "Sort and sweep along one axis grows towards N^(5/3) in a 3-D field (the pairs that overlap "
               "on one axis grow with the side of the box); the grid's cost is a sort and a fixed stencil per "
               "sphere. The collision system tests every pair up to "
             + f"`ALL_PAIRS_MAX` = {bp.ALL_PAIRS_MAX} spheres (below, the measured crossover"
             + (f": the neighbour list first wins at {cross_at[0]} spheres" if cross_at else "")
             + ") and above that keeps a neighbour list, reused for several steps (each body's skin is 8 "
               "steps of its own travel, up to 4 times that where a cost model of builds against pairs says "
               "so: small sparse scenes), so the broad phase is paid for only every few steps (the list "
               "builds column). The list is built by testing every pair up to "
             + f"`LIST_ALL_MAX` = {bp.LIST_ALL_MAX} spheres and with the grid above (table below: its "
               "territories are wider than one step's sweep, which favours the grid earlier). scipy's k-d tree "
               "is measured, not used: scipy stays a benchmark-only dependency.")
    L.append("")
    L.append("Neighbour-list build, median ms:")
    L.append("")
    L.append(common.table(["spheres"] + list(lbt),
                          [[f"{n:,}"] + [f"{lbt[m][n] * 1e3:.3g}" if n in lbt[m] else "" for m in lbt]
                           for n in sorted(lbt["grid"])]))
    L.append("")
    L.append("Collision stage alone in small scenes, median us per step:")
    L.append("")
    L.append(common.table(["spheres"] + [f"{n}" for n in xs],
                          [[label] + [f"{cross[label][n] * 1e6:.0f}" for n in xs] for label in cross]))
    common.write_section("collision_scaling", "Collision scaling: continuous vs the articles' method vs pybullet",
                         "\n".join(L), quick=quick, started=t_start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
