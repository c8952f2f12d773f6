"""The schedule: which systems a world runs, in what order, and what each one touches.

A system is an ``esper.Processor`` with ``process(dt)`` that declares, as
class attributes, its ``stage`` (one of :data:`STEP_STAGES` or
:data:`FRAME_STAGES`, or none), its ``name`` (default: the class name in
snake case without "System") and what it ``reads`` and ``writes``: tuples of
component classes, resource types (``TimeWarp``, ``OrbitState``) and event
types (``CollisionEvent``). ``after``/``before`` name systems or stages (or
give a class); an impossible order is a :class:`ScheduleError` naming the
systems of the cycle.

Each phase (``"step"``: every fixed step; ``"frame"``: every presented frame)
is ordered topologically: stage order first, then ``after``/``before``, ties
by (stage, adding order), as bevy orders systems by constraints
(``rfcs/45-stageless.md``). Two systems with no order between them whose
access conflicts (one writes what the other reads or writes) run in an order
nothing guarantees: a :class:`ScheduleAmbiguityWarning` names them, as bevy's
ambiguity detection does (``examples/ecs/nondeterministic_system_order.rs``).
"""
from __future__ import annotations

import heapq
import io
import itertools
import re
import warnings
from typing import Any, Callable, Iterable, Iterator

from driftframe.framework.step import Commit

#: Stages run once per fixed simulation step, in this order.
STEP_STAGES = ("input", "control", "movement", "spin", "collision", "commit", "camera")
#: Stages run once per presented frame (window or recorder), in this order.
FRAME_STAGES = ("render", "record")
#: Where a system with no stage and no ``after``/``before`` runs: after commit (every body at the end of
#: the step), before camera.
DEFAULT_AFTER, DEFAULT_BEFORE = "commit", "camera"
_PHASES = (("step", STEP_STAGES), ("frame", FRAME_STAGES))


class ScheduleError(ValueError):
    """Systems that cannot be ordered as asked (a cycle, an unknown name, a frame/step mix-up)."""


class ScheduleAmbiguityWarning(UserWarning):
    """Two systems with no order between them touch the same thing, one of them writing it: which runs
    first is an accident of the adding order. Say it with ``after=``/``before=``."""


def system_name(system: object) -> str:
    """A system's ``name`` attribute, or its class name in snake case without "System"."""
    name = getattr(system, "name", None)
    if isinstance(name, str) and name:
        return name
    base = type(system).__name__
    base = base[:-6] if base.endswith("System") and len(base) > 6 else base
    return re.sub(r"(?<!^)(?=[A-Z])", "_", base).lower()


def access(system: object, attr: str) -> tuple:
    """A system's ``reads`` / ``writes`` (or ``requires``) as a tuple of classes (or names), checked."""
    value = getattr(system, attr, ())
    if isinstance(value, (type, str)):
        value = (value,)
    try:
        value = tuple(value)
    except TypeError:
        raise TypeError(f"{type(system).__name__}.{attr} must be a tuple of component, resource or event "
                        f"classes, got {value!r}") from None
    for v in value:
        if not isinstance(v, (type, str)):
            raise TypeError(f"{type(system).__name__}.{attr} must hold component, resource or event classes "
                            f"(or names), got {v!r}")
    return value


def requires(system: object) -> tuple:
    """A system's ``requires``: component classes, all of which some entity must have for it to run."""
    value = access(system, "requires")
    for v in value:
        if not isinstance(v, type):
            raise TypeError(f"{type(system).__name__}.requires must hold component classes, got {v!r}")
    return value


def type_name(t: type | str) -> str:
    return t if isinstance(t, str) else t.__name__


class Entry:
    """One scheduled system: its name, phase, stage and constraints; and whether, at the structure
    epoch ``idle_epoch``, it had nothing to do (see ``requires`` in :meth:`World.add_system`)."""

    __slots__ = ("system", "name", "phase", "stage", "after", "before", "seq", "key", "idle_epoch", "idle",
                 "declared", "written", "checked")

    def __init__(self, system: Any, name: str, phase: str, stage: str | None, after: tuple, before: tuple,
                 seq: int) -> None:
        self.system, self.name, self.phase, self.stage = system, name, phase, stage
        self.after, self.before, self.seq = after, before, seq
        self.key = stage or name                     # its line in World.profile
        self.idle_epoch, self.idle = -1, False
        #: What the system may touch (reads, writes and requires), by name: what the checking mode allows.
        #: Whether the checking mode holds it to its declaration: a system that declares anything (reads,
        #: writes or requires) is held to all of it; one that declares nothing is not (a quick test's system).
        self.checked = any(hasattr(system, a) for a in ("reads", "writes", "requires"))
        self.written = frozenset(type_name(t) for t in access(system, "writes"))
        self.declared = self.written | {type_name(t) for t in access(system, "reads") + access(system, "requires")}


