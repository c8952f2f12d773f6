"""Flight control: the pilot's input becomes thrust and spin."""
from __future__ import annotations

import esper
import numpy as np

from driftframe.components.body import Acceleration, AngularVelocity, Transform
from driftframe.components.control import FlightControl, FlightInput
from driftframe.framework import frame as fr


class ControlSystem(esper.Processor):
    """Reads FlightInput, FlightControl, Transform, AngularVelocity; writes Acceleration, AngularVelocity.

    Thrust: ``a = throttle * thrust * forward_mid`` (world frame), held for
    the step and integrated exactly by the movement system. ``forward_mid``
    is the nose half-way through the step: the spin system turns the body by
    ``w dt`` this step, so the nose is sampled at ``exp(w dt/2) (x) q``. For a
    turning body that makes the thrust second order in ``dt`` (sampling at
    the step's start is first order: 0.89 m against 1e-3 m after 10 s of full
    thrust at 1 rad/s, 60 Hz; ``benchmarks/thrust_accuracy.py``); for a body
    that does not turn it is the nose itself.

    Rotation input is given about the body's *local* axes (roll about
    forward, pitch about right, yaw about up) and turned into a world vector
    ``R @ (pitch, yaw, roll)`` before it touches the world-frame spin:

    * ``direct``: ``w = R @ (turn_rate * input)`` — the body turns only while
      input is held and stops when it is released (Framework 0.0.2);
    * ``momentum``: ``w += R @ (angular_accel * input) * dt`` — spin
      accumulates and persists until countered (Framework 0.0.4).

    A handful of piloted bodies per scene: a per-entity loop is fine here.
    """

    stage = "control"
    reads = (FlightInput, FlightControl, Transform, AngularVelocity)
    writes = (Acceleration, AngularVelocity)
    requires = (FlightInput, FlightControl, Transform, Acceleration, AngularVelocity)

    def process(self, dt: float) -> None:
        for _, (inp, ctl, tf, acc, spin) in esper.get_components(
                FlightInput, FlightControl, Transform, Acceleration, AngularVelocity):
            q = tf.orientation
            local = np.array([inp.pitch, inp.yaw, inp.roll])   # about local x, y, z
            if ctl.mode == "direct":
                spin.angular = fr.rotate(q, ctl.turn_rate * local)
            elif local.any():
                spin.angular = spin.angular + fr.rotate(q, ctl.angular_accel * dt * local)
            if inp.throttle:
                w = spin.angular
                q_mid = fr.quat_multiply(fr.quat_from_rotvec(0.5 * dt * w), q) if w.any() else q
                acc.linear = (inp.throttle * ctl.thrust) * fr.rotate(q_mid, fr.FORWARD)
            else:
                acc.linear = (0.0, 0.0, 0.0)
