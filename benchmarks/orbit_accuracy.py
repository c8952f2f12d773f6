"""Orbits: energy, angular-momentum and phase error against cost, driftframe's modes against the
textbook integrators and REBOUND (WHFast, IAS15), run in the same process.

Units: ``mu = 1``, ``a = 1`` (so the period is 2 pi for every eccentricity and
one ``dt`` serves all). Each method integrates the four ellipses e = 0, 0.5,
0.9, 0.99 from periapsis at 10, 100 and 1,000 steps per orbit, for 10,000,
1,000 and 100 orbits (100,000 steps each), and a hyperbolic flyby (e = 1.5,
from 20 periapsis radii in and out again) in as many steps. Errors at the
end: ``|E/E0 - 1|``, ``|h/h0 - 1|`` and the along-track phase error (the
angle between the final position and the exact one: periapsis again after
whole orbits; Kepler's hyperbolic equation for the flyby).

Methods (all on numpy columns, vectorised over the bodies):

* explicit Euler, semi-implicit (symplectic) Euler, leapfrog (kick-drift-kick,
  what the gravity system's n-body mode does), classical RK4;
* driftframe *on rails*: every step propagates the body's epoch by the whole
  time since (``framework.kepler.Epoch.at``, warm-started by ``next_chi``),
  as :class:`systems.gravity.GravitySystem` does;
* driftframe *Kepler step to step*: each step from the last (what a body
  that thrusts does, one step at a time);
* REBOUND WHFast (Wisdom-Holman, the Kepler drift in C) at the same ``dt`` and
  IAS15 (adaptive, 15th order) to the same end time; one test particle
  (``N_active = 1``) about a unit mass.

Cost: nanoseconds per body-step at 10,000 bodies (mixed eccentricities, 100
steps per orbit), medians of interleaved repeats; REBOUND with 10,000 test
particles and the real ``GravitySystem`` in a ``World`` (the same 10,000
bodies on rails) in the same loop; WHFast both at its default ``safe_mode = 1`` and at
``safe_mode = 0`` (one Kepler solve a step: the bar's). ``--cost 1000,10000`` runs these rows alone at
the sizes given and prints them. Plus the price of gravity for a scene *without* a
well: the standard per-step systems on 10,000 free bodies, with and without
the gravity, autopilot and warp systems, interleaved.

Every step (issue 24): the worst energy and angular-momentum error over *every* step at 10 steps
per orbit, e = 0 to 0.99999, on rails from three epochs (periapsis, E0 = 1 rad, apoapsis), beside
the double-rounding floor (the exact state rounded to doubles, from a long-double reference:
:mod:`benchmarks.orbit_reference`) and IAS15 read at each step; and the angular momentum of an
e = 5 flyby 1e4, 1e8 and 1e10 s after periapsis beside its floor and IAS15.

Bars (from the issues): on rails keeps energy and angular momentum to <= 1e-12
over 10,000 orbits at every eccentricity at 10 steps per orbit, and at every step
for e <= 0.999; within 2x the floor above; at 10,000
bodies its cost per body-step is at most WHFast's (``safe_mode = 0``) per particle-step, wall and CPU
time; a scene
without a well pays nothing (ratio within noise, shown with its spread).
"""
from __future__ import annotations

import math
import os
import statistics
import time

import numpy as np

from benchmarks import common
from driftframe.framework import kepler

ECC = (0.0, 0.5, 0.9, 0.99)
E_HYP = 1.5
RUNS = ((10, 10_000), (100, 1_000), (1_000, 100))       # (steps per orbit, orbits): 100,000 steps each
QUICK_RUNS = ((10, 100), (100, 10), (1_000, 1))
METHODS = ("explicit Euler", "semi-implicit Euler", "leapfrog", "RK4", "driftframe on rails",
           "driftframe Kepler step to step", "REBOUND WHFast", "REBOUND IAS15")


# ------------------------------------------------------------------------------------- set-ups
def ellipses():
    """Periapsis states of the four ellipses (a = 1, mu = 1), orbits tilted so no axis is special."""
    r, v = [], []
    for e in ECC:
        rp = 1.0 - e
        r.append([rp, 0.0, 0.0])
        v.append([0.0, math.sqrt((1 + e) / rp), 0.0])
    tilt = np.array([[1, 0, 0], [0, math.cos(0.4), -math.sin(0.4)], [0, math.sin(0.4), math.cos(0.4)]])
    return np.array(r) @ tilt.T, np.array(v) @ tilt.T


