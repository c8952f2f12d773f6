"""Sphere collisions: exact, continuous, order-independent, bounded (and the articles' method as a baseline).

**One-way data.** The collision stage corrects the step's prediction
(:mod:`driftframe.framework.step`): it reads the colliders' start-of-step
``x0, v0`` (and ``a``) from the components, which the commit stage has not
written yet, and writes ``x1, v1`` into ``world.step_context`` for the bodies
a contact touched; every other body keeps the movement stage's free-flight
prediction. Each body moves over the step as ``p(t) = x0 + u t`` with
``u = v0 + a dt/2`` (the exact constant-acceleration end point; an impulse
changes ``u`` and ``a dt/2`` is added back at the end; contacts of a thrusting
body lie on the chord of its parabola, at most ``|a| dt^2 / 8`` off).

The physics is :mod:`driftframe.framework.contact` (times of impact,
islands of simultaneous contacts, the TC model against inelastic collapse,
the bounds on jams and on contacts per body; compiled with numba) and the
candidate pairs come from :mod:`driftframe.framework.broadphase`: every pair up
to :data:`~driftframe.framework.broadphase.ALL_PAIRS_MAX` bodies, above that a
:class:`~driftframe.framework.broadphase.NeighbourList` kept for several steps
(bodies that leave their territory are swept, in the kernel, and the list is
rebuilt once more than a few are).

**Reports.** Spheres that overlap at the start of a step (at spawn) are
reported once per change of the scene, with the count and the worst pair;
those that approach are resolved at once (one impulse, no jump), those that
separate are left to separate (no stick, no energy added). A body whose
position, velocity, acceleration, radius, mass or restitution is not finite
(a user's system wrote NaN into a column) is reported at the next step, naming
the entity and the field, and left out of collisions until it is finite again:
its NaN never reaches another body. The TC model, a jam and the per-body cap
each warn once per system.

Masses: :class:`~components.body.Mass` (``math.inf`` = immovable); a collider
without ``Mass`` weighs 1 kg; one without ``Velocity`` is a fixed obstacle.
Two immovable bodies pass through each other. Restitution of a pair: the
smaller of the two :class:`~components.collision.SphereCollider` values.
Spin is not touched (frictionless spheres exert no torque).

Bodies the gravity system integrates (marked
:class:`~driftframe.components.gravity.Orbiting`) are left out: their paths
are conics, and the gravity system finds their contacts with each other on
those conics (same :class:`CollisionEvent`, ``method="kepler"``).

The articles' discrete method lives in :mod:`driftframe.framework.articles`
(``method="articles"``).
"""
from __future__ import annotations

import math
import warnings
from typing import TYPE_CHECKING, Any

import esper
import numpy as np

from driftframe.components.body import Acceleration, Mass, Transform, Velocity
from driftframe.components.collision import BoxCollider, CollisionEvent, PlaneCollider, SphereCollider
from driftframe.components.gravity import Orbiting
from driftframe.framework import broadphase as bp
from driftframe.framework import contact, kernels
from driftframe.framework.quiet_step import gather_quiet, quiet_all_pairs, write_changed
from driftframe.framework.step import StepContext
from driftframe.systems.collider_state import Layout, State, WithoutOrbiting
from driftframe.systems.static_step import StaticShapes, load, solve_with_shapes

if TYPE_CHECKING:
    from driftframe.framework.world import World

METHODS = ("continuous", "articles")

_NO_N3 = np.empty((0, 3))
_ZERO_STATS = {"pairs": 0, "contacts": 0, "waves": 0, "builds": 0, "swept": 0, "overlaps": 0, "sequential": 0,
               "left_out": 0}


def kernel_events(ents, ev, ev_n, ev_x, t0: float, step: int, method: str = "continuous") -> list:
    """CollisionEvents from the contact kernel's arrays (:func:`framework.contact.solve_listed`:
    ``(i, j, time, impulse)``, the normal i to j, the points on i and on j), the lower entity id
    first (its point, the normal towards the other). ``ents``: entity id of each kernel body (an array,
    or a list of ints: then each event reads it without numpy's per-item cost); ``t0``: the step's
    start (s)."""
    out = []
    add = out.append
    event = CollisionEvent
    for (i, j, t, lam), nrm, pts in zip(ev.tolist(), ev_n.tolist(), ev_x.tolist()):
        a, b = int(ents[int(i)]), int(ents[int(j)])
        if a < b:
            add(event(a, b, t0 + t, t, (pts[0], pts[1], pts[2]), (nrm[0], nrm[1], nrm[2]), lam, method, step))
        else:
            add(event(b, a, t0 + t, t, (pts[3], pts[4], pts[5]), (-nrm[0], -nrm[1], -nrm[2]), lam, method, step))
    return out


