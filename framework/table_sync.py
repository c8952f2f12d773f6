"""A World's columnar tables kept in step with esper: who owns which row, checked on the way in.

A columnar component (``Transform``, ``Velocity``, ...) lives in a row of its
class's :class:`~driftframe.framework.store.Table`; esper holds the component
object, the table its numbers. The world's own ``create_entity`` /
``add_component`` / ``remove_component`` / ``delete_entity`` attach and free
rows at once (:func:`check_new`, :func:`attach_now`). esper's module functions,
called from a system or from user code, change only esper: :func:`sync` finds
what changed and :func:`reconcile` brings each class's table back in step
(new components attached, rows of removed ones freed, a component moved to
another entity followed). ``World.sync`` calls it when its one-check fast path
sees a change; the lifecycle is in ``store.py``.

A component object belongs to one entity of one world: given to two entities,
or to an entity of another world, it is a ValueError naming both, never two
entities silently sharing one row.
"""
from __future__ import annotations

from operator import attrgetter, itemgetter
from typing import TYPE_CHECKING, NoReturn

import esper
import numpy as np

from driftframe.framework import esper_adapter as ea
from driftframe.framework.store import Columnar

if TYPE_CHECKING:
    from driftframe.framework.world import World

_FIRST, _SECOND = itemgetter(0), itemgetter(1)
_ROW, _TABLE = attrgetter("_row"), attrgetter("_table")


def shared_error(cls: type, a: int, b: int) -> NoReturn:
    raise ValueError(f"the same {cls.__name__} object is on entities {a} and {b}; give each entity its "
                     f"own (copy.copy(component))")


def check_free(world: World, comp: Columnar, ent: int) -> None:
    """``comp`` is not in an entity of another world (it is about to join ``ent`` of ``world``)."""
    owner = comp._table.world
    if owner is not None and owner != world.name:
        raise ValueError(f"{type(comp).__name__} given to entity {ent} belongs to an entity of world "
                         f"{owner!r}; a component cannot be in two worlds: copy it (copy.copy)")


def check_new(world: World, comps) -> None:
    """Components about to join ``world``: not in another entity, of this world or another."""
    sources = {id(t): t for t in map(_TABLE, comps)}            # a few: one per bulk block
    for t in sources.values():
        if t.world is None:
            continue
        comp = next(c for c in comps if c._table is t)
        if t.world == world.name:
            raise ValueError(f"the same {type(comp).__name__} object is on entity {int(t.entity[comp._row])} "
                             "already; give each entity its own (copy.copy(component))")
        check_free(world, comp, -1)
    if len(comps) > 1 and len(set(map(id, comps))) != len(comps):
        raise ValueError(f"the same {type(comps[0]).__name__} object is given to two new entities; give "
                         "each its own (copy.copy(component))")


def attach_now(world: World, ent: int, components) -> None:
    """Give each columnar component of ``components`` (just added to entity ``ent``) its row."""
    for comp in components:
        if isinstance(comp, Columnar):
            table = world._table(type(comp))
            if comp._table is table:
                if table.entity[comp._row] != ent:
                    shared_error(type(comp), int(table.entity[comp._row]), ent)
                continue
            check_free(world, comp, ent)
            table.attach(np.array([ent]), [comp])


def sync(world: World) -> None:
    """Reconcile every table of ``world`` with esper after a structural change (``World.sync``'s slow
    path): bumps ``world.epoch`` when anything was added or removed since the last sync."""
    world.activate()
    probe = ea.probe()
    if probe is world._probe:
        return
    world.epoch += 1
    present = [c for c in ea.component_types() if issubclass(c, Columnar)]
    for cls in present:
        lst = esper.get_component(cls)
        if lst is not world._synced.get(cls):
            reconcile(world, cls, lst)
    for cls, table in list(world._tables.items()):
        if not ea.holders(cls) and table.live:
            reconcile(world, cls, [])
    world._probe = ea.probe()


def reconcile(world: World, cls: type, lst: list) -> None:
    """Bring ``cls``'s table in step with ``lst``, esper's ``[(entity, component), ...]`` of ``cls``."""
    table = world._table(cls)
    n = len(lst)
    ents = np.fromiter(map(_FIRST, lst), np.int64, n)
    comps = list(map(_SECOND, lst))
    tables = list(map(_TABLE, comps))
    count = tables.count(table)
    if count == n:
        mine = np.ones(n, bool)
    elif count == 0:
        mine = np.zeros(n, bool)
    else:
        mine = np.fromiter((t is table for t in tables), bool, n)
    k_mine = np.flatnonzero(mine)
    rows = np.fromiter((comps[k]._row for k in k_mine), np.intp, len(k_mine)) if len(k_mine) < n \
        else np.fromiter(map(_ROW, comps), np.intp, n)
    if len(rows) and len(np.unique(rows)) != len(rows):
        u, first, counts = np.unique(rows, return_index=True, return_counts=True)
        dup = u[counts > 1][0]
        a, b = ents[k_mine[rows == dup]][:2]
        shared_error(cls, int(a), int(b))
    # a component moved to another entity by esper (removed from one, added to another)
    table.entity[rows] = ents[k_mine]
    seen = np.zeros(table.size, bool)
    seen[rows] = True
    gone = np.flatnonzero((table.entity[: table.size] >= 0) & ~seen)
    table.detach(gone)
    if len(k_mine) < n:
        k_new = np.flatnonzero(~mine)
        new = [comps[k] for k in k_new]
        if len(set(map(id, new))) != len(new):
            seen_ids: dict[int, int] = {}
            for k, c in zip(k_new, new):
                if id(c) in seen_ids:
                    shared_error(cls, seen_ids[id(c)], int(ents[k]))
                seen_ids[id(c)] = int(ents[k])
        sources = {id(t): t for t in map(_TABLE, new)}          # a few: one per bulk block
        if any(t.world is not None and t.world != world.name for t in sources.values()):
            for k, c in zip(k_new, new):
                check_free(world, c, int(ents[k]))
        table.attach(ents[k_new], new)
    world._synced[cls] = lst