def flyby():
    """Hyperbola e = 1.5, rp = 1: state at true anomaly -nu (r = 20), time to +nu, exact end state."""
    e, rp = E_HYP, 1.0
    p = rp * (1 + e)
    nu = math.acos((p / 20.0 - 1) / e)

    def at(n):
        rr = p / (1 + e * math.cos(n))
        return (np.array([[rr * math.cos(n), rr * math.sin(n), 0.0]]),
                np.array([[-math.sin(n), e + math.cos(n), 0.0]]) / math.sqrt(p))
    a = rp / (1 - e)
    H = math.acosh((1 - 20.0 / a) / e)
    t_half = (e * math.sinh(H) - H) / math.sqrt(1.0 / (-a) ** 3)
    return at(-nu), 2 * t_half, at(nu)


def gravity(r):
    d2 = np.einsum("ij,ij->i", r, r)
    return -r / (d2 * np.sqrt(d2))[:, None]


# ------------------------------------------------------------------------------------- methods
def run_classic(name, r, v, dt, steps):
    r, v = r.copy(), v.copy()
    if name == "explicit Euler":
        for _ in range(steps):
            a = gravity(r)
            r += v * dt
            v += a * dt
    elif name == "semi-implicit Euler":
        for _ in range(steps):
            v += gravity(r) * dt
            r += v * dt
    elif name == "leapfrog":
        a = gravity(r)
        for _ in range(steps):
            v += 0.5 * dt * a
            r += v * dt
            a = gravity(r)
            v += 0.5 * dt * a
    elif name == "RK4":
        for _ in range(steps):
            k1v = gravity(r)
            k1r = v
            k2v = gravity(r + 0.5 * dt * k1r)
            k2r = v + 0.5 * dt * k1v
            k3v = gravity(r + 0.5 * dt * k2r)
            k3r = v + 0.5 * dt * k2v
            k4v = gravity(r + dt * k3r)
            k4r = v + dt * k3v
            r = r + dt / 6 * (k1r + 2 * k2r + 2 * k3r + k4r)
            v = v + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    return r, v


def run_rails(r0, v0, dt, steps):
    """The gravity system's on-rails path: from the epoch for the whole time, warm-started."""
    ep = kepler.Epoch(r0, v0, 1.0)
    chi = np.zeros(len(r0))
    r, v = r0, v0
    for k in range(1, steps + 1):
        r, v, chi = ep.at(k * dt, kepler.next_chi(chi, r, v, 1.0, dt))
    return r, v


def run_step_to_step(r, v, dt, steps):
    for _ in range(steps):
        r, v = kepler.propagate(r, v, 1.0, dt)
    return r, v


def run_rebound(integrator, r0, v0, dt, t_end):
    import rebound
    out_r, out_v = [], []
    for k in range(len(r0)):
        sim = rebound.Simulation()
        sim.G = 1.0
        sim.add(m=1.0)
        sim.add(m=0.0, x=r0[k, 0], y=r0[k, 1], z=r0[k, 2], vx=v0[k, 0], vy=v0[k, 1], vz=v0[k, 2])
        sim.N_active = 1
        sim.integrator = integrator
        if integrator == "whfast":
            sim.dt = dt
            sim.steps(int(round(t_end / dt)))
        else:
            sim.dt = dt
            sim.integrate(t_end, exact_finish_time=1)
        p = sim.particles[1]
        s = sim.particles[0]
        out_r.append([p.x - s.x, p.y - s.y, p.z - s.z])
        out_v.append([p.vx - s.vx, p.vy - s.vy, p.vz - s.vz])
    return np.array(out_r), np.array(out_v)


def errors(r, v, r0, v0, r_exact):
    E = 0.5 * np.einsum("ij,ij->i", v, v) - 1.0 / np.linalg.norm(r, axis=1)
    E0 = 0.5 * np.einsum("ij,ij->i", v0, v0) - 1.0 / np.linalg.norm(r0, axis=1)
    h = np.linalg.norm(np.cross(r, v), axis=1)
    h0 = np.linalg.norm(np.cross(r0, v0), axis=1)
    cross = np.linalg.norm(np.cross(r, r_exact), axis=1)
    phase = np.arctan2(cross, np.einsum("ij,ij->i", r, r_exact))
    with np.errstate(invalid="ignore"):
        return np.abs(E / E0 - 1), np.abs(h / h0 - 1), np.abs(phase)


