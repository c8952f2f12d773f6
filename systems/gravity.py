"""Gravity: bodies on rails about one well (exact Kepler), or kick-drift-kick in the pull of many.

Runs in the movement stage after the movement system has predicted every
body's free flight (:mod:`driftframe.framework.step`) and writes the end of the
step of every body it integrates (marked :class:`~components.gravity.Orbiting`,
which the collision system leaves out: their sphere contacts are found here,
on their conics) into the step context, from the start of the step, which the
components still hold: its result replaces the prediction, and the commit
stage writes it. A scene without a :class:`~components.gravity.GravityWell`
costs one empty esper query per step.

**Which well (patched conics).** A body moves about the deepest well whose
sphere of influence holds it (a root well's is infinite; a moon's is Laplace's
``a (m/M)^(2/5)`` unless given); ties at one depth go to the strongest pull
``mu/d^2``. Inside a moon's sphere the body's state is taken relative to the
moon, which follows its own conic about its parent. A body on rails changes
sphere *within* the step, at the exact time its conic crosses the sphere
(into a moon's: where its conic about the parent first comes within ``soi`` of
the moon's, by the conservative advancement of the sphere contacts below; out
of one: the outward crossing of ``soi`` on its conic about the moon,
:func:`framework.kepler.time_to_radius` with ``outward=True``), and goes on
from there about the new well: so a long step cannot carry a ship through a
moon (it meets the moon's surface at the time a short step finds), and the
patched-conic path is the same at every step length. A collider's crossings
are events of the contact pass below, in time order with its contacts (a
contact just before a crossing is met on the old conic, and a new conic looks
for its crossing again); another body makes at most :data:`MAX_CROSSINGS` a
step, and one after a surface bounce in the same step at the next step's start.

**Modes, per body, vectorised over all bodies of a well:**

* *On rails* (the default): the exact two-body flow about the well
  (:func:`framework.kepler.propagate`, universal variables), evaluated each
  step from the body's *epoch* — its state about the well at the last time
  something changed it — for the whole time since. Errors therefore never
  build up: energy and angular momentum stay at one rounding however long it
  runs (``benchmarks/orbit_accuracy.py``), and the state at a time ``t`` does
  not depend on how the time was stepped (time warp changes nothing). A new
  epoch is taken when the body thrusts, touches a surface, changes sphere of
  influence, or when anything else (a collision, user code) changed its
  position or velocity since this system wrote them.
* *Thrust* (the rule when the engine fires): a body whose
  :class:`~components.body.Acceleration` is non-zero this step takes the
  symplectic split ``v += a dt/2; Kepler flow for dt; v += a dt/2`` — a
  kick-drift-kick with the thrust as the kick and the exact orbit as the
  drift. It is second order in ``dt`` for the thrust, adds exactly
  ``a dt`` to the velocity (a timed burn delivers the Δv it asks for), and
  is the exact orbit again the step the engine stops: the body goes straight
  back on rails from its new state. No mode flag is kept, so nothing can
  fall out of step.
* *n-body* (opt-in, :class:`~components.gravity.NBody`): leapfrog
  (kick-drift-kick, symplectic, second order) in the pull of every well and
  of every other ``NBody`` body's :class:`~components.body.Mass`
  (``G m``, pairwise, O(n^2)).

**Surfaces.** A body on rails that reaches a well's surface sphere within the
step is found exactly on its conic (:func:`framework.kepler.time_to_radius`;
no sampling, so nothing tunnels at any speed or warp): it is advanced to the
contact, its radial velocity relative to the well reversed (elastic: kinetic
energy relative to the well, hence the orbit energy, kept to rounding), and
advanced for the rest of the step. n-body bodies sweep the straight drift of
their step against each sphere: a root well's moves straight too (a
quadratic), a moon's on its conic (conservative advancement on both paths).
Each contact is a
:class:`~components.gravity.SurfaceContact` in ``world.events``.

**Sphere contacts.** Every :class:`~components.collision.SphereCollider`
this system moves or meets takes part in one contact pass per step
(:meth:`GravitySystem._contacts`), in time order, exact on each body's own
path (the collision system leaves every ``Orbiting`` body out: it moves its
colliders along straight chords). The *movers*: colliders on rails (each on
its conic about its well, which is itself at rest, moving straight, or a moon
on its conic about its parent), n-body colliders (on the leapfrog's straight
drift between its two kicks), and *obstacles*, the colliders this system does
not move (``Mass(inf)``, or no ``Velocity``; not a well): straight at their
step-start velocity (the movement stage's prediction moves them; an
``Acceleration`` on one is not followed here). Only
where two or more colliders move, or one and an obstacle, is anything done; a
scene without colliders pays one comparison. Each step, after the
end-of-step states on rails are known:

1. *Swept boxes* (world frame): for a body on rails
   :func:`framework.kepler.arc_boxes` about its well (the box of its start and
   end, grown by its radius and by ``A h^2 / 8``, how far a path with
   acceleration at most ``A = mu / rho^2`` can leave its chord in ``h``;
   ``rho``: the nearer end's distance, or the periapsis where an apsis is
   passed, never under the surface radius; a body that touches the surface in
   the step, or came into the well's sphere in it, gets the cube it can reach
   at its top speed), moved by the box of the well centre's own path; a line's
   box of its two ends. Candidate pairs from
   :func:`framework.broadphase.box_pairs`; pairs on rails about one well less
   those whose separation's chord stays farther apart than the same bound
   allows (``_near``).
2. *Times of contact*, vectorised over the pairs, by conservative advancement
   on the gap ``|x_b - x_a| - (R_a + R_b)``, each step the largest that cannot
   pass a contact (from the closing rate and a bound on the relative
   acceleration), Newton's step near contact; exact to ~1e-12 relative at any
   step length or warp. Two bodies on rails about one well: their conics about
   it from their epochs, the bound the two pulls or the tidal
   ``2 mu |d| / rho^3`` for bodies close together
   (:func:`framework.kepler.time_to_touch`). A body on rails about a *root* well
   against a line: the line relative to the well, which moves straight too
   (``line_b=True``). Every other pair (bodies about different wells, a body
   about a moon against an obstacle, rails against n-body, two n-body bodies):
   the world-frame paths, the bound the sum of each body's pull and its well
   centre's (:func:`framework.kepler.time_to_touch_paths`). Only approaching
   pairs touch; a pair is followed from both bodies' last contacts up to the
   first surface contact of a body on rails in it.
3. *Contacts in time order*, together with the surface contacts of the
   colliders on rails: the impulse along the line of centres (masses from
   ``Mass``, 1 kg without, an obstacle's inverse mass 0; restitution the smaller
   of the two colliders', as in the collision system); a new epoch at the
   contact for a body on rails (so the rails stay exact: energy kept to
   rounding, momentum of the pair to rounding), a new drift line for an n-body
   body; new swept boxes from the contact on, their pairs looked at again and
   new ones found; a :class:`~components.collision.CollisionEvent` (fields as
   the collision system's, lower entity first, ``method="kepler"`` where a body
   on rails is in it, else ``"leapfrog"``) in ``world.events``. The bodies on
   rails touched get their end-of-step state from their new epochs.

A *resting* contact (``e = 0``, or any contact after which the pair separates
slower than the pulls between them could undo within the step) is not looked
at again in that step: the next step resolves it afresh, so a pair pressed
together by the tidal field costs one small impulse per step (no position
correction: it may sink into itself by what that pull does over a step,
``~3 mu d dt^2 / (2 r^3)``, while it presses). A resting contact on an obstacle
(the well's pull presses the body on, and the obstacle feels none of it)
separates at the least speed that keeps the pair apart to the step's end,
``A (t1 - tc) / 2``, instead of sinking in by ``A dt^2 / 2`` a step: the body
hops by at most ``A dt^2 / 8``. A body meets at most
:data:`MAX_SPHERE_CONTACTS` contacts in a step (further ones in that step are
not looked for, with a warning); a pair that grazes too slowly to converge
(``g' -> 0`` as ``g -> 0``) is taken to touch where it is within 1e-6 of
``R_a + R_b``, else left for the step with a warning. An n-body collider's
surface contacts are events of the same pass (its drift line against a root
well in closed form, against a moon by conservative advancement), so a body that
bounces off a surface meets what lies on its new path in the same step; an
n-body body without a collider sweeps its drift against the surfaces after it.

**Not modelled:** a well's own collider (bodies meet its surface radius; a
``SphereCollider`` of another radius on a well is not used, with a warning).
The warp governor's look-ahead (:meth:`GravitySystem.next_contact`,
:meth:`GravitySystem.next_sphere_contact`) predicts every contact of a body on
rails: its surface contacts, and its sphere contacts with bodies on rails
about any well and with obstacles. An n-body body's path is not known beyond
its step: for its sphere contacts the look-ahead gives a lower bound on when
it could first touch (the gap at the pair's speed plus the most the pulls can
add), so the warp drops before such a contact, perhaps early, never late.

**Checks** (the first step, and whenever wells or bodies are added): a well
inside another's surface, a moon whose parent is missing or not a well, and
a body starting inside a surface are errors naming the entities and values.

Frames: wells' positions come from their ``Transform``; a root well moves at
its own constant ``Velocity`` if it has one (the movement system moves it),
and a moon's state about its parent is its ``Transform``/``Velocity`` minus
the parent's. Bodies with infinite :class:`~components.body.Mass` are
kinematic obstacles and are left to the movement system.
"""
from __future__ import annotations

import warnings

import esper
import numpy as np

from driftframe.components.body import Acceleration, Mass, Transform, Velocity
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.components.gravity import G, GravityWell, NBody, Orbiting, SurfaceContact
from driftframe.framework import broadphase as bp
from driftframe.framework import kepler
from driftframe.framework.step import StepContext, advance
from driftframe.framework.store import as_index, to_indices

#: Most surface contacts one body may have in one step (a grazing bounce is one; more is rounding).
MAX_CONTACTS = 4
#: Most sphere-of-influence changes one body may make in one step (in and out of a moon's sphere is two).
MAX_CROSSINGS = 4
#: Most sphere-sphere contacts one body on rails may have in one step; past it, its further contacts
#: in that step are not looked for (a warning says so once): only a resting or jammed cluster gets there.
MAX_SPHERE_CONTACTS = 16
#: The broad phase sweeps while the boxes would overlap on the sweep axis at most this many times per
#: box (thin boxes: short steps), else it takes the grid (measured: sweep 1.5 ms vs grid 2.8 ms for
#: 10,000 boxes of a 1 s step in low orbit, 51 vs 10 ms for those of a 100 s step).
SWEEP_OVERLAPS = 64


_NO_BODIES = np.empty(0, np.intp)


class _Wells:
    """The scene's wells in depth order (parents first), their constants and the checks on them."""

    def __init__(self, world, q):
        ents = [int(e) for e in q.entities]
        objs = q.rows(GravityWell)
        t_rows = to_indices(q.rows(Transform))
        pos = world.table(Transform).data["position"][t_rows]
        has_v = world.query(GravityWell, Transform, optional=(Velocity,))
        has_v.refresh()
        v_rows = has_v.rows(Velocity)
        vel = np.where((v_rows >= 0)[:, None], world.table(Velocity).data["linear"][np.maximum(v_rows, 0)], 0.0)
        by_ent = {e: k for k, e in enumerate(ents)}
        for k, w in enumerate(objs):
            p = w.parent
            if p is not None and p not in by_ent:
                raise ValueError(f"GravityWell of entity {ents[k]}: parent {p!r} is not an entity with a "
                                 f"GravityWell and a Transform")
            if p is not None and v_rows[k] < 0:
                raise ValueError(f"GravityWell of entity {ents[k]} orbits {p} but has no Velocity "
                                 f"(a moon needs its orbital velocity)")
        depth = []
        for k, w in enumerate(objs):
            seen, p, d = {ents[k]}, w.parent, 0
            while p is not None:
                if p in seen:
                    raise ValueError(f"GravityWell parents form a cycle through entity {ents[k]}")
                seen.add(p)
                d += 1
                p = objs[by_ent[p]].parent
            depth.append(d)
        order = sorted(range(len(ents)), key=lambda k: (depth[k], ents[k]))
        self.ents = [ents[k] for k in order]
        self.wells = [objs[k] for k in order]
        self.depth = np.array([depth[k] for k in order], float)
        self.t_rows = t_rows[order]
        self.v_rows = v_rows[order]
        self.mu = np.array([w.mu for w in self.wells])
        self.radius = np.array([w.radius for w in self.wells])
        index = {e: i for i, e in enumerate(self.ents)}
        self.parent = np.array([index[w.parent] if w.parent is not None else -1 for w in self.wells], np.intp)
        pos, vel = pos[order], vel[order]
        self.soi = np.full(len(order), np.inf)
        for i, w in enumerate(self.wells):
            if w.soi is not None:
                self.soi[i] = w.soi
            elif w.parent is not None:
                j = self.parent[i]
                el = kepler.elements(pos[i] - pos[j], vel[i] - vel[j], self.mu[j])
                a = float(el.a[0]) if el.a[0] > 0 else float(np.linalg.norm(pos[i] - pos[j]))
                self.soi[i] = a * (w.mu / self.mu[j]) ** 0.4
        for i in range(len(order)):
            for j in range(i + 1, len(order)):
                d = float(np.linalg.norm(pos[i] - pos[j]))
                if d < self.radius[i] + self.radius[j]:
                    raise ValueError(f"GravityWell of entity {self.ents[j]} (radius {float(self.radius[j])!r} m) "
                                     f"is {d!r} m from well {self.ents[i]} (radius {float(self.radius[i])!r} m): "
                                     f"a well inside another's surface")

    def __len__(self):
        return len(self.ents)


