"""Where does each collision method fail?  Missed hits, wrong outcomes, overlap and drift against cost.

Two methods of ``systems/collision.py`` run through the same ``World``
(MovementSystem + CollisionSystem):

* ``articles``: the articles' method (discrete overlap check after the step,
  move back along the velocities to contact, reflect in the centre-of-mass
  frame, pair by pair);
* ``continuous``: the default (swept times of impact, contacts in time order,
  waves of simultaneous contacts solved together).

**Part A, isolated pairs across closing speeds and time steps.** 40 pairs of
equal spheres (r = 0.1 m, 1 kg) per run, each pair closing at ``v`` along x
with a random impact parameter (0 to 0.95 of r_a + r_b) and a random contact
time inside the third step, pairs 100 m apart so they never meet. After six
steps each pair is compared with the exact elastic answer (contact time,
normal, outgoing velocities, positions at the end):

* missed: share of pairs whose velocities did not change at all;
* velocity error: largest ``|v - v_exact| / v``;
* position error: largest ``|x - x_exact|`` (m);
* final overlap: largest ``(r_a + r_b - |d|) / (r_a + r_b)`` at the end (0 = none);
* energy drift: ``|KE_end / KE_0 - 1|``;
* cost: microseconds per ``world.step()`` over steps 2-6 (80 bodies; the
  first step builds caches), median of repeats.

**Part B, scenes with many contacts per step**: Newton's cradle, a billiard
break (in two creation orders), spheres spawned overlapping, and a dense gas
of 64 spheres. For each: energy and momentum drift, final overlap, the
symmetry error of the break, the difference between creation orders, the
largest position jump in one step (in units of the fastest body's ``v dt``),
and the cost per step.
"""
from __future__ import annotations

import math
import statistics
import time

import esper
import numpy as np

from benchmarks import common
from driftframe.components.body import Mass, Transform, Velocity
from driftframe.components.collision import SphereCollider
from driftframe.framework.world import World
from driftframe.systems.collision import CollisionSystem
from driftframe.systems.movement import MovementSystem

R_SPHERE = 0.1
PAIRS = 40
STEPS = 6
METHODS = ("articles", "continuous")


def _world(method: str, dt: float, x, v, r, m=None) -> tuple[World, list[int]]:
    n = len(r)
    w = World(dt=dt)
    w.add_system(MovementSystem())
    w.add_system(CollisionSystem(method))
    ids = w.create_entities(Transform.bulk(n, position=x), Velocity.bulk(n, linear=v),
                            Mass.bulk(n, kg=np.ones(n) if m is None else m), SphereCollider.bulk(n, radius=r))
    return w, ids


def _state(ids):
    x = np.array([esper.component_for_entity(e, Transform).position for e in ids])
    v = np.array([esper.component_for_entity(e, Velocity).linear for e in ids])
    return x, v


# ---------------------------------------------------------------------------- part A

def pairs_scene(speed: float, dt: float, seed: int = 0):
    """Start state and exact end state of PAIRS head-on-ish pairs (A at even, B at odd indices)."""
    rng = np.random.default_rng(seed)
    R = 2 * R_SPHERE
    b = rng.uniform(0.0, 0.95 * R, PAIRS)                  # impact parameter
    tc = (2.0 + rng.uniform(0.05, 0.95, PAIRS)) * dt       # contact time, inside the third step
    T = STEPS * dt
    along = np.sqrt(R * R - b * b)                         # x separation at contact
    x0 = np.zeros((2 * PAIRS, 3))
    v0 = np.zeros((2 * PAIRS, 3))
    x_end = np.zeros_like(x0)
    v_end = np.zeros_like(v0)
    for k in range(PAIRS):
        z = 100.0 * k
        va, vb = np.array([speed / 2, 0, 0]), np.array([-speed / 2, 0, 0])
        ca = np.array([-along[k] / 2, -b[k] / 2, z])       # centres at contact
        cb = np.array([along[k] / 2, b[k] / 2, z])
        x0[2 * k], x0[2 * k + 1] = ca - va * tc[k], cb - vb * tc[k]
        v0[2 * k], v0[2 * k + 1] = va, vb
        n = (cb - ca) / R
        dvn = (vb - va) @ n                                # equal masses: exchange the normal parts
        va2, vb2 = va + dvn * n, vb - dvn * n
        x_end[2 * k], x_end[2 * k + 1] = ca + va2 * (T - tc[k]), cb + vb2 * (T - tc[k])
        v_end[2 * k], v_end[2 * k + 1] = va2, vb2
    return x0, v0, x_end, v_end