def integrate(method, r0, v0, dt, steps):
    t_end = steps * dt
    if method in ("explicit Euler", "semi-implicit Euler", "leapfrog", "RK4"):
        return run_classic(method, r0, v0, dt, steps)
    if method == "driftframe on rails":
        return run_rails(r0, v0, dt, steps)
    if method == "driftframe Kepler step to step":
        return run_step_to_step(r0, v0, dt, steps)
    if method == "REBOUND WHFast":
        return run_rebound("whfast", r0, v0, dt, t_end)
    return run_rebound("ias15", r0, v0, dt, t_end)


def have_rebound() -> bool:
    try:
        import rebound  # noqa: F401
        return True
    except ImportError:
        return False


# ------------------------------------------------------------------------------------- every step
ECC_EVERY = (0.0, 0.5, 0.9, 0.99, 0.999, 0.9999, 0.99999)
#: Epochs (eccentric anomaly, rad): the periapsis start of the runs above, and two from the far side.
EPOCHS = ((0.0, "periapsis"), (1.0, "E0 = 1 rad"), (math.pi, "apoapsis"))


def tilted_periapsis(e):
    """The periapsis state of the ellipse a = 1, mu = 1, e, tilted as :func:`ellipses`'s."""
    rp = 1.0 - e
    tilt = np.array([[1, 0, 0], [0, math.cos(0.4), -math.sin(0.4)], [0, math.sin(0.4), math.cos(0.4)]])
    return np.array([[rp, 0.0, 0.0]]) @ tilt.T, np.array([[0.0, math.sqrt((1 + e) / rp), 0.0]]) @ tilt.T


def every_step(e, E0, steps, with_ias):
    """Worst ``|E/E0 - 1|`` and ``|h/h0 - 1|`` over *every* step, 10 steps per orbit, on rails from an
    epoch at eccentric anomaly ``E0`` (the exact state there rounded to doubles); the same for the exact
    state at each step rounded to doubles (the floor) and, with ``with_ias``, for IAS15 (read at each
    step, ``exact_finish_time=1``). Energies and h in long double (:mod:`benchmarks.orbit_reference`)."""
    from benchmarks import orbit_reference as ref
    rp, vp = tilted_periapsis(e)
    if E0:
        t0 = np.array([E0 - e * math.sin(E0)])                 # mean anomaly = time (n = 1)
        r0, v0 = (q.astype(np.float64) for q in ref.ellipse_states(rp[0], vp[0], t0))
    else:
        r0, v0 = rp, vp
    dt = 2 * math.pi / 10
    times = dt * np.arange(1, steps + 1)
    ep = kepler.Epoch(r0, v0, 1.0)
    R = np.empty((steps, 3))
    V = np.empty((steps, 3))
    r, v, chi = r0, v0, np.zeros(1)
    for k in range(steps):
        r, v, chi = ep.at(times[k], kepler.next_chi(chi, r, v, 1.0, dt))
        R[k], V[k] = r[0], v[0]
    E_ref, h_ref = ref.energy(r0, v0)[0], ref.ang_mom(r0, v0)[0]

    def worst(rr, vv):
        return (float(np.max(np.abs(ref.energy(rr, vv) / E_ref - 1))),
                float(np.max(np.abs(ref.ang_mom(rr, vv) / h_ref - 1))))
    out = {"rails": worst(R, V)}
    if ref.EXTENDED:
        xr, xv = ref.ellipse_states(r0[0], v0[0], times)
        out["floor"] = worst(xr.astype(np.float64), xv.astype(np.float64))
    if with_ias:
        import rebound
        sim = rebound.Simulation()
        sim.G = 1.0
        sim.add(m=1.0)
        sim.add(m=0.0, x=r0[0, 0], y=r0[0, 1], z=r0[0, 2], vx=v0[0, 0], vy=v0[0, 1], vz=v0[0, 2])
        sim.N_active = 1
        sim.integrator = "ias15"
        for k in range(steps):
            sim.integrate(times[k], exact_finish_time=1)
            p, c = sim.particles[1], sim.particles[0]
            R[k] = (p.x - c.x, p.y - c.y, p.z - c.z)
            V[k] = (p.vx - c.vx, p.vy - c.vy, p.vz - c.vz)
        out["IAS15"] = worst(R, V)
    return out


#: The hyperbolic flyby of the angular-momentum check: about the Earth, periapsis 7,000 km, e = 5.
HYP_MU, HYP_RP, HYP_E = 3.986004418e14, 7.0e6, 5.0
HYP_TIMES = (1e4, 1e8, 1e10)


