"""Exact rotation of body frames by their angular velocity."""
from __future__ import annotations

import esper
import numpy as np

from driftframe.components.body import AngularVelocity, Transform
from driftframe.framework.store import to_indices


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
    reads = (AngularVelocity,)
    writes = (Transform,)
    requires = (Transform, AngularVelocity)
    keeps_entities = True                 # (it adds and removes nothing: the world need not look after it)

    def __init__(self) -> None:
        self._scratch = np.empty((16, 0))    # work rows, reused every step (see _rotate)

    def process(self, dt: float) -> None:
        world = self.world
        c = world.query(Transform, AngularVelocity)
        c.refresh()
        if not len(c):
            return
        t_rows, w_rows = c.rows(Transform), c.rows(AngularVelocity)
        w = world.table(AngularVelocity).data["angular"][w_rows]
        spinning = (w[:, 0] != 0.0) | (w[:, 1] != 0.0) | (w[:, 2] != 0.0)
        if not spinning.any():
            return
        if not spinning.all():
            w = w[spinning]
            t_rows = to_indices(t_rows)[spinning]
        q_all = world.table(Transform).data["orientation"]
        q_all[t_rows] = self._rotate(q_all[t_rows], w, dt).T

    def _rotate(self, q: np.ndarray, w: np.ndarray, dt: float) -> np.ndarray:
        """``normalise(quat_from_rotvec(w dt) (x) q)`` for ``(n, 4)`` q and ``(n, 3)`` w, as rows ``(4, n)``.

        The same operations in the same order as ``framework.frame.quat_from_rotvec``,
        ``quat_multiply`` and ``q / |q|`` (so the same bits), done component by
        component on contiguous rows into scratch buffers kept between steps:
        several times faster than the (n, 4) array expressions, which spend their time
        allocating temporaries and striding across the quaternion's components
        (docs/design/costs.md).
        """
        n = len(q)
        if self._scratch.shape[1] < n:
            self._scratch = np.empty((16, max(n, 2 * self._scratch.shape[1])))
        b = self._scratch[:, :n]
        mul, add, sub = np.multiply, np.add, np.subtract
        tmp = b[15]
        # rotation vector r = w dt (rad); theta = |r| = sqrt((rx^2 + ry^2) + rz^2); half = theta / 2
        r = b[0:3]
        mul(w.T, dt, out=r)
        rx, ry, rz = r
        theta, half, k = b[3], b[4], b[5]
        mul(rx, rx, out=theta)
        mul(ry, ry, out=tmp)
        add(theta, tmp, out=theta)
        mul(rz, rz, out=tmp)
        add(theta, tmp, out=theta)
        np.sqrt(theta, out=theta)
        mul(theta, 0.5, out=half)
        # k = sin(theta/2) / theta; its series 1/2 - theta^2/48 below 1e-4 rad (no 0/0)
        small = theta < 1e-4
        if small.any():
            safe = np.where(small, 1.0, theta)
            k[:] = np.where(small, 0.5 - theta * theta / 48.0, np.sin(half) / safe)
        else:
            np.sin(half, out=k)
            np.divide(k, theta, out=k)
        # increment dq = (r k, cos(theta/2)) = (n sin(theta/2), cos(theta/2))
        a = b[6:10]
        mul(r, k, out=a[0:3])
        np.cos(half, out=a[3])
        ax, ay, az, aw = a
        qb = b[10:14]
        qb[...] = q.T
        bx, by, bz, bw = qb
        # Hamilton product dq (x) q, term by term as in quat_multiply (results overwrite rows 0-3)
        out = b[0:4]

        def term(dst, pairs, signs):
            mul(*pairs[0], out=dst)
            for (u, v), plus in zip(pairs[1:], signs):
                mul(u, v, out=tmp)
                (add if plus else sub)(dst, tmp, out=dst)

        term(out[0], ((aw, bx), (ax, bw), (ay, bz), (az, by)), (True, True, False))
        term(out[1], ((aw, by), (ax, bz), (ay, bw), (az, bx)), (False, True, True))
        term(out[2], ((aw, bz), (ax, by), (ay, bx), (az, bw)), (True, False, True))
        term(out[3], ((aw, bw), (ax, bx), (ay, by), (az, bz)), (False, False, False))
        # renormalise: |q| = sqrt(((x^2 + y^2) + z^2) + w^2), the order numpy's norm sums in
        norm = b[4]
        term(norm, tuple((c, c) for c in out), (True, True, True))
        np.sqrt(norm, out=norm)
        np.divide(out, norm, out=out)
        return out