def run_pairs(method: str, speed: float, dt: float, repeats: int) -> dict:
    x0, v0, x_ex, v_ex = pairs_scene(speed, dt)
    r = np.full(len(x0), R_SPHERE)
    costs = []
    for rep in range(repeats):
        w, ids = _world(method, dt, x0, v0, r)
        try:
            w.step()                                         # set-up (layout, first list) not counted
            t0 = time.perf_counter()
            w.step(STEPS - 1)
            costs.append((time.perf_counter() - t0) / (STEPS - 1))
            if rep == 0:
                x, v = _state(ids)
        finally:
            w.close()
    a, b = slice(0, None, 2), slice(1, None, 2)
    changed = np.linalg.norm(v - v0, axis=1) > 1e-9 * speed
    missed = 1.0 - float(np.mean(changed[a] | changed[b]))
    R = 2 * R_SPHERE
    dist = np.linalg.norm(x[b] - x[a], axis=1)
    ke0, ke1 = (v0 * v0).sum(), (v * v).sum()
    found = changed[a] | changed[b]
    err = np.maximum(np.linalg.norm(x[a] - x_ex[a], axis=1), np.linalg.norm(x[b] - x_ex[b], axis=1))
    return {"missed": missed,
            "position error, hits found": float(err[found].max()) if found.any() else float("nan"),
            "velocity error": float(np.max(np.linalg.norm(v - v_ex, axis=1)) / speed),
            "position error": float(np.max(np.linalg.norm(x - x_ex, axis=1))),
            "overlap": float(max(0.0, np.max((R - dist) / R))),
            "energy drift": abs(ke1 / ke0 - 1.0),
            "cost": statistics.median(costs)}


# ---------------------------------------------------------------------------- part B

def _cradle():
    r = 0.1
    x = np.array([[-0.41, 0, 0]] + [[0.2 * i, 0, 0] for i in range(5)], float)
    v = np.zeros((6, 3))
    v[0, 0] = 1.0
    return x, v, np.full(6, r), None


def _rack(order_seed=None):
    r = 0.5
    x = [[-3.05, 0.0, 0.0]]
    for row in range(5):
        for j in range(row + 1):
            x.append([row * math.sqrt(3) * r, (j - row / 2) * 2 * r, 0.0])
    x = np.array(x)
    v = np.zeros((16, 3))
    v[0, 0] = 10.0
    return x, v, np.full(16, r), None


def _overlapping():
    """20 spheres on a line, each overlapping its neighbours by 1 % of a diameter, drifting apart slowly."""
    n = 20
    x = np.zeros((n, 3))
    x[:, 0] = np.arange(n) * 0.99
    v = np.zeros((n, 3))
    v[:, 0] = np.linspace(-0.05, 0.05, n)                   # every neighbour pair separates
    return x, v, np.full(n, 0.5), None


def _gas():
    rng = np.random.default_rng(4)
    n = 64
    r = rng.uniform(0.1, 0.2, n)
    x = np.zeros((n, 3))
    k = 0
    while k < n:                                            # no overlap at spawn, in a 2 m cube
        p = rng.uniform(0, 2.0, 3)
        if k == 0 or np.all(np.linalg.norm(x[:k] - p, axis=1) > r[:k] + r[k]):
            x[k] = p
            k += 1
    return x, rng.normal(0, 5.0, (n, 3)), r, 1000 * r ** 3


SCENES = {"Newton's cradle": (_cradle, 60), "billiard break": (_rack, 90),
          "spawned overlapping, separating": (_overlapping, 120), "dense gas (64)": (_gas, 60)}