def hyperbolic_h(with_ias):
    """``|h/h0 - 1|`` of the e = 5 flyby at :data:`HYP_TIMES` (s) after periapsis: on rails (one evaluation
    from the epoch, as every step on rails is), the exact state rounded to doubles (the floor: far out
    ``r`` and ``v`` are nearly parallel and ``|r x v|`` is known only to ~ulp ``|r||v|/h``) and IAS15."""
    from benchmarks import orbit_reference as ref
    vp = math.sqrt(HYP_MU * (1 + HYP_E) / HYP_RP)
    tilt = np.array([[1, 0, 0], [0, math.cos(0.4), -math.sin(0.4)], [0, math.sin(0.4), math.cos(0.4)]])
    r0 = np.array([[HYP_RP, 0.0, 0.0]]) @ tilt.T
    v0 = np.array([[0.0, vp, 0.0]]) @ tilt.T
    h0 = ref.ang_mom(r0, v0)[0]
    out = {"rails": [], "floor": [], "IAS15": []}
    for t in HYP_TIMES:
        r, v = kepler.propagate(r0, v0, HYP_MU, t)
        out["rails"].append(float(abs(ref.ang_mom(r, v)[0] / h0 - 1)))
        if ref.EXTENDED:
            xr, xv = ref.hyperbola_states(r0[0], v0[0], np.array([t]), HYP_MU)
            out["floor"].append(float(abs(ref.ang_mom(xr.astype(np.float64), xv.astype(np.float64))[0] / h0 - 1)))
    if with_ias:
        import rebound
        sim = rebound.Simulation()
        sim.G = 1.0
        sim.add(m=HYP_MU)
        sim.add(m=0.0, x=r0[0, 0], y=r0[0, 1], z=r0[0, 2], vx=v0[0, 0], vy=v0[0, 1], vz=v0[0, 2])
        sim.N_active = 1
        sim.integrator = "ias15"
        for t in HYP_TIMES:
            sim.integrate(t, exact_finish_time=1)
            p, c = sim.particles[1], sim.particles[0]
            r = np.array([[p.x - c.x, p.y - c.y, p.z - c.z]])
            v = np.array([[p.vx - c.vx, p.vy - c.vy, p.vz - c.vz]])
            out["IAS15"].append(float(abs(ref.ang_mom(r, v)[0] / h0 - 1)))
    return out


# ------------------------------------------------------------------------------------- cost
WHFAST0 = "REBOUND WHFast (safe_mode=0)"
SYS_NAME = "driftframe GravitySystem in a World (on rails)"


def world_bar(n, cost, cost_cpu, load) -> str:
    """The bar's line: the World on rails against WHFast safe_mode = 0 (wall and CPU), and against the
    default safe_mode = 1 beside it."""
    wf, wf0 = cost["REBOUND WHFast"], cost[WHFAST0]
    sys_med = cost[SYS_NAME]
    ratio, ratio_cpu = sys_med / wf0, cost_cpu[SYS_NAME] / cost_cpu[WHFAST0]
    kern, kern_cpu = cost["driftframe on rails"] / wf0, cost_cpu["driftframe on rails"] / cost_cpu[WHFAST0]
    # (both must hold: where the CPU time disagrees with wall time, a neighbour took the CPU from one of them)
    status = "met" if max(ratio, ratio_cpu) <= 1.0 else \
        "met on wall time, NOT on CPU time" if ratio <= 1.0 else "NOT met"
    return (f"At {n:,} bodies on rails, the GravitySystem in a World costs {sys_med:.0f} ns per body-step "
            f"({cost_cpu[SYS_NAME]:.0f} CPU; the kernel alone {cost['driftframe on rails']:.0f} / "
            f"{cost_cpu['driftframe on rails']:.0f}) against REBOUND WHFast safe_mode = 0's {wf0:.0f} / "
            f"{cost_cpu[WHFAST0]:.0f} ns per particle-step, same bodies, interleaved: ratio {ratio:.2f} wall, "
            f"{ratio_cpu:.2f} CPU (kernel {kern:.2f} / {kern_cpu:.2f}; bar <= 1): **{status}**. Against WHFast's "
            f"default safe_mode = 1 ({wf:.0f} / {cost_cpu['REBOUND WHFast']:.0f} ns): {sys_med / wf:.2f} wall, "
            f"{cost_cpu[SYS_NAME] / cost_cpu['REBOUND WHFast']:.2f} CPU. The 1-minute load average was "
            f"{load[0][0]:.1f} before this measurement and {load[1][0]:.1f} after (2 cores, shared).")


