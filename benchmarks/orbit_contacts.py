"""Sphere contacts on rails: what looking for them costs, and that the long step finds the same contacts.

**Cost.** N bodies on rails in low orbit (random shells 7,000 to 8,000 km,
random inclinations, e <= 0.05, so their orbits cross but the bodies are
rarely near), stepped by the ``GravitySystem`` in a ``World``: the same scene
with no ``SphereCollider`` (the baseline: the contact check is skipped) and
with a 5 m ``SphereCollider`` on every body, interleaved in one process, ns
per body-step (median of the repeats, and the worst step), at a step of 1 s
and of 100 s (a warp of 100: the swept boxes grow with the step).

**Consistency.** A cloud of 27 spheres (250 to 350 m) sharing an orbit,
stirred by up to 2 m/s, meets itself dozens of times in 3,000 s: run at steps
of 1, 100, 1,000 and 3,000 s (half an orbit), the contacts found are listed
against the 1 s run (same pairs in the same order; largest difference of the
contact times), with the energy error of the whole cloud at the end and the
cost per step. The same cloud about a moon, with fixed obstacles in its path,
at steps of 1, 100 and 1,000 s: contacts about the moon and, across frames,
bodies about a moon against obstacles.
"""
from __future__ import annotations

import math
import statistics
import time

import numpy as np

from benchmarks import common

MU = 3.986004418e14
R_EARTH = 6.371e6


def scene(n, dt, colliders, seed=3):
    from driftframe import MovementSystem, SphereCollider, Transform, Velocity, World
    from driftframe.components.gravity import GravityWell
    from driftframe.systems.gravity import GravitySystem
    rng = np.random.default_rng(seed)
    w = World(dt=dt)
    w.add_system(GravitySystem())
    w.add_system(MovementSystem())
    w.create_entity(Transform(), GravityWell(mu=MU, radius=R_EARTH))
    r = rng.uniform(7.0e6, 8.0e6, n)
    # a random orbit plane per body: position on a random unit vector, velocity perpendicular to it
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    t = np.cross(p, rng.normal(size=(n, 3)))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    speed = np.sqrt(MU / r) * rng.uniform(1.0, 1.05, n)
    comps = [Transform.bulk(n, position=p * r[:, None]), Velocity.bulk(n, linear=t * speed[:, None])]
    if colliders:
        comps.append(SphereCollider.bulk(n, radius=np.full(n, 5.0)))
    w.create_entities(*comps)
    w.step(3)
    return w


def cost(n, dt, repeats):
    worlds = {label: scene(n, dt, label == "with colliders") for label in ("without colliders", "with colliders")}
    samples = {k: [] for k in worlds}
    try:
        for _ in range(repeats):
            for label, w in worlds.items():          # interleaved: the machine's noise hits both alike
                t0 = time.perf_counter()
                w.step()
                samples[label].append((time.perf_counter() - t0) / n * 1e9)
    finally:
        for w in worlds.values():
            w.close()
    return {k: (statistics.median(v), max(v)) for k, v in samples.items()}


