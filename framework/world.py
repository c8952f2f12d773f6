"""The world: one esper context, its component tables, its systems stepped in order, and its events.

The order is :mod:`~driftframe.framework.schedule`'s, the tables' reconcile with esper
:mod:`~driftframe.framework.table_sync`'s, the state's hash :mod:`~driftframe.framework.state_hash`'s.

Data flows one way each step. The built-in stages give the default order::

    input -> control -> movement -> spin -> collision -> commit -> camera   (every fixed step)
    render -> record                                                  (every presented frame)

A system is an ``esper.Processor`` with ``process(dt)`` that declares its
``stage``, ``name``, ``reads`` and ``writes`` (see :mod:`~driftframe.framework.schedule`,
which orders them). The schedule is open: ``world.add_system(Damage(),
after="collision")`` places a user's system, and ``print(world.describe())``
shows the order and each system's access.

``World`` owns a private esper world context and makes it current whenever it
steps, so esper's module functions (``esper.create_entity``,
``esper.get_components``, ...) act on it from inside systems and from user
code after ``world.activate()`` (a new World is also activated on creation).
It also owns one :class:`~driftframe.framework.store.Table` per columnar
component class; :meth:`World.sync` reconciles them with esper
(:mod:`~driftframe.framework.table_sync`; ``store.py`` for the lifecycle), and :meth:`World.columns` is the public way
to read and write whole columns.

Events (collision contacts, ...) go through :meth:`World.emit`:
subscribers (:meth:`World.subscribe`) are called at once, and
``world.events`` keeps every event of every fixed step since the last
rendered frame, so a reader in the render stage sees them all however many
steps the frame took. A world that renders nothing keeps those of the last
``step()`` call.

Resources are keyed by type (``world.resources[TimeWarp]``, typed through
:meth:`World.resource`; :mod:`~driftframe.framework.resources`). esper's
internals are read only through :mod:`~driftframe.framework.esper_adapter`;
the checking mode (:mod:`~driftframe.framework.access_check`) holds each
system to its ``reads``/``writes``. A World is never copied or pickled (a
copy would share the esper context): ``save`` then ``load`` makes an
independent one. A step that raises after systems ran leaves the world
broken (:class:`WorldBrokenError` on the next step) until a save is loaded.
"""
from __future__ import annotations

import itertools
import os
import time
from collections import defaultdict
from contextlib import ExitStack
from typing import Any, Callable, Iterable, NoReturn, Sequence, TypeVar

import esper
import numpy as np

from driftframe.framework import access_check
from driftframe.framework import esper_adapter as ea
from driftframe.framework import table_sync, validate
from driftframe.framework.resources import CheckedResources, Resources, key_name
from driftframe.framework.schedule import (DEFAULT_AFTER, DEFAULT_BEFORE, FRAME_STAGES, STEP_STAGES,  # noqa: F401
                                           Entry, Schedule, ScheduleAmbiguityWarning, ScheduleError, system_name)
from driftframe.framework.schedule import requires as _requires
from driftframe.framework.state_hash import state_hash as _state_hash
from driftframe.framework.step import Commit, StepContext
from driftframe.framework.store import Columnar, Columns, Query, Table

_ids = itertools.count(1)
_S = TypeVar("_S")
_C = TypeVar("_C")
_E = TypeVar("_E")
_R = TypeVar("_R")
#: What ``after=`` / ``before=`` take: a system or stage name, a system class, or several of them.
SystemRefs = str | type | Iterable[str | type]
#: A save's path.
PathLike = str | os.PathLike[str]


#: How many dry steps :meth:`World.prepare` runs at most (CPython 3.11 quickens a code object after 8 calls and
#: then specialises its instructions: a fresh process's first step needs about 12 runs of the step's code
#: before it, docs/bench/collision_stress.md), and the time after which it runs no more (s): a large scene's
#: first step is not slow for its caches and its interpreter, its own work dwarfs them.
REHEARSALS = 12
REHEARSAL_BUDGET = 1e-3