def run_scene(method: str, name: str, dt: float = 1 / 60) -> dict:
    make, steps = SCENES[name]
    x0, v0, r, m = make()
    m = np.ones(len(r)) if m is None else m
    out = {}
    orders = [np.arange(len(r)), np.random.default_rng(9).permutation(len(r))]
    finals = []
    for o_i, order in enumerate(orders):
        w, ids = _world(method, dt, x0[order], v0[order], r[order], m[order])
        back = np.empty(len(r), int)
        back[order] = np.arange(len(r))
        try:
            vmax0 = np.linalg.norm(v0, axis=1).max()
            prev, _ = _state(ids)
            jump = overlap = 0.0
            R = r[order][:, None] + r[order][None]
            apart = ~np.eye(len(r), dtype=bool)
            spawn = (np.linalg.norm(prev[:, None] - prev[None], axis=2) < R) & apart
            t = []
            for _ in range(steps):
                t0 = time.perf_counter()
                w.step()
                t.append(time.perf_counter() - t0)
                x, v = _state(ids)
                vmax = max(vmax0, np.linalg.norm(v, axis=1).max())
                jump = max(jump, float(np.linalg.norm(x - prev, axis=1).max() / (vmax * dt)))
                # overlap at a step end between spheres that did not spawn overlapping
                d = np.linalg.norm(x[:, None] - x[None], axis=2)
                overlap = max(overlap, float(np.max(np.where(apart & ~spawn, (R - d) / R, 0.0))))
                prev = x
            x, v = x[back], v[back]
            finals.append((x, v))
            if o_i == 0:
                ke0, ke1 = 0.5 * m @ (v0 * v0).sum(1), 0.5 * m @ (v * v).sum(1)
                p0, p1 = m @ v0, m @ v
                out = {"energy drift": abs(ke1 / ke0 - 1.0),
                       "momentum drift": float(np.linalg.norm(p1 - p0) / (m @ np.linalg.norm(v0, axis=1))),
                       "overlap": overlap, "jump": jump,
                       "cost": statistics.median(t)}
                if name == "Newton's cradle":
                    # exact: contact at 0.21 s, then only the last ball moves on at 1 m/s
                    T = steps * dt
                    x_ex = np.array([[-0.2, 0, 0]] + [[0.2 * i, 0, 0] for i in range(4)]
                                    + [[0.8 + (T - 0.21), 0, 0]])
                    out["last ball speed / striker's"] = float(np.linalg.norm(v[-1]))
                    out["largest speed left behind"] = float(np.linalg.norm(v[:-1], axis=1).max())
                    out["position error (m)"] = float(np.abs(x - x_ex).max())
                if name == "billiard break":
                    mirror = [int(np.argmin(np.linalg.norm(x0 - s * [1, -1, 1], axis=1))) for s in x0]
                    out["mirror error"] = float(max(np.abs(x[mirror] - x * [1, -1, 1]).max(),
                                                    np.abs(v[mirror] - v * [1, -1, 1]).max()))
        finally:
            w.close()
    out["order dependence"] = float(max(np.abs(finals[0][0] - finals[1][0]).max(),
                                        np.abs(finals[0][1] - finals[1][1]).max()))
    return out


# ---------------------------------------------------------------------------- main