def cost_only(sizes, reps: int) -> int:
    """``--cost``: the cost rows alone at each size, printed (no report): the World's bar line and the table."""
    for n in sizes:
        load = os.getloadavg()
        cost, worst, _, cost_cpu = cost_kernels(n, reps)
        load = (load, os.getloadavg())
        for m in cost:
            print(f"  {m:48s} {cost[m]:9.1f} ns wall (worst {worst[m]:9.1f})  {cost_cpu[m]:9.1f} ns CPU")
        print("- " + world_bar(n, cost, cost_cpu, load), flush=True)
    return 0


def cost_kernels(n: int, repeats: int):
    """ns per body-step at n bodies, interleaved: every method's step, and REBOUND WHFast's."""
    rng = np.random.default_rng(7)
    e = rng.uniform(0.0, 0.9, n)
    a = rng.uniform(1.0, 3.0, n)
    rp = a * (1 - e)
    r0 = np.zeros((n, 3))
    r0[:, 0] = rp
    v0 = np.zeros((n, 3))
    v0[:, 1] = np.sqrt((1 + e) / rp)
    dt = 2 * math.pi / 100
    ep = kepler.Epoch(r0, v0, 1.0)
    state = {"rails": (0, np.zeros(n), r0, v0), "kepler": (r0, v0)}

    def rails():
        k, chi, r, v = state["rails"]
        k += 1
        r, v, chi = ep.at(k * dt, kepler.next_chi(chi, r, v, 1.0, dt))
        state["rails"] = (k, chi, r, v)

    def step_to_step():
        r, v = state["kepler"]
        state["kepler"] = kepler.propagate(r, v, 1.0, dt)

    def classic(name):
        return lambda: run_classic(name, r0, v0, dt, 1)

    # the real system, same bodies (mu = 1 units: a well of mu 1 m^3/s^2, radius 0.01 m), interleaved too
    from driftframe import MovementSystem, Transform, Velocity, World
    from driftframe.components.gravity import GravityWell
    from driftframe.systems.gravity import GravitySystem
    world = World(dt=dt)
    world.add_system(GravitySystem())
    world.add_system(MovementSystem())
    world.create_entity(Transform(), GravityWell(mu=1.0, radius=0.01))
    world.create_entities(Transform.bulk(n, position=r0), Velocity.bulk(n, linear=v0))
    world.step(2)
    fns = {"driftframe on rails": rails, "driftframe Kepler step to step": step_to_step,
           "driftframe GravitySystem in a World (on rails)": world.step,
           "explicit Euler": classic("explicit Euler"), "semi-implicit Euler": classic("semi-implicit Euler"),
           "leapfrog": classic("leapfrog"), "RK4": classic("RK4")}
    sim = None
    if have_rebound():
        import rebound
        sim = rebound.Simulation()
        sim.G = 1.0
        sim.add(m=1.0)
        for k in range(n):
            sim.add(m=0.0, x=r0[k, 0], vy=v0[k, 1])
        sim.N_active = 1
        sim.integrator = "whfast"
        sim.dt = dt
        fns["REBOUND WHFast"] = lambda: sim.steps(10)
        # safe_mode = 0: WHFast joins each step's second half drift to the next step's first (one Kepler
        # solve a step instead of two, no synchronisation): the bar is against this one
        sim0 = rebound.Simulation()
        sim0.G = 1.0
        sim0.add(m=1.0)
        for k in range(n):
            sim0.add(m=0.0, x=r0[k, 0], vy=v0[k, 1])
        sim0.N_active = 1
        sim0.integrator = "whfast"
        sim0.integrator.safe_mode = 0
        sim0.dt = dt
        fns[WHFAST0] = lambda: sim0.steps(10)
        sim2 = rebound.Simulation()
        sim2.G = 1.0
        sim2.add(m=1.0)
        for k in range(n):
            sim2.add(m=0.0, x=r0[k, 0], vy=v0[k, 1])
        sim2.N_active = 1
        sim2.integrator = "ias15"
        state["ias"] = [sim2, 0.0]

        def ias():
            s, t = state["ias"]
            steps0 = s.steps_done
            t += 10 * dt
            s.integrate(t, exact_finish_time=0)
            state["ias"][1] = t
            state["ias_steps"] = s.steps_done - steps0
        fns["REBOUND IAS15"] = ias
    per = {k: [] for k in fns}
    cpu = {k: [] for k in fns}
    worst = {k: 0.0 for k in fns}
    for _ in range(repeats):
        for name, fn in fns.items():            # interleaved: the machine's noise hits all alike
            c0 = time.process_time()
            t0 = time.perf_counter()
            fn()
            took = time.perf_counter() - t0
            used = time.process_time() - c0
            steps = 10 if name.startswith("REBOUND") else 1
            per[name].append(took / (steps * n) * 1e9)
            cpu[name].append(used / (steps * n) * 1e9)
            worst[name] = max(worst[name], took / (steps * n) * 1e9)
    world.close()
    med = {k: statistics.median(v) for k, v in per.items()}
    med_cpu = {k: statistics.median(v) for k, v in cpu.items()}
    return med, worst, state.get("ias_steps"), med_cpu