def _dominant(w: _Wells, x, X, moon_parent) -> np.ndarray:
    """Each body's well: the deepest sphere of influence holding it, then the strongest pull.
    ``moon_parent[k] >= 0``: body k is a moon and orbits that well, whatever the spheres say."""
    d2 = np.einsum("nwk,nwk->nw", x[:, None, :] - X[None], x[:, None, :] - X[None])
    inside = d2 < (w.soi * w.soi)[None, :]
    moons = np.flatnonzero(moon_parent >= 0)
    if moons.size:
        inside[moons] = False
        inside[moons, moon_parent[moons]] = True
    with np.errstate(divide="ignore"):
        pull = w.mu[None, :] / d2
    deepest = np.where(inside, w.depth[None, :], -1.0).max(axis=1, keepdims=True)
    return np.argmax(np.where(inside & (w.depth[None, :] == deepest), pull, -np.inf), axis=1)


def _settle(tc, ts, idx, t, start, upto) -> None:
    """Pairs ``idx`` were searched from ``start`` to ``upto``: their contact time ``t`` (inf: none, or
    a search that could not start), and how far each is now known to be apart (``ts``)."""
    t = np.where(start <= upto, t, np.inf)
    tc[idx] = t
    ts[idx] = np.where(np.isfinite(t), start, upto)


def _first_reach(g, c, A):
    """The least time a gap ``g`` (m) closing at up to ``c`` (m/s) with up to ``A`` (m/s^2) more can
    reach 0: the smaller positive root of ``g - c t - A t^2 / 2`` (0 where ``g`` is 0)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        t = 2.0 * g / (c + np.sqrt(c * c + 2.0 * A * g))
    return np.where(g > 0, t, 0.0)


def _broad_method(lo, hi) -> str:
    """"sweep" or "grid" for boxes ``lo, hi`` (n, 3): the sweep's work is the overlaps along its axis,
    about ``n^2 width / extent`` for boxes spread evenly."""
    n = len(lo)
    ax = int(np.argmax(np.ptp(lo[:: max(n // 64, 1)], axis=0)))      # (the axis from a sample of boxes)
    l, h = lo[:, ax], hi[:, ax]
    extent = float(h.max() - l.min())
    width = float(h.sum() - l.sum()) / n
    return "sweep" if n * width <= SWEEP_OVERLAPS * extent else "grid"


class _PairTimes:
    """The contact pass's candidate pairs ``(pa, pb)`` (movers, ``pa < pb``), each known to be apart up
    to ``ts`` and touching at ``tc`` (inf: not before ``ts`` in the step; NaN: to be looked at)."""

    def __init__(self, pa, pb, t0, n_movers):
        self.n = n_movers
        self.pa, self.pb = pa, pb
        self.ts = np.full(pa.size, t0)
        self.tc = np.full(pa.size, np.nan)

    def look_again(self, movers, t1):
        """Movers' paths changed at a time their pairs were followed to: look at those pairs again."""
        moved = np.zeros(self.n, bool)
        moved[movers] = True
        again = (moved[self.pa] | moved[self.pb]) & (self.ts < t1)
        self.tc[again] = np.nan

    def renew(self, movers, tp):
        """Movers' paths are new from ``tp``: their pairs are looked at again from there."""
        mine = np.isin(self.pa, movers) | np.isin(self.pb, movers)
        self.tc[mine] = np.nan
        self.ts[mine] = tp

    def settle(self, k, t1):
        """Pair ``k`` is not looked at again in this step."""
        self.tc[k] = np.inf
        self.ts[k] = t1

    def drop(self, mask, t1):
        self.tc[mask] = np.inf
        self.ts[mask] = t1

    def add(self, new, tp):
        """New pairs ``[(a, b), ...]`` (``a < b``), apart up to ``tp``."""
        if new:
            a, b = (np.array(c, np.intp) for c in zip(*new))
            self.pa = np.concatenate([self.pa, a])
            self.pb = np.concatenate([self.pb, b])
            self.ts = np.concatenate([self.ts, np.full(a.size, tp)])
            self.tc = np.concatenate([self.tc, np.full(a.size, np.nan)])


def _overlapping(mv, c, pairs) -> list:
    """The pairs mover ``c``'s (new) box makes that are not candidates yet (obstacle pairs left out)."""
    lo, hi, kind = mv["lo"], mv["hi"], mv["kind"]
    over = np.all((lo[c] <= hi) & (hi[c] >= lo), axis=1)
    over[c] = False
    if kind[c] == 2:
        over &= kind != 2
    have = set(pairs.pb[pairs.pa == c].tolist()) | set(pairs.pa[pairs.pb == c].tolist())
    return [(min(c, int(o)), max(c, int(o))) for o in np.flatnonzero(over) if int(o) not in have]


