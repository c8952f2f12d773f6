"""Camera settings (cold data): which body a camera follows, how, and its lens.

The camera entity carries a ``Camera`` and, once the camera system has run,
its own ``Transform`` (the eye: position and frame, +z = viewing direction).
The render system draws from the first *active* camera (lowest entity id).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from driftframe.framework import validate

#: "cockpit": the target's own frame. "chase": behind and above, looking along the velocity.
#: "overhead": straight down on the target from above, fixed in world orientation (table tops, maps).
#: "frame": down at an angle onto the x-z plane, over the target towards its first framed body, far enough back that the
#: target and the bodies of ``Camera.frame`` are all in the picture (an orbit: the planet, ship and station).
MODES = ("cockpit", "chase", "overhead", "frame")


@dataclass
class Camera:
    """A cockpit, chase or overhead camera on a target body.

    ``target``: entity id of the followed body; it must have a Transform (a
    Velocity, when present, steers the chase camera).

    * ``cockpit``: the eye takes the target's frame exactly, at
      ``cockpit_offset`` (local axes, m) from its centre of mass. The target's
      own model is not drawn (the eye is inside it).
    * ``chase``: the eye looks along the target's direction of *travel*
      (its velocity) when faster than ``rest_speed``, along its nose
      otherwise, and sits ``chase_distance`` m behind and ``chase_height`` m
      above the target in its own (smoothed) frame. The viewing direction
      follows with time constant ``smoothing`` s (0 = no lag), so it does not
      jitter and is the same at any frame rate.

    * ``overhead``: the eye sits ``overhead_height`` m above the target along
      world +y and looks straight down (-y); the top of the picture points
      along ``overhead_up`` (world frame, made perpendicular to y). It follows
      the target's position, never its rotation: a plan view. With bodies in ``frame`` it stands over
      them and the target together, as high as it must to see them all (never under
      ``overhead_height`` above the target): the fit of the frame mode, looking straight down.

    * ``frame``: the eye looks ``frame_pitch`` degrees below the horizontal (across world y: the scene's
      x-z plane), facing from the target towards the first body of ``frame`` (an orbit: over the ship's
      shoulder onto its planet; without one, along the target's travel as the chase camera takes it, or
      ``overhead_up`` where that is vertical), its up as near world +y as it can be, smoothed as the chase
      camera is; it stands as close as it can with the target and
      every ``(entity, radius)`` of ``frame`` inside the picture (each body a sphere of that radius, m; one
      that is gone is left out), and never nearer the target than ``chase_distance``. The fit uses the
      vertical field of view across the width too (a picture wider than tall shows them all).

    ``cycle``: the modes :func:`systems.camera.switch_camera` steps through
    for this camera (a camera whose mode is not in it goes to the first).
    ``fov``: vertical field of view, degrees; ``near``/``far``: clip planes, m.
    The aspect ratio comes from the render target's size.
    """

    target: int | None = None
    mode: str = "chase"
    #: Vertical field of view, degrees, in (0, 180).
    fov: float = 60.0
    #: Near and far clip distances, m (0 < near < far).
    near: float = 0.1
    far: float = 5000.0
    #: Chase: distance behind the target along the viewing direction, m.
    chase_distance: float = 10.0
    #: Chase: height above the target along the camera's up, m.
    chase_height: float = 2.5
    #: Chase: time constant of the direction smoothing, s (0 = follow exactly).
    smoothing: float = 0.25
    #: Chase: below this speed (m/s) look along the nose, not the velocity.
    rest_speed: float = 0.5
    #: Cockpit: eye position in the target's local axes, m.
    cockpit_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: Overhead: height of the eye above the target along world +y, m (> 0).
    overhead_height: float = 20.0
    #: Overhead: the world direction that points to the top of the picture (not along y).
    overhead_up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    #: Frame (and overhead): the other bodies kept in the picture with the target, ``(entity id, radius in m)``
    #: pairs.
    frame: tuple[tuple[int, float], ...] = ()
    #: Frame: how far below the direction of travel the eye looks, degrees in (0, 90] (90: a plan view).
    frame_pitch: float = 55.0
    #: Modes a switch steps through, in order.
    cycle: tuple[str, ...] = ("cockpit", "chase")
    #: The render system draws from the first active camera.
    active: bool = True
    #: Set by the camera system while the target entity is gone (deleted, or lost its Transform):
    #: the eye holds its last pose, and the HUD says so. Cleared when the target is back.
    target_lost: bool = False

    #: A camera is presentation, not simulation: ``World.state_hash`` leaves its entity out.
    presentation: ClassVar[bool] = True

    def __post_init__(self):
        if self.target is None:
            raise ValueError("Camera.target is None: a camera without a target; give the entity id of the "
                             "body to follow (it needs a Transform)")
        self.target = validate.entity_id("Camera.target", self.target)
        check_mode(self.mode)
        self.fov = validate.scalar("Camera.fov", self.fov, lo=1e-3, hi=179.0)
        self.near = validate.scalar("Camera.near", self.near, positive=True)
        self.far = validate.scalar("Camera.far", self.far, positive=True)
        if not self.far > self.near:
            raise ValueError(f"Camera.far must be > Camera.near, got near={validate.shown(self.near)},"
                             f" far={validate.shown(self.far)}")
        self.chase_distance = validate.scalar("Camera.chase_distance", self.chase_distance, nonnegative=True)
        self.chase_height = validate.scalar("Camera.chase_height", self.chase_height)
        self.smoothing = validate.scalar("Camera.smoothing", self.smoothing, nonnegative=True)
        self.rest_speed = validate.scalar("Camera.rest_speed", self.rest_speed, nonnegative=True)
        self.cockpit_offset = tuple(validate.vector("Camera.cockpit_offset", self.cockpit_offset).tolist())
        self.overhead_height = validate.scalar("Camera.overhead_height", self.overhead_height, positive=True)
        up = validate.vector("Camera.overhead_up", self.overhead_up)
        if not np.hypot(up[0], up[2]) > 1e-6 * max(np.linalg.norm(up), 1e-300):
            raise ValueError(f"Camera.overhead_up must have a part across world y (the overhead view looks "
                             f"along -y), got {up.tolist()}")
        self.overhead_up = tuple(up.tolist())
        self.frame = _framed(self.frame)
        self.frame_pitch = validate.scalar("Camera.frame_pitch", self.frame_pitch, positive=True, lo=0.0, hi=90.0)
        cycle = (self.cycle,) if isinstance(self.cycle, str) else tuple(self.cycle)
        if not cycle:
            raise ValueError("Camera.cycle must name at least one mode")
        bad = [m for m in cycle if m not in MODES]
        if bad:
            raise ValueError(f"Camera.cycle: modes must be among {MODES}, got {validate.shown(bad[0])} "
                             f"in {validate.shown(cycle)}")
        self.cycle = cycle
        self.active = bool(self.active)
        self.target_lost = bool(self.target_lost)

    @property
    def tan_half_fov(self) -> float:
        """tan(fov / 2): half the view's height at 1 m distance."""
        return math.tan(math.radians(self.fov) / 2.0)


def _framed(frame) -> tuple[tuple[int, float], ...]:
    """``Camera.frame`` checked: (entity id, radius >= 0) pairs."""
    try:
        pairs = [tuple(p) for p in frame]
    except TypeError:
        pairs = None
    if pairs is None or any(len(p) != 2 for p in pairs):
        raise ValueError(f"Camera.frame must be (entity id, radius in m) pairs, got {validate.shown(frame)}")
    return tuple((validate.entity_id(f"Camera.frame[{k}] entity", e),
                  validate.scalar(f"Camera.frame[{k}] radius", r, nonnegative=True))
                 for k, (e, r) in enumerate(pairs))


def check_mode(mode) -> str:
    return validate.choice("Camera.mode", mode, MODES)
