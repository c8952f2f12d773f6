"""Position under thrust: explicit Euler, semi-implicit Euler and the exact constant-acceleration update.

A body starts at ``x0`` with velocity ``v0`` and thrusts with a constant
acceleration ``a`` (world frame, m/s^2) for T = 10 s. The closed form is
``x(t) = x0 + v0 t + a t^2 / 2``. Per step of ``dt``:

* explicit Euler:       ``x += v dt;  v += a dt``   (lags by ``a t dt / 2``)
* semi-implicit Euler:  ``v += a dt;  x += v dt``   (leads by ``a t dt / 2``)
* exact:                ``x += v dt + a dt^2 / 2;  v += a dt``  (what ``MovementSystem`` does,
  as two adds: ``x += v dt`` for every moving body, then ``x += a dt^2/2`` for thrusting ones)

The reference is evaluated in exact rational arithmetic from the same float
inputs, so the error of the exact update is pure rounding. The real
``MovementSystem`` is run through a ``World`` beside the kernels, and checked
to land on the exact kernel's result.

A second case shows what "exact" does not cover: thrust along the nose of a
body that keeps turning (1 rad/s). The thrust direction changes inside the
step, so a scheme that holds the nose of the step's start is first order in
``dt`` against the continuous solution whatever its integrator: the exact
update removes the integration error, not the sampling error. The real
pipeline (control -> movement -> spin) samples the nose at mid-step, which
makes it second order.
"""
from __future__ import annotations

import math
import time
from fractions import Fraction

import esper
import numpy as np

from benchmarks import common
from driftframe.components.body import Acceleration, AngularVelocity, Transform, Velocity
from driftframe.components.control import FlightControl, FlightInput
from driftframe.framework.world import World
from driftframe.systems.control import ControlSystem
from driftframe.systems.movement import MovementSystem
from driftframe.systems.spin import SpinSystem

X0 = np.array([120.0, -35.0, 40.0])              # m
V0 = np.array([20.0, 3.0, -5.0])                 # m/s
A = 10.0 * np.array([0.36, 0.48, 0.8])           # m/s^2 (|a| = 10)
T = 10.0                                          # s


# ---------------------------------------------------------------------------- kernels on (n, 3) columns

def explicit_euler(x, v, a, dt):
    x += v * dt
    v += a * dt


def semi_implicit_euler(x, v, a, dt):
    v += a * dt
    x += v * dt


def exact_update(x, v, a, dt):
    # as MovementSystem: the free part x += v dt, then the constant-acceleration term a dt^2 / 2
    x += v * dt
    x += (0.5 * dt * dt) * a
    v += dt * a


METHODS = {
    "explicit Euler": (explicit_euler, "s--", "#d62728"),
    "semi-implicit Euler": (semi_implicit_euler, "^--", "#ff7f0e"),
    "exact constant-acceleration": (exact_update, "o-", "#2ca02c"),
}


def closed_form(dt: float, steps: int) -> np.ndarray:
    """x0 + v0 t + a t^2 / 2 at t = steps * dt, in exact rationals from the float inputs."""
    t = Fraction(steps) * Fraction(dt)
    return np.array([float(Fraction(x) + Fraction(v) * t + Fraction(a) * t * t / 2)
                     for x, v, a in zip(X0.tolist(), V0.tolist(), A.tolist())])


def run_kernel(fn, dt: float, steps: int) -> np.ndarray:
    x, v, a = X0[None].copy(), V0[None].copy(), A[None].copy()
    for _ in range(steps):
        fn(x, v, a, dt)
    return x[0]


def run_movement_system(dt: float, steps: int) -> np.ndarray:
    world = World(dt=dt)
    try:
        world.add_system(MovementSystem())
        e = world.create_entity(Transform(position=X0), Velocity(V0), Acceleration(A))
        world.step(steps)
        return esper.component_for_entity(e, Transform).position.copy()
    finally:
        world.close()


def cost(n: int, repeats: int) -> dict[str, float]:
    """ns per body-step of each kernel on (n, 3) arrays, and of MovementSystem.process with thrust."""
    rng = np.random.default_rng(0)
    x, v, a = rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    out = {}
    for name, (fn, _, _) in METHODS.items():
        out[name] = common.median_time(lambda: fn(x, v, a, 1 / 60), repeats=repeats, number=20) / n * 1e9
    world = World()
    try:
        move = world.add_system(MovementSystem())
        world.create_entities(Transform.bulk(n, position=x), Velocity.bulk(n, linear=v),
                              Acceleration.bulk(n, linear=a))
        world.step()
        out["MovementSystem"] = common.median_time(lambda: move.process(world.dt), repeats=repeats,
                                                   number=20) / n * 1e9
    finally:
        world.close()
    return out


# ---------------------------------------------------------------------------- turning thrust

