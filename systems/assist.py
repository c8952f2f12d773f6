"""The kill-rotation assist."""
from __future__ import annotations

import esper
import numpy as np

from driftframe.components.body import AngularVelocity, Transform
from driftframe.components.control import FlightInput, RotationAssist
from driftframe.framework import frame as fr

_ORDER = ("roll", "pitch", "yaw")
_CONJUGATE = np.array([-1.0, -1.0, -1.0, 1.0])   # q * _CONJUGATE is the inverse rotation


def brake_spin(w: np.ndarray, q: np.ndarray, axes: str, budget: float) -> np.ndarray:
    """New world spin after removing at most ``budget`` rad/s of it (``budget = max_decel * dt``).

    * ``all``: shrink ``w`` along itself by ``min(|w|, budget)``; exactly zero at the end.
    * ``roll``/``pitch``/``yaw``: shrink that local component towards zero by at most ``budget``.
    * ``sequential``: roll, then pitch, then yaw, spending the budget in that order.

    Never overshoots: a component that would pass zero is set to zero.
    Local components come from ``R^T w`` and go back with ``R``; with no torque
    acting, a frame spinning about ``w`` keeps those components constant.
    """
    if axes == "all":
        rate = float(np.linalg.norm(w))
        if rate <= budget:
            return np.zeros(3)
        return w * ((rate - budget) / rate)
    local = fr.rotate(q * _CONJUGATE, w)          # R^T w
    names = _ORDER if axes == "sequential" else (axes,)
    for name in names:
        i = {"pitch": 0, "yaw": 1, "roll": 2}[name]
        take = min(abs(local[i]), budget)
        local[i] = 0.0 if take == abs(local[i]) else local[i] - np.copysign(take, local[i])
        budget -= take
        if budget <= 0:
            break
    return fr.rotate(q, local)


class RotationAssistSystem(esper.Processor):
    """Reads RotationAssist, FlightInput, Transform; writes AngularVelocity.  Kill rotation.

    While engaged (``RotationAssist.engaged`` or ``FlightInput.kill_rotation``)
    removes spin at no more than ``max_decel`` rad/s^2: all axes at once, or
    one local axis at a time (see :func:`brake_spin`). Runs after control, so
    holding a turn key and the assist together leaves only what the assist
    allows. Few bodies carry an assist: a per-entity loop.
    """

    stage = "control"
    name = "assist"
    after = ("control",)        # it brakes what the pilot's input left
    reads = (RotationAssist, FlightInput, Transform, AngularVelocity)
    writes = (AngularVelocity,)
    requires = (RotationAssist, Transform, AngularVelocity)

    def process(self, dt: float) -> None:
        for ent, (assist, tf, spin) in esper.get_components(RotationAssist, Transform, AngularVelocity):
            inp = esper.try_component(ent, FlightInput)
            if not (assist.engaged or (inp is not None and inp.kill_rotation)):
                continue
            w = spin.angular
            if not w.any():
                continue
            spin.angular = brake_spin(w.copy(), tf.orientation.copy(), assist.axes, assist.max_decel * dt)