class GravitySystem(esper.Processor):
    """Reads GravityWell, Transform, Velocity, Acceleration, Mass, NBody, SphereCollider; writes the step
    context (its bodies' end of the step), Orbiting; appends SurfaceContact and CollisionEvent to world.events.  Gravity: on rails
    (exact Kepler from an epoch, with the sphere contacts of the bodies on rails) or kick-drift-kick
    (n-body)."""

    stage = "movement"
    name = "gravity"
    reads = (GravityWell, Transform, Velocity, Acceleration, Mass, NBody, Orbiting, SphereCollider)
    writes = (StepContext, Orbiting, SurfaceContact, CollisionEvent)
    #: after the movement system's prediction, in whatever order the two were added: this system's end
    #: of the step replaces the prediction of its bodies
    after = ("movement",)

    @property
    def requires(self) -> tuple:
        """Nothing to do without a well or an NBody body; while it holds bodies it runs, to hand them back
        to movement when the last well goes (see :meth:`World.add_system`). (Read once per structure
        epoch: the NBody look-up is esper's cached query.)"""
        if self._wells is not None or esper.get_component(NBody):
            return ()
        return (GravityWell, Transform)

    def __init__(self):
        self._wells = None
        self._n = 0
        self._epoch_version = 0
        self._lookahead = None                            # (epoch version, contact or None, looked up to)
        self._epochs: dict = {}
        self._n_col = 0
        self._n_nb_col = 0
        self._n_ob = 0                                    # colliders gravity does not move (obstacles)
        self._ob_version = None
        self._warned: set = set()
        self.lookahead_is_bound = False

    # -- the scene ------------------------------------------------------------------------------
    def _build_bodies(self, q) -> None:
        world = self.world
        ents = q.entities
        wells = self._wells
        well_of = {e: i for i, e in enumerate(wells.ents)}
        m_rows = q.rows(Mass)
        kg = np.where(m_rows >= 0, world.table(Mass).data["kg"][np.maximum(m_rows, 0)], 1.0)
        roots = {e for i, e in enumerate(wells.ents) if wells.parent[i] < 0}
        keep = np.array([int(e) not in roots for e in ents], bool) & np.isfinite(kg)
        self.ents = ents[keep]
        self.t_rows = as_index(to_indices(q.rows(Transform))[keep])    # a slice when contiguous
        self.v_rows = as_index(to_indices(q.rows(Velocity))[keep])
        self.a_rows = q.rows(Acceleration)[keep]
        self.gm = G * kg[keep]
        self.m_rows = m_rows[keep]
        n = self._n = len(self.ents)
        nb = world.query(NBody)
        nb.refresh()
        self.nbody = np.isin(self.ents, nb.entities)
        # a moon orbits its parent: its well is fixed, never chosen by spheres of influence
        self.moon_parent = np.full(n, -1, np.intp)
        self.well_index = np.full(n, -1, np.intp)        # this body's own well (moons), else -1
        for k, e in enumerate(self.ents):
            i = well_of.get(int(e))
            if i is not None:
                self.moon_parent[k] = wells.parent[i]
                self.well_index[k] = i
        # the bodies on rails that collide as spheres (SphereCollider rows, -1: none). A moon is a well
        # (bodies hit its surface); n-body bodies drift straight, and collide with each other on the drift
        self.c_rows = np.full(n, -1, np.intp)
        cq = world.query(SphereCollider)
        cq.refresh()
        if len(cq) and n:
            ce = cq.entities
            at = np.minimum(np.searchsorted(ce, self.ents), len(ce) - 1)
            has = ce[at] == self.ents
            self.c_rows[has] = to_indices(cq.rows(SphereCollider))[at[has]]
        if len(cq):
            # a well is met at its surface sphere; a collider of another size on it would say otherwise
            ce, radii = cq.entities, world.table(SphereCollider).data["radius"][to_indices(cq.rows(SphereCollider))]
            for i, e in enumerate(wells.ents):
                at_w = int(np.searchsorted(ce, e))
                if at_w < len(ce) and ce[at_w] == e and float(radii[at_w]) != float(wells.radius[i]):
                    self._warn_once(f"well-collider-{e}", f"gravity: well {e} has a SphereCollider of radius "
                                    f"{float(radii[at_w])!r} m and a surface of radius {float(wells.radius[i])!r} m; "
                                    "bodies meet its surface (GravityWell.radius): the SphereCollider is not used")
        self.nb_c_rows = np.where(self.nbody & (self.well_index < 0), self.c_rows, -1)
        self.c_rows[(self.well_index >= 0) | self.nbody] = -1
        self._n_col = int(np.count_nonzero(self.c_rows >= 0))
        self._n_nb_col = int(np.count_nonzero(self.nb_c_rows >= 0))
        # epochs: (state about the well, time, well); -1 = take a new one
        self.ep_r = np.zeros((n, 3))
        self.ep_v = np.zeros((n, 3))
        self.ep_t = np.zeros(n)
        self.ep_well = np.full(n, -1, np.intp)
        self.ep_contact = np.full(n, np.inf)             # absolute time of the next surface contact
        self.ep_chi = np.zeros(n)                         # universal anomaly at the last step (a warm start)
        self.last_x = np.full((n, 3), np.nan)
        self.last_v = np.full((n, 3), np.nan)
        self._epoch_version += 1
        orbiting = world.query(Orbiting)
        orbiting.refresh()
        for e in self.ents[~np.isin(self.ents, orbiting.entities)]:
            world.add_component(int(e), Orbiting())
        # no body may start inside a surface
        x = world.table(Transform).data["position"][self.t_rows]
        X = world.table(Transform).data["position"][wells.t_rows]
        for i in range(len(wells)):
            d = np.linalg.norm(x - X[i], axis=1)
            inside = (d < wells.radius[i]) & (self.ents != wells.ents[i])
            if inside.any():
                k = int(np.flatnonzero(inside)[0])
                raise ValueError(f"entity {int(self.ents[k])} starts {float(d[k])!r} m from the centre of "
                                 f"well {wells.ents[i]}, inside its surface (radius {float(wells.radius[i])!r} m)")

    def _build_obstacles(self, oq) -> None:
        """The colliders gravity does not move (not bodies of this system, not wells: ``Mass(inf)``,
        or no Velocity): obstacles that move straight at their Velocity (the movement system moves
        them), met by the colliders on rails about a root well, exactly (inverse mass 0)."""
        self._ob_version = True
        ents = oq.entities
        mine = np.isin(ents, self.ents) | np.isin(ents, np.array(self._wells.ents, np.int64))
        keep = ~mine
        self.ob_ents = ents[keep]
        self.ob_t_rows = to_indices(oq.rows(Transform))[keep]
        self.ob_v_rows = oq.rows(Velocity)[keep]
        self.ob_c_rows = to_indices(oq.rows(SphereCollider))[keep]
        self._n_ob = len(self.ob_ents)

    def _release(self) -> None:
        world = self.world
        orbiting = world.query(Orbiting)
        orbiting.refresh()
        for e in orbiting.entities:
            world.remove_component(int(e), Orbiting)
        self._wells = None
        self._n = 0
        self._epoch_version += 1

    _EPOCH = ("ep_r", "ep_v", "ep_t", "ep_well", "ep_contact", "ep_chi", "last_x", "last_v")

    def _carry(self):
        return (list(self._wells.ents), self.ents.copy(), {k: getattr(self, k) for k in self._EPOCH})

    def _restore(self, old) -> None:
        ents, arrays = old
        if not len(ents) or not self._n:
            return
        common, new_i, old_i = np.intersect1d(self.ents, ents, assume_unique=True, return_indices=True)
        for k, arr in arrays.items():
            getattr(self, k)[new_i] = arr[old_i]

    def state(self):
        """What a save keeps of this system (see framework/save.py): each body's epoch on rails (the
        state its conic is evaluated from) and what it last wrote, by entity; None before the first step."""
        saved = getattr(self, "_saved", None)
        if self._wells is None and saved is None:
            return None
        wells, ents, arrays = self._carry() if self._wells is not None else saved   # (a load not stepped yet)
        return {"wells": [int(e) for e in wells], "bodies": [int(e) for e in ents],
                "epochs": {k: v.copy() for k, v in arrays.items()}}

    def restore(self, state) -> None:
        """Take back :meth:`state` (a load): the bodies are gathered again at the next step and take
        their saved epochs (bodies about other wells than saved start new ones)."""
        self._wells = None
        self._saved = None if state is None else (state["wells"], np.asarray(state["bodies"], np.int64),
                                                  dict(state["epochs"]))

    def _pull_without_wells(self, dt: float) -> None:
        """A scene with ``NBody`` bodies and no well: they attract each other all the same.

        Each step kicks every NBody body's velocity by the pull of the others,
        ``v' = v + dt * sum_j G m_j (x_j - x_i) / |x_j - x_i|^3`` (positions at
        the step's start), then drifts it, ``x += v' dt``, into the step context
        in place of the movement stage's prediction (without a movement stage,
        the kick alone): symplectic Euler, first order, energy bounded; the
        collision system meets them as any other bodies. A body of infinite
        (or no) mass pulls nothing and is not kicked. With a well in the scene
        they are this system's own, on the leapfrog above.
        """
        q = self.world.query(NBody, Transform, Velocity, Mass, optional=(Acceleration,))
        q.refresh()
        if len(q) < 2:
            return
        world = self.world
        t_rows, v_rows = to_indices(q.rows(Transform)), to_indices(q.rows(Velocity))
        kg = world.table(Mass).data["kg"][to_indices(q.rows(Mass))]
        live = np.isfinite(kg)
        if np.count_nonzero(live) < 2:
            return
        t_rows, v_rows, gm = t_rows[live], v_rows[live], G * kg[live]
        a_rows = np.asarray(q.rows(Acceleration), np.intp)[live]
        x = world.table(Transform).data["position"][t_rows]
        d = x[None, :, :] - x[:, None, :]                       # d[i, j] = x_j - x_i, m
        r2 = np.einsum("ijk,ijk->ij", d, d)
        np.fill_diagonal(r2, np.inf)                            # no self-pull
        with np.errstate(divide="ignore", invalid="ignore"):
            w = gm[None, :] / (r2 * np.sqrt(r2))                # G m_j / r^3, 1/s^2
        w[~np.isfinite(w)] = 0.0                                # two bodies at one point: no kick
        v = world.table(Velocity).data["linear"][v_rows] + dt * np.einsum("ij,ijk->ik", w, d)
        ctx = world.step_context
        ctx.begin(world.step_count, dt, world.table(Transform), world.table(Velocity))
        if not ctx.predicted:
            ctx.velocity[v_rows] = v
            return
        has_a = a_rows >= 0
        for sel, a in ((~has_a, None), (has_a, world.table(Acceleration).data["linear"][a_rows[has_a]])):
            if sel.any():
                ctx.position[t_rows[sel]], ctx.velocity[v_rows[sel]] = advance(x[sel], v[sel], a, dt)

    def reference(self, entity: int):
        """The well ``entity`` moves about now, as ``(well entity, mu, radius, X, V)`` (its centre's
        position and velocity, world frame), or None in a scene without wells or for a root well.
        For orbit readouts and flight aids: prograde means along the velocity relative to this well."""
        world = self.world
        wq = world.query(GravityWell, Transform)
        wq.refresh()
        if not len(wq):
            return None
        wells = self._wells if self._wells is not None else _Wells(world, wq)
        pos_t = world.table(Transform).data["position"]
        vel_t = world.table(Velocity).data["linear"]
        X = pos_t[wells.t_rows]
        V = np.where((wells.v_rows >= 0)[:, None], vel_t[np.maximum(wells.v_rows, 0)], 0.0)
        x = world.columns(Transform, [entity]).position
        if entity in wells.ents:
            i = wells.ents.index(entity)
            if wells.parent[i] < 0:
                return None
            wi = int(wells.parent[i])
        else:
            wi = int(_dominant(wells, x, X, np.full(1, -1, np.intp))[0])
        return wells.ents[wi], float(wells.mu[wi]), float(wells.radius[wi]), X[wi].copy(), V[wi].copy()

    def next_contact(self):
        """``(time, entity, well)`` of the earliest predicted surface contact of a body on rails
        (absolute seconds, exact on its conic), or None. For the warp governor."""
        if not self._n:
            return None
        valid = self.ep_well >= 0
        if not valid.any():
            return None
        t = np.where(valid, self.ep_contact, np.inf)
        k = int(np.argmin(t))
        if not np.isfinite(t[k]):
            return None
        return float(t[k]), int(self.ents[k]), self._wells.ents[int(self.ep_well[k])]

    def next_sphere_contact(self, horizon: float):
        """``(time, entity, entity)`` of the earliest predicted contact between two colliders on rails
        about the same well, or a collider on rails about a root well and an obstacle (a collider
        gravity does not move), within ``horizon`` s of the end of this step (absolute seconds, exact on
        their conics: :func:`framework.kepler.time_to_touch` from the epochs), or None; lower entity
        first. For the warp governor. Each look at the pairs on rails covers twice the horizon and is
        kept while no epoch changes (a thrust, a contact, an edit), so a steady warp looks again only
        every ``horizon`` s; the obstacles (whose velocity anyone may change) are looked at on every
        call, from their state now. A pair is followed up to the first surface contact of the body on
        rails (itself an event the governor slows down for)."""
        exact = [c for c in (self._next_rails_contact(horizon), self._next_obstacle_contact(horizon),
                             self._next_cross_contact(horizon)) if c is not None]
        bound = self._next_nbody_contact(horizon)
        best = min(exact) if exact else None
        #: Whether the last answer is only a lower bound (an n-body pair that *could* touch by then).
        self.lookahead_is_bound = bound is not None and (best is None or bound[0] < best[0])
        return bound if self.lookahead_is_bound else best

    def _next_nbody_contact(self, horizon: float):
        """next_sphere_contact's look at the n-body colliders, whose paths are not known beyond their
        step: the earliest time any of them *could* touch another collider within the horizon, a lower
        bound (the gap closed at the pair's speed now plus the most the pulls can add: every well's
        ``mu / R^2`` on each body and the n-body bodies' own pulls; for two n-body bodies, which feel the
        same wells, the tidal difference ``2 mu D / (R - D/2)^3`` instead), so the warp drops before
        such a contact, never after it (two n-body colliders 1 km apart in low orbit hold it at 100x:
        the tidal field can bring them together within a few hundred seconds)."""
        if not self._n_nb_col or not horizon > 0 or self._wells is None or self._n_col + self._n_nb_col + self._n_ob < 2:
            return None
        world = self.world
        now = (world.step_count + 1) * world.dt
        wells = self._wells
        pos_t = world.table(Transform).data["position"]
        vel_t = world.table(Velocity).data["linear"]
        col = world.table(SphereCollider).data["radius"]
        nbk = np.flatnonzero(self.nb_c_rows >= 0)
        rk = np.flatnonzero(self.c_rows >= 0)
        t_rows, v_rows = (np.arange(r.start, r.stop, r.step or 1) if isinstance(r, slice) else r
                          for r in (self.t_rows, self.v_rows))
        x = np.concatenate([pos_t[t_rows[nbk]], pos_t[t_rows[rk]], pos_t[self.ob_t_rows]])
        v = np.concatenate([vel_t[v_rows[nbk]], vel_t[v_rows[rk]],
                            np.where((self.ob_v_rows >= 0)[:, None], vel_t[np.maximum(self.ob_v_rows, 0)], 0.0)])
        r = np.concatenate([col[self.nb_c_rows[nbk]], col[self.c_rows[rk]], col[self.ob_c_rows]]).astype(np.float64)
        pull = float(np.sum(wells.mu / wells.radius ** 2))
        gm = self.gm[nbk]
        acc = np.concatenate([np.full(nbk.size, pull + float(np.sum(gm / (r[:nbk.size].min() * 2.0) ** 2))),
                              np.full(rk.size, pull), np.zeros(self._n_ob)])
        h = horizon
        half = kepler._norm(v) * h + 0.5 * acc * h * h + r
        pa, pb = bp.box_pairs(x - half[:, None], x + half[:, None], "sweep")
        pa, pb = pa.astype(np.intp), pb.astype(np.intp)
        mine = pa < nbk.size                              # (i < j: an n-body collider is always a)
        pa, pb = pa[mine], pb[mine]
        if not pa.size:
            return None
        d = kepler._norm(x[pb] - x[pa])
        g = np.maximum(d - r[pa] - r[pb], 0.0)
        A = acc[pa] + acc[pb]
        # (the leapfrog's first half kick moves a drift's velocity by up to A dt / 2 at once)
        w = kepler._norm(v[pb] - v[pa]) + A * world.dt
        tau = _first_reach(g, w, A)
        both = pb < nbk.size
        if both.any():
            # two n-body bodies feel the same wells: their relative acceleration is the tidal difference
            # (|grad g| = 2 mu / r^3, and no body is nearer a well's centre than its surface) plus their
            # own pulls. Over a trial span T their distance stays under D = d + w T + A_T T^2 / 2, A_T
            # the bound at D (iterated up from the first guess: the least such D is a bound); the step
            # min(root, T) is safe for each trial, and the longest of them is taken
            own = 2.0 * self.gm[nbk].sum() / (2.0 * r[:nbk.size].min()) ** 2
            db, wb, gb = d[both], w[both], g[both]
            best = tau[both]
            for T in h * 0.25 ** np.arange(12):
                D = db + wb * T
                for _ in range(4):
                    seg = wells.radius[None, :] - 0.5 * D[:, None]
                    with np.errstate(divide="ignore", over="ignore"):
                        A_T = np.where((seg > 0).all(axis=1),
                                       np.sum(2.0 * wells.mu[None, :] * D[:, None] / np.where(seg > 0, seg, 1.0) ** 3,
                                              axis=1), np.inf) + own
                    D_next = db + wb * T + 0.5 * A_T * T * T
                    done = D_next <= D * 1.001
                    D = np.maximum(D, D_next)
                ok = done & np.isfinite(A_T)
                best = np.where(ok, np.maximum(best, np.minimum(_first_reach(gb, wb, A_T), T)), best)
            tau[both] = best
        k = int(np.argmin(tau))
        if not tau[k] <= h:
            return None
        ents = np.concatenate([self.ents[nbk], self.ents[rk], self.ob_ents])
        a, b = sorted((int(ents[pa[k]]), int(ents[pb[k]])))
        return float(now + tau[k]), a, b

    def _next_cross_contact(self, horizon: float):
        """next_sphere_contact's look at the pairs in different frames on rails: colliders on rails about
        different wells, and about a moon against an obstacle, on their world-frame paths
        (:func:`framework.kepler.time_to_touch_paths`) from the last step's epochs and wells."""
        if self._wells is None or not self._n_col or not horizon > 0 or getattr(self, "_step", None) is None:
            return None
        wells = self._wells
        cs = np.flatnonzero((self.c_rows >= 0) & (self.ep_well >= 0))
        w_of = self.ep_well[cs]
        moons_in = (wells.parent[w_of] >= 0).any() if cs.size else False
        if not cs.size or (np.unique(w_of).size < 2 and not (moons_in and self._n_ob)):
            return None
        world = self.world
        now = (world.step_count + 1) * world.dt
        end = now + horizon
        col = world.table(SphereCollider).data
        n_ob = self._n_ob
        M = cs.size + n_ob
        mv = {"kind": np.concatenate([np.zeros(cs.size, np.intp), np.full(n_ob, 2, np.intp)]),
              "body": np.concatenate([cs, np.arange(n_ob)]),
              "well": np.concatenate([w_of, np.full(n_ob, -1, np.intp)]),
              "rad": np.concatenate([col["radius"][self.c_rows[cs]], col["radius"][self.ob_c_rows]]).astype(np.float64),
              "lp": np.concatenate([np.zeros((cs.size, 3)), self._ob_x]),
              "lu": np.concatenate([np.zeros((cs.size, 3)), self._ob_v])}
        pos, vel = self._movers_at(mv, np.arange(M), np.full(M, now))
        # a box each can reach within the horizon: its speed now, and a bound on its acceleration (no body
        # on rails comes nearer its well than the surface; a moon nearer its parent than the parent's)
        acc = np.zeros(M)
        for wi in np.unique(w_of):
            chain, w = 0.0, int(wi)
            while w >= 0:
                chain += wells.mu[w] / wells.radius[w] ** 2
                w = int(wells.parent[w])
            acc[: cs.size][w_of == wi] = chain
        h = horizon
        half = kepler._norm(vel) * h + 0.5 * acc * h * h + mv["rad"]
        lo, hi = pos - half[:, None], pos + half[:, None]
        pa, pb = bp.box_pairs(lo, hi, _broad_method(lo, hi))
        pa, pb = pa.astype(np.intp), pb.astype(np.intp)
        kind, well = mv["kind"], mv["well"]
        cross = (kind[pa] == 0) & (((kind[pb] == 0) & (well[pa] != well[pb]))
                                   | ((kind[pb] == 2) & (wells.parent[np.maximum(well[pa], 0)] >= 0)))
        pa, pb = pa[cross], pb[cross]
        if not pa.size:
            return None
        ka = mv["body"][pa]
        upto = np.minimum(end, np.minimum(self.ep_contact[ka],
                                          np.where(kind[pb] == 0, self.ep_contact[mv["body"][pb]], np.inf)))
        t, _ = kepler.time_to_touch_paths(lambda i, tt: self._movers_at(mv, pa[i], tt),
                                          lambda i, tt: self._movers_at(mv, pb[i], tt),
                                          mv["rad"][pa] + mv["rad"][pb], np.full(pa.size, now), upto,
                                          acc[pa] + acc[pb])
        t = np.where(now <= upto, t, np.inf)
        k = int(np.argmin(t))
        if not np.isfinite(t[k]):
            return None
        name = lambda m: int(self.ob_ents[mv["body"][m]]) if kind[m] == 2 else int(self.ents[mv["body"][m]])  # noqa: E731
        a, b = sorted((name(pa[k]), name(pb[k])))
        return float(t[k]), a, b

    def _next_obstacle_contact(self, horizon: float):
        """next_sphere_contact's look at the obstacles: from their Transform and Velocity now (the
        end of the step: the movement system has moved them), straight, against the conics."""
        if not self._n_ob or not self._n_col or not horizon > 0 or self._wells is None:
            return None
        world = self.world
        now = (world.step_count + 1) * world.dt
        end = now + horizon
        wells = self._wells
        pos_t = world.table(Transform).data["position"]
        vel_t = world.table(Velocity).data["linear"]
        X = pos_t[wells.t_rows]
        V = np.where((wells.v_rows >= 0)[:, None], vel_t[np.maximum(wells.v_rows, 0)], 0.0)
        ox = pos_t[self.ob_t_rows]
        ov = np.where((self.ob_v_rows >= 0)[:, None], vel_t[np.maximum(self.ob_v_rows, 0)], 0.0)
        col = world.table(SphereCollider).data
        orad = col["radius"][self.ob_c_rows].astype(np.float64)
        best = None
        for wi in np.flatnonzero(wells.parent < 0):
            cs = np.flatnonzero((self.c_rows >= 0) & (self.ep_well == wi))
            if not cs.size:
                continue
            nc = cs.size
            mu, R = wells.mu[wi], wells.radius[wi]
            rad = col["radius"][self.c_rows[cs]].astype(np.float64)
            p0, w0 = kepler.propagate(self.ep_r[cs], self.ep_v[cs], mu, now - self.ep_t[cs])
            p1, w1 = kepler.propagate(self.ep_r[cs], self.ep_v[cs], mu, end - self.ep_t[cs])
            lo, hi, A, _ = kepler.arc_boxes(p0, w0, p1, w1, end - now, mu, R, self.ep_contact[cs] <= end, rad)
            q0 = ox - X[wi]
            qv = ov - V[wi]
            q1 = q0 + qv * (end - now)
            lo = np.concatenate([lo, np.minimum(q0, q1) - orad[:, None]])
            hi = np.concatenate([hi, np.maximum(q0, q1) + orad[:, None]])
            pa, pb = bp.box_pairs(lo, hi, _broad_method(lo, hi))
            mixed = (pa < nc) & (pb >= nc)                 # (i < j: the obstacle is pb)
            if not mixed.any():
                continue
            pa, o = pa[mixed].astype(np.intp), (pb[mixed] - nc).astype(np.intp)
            ka = cs[pa]
            upto = np.minimum(end, self.ep_contact[ka])
            t, _ = kepler.time_to_touch(self.ep_r[ka], self.ep_v[ka], self.ep_t[ka], q0[o], qv[o], now, mu,
                                        rad[pa] + orad[o], np.full(len(pa), now), upto, A[pa], line_b=True)
            t = np.where(now <= upto, t, np.inf)
            k = int(np.argmin(t))
            if np.isfinite(t[k]) and (best is None or t[k] < best[0]):
                a, b = sorted((int(self.ents[ka[k]]), int(self.ob_ents[o[k]])))
                best = (float(t[k]), a, b)
        return best

    def _next_rails_contact(self, horizon: float):
        """next_sphere_contact's look at the pairs on rails (see there)."""
        if self._n_col < 2 or not horizon > 0 or self._wells is None:
            return None
        world = self.world
        now = (world.step_count + 1) * world.dt           # the state is at the end of this step
        kept = self._lookahead
        if kept is not None and kept[0] == self._epoch_version:
            found, upto = kept[1], kept[2]
            if found is not None and found[0] >= now:
                return found if found[0] <= now + horizon else None
            if found is None and upto >= now + horizon:
                return None
        end = now + 2.0 * horizon
        best = None
        col = world.table(SphereCollider).data
        for wi in range(len(self._wells)):
            cs = np.flatnonzero((self.c_rows >= 0) & (self.ep_well == wi))
            if cs.size < 2:
                continue
            mu, R = self._wells.mu[wi], self._wells.radius[wi]
            rad = col["radius"][self.c_rows[cs]].astype(np.float64)
            p0, w0 = kepler.propagate(self.ep_r[cs], self.ep_v[cs], mu, now - self.ep_t[cs])
            p1, w1 = kepler.propagate(self.ep_r[cs], self.ep_v[cs], mu, end - self.ep_t[cs])
            lo, hi, A, rho = kepler.arc_boxes(p0, w0, p1, w1, end - now, mu, R, self.ep_contact[cs] <= end, rad)
            pa, pb = bp.box_pairs(lo, hi, _broad_method(lo, hi))
            if not len(pa):
                continue
            pa, pb = pa.astype(np.intp), pb.astype(np.intp)
            ka, kb = cs[pa], cs[pb]
            upto = np.minimum(end, np.minimum(self.ep_contact[ka], self.ep_contact[kb]))
            t, _ = kepler.time_to_touch(self.ep_r[ka], self.ep_v[ka], self.ep_t[ka], self.ep_r[kb], self.ep_v[kb],
                                        self.ep_t[kb], mu, rad[pa] + rad[pb], np.full(len(pa), now), upto,
                                        A[pa] + A[pb], np.minimum(rho[pa], rho[pb]))
            t = np.where(now <= upto, t, np.inf)
            k = int(np.argmin(t))
            if np.isfinite(t[k]) and (best is None or t[k] < best[0]):
                a, b = sorted((int(self.ents[ka[k]]), int(self.ents[kb[k]])))
                best = (float(t[k]), a, b)
        self._lookahead = (self._epoch_version, best, end)
        return best if best is not None and best[0] <= now + horizon else None

    # -- the step -------------------------------------------------------------------------------
    def process(self, dt: float) -> None:
        world = self.world
        wq = world.query(GravityWell, Transform)
        changed = wq.refresh()
        if not len(wq):
            if self._wells is not None:               # the last well went: hand the bodies back to movement
                self._release()
            self._pull_without_wells(dt)
            return
        bq = world.query(Transform, Velocity, optional=(Acceleration, Mass))
        if bq.refresh() or changed or self._wells is None:
            # any structural change anywhere gives esper new lists: rebuild, but keep the epochs of the
            # bodies that are still here about the same wells (so nothing is re-anchored for nothing)
            old = self._carry() if self._wells is not None else getattr(self, "_saved", None)
            self._saved = None
            self._wells = _Wells(world, wq)
            self._build_bodies(bq)
            if old is not None and old[0] == self._wells.ents:
                self._restore(old[1:])
            self._epoch_version += 1
            wq.refresh()                                  # Orbiting may have been added: new lists
            bq.refresh()
            self._ob_version = None
        oq = world.query(Transform, SphereCollider, optional=(Velocity,))
        if oq.refresh() or self._ob_version is None:
            self._build_obstacles(oq)
        n = self._n
        if not n:
            return
        wells = self._wells
        pos_t = world.table(Transform).data["position"]
        vel_t = world.table(Velocity).data["linear"]
        x = pos_t[self.t_rows]
        v = vel_t[self.v_rows]
        a = np.zeros((n, 3))
        has_a = self.a_rows >= 0
        thrust = np.zeros(n, bool)
        if has_a.any():
            a[has_a] = world.table(Acceleration).data["linear"][self.a_rows[has_a]]
            thrust = np.any(a != 0.0, axis=1)
        # times as step_count * dt (never summed), so a time is the same number however it was reached
        t0 = world.step_count * dt
        t1 = (world.step_count + 1) * dt
        W = len(wells)
        X0 = pos_t[wells.t_rows]
        V0 = np.where((wells.v_rows >= 0)[:, None], vel_t[np.maximum(wells.v_rows, 0)], 0.0)
        # root wells move at their own velocity (the movement system moves them); moons as bodies below
        X1 = X0 + V0 * dt
        V1 = V0.copy()
        x1 = np.empty_like(x)
        v1 = np.empty_like(v)
        events = []
        dom = _dominant(wells, x, X0, self.moon_parent) if W > 1 else np.zeros(n, np.intp)
        if np.array_equal(x, self.last_x) and np.array_equal(v, self.last_v):
            edited = np.zeros(n, bool)                    # the usual step: nobody else moved anything
        else:
            edited = np.any(x != self.last_x, axis=1) | np.any(v != self.last_v, axis=1)
        # the obstacles at the step's start (the components: the commit stage writes their end later)
        self._ob_x = pos_t[self.ob_t_rows]
        has = self.ob_v_rows >= 0
        self._ob_v = np.where(has[:, None], vel_t[np.maximum(self.ob_v_rows, 0)], 0.0)
        self._step = (X0, V0, t0, t1)
        rails = ~self.nbody
        nb = np.flatnonzero(self.nbody)
        # sphere contacts are looked for where two or more colliders move, or one and an obstacle
        movers = self._n_col + self._n_nb_col
        look = movers >= 2 or (movers and self._n_ob)
        done = crossed = None
        if W > 1 and (wells.parent >= 0).any():
            # bodies that enter or leave a moon's sphere of influence do so at the exact time in the step
            done, crossed = self._crossings(rails, dom, x, v, a, thrust, edited, X0, V0, t0, t1,
                                            defer=(self.c_rows >= 0) if look else None)
        else:
            self.ep_cross = None
        ends = {}
        self._wA = np.zeros(W)                            # a bound on each well centre's acceleration
        for wi in range(W):                               # parents first: a moon is placed before its bodies
            sel = np.flatnonzero(rails & (dom == wi))
            if sel.size:
                ends[wi] = (sel, *self._rails(sel, wi, x, v, a, thrust, edited, X0, V0, t0, t1, events, look,
                                              done, crossed))
            # wells whose parent is wi: their state at t1 is now known (a moon is never touched by a
            # sphere contact: it is a well)
            for wj in np.flatnonzero(wells.parent == wi):
                kk = int(np.flatnonzero(self.well_index == wj)[0])
                sel_w, r, u = ends[wi][0], ends[wi][1], ends[wi][2]
                p = int(np.searchsorted(sel_w, kk))
                X1[wj] = X1[wi] + r[p]
                V1[wj] = V1[wi] + u[p] + (0.5 * dt * a[kk] if thrust[kk] else 0.0)
                _, _, A_m, _ = kepler.arc_boxes(x[kk:kk + 1] - X0[wi], v[kk:kk + 1] - V0[wi], r[p:p + 1], u[p:p + 1],
                                                dt, wells.mu[wi], wells.radius[wi], np.zeros(1, bool))
                self._wA[wj] = A_m[0] + self._wA[wi]
        line = None
        if nb.size:
            line = self._kick(nb, x, v, a, X0, dt)
        touched = _NO_BODIES
        self._nb_surfaces_done = False
        if look:
            # every sphere contact of the step, in time order: on rails, on the n-body drift, obstacles
            touched, line = self._contacts(ends, nb, line, x, v, a, X0, V0, X1, t0, t1, events)
        for wi, (sel, r, u, chi, guess) in ends.items():
            self._rails_end(sel, wi, r, u, chi, guess, touched, a, thrust, X1, V1, t1, x1, v1)
        if nb.size:
            self._leapfrog_end(nb, line, a, X0, X1, dt, t0, x1, v1, events)
        ctx = world.step_context
        ctx.begin(world.step_count, dt, world.table(Transform), world.table(Velocity))
        ctx.position[self.t_rows] = x1
        ctx.velocity[self.v_rows] = v1
        self.last_x = x1
        self.last_v = v1
        for ev in events:
            world.emit(ev)

    def _take_epochs(self, sel, wi, x, v, a, thrust, edited, X0, V0, t0, dt, done=None):
        """A new epoch at ``t0`` about well ``wi`` for those of bodies ``sel`` whose engine fires, whose
        well changed, or that someone else moved (not those in ``done``: taken already this step)."""
        g = slice(None) if sel.size == self._n else sel     # a slice gathers faster than an index
        new = thrust[g] | edited[g] | (self.ep_well[g] != wi)
        if done is not None:
            new &= ~done[g]
        if new.any():
            mu, R = self._wells.mu[wi], self._wells.radius[wi]
            self._epoch_version += 1
            k = sel[new]
            self.ep_r[k] = x[k] - X0[wi]
            self.ep_v[k] = v[k] - V0[wi] + 0.5 * dt * a[k]           # thrust: the first half kick
            self.ep_t[k] = t0
            self.ep_well[k] = wi
            self.ep_contact[k] = t0 + kepler.time_to_radius(self.ep_r[k], self.ep_v[k], mu, R, np.inf)
            self.ep_chi[k] = 0.0

    def _crossings(self, rails, dom, x, v, a, thrust, edited, X0, V0, t0, t1, defer=None):
        """Sphere-of-influence changes within the step, at their exact times (patched conics): a body
        on rails about well ``w`` enters a moon ``m`` of ``w`` where its conic comes within ``soi_m``
        of the moon's (:func:`framework.kepler.time_to_touch` about ``w``, approaching), and leaves a
        moon where its conic about it passes ``soi`` outwards (:func:`framework.kepler.time_to_radius`,
        ``outward=True``); it takes a new epoch about its new well there, so the rest of the step,
        a surface contact on the moon included, is on the new conic. Takes every body's epoch for the
        step first. The bodies in ``defer`` (the colliders, when the contact pass runs) only get their
        first crossing's time (``ep_cross``, ``cross_to``): the contact pass makes it, in time order with
        their contacts. Returns the bodies whose epochs are taken (all of ``rails``) and those that
        crossed (``dom`` is updated to each body's well at the step's end)."""
        wells = self._wells
        W, n = len(wells), self._n
        dt = t1 - t0
        done = np.zeros(n, bool)
        for wi in range(W):
            sel = np.flatnonzero(rails & (dom == wi))
            if sel.size:
                self._take_epochs(sel, wi, x, v, a, thrust, edited, X0, V0, t0, dt)
                done[sel] = True
        crossed = np.zeros(n, bool)
        movers = rails & (self.well_index < 0)            # (a moon keeps its parent, whatever the spheres say)
        self.ep_cross = np.full(n, np.inf)
        self.cross_to = np.full(n, -1, np.intp)
        t_from = np.full(n, t0)
        state = (x, v, a, X0, V0, t0)
        for _ in range(MAX_CROSSINGS):
            k = np.flatnonzero(movers & (t_from < t1))
            best_t, best_w = self._next_crossing(k, t_from[k], t1, state)
            hit = best_t <= t1
            if defer is not None:
                later = hit & defer[k]
                self.ep_cross[k[later]] = best_t[later]
                self.cross_to[k[later]] = best_w[later]
                hit &= ~defer[k]
            if not hit.any():
                break
            self._epoch_version += 1
            for j in np.flatnonzero(hit):
                self._cross(int(k[j]), int(best_w[j]), float(best_t[j]))
            crossed[k[hit]] = True
            t_from[k[hit]] = best_t[hit]
            movers[k[~hit]] = False
        dom[crossed] = self.ep_well[crossed]
        return done, crossed

    def _next_crossing(self, k, t_from, t1, state=None):
        """The first sphere-of-influence crossing of bodies ``k`` on rails (current epochs) in
        ``[t_from, t1]``, before any surface contact: ``(time, new well)`` (inf, -1: none). ``state``:
        the step-start table state, used for bodies looked at from the step's start (no Kepler solve)."""
        wells = self._wells
        best_t = np.full(k.size, np.inf)
        best_w = np.full(k.size, -1, np.intp)
        if not k.size:
            return best_t, best_w
        X0, V0, t0, _ = self._step
        for wi in np.unique(self.ep_well[k]):
            wi = int(wi)
            moons = np.flatnonzero(wells.parent == wi)
            if wells.parent[wi] < 0 and not moons.size:
                continue
            g = np.flatnonzero(self.ep_well[k] == wi)
            kw, tf = k[g], t_from[g]
            mu, R = wells.mu[wi], wells.radius[wi]
            upto = np.minimum(t1, self.ep_contact[kw])      # (a surface contact first: its own conic after)
            span = np.maximum(upto - tf, 0.0)
            # the state at t_from: at the step's start the table's (no Kepler solve), else from the epoch
            later = tf > t0 if state is not None else np.ones(kw.size, bool)
            r = np.empty((kw.size, 3))
            u = np.empty((kw.size, 3))
            if (~later).any():
                x, v, a, _, _, _ = state
                ke = kw[~later]
                r[~later] = x[ke] - X0[wi]
                u[~later] = v[ke] - V0[wi] + 0.5 * (t1 - t0) * a[ke]
            if later.any():
                kl = kw[later]
                r[later], u[later] = kepler.propagate(self.ep_r[kl], self.ep_v[kl], mu, tf[later] - self.ep_t[kl])
            # how far a body can move in the span: no body on rails about wi comes nearer its centre
            # than its surface, so no pull on it (nor on a moon of wi) exceeds mu / R^2
            A = mu / (R * R)
            if wells.parent[wi] >= 0:                       # out through this moon's sphere
                out = kepler._norm(r) + kepler._norm(u) * span + 0.5 * A * span * span >= wells.soi[wi]
                if out.any():
                    te = tf[out] + kepler.time_to_radius(r[out], u[out], mu, wells.soi[wi], span[out], outward=True)
                    better = te < best_t[g[out]]
                    best_t[g[out][better]] = te[better]
                    best_w[g[out][better]] = wells.parent[wi]
            for wj in moons:                                # into a moon's sphere
                kk = int(np.flatnonzero(self.well_index == wj)[0])
                rm = np.broadcast_to(X0[wj] - X0[wi], (kw.size, 3)).copy()
                um = np.broadcast_to(V0[wj] - V0[wi], (kw.size, 3)).copy()
                if later.any():
                    ml = int(np.count_nonzero(later))
                    rm[later], um[later] = kepler.propagate(np.broadcast_to(self.ep_r[kk], (ml, 3)),
                                                            np.broadcast_to(self.ep_v[kk], (ml, 3)), mu,
                                                            tf[later] - self.ep_t[kk])
                gap = kepler._norm(r - rm) - wells.soi[wj]
                near = gap <= kepler._norm(u - um) * span + A * span * span
                if not near.any():
                    continue
                kn = kw[near]
                tk, _ = kepler.time_to_touch(self.ep_r[kn], self.ep_v[kn], self.ep_t[kn],
                                             np.broadcast_to(self.ep_r[kk], (kn.size, 3)),
                                             np.broadcast_to(self.ep_v[kk], (kn.size, 3)), self.ep_t[kk],
                                             mu, wells.soi[wj], tf[near], upto[near], 2.0 * A)
                better = tk < best_t[g[near]]
                best_t[g[near][better]] = tk[better]
                best_w[g[near][better]] = wj
        return best_t, best_w

    def _cross(self, k, new, tc):
        """Body ``k`` changes well to ``new`` at ``tc``: its state at ``tc`` about the old well, moved
        to the new one by the moon's state there, is its new epoch."""
        wells = self._wells
        old = int(self.ep_well[k])
        r, u = kepler.propagate(self.ep_r[k], self.ep_v[k], wells.mu[old], tc - self.ep_t[k])
        moon, sign = (new, -1.0) if wells.parent[new] == old else (old, 1.0)   # into a moon / out of it
        mk = int(np.flatnonzero(self.well_index == moon)[0])
        rm, um = kepler.propagate(self.ep_r[mk], self.ep_v[mk], wells.mu[wells.parent[moon]], tc - self.ep_t[mk])
        self.ep_r[k] = r + sign * rm
        self.ep_v[k] = u + sign * um
        self.ep_t[k] = tc
        self.ep_well[k] = new
        self.ep_chi[k] = 0.0
        self.ep_contact[k] = tc + kepler.time_to_radius(self.ep_r[k], self.ep_v[k], wells.mu[new],
                                                        wells.radius[new], np.inf)[0]

    def _rails(self, sel, wi, x, v, a, thrust, edited, X0, V0, t0, t1, events, look, done=None, crossed=None):
        """Bodies ``sel`` on rails about well ``wi``: their epochs for the step, the surface contacts of
        those whose contacts are not looked for in :meth:`_contacts` (there the colliders meet the
        surface in time order with everything else), and their states about the well at ``t1``
        (before any sphere contact): ``r, u, chi, guess``."""
        wells = self._wells
        mu = wells.mu[wi]
        dt = t1 - t0
        g = slice(None) if sel.size == self._n else sel     # a slice gathers faster than an index
        self._take_epochs(sel, wi, x, v, a, thrust, edited, X0, V0, t0, dt, done)
        plain = sel[self.c_rows[sel] < 0] if look else sel
        if plain.size:
            self._surfaces(plain, wi, t1, events)
        # from the epoch for the whole time since (no error carried from step to step), warm-started
        # from the last step's chi moved on by its Taylor series (kepler.next_chi; the state at the
        # step's start is the last step's result). The guess changes how fast the solver converges,
        # and where only within its few ulp.
        guess = kepler.next_chi(self.ep_chi[g], x[g], v[g], mu, t1 - t0, origin=(X0[wi], V0[wi]))
        if crossed is not None and crossed[g].any():
            guess[crossed[g]] = np.nan                     # (it started the step about another well: no guess)
        r, u, chi = self._epoch(wi, sel, mu).at(t1 - self.ep_t[g], guess)
        return r, u, chi, guess

    def _rails_end(self, sel, wi, r, u, chi, guess, touched, a, thrust, X1, V1, t1, x1, v1):
        """The end-of-step states of bodies ``sel`` about well ``wi``: again from their new epochs where a
        sphere contact ``touched`` them, then thrust's second half kick."""
        mu = self._wells.mu[wi]
        g = slice(None) if sel.size == self._n else sel
        if touched.size:
            mine = touched[np.isin(touched, sel)]
            mine = mine[self.ep_well[mine] == wi]
            if mine.size:
                p = np.searchsorted(sel, mine)
                r[p], u[p], chi[p] = kepler.Epoch(self.ep_r[mine], self.ep_v[mine], mu).at(
                    t1 - self.ep_t[mine], guess[p])
        self.ep_chi[g] = chi
        dt = t1 - self._step[2]
        th = thrust[g]
        if th.any():
            # the second half kick; the state after it is the next step's epoch (taken then, as thrust)
            u[th] += 0.5 * dt * a[sel[th]]
        x1[g] = X1[wi] + r
        v1[g] = V1[wi] + u
        if touched.size:
            # colliders that changed sphere of influence in the contact pass: about their new well
            away = touched[np.isin(touched, sel) & (self.ep_well[touched] != wi)]
            for c in away:
                wj = int(self.ep_well[c])
                rr, uu = kepler.propagate(self.ep_r[c], self.ep_v[c], self._wells.mu[wj], t1 - self.ep_t[c])
                x1[c] = X1[wj] + rr
                v1[c] = V1[wj] + uu + (0.5 * dt * a[c] if thrust[c] else 0.0)
                self.ep_chi[c] = 0.0
        if th.any():
            self.ep_well[sel[th]] = -1

    def _surfaces(self, sel, wi, t1, events):
        """The surface contacts of bodies ``sel`` up to ``t1``, each body's in its own time order."""
        for _ in range(MAX_CONTACTS):
            hit = sel[self.ep_contact[sel] <= t1]
            if not hit.size:
                break
            self._bounce(hit, wi, events)

    def _bounce(self, hit, wi, events):
        """Bodies ``hit`` touch well ``wi``'s surface at their ``ep_contact``: one elastic bounce each."""
        wells = self._wells
        mu, R = wells.mu[wi], wells.radius[wi]
        self._epoch_version += 1
        tc = self.ep_contact[hit]
        rc, uc = kepler.propagate(self.ep_r[hit], self.ep_v[hit], mu, tc - self.ep_t[hit])
        n_hat = rc / np.linalg.norm(rc, axis=1, keepdims=True)
        un = np.einsum("ij,ij->i", uc, n_hat)
        speed = np.linalg.norm(uc, axis=1)
        uc = uc - 2.0 * un[:, None] * n_hat                        # elastic: reverse the radial part
        for j, k in enumerate(hit):
            events.append(SurfaceContact(int(self.ents[k]), wells.ents[wi], float(tc[j]), float(speed[j]),
                                         float(-un[j])))
        self.ep_r[hit], self.ep_v[hit], self.ep_t[hit] = rc, uc, tc
        self.ep_chi[hit] = 0.0
        # the next contact of the new epoch (an outbound body: after its next periapsis dip, if any), on
        # this very conic: time_to_radius takes a body on the surface moving out (no nudge of rc, which
        # moved the conic: 8e-9 s late a bounce on a radial line, the body then 5e-5 m inside, missed next)
        nxt = kepler.time_to_radius(rc, uc, mu, R, np.inf)
        self.ep_contact[hit] = tc + nxt

    # -- sphere-sphere contacts along the conics ------------------------------------------------
    def _near(self, pa, pb, ball, p0, p1, rad, A, rho, span, mu):
        """Which of the candidate pairs ``(pa, pb)`` (movers on rails about one well) are not proven apart
        for the whole step without solving Kepler's equation: the separation ``d(t)`` leaves the chord between its two
        ends by at most ``A_d span^2 / 8``, with ``A_d`` the bound on ``|d''|`` (the sum of the two
        pulls, or the tidal ``2 mu D / (rho - D/2)^3`` for a pair never more than ``D`` apart; see
        kepler.time_to_touch), so a chord that stays farther than that plus ``r_a + r_b`` from zero
        is a pair that cannot touch. Bodies that touch a surface in the step are kept (two conics)."""
        dA = p0[pb] - p0[pa]
        dB = p1[pb] - p1[pa]
        e = dB - dA
        ee = kepler._dot(e, e)
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.clip(np.where(ee > 0, -kepler._dot(dA, e) / ee, 0.0), 0.0, 1.0)
        closest = kepler._norm(dA + f[:, None] * e)
        acc = A[pa] + A[pb]
        D = np.maximum(kepler._norm(dA), kepler._norm(dB)) + 0.125 * acc * span * span
        seg = np.minimum(rho[pa], rho[pb]) - 0.5 * D
        with np.errstate(invalid="ignore", divide="ignore"):
            acc = np.where(seg > 0, np.minimum(acc, 2.0 * mu * D / seg ** 3), acc)
        # (+ the rounding of the states: 1e-12 of their distance from the well, and a micrometre)
        slack = 0.125 * acc * span * span + 1e-12 * (kepler._norm(p0[pa]) + kepler._norm(p0[pb])) + 1e-6
        return (closest - slack <= rad[pa] + rad[pb]) | ball[pa] | ball[pb]

    # -- the movers of the contact pass: colliders on rails (0), on the n-body drift (1), obstacles (2) --
    def _well_at(self, wi, t):
        """Well ``wi``'s centre at absolute times ``t`` ``(n,)`` in the step: positions, velocities (world
        frame). A root well moves straight; a moon on its conic about its parent."""
        X0, V0, t0, _ = self._step
        wells = self._wells
        t = np.asarray(t, dtype=np.float64)
        p = wells.parent[wi]
        if p < 0:
            return X0[wi] + V0[wi] * (t - t0)[:, None], np.broadcast_to(V0[wi], (t.size, 3))
        kk = int(np.flatnonzero(self.well_index == wi)[0])
        r, v = kepler.propagate(np.broadcast_to(self.ep_r[kk], (t.size, 3)), np.broadcast_to(self.ep_v[kk], (t.size, 3)),
                                wells.mu[p], t - self.ep_t[kk])
        P, Vp = self._well_at(int(p), t)
        return P + r, Vp + v

    def _movers_at(self, mv, ms, t):
        """Positions and velocities (world frame) of movers ``ms`` at absolute times ``t``."""
        t0 = self._step[2]
        kind, body, well = mv["kind"][ms], mv["body"][ms], mv["well"][ms]
        pos = np.empty((ms.size, 3))
        vel = np.empty((ms.size, 3))
        line = kind != 0
        if line.any():
            pos[line] = mv["lp"][ms[line]] + mv["lu"][ms[line]] * (t[line] - t0)[:, None]
            vel[line] = mv["lu"][ms[line]]
        for wi in np.unique(well[~line]):
            m = ~line & (well == wi)
            k = body[m]
            r, u = kepler.propagate(self.ep_r[k], self.ep_v[k], self._wells.mu[wi], t[m] - self.ep_t[k])
            P, V = self._well_at(int(wi), t[m])
            pos[m] = P + r
            vel[m] = V + u
        return pos, vel

    def _rail_boxes(self, wi, rad, p0, w0, p1, w1, span, ball):
        """World boxes, bounds ``A`` (on the pull relative to the well) and ``rho`` of colliders of radii
        ``rad`` on rails about well ``wi``, from their states ``p0, w0`` about it at the start of the span
        to ``p1, w1`` at its end: kepler.arc_boxes about the well, then moved into the world frame by the
        box of the well centre's own path over the step (a point for a well at rest)."""
        wells = self._wells
        lo, hi, A, rho = kepler.arc_boxes(p0, w0, p1, w1, span, wells.mu[wi], wells.radius[wi], ball, rad)
        X0, _, t0, t1 = self._step
        a, b = X0[wi], self._X1[wi]
        if np.array_equal(a, b):
            if not a.any():                               # (a well at rest at the origin: the usual case)
                return lo, hi, A, rho
            return lo + a, hi + a, A, rho
        grow = 0.125 * self._wA[wi] * (t1 - t0) ** 2
        return lo + (np.minimum(a, b) - grow), hi + (np.maximum(a, b) + grow), A, rho

    def _contacts(self, ends, nb, line, x, v, a, X0, V0, X1, t0, t1, events):
        """Every sphere contact of the step in time order, exact on each body's path: colliders on
        rails (each on its conic about its well, which may itself move on a conic), n-body colliders
        on the leapfrog's straight drift, and obstacles (straight, inverse mass 0), together with the
        surface contacts of the colliders on rails. Pairs on rails about one well take the conic
        search with the tidal bound (:func:`framework.kepler.time_to_touch`); a collider on rails about
        a root well against a straight path takes it with ``line_b``; every other pair (different wells,
        a moon's frame against a line, two lines) the same conservative advancement on the world-frame
        paths (:func:`framework.kepler.time_to_touch_paths`, the bound on the relative acceleration the
        sum of each body's pull and its well's). Returns the bodies on rails given new epochs, and the
        n-body drift lines after their contacts."""
        self._X1 = X1
        mv = self._movers(ends, nb, line, x, v, a, X0, V0, t0, t1)
        kind, body, well = mv["kind"], mv["body"], mv["well"]
        pairs = _PairTimes(*self._candidates(mv, t1 - t0), t0, mv["kind"].size)
        rails_m = np.flatnonzero(kind == 0)
        xing = self.ep_cross                             # (sphere-of-influence crossings to come, or None)
        if xing is not None and not (xing[body[rails_m]] <= t1).any():
            xing = None
        lines_m = np.flatnonzero(kind == 1)
        nb_surf = np.full(kind.size, np.inf)              # each n-body collider's next surface contact, and where
        nb_well = np.full(kind.size, -1, np.intp)
        if lines_m.size:
            nb_surf[lines_m], nb_well[lines_m] = self._line_surfaces(mv["lp"][lines_m], mv["lu"][lines_m],
                                                                     np.full(lines_m.size, t0), t1)
        if not pairs.pa.size and xing is None and not (nb_surf <= t1).any():   # the usual step: nobody near
            return self._surfaces_of(mv, t1, events), line
        self._nb_surfaces_done = True                    # (their surface contacts are met here, in time order)
        wells = self._wells
        touched = []
        count = np.zeros(mv["kind"].size, np.intp)        # (an obstacle's count stays 0: no cap on it)
        for _ in range(64 + 4 * count.size):
            need = np.flatnonzero(np.isnan(pairs.tc))
            if need.size:
                self._search(mv, need, pairs, t0, t1)
            k = int(np.argmin(pairs.tc)) if pairs.tc.size else -1
            tp = float(pairs.tc[k]) if k >= 0 else np.inf
            surf = self.ep_contact[body[rails_m]]
            ts_min = float(surf.min()) if surf.size else np.inf
            tx = float(xing[body[rails_m]].min()) if xing is not None else np.inf
            tn = float(nb_surf.min())
            if not min(tp, ts_min, tx, tn) <= t1:
                break
            if tn < min(tp, ts_min, tx):
                # an n-body collider meets a well's surface: its drift reflected there (relative to the well)
                moved = np.flatnonzero(nb_surf == tn)
                for m in moved:
                    mv["lp"][m], mv["lu"][m] = self._reflect(body[m], mv["lp"][m], mv["lu"][m], int(nb_well[m]),
                                                             tn, events)
                    mv["after"][m] = tn
                nb_surf[moved], nb_well[moved] = self._line_surfaces(mv["lp"][moved], mv["lu"][moved],
                                                                     np.full(moved.size, tn), t1)
                for m in moved:
                    self._rebox(mv, int(m), tn, t0, t1)
                pairs.renew(moved, tn)
                for c in moved:
                    pairs.add(_overlapping(mv, int(c), pairs), tn)
                continue
            if ts_min < tp and ts_min <= tx:              # surface contacts come first
                hm = rails_m[(surf < tp) & (surf <= t1) & (surf <= tx)]
                for wi in np.unique(well[hm]):
                    self._bounce(body[hm[well[hm] == wi]], int(wi), events)
                touched.append(body[hm])
                if xing is not None:                      # (a new conic: its crossing looked for again)
                    self._recross(body[hm], ts_min, t1)
                # their pairs were followed up to the bounce (their boxes hold both conics): on from there
                pairs.look_again(hm, t1)
                continue
            if tx < tp:
                # bodies that change sphere of influence: a new epoch about the new well at the crossing,
                # then as after a contact (new boxes, their pairs looked at again from there)
                moved = rails_m[xing[body[rails_m]] == tx]
                for m in moved:
                    i = int(body[m])
                    self._epoch_version += 1
                    self._cross(i, int(self.cross_to[i]), tx)
                    well[m] = self.ep_well[i]
                    mv["wA"][m] = self._wA[well[m]]
                    mv["root"][m] = wells.parent[well[m]] < 0
                    touched.append(body[m:m + 1])
                self._recross(body[moved], tx, t1)
                tp, resting = tx, False
            else:
                ia, ib = int(pairs.pa[k]), int(pairs.pb[k])
                resting = self._resolve(mv, ia, ib, tp, t0, t1, events)
                moved = np.array([m for m in (ia, ib) if kind[m] != 2], np.intp)
                count[moved] += 1
                on_rails = moved[kind[moved] == 0]
                touched.append(body[on_rails])
                if xing is not None:
                    self._recross(body[on_rails], tp, t1)
                on_line = moved[kind[moved] == 1]
                if on_line.size:
                    nb_surf[on_line], nb_well[on_line] = self._line_surfaces(mv["lp"][on_line], mv["lu"][on_line],
                                                                             np.full(on_line.size, tp), t1)
            # their paths from tp on: new boxes, their pairs looked at again from tp, and new pairs
            for m in moved:
                self._rebox(mv, int(m), tp, t0, t1)
            pairs.renew(moved, tp)
            if resting:
                # not looked at again this step (the next step resolves it afresh, one impulse per step)
                # instead of a cascade of ever smaller impulses
                pairs.settle(k, t1)
            for c in moved:
                pairs.add(_overlapping(mv, int(c), pairs), tp)
            full = count >= MAX_SPHERE_CONTACTS
            if full.any():
                pairs.drop(full[pairs.pa] | full[pairs.pb], t1)
                self._warn_once("cap", f"gravity: a body met {MAX_SPHERE_CONTACTS} sphere contacts "
                                       "in one step; its further contacts in that step are not resolved")
        else:
            self._warn_once("events", "gravity: too many contacts in one step; the rest of that step's "
                                      "contacts are not resolved")
        return (np.unique(np.concatenate(touched)) if touched else _NO_BODIES), self._lines_after(mv, nb, line, t0)

    def _line_surfaces(self, lp, lu, t_from, t1):
        """The first surface contact of drift lines ``lp + lu (t - t0)`` (n-body bodies, world frame,
        ``(n, 3)``) after ``t_from`` ``(n,)``, by ``t1``: ``(time, well)`` (inf, -1: none). A root well
        moves straight: the closed form of two lines; a moon on its conic: conservative advancement
        (:func:`framework.kepler.time_to_touch_paths`), after a cheap test of how far the gap can close."""
        wells = self._wells
        X0, V0, t0, _ = self._step
        n = lp.shape[0]
        best_t = np.full(n, np.inf)
        best_w = np.full(n, -1, np.intp)
        for wi in range(len(wells)):
            R = wells.radius[wi]
            if wells.parent[wi] < 0:
                d0 = lp + lu * (t_from - t0)[:, None] - (X0[wi] + V0[wi] * (t_from - t0)[:, None])
                w_rel = lu - V0[wi]
                aa = kepler._dot(w_rel, w_rel)
                bb = kepler._dot(d0, w_rel)
                cc = kepler._dot(d0, d0) - R * R
                disc = bb * bb - aa * cc
                with np.errstate(invalid="ignore", divide="ignore"):
                    s = cc / (-bb + np.sqrt(np.maximum(disc, 0.0)))     # the smaller root, without cancelling
                t = t_from + s
                hit = (bb < 0) & (disc >= 0) & (cc > 0) & (t <= t1)
            else:
                X, V = self._well_at(wi, t_from)
                span = np.maximum(t1 - t_from, 0.0)
                near = np.flatnonzero(kepler._norm(lp + lu * (t_from - t0)[:, None] - X) - R
                                      <= (kepler._norm(lu - V) + self._wA[wi] * span) * span)
                t = np.full(n, np.inf)
                if near.size:
                    at_line = lambda i, tt: (lp[near[i]] + lu[near[i]] * (tt - t0)[:, None], lu[near[i]])  # noqa: E731
                    at_moon = lambda i, tt: self._well_at(wi, tt)                                          # noqa: E731
                    t[near], _ = kepler.time_to_touch_paths(at_line, at_moon, np.full(near.size, R), t_from[near],
                                                            np.full(near.size, t1), np.full(near.size, self._wA[wi]))
                hit = np.isfinite(t)
            better = hit & (t < best_t)
            best_t[better] = t[better]
            best_w[better] = wi
        return best_t, best_w

    def _reflect(self, k, p, u, wi, tc, events):
        """n-body body ``self.ents[k]`` on the line ``p + u (t - t0)`` meets well ``wi``'s surface at
        ``tc``: its velocity relative to the well reflected about the normal (elastic); returns the line
        through the contact from then on, ``(p, u)``."""
        t0 = self._step[2]
        xc = p + u * (tc - t0)
        Xc, Vc = self._well_at(wi, np.array([tc]))
        n_hat = (xc - Xc[0]) / np.linalg.norm(xc - Xc[0])
        w_rel = u - Vc[0]
        un = float(w_rel @ n_hat)
        events.append(SurfaceContact(int(self.ents[k]), self._wells.ents[wi], float(tc),
                                     float(np.linalg.norm(w_rel)), -un))
        u_new = w_rel - 2.0 * un * n_hat + Vc[0]
        return xc - u_new * (tc - t0), u_new

    def _movers(self, ends, nb, line, x, v, a, X0, V0, t0, t1):
        """The contact pass's movers, as columns of one dict: ``kind`` (0 rails, 1 n-body line,
        2 obstacle), ``body`` (index into this system's bodies, or the obstacle's), ``well`` (rails: its
        well, else -1), ``rad``; lines' ``lp, lu`` (world position at the step's start, velocity);
        world boxes ``lo, hi`` over the step; the pull bound ``A`` and distance bound ``rho`` about the
        well and the well centre's own acceleration bound ``wA`` (rails; 0 on a line), ``root`` (rails
        about a root well); ``P0, P1, ball`` (rails: the states about the well at the span's ends, and
        whether its box is the cube it can reach) for the pruning; ``after`` (a line's last contact);
        ``groups``: the rails movers' slices, one per well (rails movers first, then lines)."""
        span = t1 - t0
        col = self.world.table(SphereCollider).data
        kinds, bodies, wells_of, rads = [], [], [], []
        p0s, p1s, w0s, w1s, balls = [], [], [], [], []
        for wi, (sel, r1, u1, _, _) in ends.items():
            is_c = self.c_rows[sel] >= 0
            if is_c.all():                                # (every body a collider, the usual swarm: slices)
                cs, pc = sel, slice(None)
                g = slice(None) if sel.size == self._n else sel
            else:
                cs = sel[is_c]
                if not cs.size:
                    continue
                pc = np.flatnonzero(is_c)
                g = cs
            p0 = x[g] - X0[wi]
            w0 = v[g] - V0[wi]
            if a.any():
                w0 += 0.5 * span * a[g]                   # (thrust: after the first half kick)
            late = self.ep_t[g] > t0
            if late.any():
                # bodies that came into this well's sphere in the step: on its conic from then on, boxed as
                # the sphere they can reach from there (their path before was about another well)
                p0[late] = self.ep_r[cs[late]]
                w0[late] = self.ep_v[cs[late]]
            kinds.append(np.zeros(cs.size, np.intp))
            bodies.append(cs)
            wells_of.append(np.full(cs.size, wi, np.intp))
            rads.append(col["radius"][self.c_rows[g]].astype(np.float64))
            p0s.append(p0)
            w0s.append(w0)
            p1s.append(r1[pc])
            w1s.append(u1[pc])
            balls.append((self.ep_contact[g] <= t1) | late)
        n_rail = sum(b.size for b in bodies)
        lp, lu = [], []
        if line is not None:
            p, u, _ = line
            k = np.flatnonzero(self.nb_c_rows[nb] >= 0)
            if k.size:
                kinds.append(np.ones(k.size, np.intp))
                bodies.append(nb[k])
                wells_of.append(np.full(k.size, -1, np.intp))
                rads.append(col["radius"][self.nb_c_rows[nb[k]]].astype(np.float64))
                lp.append(p[k])
                lu.append(u[k])
        if self._n_ob:
            kinds.append(np.full(self._n_ob, 2, np.intp))
            bodies.append(np.arange(self._n_ob))
            wells_of.append(np.full(self._n_ob, -1, np.intp))
            rads.append(col["radius"][self.ob_c_rows].astype(np.float64))
            lp.append(self._ob_x)
            lu.append(self._ob_v)
        one = len(kinds) == 1
        cat = (lambda parts: parts[0]) if one else np.concatenate            # noqa: E731
        mv = {"kind": cat(kinds), "body": cat(bodies), "well": cat(wells_of), "rad": cat(rads),
              "lp": np.concatenate([np.zeros((n_rail, 3))] + lp) if lp else None,
              "lu": np.concatenate([np.zeros((n_rail, 3))] + lu) if lu else None}
        M = mv["kind"].size
        kind, well, rad = mv["kind"], mv["well"], mv["rad"]
        groups, at = [], 0
        for p0 in p0s:
            groups.append((int(well[at]), slice(at, at + p0.shape[0])))
            at += p0.shape[0]
        mv["groups"] = groups
        if one and n_rail:                                # (one well's colliders and nothing else: no copies)
            wi = groups[0][0]
            mv["lo"], mv["hi"], mv["A"], mv["rho"] = self._rail_boxes(wi, rad, p0s[0], w0s[0], p1s[0], w1s[0],
                                                                      span, balls[0])
            mv["P0"], mv["P1"], mv["ball"] = p0s[0], p1s[0], balls[0]
            mv["wA"] = np.full(M, self._wA[wi])
            mv["root"] = np.full(M, self._wells.parent[wi] < 0)
        else:
            lo, hi = np.empty((M, 3)), np.empty((M, 3))
            mv["A"], mv["rho"] = np.zeros(M), np.zeros(M)         # 0 on a line
            mv["P0"], mv["P1"], mv["ball"] = np.zeros((M, 3)), np.zeros((M, 3)), np.zeros(M, bool)
            for k, (wi, ms) in enumerate(groups):
                lo[ms], hi[ms], mv["A"][ms], mv["rho"][ms] = self._rail_boxes(wi, rad[ms], p0s[k], w0s[k], p1s[k],
                                                                              w1s[k], span, balls[k])
                mv["P0"][ms], mv["P1"][ms], mv["ball"][ms] = p0s[k], p1s[k], balls[k]
            lines = np.flatnonzero(kind != 0)
            if lines.size:
                q0 = mv["lp"][lines]
                q1 = q0 + mv["lu"][lines] * span
                lo[lines] = np.minimum(q0, q1) - rad[lines, None]
                hi[lines] = np.maximum(q0, q1) + rad[lines, None]
            mv["lo"], mv["hi"] = lo, hi
            mv["wA"] = np.where(kind == 0, self._wA[np.maximum(well, 0)], 0.0)
            mv["root"] = np.where(kind == 0, self._wells.parent[np.maximum(well, 0)] < 0, False)
        mv["after"] = np.full(M, -np.inf)
        return mv

    def _candidates(self, mv, span):
        """The pairs of movers whose boxes meet (``i < j``: a rails mover before a line), less obstacle
        pairs and the pairs on rails about one well whose chords prove them apart (``_near``)."""
        kind, well = mv["kind"], mv["well"]
        lo, hi = mv["lo"], mv["hi"]
        pa, pb = bp.box_pairs(lo, hi, _broad_method(lo, hi))
        pa, pb = pa.astype(np.intp), pb.astype(np.intp)
        if self._n_ob > 1:
            keep = ~((kind[pa] == 2) & (kind[pb] == 2))  # obstacle with obstacle: not ours
            pa, pb = pa[keep], pb[keep]
        mu = self._wells.mu
        near = lambda i, j, wi: self._near(i, j, mv["ball"], mv["P0"], mv["P1"], mv["rad"], mv["A"],  # noqa: E731
                                           mv["rho"], span, mu[wi])
        groups = mv["groups"]
        if len(groups) == 1 and groups[0][1].stop == kind.size:      # (all on rails about one well)
            keep = near(pa, pb, groups[0][0])
            return pa[keep], pb[keep]
        same = (kind[pa] == 0) & (kind[pb] == 0) & (well[pa] == well[pb])
        if same.any():
            keep = np.ones(pa.size, bool)
            for wi in np.unique(well[pa[same]]):
                m = np.flatnonzero(same & (well[pa] == wi))
                keep[m] = near(pa[m], pb[m], int(wi))
            pa, pb = pa[keep], pb[keep]
        return pa, pb

    def _surfaces_of(self, mv, t1, events):
        """No pair near: only the rails movers' surface contacts, well by well. Returns those that bounced."""
        moved = []
        for wi, ms in mv["groups"]:
            cs = mv["body"][ms]
            if (self.ep_contact[cs] <= t1).any():
                hit0 = self.ep_t[cs].copy()
                self._surfaces(cs, wi, t1, events)
                moved.append(cs[self.ep_t[cs] != hit0])
        return np.concatenate(moved) if moved else _NO_BODIES

    def _rebox(self, mv, m, tp, t0, t1):
        """Mover ``m`` is on a new path from ``tp``: its box (and bounds) from there to ``t1``."""
        if mv["kind"][m] == 0:
            i = mv["body"][m]
            wi = int(mv["well"][m])
            pe, we = kepler.propagate(self.ep_r[i:i + 1], self.ep_v[i:i + 1], self._wells.mu[wi], t1 - self.ep_t[i])
            ms = np.array([m])
            mv["lo"][ms], mv["hi"][ms], mv["A"][ms], mv["rho"][ms] = self._rail_boxes(
                wi, mv["rad"][ms], self.ep_r[i:i + 1], self.ep_v[i:i + 1], pe, we, t1 - tp,
                np.array([self.ep_contact[i] <= t1]))
        else:
            q0 = mv["lp"][m] + mv["lu"][m] * (tp - t0)
            q1 = mv["lp"][m] + mv["lu"][m] * (t1 - t0)
            mv["lo"][m] = np.minimum(q0, q1) - mv["rad"][m]
            mv["hi"][m] = np.maximum(q0, q1) + mv["rad"][m]

    def _lines_after(self, mv, nb, line, t0):
        """The n-body drift lines after the pass: ``(p, u, since)``, ``since`` each body's last contact in
        the step (s from its start; -inf: none)."""
        if line is None:
            return None
        k = np.flatnonzero(self.nb_c_rows[nb] >= 0)
        if not k.size:
            return line
        ms = np.flatnonzero(mv["kind"] == 1)
        p, u = line[0].copy(), line[1].copy()
        p[k], u[k] = mv["lp"][ms], mv["lu"][ms]
        since = np.full(nb.size, -np.inf)
        since[k] = mv["after"][ms] - t0
        return p, u, since

    def _recross(self, ks, t_from, t1):
        """Bodies ``ks`` on rails are on a new conic from ``t_from``: their next sphere-of-influence
        crossing in the step."""
        if self.ep_cross is None or not len(ks):
            return
        ks = np.asarray(ks, np.intp)
        t, w = self._next_crossing(ks, np.full(ks.size, float(t_from)), t1)
        self.ep_cross[ks] = t
        self.cross_to[ks] = w

    def _search(self, mv, need, pairs, t0, t1):
        """The contact times of pairs ``need`` (from what each is known to be apart, ``pairs.ts``)."""
        wells = self._wells
        kind, body, well, rad = mv["kind"], mv["body"], mv["well"], mv["rad"]
        A, rho, wA, root, after = mv["A"], mv["rho"], mv["wA"], mv["root"], mv["after"]
        ts, tc = pairs.ts, pairs.tc
        ia, ib = pairs.pa[need], pairs.pb[need]
        ka, kb = body[ia], body[ib]
        ra, rb = kind[ia] == 0, kind[ib] == 0
        # a pair is followed up to the first surface contact of a body on rails in it (its path changes
        # there), and from its last contact (a rails body's epoch, a line's last contact)
        upto = np.minimum(t1, np.minimum(np.where(ra, self.ep_contact[ka], np.inf),
                                         np.where(rb, self.ep_contact[kb], np.inf)))
        if self.ep_cross is not None:                     # (and up to a change of sphere of influence)
            upto = np.minimum(upto, np.minimum(np.where(ra, self.ep_cross[ka], np.inf),
                                               np.where(rb, self.ep_cross[kb], np.inf)))
        start = np.maximum(ts[need], np.maximum(np.where(ra, self.ep_t[ka], t0), np.where(rb, self.ep_t[kb], t0)))
        start = np.maximum(start, np.maximum(after[ia], after[ib]))
        reach = rad[ia] + rad[ib]
        t = np.full(need.size, np.inf)
        stuck = np.zeros(need.size, bool)
        same = ra & rb & (well[ia] == well[ib])
        line = ra & ~rb & root[ia]
        for wi in np.unique(well[ia[same]]):
            m = np.flatnonzero(same & (well[ia] == wi))
            t[m], stuck[m] = kepler.time_to_touch(
                self.ep_r[ka[m]], self.ep_v[ka[m]], self.ep_t[ka[m]], self.ep_r[kb[m]], self.ep_v[kb[m]],
                self.ep_t[kb[m]], wells.mu[wi], reach[m], start[m], upto[m], A[ia[m]] + A[ib[m]],
                np.minimum(rho[ia[m]], rho[ib[m]]))
        X0, V0, _, _ = self._step
        for wi in np.unique(well[ia[line]]):
            m = np.flatnonzero(line & (well[ia] == wi))
            q0 = mv["lp"][ib[m]] - X0[wi]                  # the line relative to the (straight-moving) root
            qv = mv["lu"][ib[m]] - V0[wi]
            t[m], stuck[m] = kepler.time_to_touch(
                self.ep_r[ka[m]], self.ep_v[ka[m]], self.ep_t[ka[m]], q0, qv, t0, wells.mu[wi], reach[m],
                start[m], upto[m], A[ia[m]], line_b=True)
        gen = np.flatnonzero(~same & ~line)
        if gen.size:
            ga, gb = ia[gen], ib[gen]
            t[gen], stuck[gen] = kepler.time_to_touch_paths(
                lambda i, tt: self._movers_at(mv, ga[i], tt), lambda i, tt: self._movers_at(mv, gb[i], tt),
                reach[gen], start[gen], upto[gen], A[ga] + wA[ga] + A[gb] + wA[gb])
        _settle(tc, ts, need, t, start, upto)
        if stuck.any():
            m = int(np.flatnonzero(stuck)[0])
            self._warn_once("graze", f"gravity: {self._mover_name(mv, ia[m])} and {self._mover_name(mv, ib[m])} "
                                     "graze too slowly to converge; their contact (if any) in this step is not "
                                     "resolved")

    def _mover_mass_rest(self, mv, ms):
        """Inverse masses (1/kg: Mass, 1 kg without; an obstacle's 0) and restitutions of movers ``ms``."""
        world = self.world
        kg_t = world.table(Mass).data["kg"]
        col = world.table(SphereCollider).data["restitution"]
        inv, rest = np.zeros(ms.size), np.zeros(ms.size)
        for j, m in enumerate(ms):
            k = mv["body"][m]
            if mv["kind"][m] == 2:
                rest[j] = col[self.ob_c_rows[k]]
                continue
            rest[j] = col[self.c_rows[k] if mv["kind"][m] == 0 else self.nb_c_rows[k]]
            inv[j] = 1.0 / (kg_t[self.m_rows[k]] if self.m_rows[k] >= 0 else 1.0)
        return inv, rest

    def _mover_name(self, mv, m):
        k = mv["body"][m]
        if mv["kind"][m] == 2:
            return f"obstacle {int(self.ob_ents[k])}"
        return f"body {int(self.ents[k])}"

    def _resolve(self, mv, ia, ib, tp, t0, t1, events):
        """Movers ``ia`` and ``ib`` touch at ``tp``: the impulse, their new paths, the event. Returns
        whether the contact is resting (the pair separates slower than the pulls on it can undo within
        the step: not looked at again in this step)."""
        kind, body, well, rad = mv["kind"], mv["body"], mv["well"], mv["rad"]
        A, rho, wA = mv["A"], mv["rho"], mv["wA"]
        if kind[ia] == 0 and kind[ib] == 0 and well[ia] == well[ib]:
            wi = int(well[ia])
            sep = self._collide(int(body[ia]), int(body[ib]), wi, tp, t0, events)
            # a resting contact (e = 0, or a slow one): separating slower than the tidal pull between them
            reach = rad[ia] + rad[ib]
            seg = min(rho[ia], rho[ib]) - reach
            return bool(seg > 0 and sep < 2.0 * self._wells.mu[wi] * 2.0 * reach / seg ** 3 * (t1 - tp))
        return self._collide_paths(mv, ia, ib, tp, A[ia] + wA[ia] + A[ib] + wA[ib], t0, t1, events)

    def _collide_paths(self, mv, ia, ib, tp, accel, t0, t1, events):
        """Any pair but two bodies on rails about one well touches at ``tp``: the impulse along the line
        of centres in the world frame (masses from Mass, 1 kg without; an obstacle's inverse mass 0, so
        its velocity is left alone; restitution the smaller of the two), a new epoch about its well for
        a body on rails, a new drift line for an n-body body, and the CollisionEvent
        (``method="kepler"`` where a body on rails is in it, else ``"leapfrog"``). Returns whether the
        contact is resting.

        A slow contact against an obstacle (separating slower than ``accel (t1 - tp) / 2``, ``accel`` the
        bound on the pair's relative acceleration: restitution 0, or a body pressed on by a well's pull)
        leaves at that speed, the least that keeps the gap ``g >= s tau - accel tau^2 / 2`` open up to
        ``t1``: the obstacle feels none of the pull, so a body left at rest on it would sink by
        ``accel dt^2 / 2`` a step and, step after step, pass through it. The cost is a hop of at most
        ``accel dt^2 / 8``, only in such slow contacts. Between two bodies such a contact is resting."""
        kind, body, well = mv["kind"], mv["body"], mv["well"]
        ms = np.array([ia, ib])
        pos, vel = self._movers_at(mv, ms, np.full(2, tp))
        d = pos[1] - pos[0]
        nrm = d / np.linalg.norm(d)
        vn = float((vel[1] - vel[0]) @ nrm)                # < 0: approaching (the search finds only those)
        inv, rest = self._mover_mass_rest(mv, ms)
        e = float(rest.min())
        fixed = bool((inv == 0).any())
        keep_out = 0.5 * accel * (t1 - tp)
        if vn < 0 and inv.sum() > 0:
            sep = max(-e * vn, keep_out) if fixed else -e * vn
            impulse = (sep - vn) / (inv[0] + inv[1])
        else:
            impulse = 0.0
        vel[0] -= impulse * inv[0] * nrm
        vel[1] += impulse * inv[1] * nrm
        wells = self._wells
        for j, m in enumerate(ms):
            k = body[m]
            if kind[m] == 0:
                wi = int(well[m])
                W, Wv = self._well_at(wi, np.array([tp]))
                self._epoch_version += 1
                self.ep_r[k] = pos[j] - W[0]
                self.ep_v[k] = vel[j] - Wv[0]
                self.ep_t[k] = tp
                self.ep_chi[k] = 0.0
                self.ep_contact[k] = tp + kepler.time_to_radius(self.ep_r[k], self.ep_v[k], wells.mu[wi],
                                                                wells.radius[wi], np.inf)[0]
            elif kind[m] == 1:
                mv["lp"][m] = pos[j] - vel[j] * (tp - t0)   # the line through the contact, as of t0
                mv["lu"][m] = vel[j]
                mv["after"][m] = tp
        ents = [int(self.ob_ents[body[m]]) if kind[m] == 2 else int(self.ents[body[m]]) for m in ms]
        first = 0 if ents[0] < ents[1] else 1
        n_ab = nrm if first == 0 else -nrm
        point = pos[first] + float(mv["rad"][ms[first]]) * n_ab
        method = "kepler" if (kind[ms] == 0).any() else "leapfrog"
        events.append(CollisionEvent(min(ents), max(ents), float(tp), float(tp - t0),
                                     tuple(float(c) for c in point), tuple(float(c) for c in n_ab),
                                     float(impulse), method=method, step=self.world.step_count))
        sep_now = float((vel[1] - vel[0]) @ nrm)
        return not fixed and sep_now < keep_out * 2.0

    def _collide(self, i, j, wi, tc, t0, events):
        """Bodies ``i`` and ``j`` touch at ``tc``: the impulse along the line of centres (masses from
        Mass, 1 kg without; restitution the smaller of the two), new epochs for both at ``tc``, their
        next surface contacts, the CollisionEvent. Returns their separating speed along the normal after
        the impulse."""
        world = self.world
        wells = self._wells
        mu, R = wells.mu[wi], wells.radius[wi]
        k = np.array([i, j])
        rc, uc = kepler.propagate(self.ep_r[k], self.ep_v[k], mu, tc - self.ep_t[k])
        d = rc[1] - rc[0]
        nrm = d / np.linalg.norm(d)
        vn = float((uc[1] - uc[0]) @ nrm)                  # < 0: approaching (the search finds only those)
        kg = np.where(self.m_rows[k] >= 0, world.table(Mass).data["kg"][np.maximum(self.m_rows[k], 0)], 1.0)
        with np.errstate(divide="ignore"):
            inv = 1.0 / kg
        rest = world.table(SphereCollider).data["restitution"][self.c_rows[k]]
        e = float(min(rest[0], rest[1]))
        impulse = -(1.0 + e) * vn / (inv[0] + inv[1]) if vn < 0 and inv.sum() > 0 else 0.0
        uc[0] -= impulse * inv[0] * nrm
        uc[1] += impulse * inv[1] * nrm
        self._epoch_version += 1
        self.ep_r[k], self.ep_v[k], self.ep_t[k] = rc, uc, tc
        self.ep_chi[k] = 0.0
        self.ep_contact[k] = tc + kepler.time_to_radius(rc, uc, mu, R, np.inf)
        # the event in the world frame, named as the collision system names it (lower entity first)
        well = self._well_at(wi, np.array([tc]))[0][0]
        radius = world.table(SphereCollider).data["radius"][self.c_rows[k]]
        ea, eb = int(self.ents[i]), int(self.ents[j])
        first = 0 if ea < eb else 1
        n_ab = nrm if first == 0 else -nrm
        point = well + rc[first] + float(radius[first]) * n_ab
        events.append(CollisionEvent(min(ea, eb), max(ea, eb), float(tc), float(tc - t0),
                                     tuple(float(c) for c in point), tuple(float(c) for c in n_ab),
                                     float(impulse), method="kepler", step=world.step_count))
        return float((uc[1] - uc[0]) @ nrm)

    def _warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            warnings.warn(text, RuntimeWarning, stacklevel=4)

    def _epoch(self, wi, sel, mu) -> kepler.Epoch:
        """The epochs of bodies ``sel`` about well ``wi`` as a kepler.Epoch, kept while none changes
        (what depends only on the epoch state is then derived once, not every step)."""
        key = (wi, self._epoch_version, sel.size)
        cached = self._epochs.get(wi)
        # (the same epochs and as many bodies: the same bodies unless the split between wells changed,
        # which is compared; every body about the one well, the usual case, needs no comparison)
        if cached is not None and cached[0] == key and (sel.size == self._n or np.array_equal(cached[1], sel)):
            return cached[2]
        ep = kepler.Epoch(self.ep_r[sel], self.ep_v[sel], mu)
        self._epochs[wi] = (key, sel.copy(), ep)
        return ep

    def _accel(self, pos, X, gm):
        """Pull of every well at positions ``pos`` and of the n-body bodies on each other (``G m``)."""
        w = self._wells
        acc = np.zeros_like(pos)
        for wi in range(len(X)):
            d = pos - X[wi]
            r2 = np.einsum("ij,ij->i", d, d)
            acc -= (w.mu[wi] / (r2 * np.sqrt(r2)))[:, None] * d
        if len(pos) > 1:
            d = pos[:, None, :] - pos[None, :, :]
            r2 = np.einsum("ijk,ijk->ij", d, d)
            np.fill_diagonal(r2, np.inf)
            acc -= np.einsum("ij,ijk->ik", gm[None, :] / (r2 * np.sqrt(r2)), d)
        return acc

    def _kick(self, sel, x, v, a, X0, dt):
        """The n-body bodies' first half kick: their straight drift over the step, ``p + u t`` (t from the
        step's start), and each body's last contact time in the step (-inf: none)."""
        p = x[sel]
        u = v[sel] + 0.5 * dt * (self._accel(p, X0, self.gm[sel]) + a[sel])
        return p, u, np.full(sel.size, -np.inf)

    def _leapfrog_end(self, sel, line, a, X0, X1, dt, t0, x1, v1, events):
        """The rest of the n-body step: the drift (met by the sphere contacts in :meth:`_contacts`, so
        each body is on the line ``p + u t`` from its last contact on) against each well's surface (the
        colliders' met there already, when the contact pass ran), then the second half kick."""
        gm = self.gm[sel]
        p, u, after = line
        p, u = p.copy(), u.copy()
        todo = np.arange(sel.size)
        if self._nb_surfaces_done:
            todo = todo[self.nb_c_rows[sel] < 0]
        if todo.size:
            t_hit, w_hit = self._line_surfaces(p[todo], u[todo], t0 + np.maximum(after[todo], 0.0), t0 + dt)
            for j in np.flatnonzero(np.isfinite(t_hit)):
                k = todo[j]
                p[k], u[k] = self._reflect(sel[k], p[k], u[k], int(w_hit[j]), float(t_hit[j]), events)
        q = p + u * dt
        u = u + 0.5 * dt * (self._accel(q, X1, gm) + a[sel])
        x1[sel] = q
        v1[sel] = u