def cost_without_well(n: int, repeats: int):
    """Standard per-step systems on n free bodies, with and without the gravity/autopilot/warp systems."""
    from driftframe import MovementSystem, SpinSystem, Transform, Velocity, AngularVelocity, World
    from driftframe.systems.autopilot import AutopilotSystem
    from driftframe.systems.gravity import GravitySystem
    from driftframe.systems.warp import WarpGovernorSystem
    rng = np.random.default_rng(5)
    worlds = {}
    for label, extra in (("without", False), ("with", True)):
        w = World()
        if extra:
            w.add_system(AutopilotSystem())
            w.add_system(GravitySystem())
            w.add_system(WarpGovernorSystem())
        w.add_system(MovementSystem())
        w.add_system(SpinSystem())
        w.create_entities(Transform.bulk(n, position=rng.normal(size=(n, 3))),
                          Velocity.bulk(n, linear=rng.normal(size=(n, 3))),
                          AngularVelocity.bulk(n, angular=rng.normal(size=(n, 3))))
        w.step(3)
        worlds[label] = w
    samples = {k: [] for k in worlds}
    try:
        for _ in range(repeats):
            for label, w in worlds.items():
                t0 = time.perf_counter()
                w.step()
                samples[label].append((time.perf_counter() - t0) / n * 1e9)
    finally:
        for w in worlds.values():
            w.close()
    return {k: (statistics.median(v), max(v)) for k, v in samples.items()}, samples


