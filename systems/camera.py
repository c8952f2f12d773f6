"""The camera system: every fixed step (stage ``"camera"``, after collision) it places each camera's eye by
its mode, so the chase camera's smoothing is part of the deterministic simulation and is the same at any
frame rate: it never sees the rendered frame rate, only ``dt``, and its exponential smoothing
``alpha = 1 - exp(-dt/tau)`` composes exactly across steps (two steps of ``dt`` = one of ``2 dt``).

Where a mode puts the eye, the matrices and :func:`switch_camera` are :mod:`systems.camera_rig`'s
(re-exported here under their old names).
"""
from __future__ import annotations

import esper

from driftframe.components.body import Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.systems.camera_rig import (  # noqa: F401  (re-exported: the names this module always had)
    view_rotation,
    view_matrix,
    perspective,
    world_to_pixels,
    slerp,
    chase_direction,
    overhead_rotation,
    update_camera,
    eye_pose,
    frame_rotation,
    framing_eye,
    placed_pose,
    update_cameras,
    active_camera,
    switch_camera,
)


class CameraSystem(esper.Processor):
    """Reads Camera, the target's Transform and Velocity; writes the camera entity's Transform.

    cockpit: eye = target frame (plus ``cockpit_offset``). chase: viewing
    direction -> velocity direction (nose below ``rest_speed``), smoothed by
    ``q <- slerp(q, q_goal, 1 - exp(-dt / smoothing))``; eye at
    ``target + R_eye (0, chase_height, -chase_distance)``. overhead: eye at
    ``target + (0, overhead_height, 0)`` looking down -y, fixed orientation (with ``frame`` bodies: over
    them all, as high as it must be to see them). frame: looking ``frame_pitch`` below the horizontal from
    over the target towards its first framed body, smoothed as chase, as near as it can be with the target
    and every framed sphere in view (:func:`systems.camera_rig.framing_eye`). A handful of
    cameras: a per-camera loop.
    """

    stage = "camera"
    reads = (Camera, Transform, Velocity)
    writes = (Transform, Camera)

    def process(self, dt: float) -> None:
        for ent, cam in list(esper.get_component(Camera)):
            update_camera(ent, cam, dt)
