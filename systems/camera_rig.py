"""Camera rigs: where a cockpit, chase, overhead or frame camera puts its eye, the view / projection matrices drawn
from it, and switching a camera's mode.

The functions the camera system (:mod:`systems.camera`), the render system, the HUD and keyboard input
share: a module of functions, not a system, so no system imports another.

Matrix conventions (shared with :mod:`systems.render` and a HUD):

* :func:`view_matrix` maps world points to OpenGL eye space: x right, y up,
  the camera looking down -z. With driftframe's body frame (+z forward) that
  is ``E = diag(1, 1, -1) R^T`` and ``view = [E | -E c]`` for an eye at
  ``c`` with rotation ``R``. (The flip makes outward, counter-clockwise
  triangles appear clockwise on screen: the renderer culls with
  ``front_face = "cw"``.)
* :func:`perspective` is the classic ``gluPerspective`` matrix (vertical fov,
  aspect = width / height, depth -1..1 between near and far).
* :func:`world_to_pixels` projects world points to pixel coordinates, x from
  the left edge, y from the *top* edge, as in :meth:`RenderTarget.read_rgba`.

Run-time switch: :func:`switch_camera` (``world``, ``mode=None`` steps
through the camera's ``cycle``, cockpit <-> chase by default) is what
keyboard input and scripted input call.
"""
from __future__ import annotations

import math

import esper
import numpy as np

from driftframe.components.body import Transform, Velocity
from driftframe.components.camera import Camera, check_mode
from driftframe.framework import frame as fr
from driftframe.framework.frame import slerp  # the one slerp (and systems.camera_rig.slerp, as before)
from driftframe.framework import validate

_FLIP_Z = np.diag([1.0, 1.0, -1.0])


# -- matrices -------------------------------------------------------------------------
def view_rotation(orientation) -> np.ndarray:
    """3x3 world -> eye rotation (eye: x right, y up, looking down -z): ``diag(1, 1, -1) R^T``."""
    return _FLIP_Z @ fr.quat_to_matrix(np.asarray(orientation, dtype=np.float64)).T


def view_matrix(position, orientation) -> np.ndarray:
    """4x4 world -> eye matrix of an eye at ``position`` (m) with frame ``orientation`` (quaternion)."""
    e = view_rotation(orientation)
    m = np.eye(4)
    m[:3, :3] = e
    m[:3, 3] = -e @ np.asarray(position, dtype=np.float64)
    return m