OMEGA = 1.0          # rad/s about world up: the nose turns in the x-z plane
THRUST = 10.0        # m/s^2 along the nose


def turning_closed_form(t: float) -> np.ndarray:
    """Continuous solution: a(t) = A (sin wt, 0, cos wt) from the nose (0, 0, 1) at t = 0."""
    w = OMEGA
    return X0 + V0 * t + (THRUST / w) * np.array([t - math.sin(w * t) / w, 0.0, (1.0 - math.cos(w * t)) / w])


def turning_kernel(fn, dt: float, steps: int, at: float = 0.0) -> np.ndarray:
    """The kernel with the thrust direction sampled at ``at`` of each step (0 = its start, as the
    control stage does; 0.5 = mid-step)."""
    x, v = X0[None].copy(), V0[None].copy()
    for k in range(steps):
        t = (k + at) * dt
        a = THRUST * np.array([[math.sin(OMEGA * t), 0.0, math.cos(OMEGA * t)]])
        fn(x, v, a, dt)
    return x[0]


def turning_pipeline(dt: float, steps: int) -> np.ndarray:
    """The real pipeline: ControlSystem (throttle 1) -> MovementSystem -> SpinSystem."""
    world = World(dt=dt)
    try:
        for s in (ControlSystem(), MovementSystem(), SpinSystem()):
            world.add_system(s)
        e = world.create_entity(Transform(position=X0), Velocity(V0), Acceleration(), AngularVelocity((0, OMEGA, 0)),
                                FlightInput(throttle=1.0), FlightControl(thrust=THRUST, mode="momentum"))
        world.step(steps)
        return esper.component_for_entity(e, Transform).position.copy()
    finally:
        world.close()


