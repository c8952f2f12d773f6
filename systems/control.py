"""Flight control: the pilot's input becomes thrust and spin."""
from __future__ import annotations

import esper
import numpy as np

from components.body import Acceleration, AngularVelocity, Transform
from components.control import FlightControl, FlightInput
from framework import frame as fr


class ControlSystem(esper.Processor):
    """Reads FlightInput, FlightControl, Transform; writes Acceleration, AngularVelocity.

    Thrust: ``a = throttle * thrust * forward`` (world frame), held for the
    step and integrated exactly by the movement system.

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

    def process(self, dt: float) -> None:
        for _, (inp, ctl, tf, acc, spin) in esper.get_components(
                FlightInput, FlightControl, Transform, Acceleration, AngularVelocity):
            q = tf.orientation
            acc.linear = (inp.throttle * ctl.thrust) * fr.rotate(q, fr.FORWARD)
            local = np.array([inp.pitch, inp.yaw, inp.roll])   # about local x, y, z
            if ctl.mode == "direct":
                spin.angular = fr.rotate(q, ctl.turn_rate * local)
            elif local.any():
                spin.angular = spin.angular + fr.rotate(q, ctl.angular_accel * dt * local)
