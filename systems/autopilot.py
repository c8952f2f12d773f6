"""Flight aids: attitude holds, match velocity, timed burns, flip-and-burn (an autopilot that flies
through the pilot's controls)."""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import esper
import numpy as np

from driftframe.components.autopilot import Autopilot, FlightPlan
from driftframe.components.body import AngularVelocity, Transform, Velocity
from driftframe.components.control import FlightControl, FlightInput
from driftframe.components.gravity import GravityWell
from driftframe.framework import frame as fr
from driftframe.framework import validate
from driftframe.framework.orbit_state import OrbitState

_CONJ = np.array([-1.0, -1.0, -1.0, 1.0])


def _cross(a, b) -> np.ndarray:
    """a x b for two 3-vectors (np.cross's set-up dwarfs one vector's six products: docs/design/costs.md)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _rotate(q, v) -> np.ndarray:
    """v rotated by unit quaternion q (x, y, z, w): v + 2 w (u x v) + 2 u x (u x v), u = q.xyz."""
    u = q[:3]
    t = 2.0 * _cross(u, v)
    return np.asarray(v, float) + float(q[3]) * t + _cross(u, t)
#: Share of the ship's angular acceleration the turn plans with: the rest absorbs the turning of the
#: local axes during a manoeuvre and a target direction that moves, so the plan never needs more.
TURN_MARGIN = 0.8
#: Share of the thrust flip-and-burn plans its braking with.
BRAKE_MARGIN = 0.8


def stopping_rate(angle, accel: float, dt: float):
    """Fastest turn rate from which a turn of ``angle`` rad can stop *exactly* at zero, braking
    at ``accel`` rad/s^2 in fixed steps of ``dt`` (rate set, then the step turns by rate * dt).

    Steps of ``accel dt`` down to zero cover ``accel dt^2 n (n+1)/2``; solving for the rate
    ``accel dt n`` gives ``accel dt (sqrt(1/4 + 2 angle/(accel dt^2)) - 1/2)``. With it the last
    step lands on the target (no overshoot) and the next finds nothing left to do (no jitter).
    """
    h = accel * dt
    return h * (np.sqrt(0.25 + 2.0 * np.asarray(angle) / (h * dt)) - 0.5)


def flip_profile(distance, accel: float, flip_time: float):
    """Closing speed from which a ship can still flip (``flip_time`` s, coasting) and brake at
    ``accel`` to stop in ``distance``: the root of ``v T + v^2 / (2 a) = d``."""
    return accel * (np.sqrt(flip_time * flip_time + 2.0 * np.asarray(distance) / accel) - flip_time)


class AutopilotSystem(esper.Processor):
    """Reads Autopilot, FlightPlan, FlightControl, Transform, Velocity, AngularVelocity, OrbitState (and the
    GravityWell it answers from); writes FlightInput, Autopilot, FlightPlan.  Points the nose and works the
    throttle for the aid engaged.

    **Turning.** The error is the rotation taking the nose onto the wanted
    direction ``d``: axis ``f x d``, angle ``atan2(|f x d|, f.d)``. The wanted
    spin is ``axis * min(max_rate, stopping_rate(angle))`` (see
    :func:`stopping_rate`, planned with ``TURN_MARGIN`` of the ship's angular
    acceleration) plus the rate at which ``d`` itself turns (measured over the
    last step, so a prograde hold tracks the orbit without lag). The input is
    the spin change this needs, in the ship's local axes, divided by
    ``angular_accel * dt`` and clamped to [-1, 1]: so the angular acceleration
    is bounded by the ship's own, the turn never overshoots, and a held
    direction is held with zero input (no jitter). Roll is brought to zero.

    **Plans.** A :class:`~components.autopilot.FlightPlan` switches the
    Autopilot to its next leg at the step that holds the leg's time.

    **Thrust** fires only while the nose is within ``aim`` of ``d``, and never
    more than the task needs: the last step of a burn uses the throttle that
    delivers exactly what is left, so a timed burn delivers its ``dv`` to
    rounding (the gravity and movement systems add exactly ``a dt``).

    **Orbits.** Prograde, normal and radial are relative to the well the ship
    moves about now, as the gravity system's
    :class:`~driftframe.framework.orbit_state.OrbitState` resource tells it
    (``world.resources[OrbitState]``; without one, relative to the world frame).

    Few ships carry an autopilot: a per-entity loop. It runs in the control
    stage (after the input stage) before the other systems of that stage: the
    control system turns its input into spin and thrust.
    """

    stage = "control"
    before = ("control",)                # the control system, by name: its input is for it
    reads = (Autopilot, FlightPlan, FlightControl, Transform, Velocity, AngularVelocity, OrbitState, GravityWell)
    writes = (FlightInput, Autopilot, FlightPlan)
    requires = (Autopilot,)              # (a FlightPlan engages an Autopilot: without one, nothing to do)

    def __init__(self) -> None:
        self._last_dir: dict[int, np.ndarray] = {}

    def state(self) -> dict[str, Any]:
        """What a save keeps of this system (see framework/save.py): each ship's wanted direction of the
        last step (the turn rate of the direction is measured against it)."""
        return {"last_dir": {int(e): np.array(d, float) for e, d in self._last_dir.items()}}

    def restore(self, state: dict[str, Any]) -> None:
        """Take back :meth:`state` (a load)."""
        self._last_dir = {int(e): np.array(d, float) for e, d in state["last_dir"].items()}

    # -- where things are -----------------------------------------------------------------------
    def _state(self, ent: int, what: str):
        tf = esper.try_component(ent, Transform)
        if tf is None:
            raise ValueError(f"Autopilot {what}: entity {validate.shown(ent)} does not exist or has no Transform "
                             f"(an unreachable target)")
        vel = esper.try_component(ent, Velocity)
        return tf.position.copy(), (vel.linear.copy() if vel is not None else np.zeros(3))

    def _well(self, ent: int) -> tuple[np.ndarray, np.ndarray]:
        """The centre (m) and velocity (m/s) of the well ``ent`` moves about now; the world's origin at rest
        without one."""
        orbits = self.world.resources.get(OrbitState)
        ref = orbits.reference(ent) if orbits is not None else None
        if ref is None:
            return np.zeros(3), np.zeros(3)
        return ref.position, ref.velocity

    def direction(self, ent: int, name: str, ap: Autopilot, x: np.ndarray, v: np.ndarray) -> np.ndarray | None:
        """Unit vector (world frame) of direction ``name`` for ship ``ent`` now, or None if undefined."""
        if name in ("target", "anti_target"):
            p, _ = self._state(ap.target, f"{name} of entity {ent}")
            d = p - x
            if name == "anti_target":
                d = -d
        else:
            X, V = self._well(ent)
            r, u = x - X, v - V
            if name in ("prograde", "retrograde"):
                d = u if name == "prograde" else -u
            elif name in ("normal", "antinormal"):
                d = _cross(r, u)
                if name == "antinormal":
                    d = -d
            else:                                   # radial: r made perpendicular to the velocity
                uu = u @ u
                d = r - (r @ u / uu) * u if uu > 0 else r
                if name == "radial_in":
                    d = -d
        n = float(np.linalg.norm(d))
        return d / n if n > 0 and np.isfinite(n) else None

    # -- the step -------------------------------------------------------------------------------
    def _follow_plans(self, t0: float, dt: float) -> None:
        """Engage the legs of every FlightPlan whose time has come (at the step that holds it)."""
        for ent, (plan, ap) in esper.get_components(FlightPlan, Autopilot):
            while plan.next < len(plan.legs) and plan.legs[plan.next][0] < t0 + 0.5 * dt:
                leg = plan.legs[plan.next][1]
                for f in dataclasses.fields(Autopilot):
                    setattr(ap, f.name, getattr(leg, f.name))
                ap.delivered, ap.done, ap.status = 0.0, False, ""
                plan.next += 1

    def process(self, dt: float) -> None:
        t0 = self.world.step_count * dt
        self._follow_plans(t0, dt)
        flown = esper.get_components(Autopilot, FlightControl, FlightInput)
        if len(flown) != len(esper.get_component(Autopilot)):
            self._name_the_unflyable({ent for ent, _ in flown})
        for ent, (ap, ctl, inp) in flown:
            if ap.mode == "off":
                self._last_dir.pop(ent, None)
                continue
            if ctl.mode != "momentum":
                raise ValueError(f"Autopilot of entity {ent} needs FlightControl.mode 'momentum' "
                                 f"(it flies by angular acceleration), got {ctl.mode!r}")
            tf = esper.component_for_entity(ent, Transform)
            spin = esper.component_for_entity(ent, AngularVelocity)
            q = tf.orientation.copy()
            w = spin.angular.copy()
            x, v = tf.position.copy(), esper.component_for_entity(ent, Velocity).linear.copy()
            d, throttle = self._task(ent, ap, ctl, x, v, t0, dt, q)
            pitch, yaw, roll, err = self._turn(ent, q, w, d, ctl.angular_accel, dt, ap)
            if throttle > 0 and err > ap.aim:
                throttle = 0.0                       # not pointing there yet: wait
            if throttle > 0 and ap.mode in ("burn",):
                ap.delivered += throttle * ctl.thrust * dt
            inp.pitch, inp.yaw, inp.roll = pitch, yaw, roll
            inp.throttle = float(min(max(throttle, 0.0), 1.0))

    def _name_the_unflyable(self, flyable: set) -> None:
        """A ValueError naming the first engaged Autopilot that cannot fly: it flies through the ship's own
        FlightInput and FlightControl (and reads its Transform, Velocity, AngularVelocity), so without one of
        them it would do nothing, without a word."""
        for ent, ap in sorted(esper.get_component(Autopilot), key=lambda p: p[0]):
            if ent in flyable or ap.mode == "off":
                continue
            missing = [c.__name__ for c in (FlightInput, FlightControl)
                       if not esper.has_component(ent, c)]
            raise ValueError(f"Autopilot {ap.mode} of entity {ent} cannot fly it: it has no "
                             f"{' and no '.join(missing)} (the autopilot flies through the ship's own "
                             "FlightInput, with its FlightControl's thrust and angular_accel)")

    def _task(self, ent, ap: Autopilot, ctl, x, v, t0, dt, q):
        """(wanted nose direction or None to hold still, throttle in [0, 1]) for the aid engaged."""
        mode = ap.mode
        if mode in ("target", "anti_target", "match_velocity") or ap.target is not None:
            self._state(ap.target, f"{mode} of entity {ent}") if ap.target is not None else None
        if mode not in ("match_velocity", "burn", "flip_and_burn"):
            ap.status = mode.replace("_", " ")
            return self.direction(ent, mode, ap, x, v), 0.0
        if ctl.thrust <= 0:
            raise ValueError(f"Autopilot {mode} of entity {ent}: FlightControl.thrust is {float(ctl.thrust)!r}, "
                             f"so no burn can reach it (an unreachable target)")
        full = ctl.thrust * dt                      # m/s one step at full throttle gives
        if ap.done and mode != "flip_and_burn":     # flip-and-burn keeps station once there
            return None, 0.0
        if mode == "burn":
            d = self.direction(ent, ap.along, ap, x, v)
            left = ap.dv - ap.delivered
            start = ap.at - 0.5 * ap.dv / ctl.thrust
            if left <= 1e-12 * ap.dv:
                ap.done = True
                ap.status = f"burn done: {ap.delivered:.3f} m/s"
                return None, 0.0
            if t0 + 0.5 * dt < start:
                ap.status = f"burn {ap.dv:.1f} m/s {ap.along} in {start - t0:.0f} s"
                return d, 0.0
            ap.status = f"burning: {left:.1f} m/s to go"
            return d, min(1.0, left / full)
        # relative velocity to the target (or to rest at a point)
        if ap.target is not None:
            p, vt = self._state(ap.target, f"{mode} of entity {ent}")
        else:
            p, vt = np.asarray(ap.point, float), np.zeros(3)
        v_rel = v - vt
        if mode == "match_velocity":
            s = float(np.linalg.norm(v_rel))
            if s <= ap.tolerance:
                ap.done = True
                ap.status = f"velocity matched ({s:.3f} m/s)"
                return None, 0.0
            ap.status = f"matching velocity: {s:.2f} m/s"
            return -v_rel / s, min(1.0, s / full)
        # flip and burn: wanted velocity towards the point on the braking profile
        rel = p - x
        dist = float(np.linalg.norm(rel))
        # the words give the distance to the target itself (the HUD's CLOSEST measures the same), not to
        # the stopping point standoff m short of it: "arrived 0.09 m" beside "CLOSEST 30 m" read as a contradiction
        away = dist
        if ap.standoff > 0 and dist > 0:                # stop short of it, on the line towards it
            rel = rel * max(0.0, 1.0 - ap.standoff / dist)
            dist = float(np.linalg.norm(rel))
        speed = float(np.linalg.norm(v_rel))
        if dist <= ap.tolerance * 10.0 and speed <= ap.tolerance:
            ap.done = True
            ap.status = f"arrived: {away:.1f} m off, {speed:.3f} m/s"
            return None, 0.0
        if ap.done:                                  # drifted off (tides in orbit): back to the point
            ap.status = f"keeping station: {away:.1f} m off"
        alpha = TURN_MARGIN * ctl.angular_accel
        flip = 2.0 * math.sqrt(math.pi / alpha) + 4.0 * dt    # a half turn, bang-bang, and a margin
        v_want = (rel / dist if dist > 0 else np.zeros(3)) * float(flip_profile(dist, BRAKE_MARGIN * ctl.thrust,
                                                                                 flip))
        need = v_want - v_rel
        n = float(np.linalg.norm(need))
        if not ap.done:
            ap.status = f"flip & burn: {away:.0f} m, closing {float((rel @ v_rel) / max(dist, 1e-300)):.1f} m/s"
        if n <= 0.5 * ap.tolerance:
            return None, 0.0                         # on the profile: coast, hold the attitude
        return need / n, min(1.0, n / full)

    def _turn(self, ent, q, w, d, accel: float, dt: float, ap: Autopilot):
        """(pitch, yaw, roll inputs, pointing error in rad) that bring the nose onto ``d``."""
        f = _rotate(q, fr.FORWARD)
        if d is None:                                # hold still: take the spin out
            self._last_dir.pop(ent, None)
            want = np.zeros(3)
            err = 0.0
        else:
            c = _cross(f, d)
            s = float(np.linalg.norm(c))
            err = math.atan2(s, float(f @ d))
            if s > 1e-300:
                axis = c / s
            elif err > 1.0:                          # exactly backwards: any perpendicular axis
                axis = _rotate(q, fr.UP)
            else:
                axis = np.zeros(3)
            rate = min(ap.max_rate, float(stopping_rate(err, TURN_MARGIN * accel, dt)))
            want = axis * rate
            last = self._last_dir.get(ent)
            if last is not None:                     # the direction's own turning, fed forward
                cc = _cross(last, d)
                sc = float(np.linalg.norm(cc))
                if sc > 0:
                    want = want + cc / sc * (math.atan2(sc, float(last @ d)) / dt)
            self._last_dir[ent] = d.copy()
        change = _rotate(q * _CONJ, want - w)      # world -> local (pitch about x, yaw about y, roll about z)
        inp = np.clip(change / (accel * dt), -1.0, 1.0) if accel > 0 else np.zeros(3)
        return float(inp[0]), float(inp[1]), float(inp[2]), err