class _Refill:
    """The dry step's stand-in just before the commit: the step context refilled from the tables, so that the
    commit writes back the bytes they hold (:meth:`StepContext.refill`)."""

    __slots__ = ("ctx",)

    def __init__(self, ctx: StepContext) -> None:
        self.ctx = ctx

    def process(self, dt: float) -> None:
        self.ctx.refill()


class WorldBrokenError(RuntimeError):
    """A step of this world raised after one of its systems had run: the world is half-stepped (some
    systems moved it, the rest did not), so it refuses to step or save until a save is loaded into it."""


class World:
    """A simulation: entities (esper), their component tables, systems in order, a fixed time step.

    ``dt`` is the fixed step in seconds (default 1/60 s). The simulation never
    reads the wall clock; ``time`` is ``step_count * dt``.
    """

    def __init__(self, dt: float = 1.0 / 60.0, *, name: str | None = None) -> None:
        self.dt = validate.scalar("dt", dt, positive=True)
        self.name = name or f"driftframe-{next(_ids)}"
        if ea.exists(self.name):
            raise ValueError(f"an esper world named {self.name!r} exists already")
        self.step_count = 0
        self._schedule = Schedule()
        #: Each phase's systems in running order (the schedule's: ``_order["step"]``, ``_order["frame"]``).
        self._order = self._schedule.order
        #: Seconds each stage (or unstaged system) took in the last step / frame (wall time, profiling only).
        self.profile: dict[str, float] = defaultdict(float, {s: 0.0 for s in STEP_STAGES + FRAME_STAGES})
        #: Seconds each stage (or unstaged system) took in total since creation.
        self.profile_total: dict[str, float] = defaultdict(float)
        #: Events of every fixed step since the last rendered frame (see :meth:`emit`).
        self.events: list = []
        #: The events of the frame before (the other half of the double buffer).
        self.previous_events: list = []
        self._rendered = False
        self._subscribers: dict[type, list] = defaultdict(list)
        #: Shared per-world services and state keyed by type (``resources[TimeWarp]``; see
        #: :mod:`~driftframe.framework.resources` and :meth:`resource`), or, the old way, by name.
        self.resources: Resources = (CheckedResources if access_check.enabled else Resources)(self.name, self._writers)
        #: Why the world is half-stepped (:class:`WorldBrokenError`), or None.
        self.broken: str | None = None
        self._broken_by: BaseException | None = None
        self._tables: dict[type, Table] = {}
        self._synced: dict[type, list] = {}
        self._probe = None
        self._queries: dict[tuple, Query] = {}
        #: Each phase's plan: ``(epoch, schedule version, systems with work, how many resources)`` (see
        #: :meth:`_plan`).
        self._plans: dict[str, tuple] = {}
        #: Bumped whenever an entity gains or loses a component (seen by :meth:`sync`, or made by this
        #: world): what is cached on "which entities have what" (a Query's rows, an idle system) is
        #: current while the epoch is the one it was made at.
        self.epoch = 0
        self.closed = False
        ea.switch(self.name)
        #: Every body's end-of-step state while a step runs (framework/step.py): predicted by the movement
        #: stage, corrected by the systems that own bodies, written into the components by the commit
        #: stage, which every world has.
        self.step_context = StepContext()
        self.add_system(Commit())

    # -- entities ---------------------------------------------------------------
    def activate(self) -> "World":
        """Make this world the current esper context (for esper's module functions)."""
        if self.closed:
            raise RuntimeError(f"world {self.name!r} is closed")
        ea.switch(self.name)
        return self

    def create_entity(self, *components: object) -> int:
        """``esper.create_entity`` in this world; columnar components move into its tables at once."""
        self.sync()
        for comp in components:
            if isinstance(comp, Columnar):
                table_sync.check_new(self, [comp])
        ent = esper.create_entity(*components)
        table_sync.attach_now(self, ent, components)
        self._own_change()
        return ent

    def create_entities(self, *columns: Sequence[object] | None) -> list[int]:
        """Create ``n`` entities from equally long lists of components (e.g. ``Transform.bulk(n, ...)``).

        ``None`` in place of a list skips it. Returns the entity ids in order.
        Each list moves into its table in one copy per field.
        """
        cols = [c for c in columns if c is not None]
        if not cols:
            return []
        n = len(cols[0])
        for c in cols:
            if len(c) != n:
                raise ValueError(f"create_entities: component lists differ in length ({len(c)} != {n})")
        self.sync()
        columnar = [c for c in cols if n and isinstance(c[0], Columnar)]
        for c in columnar:
            table_sync.check_new(self, c)
        create = esper.create_entity
        ents = [create(*comps) for comps in zip(*cols)]
        ids = np.asarray(ents, np.int64)
        for c in columnar:
            self._table(type(c[0])).attach(ids, list(c))
        self._own_change()
        return ents

    def _own_change(self) -> None:
        # the world's own add/remove keeps its tables right: only esper's own calls need a reconcile
        self._probe = ea.probe()
        self.epoch += 1

    def add_component(self, entity: int, component: object) -> None:
        """``esper.add_component`` in this world (a component of that type already there is replaced)."""
        self.sync()
        old = esper.try_component(entity, type(component))
        if old is not None and old is not component and isinstance(old, Columnar) and old._table.world == self.name:
            old._table.detach([old._row])
        if isinstance(component, Columnar) and component is not old:
            table_sync.check_new(self, [component])
        esper.add_component(entity, component)
        table_sync.attach_now(self, entity, (component,))
        self._own_change()

    def remove_component(self, entity: int, component_type: type[_C]) -> _C:
        """``esper.remove_component`` in this world; the component keeps its values, its row is freed."""
        self.sync()
        comp = esper.remove_component(entity, component_type)
        if isinstance(comp, Columnar) and comp._table.world == self.name:
            comp._table.detach([comp._row])
        self._own_change()
        return comp

    def delete_entity(self, entity: int) -> None:
        """Delete ``entity`` now; its columnar rows are freed (its components keep their values)."""
        self.sync()
        if esper.entity_exists(entity):
            for comp in esper.components_for_entity(entity):
                if isinstance(comp, Columnar) and comp._table.world == self.name:
                    comp._table.detach([comp._row])
        esper.delete_entity(entity, immediate=True)
        self._own_change()

    # -- storage ----------------------------------------------------------------
    def table(self, cls: type[Columnar]) -> Table:
        """This world's table of columnar component class ``cls`` (made on first use, small)."""
        if access_check.running is not None:
            access_check.touched(cls, "world.table", world=self.name)
        return self._table(cls)

    def _table(self, cls: type[Columnar]) -> Table:
        t = self._tables.get(cls)
        if t is None:
            if not (isinstance(cls, type) and issubclass(cls, Columnar)):
                raise TypeError(f"{cls!r} is not a columnar component class (Transform, Velocity, ...)")
            t = self._tables[cls] = Table(cls, 16, world=self.name)
        return t

    def sync(self) -> None:
        """Reconcile the tables with esper: attach new components, free the rows of removed ones.

        Cheap when nothing was added or removed (one identity check). Called
        before every system runs, by every :class:`Query` refresh and by
        :meth:`columns`, so esper's own ``add_component`` / ``remove_component``
        / ``delete_entity`` calls are seen before any column is read.
        """
        # (the fast path, every system of every step: esper's cache is clean and holds the same probe list)
        if ea.structure_unchanged(self._probe, self.name):
            return
        table_sync.sync(self)                       # (see table_sync: attach, free, follow what esper did)

    def query(self, *types: type, optional: tuple[type, ...] = ()) -> Query:
        """The cached :class:`~driftframe.framework.store.Query` of entities with all of ``types``.

        For systems: ``q.refresh()`` at the top of ``process``, then
        ``q.entities`` (ascending ids) and ``q.rows(T)`` into ``self.table(T).data``.
        """
        key = (types, tuple(optional))
        if access_check.running is not None:
            for T in key[0] + key[1]:
                access_check.touched(T, "world.query", world=self.name)
        q = self._queries.get(key)
        if q is None:
            for T in types + tuple(optional):
                validate.a_class("a query's type", T, "Transform")
            q = self._queries[key] = Query(self, types, tuple(optional))
        return q

    def columns(self, cls: type[Columnar], entities: Sequence[int] | np.ndarray | None = None) -> Columns:
        """Read and write field ``f`` of component ``cls`` for many entities at once.

        ``entities``: entity ids in the order you want (a list or array), or
        None for every entity that has ``cls``, in ascending id order (then
        ``cols.entities`` says which). ``cols.f`` gathers a copy of shape
        ``(n, *field shape)``; ``cols.f = array`` validates and scatters it.
        An entity without ``cls`` is a KeyError naming it.
        """
        if access_check.running is not None:
            access_check.touched(cls, "world.columns", world=self.name)
        self.sync()
        table = self._table(cls)
        if entities is None:
            q = self.query(cls)
            q.refresh()
            return Columns(table, q.entities, q.rows(cls))
        ents = np.asarray(entities)
        if ents.ndim != 1 or not (ents.dtype.kind in "iu" or len(ents) == 0):
            raise TypeError(f"columns({cls.__name__}, entities): entities must be a 1-D list of entity ids, "
                            f"got {entities!r}")
        ents = ents.astype(np.int64)
        return Columns(table, ents, table.rows_of(ents, " (columns: entity order as given)"))

    # -- systems ----------------------------------------------------------------
    def add_system(self, system: _S, stage: str | None = None, *, after: SystemRefs = (), before: SystemRefs = (),
                   name: str | None = None) -> _S:
        """Schedule an ``esper.Processor``; returns it.

        ``stage``: one of :data:`STEP_STAGES` or :data:`FRAME_STAGES` (default:
        ``system.stage``). ``after`` / ``before``: a name or a list of names of
        systems or stages (or system classes) this one must run after / before.
        A system with neither a stage nor constraints runs after collision and
        before camera. ``reads`` / ``writes`` are checked to be tuples of
        component classes.

        ``requires`` (optional, a tuple of component classes): the system has
        nothing to do in a step in which no entity has all of them, so the world
        does not call its ``process`` then (its profile line reads 0). The
        world asks esper once each time entities gain or lose components
        (:attr:`epoch`), the schedule changes or a resource is published or
        taken away, and keeps a plan of the systems with work, so an idle
        system costs nothing a step. A system may change its ``requires``
        (the gravity system while it holds bodies, the input system when a
        key is pressed); the world reads it again at the next such change,
        or at the next step after :meth:`wake`.

        ``keeps_entities = True`` (optional): the system's ``process`` never
        adds or removes a component or an entity, nor calls code that could
        (event subscribers), so the world does not look for a change of
        entities after it (the movement, spin and commit stages).
        """
        self._schedule.add(system, stage, after=after, before=before, name=name)
        system.world = self
        return system

    def wake(self) -> None:
        """Read every system's ``requires`` again before the next step: for a system whose work changed
        without any entity gaining or losing a component (a key pressed, a track given to the input
        system), so that one idle until then is called."""
        self._plans.clear()

    def remove_system(self, system: object) -> None:
        """Take ``system`` out of the schedule (its ``release()`` is called when it has one)."""
        self._schedule.remove(system)
        release = getattr(system, "release", None)
        if callable(release):
            release()

    @property
    def systems(self) -> dict[str, list]:
        """Systems by stage (unstaged ones under their own name), in running order."""
        out: dict[str, list] = {s: [] for s in STEP_STAGES + FRAME_STAGES}
        for phase in ("step", "frame"):
            for e in self._order[phase]:
                out.setdefault(e.stage or e.name, []).append(e.system)
        return out

    def get_system(self, cls: type[_S]) -> _S | None:
        """The first scheduled system that is an instance of ``cls``, or None."""
        for phase in ("step", "frame"):
            for e in self._order[phase]:
                if isinstance(e.system, cls):
                    return e.system
        return None

    def resource(self, key: type[_R]) -> _R:
        """The resource of type ``key`` (``world.resources[key]``, typed as a ``key``).

        None there is a KeyError naming the type and who publishes it (a system that declares it in its
        ``writes``, or the type's ``published_by``); a value not of that type is a TypeError."""
        validate.a_class("resource(key): key", key, "TimeWarp")
        value = self.resources[key]
        if not isinstance(value, key):
            raise TypeError(f"world {self.name!r}: resources[{key.__name__}] holds a {type(value).__name__}, "
                            f"not a {key.__name__}")
        return value

    def _writers(self, key: object) -> list[str]:
        """The systems that declare resource ``key`` in their writes (for a missing resource's error)."""
        name = key.__name__ if isinstance(key, type) else key
        return [f"system {e.name!r} ({type(e.system).__name__})" for e in self._schedule.entries
                if name in e.written]

    def describe(self) -> str:
        """The schedule as text: each system in running order with its stage, reads and writes; then the
        resources the world holds now, by type."""
        held = ", ".join(sorted(key_name(k) for k in self.resources)) or "-"
        return self._schedule.describe(self.dt) + f"resources: {held}\n"

    def _idle(self, e: Entry) -> None:
        """Decide whether ``e``'s system has nothing to do now: it declares ``requires`` and no entity has
        all of them. Once per structure epoch (an esper query, which esper caches until it changes)."""
        req = _requires(e.system)
        e.idle = bool(req) and not esper.get_components(*req)
        e.idle_epoch = self.epoch

    def _busy(self, e: Entry) -> bool:
        self._idle(e)
        return not e.idle

    def _plan(self, phase: str) -> tuple:
        """The systems of ``phase`` that have work at this structure epoch (see add_system's ``requires``;
        :meth:`Schedule.plan`), made anew when the epoch, the schedule or the number of resources
        changes, or after :meth:`wake`. A new plan zeroes the phase's profile lines: those of the systems
        it leaves out stay 0 while it holds."""
        kept = self._plans.get(phase)
        version = self._schedule.version
        resources = len(self.resources)             # (a system may need a resource: the warp governor)
        if kept is not None and kept[0] == self.epoch and kept[1] == version and kept[3] == resources:
            return kept[2]
        plan = self._schedule.plan(phase, self._busy)
        self._plans[phase] = (self.epoch, version, plan, resources)
        self.profile.update(self._schedule.zero[phase])
        return plan

    def _rest(self, phase: str, plan: tuple, e: Entry) -> tuple:
        """What is left of this step's ``plan`` after ``e``'s system changed which entities have what:
        the systems after it that have work now (a system made busy by an earlier one runs in the same
        step; one made idle does not, and its profile line reads 0)."""
        written: set[str] = set()
        k = 0
        while True:
            written.add(plan[k][2])
            if plan[k][0] is e:
                break
            k += 1
        for p in plan[k + 1:]:
            if p[2] not in written:
                self.profile[p[2]] = 0.0
        return self._schedule.plan(phase, self._busy, after=e, written=written)

    def _run(self, phase: str, dt: float) -> None:
        name = self.name
        if self.closed:
            self.activate()                         # (raises: closed)
        unchanged = ea.structure_unchanged
        # current, its dead entities deleted, and self.sync()'s fast path: esper's cache is clean and holds
        # the probe list of the last sync, so no entity gained or lost a component (code outside the step
        # may have); then after every system
        if not ea.ready(name, self._probe):
            self.sync()
        kept = self._plans.get(phase)               # (self._plan(phase)'s test, inline: the usual step)
        if kept is not None and kept[0] == self.epoch and kept[1] == self._schedule.version \
                and kept[3] == len(self.resources):
            plan = kept[2]
        else:
            plan = self._plan(phase)
        clock = time.perf_counter
        profile, total = self.profile, self.profile_total
        checked = access_check.enabled
        outer = access_check.running                # (a system of another world stepping this one)
        last = None                                 # the system running, or the last one that ran
        # one clock read per system: each one's time runs from the end of the one before (its line in the
        # profile holds the loop's few bookkeeping operations too)
        t0 = clock()
        try:
            while plan:
                todo, plan = plan, ()
                for e, system, key, first, check in todo:
                    last = e
                    if checked and e.checked:
                        access_check.running = (name, e)
                    system.process(dt)
                    t1 = clock()
                    took = t1 - t0
                    t0 = t1
                    if checked:
                        access_check.running = outer
                    if first:
                        profile[key] = took
                    else:
                        profile[key] += took
                    total[key] += took
                    if check and not unchanged(self._probe, name):
                        epoch = self.epoch
                        self.sync()
                        t0 = clock()                # (the sync is booked under no system)
                        if self.epoch != epoch:     # an entity gained or lost a component: plan the rest anew
                            plan = self._rest(phase, todo, e)
                            break
        except BaseException as exc:
            if checked:
                access_check.running = outer
            if phase == "step" and last is not None:
                self._break(last, exc)
            raise

    def _break(self, e: Entry, exc: BaseException) -> None:
        """Mark this world half-stepped: ``e``'s system raised ``exc`` (or the world's bookkeeping raised
        after it ran), after it and the systems before it had changed the world."""
        self.broken = (f"world {self.name!r} is broken: in step {self.step_count + 1}, system {e.name!r} "
                       f"({type(e.system).__name__}) raised {type(exc).__name__}: {exc}. It and the systems "
                       "before it had already changed the world, so stepping on would step them twice: load a "
                       "save into it (world.restore(path)) or make it again (World.load(path))")
        self._broken_by = exc

    def _check_whole(self, doing: str) -> None:
        if self.broken is not None:
            raise WorldBrokenError(f"cannot {doing}: {self.broken}") from self._broken_by

    # -- events -----------------------------------------------------------------
    def emit(self, event: object) -> None:
        """Record ``event`` in :attr:`events` and call every subscriber of its type at once."""
        if access_check.running is not None:
            access_check.touched(type(event), "world.emit", write=True, world=self.name)
        self.events.append(event)
        subs = self._subscribers.get(type(event), ())
        if subs and access_check.running is not None:
            running, access_check.running = access_check.running, None     # a subscriber is not the system
            try:
                for fn in subs:
                    fn(event)
            finally:
                access_check.running = running
            return
        for fn in subs:
            fn(event)

    def subscribe(self, event_type: type[_E], callback: Callable[[_E], object]) -> Callable[[], None]:
        """Call ``callback(event)`` for every emitted event of ``event_type``; returns an unsubscribe function."""
        validate.a_class("subscribe: event_type", event_type, "CollisionEvent")
        validate.function("subscribe: callback", callback)
        subs = self._subscribers[event_type]
        subs.append(callback)

        def unsubscribe() -> None:
            if callback in subs:
                subs.remove(callback)
        return unsubscribe

    # -- stepping ---------------------------------------------------------------
    def step(self, n: int = 1) -> None:
        """Advance the simulation by ``n`` fixed steps of ``dt``.

        A step in which a system raises leaves the world broken (:attr:`broken`): the systems before it
        moved it, the rest did not. The exception goes on to the caller; every later ``step()`` (and
        ``save()``) raises :class:`WorldBrokenError` naming the system and the exception, until a save is
        loaded into the world (:meth:`restore`)."""
        if self.broken is not None:
            self._check_whole("step")
        if self._rendered or not self._order["frame"]:
            self.previous_events, self.events = self.events, []
            self._rendered = False
        for _ in range(n):
            try:
                self._run("step", self.dt)
            except BaseException:
                self.step_context.close()           # a prediction of a step that did not end is never committed
                raise
            self.step_count += 1

    def render(self) -> None:
        """Run the per-frame systems (render, record) once; the frame's events are then consumed.

        Resources with a ``frame_scope()`` (a GL context: :class:`framework.gl.ContextHandle`) are
        entered for the frame, so a process with several worlds, each with its own context, draws each
        into its own."""
        with self._frame_scopes():
            self._run("frame", self.dt)
        self._rendered = True

    def _frame_scopes(self) -> ExitStack:
        """The ``frame_scope()`` of every resource that has one, entered (see :meth:`render`)."""
        scopes = ExitStack()
        for res in list(self.resources.values()):
            scope = getattr(res, "frame_scope", None)
            if scope is not None:
                scopes.enter_context(scope())
        return scopes

    @property
    def time(self) -> float:
        """Simulated seconds since the start (step_count * dt)."""
        return self.step_count * self.dt

    # -- determinism ------------------------------------------------------------
    def state_hash(self) -> str:
        """BLAKE2 hash of the simulation's state (exact bytes of every simulated number): the same for two
        runs of the same scene with the same inputs, whatever the entity order or row placement; the
        presentation (a Camera and its entity) left out. See :mod:`~driftframe.framework.state_hash`."""
        return _state_hash(self)

    # -- saves ----------------------------------------------------------------------
    def save(self, path: PathLike, *, overwrite: bool = False) -> str:
        """Write this world to ``path`` (a ``.npz``: columns, plus a JSON manifest), atomically; an
        existing file is refused unless ``overwrite``. See :mod:`driftframe.framework.save`."""
        from driftframe.framework import save
        return save.save(self, path, overwrite=overwrite)

    def __copy__(self) -> NoReturn:
        raise TypeError(self._no_copy("copied (copy.copy)"))

    def __deepcopy__(self, memo: dict[int, Any]) -> NoReturn:
        raise TypeError(self._no_copy("copied (copy.deepcopy)"))

    def __reduce_ex__(self, protocol: Any) -> NoReturn:
        raise TypeError(self._no_copy("pickled"))

    def _no_copy(self, how: str) -> str:
        # a copy would share the esper context (closing it would delete this world's entities), the systems'
        # GL handles and the subscribers' closures: a save is the one complete, independent copy of a world
        return (f"a World cannot be {how}: it owns an esper context, GL handles and callbacks. For an "
                f"independent world with the same state_hash, save it and load the save: "
                f"world.save(path) then World.load(path) (or World.load(path, build=...))")

    @classmethod
    def load(cls, path: PathLike, build: Callable[[], World] | None = None) -> World:
        """The world saved in ``path``: rebuilt (``make_world`` of the scene the save names, or
        ``build()``, which returns a world with its systems), then its entities, step count, resources
        and systems' state replaced by the saved ones; it steps on bit-identically."""
        from driftframe.framework import save
        return save.load(path, build=build)

    def restore(self, path: PathLike) -> None:
        """Replace this world's state with the save in ``path`` (quick-load: this world keeps its systems)."""
        from driftframe.framework import save
        save.restore(self, path)

    def prepare(self) -> None:
        """Do now the one-time work the first step would do: reconcile the tables with esper and let
        every system that has a ``prepare()`` build what it caches for the current entities (packed
        rows, buffers), then run the step's built-in stages dry (:meth:`_rehearse`: no other system
        runs). Call it when a level has loaded, so the first frame is not the slow one; it
        changes no state (the hash is the same with and without it), and the systems rebuild
        whatever a later change of entities makes stale, as they always do."""
        self.activate()
        self.sync()
        for phase in ("step", "frame"):
            for e in self._order[phase]:
                prepare = getattr(e.system, "prepare", None)
                if callable(prepare):
                    prepare()
                    self.sync()
        for phase in ("step", "frame"):
            self._plans.pop(phase, None)
            self._plan(phase)                   # which systems have nothing to do (see add_system's requires)
        self._rehearse()

    def _rehearse(self) -> None:
        """A dry step, run up to :data:`REHEARSALS` times: the step's built-in stages whose ``process`` now
        changes nothing but the step context and their own caches (``dry_run_safe(dt)``: the movement
        stage, and the collision stage where its prepare() found the coming step quiet), then the
        commit, which writes back the bytes the tables hold (the context refilled from them first);
        through World.step itself, the systems' own ``process`` (the same calls as a step: a dry step
        of stand-ins left the first step 2x slower than one of the systems). No other system runs; the
        step count, the events and the profile are put back. Why: the first step after a level's load
        otherwise runs its code and data out of the CPU's caches (and untrained branch predictors) after
        the load's other work, and in a fresh process on code objects the interpreter has not yet
        quickened, several times a tiny scene's median step (docs/bench/collision_stress.md, "First
        step"). The state is the same (its hash too). No dry step starts after :data:`REHEARSAL_BUDGET`
        seconds of them."""
        kept = self._plans.get("step")
        if kept is None or self.broken is not None:
            return
        dt, ctx = self.dt, self.step_context
        dry: list = []
        for e, s, key, first, _ in kept[2]:
            if type(s) is Commit:
                dry += [(e, _Refill(ctx), key, first, False), (e, s, key, False, False)]
                continue
            safe = getattr(s, "dry_run_safe", None)
            if callable(safe) and safe(dt):
                dry.append((e, s, key, first, False))
        if all(type(d[1]) in (Commit, _Refill) for d in dry):
            return                                      # (nothing but the commit to rehearse)
        profile, total = dict(self.profile), dict(self.profile_total)
        # what step() itself changes, put back after each dry step (World.step: a subclass's step is not called)
        kept_step = self.step_count, self.events, self.previous_events, self._rendered
        self._plans["step"] = kept[:2] + (tuple(dry),) + kept[3:]
        try:
            t = time.perf_counter()
            for _ in range(REHEARSALS):
                World.step(self)
                self.step_count, self.events, self.previous_events, self._rendered = kept_step
                if time.perf_counter() - t > REHEARSAL_BUDGET:
                    break
        except BaseException:
            self.broken = self._broken_by = None        # (nothing was changed: the world is whole, as it was)
            raise
        finally:
            ctx.close()
            self.step_count, self.events, self.previous_events, self._rendered = kept_step
            self._plans["step"] = kept
            self.profile.update(profile)
            self.profile_total.clear()
            self.profile_total.update(total)

    def close(self) -> None:
        """Release what every system and resource holds (GL objects included), free the tables,
        and delete the esper world context. Components keep their values."""
        if self.closed:
            return
        with self._frame_scopes():           # (a system's GL objects are freed in its own context)
            for phase in ("frame", "step"):
                for e in reversed(self._order[phase]):
                    release = getattr(e.system, "release", None)
                    if callable(release):
                        release()
            for res in list(self.resources.values()):
                release = getattr(res, "release", None)
                if callable(release):
                    release()
        self.resources.clear()
        for table in self._tables.values():
            table.detach_all()
            table.world = None
        self._tables.clear()
        self._queries.clear()
        self._subscribers.clear()
        ea.delete(self.name)
        self.closed = True

    def __enter__(self) -> World:
        return self.activate()

    def __exit__(self, *exc: object) -> None:
        self.close()