def cloud(dt, steps, seed=11):
    from driftframe import Mass, MovementSystem, SphereCollider, Transform, Velocity, World
    from driftframe.components.collision import CollisionEvent
    from driftframe.components.gravity import GravityWell
    from driftframe.systems.gravity import GravitySystem
    rng = np.random.default_rng(seed)
    w = World(dt=dt)
    w.add_system(GravitySystem())
    w.add_system(MovementSystem())
    w.create_entity(Transform(), GravityWell(mu=MU, radius=R_EARTH))
    seen = []
    w.subscribe(CollisionEvent, seen.append)
    ents = []
    v_circ = math.sqrt(MU / 7e6)
    for cell in np.stack(np.meshgrid(*[np.arange(3) - 1] * 3, indexing="ij"), -1).reshape(-1, 3):
        p = np.array([7e6, 0.0, 0.0]) + 800.0 * cell
        u = np.array([0.0, v_circ, 0.0]) + rng.uniform(-2.0, 2.0, 3)
        ents.append(w.create_entity(Transform(p), Velocity(u), SphereCollider(radius=rng.uniform(250.0, 350.0)),
                                    Mass(float(rng.uniform(0.5, 4.0)))))
    kg = w.columns(Mass, ents).kg

    def energy():
        x, v = w.columns(Transform, ents).position, w.columns(Velocity, ents).linear
        return float(np.sum(kg * (0.5 * np.einsum("ij,ij->i", v, v) - MU / np.linalg.norm(x, axis=1))))
    e0 = energy()
    t0 = time.perf_counter()
    w.step(steps)
    took = time.perf_counter() - t0
    out = (seen, abs(energy() / e0 - 1.0), took / steps)
    w.close()
    return out


MU_MOON, D_MOON, R_MOON = 4.9048695e12, 3.844e8, 1.7374e6


def moon_cloud(dt, steps, seed=5):
    """The cloud of 27 in low orbit about a moon (which orbits the planet), and three fixed obstacles
    placed where the cloud's centre will be at 400, 900 and 1,500 s: contacts on rails about the moon,
    and of bodies about a moon against obstacles (world-frame paths, kepler.time_to_touch_paths)."""
    from driftframe import Mass, MovementSystem, SphereCollider, Transform, Velocity, World
    from driftframe.components.collision import CollisionEvent
    from driftframe.components.gravity import GravityWell
    from driftframe.framework import kepler
    from driftframe.systems.gravity import GravitySystem
    rng = np.random.default_rng(seed)
    w = World(dt=dt)
    w.add_system(GravitySystem())
    w.add_system(MovementSystem())
    planet = w.create_entity(Transform(), GravityWell(mu=MU, radius=R_EARTH))
    m0, mv0 = np.array([D_MOON, 0.0, 0.0]), np.array([0.0, math.sqrt(MU / D_MOON), 0.0])
    w.create_entity(Transform(m0), Velocity(mv0), GravityWell(mu=MU_MOON, radius=R_MOON, parent=planet))
    seen = []
    w.subscribe(CollisionEvent, seen.append)
    c0, cv0 = np.array([2.5e6, 0.0, 0.0]), np.array([0.0, 0.0, math.sqrt(MU_MOON / 2.5e6)])
    for cell in np.stack(np.meshgrid(*[np.arange(3) - 1] * 3, indexing="ij"), -1).reshape(-1, 3):
        w.create_entity(Transform(m0 + c0 + 800.0 * cell), Velocity(mv0 + cv0 + rng.uniform(-2.0, 2.0, 3)),
                        SphereCollider(radius=rng.uniform(250.0, 350.0)), Mass(float(rng.uniform(0.5, 4.0))))
    for t in (400.0, 900.0, 1500.0):
        m, _ = kepler.propagate(m0, mv0, MU, t)
        c, _ = kepler.propagate(c0, cv0, MU_MOON, t)
        w.create_entity(Transform(m + c), SphereCollider(radius=600.0))
    t0 = time.perf_counter()
    w.step(steps)
    took = time.perf_counter() - t0
    w.close()
    return seen, took / steps


