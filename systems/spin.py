"""Exact rotation of body frames by their angular velocity."""
from __future__ import annotations

import esper
import numpy as np

from components.body import AngularVelocity, Transform
from framework import frame as fr
from framework.store import RowCache, to_indices


class SpinSystem(esper.Processor):
    """Reads AngularVelocity; writes Transform.orientation.  q' = exp(w dt / 2) (x) q, renormalised.

    ``w`` is a world-frame vector, so the increment ``dq`` = rotation by
    ``|w| dt`` about ``w/|w|`` multiplies on the left. The rotation is exact
    for any angle (no small-angle approximation: ``|w| dt`` above pi is
    fine), and renormalising ``q`` each step keeps the derived frame
    orthonormal to a few ulps for any number of steps.

    Model no more than needed: bodies whose spin is exactly zero are not
    touched (their quaternion keeps its bits). Whole-column numpy; rows are
    rebuilt only when esper's query changes.
    """

    stage = "spin"

    def __init__(self):
        self._rows = RowCache()

    def process(self, dt: float) -> None:
        c = self._rows
        c.update(esper.get_components(Transform, AngularVelocity))
        if not len(c.entities):
            return
        t_rows, w_rows = c.rows
        w = AngularVelocity._table.data["angular"][w_rows]
        spinning = np.any(w != 0.0, axis=1)
        if not spinning.any():
            return
        if not spinning.all():
            w = w[spinning]
            t_rows = to_indices(t_rows)[spinning]
        q_all = Transform._table.data["orientation"]
        q = fr.quat_multiply(fr.quat_from_rotvec(w * dt), q_all[t_rows])
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        q_all[t_rows] = q