def perspective(fov_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    """4x4 OpenGL projection: vertical field of view ``fov_deg``, ``aspect`` = width / height.

    ``f = 1 / tan(fov/2)``; eye ``(x, y, z)`` goes to clip
    ``(f x / aspect, f y, (far + near) z / (near - far) + 2 far near / (near - far), -z)``.
    """
    f = 1.0 / math.tan(math.radians(fov_deg) / 2.0)
    p = np.zeros((4, 4))
    p[0, 0] = f / aspect
    p[1, 1] = f
    p[2, 2] = (far + near) / (near - far)
    p[2, 3] = 2.0 * far * near / (near - far)
    p[3, 2] = -1.0
    return p


def world_to_pixels(points, view_projection, size) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates ``(N, 2)`` (x from the left, y from the top) and an in-front mask ``(N,)``.

    Pixel centres are at half-integers: the centre of the image is
    ``(W/2, H/2)``. Points behind the eye get ``in_front = False``.
    """
    p = np.atleast_2d(np.asarray(points, dtype=np.float64))
    clip = np.hstack([p, np.ones((len(p), 1))]) @ np.asarray(view_projection).T
    w = clip[:, 3]
    in_front = w > 0
    ndc = clip[:, :2] / np.where(in_front, w, 1.0)[:, None]
    width, height = size
    px = np.column_stack([(ndc[:, 0] + 1.0) * 0.5 * width, (1.0 - ndc[:, 1]) * 0.5 * height])
    return px, in_front


# -- the system -----------------------------------------------------------------------
def _target_transform(ent: int, cam: Camera) -> Transform | None:
    """The target's Transform, or None when the target is gone (deleted, or without a Transform)."""
    if cam.target == ent:
        raise ValueError(f"Camera on entity {ent} targets itself; give the entity id of the body to follow")
    if not esper.entity_exists(cam.target):
        return None
    return esper.try_component(cam.target, Transform)


def chase_direction(cam: Camera, q_target: np.ndarray, velocity) -> np.ndarray:
    """Unit viewing direction of a chase camera: the velocity's, or the nose's when nearly at rest."""
    if velocity is not None:
        v = np.asarray(velocity, dtype=np.float64)
        speed = float(np.linalg.norm(v))
        if speed > cam.rest_speed and speed > 0.0:
            return v / speed
    return fr.rotate(q_target, fr.FORWARD)


def overhead_rotation(up) -> np.ndarray:
    """Quaternion of an eye looking straight down (world -y) with ``up`` (made perpendicular) to the top."""
    return fr.look_rotation((0.0, -1.0, 0.0), (up[0], 0.0, up[2]))


def _frame_heading(cam: Camera, p_target, travel) -> np.ndarray:
    """Where a frame camera faces: from the target towards the first body of ``cam.frame`` that is there
    (an orbit: over the ship's shoulder onto its planet), else along ``travel``."""
    for ent, _ in cam.frame:
        tf = esper.try_component(ent, Transform) if esper.entity_exists(ent) else None
        if tf is not None:
            d = tf.position - p_target
            if np.hypot(d[0], d[2]) > 0.0:
                return d
            break
    return travel


def frame_rotation(travel, pitch_deg: float, fallback) -> np.ndarray:
    """Quaternion of a frame camera's eye: ``pitch_deg`` below the horizontal part of ``travel`` (across
    world y), its up as near +y as it can be; ``fallback``'s horizontal part where ``travel`` is vertical."""
    h = np.array([travel[0], 0.0, travel[2]])
    n = float(np.hypot(h[0], h[2]))
    if not n > 1e-9 * float(np.linalg.norm(travel)):
        h, n = np.array([fallback[0], 0.0, fallback[2]]), float(np.hypot(fallback[0], fallback[2]))
    p = math.radians(pitch_deg)
    # d = cos p h - sin p y; its up (the look rotation's, from +y) = sin p h + cos p y
    return fr.look_rotation(math.cos(p) * h / n - math.sin(p) * fr.UP, fr.UP)


#: A frame camera fits its bodies into this share of the field of view (a margin round the edges).
FRAME_FILL = 0.85


def framing_eye(q, cam: Camera, p_target, back: float | None = None) -> np.ndarray:
    """Eye position, with orientation ``q``, nearest the target with it and ``cam.frame``'s spheres in view.

    In the eye's axes (a across, b up, f forward) a sphere at (x, y, z) of radius r is inside the top and
    bottom planes through the eye at slope t = tan(FRAME_FILL fov / 2) when
    ``y - t z + r sec <= y_e - t z_e`` and ``y + t z - r sec >= y_e + t z_e`` (sec = sqrt(1 + t^2)):
    with T the largest left side and B the smallest, y_e = (T + B) / 2 and z_e = (B - T) / (2 t) is the
    nearest eye, and any eye further back along f still holds them. The same across (x) with the same
    slope; the eye takes the further of the two depths, and stands at least ``back`` (default
    ``chase_distance``; an overhead camera's ``overhead_height``) behind the target along f.
    """
    axes = fr.quat_to_matrix(np.asarray(q, dtype=np.float64))      # columns: a, b, f in world axes
    pts, radii = [np.asarray(p_target, dtype=np.float64)], [0.0]
    for ent, r in cam.frame:
        tf = esper.try_component(ent, Transform) if esper.entity_exists(ent) else None
        if tf is not None:
            pts.append(tf.position)
            radii.append(r)
    local = np.asarray(pts) @ axes                                    # (n, 3): x, y, z in the eye's axes
    rad = np.asarray(radii)
    t = FRAME_FILL * cam.tan_half_fov
    sec = math.sqrt(1.0 + t * t)
    eye = np.empty(3)
    depth = np.inf
    for k in (0, 1):
        u, z = local[:, k], local[:, 2]
        top = float(np.max(u - t * z + rad * sec))
        bottom = float(np.min(u + t * z - rad * sec))
        eye[k] = 0.5 * (top + bottom)
        depth = min(depth, (bottom - top) / (2.0 * t))
    eye[2] = min(depth, local[0, 2] - (cam.chase_distance if back is None else back))
    return axes @ eye


def update_camera(ent: int, cam: Camera, dt: float, *, snap: bool = False) -> Transform:
    """Move camera entity ``ent`` for one step of ``dt`` s; ``snap`` skips the smoothing.

    The esper world of the camera must be current. Adds a Transform to the
    camera entity the first time (snapped). Returns the camera's Transform.
    When the target is gone (in a game, targets die) the eye holds its last
    pose and ``cam.target_lost`` is set; a camera that never saw its target
    is a clear error.
    """
    check_mode(cam.mode)
    tt = _target_transform(ent, cam)
    tf = esper.try_component(ent, Transform)
    if tt is None:
        if tf is None:
            why = "has no Transform" if esper.entity_exists(cam.target) else "does not exist"
            raise ValueError(f"Camera on entity {ent}: target entity {cam.target} {why} (a camera without a "
                             "target); give the entity id of a body with a Transform")
        cam.target_lost = True
        return tf
    cam.target_lost = False
    if tf is None:
        tf = Transform()
        esper.add_component(ent, tf)
        snap = True
    tf.position, tf.orientation = eye_pose(cam, tt, tf.orientation, dt, snap=snap)
    return tf


def eye_pose(cam: Camera, target: Transform, q_prev, dt: float, *, snap: bool = False
             ) -> tuple[np.ndarray, np.ndarray]:
    """``(position, orientation)`` of a camera's eye on ``target`` (its Transform); writes nothing.

    ``q_prev``: the eye's orientation one step ago (the chase camera's smoothing starts
    from it); ``snap`` (or ``smoothing == 0``): the goal at once.
    """
    p_t = target.position
    q_t = target.orientation
    if cam.mode == "cockpit":
        return p_t + fr.rotate(q_t, np.asarray(cam.cockpit_offset)), q_t
    if cam.mode == "overhead":
        q = overhead_rotation(cam.overhead_up)
        if cam.frame:                   # over the target and its framed bodies, high enough to see them all
            return framing_eye(q, cam, p_t, back=cam.overhead_height), q
        return p_t + np.array([0.0, cam.overhead_height, 0.0]), q
    vel = esper.try_component(cam.target, Velocity)
    d = chase_direction(cam, q_t, None if vel is None else vel.linear)
    if cam.mode == "frame":
        q_goal = frame_rotation(_frame_heading(cam, p_t, d), cam.frame_pitch, cam.overhead_up)
    else:
        # the eye's up stays as close as possible to the target's up: it rolls with the ship
        q_goal = fr.look_rotation(d, fr.rotate(q_t, fr.UP))
    if snap or cam.smoothing == 0.0:
        q = q_goal
    else:
        # first-order lag with time constant tau: exact for any dt, so frame-rate independent
        alpha = 1.0 - math.exp(-dt / cam.smoothing)
        q = slerp(q_prev, q_goal, alpha)
    if cam.mode == "frame":
        return framing_eye(q, cam, p_t), q
    # behind (-forward) and above (+up) the target, in the eye's own smoothed frame
    return p_t + fr.rotate(q, np.array([0.0, cam.chase_height, -cam.chase_distance])), q


def placed_pose(ent: int, cam: Camera) -> tuple[np.ndarray, np.ndarray]:
    """The eye pose of camera entity ``ent`` as drawn now, writing nothing: its Transform once the camera
    system has placed it, else the snapped pose on its target (a camera made since the last step)."""
    tf = esper.try_component(ent, Transform)
    if tf is not None:
        return tf.position.copy(), tf.orientation.copy()
    tt = _target_transform(ent, cam)
    if tt is None:
        why = "has no Transform" if esper.entity_exists(cam.target) else "does not exist"
        raise ValueError(f"Camera on entity {ent}: target entity {cam.target} {why} (a camera without a "
                         "target); give the entity id of a body with a Transform")
    check_mode(cam.mode)
    return eye_pose(cam, tt, tt.orientation, 0.0, snap=True)


def update_cameras(world, *, snap: bool = True) -> None:
    """Place every camera now (snapped by default): before the first step, or after a switch."""
    world.activate()
    for ent, cam in list(esper.get_component(Camera)):
        update_camera(ent, cam, world.dt, snap=snap)


def active_camera(world) -> tuple[int, Camera]:
    """``(entity, Camera)`` of the first active camera (lowest entity id); a clear error if none."""
    world.activate()
    cams = sorted((e, c) for e, c in esper.get_component(Camera) if c.active)
    if not cams:
        raise LookupError("no active Camera in the world: add one, e.g. "
                          "world.create_entity(Camera(target=ship, mode='chase'))")
    return cams[0]


def switch_camera(world, mode: str | None = None, *, camera: int | None = None) -> str:
    """Switch a camera's mode at run time; returns the new mode.

    ``mode=None`` steps to the next mode in the camera's ``cycle`` (cockpit ->
    chase -> cockpit by default); a mode name (``"cockpit"``, ``"chase"``,
    ``"overhead"``) sets it. ``camera`` is the camera entity (default: the active
    one). The camera is placed for the new mode at once (no smoothing from the
    old view), so the next rendered frame already shows it.
    """
    world.activate()
    if camera is None:
        ent, cam = active_camera(world)
    else:
        ent = camera
        cam = esper.try_component(ent, Camera) if esper.entity_exists(ent) else None
        if cam is None:
            raise ValueError(f"switch_camera: entity {validate.shown(ent)} has no Camera")
    if mode is None:
        cycle = cam.cycle
        new = cycle[(cycle.index(cam.mode) + 1) % len(cycle)] if cam.mode in cycle else cycle[0]
    else:
        new = check_mode(mode)
    cam.mode = new
    update_camera(ent, cam, world.dt, snap=True)
    return new
