"""What the gravity system knows of the orbits, as a typed resource: ``world.resources[OrbitState]``.

The flight aids (prograde is along the velocity relative to the well a ship moves
about), the warp governor (time warp drops before a predicted contact) and the orbit
readouts need what only the gravity system knows: which well a body moves about now,
and the next contacts on the bodies' conics. They read it here, never by importing
the gravity system (bevy's ``Res<T>``: a resource is a type, and reading it is part of
a system's declared access): the gravity system puts its :class:`OrbitState` into
``world.resources`` under this class when it is added to a world, and a system that
reads it lists ``OrbitState`` in its ``reads``. A world without a gravity system has
none: ``world.resources.get(OrbitState)`` is None, and there is no well to move about.

The answers are records with named fields (:class:`Reference`, :class:`SurfaceAhead`,
:class:`ContactAhead`), tuples still, so ``well, mu, radius, X, V = ref`` reads as before.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Reference(NamedTuple):
    """The well a body moves about now: its entity, ``mu`` (m^3/s^2), surface radius (m), and its centre's
    position (m) and velocity (m/s) in the world frame now. Prograde is along the body's velocity minus
    ``velocity``; the body's orbit is its state minus the centre's, about ``mu``."""

    well: int
    mu: float
    radius: float
    position: np.ndarray
    velocity: np.ndarray


class SurfaceAhead(NamedTuple):
    """The earliest predicted surface contact of a body on rails: absolute time (s, exact on its conic),
    the body and the well."""

    time: float
    entity: int
    well: int


class ContactAhead(NamedTuple):
    """The earliest predicted contact between two colliders: absolute time (s), the two entities (lower
    first), and whether ``time`` is only a lower bound (``bound``: an n-body body, whose path is not known
    beyond its step, *could* touch by then; the exact contact on the conics otherwise)."""

    time: float
    a: int
    b: int
    bound: bool = False


class OrbitState:
    """The orbits as the gravity system sees them (the interface; the gravity system publishes one).

    Every answer is about the world's state now: between two steps the end of the last one. Absolute
    times are seconds since the world's start (``step_count * dt``)."""

    #: Who makes it (for the error of ``world.resource(OrbitState)`` in a world without one).
    published_by = "the gravity system (driftframe.GravitySystem) publishes it when it is added to the world"
    #: A save does not hold it: the loaded world's gravity system publishes its own.
    saved = False

    def reference(self, entity: int) -> Reference | None:
        """The well ``entity`` moves about now (the deepest sphere of influence holding it, then the
        strongest pull), or None in a scene without wells or for a root well."""
        raise NotImplementedError

    def next_contact(self) -> SurfaceAhead | None:
        """The earliest predicted surface contact of a body on rails, or None."""
        raise NotImplementedError

    def next_sphere_contact(self, horizon: float) -> ContactAhead | None:
        """The earliest predicted contact between two colliders within ``horizon`` s of now, or None."""
        raise NotImplementedError