# ------------------------------------------------------------------------------------- main
def main(argv=None) -> int:
    parser = common.parser(__doc__.splitlines()[0])
    parser.add_argument("--cost", metavar="N", help="only the cost rows at these body counts, comma-separated "
                        "(e.g. 1000,10000), printed; no report")
    args = parser.parse_args(argv)
    if args.cost:
        return cost_only([int(k) for k in args.cost.split(",")], 5 if args.quick else 15)
    started = time.perf_counter()
    runs = QUICK_RUNS if args.quick else RUNS
    methods = [m for m in METHODS if have_rebound() or not m.startswith("REBOUND")]
    r0, v0 = ellipses()
    results = {}          # (method, spo) -> (E err per e + hyp, h err, phase err, seconds)
    for spo, orbits in runs:
        dt = 2 * math.pi / spo
        steps = spo * orbits
        (hr0, hv0), t_hyp, (hr1, _) = flyby()
        for m in methods:
            t0 = time.perf_counter()
            r, v = integrate(m, r0, v0, dt, steps)
            took = time.perf_counter() - t0
            eE, eh, eph = errors(r, v, r0, v0, r0)
            rh, vh = integrate(m, hr0, hv0, t_hyp / spo, spo)
            hE, hh, hph = errors(rh, vh, hr0, hv0, hr1)
            results[(m, spo)] = (np.append(eE, hE), np.append(eh, hh), np.append(eph, hph), took)
            print(f"  {m:32s} {spo:5d} steps/orbit x {orbits:6d} orbits: {took:7.2f} s  "
                  f"E {np.nanmax(eE):.1e}  h {np.nanmax(eh):.1e}  phase {np.nanmax(eph):.1e}", flush=True)
    n = 1_000 if args.quick else 10_000
    reps = 5 if args.quick else 15
    load_cost = os.getloadavg()
    cost, worst, ias_steps, cost_cpu = cost_kernels(n, reps)
    load_cost = (load_cost, os.getloadavg())
    sys_name = "driftframe GravitySystem in a World (on rails)"
    sys_med, sys_worst = cost[sys_name], worst[sys_name]
    free, _ = cost_without_well(n, 9 if args.quick else 41)

    # anchor: WHFast and IAS15, e = 0.5, 100 steps per orbit, 1,000 orbits, one particle
    anchor = {}
    if have_rebound():
        for integ in ("whfast", "ias15"):
            k = ECC.index(0.5)
            t0 = time.perf_counter()
            orbits = 10 if args.quick else 1_000
            r, v = run_rebound(integ, r0[k:k + 1], v0[k:k + 1], 2 * math.pi / 100, orbits * 2 * math.pi)
            anchor[integ] = (time.perf_counter() - t0, errors(r, v, r0[k:k + 1], v0[k:k + 1], r0[k:k + 1])[0][0])

    # every step, 10 steps per orbit, from three epochs; the floor; IAS15 from periapsis
    every_steps = 1_000 if args.quick else 10_000
    ias_steps = 200 if args.quick else 2_000
    every = {}
    for E0, label in EPOCHS:
        for e in ECC_EVERY:
            every[(label, e)] = every_step(e, E0, every_steps, False)
            if E0 == 0.0 and have_rebound():
                every[(label, e)]["IAS15"] = every_step(e, E0, ias_steps, True)["IAS15"]
            print(f"  every step from {label:11s} e={e:<8} " + "  ".join(
                f"{k} {v[0]:.2e}/{v[1]:.2e}" for k, v in every[(label, e)].items()), flush=True)
    hyp = hyperbolic_h(have_rebound())

    # ---- tables
    labels = [f"e={e}" for e in ECC] + [f"flyby e={E_HYP}"]
    body = []
    body.append(f"**Every step** ({every_steps:,} steps at 10 per orbit, on rails from an epoch at the eccentric "
                "anomaly shown): the worst |E/E0 - 1| and |h/h0 - 1| over all steps, beside the double-rounding "
                "floor (the exact state at each step rounded to doubles; long-double reference, "
                f"`benchmarks/orbit_reference.py`) and IAS15 read at each step ({ias_steps:,} steps, from "
                "periapsis). Energies and h are evaluated in long double.\n")
    rows = []
    for E0, label in EPOCHS:
        for e in ECC_EVERY:
            o = every[(label, e)]
            fl = o.get("floor", (float("nan"),) * 2)
            ias = o.get("IAS15", (float("nan"),) * 2)
            rows.append([label, e, o["rails"][0], fl[0], o["rails"][0] / fl[0], ias[0], o["rails"][1], fl[1], ias[1]])
    body.append(common.table(["epoch", "e", "E rails", "E floor", "rails/floor", "E IAS15", "h rails", "h floor",
                              "h IAS15"], rows) + "\n")
    body.append(f"Hyperbolic flyby (mu = {HYP_MU:.4g} m^3/s^2, periapsis {HYP_RP:.0f} m, e = {HYP_E}): |h/h0 - 1| "
                "at a time after periapsis, on rails (one evaluation from the epoch, the focal frame), the exact "
                "state rounded to doubles (floor: far out r and v are nearly parallel, so |r x v| of a double "
                "state is known only to ~ulp |r||v|/h) and IAS15:\n")
    body.append(common.table(["method"] + [f"t = {t:.0e} s" for t in HYP_TIMES],
                             [[k] + v for k, v in hyp.items() if v]) + "\n")
    body.append("Relative energy error |E/E0 - 1| after the run (ellipses: whole orbits from periapsis; "
                "flyby: from r = 20 rp in and out again in the same number of steps).\n")
    for spo, orbits in runs:
        rows = [[m] + [float(x) for x in results[(m, spo)][0]] + [float(results[(m, spo)][3])] for m in methods]
        body.append(f"**{spo} steps per orbit, {orbits:,} orbits** ({spo * orbits:,} steps)\n")
        body.append(common.table(["method"] + labels + ["run, s"], rows) + "\n")
    body.append("Angular-momentum error |h/h0 - 1| and along-track phase error (rad) at 10 steps per orbit "
                f"({runs[0][1]:,} orbits):\n")
    spo = runs[0][0]
    rows = [[m] + [float(x) for x in results[(m, spo)][1]] + [float(x) for x in results[(m, spo)][2]]
            for m in methods]
    body.append(common.table(["method"] + [f"h {lb}" for lb in labels] + [f"phase {lb}" for lb in labels],
                             rows) + "\n")
    body.append(f"Cost at {n:,} bodies (mixed e <= 0.9, 100 steps per orbit), ns per body-step, median of "
                f"{reps} interleaved repeats, wall time (the bar) and this process's CPU time (the machine is "
                "shared: numpy's many passes over memory suffer more from the neighbours than one C loop):\n")
    rows = [[m, float(cost[m]), float(worst[m]), float(cost_cpu[m])] for m in methods + [WHFAST0, sys_name]
            if m in cost]
    body.append(common.table(["method", "ns per body-step", "worst", "CPU ns per body-step"], rows) + "\n")
    if ias_steps is not None:
        body.append(f"(IAS15 is adaptive: {ias_steps} of its own steps per 10 of the others here; its cost "
                    "is per body per *fixed* step of the others.)\n")
    wf = cost.get("REBOUND WHFast")
    rails_e = max(float(np.max(results[("driftframe on rails", runs[0][0])][0][:4])),
                  float(np.max(results[("driftframe on rails", runs[0][0])][1][:4])))
    bars = [f"- On rails, 10 steps per orbit, {runs[0][1]:,} orbits: worst energy / angular-momentum error "
            f"{rails_e:.2e} (bar <= 1e-12): **{'met' if rails_e <= 1e-12 else 'NOT met'}**."]
    low = max(every[(lb, e)]["rails"][0] for _, lb in EPOCHS for e in ECC_EVERY if e <= 0.999)
    bars.append(f"- Every step, e <= 0.999, every epoch: worst energy error {low:.2e} (bar <= 1e-12): "
                f"**{'met' if low <= 1e-12 else 'NOT met'}**.")
    hi = [every[(lb, e)]["rails"][0] / every[(lb, e)]["floor"][0] for _, lb in EPOCHS for e in ECC_EVERY
          if e > 0.999 and "floor" in every[(lb, e)]]
    if hi:
        bars.append(f"- Every step, e > 0.999: worst ratio to the double-rounding floor {max(hi):.2f} (bar <= 2): "
                    f"**{'met' if max(hi) <= 2 else 'NOT met'}**.")
    if wf is not None:
        bars.append("- " + world_bar(n, cost, cost_cpu, load_cost) + " From "
                    f"{kepler.COMPILED_MIN} bodies on, Epoch.at runs one compiled (numba) loop per step, and the "
                    "system's usual step (one well, no thrust, no edit, no contact due) is one compiled call "
                    "straight from the tables: the gathers, the checks, the pass (the guess, the solution, the "
                    "move to the well) and the writes into the step context; what is left over the kernel is the "
                    "world's own step (the movement system's prediction, the step context's copies, the commit). "
                    "Kepler step to step is the numpy path (about 170 passes over the columns per step).")
    fw, fo = free["with"][0], free["without"][0]
    bars.append(f"- A scene without a well: the standard step on {n:,} free bodies costs {fw:.1f} ns per body with "
                f"the gravity, autopilot and warp systems scheduled and {fo:.1f} without (ratio {fw / fo:.3f}; "
                f"worst {free['with'][1]:.1f} / {free['without'][1]:.1f}): the gravity system returns after one "
                f"empty query and the movement system's skip check is one cached query.")
    if anchor:
        bars.append(f"- Anchor (issue: WHFast 0.039 s with 1.2e-13, IAS15 0.30 s with 9.6e-15): here WHFast "
                    f"{anchor['whfast'][0]:.3f} s with {anchor['whfast'][1]:.1e}, IAS15 {anchor['ias15'][0]:.3f} s "
                    f"with {anchor['ias15'][1]:.1e} (e = 0.5, 100 steps per orbit, "
                    f"{10 if args.quick else 1000} orbits, one particle).")
    body.append("\n".join(bars) + "\n")
    body.append("On rails the error does not grow with the number of orbits: each step propagates the epoch "
                "by the whole time since, so what is left is one evaluation's rounding (v^2/2 and mu/r cancel "
                "by 2/(1 - e) at periapsis, which is the floor at e = 0.99). Kepler step to step carries the "
                "rounding of each step into the next, repeated at the same phases every orbit, so it grows "
                "linearly; that path is only taken by a thrusting body, for the steps it thrusts.")

    # ---- chart: energy error vs cost, one panel per steps-per-orbit
    fig, axes = common.figure(1, len(runs), figsize=(5 * len(runs), 4.2), sharey=True)
    for ax, (spo, orbits) in zip(np.atleast_1d(axes), runs):
        for m in methods:
            if m not in cost:
                continue
            err = float(np.nanmax(results[(m, spo)][0][:4]))
            ax.scatter(cost[m], max(err, 1e-17), label=m, s=40)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("ns per body-step at 10,000 bodies")
        ax.set_title(f"{spo} steps/orbit, {orbits:,} orbits")
        ax.axhline(1e-12, color="grey", lw=0.8, ls="--")
    np.atleast_1d(axes)[0].set_ylabel("worst |E/E0 - 1| over e = 0..0.99")
    np.atleast_1d(axes)[-1].legend(fontsize=7, loc="best")
    common.save_chart(fig, "orbit_accuracy")
    common.write_section("orbit_accuracy", "Orbits: error against cost (driftframe, textbook, REBOUND)",
                         "\n".join(body), quick=args.quick, started=started)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