def main(argv=None) -> int:
    args = common.parser(__doc__.splitlines()[0]).parse_args(argv)
    started = time.perf_counter()
    sizes = (100, 1_000) if args.quick else (100, 1_000, 10_000)
    reps = 5 if args.quick else 31
    rows, chart = [], {}
    for dt in (1.0, 100.0):
        for n in sizes:
            res = cost(n, dt, reps)
            (b, bw), (c, cw) = res["without colliders"], res["with colliders"]
            rows.append([f"{dt:g}", n, b, bw, c, cw, c / b])
            chart.setdefault(dt, []).append((n, b, c))
            print(f"  dt {dt:g} s, {n:6d} bodies: {b:7.0f} ns without colliders, {c:7.0f} with ({c / b:.2f}x)",
                  flush=True)
    body = ["Cost of the contact check on rails (ns per body-step; median of "
            f"{reps} interleaved steps, and the worst):\n",
            common.table(["step, s", "bodies", "no colliders", "worst", "5 m colliders", "worst", "ratio"],
                         rows) + "\n"]
    T = 300.0 if args.quick else 3000.0
    runs = {}
    for dt in (1.0, 100.0, 1000.0, 3000.0):
        if dt > T:
            continue
        runs[dt] = cloud(dt, int(round(T / dt)))
    ref = runs[1.0][0]
    crow = []
    for dt, (seen, de, per) in runs.items():
        same = [(e.a, e.b) for e in seen] == [(e.a, e.b) for e in ref]
        dtime = max((abs(e.time - f.time) / e.time for e, f in zip(ref, seen)), default=0.0) if same else math.nan
        crow.append([f"{dt:g}", len(seen), "yes" if same else "NO", dtime, de, per * 1e3])
    body.append(f"A cloud of 27 spheres sharing an orbit for {T:g} s, at four step lengths (contacts against "
                "the 1 s run):\n")
    body.append(common.table(["step, s", "contacts", "same pairs, same order", "largest relative time difference",
                              "energy error at the end", "ms per step"], crow) + "\n")
    mixed = {dt: moon_cloud(dt, int(round(T / dt))) for dt in (1.0, 100.0, 1000.0) if dt <= T}
    mref = mixed[1.0][0]
    mrow = []
    for dt, (seen, per) in mixed.items():
        same = [(e.a, e.b) for e in seen] == [(e.a, e.b) for e in mref]
        dtime = max((abs(e.time - f.time) / e.time for e, f in zip(mref, seen)), default=0.0) if same else math.nan
        n_ob = sum(1 for e in seen if e.b >= 30)           # (the obstacles are the last entities made)
        mrow.append([f"{dt:g}", len(seen), n_ob, "yes" if same else "NO", dtime, per * 1e3])
    body.append(f"The same cloud about a moon (which orbits the planet), with three fixed obstacles in its path, for "
                f"{T:g} s: contacts about the moon and, across frames, of bodies about the moon with obstacles "
                "(`kepler.time_to_touch_paths` on the world-frame paths):\n")
    body.append(common.table(["step, s", "contacts", "with obstacles", "same pairs, same order",
                              "largest relative time difference", "ms per step"], mrow) + "\n")
    worst = max(r[-1] for r in rows)
    big = [r for r in rows if r[1] == max(sizes)]
    body.append(
        f"- Scenes without colliders skip the check (one count compared per well). With colliders that are "
        f"never near, the check is a swept box per body and one broad phase: at {max(sizes):,} bodies it adds "
        + ", ".join(f"{(r[6] - 1) * 100:.0f} % at a {r[0]} s step" for r in big)
        + f" to the step (worst ratio over all sizes {worst:.2f}).\n"
        "- Every contact time is exact on the conics (conservative advancement, `kepler.time_to_touch`), so a "
        "longer step finds the same contacts; what differs is rounding, carried from contact to contact.\n")
    fig, ax = common.figure(1, 1, figsize=(6, 4))
    for dt, pts in chart.items():
        n = [p[0] for p in pts]
        ax.plot(n, [p[1] for p in pts], "o--", label=f"no colliders, step {dt:g} s")
        ax.plot(n, [p[2] for p in pts], "o-", label=f"5 m colliders, step {dt:g} s")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("bodies on rails")
    ax.set_ylabel("ns per body-step")
    ax.legend(fontsize=8)
    common.save_chart(fig, "orbit_contacts")
    common.write_section("orbit_contacts", "Sphere contacts on rails: cost and step-length invariance",
                         "\n".join(body), quick=args.quick, started=started)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