class CollisionSystem(esper.Processor):
    """Reads Transform, Velocity, Acceleration, Mass, SphereCollider; writes the step context (the end of
    the step of the colliders a contact touched); appends CollisionEvent to world.events.
    Elastic (or restitution-scaled) sphere impulses at the exact times of impact inside the step.

    ``method``: ``"continuous"`` (default; swept, time-ordered, islands of
    simultaneous contacts) or ``"articles"`` (the articles' discrete method,
    kept as a baseline, :mod:`~driftframe.framework.articles`).
    ``broadphase``: ``"auto"``, ``"all"`` (every pair every step), or the method
    the neighbour list is built with (``"grid"``, ``"sweep"``, ``"kdtree"``).
    ``skin_steps``: how many steps the neighbour list should last.
    ``events``: append a :class:`CollisionEvent` per contact. ``contact_time``:
    the TC model's ``t_c`` in seconds (default ``1e-6 dt``); ``max_contacts``:
    a body's contacts per step before they lose their bounce (see
    :mod:`~driftframe.framework.contact`).

    After each step ``stats`` holds counts: candidate pairs, contacts, waves,
    list builds, bodies swept, overlapping pairs at the start of the step,
    islands solved contact by contact, bodies left out (non-finite).
    """

    stage = "collision"
    reads = (Transform, Velocity, Acceleration, Mass, SphereCollider, PlaneCollider, BoxCollider, Orbiting)
    writes = (StepContext, CollisionEvent)

    def __init__(self, method: str = "continuous", *, broadphase: str = "auto",
                 skin_steps: float = 8.0, events: bool = True, contact_time: float | None = None,
                 max_contacts: int = contact.CAP):
        if method not in METHODS:
            raise ValueError(f"CollisionSystem.method must be one of {METHODS}, got {method!r}")
        if broadphase not in bp.METHODS:
            raise ValueError(f"CollisionSystem.broadphase must be one of {bp.METHODS}, got {broadphase!r}")
        if isinstance(skin_steps, bool) or not isinstance(skin_steps, (int, float)) or not skin_steps > 0 \
                or not math.isfinite(skin_steps):
            raise ValueError(f"CollisionSystem.skin_steps must be a finite number > 0, got {skin_steps!r}")
        if contact_time is not None and (isinstance(contact_time, bool) or not isinstance(contact_time, (int, float))
                                         or not contact_time >= 0 or not math.isfinite(contact_time)):
            raise ValueError(f"CollisionSystem.contact_time must be a finite number >= 0, got {contact_time!r}")
        if isinstance(max_contacts, bool) or not isinstance(max_contacts, (int, np.integer)) or max_contacts < 1:
            raise ValueError(f"CollisionSystem.max_contacts must be an int >= 1, got {max_contacts!r}")
        self.method = method
        self.broadphase = broadphase
        self.events = bool(events)
        self.contact_time = contact_time
        self.max_contacts = int(max_contacts)
        self._world = None
        self._layout: Layout | None = None
        self._layout_epoch = -1
        self._list = bp.NeighbourList(skin_steps, "auto" if broadphase == "all" else broadphase)
        self._list_layout = None
        self._list_dirty = True
        self._lst = None
        self._pairs_n = -1
        self._pairs = None
        self._warned: set[str] = set()
        self._reported_overlap = None
        self._bad: set[int] = set()
        self._t_last_layout = None
        self._none_changed = None
        self._stick = False                          # a step jammed: solve with the jam path's variant
        self.stats = dict(_ZERO_STATS)
        self._quiet_stats = -1                       # n of the last quiet step, whose counts stats holds
        self._quick: tuple | None = None             # the shortest path's call, kept (see _quick_path)
        self._solver_entry = None                    # the all-pairs solver's entry point (_all_pairs_solver)
        self._shapes: StaticShapes | None = None     # static planes and boxes, when the world has any (_refresh)
        self._dry: tuple | None = None               # prepare()'s finding that the next step is quiet (dry_run_safe)

    @property
    def requires(self) -> tuple[type, ...]:
        """Nothing to do without a sphere collider, unless it holds colliders from before (it then runs
        to let them go and zero its stats, like the gravity system with its bodies). Read by the world
        once per change of entities: the world does not call an idle system (issue 20)."""
        lay = self._layout
        return () if lay is not None and lay.n else (Transform, SphereCollider)

    @property
    def world(self) -> World | None:
        return self._world

    @world.setter
    def world(self, w: World | None) -> None:
        self._world = w

    # -- bookkeeping ----------------------------------------------------------
    def _refresh(self) -> Layout:
        world = self.world
        world.sync()
        lay = self._layout
        if lay is not None and self._layout_epoch == world.epoch:
            return lay                              # no entity gained or lost a component since
        q = world.query(Transform, SphereCollider, optional=(Velocity, Mass, Acceleration))
        q.refresh()
        orbiting = world.query(Orbiting)
        orbiting.refresh()
        version = (q.version, orbiting.version) if len(orbiting) else q.version
        if lay is None or lay.version != version:
            lay = self._layout = Layout(WithoutOrbiting(q, orbiting) if len(orbiting) else q)
        self._layout_epoch = world.epoch
        shapes = self._shapes or StaticShapes(world)       # (a scene with none: None, and no other cost)
        self._shapes = shapes if shapes.present() else None
        return lay

    def prepare(self) -> None:
        """The packed layout of the current colliders, the buffers a step fills and, where the step
        uses one, the neighbour list of the bodies as they are now (see :meth:`World.prepare`); the
        solvers loaded and rehearsed on copies (:meth:`_rehearse`), and whether the coming step is quiet,
        for the world's dry steps (:meth:`dry_run_safe`): the first step then costs what the others do. (The
        list is checked every step against where the bodies are, so one built here for a state changed
        before the step is rebuilt then.)"""
        self._dry = None
        lay = self._refresh()
        if not lay.n:
            return
        dt = self.world.dt
        st = State.of(self.world, lay).gather(lay, dt)
        n = lay.n
        listed = self._uses_list(n)
        quiet = False
        if not listed:
            if self._shapes is None:    # (with shapes no step takes the shortest path: its test sees spheres only)
                quiet = st.gather_quiet(lay, dt, self._all_pairs(n))     # its first call
                self._quick_path(dt)    # (its entry point: typing its 13 arguments once here, not in a step)
        elif n >= 2 and st.bad(lay) is None:
            self._build_list(lay, st, dt)
        t_last = self._t_last_of(lay)
        # the contact step's end-of-step writer, loaded now (numba loads a kernel at its first call); all
        # False: it writes nothing
        write_changed(self._unchanged(n), lay.t_idx, lay.v_idx, st.x, st.u, st.a if st.a is not None else _NO_N3,
                      float(dt), _NO_N3, _NO_N3)
        if self._shapes is not None and st.bad(lay) is None and self.method == "continuous":
            load(self._inputs(st, t_last, dt, *self._all_pairs(n)), self._shapes.refresh())
        elif n >= 2 and st.bad(lay) is None and self.method == "continuous":
            self._load_solvers(st, t_last, dt, listed)
            if st.moving:
                quiet = self._rehearse(st, t_last, dt, listed)
        if self.method == "continuous" and self._shapes is None and st.bad(lay) is None and not self._bad \
                and (n < 2 or not st.moving or quiet):
            self._dry = (self.world.epoch, dt)                   # (see dry_run_safe)

    def dry_run_safe(self, dt: float) -> bool:
        """Whether :meth:`process` may run in ``World.prepare``'s dry steps, which follow :meth:`prepare` at
        once: where prepare found this step quiet (no pair meets, no body is invalid or strays from the
        neighbour list), it changes nothing but :attr:`stats`, which then hold the coming step's counts (a
        step with work prepare rehearsed on copies)."""
        return self._dry == (self.world.epoch, dt) and type(self).process is CollisionSystem.process

    def _rehearse(self, st: State, t_last: np.ndarray, dt: float, listed: bool) -> bool:
        """The first step's kernels run once on copies of what they change, their results dropped, whether
        or not the step has a contact: the step, or the first contact step after a few quiet ones, then finds
        most of the solver's temporaries in memory already mapped (the heap's first growth: page faults)
        and its code and data in the CPU's caches (figures: docs/bench/collision_stress.md, "First step").
        Nothing the step reads changes. Returns whether the coming step is quiet: no pair meets, and no
        body strays from the neighbour list (see :meth:`dry_run_safe`)."""
        x, u, r = st.x.copy(), st.u.copy(), st.r
        if listed:
            nl = self._list
            swept = nl.swept.copy()
            new, total = bp.mark_strays(x, u, dt, nl.centre, nl.skin, swept, r, nl.radius)
            if new < 0 or (new > 0 and total > nl.budget):
                return False                                 # the step rebuilds first (as _continuous)
            quiet = total == 0 and quiet_all_pairs(x, u, r, st.inv, st.live, self._pi, self._pj, dt)
            centre, skin, reach, order, lo_x, width = nl.kernel_arrays()
            # (the path boxes and the scratch are the step's own: every step fills them before it reads them)
            lst = contact.ListedArrays(swept, self._blo, self._bhi, centre, skin, reach, order, lo_x, float(width),
                                       int(nl.budget), self._tosweep, self._newlo, self._newhi)
            pi, pj = self._pi, self._pj
        else:
            lst = None
            pi, pj = self._pairs
            quiet = quiet_all_pairs(x, u, r, st.inv, st.live, pi, pj, dt)
        t_c = self.contact_time if self.contact_time is not None else contact.TC * dt
        contact.solve_step(contact.StepInputs(x, u, r, st.inv, st.e, st.live, t_last.copy(), self._now(), pi, pj,
                                              float(dt), float(t_c), self.max_contacts, lst), stick=self._stick)
        return quiet

    def _load_solvers(self, st: State, t_last: np.ndarray, dt: float, listed: bool) -> None:
        """Load (from the kernel cache, or compile) the solver this scene's steps call, without calling it,
        and its jam-path variant where a restitution below 1 can jam (inelastic collapse): numba loads a
        kernel at its first call, and the jam variant's first call came in the step that first jams
        (docs/design/costs.md). Types only: nothing is solved."""
        if listed:
            lst = self._listed()                             # (made here, not in the first step that needs it)
            pi, pj = self._pi, self._pj
        else:
            lst = None
            pi, pj = self._pairs
        solvers = contact.solvers(listed)
        t_c = self.contact_time if self.contact_time is not None else contact.TC * dt
        args = (st.x, st.u, st.r, st.inv, st.e, st.live, t_last, 0.0, pi, pj, float(dt), float(t_c),
                self.max_contacts, lst)
        for solve in solvers if float(st.e.min()) < 1.0 else solvers[:1]:
            if hasattr(solve, "compile"):                  # (a plain function under NUMBA_DISABLE_JIT)
                solve.compile(tuple(solve.typeof_pyval(a) for a in args))
        if not listed:
            self._solver_entry = kernels.entry(solvers[0], args)     # (typing 14 arguments: not in a step)

    def _listed(self) -> contact.ListedArrays:
        """The neighbour list's arrays a listed step's solver takes (:class:`contact.ListedArrays`): made once
        a build, kept until the next."""
        if self._lst is None:
            nl = self._list
            centre, skin, reach, order, lo_x, width = nl.kernel_arrays()
            self._lst = contact.ListedArrays(nl.swept, self._blo, self._bhi, centre, skin, reach, order, lo_x,
                                             float(width), int(nl.budget), self._tosweep, self._newlo, self._newhi)
        return self._lst

    def _uses_list(self, n: int) -> bool:
        """Whether a step of ``n`` colliders takes its candidate pairs from the neighbour list."""
        return not (self.broadphase == "all" or (self.broadphase == "auto" and n <= bp.ALL_PAIRS_MAX))

    def _build_list(self, lay, st, dt, x=None, u=None, r=None) -> None:
        """The neighbour list of the layout's bodies from their state ``st`` (positions, mean velocities)."""
        x = st.x if x is None else x
        u = st.u if u is None else u
        r = st.r if r is None else r
        n = lay.n
        nl = self._list
        nl.build(x.T, r, bp.step_lengths(u, float(dt)))          # |u| dt (one compiled pass)
        self._list_layout = lay
        self._list_dirty = False
        self._pi = np.asarray(nl.i, np.int64)             # (no copy: the grid build gives int64)
        self._pj = np.asarray(nl.j, np.int64)
        self._blo = np.empty((n, 3))
        self._bhi = np.empty((n, 3))
        self._tosweep = np.empty(n, np.int64)               # the kernel's scratch for bodies swept mid-step
        self._newlo = np.empty((n, 3))
        self._newhi = np.empty((n, 3))
        self._lst = None                                    # ListedArrays of this build (made at its first use)

    def _now(self) -> float:
        return self.world.time if self.world is not None else 0.0

    def _warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            warnings.warn(text, RuntimeWarning, stacklevel=4)

    def process(self, dt: float) -> None:
        world = self._world
        quick = self._quick
        if quick is None or quick[0] != world.epoch or quick[1] != dt or quick[2] is not self.method \
                or quick[3] is not self.broadphase:
            quick = self._quick_path(dt)
            if quick is None:
                self._process(dt)
                return
        # the shortest path, a scene of a few bodies: one compiled call gathers them and finds the step
        # quiet (no pair meets), and the movement stage's prediction stands
        st = quick[4]
        st.n_bad, st.moving, quiet = quick[7](*quick[5])   # (gather_quiet's entry point: see _quick_path)
        if not quiet:
            self._zero_stats()
            self._continuous(self._layout, st, dt)
            return
        n = quick[6]
        if self._quiet_stats != n:                           # (the same counts as the last quiet step's)
            self.stats.update(_ZERO_STATS)
            self.stats["pairs"] = len(self._pairs[0])        # what the solver would say of a quiet step
            self._quiet_stats = n
        if self._bad:
            self._bad.clear()
        ctx = world.step_context
        if ctx.step != world.step_count or not ctx.predicted:
            self._finish(self._layout, st, self._unchanged(n), dt)   # (no movement stage: free flight here)

    def _quick_path(self, dt: float) -> tuple | None:
        """What :meth:`process` keeps for the shortest path (a few colliders, all pairs, the continuous
        method): ``(epoch, dt, method, broadphase, state, the quiet kernel's arguments, n, its entry
        point)``, valid while those five are the same; None (and nothing kept) where a step of the current
        colliders does not take it. The arguments are the same objects while it is (the world's columns and
        the state's arrays at this epoch, ``float(dt)``), so the kernel's entry point for their types is
        called directly (kernels.entry: 13 arguments' dispatch saved; docs/design/costs.md)."""
        self._quick = None
        world = self._world
        lay = self._layout                          # (the world has synced its tables before calling this)
        if lay is None or self._layout_epoch != world.epoch:
            lay = self._refresh()
        n = lay.n
        if n < 2 or self.method != "continuous" or self._uses_list(n) or self._shapes is not None:
            return None
        st = lay.state or State.of(world, lay)
        call = st.quiet_call(lay, dt, self._pairs if self._pairs_n == n else self._all_pairs(n))
        self._quick = (world.epoch, dt, self.method, self.broadphase, st, call, n,
                       kernels.entry(gather_quiet, call))
        return self._quick

    def _process(self, dt: float) -> None:
        """A step that does not take the shortest path (see :meth:`process`)."""
        lay = self._layout
        n = lay.n
        self._zero_stats()
        if n == 0:
            return
        st = State.of(self.world, lay)
        st.gather(lay, dt)
        if self.method == "articles":
            from driftframe.framework.articles import articles_step
            x, v, contacts = articles_step(st, lay, dt, self._now(), self.events)
            self._write(lay, x, v, dt)
            self.stats["pairs"] = lay.n * (lay.n - 1) // 2
            self.stats["contacts"] = len(contacts)
            step = self.world.step_count
            for c in contacts:
                self.world.emit(CollisionEvent(*c, "articles", step=step))
            return
        self._continuous(lay, st, dt)

    def _zero_stats(self) -> None:
        self.stats.update(_ZERO_STATS)
        self._quiet_stats = -1

    def _context(self, dt: float) -> StepContext:
        """The step context, opened for this step (by the movement stage, or here in a world without one)."""
        world = self.world
        ctx = world.step_context
        if ctx.step != world.step_count:
            ctx.begin(world.step_count, dt, world.table(Transform), world.table(Velocity))
        return ctx

    def _write(self, lay: Layout, x1: np.ndarray, v1: np.ndarray, dt: float) -> None:
        """Position and velocity at the end of the step of every collider that has a Velocity."""
        if len(lay.v_sel) == 0:
            return
        ctx = self._context(dt)
        if lay.all_v:
            ctx.position[lay.t_rows] = x1
            ctx.velocity[lay.v_rows] = v1
        else:
            ctx.position[lay.tv_rows] = x1[lay.v_sel]
            ctx.velocity[lay.v_rows] = v1[lay.v_sel]

    def _finish(self, lay: Layout, st: State, changed: np.ndarray, dt: float) -> None:
        """The end of the step of the bodies a contact changed, ``x + u dt`` with ``u`` (plus the second
        ``a dt/2``), into the step context; the others keep the movement stage's prediction (in a world
        without a movement stage, their free flight is written here)."""
        ctx = self._context(dt)
        if not ctx.predicted:
            x1, v1 = st.end_of_step(dt)
            self._write(lay, x1, v1, dt)
        if changed is self._none_changed:
            return
        # one compiled pass over the changed bodies (quiet_step.write_changed: numpy's fancy indexing was
        # most of a small scene's contact step); the velocities are opened first, as a write to them does
        write_changed(changed, lay.t_idx, lay.v_idx, st.x, st.u, st.a if st.a is not None else _NO_N3, float(dt),
                      ctx.position, ctx.open_velocity())

    def _t_last_of(self, lay: Layout) -> np.ndarray:
        """The last contact of each body of the layout (absolute time, s; -inf: none yet), kept across
        steps for the TC model; new for a new layout (from a restored save's, by entity, after a load)."""
        if self._t_last_layout is not lay:
            self._t_last = np.full(lay.n, -math.inf)
            self._t_last_layout = lay
            saved, self._saved = getattr(self, "_saved", None), None
            if saved is not None and lay.n:
                ents, t_last = np.asarray(saved[0], np.int64), np.asarray(saved[1], float)
                _, new_i, old_i = np.intersect1d(lay.entities, ents, assume_unique=True, return_indices=True)
                self._t_last[new_i] = t_last[old_i]
        return self._t_last

    def state(self) -> dict[str, Any]:
        """What a save keeps of this system (see framework/save.py): the TC model's last contact time of
        each collider (it damps the next contact's restitution) and whether a jam switched the solver."""
        lay, saved = self._t_last_layout, getattr(self, "_saved", None)
        if lay is None:                                 # (a load not stepped yet: what it restored)
            ents, t_last = saved if saved is not None else ([], np.empty(0))
            return {"entities": [int(e) for e in ents], "t_last": np.array(t_last, float), "stick": self._stick}
        return {"entities": [int(e) for e in lay.entities], "t_last": self._t_last.copy(), "stick": self._stick}

    def restore(self, state: dict[str, Any]) -> None:
        """Take back :meth:`state` (a load): the layout is rebuilt at the next step and takes the times."""
        self._saved = (state["entities"], state["t_last"])
        self._stick = bool(state["stick"])
        self._layout = self._t_last_layout = self._quick = None
        self._list_dirty = True

    def _unchanged(self, n: int) -> np.ndarray:
        """All False, n long (read only): one array kept."""
        z = self._none_changed
        if z is None or len(z) != n:
            z = self._none_changed = np.zeros(n, np.bool_)
        return z

    # -- continuous -----------------------------------------------------------
    def _all_pairs(self, n: int) -> np.ndarray:
        """Every pair of ``n`` bodies, ``(2, m)``: the rows ``pi, pj`` (kept for this n only)."""
        if self._pairs_n != n:
            self._pairs = np.stack(contact.all_pairs(n))
            self._pairs_n = n
        return self._pairs

    def _continuous(self, lay: Layout, st: State, dt: float) -> None:
        """The continuous solver's step (on the all-pairs path, :meth:`process` has found it not quiet)."""
        n = lay.n
        bad = st.bad(lay)
        live = st.live
        x, u = st.x, st.u
        inv, r, e = st.inv, st.r, st.e
        if bad is not None:
            self._report_bad(lay, st, bad)
            x[bad] = 0.0                                     # the kernel never reads them (not live)
            u[bad] = 0.0
            inv = np.where(bad, 0.0, inv)
            r = np.where(bad, 1.0, r)
            e = np.where(bad, 1.0, e)
            self.stats["left_out"] = int(bad.sum())
        elif self._bad:
            self._bad.clear()
        shapes = self._shapes
        if (n < 2 and shapes is None) or not st.moving:
            self._finish(lay, st, self._unchanged(n), dt)    # nothing moves relative to anything: no contact
            return
        t_c = self.contact_time if self.contact_time is not None else contact.TC * dt
        # last contact of each body (absolute time), for the TC model across steps
        now = self._now()
        t_last = self._t_last_of(lay)                      # absolute: the kernel makes it relative to now

        if shapes is not None:       # spheres overlapping a shape at spawn: reported once (static_step)
            shapes.refresh().report_overlaps(lay.entities, x, r, live & (inv > 0.0), now)
            res = solve_with_shapes(self._inputs(st, t_last, dt, *self._all_pairs(n)), shapes, self._stick)
            self._stick = res.stick
            self._result(lay, st, res, dt, [*lay.entities.tolist(), *shapes.entities.tolist()])
            return
        if not self._uses_list(n):
            pi, pj = self._all_pairs(n)                   # (process made the quiet-step test: not quiet)
            lst = None
        else:
            nl = self._list
            rebuild = self._list_dirty or self._list_layout is not lay or len(nl.radius) != n
            total = -1
            if not rebuild:
                # the list no longer speaks for bodies whose path leaves their territory: they are swept
                # (and a change of radius anywhere means a rebuild: mark_strays says -1)
                new, total = bp.mark_strays(x, u, dt, nl.centre, nl.skin, nl.swept, r, nl.radius)
                rebuild = new < 0 or (new > 0 and total > nl.budget)   # too many to sweep each step: rebuild
            if rebuild:
                self._build_list(lay, st, dt, x, u, r)
                self.stats["builds"] = 1
                total = int(np.count_nonzero(nl.swept))
            pi, pj = self._pi, self._pj
            # no body swept: the list's pairs are every pair that can meet this step, so the quiet-step
            # test over them is the solver's answer (a swept body's pairs are found in the solver)
            if total == 0 and quiet_all_pairs(x, u, r, inv, live, pi, pj, dt):
                self.stats["pairs"] = len(pi)
                self._finish(lay, st, self._unchanged(n), dt)
                return
            lst = self._lst or self._listed()
        args = (x, u, r, inv, e, live, t_last, float(now), pi, pj, float(dt), float(t_c), self.max_contacts, lst)
        if lst is None and not self._stick:
            out = self._all_pairs_solver(args)(*args)
            if not out[5] & contact.F_AGAIN:
                self._result(lay, st, out, dt)
                return
            # (as solve_step does: the step again with the jam path; its inputs came back as they were)
            res = contact.solve_step(contact.StepInputs(*args), stick=True)
        else:
            res = contact.solve_step(contact.StepInputs(*args), stick=self._stick)
        self._stick = res.stick                              # after a jam, the variant with the jam path
        self._result(lay, st, res, dt)

    def _all_pairs_solver(self, inputs: tuple):
        """The all-pairs solver's compiled entry point (kernels.entry), made in prepare() or at its first call:
        the few bodies' contact step calls it past numba's dispatch and past :func:`contact.solve_step`'s records
        (with cold caches, as a contact step among quiet ones runs, the dispatch of its 14 arguments and the
        records cost about as much as the solver itself: docs/design/costs.md). Its arguments always have these types: the
        state's float64 and bool arrays (C order), the pairs' int64 rows, ``now``, ``dt``, ``t_c`` as floats
        (made so in :meth:`_continuous`), ``cap`` an int, ``lst`` None (``inputs``: :class:`contact.StepInputs`'s
        fields, in its order)."""
        entry = self._solver_entry
        if entry is None:
            entry = self._solver_entry = kernels.entry(contact.solvers(False)[0], tuple(inputs))
        return entry

    def _inputs(self, st: State, t_last: np.ndarray, dt: float, pi: np.ndarray, pj: np.ndarray):
        """A step's inputs on the all-pairs path (the static shapes' step)."""
        t_c = self.contact_time if self.contact_time is not None else contact.TC * dt
        bad = st.bad(self._layout)
        inv, r, e = st.inv, st.r, st.e
        if bad is not None:                                  # (as _continuous: the kernel never reads them)
            inv, r, e = np.where(bad, 0.0, inv), np.where(bad, 1.0, r), np.where(bad, 1.0, e)
        return contact.StepInputs(st.x, st.u, r, inv, e, st.live, t_last, self._now(), pi, pj, float(dt),
                                  float(t_c), self.max_contacts, None)

    def _result(self, lay: Layout, st: State, res, dt: float, ents: list | None = None) -> None:
        """A solved step's stats, flags, end of step and events (``ents``: the entity of each kernel body,
        when not the layout's: the static shapes' step). ``res``: a :class:`contact.StepResult`, or the
        solver's own 6-tuple (the same first six fields, the stats as the solver's array)."""
        n = lay.n
        changed, ev, ev_n, ev_x, s, flags = res[:6]
        if not isinstance(s, tuple):
            s = s.tolist()                                   # (indexed by contact.S_*: StepStats's order)
        st_ = self.stats
        contacts, waves, overlaps = s[contact.S_CONTACTS], s[contact.S_WAVES], s[contact.S_OVERLAPS]
        st_["pairs"], st_["contacts"], st_["waves"] = int(s[contact.S_PAIRS]), int(contacts), int(waves)
        if s[contact.S_SWEPT]:
            st_["swept"] += int(s[contact.S_SWEPT])
        if overlaps or s[contact.S_SEQUENTIAL]:
            st_["overlaps"], st_["sequential"] = int(overlaps), int(s[contact.S_SEQUENTIAL])
        if flags:
            if flags & contact.F_REBUILD:
                self._list_dirty = True
            self._flags(flags, lay)
        if overlaps and self._reported_overlap is not lay:
            self._reported_overlap = lay
            i, j = int(s[contact.S_WORST_I]), int(s[contact.S_WORST_J])
            warnings.warn(f"collision: {int(overlaps)} pairs of spheres overlap at t = {self._now()!r} s; the "
                          f"deepest: entities {int(lay.entities[i])} and {int(lay.entities[j])}, centres "
                          f"{s[contact.S_WORST]:.6g} of r_a + r_b apart. Pairs that approach bounce at once, the "
                          f"rest separate (use driftframe.framework.placement to place bodies apart)",
                          RuntimeWarning, stacklevel=4)
        if not (contacts or waves or flags):
            changed = self._unchanged(n)                    # no contact, no wave, no flag: nothing changed
        self._finish(lay, st, changed, dt)
        if len(ev) and self.events and self.world is not None:
            self._emit(lay, ev, ev_n, ev_x, ents)

    def _report_bad(self, lay, st, bad):
        now = set()
        for k in np.flatnonzero(bad).tolist():
            ent = int(lay.entities[k])
            now.add(ent)
            if ent not in self._bad:                          # once, until it is valid again
                warnings.warn(f"collision: entity {ent} has {st.describe(k)} at t = {self._now()!r} s; it is left "
                              f"out of collisions until it is valid again", RuntimeWarning, stacklevel=4)
        self._bad = now

    def _flags(self, flags, lay):
        if flags & contact.F_JAM:
            self._warn_once("jam", f"collision: more than {contact.JAM} contacts of one body in a burst (bodies "
                                   "jammed between immovable ones, or a stack hit at once); the rest of that burst "
                                   "is resolved without bounce (e = 0)")
        if flags & contact.F_TC:
            self._warn_once("tc", "collision: inelastic collapse: contacts repeating within t_c are taken as "
                                  "elastic (TC model, Luding & McNamara 1998)")
        if flags & contact.F_CAP:
            self._warn_once("cap", f"collision: a body met more than {self.max_contacts} contacts in one step; "
                                   "its further contacts this step are resolved without bounce (e = 0)")
        if flags & contact.F_STICK:
            self._warn_once("stick", "collision: a jam did not end without bounce; the island was given its "
                                     "centre-of-mass velocity")
        if flags & contact.F_LIMIT:
            self._warn_once("limit", "collision: the step's wave limit was reached; contacts left unresolved")

    def _emit(self, lay, ev, ev_n, ev_x, ents=None):
        """One CollisionEvent per contact (a Python loop over contacts that happened)."""
        ents = lay.entity_list if ents is None else ents
        if ents is None:                                     # (the layout's ids as ints, made at its first event)
            ents = lay.entity_list = lay.entities.tolist()
        for event in kernel_events(ents, ev, ev_n, ev_x, self._now(), self.world.step_count):
            self.world.emit(event)
