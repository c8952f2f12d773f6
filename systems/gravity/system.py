"""The gravity system: gathers the wells and bodies, runs each step's stages (crossings, rails, n-body,
contacts) and writes its bodies' end of the step into the step context. See :mod:`driftframe.systems.gravity`."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import warnings

import esper
import numpy as np

from driftframe.components.body import Acceleration, Mass, Transform, Velocity
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.components.gravity import G, GravityWell, NBody, Orbiting, SurfaceContact
from driftframe.framework import kepler
from driftframe.framework.orbit_state import OrbitState
from driftframe.framework.step import StepContext
from driftframe.framework.store import as_index, to_indices
from driftframe.systems.gravity.contacts import _NO_BODIES, SphereContacts
from driftframe.systems.gravity.context import GravityStep, PassResult, RailsEnd
from driftframe.systems.gravity.crossings import Crossings
from driftframe.systems.gravity.lookahead import GravityOrbits, LookAhead, _Kept
from driftframe.systems.gravity.movers import ContactMovers
from driftframe.systems.gravity.nbody import NBodyFlight
from driftframe.systems.gravity.rails import Rails
from driftframe.systems.gravity.wells import WellPaths, _dominant, _Wells

if TYPE_CHECKING:
    from driftframe.framework.world import World


class _Carried(NamedTuple):
    """The bodies' epochs kept across a rebuild of the scene or a load: the wells they were about (in
    depth order), the bodies (entity ids) and the epoch arrays by name (:data:`GravitySystem._EPOCH`)."""

    wells: list
    bodies: np.ndarray
    epochs: dict


class GravitySystem(LookAhead, SphereContacts, ContactMovers, Crossings, Rails, NBodyFlight, WellPaths,
                    esper.Processor):
    """Reads GravityWell, Transform, Velocity, Acceleration, Mass, NBody, SphereCollider; writes the step
    context (its bodies' end of the step), Orbiting, the OrbitState resource; appends SurfaceContact and
    CollisionEvent to world.events.  Gravity: on rails (exact Kepler from an epoch, with the sphere contacts
    of the bodies on rails) or kick-drift-kick (n-body).

    Added to a world, it publishes what it knows of the orbits there, ``world.resources[OrbitState]``
    (:mod:`driftframe.framework.orbit_state`: the well a body moves about, the next contacts), for the
    systems that need it (flight aids, the warp governor, the orbit readouts), which read the resource
    and never this system."""

    stage = "movement"
    name = "gravity"
    reads = (GravityWell, Transform, Velocity, Acceleration, Mass, NBody, Orbiting, SphereCollider)
    writes = (StepContext, Orbiting, SurfaceContact, CollisionEvent, OrbitState)
    #: A save does not hold the OrbitState: the rebuilt world's gravity system publishes its own.
    rebuilt_resources = (OrbitState,)
    #: after the movement system's prediction, in whatever order the two were added: this system's end
    #: of the step replaces the prediction of its bodies
    after = ("movement",)

    @property
    def requires(self) -> tuple[type, ...]:
        """Nothing to do without a well or an NBody body; while it holds bodies it runs, to hand them back
        to movement when the last well goes (see :meth:`World.add_system`). (Read once per structure
        epoch: the NBody look-up is esper's cached query.)"""
        if self._wells is not None or esper.get_component(NBody):
            return ()
        return (GravityWell, Transform)

    def __init__(self) -> None:
        self._world: World | None = None
        self._orbits = GravityOrbits(self)
        self._wells = None
        self._n = 0
        self._n_nb = 0
        self._epoch_version = 0
        self._lookahead: _Kept | None = None              # (the last look at the pairs on rails)
        self._epochs: dict = {}
        self._n_col = 0
        self._n_nb_col = 0
        self._n_ob = 0                                    # colliders gravity does not move (obstacles)
        self._spheres_may_meet = False                    # a contact pass this step (2 colliders, or 1 and an obstacle)
        self._ob_version = None
        self._warned: set = set()
        self._last_step: GravityStep | None = None       # (the look-ahead evaluates from the last step)
        self.lookahead_is_bound = False

    @property
    def world(self) -> World:
        """The world this system is in (set by :meth:`World.add_system`)."""
        if self._world is None:
            raise AttributeError("GravitySystem: not in a world yet (World.add_system puts it in one)")
        return self._world

    @world.setter
    def world(self, world: World) -> None:
        # joining a world publishes the orbits there: the flight aids read them before this system's first step
        self._world = world
        world.resources[OrbitState] = self._orbits

    def release(self) -> None:
        """Taken out of its world (:meth:`World.remove_system`, :meth:`World.close`): its OrbitState goes too."""
        if self._world is not None and self._world.resources.get(OrbitState) is self._orbits:
            del self._world.resources[OrbitState]

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
        self._has_a = np.flatnonzero(self.a_rows >= 0)    # (the bodies with an Acceleration)
        self.gm = G * kg[keep]
        self.m_rows = m_rows[keep]
        n = self._n = len(self.ents)
        nb = world.query(NBody)
        nb.refresh()
        self.nbody = np.isin(self.ents, nb.entities)
        self._n_nb = int(np.count_nonzero(self.nbody))
        # a step's thrust and edits where there are none (read-only: the stages only read them)
        self._no_a, self._none = np.zeros((n, 3)), np.zeros(n, bool)
        self._no_a.flags.writeable = self._none.flags.writeable = False
        self._every = np.arange(n)                         # (every body: the one well's, in a quiet step)
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
        # the step's end states are written into these, which then swap with last_x, last_v: no (n, 3) array
        # is made and freed each step (at 10,000 bodies each costs its page faults again, ~1 ns a body)
        self._x1_next = np.empty((n, 3))
        self._v1_next = np.empty((n, 3))
        # the quiet step from the tables (Rails._quiet_from_tables): row numbers as arrays, and two sets of
        # its start states (bodies' x, v and the well's), one for this step and one kept as the last step's
        self._t_idx = to_indices(self.t_rows).astype(np.int64)
        self._v_idx = to_indices(self.v_rows).astype(np.int64)
        self._quiet_bufs = [(np.empty((n, 3)), np.empty((n, 3)), np.empty((4, 3))) for _ in range(2)]
        self._quiet_flip = 0
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

    def _carry(self) -> _Carried:
        return _Carried(list(self._wells.ents), self.ents.copy(), {k: getattr(self, k) for k in self._EPOCH})

    def _restore(self, old: _Carried) -> None:
        """The epochs of the bodies of ``old`` that are still here (the wells are the same)."""
        ents, arrays = old.bodies, old.epochs
        if not len(ents) or not self._n:
            return
        common, new_i, old_i = np.intersect1d(self.ents, ents, assume_unique=True, return_indices=True)
        for k, arr in arrays.items():
            getattr(self, k)[new_i] = arr[old_i]

    def state(self) -> dict[str, Any] | None:
        """What a save keeps of this system (see framework/save.py): each body's epoch on rails (the
        state its conic is evaluated from) and what it last wrote, by entity; None before the first step."""
        saved = getattr(self, "_saved", None)
        if self._wells is None and saved is None:
            return None
        wells, ents, arrays = self._carry() if self._wells is not None else saved   # (a load not stepped yet)
        return {"wells": [int(e) for e in wells], "bodies": [int(e) for e in ents],
                "epochs": {k: v.copy() for k, v in arrays.items()}}

    def restore(self, state: dict[str, Any] | None) -> None:
        """Take back :meth:`state` (a load): the bodies are gathered again at the next step and take
        their saved epochs (bodies about other wells than saved start new ones)."""
        self._wells = None
        self._saved = None if state is None else _Carried(state["wells"], np.asarray(state["bodies"], np.int64),
                                                          dict(state["epochs"]))

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
            if old is not None and old.wells == self._wells.ents:
                self._restore(old)
            self._epoch_version += 1
            wq.refresh()                                  # Orbiting may have been added: new lists
            bq.refresh()
            self._ob_version = None
        oq = world.query(Transform, SphereCollider, optional=(Velocity,))
        if oq.refresh() or self._ob_version is None:
            self._build_obstacles(oq)
        if not self._n:
            return
        # sphere contacts are looked for where two or more colliders move, or one and an obstacle
        movers = self._n_col + self._n_nb_col
        look = movers >= 2 or (movers and self._n_ob)
        self._spheres_may_meet = bool(look)               # (else an n-body collider may drift on its conic)
        step = None if look else self._quiet_from_tables(dt)
        written = step is not None                        # (its end states are in the step context already)
        if step is None:
            step = self._begin(dt)
            if look or not self._quiet(step):
                self._stages(step, look)
        self._last_step = step                            # (the look-ahead evaluates from the last step)
        if not written:
            ctx = world.step_context
            ctx.begin(world.step_count, dt, world.table(Transform), world.table(Velocity))
            ctx.position[self.t_rows] = step.x1
            ctx.velocity[self.v_rows] = step.v1
        self.last_x, self._x1_next = step.x1, self.last_x
        self.last_v, self._v1_next = step.v1, self.last_v
        for ev in step.events:
            world.emit(ev)

    def _stages(self, step: GravityStep, look: bool) -> None:
        """The step's stages: crossings, rails, n-body, the contact pass, into ``step.x1, step.v1``."""
        n, W, wells = self._n, len(self._wells), self._wells
        dom = _dominant(wells, step.x, step.X0, self.moon_parent) if W > 1 else np.zeros(n, np.intp)
        rails = ~self.nbody
        nb = np.flatnonzero(self.nbody)
        done = crossed = None
        if W > 1 and (wells.parent >= 0).any():
            # bodies that enter or leave a moon's sphere of influence do so at the exact time in the step
            done, crossed = self._crossings(step, rails, dom, defer=(self.c_rows >= 0) if look else None)
        else:
            self.ep_cross = None
        ends: dict[int, RailsEnd] = {}
        for wi in range(W):                               # parents first: a moon is placed before its bodies
            sel = np.flatnonzero(rails & (dom == wi))
            if sel.size:
                ends[wi] = self._rails(step, sel, wi, look, done, crossed)
            # wells whose parent is wi: their state at t1 is now known (a moon is never touched by a
            # sphere contact: it is a well)
            for wj in np.flatnonzero(wells.parent == wi):
                self._place_moon(step, int(wj), ends[wi])
        drift = self._kick(step, nb) if nb.size else None
        passed = PassResult(_NO_BODIES, drift, False)
        if look:
            # every sphere contact of the step, in time order: on rails, on the n-body drift, obstacles
            passed = self._contacts(step, ends, nb, drift)
        for wi, end in ends.items():
            self._rails_end(step, wi, end, passed.touched)
        if nb.size:
            self._leapfrog_end(step, nb, passed.drift, passed.surfaces_met)

    def _begin(self, dt: float) -> GravityStep:
        """The step's context: its times as given, the wells' and the bodies' states at its start."""
        world = self.world
        n, wells = self._n, self._wells
        pos_t = world.table(Transform).data["position"]
        vel_t = world.table(Velocity).data["linear"]
        x = pos_t[self.t_rows]
        v = vel_t[self.v_rows]
        a, thrust = self._no_a, self._none                # (read-only zeros: no body has an Acceleration)
        has_a = self._has_a
        if has_a.size:
            a = np.zeros((n, 3))
            a[has_a] = world.table(Acceleration).data["linear"][self.a_rows[has_a]]
            thrust = (a[:, 0] != 0.0) | (a[:, 1] != 0.0) | (a[:, 2] != 0.0)
        X0 = pos_t[wells.t_rows]
        V0 = np.where((wells.v_rows >= 0)[:, None], vel_t[np.maximum(wells.v_rows, 0)], 0.0)
        if np.array_equal(x, self.last_x) and np.array_equal(v, self.last_v):
            edited = self._none                           # the usual step: nobody else moved anything
        else:
            edited = np.any(x != self.last_x, axis=1) | np.any(v != self.last_v, axis=1)
        # the obstacles at the step's start (the components: the commit stage writes their end later)
        has = self.ob_v_rows >= 0
        # times as step_count * dt (never summed), so a time is the same number however it was reached;
        # root wells move at their own velocity (the movement system moves them); moons as bodies
        return GravityStep(t0=world.step_count * dt, t1=(world.step_count + 1) * dt, dt=dt,
                           X0=X0, V0=V0, X1=X0 + V0 * dt, V1=V0.copy(), wA=np.zeros(len(wells)),
                           x=x, v=v, a=a, thrust=thrust, edited=edited,
                           ob_x=pos_t[self.ob_t_rows],
                           ob_v=np.where(has[:, None], vel_t[np.maximum(self.ob_v_rows, 0)], 0.0),
                           x1=self._x1_next, v1=self._v1_next, events=[])

    def _place_moon(self, step: GravityStep, wj: int, end: RailsEnd) -> None:
        """Moon ``wj``'s centre at ``t1`` from its parent's bodies' end (it is one of them), and the bound
        on its acceleration over the step (its pull about the parent's, plus the parent's own)."""
        wells = self._wells
        wi = int(wells.parent[wj])
        kk = int(np.flatnonzero(self.well_index == wj)[0])
        p = int(np.searchsorted(end.sel, kk))
        r, u = end.r, end.u
        step.X1[wj] = step.X1[wi] + r[p]
        step.V1[wj] = step.V1[wi] + u[p] + (0.5 * step.dt * step.a[kk] if step.thrust[kk] else 0.0)
        _, _, A_m, _ = kepler.arc_boxes(step.x[kk:kk + 1] - step.X0[wi], step.v[kk:kk + 1] - step.V0[wi],
                                        r[p:p + 1], u[p:p + 1], step.dt, wells.mu[wi], wells.radius[wi],
                                        np.zeros(1, bool))
        step.wA[wj] = A_m[0] + step.wA[wi]

    def _warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            warnings.warn(text, RuntimeWarning, stacklevel=4)
