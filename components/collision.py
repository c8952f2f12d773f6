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
    ``impulse * normal / m_b``. ``method`` names the method that resolved it;
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
