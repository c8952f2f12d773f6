"""Collision data: the sphere a body collides as, and what a contact reports.

``SphereCollider`` is hot (the collision system reads every radius each
step), so it is a :class:`~framework.store.Columnar` component like the body
state. ``CollisionEvent`` is not a component: it is the small, immutable
record the collision system appends to ``world.events`` for every contact it
resolves, so other systems and user code can react (sound, damage, score).

Mass comes from :class:`components.body.Mass` (``math.inf`` = immovable). A
collider on an entity with no ``Mass`` weighs 1 kg (``Mass``'s own default);
a collider on an entity with no ``Velocity`` is a fixed obstacle (infinite
mass, at rest).

``PlaneCollider`` and ``BoxCollider`` are static shapes (a table's cushions,
a floor, a wall): always immovable, whatever else the entity has. Spheres meet
them in the same time-ordered event loop as each other (exact time of impact
on the step's path, restitution the smaller of the two coefficients). A
sphere that starts inside a box or behind a plane is reported once and
resolved as overlapping spheres are (:mod:`driftframe.systems.static_step`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from driftframe.framework import validate
from driftframe.framework.store import Columnar, Field


def _positive_radius(name, r):
    r = np.asarray(r)
    validate.rows(name, r, ~(r > 0), "> 0")
    return r


def _unit_interval(name, e):
    e = np.asarray(e)
    validate.rows(name, e, ~((e >= 0) & (e <= 1)), "in [0, 1]")
    return e


class SphereCollider(Columnar):
    """The body collides as a sphere of ``radius`` about its centre of mass.

    ``restitution`` is the coefficient of restitution ``e`` in [0, 1]: the
    normal relative speed after a contact is ``e`` times the speed before.
    1.0 (the default) is perfectly elastic, 0.0 perfectly inelastic. A pair
    uses the smaller of its two coefficients (a ball of clay does not bounce
    off steel, and two balls of one material keep that material's ``e``).
    """

    __slots__ = ()

    #: Metres, finite and > 0.
    radius = Field((), "Sphere radius, m (> 0).", default=1.0, check=_positive_radius)
    #: Dimensionless, in [0, 1]; 1 = elastic.
    restitution = Field((), "Coefficient of restitution in [0, 1]; 1 = elastic.", default=1.0,
                        check=_unit_interval)


def _direction(name, n):
    n = np.asarray(n, dtype=np.float64)
    rows = n.reshape(-1, 3)
    bad = np.flatnonzero(~((rows * rows).sum(axis=1) > 0))
    if len(bad):
        where = f"[{int(bad[0])}]" if n.ndim > 1 else ""
        raise ValueError(f"{name}{where} must be a non-zero vector, got {rows[bad[0]].tolist()!r}")
    return n


def _positive_extents(name, h):
    h = np.asarray(h, dtype=np.float64)
    rows = h.reshape(-1, 3)
    bad = np.flatnonzero(~(rows > 0).all(axis=1))
    if len(bad):
        where = f"[{int(bad[0])}]" if h.ndim > 1 else ""
        raise ValueError(f"{name}{where} must be three numbers > 0 (half the sides, m), got {rows[bad[0]].tolist()!r}")
    return h


class PlaneCollider(Columnar):
    """A static half-space: the points ``p`` with ``normal . (p - position) <= offset`` are solid
    (``position``: the entity's Transform; ``normal``: in the entity's frame, rotated by its orientation;
    any length but zero, made unit). Spheres bounce off its face ``normal . (p - position) = offset``
    from the side ``normal`` points to. Immovable whatever the entity has (no mass, no velocity).

    Example (a floor at y = 0)::

        world.create_entity(Transform((0, 0, 0)), PlaneCollider(normal=(0, 1, 0)))
    """

    __slots__ = ()

    #: Entity frame, any length > 0 (made unit).
    normal = Field((3,), "Outward normal, entity frame (any length > 0; made unit).", default=(0.0, 1.0, 0.0),
                   check=_direction)
    #: Metres along the normal from the Transform's position.
    offset = Field((), "Face's distance from the Transform's position along the normal, m.", default=0.0)
    restitution = Field((), "Coefficient of restitution in [0, 1]; 1 = elastic.", default=1.0,
                        check=_unit_interval)


class BoxCollider(Columnar):
    """A static box: centre the entity's Transform position, axes its orientation's, half its sides
    ``half_extents`` (m, each > 0). Spheres bounce off its faces, edges and corners. Immovable whatever
    the entity has.

    Example (a cushion 28 m long, 0.4 m deep)::

        world.create_entity(Transform((0, 0, 7.7)), BoxCollider(half_extents=(14, 0.5, 0.2)))
    """

    __slots__ = ()

    #: Metres, each > 0, in the entity's frame.
    half_extents = Field((3,), "Half the box's sides along its x, y, z axes, m (each > 0).",
                         default=(0.5, 0.5, 0.5), check=_positive_extents)
    restitution = Field((), "Coefficient of restitution in [0, 1]; 1 = elastic.", default=1.0,
                        check=_unit_interval)


@dataclass(frozen=True, slots=True)
class CollisionEvent:
    """One resolved contact between entities ``a`` and ``b`` (``a < b``).

    ``time`` is absolute simulated time in seconds (``world.time`` at the
    start of the step plus ``step_time``, the offset inside the step,
    0 <= step_time <= dt). ``normal`` is the unit vector from ``a``'s centre
    to ``b``'s at contact (world frame); ``point`` the contact point on
    ``a``'s surface (world frame, m). ``impulse`` (N s, >= 0) is the size of
    the impulse along ``normal``: ``b`` received ``+impulse * normal`` and
    ``a`` ``-impulse * normal``, so ``b``'s velocity changed by
    ``impulse * normal / m_b``. With a static shape (:class:`PlaneCollider`, :class:`BoxCollider`) the
    normal is the shape's surface normal at the contact (pointing from ``a`` towards ``b``), ``point``
    where the sphere touches the shape, and the shape's velocity does not change (it is immovable).
    ``method`` names the method that resolved it;
    ``step`` is the index of the fixed step it happened in. The world keeps
    the events of every step since the last rendered frame (``world.events``)
    and calls subscribers at once (``world.subscribe(CollisionEvent, fn)``).
    """

    a: int
    b: int
    time: float
    step_time: float
    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    impulse: float
    method: str = "continuous"
    #: Index of the fixed step it happened in (``world.step_count`` during that step).
    step: int = -1