def _refs(value: Any) -> tuple:
    if isinstance(value, (str, type)):
        value = (value,)
    out = []
    for v in value:
        if isinstance(v, (str, type)):
            out.append(v)
        else:
            raise TypeError(f"after/before take system or stage names or system classes, got {v!r}")
    return tuple(out)


def _matches(entry: Entry, ref: str | type) -> bool:
    if isinstance(ref, type):
        return isinstance(entry.system, ref)
    return entry.name == ref or entry.stage == ref


class Schedule:
    """A world's systems in running order, per phase (``order["step"]``, ``order["frame"]``)."""

    def __init__(self) -> None:
        self.entries: list[Entry] = []
        self.order: dict[str, list[Entry]] = {"step": [], "frame": []}
        # each phase's lines of the profile, all 0.0 (set at the start of each step / frame)
        self.zero: dict[str, dict[str, float]] = {"step": dict.fromkeys(STEP_STAGES, 0.0),
                                                   "frame": dict.fromkeys(FRAME_STAGES, 0.0)}
        self._seq = itertools.count()
        self._warned: set[tuple[int, int]] = set()
        #: Bumped whenever a system is added or removed: a world's plans (:meth:`plan`) made before are stale.
        self.version = 0

    def add(self, system: Any, stage: str | None = None, *, after: Any = (), before: Any = (),
            name: str | None = None) -> Entry:
        """Place ``system`` (see :meth:`World.add_system`); the schedule is unchanged when it cannot be."""
        for e in self.entries:
            if e.system is system:
                raise ValueError(f"system {e.name!r} ({type(system).__name__}) is in this world already: a system "
                                 "object is added once (make another to run it twice)")
        stage = stage if stage is not None else getattr(system, "stage", None)
        if stage is not None and stage not in STEP_STAGES + FRAME_STAGES:
            raise ScheduleError(f"unknown stage {stage!r}; stages are {STEP_STAGES + FRAME_STAGES}")
        if not callable(getattr(system, "process", None)):
            raise TypeError(f"system {system!r} has no process(dt) method")
        access(system, "reads")
        access(system, "writes")
        requires(system)
        after = _refs(after if after else getattr(system, "after", ()))
        before = _refs(before if before else getattr(system, "before", ()))
        if stage is None and not after and not before:
            after, before = (DEFAULT_AFTER,), (DEFAULT_BEFORE,)
        nm = name or system_name(system)
        phase = "frame" if stage in FRAME_STAGES else "step"
        if stage is None:
            phases = {self._phase_of(r) for r in after + before} - {None}
            if len(phases) > 1:
                raise ScheduleError(f"system {nm!r}: after={after} / before={before} mix per-step and per-frame "
                                    "systems")
            phase = phases.pop() if phases else "step"
        entry = Entry(system, nm, phase, stage, after, before, next(self._seq))
        self.entries.append(entry)
        try:
            self._build()
        except ScheduleError:
            self.entries.remove(entry)
            self._build()
            raise
        return entry

    def remove(self, system: Any) -> None:
        self.entries = [e for e in self.entries if e.system is not system]
        self._build()

    def running(self) -> Iterator[Entry]:
        """Every entry, the step's in order, then the frame's."""
        for phase, _ in _PHASES:
            yield from self.order[phase]

    def _phase_of(self, ref: str | type) -> str | None:
        if isinstance(ref, str):
            if ref in STEP_STAGES:
                return "step"
            if ref in FRAME_STAGES:
                return "frame"
        for e in self.entries:
            if _matches(e, ref):
                return e.phase
        return None

    def plan(self, phase: str, busy: Callable[[Entry], bool], after: Entry | None = None,
             written: set[str] | None = None) -> tuple[tuple[Entry, Any, str, bool, bool], ...]:
        """The systems of ``phase`` that have work (``busy(entry)``), in running order, each as
        ``(entry, system, profile key, first, check)``: what a step runs while no entity gains or loses a
        component (the world makes one per structure epoch, so an idle system costs nothing a step).
        ``first``: the first of the plan's systems to book its time under that key (it sets the
        profile's line, the others add to it). ``check``: whether the world looks for a change of
        entities after it (not after a system that declares ``keeps_entities = True``: its ``process``
        never adds or removes a component or an entity, nor calls code that could, such as event
        subscribers). ``after``: only the systems after that entry (a change of entities mid-step);
        ``written``: the profile keys already booked this step (updated)."""
        order = self.order[phase]
        if after is not None:
            order = order[order.index(after) + 1:]
        seen = set() if written is None else written
        out = []
        for e in order:
            if busy(e):
                check = getattr(e.system, "keeps_entities", False) is not True
                out.append((e, e.system, e.key, e.key not in seen, check))
                seen.add(e.key)
        return tuple(out)

    def _build(self) -> None:
        """Topological order of each phase: stage order, then after/before, ties by (stage, adding order)."""
        self.version += 1
        names = {e.name for e in self.entries}
        for e in self.entries:
            for ref in e.after + e.before:
                if isinstance(ref, str) and ref not in names and ref not in STEP_STAGES + FRAME_STAGES:
                    raise ScheduleError(f"system {e.name!r}: no system or stage named {ref!r}; systems: "
                                        f"{', '.join(sorted(names))}; stages: {', '.join(STEP_STAGES + FRAME_STAGES)}")
        ambiguous = []
        for phase, stages in _PHASES:
            entries = [e for e in self.entries if e.phase == phase]
            edges = _edges(entries, stages)
            order = _toposort(entries, edges, _ranks(entries, stages))
            self.order[phase] = order
            self.zero[phase] = dict.fromkeys(stages + tuple(e.key for e in order), 0.0)
            ambiguous += _ambiguities(order, _implied(entries, stages, edges))
        _check_held(self.order["step"])
        for a, b, what in ambiguous:
            if (a.seq, b.seq) not in self._warned:
                self._warned.add((a.seq, b.seq))
                warnings.warn(f"systems {a.name!r} and {b.name!r} both touch {what}, one writing it, and nothing "
                              f"orders them: give one after={a.name!r} or before={a.name!r}",
                              ScheduleAmbiguityWarning, stacklevel=4)

    def describe(self, dt: float) -> str:
        """The schedule as text: each system in running order with its stage, reads and writes."""
        out = io.StringIO()

        def names(ts: Iterable[type | str]) -> str:
            return ", ".join(type_name(t) for t in ts) or "-"

        for phase, title in (("step", f"every fixed step (dt = {dt:g} s)"), ("frame", "every presented frame")):
            out.write(f"{title}:\n")
            for k, e in enumerate(self.order[phase], 1):
                s = e.system
                out.write(f"  {k:2d}. {e.name:<14} {type(s).__name__:<22} stage: {e.stage or '-'}\n"
                          f"      reads:  {names(access(s, 'reads'))}\n"
                          f"      writes: {names(access(s, 'writes'))}\n")
                if requires(s):
                    out.write(f"      runs when an entity has: {names(requires(s))}\n")
        return out.getvalue()


