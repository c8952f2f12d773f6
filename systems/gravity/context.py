"""The gravity system's step context: the step's times as given and the state every stage of the step reads.

As Box2D's ``b2StepContext`` carries ``dt`` and the solver's scratch through its
stages, :class:`GravityStep` carries one step of the gravity system from stage to
stage (crossings, rails, n-body, contacts), so that a stage's inputs are visible at
its call instead of living in attributes between calls. The records beside it name
what used to be tuples and dicts: a well's bodies at the step's end
(:class:`RailsEnd`), an n-body drift (:class:`Drift`), what the contact pass hands
back (:class:`PassResult`) and the pass's movers (:class:`Movers`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

#: The contact pass's kinds of mover (:attr:`Movers.kind`): a collider on rails about its well, an n-body
#: collider on its straight drift, an obstacle (a collider gravity does not move: straight, inverse mass 0).
RAILS, LINE, OBSTACLE = 0, 1, 2


class GravityStep(NamedTuple):
    """One step: its times exactly as the world gives them, the wells' and the bodies' states at its start,
    and the arrays its stages fill in (the fields are fixed; the arrays' contents are the step's). A named
    tuple, made once a step (why not a frozen dataclass: docs/design/gravity.md).

    ``dt`` is the step's length as given, used wherever the length of the step enters (a thrust's two half
    kicks ``a dt / 2``, the bounds over the step); it is never recomputed as ``t1 - t0``, which differs
    from ``dt`` by the rounding of two large times (``(k + 1) dt - k dt``: 3.7e-9 relative after 1e8
    steps). ``t0`` and ``t1`` are absolute times, ``step_count * dt`` and ``(step_count + 1) * dt``
    (never summed, so a time is the same number however it was reached); a time within the step is
    measured from ``t0``."""

    #: The step's start and end, s since the world's start.
    t0: float
    t1: float
    #: The step's length as given, s.
    dt: float
    #: The wells' centres (W, 3), m, and velocities (W, 3), m/s, world frame, at ``t0``.
    X0: np.ndarray
    V0: np.ndarray
    #: The wells' centres and velocities at ``t1``: a root well's moved straight at the start; a moon's
    #: filled in once its parent's bodies are placed.
    X1: np.ndarray
    V1: np.ndarray
    #: A bound on each well centre's acceleration over the step, m/s^2 (0 for a root well; filled in
    #: for a moon with its parent's bodies).
    wA: np.ndarray
    #: This system's bodies at ``t0`` (n, 3): positions (m), velocities (m/s), thrust accelerations (m/s^2).
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    #: (n,) bool: the body thrusts this step; someone else moved it since this system last wrote it.
    thrust: np.ndarray
    edited: np.ndarray
    #: The obstacles at ``t0`` (positions, velocities): the components, before the commit stage moves them.
    ob_x: np.ndarray
    ob_v: np.ndarray
    #: The bodies' states at ``t1`` (n, 3), filled in by the stages.
    x1: np.ndarray
    v1: np.ndarray
    #: The events of the step (SurfaceContact, CollisionEvent), in the order they are found.
    events: list


class RailsEnd(NamedTuple):
    """The bodies ``sel`` on rails about one well at the step's end, before any sphere contact: states about
    the well ``r`` (m), ``u`` (m/s), the universal anomalies ``chi`` and the guesses they were solved from."""

    sel: np.ndarray
    r: np.ndarray
    u: np.ndarray
    chi: np.ndarray
    guess: np.ndarray


class Drift(NamedTuple):
    """The n-body bodies' straight drift between their two kicks: ``p + u (t - t0)`` (world frame, m and
    m/s), ``since`` each body's last contact in the step (s from its start; -inf: none)."""

    p: np.ndarray
    u: np.ndarray
    since: np.ndarray


class PassResult(NamedTuple):
    """What the contact pass hands back: the bodies on rails given new epochs, the n-body drifts after
    their contacts, and whether the n-body colliders' surface contacts were met in it."""

    touched: np.ndarray
    drift: Drift | None
    surfaces_met: bool


@dataclass(eq=False)
class Movers:
    """The contact pass's movers, as columns (M rows). The path of each (what :meth:`ContactMovers._movers_at`
    evaluates) and, for the pass, its swept box over the step and the bounds that prune its pairs."""

    #: RAILS, LINE or OBSTACLE.
    kind: np.ndarray
    #: Index into the system's bodies (RAILS, LINE) or its obstacles (OBSTACLE).
    body: np.ndarray
    #: RAILS: the well it moves about; else -1.
    well: np.ndarray
    #: Collider radius, m.
    rad: np.ndarray
    #: LINE, OBSTACLE: the line's world position at the step's start (m) and its velocity (m/s); RAILS rows 0.
    lp: np.ndarray | None
    lu: np.ndarray | None
    #: The rails movers' slices, one ``(well, slice)`` per well (rails movers first, then lines).
    groups: list | None = None
    #: World boxes over the step (M, 3), m.
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None
    #: RAILS: the bound on the pull about the well (m/s^2) and on the distance from it (m); 0 on a line.
    A: np.ndarray | None = None
    rho: np.ndarray | None = None
    #: RAILS: the well centre's own acceleration bound (m/s^2), and whether the well is a root; 0 / False on a line.
    wA: np.ndarray | None = None
    root: np.ndarray | None = None
    #: RAILS: the states about the well at the span's ends (for the pruning) and whether the box is the
    #: cube the body can reach (it touches a surface or came into the well's sphere in the step).
    P0: np.ndarray | None = None
    P1: np.ndarray | None = None
    ball: np.ndarray | None = None
    #: LINE: the time of its last contact in the step (absolute s; -inf: none).
    after: np.ndarray | None = None
