"""Gravity data: wells that attract, the n-body opt-in, and what a surface contact reports.

A scene has gravity only where it asks for it: an entity with a
:class:`GravityWell` (and a :class:`~components.body.Transform`: the well's
centre) pulls every body with a ``Transform`` and ``Velocity``. Without a
well nothing about gravity runs.

Units and frames: positions and velocities in the world frame, m and m/s;
``mu = G M`` in m^3/s^2 (``G`` = :data:`G`, CODATA 2018); radii in m; times
in s. The world frame is inertial; a well with no ``parent`` is fixed in it
(or moves at its own constant ``Velocity``), a well with a ``parent`` (a
moon) follows its own exact two-body orbit about the parent from the state
it is created with.

Few wells per scene: these are plain dataclasses, read in a Python loop.
"""
from __future__ import annotations

from dataclasses import dataclass

from driftframe.framework import validate

#: Newton's constant of gravitation, m^3 kg^-1 s^-2 (CODATA 2018).
G = 6.67430e-11


@dataclass
class GravityWell:
    """A point mass that attracts: give ``mu`` (m^3/s^2) or ``mass`` (kg), not both.

    ``radius``: the surface sphere, m (> 0): bodies hit it (an elastic contact
    with the surface, reported as a :class:`SurfaceContact`), and no body may
    start inside it. ``parent``: the entity id of the well this one orbits
    (a moon about its planet), or None for a well fixed in the world frame.
    ``soi``: radius of the sphere of influence, m, inside which a body moves
    about this well rather than its parent (patched conics); None takes
    Laplace's ``a (m/M)^(2/5)`` from the orbit about the parent (a root well's
    sphere is infinite).
    """

    #: Gravitational parameter G M, m^3/s^2 (> 0, finite).
    mu: float | None = None
    #: Surface radius, m (> 0).
    radius: float = 1.0
    #: Mass, kg (alternative to mu: mu = G * mass).
    mass: float | None = None
    #: Entity id of the well this one orbits; None = fixed in the world frame.
    parent: int | None = None
    #: Sphere of influence radius, m; None = Laplace's, from the orbit about the parent.
    soi: float | None = None

    def __post_init__(self):
        if (self.mu is None) == (self.mass is None):
            raise ValueError(f"GravityWell: give exactly one of mu (m^3/s^2) or mass (kg), "
                             f"got mu={validate.shown(self.mu)}, mass={validate.shown(self.mass)}")
        if self.mass is not None:
            self.mass = validate.scalar("GravityWell.mass", self.mass, positive=True)
            self.mu = G * self.mass
        else:
            self.mu = validate.scalar("GravityWell.mu", self.mu, positive=True)
            self.mass = self.mu / G
        self.radius = validate.scalar("GravityWell.radius", self.radius, positive=True)
        self.parent = validate.entity_id("GravityWell.parent", self.parent, optional=True)
        if self.soi is not None:
            self.soi = validate.scalar("GravityWell.soi", self.soi, positive=True, allow_inf=True)
            if not self.soi > self.radius:
                raise ValueError(f"GravityWell.soi must be larger than its radius {validate.shown(self.radius)} m, "
                                 f"got {validate.shown(self.soi)}")


class NBody:
    """Marker: this body's :class:`~components.body.Mass` attracts the other ``NBody`` bodies,
    and it is integrated by the symplectic kick-drift-kick scheme in the pull of every well
    and of those bodies, instead of on rails about one well. Opt-in: pairwise forces cost
    O(n^2) per step."""


class Orbiting:
    """Marker the gravity system puts on every body it integrates (added by the system, not by
    users): the movement system leaves such bodies alone, so nothing is moved twice."""


@dataclass(frozen=True)
class SurfaceContact:
    """A body touched a well's surface sphere (appended to ``world.events``).

    ``time``: s since the world's start, exact on the body's conic (not the
    step's end). ``speed``: m/s, the body's speed relative to the well at
    contact; ``normal_speed`` its radial part. The contact is elastic: the
    radial velocity relative to the well is reversed, energy kept.
    """

    entity: int
    well: int
    time: float
    speed: float
    normal_speed: float

