"""Hot body state: where a body is, how it is turned, how it moves and spins.

These are :class:`~framework.store.Columnar` components: each field is a view
into one row of a per-class numpy table, so systems process every body at
once while user code still reads and writes ``body.position`` per entity.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from driftframe.framework import frame as fr
from driftframe.framework import validate
from driftframe.framework.store import Columnar, Field

if TYPE_CHECKING:
    from numpy.typing import ArrayLike


def _unit_quat(name, q):
    return fr.check_unit_quat(name, q)


def _mass(name, m):
    m = np.asarray(m)
    validate.rows(name, m, ~(m > 0), "> 0 (use math.inf for an immovable body)")
    return m


class Transform(Columnar):
    """Position of the centre of mass and the body's orthonormal frame.

    Construct with ``position`` and either ``orientation`` (unit quaternion,
    x, y, z, w) or the frame vectors ``right``, ``up``, ``forward`` (world
    frame, orthonormal, right-handed). The frame is derived from the stored
    quaternion, so it stays orthonormal to rounding however long it spins.
    """

    __slots__ = ()

    #: Centre of mass, world frame, metres.
    position = Field((3,), "Centre of mass, world frame, m.")
    #: Orientation as a unit quaternion (x, y, z, w): local -> world rotation.
    orientation = Field((4,), "Unit quaternion (x, y, z, w), local -> world.",
                        default=fr.IDENTITY_QUAT, check=_unit_quat)

    def __init__(self, position: ArrayLike = (0.0, 0.0, 0.0), orientation: ArrayLike | None = None, *,
                 right: ArrayLike | None = None, up: ArrayLike | None = None, forward: ArrayLike | None = None) -> None:
        given = [v is not None for v in (right, up, forward)]
        if any(given):
            if not all(given):
                raise ValueError("Transform: give all three of right, up, forward (or an orientation), "
                                 f"got right={validate.shown(right)}, up={validate.shown(up)}, "
                                 f"forward={validate.shown(forward)}")
            if orientation is not None:
                raise ValueError("Transform: give either orientation or right/up/forward, not both")
            orientation = fr.frame_to_quat(right, up, forward, name="Transform frame")
        super().__init__(position=position,
                         orientation=fr.IDENTITY_QUAT if orientation is None else orientation)

    @property
    def rotation(self) -> np.ndarray:
        """3x3 rotation matrix, columns = right, up, forward (world frame). A copy."""
        return fr.quat_to_matrix(self.orientation)

    @rotation.setter
    def rotation(self, m: ArrayLike) -> None:
        m = validate.vector("Transform.rotation", m, (3, 3))
        self.orientation = fr.frame_to_quat(m[:, 0], m[:, 1], m[:, 2], name="Transform.rotation")

    @property
    def right(self) -> np.ndarray:
        """Local +x in world coordinates (unit)."""
        return fr.rotate(self.orientation, fr.RIGHT)

    @property
    def up(self) -> np.ndarray:
        """Local +y in world coordinates (unit)."""
        return fr.rotate(self.orientation, fr.UP)

    @property
    def forward(self) -> np.ndarray:
        """Local +z in world coordinates (unit): the nose."""
        return fr.rotate(self.orientation, fr.FORWARD)


class Velocity(Columnar):
    """Linear velocity of the centre of mass. Nothing slows it down."""

    __slots__ = ()
    #: World frame, m/s.
    linear = Field((3,), "Velocity of the centre of mass, world frame, m/s.")


class AngularVelocity(Columnar):
    """Spin as a world-frame vector: direction = axis (right-hand rule), length = rate."""

    __slots__ = ()
    #: World frame, rad/s.
    angular = Field((3,), "Angular velocity, world frame, rad/s (axis * rate).")


class Acceleration(Columnar):
    """Linear acceleration held constant over the next step (thrust): the movement
    system integrates it exactly, ``x += v dt + a dt^2/2``, ``v += a dt``."""

    __slots__ = ()
    #: World frame, m/s^2.
    linear = Field((3,), "Acceleration held over the step, world frame, m/s^2.")


class Mass(Columnar):
    """Mass in kg; ``math.inf`` makes a body immovable (it still moves at its own velocity)."""

    __slots__ = ()
    #: kg, > 0, may be +inf.
    kg = Field((), "Mass, kg; +inf for an immovable body.", default=1.0, allow_inf=True, check=_mass)

    @property
    def inverse(self) -> float:
        """1/kg, 0 for an immovable body."""
        return 0.0 if np.isinf(self.kg) else 1.0 / self.kg