def main(argv=None) -> int:
    args = common.parser(__doc__.splitlines()[0]).parse_args(argv)
    quick = args.quick
    t_start = time.perf_counter()
    speeds = [1.0, 30.0, 10_000.0] if quick else [0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 1_000.0, 10_000.0]
    dts = [1 / 60] if quick else [1 / 30, 1 / 60, 1 / 120, 1 / 240]
    repeats = 2 if quick else 5
    A = {}
    for method in METHODS:
        for dt in dts:
            for s in speeds:
                A[method, dt, s] = run_pairs(method, s, dt, repeats)
        print(f"[collision_accuracy] part A, {method}: done", flush=True)
    B = {(method, name): run_scene(method, name) for method in METHODS for name in SCENES}
    print("[collision_accuracy] part B: done", flush=True)

    # ------------------------------------------------------------------ chart
    fig, axes = common.figure(2, 2, figsize=(12, 8.5))
    colors = {"articles": "#d62728", "continuous": "#2ca02c"}
    styles = {1 / 30: ":", 1 / 60: "-", 1 / 120: "--", 1 / 240: "-."}
    panels = [("missed", "missed collisions (share of pairs)", False),
              ("velocity error", "largest |v - v_exact| / v", True),
              ("position error", "largest |x - x_exact| after 6 steps (m)", True)]
    for ax, (key, label, log) in zip([axes[0][0], axes[0][1], axes[1][0]], panels):
        for method in METHODS:
            for dt in dts:
                y = [A[method, dt, s][key] for s in speeds]
                if log:
                    y = [max(v, 1e-17) for v in y]
                ax.plot(speeds, y, styles[dt], color=colors[method], marker="o", ms=3,
                        label=f"{method}, dt = 1/{round(1 / dt)} s")
        ax.set_xscale("log")
        if log:
            ax.set_yscale("log")
        ax.set_xlabel("closing speed (m/s); r_a + r_b = 0.2 m")
        ax.set_ylabel(label)
        ax.set_title(label, fontsize=10)
    axes[0][0].legend(fontsize=7)
    ax = axes[1][1]
    for method in METHODS:
        cost = [A[method, dt, s]["cost"] * 1e6 for dt in dts for s in speeds]
        err = [max(A[method, dt, s]["position error"], 1e-17) for dt in dts for s in speeds]
        ax.scatter(cost, err, color=colors[method], s=14, label=method)
    ax.set_yscale("log")
    ax.set_xlabel("cost, us per step (80 bodies)")
    ax.set_ylabel("largest position error after 6 steps (m)")
    ax.set_title("accuracy against cost (every speed and dt)", fontsize=10)
    ax.legend(fontsize=8)
    common.save_chart(fig, "collision_accuracy")

    # ------------------------------------------------------------------ tables
    L = ["**Part A: isolated pairs** (40 pairs of r = 0.1 m spheres per run, contact inside the third step, "
         "compared with the exact elastic answer after 6 steps). Columns per method: missed share, largest "
         "velocity error (relative), largest position error (m), largest final overlap (relative), energy "
         "drift, cost (us per step).", ""]
    rows = []
    for dt in dts:
        for s in speeds:
            row = [f"1/{round(1 / dt)}", f"{s:g}", f"{s * dt / (2 * R_SPHERE):.2g}"]
            for method in METHODS:
                a = A[method, dt, s]
                row += [f"{a['missed']:.0%}", f"{a['velocity error']:.1e}", f"{a['position error']:.1e}",
                        f"{a['overlap']:.2g}", f"{a['energy drift']:.0e}", f"{a['cost'] * 1e6:.0f}"]
            rows.append(row)
    head = ["dt (s)", "closing m/s", "v dt / (r_a+r_b)"]
    for method in METHODS:
        head += [f"{method}: missed", "v err", "x err (m)", "overlap", "energy", "us/step"]
    L.append(common.table(head, rows))
    L.append("")
    cont = [A["continuous", dt, s] for dt in dts for s in speeds]
    art = [A["articles", dt, s] for dt in dts for s in speeds]
    worst = {k: max(a[k] for a in cont) for k in ("missed", "velocity error", "position error", "overlap",
                                                 "energy drift")}
    first_miss = min((s * dt / (2 * R_SPHERE) for dt in dts for s in speeds
                      if A["articles", dt, s]["missed"] > 0), default=float("nan"))
    L.append(f"The continuous method caught every hit at every speed and step (missed {worst['missed']:.0%}); "
             f"its worst velocity error was {worst['velocity error']:.1e} (relative), position error "
             f"{worst['position error']:.1e} m, final overlap {worst['overlap']:.1e}, energy drift "
             f"{worst['energy drift']:.0e}. The articles' method starts missing hits once a pair closes by about "
             f"{first_miss:.2g} combined diameters in one step (a missed pair passes through: up to "
             f"{max(a['position error'] for a in art):.2g} m off), and even the hits it finds end up to "
             f"{np.nanmax([a['position error, hits found'] for a in art]):.2g} m off (it moves the pair back "
             f"to contact and does not re-advance it for the rest of the step). Its cost is "
             f"{statistics.median(a['cost'] for a in art) * 1e6:.0f} us per step against "
             f"{statistics.median(a['cost'] for a in cont) * 1e6:.0f} us for the continuous method (80 "
             f"bodies: a Python loop over 3,160 pairs against whole-array work).")
    L.append("")
    L.append("**Part B: many contacts per step** (dt = 1/60 s).")
    L.append("")
    rows = []
    for name in SCENES:
        for method in METHODS:
            b = B[method, name]
            extra = []
            for k in ("last ball speed / striker's", "largest speed left behind", "position error (m)",
                      "mirror error"):
                if k in b:
                    extra.append(f"{k} {b[k]:.2g}")
            rows.append([name, method, f"{b['energy drift']:.0e}", f"{b['momentum drift']:.0e}",
                         f"{b['overlap']:.2g}", f"{b['jump']:.3g}", f"{b['order dependence']:.1e}",
                         f"{b['cost'] * 1e6:.0f}", "; ".join(extra)])
    L.append(common.table(["scene", "method", "energy drift", "momentum drift", "overlap at step ends",
                           "largest jump (x v dt)", "order dependence", "us/step", "scene check"], rows))
    L.append("")
    L.append("`overlap at step ends`: the deepest overlap, relative to r_a + r_b, at the end of any step, "
             "between spheres that did not spawn overlapping. "
             "`largest jump`: the largest distance a body moved in one step, divided by the fastest speed "
             "(at the start or now) times dt: 1 or less means nothing moved faster than a body can. `order "
             "dependence`: the largest difference in any position or velocity between two creation orders "
             "of the same scene (the second a fixed random permutation).")
    L.append("")
    notes = []
    for name in SCENES:
        a, c = B["articles", name], B["continuous", name]
        parts = []
        for k, what in (("order dependence", "differs between creation orders by"), ("jump", "largest jump"),
                        ("overlap", "overlap at step ends"), ("mirror error", "mirror error"),
                        ("position error (m)", "position error (m)")):
            ok = 1.0 + 1e-9 if k == "jump" else 1e-9        # a jump of up to 1 x v dt is plain motion
            if k in a and (a[k] > ok or c[k] > ok):
                parts.append(f"{what} {a[k]:.3g} (articles) against {c[k]:.3g} (continuous)")
        if parts:
            notes.append(f"- {name}: " + "; ".join(parts) + ".")
    L += notes
    L.append("")
    common.write_section("collision_accuracy", "Collision accuracy: the articles' method vs continuous",
                         "\n".join(L), quick=quick, started=t_start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
