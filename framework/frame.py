"""Rotation math for body frames, vectorised over many bodies.

Conventions (used everywhere in driftframe):

* A body's frame is three orthonormal world vectors: ``right``, ``up``,
  ``forward`` = the images of local +x, +y, +z. ``right x up = forward``
  (right-handed). The rotation matrix ``R`` has them as its *columns*, so
  ``world = R @ local``.
* Local rotations follow the right-hand rule: roll about ``forward``, pitch
  about ``right``, yaw about ``up``. Positive yaw turns the nose towards
  ``right``; positive pitch turns it towards ``-up`` (nose down); positive
  roll turns ``right`` towards ``up``... see :data:`LOCAL_AXES`.
* Orientation is stored as a unit quaternion ``q = (x, y, z, w)``, scalar last
  (the order SciPy uses). ``benchmarks/spin_accuracy.py`` chose it: the exact
  exponential-map update costs about what a matrix update costs, and keeping
  ``|q| = 1`` by renormalising keeps the derived frame orthonormal to a few
  ulps *for any number of steps*, where a stored matrix drifts.

Exact rotation by an angular velocity ``w`` (world frame, rad/s) over ``dt``:
``theta = |w| dt``, axis ``n = w/|w|``, ``dq = (n sin(theta/2), cos(theta/2))``
and ``q' = dq (x) q`` (world-frame increment multiplies on the left).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from driftframe.framework import validate

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

#: Local axis of each control channel, in body coordinates.
RIGHT = np.array([1.0, 0.0, 0.0])
UP = np.array([0.0, 1.0, 0.0])
FORWARD = np.array([0.0, 0.0, 1.0])
#: roll about forward, pitch about right, yaw about up (the articles' names).
LOCAL_AXES = {"roll": FORWARD, "pitch": RIGHT, "yaw": UP}

IDENTITY_QUAT = np.array([0.0, 0.0, 0.0, 1.0])

#: Tolerance for accepting a user-given frame as orthonormal.
ORTHONORMAL_TOL = 1e-9


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a (x) b`` of quaternions ``(..., 4)``, scalar last."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ], axis=-1)


def quat_from_rotvec(rotvec: np.ndarray) -> np.ndarray:
    """Exponential map: rotation vector ``theta * n`` (rad) -> unit quaternion, exact for any angle."""
    rotvec = np.asarray(rotvec, dtype=np.float64)
    theta = np.linalg.norm(rotvec, axis=-1, keepdims=True)
    half = 0.5 * theta
    # sin(theta/2)/theta without dividing by zero: its series 1/2 - theta^2/48 below 1e-4 rad.
    small = theta < 1e-4
    safe = np.where(small, 1.0, theta)
    k = np.where(small, 0.5 - theta * theta / 48.0, np.sin(half) / safe)
    return np.concatenate([rotvec * k, np.cos(half)], axis=-1)


def quat_from_axis_angle(axis, angle) -> np.ndarray:
    """Unit quaternion rotating by ``angle`` rad about ``axis`` (any non-zero length; right-hand rule)."""
    from driftframe.framework import validate

    a = validate.vector("axis", axis)
    angle = validate.scalar("angle", angle)
    n = float(np.linalg.norm(a))
    if not n > 0:
        raise ValueError(f"axis must have non-zero length, got {a.tolist()}")
    return quat_from_rotvec(a / n * angle)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` -> rotation matrices ``(..., 3, 3)`` (columns right, up, forward)."""
    x, y, z, w = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    m = np.empty(np.shape(x) + (3, 3))
    m[..., 0, 0] = 1 - 2 * (yy + zz)
    m[..., 0, 1] = 2 * (xy - wz)
    m[..., 0, 2] = 2 * (xz + wy)
    m[..., 1, 0] = 2 * (xy + wz)
    m[..., 1, 1] = 1 - 2 * (xx + zz)
    m[..., 1, 2] = 2 * (yz - wx)
    m[..., 2, 0] = 2 * (xz - wy)
    m[..., 2, 1] = 2 * (yz + wx)
    m[..., 2, 2] = 1 - 2 * (xx + yy)
    return m


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` -> unit quaternions (Shepperd's method, stable for all angles)."""
    m = np.asarray(m, dtype=np.float64)
    flat = m.reshape(-1, 3, 3)
    out = np.empty((len(flat), 4))
    tr = np.trace(flat, axis1=1, axis2=2)
    diag = np.diagonal(flat, axis1=1, axis2=2)
    # pick the largest of (w, x, y, z) to divide by: avoids cancellation
    choice = np.argmax(np.column_stack([diag, tr]), axis=1)
    for i, mi in enumerate(flat):
        c = choice[i]
        if c == 3:
            s = 2.0 * np.sqrt(1.0 + tr[i])
            out[i] = [(mi[2, 1] - mi[1, 2]) / s, (mi[0, 2] - mi[2, 0]) / s, (mi[1, 0] - mi[0, 1]) / s, 0.25 * s]
        else:
            j, k = (c + 1) % 3, (c + 2) % 3
            s = 2.0 * np.sqrt(1.0 + mi[c, c] - mi[j, j] - mi[k, k])
            q = np.empty(4)
            q[c] = 0.25 * s
            q[j] = (mi[j, c] + mi[c, j]) / s
            q[k] = (mi[k, c] + mi[c, k]) / s
            q[3] = (mi[k, j] - mi[j, k]) / s
            out[i] = q
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return out.reshape(m.shape[:-2] + (4,))


def slerp(q0: np.ndarray, q1: np.ndarray, t: float) -> np.ndarray:
    """Spherical interpolation of unit quaternions (scalar last) from ``q0`` (t = 0) to ``q1`` (t = 1), row
    by row for ``(n, 4)`` arrays or for one ``(4,)`` pair; the one slerp of the project.

    Takes the shorter arc (``q`` and ``-q`` are the same rotation). Where the two are within 1e-6 rad
    (``sin`` of half the angle between them below 1e-6) it falls back to a normalised lerp, which is
    exact to rounding there (a wider fallback, a dot product above 0.9995, is off by up to ~1e-6 rad).
    """
    one = np.ndim(q0) == 1
    q0 = np.atleast_2d(np.asarray(q0, np.float64))
    q1 = np.atleast_2d(np.asarray(q1, np.float64))
    d = np.einsum("ij,ij->i", q0, q1)
    q1 = np.where((d < 0)[:, None], -q1, q1)
    d = np.abs(d)
    theta = np.arccos(np.minimum(d, 1.0))               # half the rotation angle between them
    s = np.sin(theta)
    small = s < 1e-6
    safe = np.where(small, 1.0, s)
    w0 = np.where(small, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(small, t, np.sin(t * theta) / safe)
    q = w0[:, None] * q0 + w1[:, None] * q1
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q[0] if one else q


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v (..., 3)`` by unit quaternions ``q (..., 4)``: ``v + 2 u x (u x v + w v)``."""
    u = q[..., :3]
    w = q[..., 3:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def axis_angle_matrix(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation matrices about unit ``axis (..., 3)`` by ``angle (...)`` rad."""
    axis = np.asarray(axis, dtype=np.float64)
    angle = np.asarray(angle, dtype=np.float64)[..., None, None]
    x, y, z = np.moveaxis(axis, -1, 0)
    zero = np.zeros_like(x)
    k = np.stack([np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1), np.stack([-y, x, zero], -1)], -2)
    eye = np.broadcast_to(np.eye(3), k.shape)
    return eye + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def orthonormality_error(m: np.ndarray) -> np.ndarray:
    """max |R^T R - I| per matrix: 0 for a perfect frame."""
    m = np.asarray(m)
    err = np.swapaxes(m, -1, -2) @ m - np.eye(3)
    return np.abs(err).max(axis=(-1, -2))


def frame_to_quat(right, up, forward, *, name: str = "frame") -> np.ndarray:
    """Validate a user-given frame (orthonormal, right-handed) and return its quaternion."""
    from driftframe.framework import validate

    r = validate.vector(f"{name}.right", right)
    u = validate.vector(f"{name}.up", up)
    f = validate.vector(f"{name}.forward", forward)
    m = np.column_stack([r, u, f])
    err = float(orthonormality_error(m))
    if err > ORTHONORMAL_TOL:
        raise ValueError(
            f"{name} is not orthonormal (max |R^T R - I| = {err:.3g} > {ORTHONORMAL_TOL:g}): "
            f"right={r.tolist()}, up={u.tolist()}, forward={f.tolist()}")
    if np.linalg.det(m) < 0:
        raise ValueError(f"{name} is left-handed (right x up = -forward): right={r.tolist()}, "
                         f"up={u.tolist()}, forward={f.tolist()}")
    return matrix_to_quat(m)


def check_unit_quat(name: str, q: np.ndarray) -> np.ndarray:
    """Reject quaternions whose length is not 1 (within 1e-9): they are not rotations."""
    q = np.asarray(q, dtype=np.float64)
    n = np.linalg.norm(q.reshape(-1, 4), axis=1)
    validate.rows(name, q, np.abs(n - 1.0) > ORTHONORMAL_TOL, "a unit quaternion (x, y, z, w)", row_ndim=1,
                  detail=lambda i: f" with length {float(n[i])!r}")
    return q


def look_rotation(forward: ArrayLike, up_hint: ArrayLike = (0.0, 1.0, 0.0)) -> np.ndarray:
    """Quaternion whose forward is ``forward`` and whose up is as close to ``up_hint`` as possible."""
    f = np.asarray(forward, dtype=np.float64)
    nf = np.linalg.norm(f)
    if not nf > 0 or not np.isfinite(nf):
        raise ValueError(f"look_rotation: forward must be a non-zero finite vector, got {f.tolist()}")
    f = f / nf
    hint = np.asarray(up_hint, dtype=np.float64)
    r = np.cross(hint, f)
    if np.linalg.norm(r) < 1e-9:  # forward parallel to the hint: pick any perpendicular
        r = np.cross(np.array([1.0, 0.0, 0.0]) if abs(f[0]) < 0.9 else np.array([0.0, 0.0, 1.0]), f)
    r /= np.linalg.norm(r)
    u = np.cross(f, r)
    return matrix_to_quat(np.column_stack([r, u, f]))