def _ranks(entries: list[Entry], stages: tuple[str, ...]) -> dict[int, float]:
    """Each system's tie-break rank: its stage's index; an unstaged one half a stage after what it follows."""
    rank: dict[int, float] = {}
    for e in entries:
        if e.stage is not None:
            rank[e.seq] = float(stages.index(e.stage))
    for e in entries:
        if e.stage is None:
            ranks = [stages.index(r) + 0.5 for r in e.after if isinstance(r, str) and r in stages]
            ranks += [rank[o.seq] + 0.5 for o in entries for r in e.after
                      if o is not e and o.seq in rank and _matches(o, r)]
            if not ranks:
                ranks = [stages.index(r) - 0.5 for r in e.before if isinstance(r, str) and r in stages]
            rank[e.seq] = max(ranks) if ranks else len(stages) - 0.5
    return rank


def _edges(entries: list[Entry], stages: tuple[str, ...]) -> dict[int, set[int]]:
    """a -> b when a's stage comes before b's, or b says after=a, or a says before=b."""
    edges: dict[int, set[int]] = {e.seq: set() for e in entries}
    for a in entries:
        for b in entries:
            if a is b:
                continue
            if a.stage is not None and b.stage is not None and stages.index(a.stage) < stages.index(b.stage):
                edges[a.seq].add(b.seq)
            if any(_matches(a, r) for r in b.after) or any(_matches(b, r) for r in a.before):
                edges[a.seq].add(b.seq)
    return edges


