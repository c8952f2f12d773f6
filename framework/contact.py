"""Sphere contact kernels: times of impact, islands of simultaneous contacts, the step's event loop.

Pure functions over arrays, compiled with numba and cached (only the first
run on a machine pays the compilation; docs/bench/compile.md measures it).
The collision system (:mod:`driftframe.systems.collision`) gathers the
bodies' start-of-step state, calls a solver (:func:`solve_all_pairs`,
:func:`solve_listed`) once per step and writes the result back; nothing
here knows about entities or components.

**Paths.** Body ``k`` moves as ``p(t) = x[k] + u[k] t`` for ``0 <= t <= dt``.
An impulse at time ``t`` changes ``u`` and moves the path's origin by
``-du t``, so the body stays where it is at ``t``.

**Time of impact** of a pair: the smaller root of ``|d + w t|^2 = R^2`` (``d``
relative position, ``w`` relative velocity, ``R = r_i + r_j``), written
``t = c / (-b + sqrt(b^2 - a c))`` with ``a = w.w``, ``b = d.w``, ``c =
d.d - R^2`` so that nothing cancels, and solved once more from where the pair
is at that estimate when it starts more than ``4 R`` apart (``c`` loses
digits there). A pair counts only when it approaches, ``v_n < -APPROACH
(|u_i| + |u_j|)`` -- a threshold from the pair's *own* speeds -- and when the
exact paths meet (``c <= 0``, or a real root): a near miss is never a
contact, whatever the tolerances. Pairs that already overlap (at spawn) and
approach are in contact now; those that overlap and separate are left to
separate (no stick, no jump).

**Waves and islands.** Contacts are taken in time order from a binary heap
(one entry per pair and version; a pair's entry is void once either body's
velocity changes). At the earliest instant ``t*`` every pending pair whose
contact lies within ``TOUCH R / |v_n|`` of ``t*`` (its gap is below
``TOUCH R`` there) and that still approaches forms one *wave*. The wave is
split into *islands* (connected components over movable bodies; an
immovable body joins nothing) and each island is solved on its own:
impulses ``lambda >= 0`` with

    A lambda = -(1 + e) v_n,   A = J M^-1 J^T   (the island's contacts only)

by Gaussian elimination with symmetric (diagonal) pivoting in a fixed order,
dropping contacts whose impulse comes out negative and solving again (at
most ``K`` times). Only ``+ - * / sqrt`` are used, in a fixed order, so a
step's result is the same bit for bit on any CPU (no LAPACK, no transcendental
ufunc). Islands of more than :data:`DENSE_MAX` contacts (a crystal or a pile
hit at once) are resolved contact by contact in pair order (packed index
order: ascending entity id), each a textbook two-body impulse, which keeps
the energy of elastic contacts exactly and costs ``O(K)``. With ``e = 1``
each contact reverses its normal velocity and the energy is unchanged:
``dKE = lambda . (v_n + v_n') / 2 = 0``. The bodies that changed have their
pairs re-examined from ``t*``; contacts that now approach at ``t*`` form the
next wave, so a chain of touching balls (Newton's cradle) passes the impulse
ball by ball inside one instant, and a symmetric hit stays symmetric.

**Bounds.** Each body keeps, within the step, the time of its last contact
and a *burst*: how many waves in a row it met within ``t_c`` of the previous
one.

* *Inelastic collapse* (Luding & McNamara's TC model, Granular Matter 1,
  1998): hard spheres with ``e < 1`` can meet infinitely often in finite
  time. A contact of a body whose previous contact was less than ``t_c``
  earlier is taken as elastic (``e = 1``). Energy is never gained; it is lost
  only by contacts the model keeps inelastic.
* *Jams*: a sphere wedged between immovable ones has no elastic answer and
  bounces forever in no time. Once a body's burst exceeds :data:`JAM` waves,
  its contacts are taken with ``e = 0`` for the rest of that burst (the
  motion along the walls is kept); past ``2 JAM`` the island's touching
  cluster is given one velocity (its centre of mass's, or that of an
  immovable body it touches), so every relative velocity in it is zero,
  which ends any burst.
* *Inelastic contacts per body per step* (pairs with ``e < 1``) are capped
  the same way: past ``cap`` a body's contacts are taken with ``e = 0``,
  past ``2 cap`` its touching cluster moves as one. A clump of inelastic
  spheres comes to rest as a clump instead of chattering. Elastic pairs are
  never capped (only bursts bound them), so no energy that should be kept is
  lost.

So the work of a step is bounded by the bodies involved times these
constants: it grows with the island, not with the scene.


The solver's ``flags`` say which of these engaged (for a warning).

**Modules.** :mod:`.contact_params` (tolerances, bounds, flag bits, the stats
layout), :mod:`.contact_toi` (a pair's time of impact), :mod:`.contact_heap`
(the heap of pending contacts), :mod:`.contact_islands` (a wave's
restitution, islands and impulses), :mod:`.contact_jam` (the jam path),
:mod:`.contact_pairs` (the candidate pairs, all of them or the neighbour
list's), :mod:`.contact_again` (running a step again from its inputs),
:mod:`.contact_solve` (the event loop and the four solvers compiled from it),
:mod:`.contact_bodies` (gathering the colliders' state), :mod:`.static_shapes` (a sphere against a
static plane or box: time of impact and normal) and :mod:`driftframe.systems.static_step` (a step with such shapes: they
join the event loop as the last bodies, immovable, in :func:`~.contact_solve.solve_static`, a variant
compiled only for scenes that have them). This module names
a step's inputs and outputs (:class:`StepInputs`, :class:`StepResult`,
:class:`StepStats`) and runs one (:func:`solve_step`).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from driftframe.framework.contact_bodies import gather_bodies
from driftframe.framework.contact_islands import solve_psd
from driftframe.framework.contact_pairs import all_pairs
from driftframe.framework.contact_params import (APPROACH, CAP, CENTRED, DENSE_MAX, F_AGAIN, F_CAP, F_JAM, F_LIMIT,
                                                 F_REBUILD, F_STICK, F_TC, JAM, N_STATS, S_BACK, S_CONTACTS,
                                                 S_OVERLAPS, S_PAIRS, S_POPPED, S_PUSHED, S_SEQUENTIAL, S_SWEPT,
                                                 S_WAVES, S_WORST, S_WORST_I, S_WORST_J, SLACK_MAX, TC, TOUCH,
                                                 ListedArrays)
from driftframe.framework.contact_solve import solve_all_pairs, solve_all_pairs_stick, solve_listed, solve_listed_stick
from driftframe.framework.contact_toi import toi

__all__ = ["APPROACH", "CAP", "CENTRED", "DENSE_MAX", "F_AGAIN", "F_CAP", "F_JAM", "F_LIMIT", "F_REBUILD", "F_STICK",
           "F_TC", "JAM", "N_STATS", "S_BACK", "S_CONTACTS", "S_OVERLAPS", "S_PAIRS", "S_POPPED", "S_PUSHED",
           "S_SEQUENTIAL", "S_SWEPT", "S_WAVES", "S_WORST", "S_WORST_I", "S_WORST_J", "SLACK_MAX", "TC", "TOUCH",
           "ListedArrays", "StepInputs", "StepResult", "StepStats", "all_pairs", "gather_bodies", "solve_all_pairs",
           "solve_all_pairs_stick", "solve_listed", "solve_listed_stick", "solve_psd", "solve_step", "solvers",
           "toi"]


class StepInputs(NamedTuple):
    """A step's inputs, in the solvers' order (:func:`~.contact_solve.solve_listed` says each in full)."""

    #: (n, 3) start positions and mean velocities (m, m/s): the paths ``x + u t``; changed in place
    x: np.ndarray
    u: np.ndarray
    #: (n,) radius (m), inverse mass (1/kg, 0 = immovable), restitution, taking part (False: left out)
    r: np.ndarray
    inv: np.ndarray
    e: np.ndarray
    live: np.ndarray
    #: (n,) each body's last contact, absolute seconds (-inf: none); updated in place
    t_last: np.ndarray
    #: the step's start, s
    now: float
    #: candidate pairs i < j (every pair, or the neighbour list's)
    pi: np.ndarray
    pj: np.ndarray
    #: the step, the TC model's t_c (s), and the cap on one body's inelastic contacts in a step
    dt: float
    t_c: float
    cap: int
    #: the neighbour list's arrays, or None: every pair in ``pi``, ``pj`` is a candidate
    lst: ListedArrays | None


class StepStats(NamedTuple):
    """What a step did (the solvers' stats array, field by field; counts are whole floats)."""

    pairs: float           #: candidate pairs
    contacts: float        #: contacts resolved (events)
    waves: float           #: waves (instants with contacts)
    swept: float           #: bodies swept (their paths tested against the list's territories)
    overlaps: float        #: pairs overlapping at the start
    worst_i: float         #: the deepest overlap's bodies i and j (-1: none)
    worst_j: float
    worst: float           #: its centres' distance / (r_i + r_j) (inf: none)
    sequential: float      #: islands solved contact by contact (more than DENSE_MAX contacts)
    popped: float          #: heap entries popped into a wave
    pushed: float          #: heap entries pushed
    put_back: float        #: heap entries put back (not of the wave's instant)


class StepResult(NamedTuple):
    """A step's outputs (:func:`solve_step`)."""

    #: (n,) whose velocity changed
    changed: np.ndarray
    #: (k, 4) per contact: i, j, time (s, from the step's start), impulse (N s)
    events: np.ndarray
    #: (k, 3) the contact normal, i to j
    normals: np.ndarray
    #: (k, 6) the contact points on i's and on j's surface
    points: np.ndarray
    stats: StepStats
    #: F_* bits
    flags: int
    #: whether the jam path ran (the caller keeps to it from then on)
    stick: bool


_SOLVERS = {False: (solve_all_pairs, solve_all_pairs_stick), True: (solve_listed, solve_listed_stick)}


def solvers(listed: bool) -> tuple:
    """The compiled solvers of a step with (``listed``) or without the neighbour list: without and with
    the jam path."""
    return _SOLVERS[listed]


def solve_step(inputs: StepInputs, stick: bool = False) -> StepResult:
    """One step of contacts (``inputs.x``, ``u``, ``t_last`` and the list's arrays change in place).

    ``stick``: take the variant with the jam path (and the big islands' solve) from the start. A step that
    needs it and ran without it ends with F_AGAIN and its inputs as they came, and is run again with it (the
    same result, bit for bit, as that variant alone): ``result.stick`` is then True.
    """
    plain, jam = _SOLVERS[inputs.lst is not None]
    out = jam(*inputs) if stick else plain(*inputs)
    if out[5] & F_AGAIN:
        stick = True
        out = jam(*inputs)
    changed, ev, ev_n, ev_x, stats, flags = out
    return StepResult(changed, ev, ev_n, ev_x, StepStats._make(stats.tolist()), flags, stick)
