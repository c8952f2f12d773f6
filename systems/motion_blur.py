"""Poses between fixed steps, for motion blur in recordings (``record(..., motion_blur=N)``).

The recorder renders N sub-frames per frame and averages them. Each sub-frame
needs the scene at a time between two fixed steps; this module keeps the
poses of every Transform at each step of the frame and poses the scene at a
fraction ``s`` of the frame's interval, then puts the stepped state back
exactly, so the simulation never sees the sub-frames.

Between step ``i`` and ``i + 1`` (``a`` in [0, 1) of the way):

* position: ``x_i + a (x_{i+1} - x_i)``, the chord between the stepped
  positions, exact in free flight. Not the step's own update
  (:func:`framework.step.advance`) from ``x_i``: the chord ends where the
  step ended also for a body whose step a contact or a rail corrected, and
  under a constant acceleration ``g`` it is off the parabola by at most
  ``|g| dt^2 / 8`` (0.7 mm at 20 m/s^2 and 60 Hz);
* orientation of a body with an AngularVelocity ``w`` (world frame, rad/s,
  as it was during the step): ``exp(a dt w / 2) (x) q_i``, the spin system's
  own exact rotation for part of a step. Slerp between the two stepped
  quaternions cannot do this: a body turning a whole revolution per step has
  the same quaternion at both ends, and would look still (the wagon-wheel
  effect the blur is there to remove);
* orientation of anything else (cameras): slerp from ``q_i`` to ``q_{i+1}``.

If entities appear or disappear during the frame, that frame is not blurred
(every sub-frame shows the stepped state).
"""
from __future__ import annotations

from fractions import Fraction

import numpy as np

from driftframe.components.body import AngularVelocity, Transform
from driftframe.framework import frame as fr


class SubframePoses:
    """What :func:`framework.recorder.record` calls to pose sub-frames: start, after_step, pose, restore.

    Reads and writes Transform and reads AngularVelocity through the world's
    column API (``world.columns``), whole columns at a time.
    """

    def start(self, world) -> None:
        """A frame begins: remember the poses it starts from."""
        cols = world.columns(Transform)
        self._dt = world.dt
        self._entities = cols.entities.copy()
        self._pos = [cols.position]
        self._quat = [cols.orientation]
        self._spin: list[np.ndarray] = []
        self._changed = False

    def _same_entities(self, cols) -> bool:
        return len(cols.entities) == len(self._entities) and bool(np.all(cols.entities == self._entities))

    def after_step(self, world) -> None:
        """One fixed step of the frame is done: remember its poses and the spin it turned by."""
        cols = world.columns(Transform)
        if self._changed or not self._same_entities(cols):
            self._changed = True
            return
        self._pos.append(cols.position)
        self._quat.append(cols.orientation)
        w = np.full((len(self._entities), 3), np.nan)  # NaN: no AngularVelocity, slerp instead
        spin = world.columns(AngularVelocity)
        if len(spin.entities):
            k = np.searchsorted(self._entities, spin.entities)   # both ascending
            ok = k < len(self._entities)
            ok[ok] &= self._entities[k[ok]] == spin.entities[ok]
            w[k[ok]] = spin.angular[ok]
        self._spin.append(w)

    def pose(self, world, s) -> None:
        """Put every body where it was at fraction ``s`` (0 < s <= 1) of the frame's interval."""
        steps = len(self._spin)
        if self._changed or steps == 0:
            return
        x = Fraction(s) * steps
        i = min(int(x), steps - 1)
        a = float(x - i)
        if a >= 1.0:                                    # the end of the frame: the stepped state itself
            self.restore(world)
            return
        p0, p1 = self._pos[i], self._pos[i + 1]
        q0, q1 = self._quat[i], self._quat[i + 1]
        pos = p0 + a * (p1 - p0)
        quat = fr.slerp(q0, q1, a) if len(q0) else q0
        w = self._spin[i]
        spinning = ~np.isnan(w[:, 0])
        if spinning.any():
            dq = fr.quat_from_rotvec(w[spinning] * (a * self._dt))
            q = fr.quat_multiply(dq, q0[spinning])
            quat[spinning] = q / np.linalg.norm(q, axis=1, keepdims=True)
        self._write(world, pos, quat)

    def restore(self, world) -> None:
        """Put back the state the last step left (the exact bits)."""
        if not self._changed and len(self._spin):
            self._write(world, self._pos[-1], self._quat[-1])

    def _write(self, world, pos: np.ndarray, quat: np.ndarray) -> None:
        cols = world.columns(Transform)
        if self._same_entities(cols):
            cols.position = pos
            cols.orientation = quat