def _toposort(entries: list[Entry], edges: dict[int, set[int]], rank: dict[int, float]) -> list[Entry]:
    by_seq = {e.seq: e for e in entries}
    indeg = {s: 0 for s in edges}
    for outs in edges.values():
        for o in outs:
            indeg[o] += 1
    ready = [(rank[s], s) for s, d in indeg.items() if d == 0]
    heapq.heapify(ready)
    order = []
    while ready:
        _, s = heapq.heappop(ready)
        order.append(by_seq[s])
        for o in edges[s]:
            indeg[o] -= 1
            if indeg[o] == 0:
                heapq.heappush(ready, (rank[o], o))
    if len(order) != len(entries):
        left = {s for s, d in indeg.items() if d > 0}
        raise ScheduleError("systems cannot be ordered, they form a cycle: "
                            + " -> ".join(_cycle(left, edges, by_seq)))
    return order


def _implied(entries: list[Entry], stages: tuple[str, ...], edges: dict[int, set[int]]) -> dict[int, set[int]]:
    """``edges`` plus what a stage name in ``after``/``before`` says of the staged systems: a system after
    stage s comes after every system of s and of the stages before it, one before s before every system
    of s and of the stages after it (the order already keeps this by rank; the edges make it checkable)."""
    out = {k: set(v) for k, v in edges.items()}
    staged = [x for x in entries if x.stage is not None]
    for e in entries:
        if e.stage is not None:
            continue
        for r in e.after:
            if isinstance(r, str) and r in stages:
                for x in staged:
                    if stages.index(x.stage) <= stages.index(r):           # type: ignore[arg-type]
                        out[x.seq].add(e.seq)
        for r in e.before:
            if isinstance(r, str) and r in stages:
                for x in staged:
                    if stages.index(x.stage) >= stages.index(r):           # type: ignore[arg-type]
                        out[e.seq].add(x.seq)
    return out


def _ambiguities(order: list[Entry], edges: dict[int, set[int]]) -> list[tuple[Entry, Entry, str]]:
    """Pairs of systems with no path between them in ``edges`` whose access conflicts (bevy's ambiguity
    detection): ``(first in order, second, what they share)``."""
    reach: dict[int, set[int]] = {}
    for e in order:                                 # what each system comes before, directly or not
        seen: set[int] = set()
        todo = list(edges[e.seq])
        while todo:
            o = todo.pop()
            if o not in seen:
                seen.add(o)
                todo.extend(edges[o])
        reach[e.seq] = seen
    acc = {e.seq: ({type_name(t) for t in access(e.system, "reads")}, {type_name(t) for t in access(e.system, "writes")})
           for e in order}
    out = []
    for i, a in enumerate(order):
        ra, wa = acc[a.seq]
        for b in order[i + 1:]:
            if b.seq in reach[a.seq] or a.seq in reach[b.seq]:
                continue
            rb, wb = acc[b.seq]
            shared = (wa & (rb | wb)) | (wb & ra)
            if shared:
                out.append((a, b, ", ".join(sorted(shared))))
    return out


def _check_held(order: list[Entry]) -> None:
    """No system between the movement stage and the commit writes what the step holds there (the
    commit would overwrite it: framework/step.py)."""
    moved = False
    for e in order:
        if isinstance(e.system, Commit):
            return
        if moved:
            held = [w for w in access(e.system, "writes") if type_name(w) in Commit.holds]
            if held:
                what = ", ".join(type_name(w) for w in held)
                raise ScheduleError(
                    f"system {e.name!r} writes {what} between the movement stage and the commit, where the "
                    f"step holds every body's {what}: the commit would overwrite what it writes. Place it "
                    "before='movement' (a force, a change of velocity) or after='commit' (the default)")
        moved = moved or e.stage == "movement"


def _cycle(left: set[int], edges: dict[int, set[int]], by_seq: dict[int, Entry]) -> list[str]:
    # systems after a cycle are left unordered too: drop those with no way on inside what is left,
    # until every one left leads to another (so the walk below ends on a cycle)
    left = set(left)
    while True:
        dead = {s for s in left if not any(o in left for o in edges[s])}
        if not dead:
            break
        left -= dead
    start = min(left)
    path, seen = [start], {start: 0}
    while True:
        nxt = min(o for o in edges[path[-1]] if o in left)
        if nxt in seen:
            cyc = path[seen[nxt]:] + [nxt]
            return [by_seq[s].name for s in cyc]
        seen[nxt] = len(path)
        path.append(nxt)