def main(argv=None) -> int:
    args = common.parser(__doc__.splitlines()[0]).parse_args(argv)
    quick = args.quick
    dts = [1 / 15, 1 / 60, 1 / 240] if quick else [1 / 15, 1 / 30, 1 / 60, 1 / 120, 1 / 240, 1 / 480, 1 / 960,
                                                   1 / 1920]
    n_cost = 2_000 if quick else 10_000
    repeats = 3 if quick else 9
    t_start = time.perf_counter()

    err = {name: {} for name in METHODS}
    err["MovementSystem"] = {}
    turn = {name: {} for name in METHODS}
    turn["driftframe pipeline"] = {}
    turn["exact, nose sampled mid-step"] = {}
    same_as_exact = True
    for dt in dts:
        steps = round(T / dt)
        ref = closed_form(dt, steps)
        for name, (fn, _, _) in METHODS.items():
            err[name][dt] = float(np.linalg.norm(run_kernel(fn, dt, steps) - ref))
        sys_x = run_movement_system(dt, steps)
        err["MovementSystem"][dt] = float(np.linalg.norm(sys_x - ref))
        same_as_exact &= bool(np.array_equal(sys_x, run_kernel(exact_update, dt, steps)))
        tref = turning_closed_form(steps * dt)
        for name, (fn, _, _) in METHODS.items():
            turn[name][dt] = float(np.linalg.norm(turning_kernel(fn, dt, steps) - tref))
        turn["driftframe pipeline"][dt] = float(np.linalg.norm(turning_pipeline(dt, steps) - tref))
        turn["exact, nose sampled mid-step"][dt] = float(np.linalg.norm(
            turning_kernel(exact_update, dt, steps, at=0.5) - tref))
    c = cost(n_cost, repeats)
    print(f"[thrust_accuracy] errors at dt=1/60: { {k: v.get(1 / 60) for k, v in err.items()} }")
    print(f"[thrust_accuracy] ns per body-step: { {k: round(v, 2) for k, v in c.items()} }")
    print(f"[thrust_accuracy] MovementSystem bit-identical to the exact kernel: {same_as_exact}")

    # ------------------------------------------------------------------ chart
    fig, axs = common.figure(1, 3, figsize=(16, 4.8))
    floor = 1e-16
    for name, (_, style, color) in METHODS.items():
        axs[0].plot(dts, [max(err[name][d], floor) for d in dts], style, color=color, label=name)
        axs[2].plot(dts, [max(turn[name][d], floor) for d in dts], style, color=color, label=name)
        axs[1].scatter(c[name], max(err[name][1 / 60], floor), color=color, s=50, label=name)
    axs[0].plot(dts, [max(err["MovementSystem"][d], floor) for d in dts], "k+", ms=10, label="MovementSystem (World)")
    axs[2].plot(dts, [turn["driftframe pipeline"][d] for d in dts], "k+", ms=10,
                label="control -> movement -> spin (World)")
    axs[2].plot(dts, [turn["exact, nose sampled mid-step"][d] for d in dts], "o:", color="#1f77b4",
                label="exact, nose sampled mid-step")
    axs[1].scatter(c["MovementSystem"], max(err["MovementSystem"][1 / 60], floor), color="k", marker="+", s=80,
                   label="MovementSystem (World)")
    for ax in (axs[0], axs[2]):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("dt (s)")
        ax.set_ylabel(f"position error after {T:g} s (m)")
        ax.legend(fontsize=8)
    axs[0].set_title("constant thrust (10 m/s^2): error against dt", fontsize=10)
    axs[2].set_title(f"thrust along a nose turning at {OMEGA:g} rad/s ", fontsize=10)
    axs[1].set_xlabel(f"ns per body-step ({n_cost:,} bodies)")
    axs[1].set_ylabel("position error after 10 s at dt = 1/60 (m)")
    axs[1].set_yscale("log")
    axs[1].set_title("constant thrust: error against cost, dt = 1/60", fontsize=10)
    axs[1].legend(fontsize=8)
    common.save_chart(fig, "thrust_accuracy")

    # ------------------------------------------------------------------ table
    L = [f"Constant thrust |a| = 10 m/s^2 for {T:g} s from x0 = {X0.tolist()} m, v0 = {V0.tolist()} m/s; "
         f"error = distance from the closed form (exact rationals). Cost: {n_cost:,} bodies as (N, 3) "
         f"arrays, median of {repeats}. The real `MovementSystem`, run through a `World`, is "
         f"{'bit-identical to' if same_as_exact else 'NOT identical to'} the exact kernel at every dt.", ""]
    names = list(METHODS) + ["MovementSystem"]
    rows = []
    for dt in dts:
        rows.append([f"1/{round(1 / dt)}", round(T / dt)] + [f"{err[n][dt]:.2e}" for n in names])
    rows.append(["ns per body-step", "-"] + [f"{c[n]:.2f}" for n in names])
    L.append(common.table(["dt (s)", "steps"] + [f"{n} error (m)" for n in names], rows))
    L.append("")
    e60 = {n: err[n][1 / 60] for n in names}
    half = 0.5 * 10.0 * T * (1 / 60)
    L.append(f"At dt = 1/60 both Euler variants are off by {e60['explicit Euler']:.3f} m and "
             f"{e60['semi-implicit Euler']:.3f} m after {T:g} s, as predicted by |a| T dt / 2 = {half:.3f} m "
             f"(explicit lags, semi-implicit leads), and halve with dt; the exact update is off by "
             f"{e60['exact constant-acceleration']:.1e} m, which is rounding (it grows slowly as steps get "
             f"smaller and more numerous, it does not shrink). It costs "
             f"{c['exact constant-acceleration'] / c['explicit Euler']:.2f}x explicit Euler per body-step "
             f"({c['exact constant-acceleration']:.2f} vs {c['explicit Euler']:.2f} ns); the whole "
             f"`MovementSystem` step with thrust (gathers and scatters included) costs "
             f"{c['MovementSystem']:.2f} ns per body.")
    L.append("")
    L.append(f"Thrust along a turning nose ({OMEGA:g} rad/s), against the continuous solution:")
    L.append("")
    tnames = list(METHODS) + ["driftframe pipeline", "exact, nose sampled mid-step"]
    rows = [[f"1/{round(1 / dt)}"] + [f"{turn[n][dt]:.2e}" for n in tnames] for dt in dts]
    L.append(common.table(["dt (s)"] + [f"{n} error (m)" for n in tnames], rows))
    L.append("")
    def order(name):
        return math.log(turn[name][dts[0]] / turn[name][dts[-1]]) / math.log(dts[0] / dts[-1])

    L.append(f"With the nose of the step's start held for the whole step the exact update is first order "
             f"too (error ~ dt^{order('exact constant-acceleration'):.2f}): the error is in the sampling, not "
             f"the integration, and the three schemes differ little (at 60 Hz after {T:g} s of turning at "
             f"full thrust: explicit {turn['explicit Euler'][1 / 60]:.3f} m, semi-implicit "
             f"{turn['semi-implicit Euler'][1 / 60]:.3f} m, exact {turn['exact constant-acceleration'][1 / 60]:.3f}"
             f" m). Sampling the nose at mid-step makes it order {order('exact, nose sampled mid-step'):.2f} "
             f"({turn['exact, nose sampled mid-step'][1 / 60]:.1e} m at 60 Hz), and that is what driftframe's "
             f"`ControlSystem` does: the real pipeline is off by {turn['driftframe pipeline'][1 / 60]:.1e} m "
             f"(order {order('driftframe pipeline'):.2f}), for one extra quaternion product per piloted body.")
    common.write_section("thrust_accuracy", "Thrust accuracy: Euler vs exact",
                         "\n".join(L), quick=quick, started=t_start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
