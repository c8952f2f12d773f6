"""The one place driftframe reads esper's internals: esper's world contexts and its module state.

esper (3.x) keeps the current world's state in module globals (``_components``,
``_entities``, ``_cache_dirty``, ``_get_component_cache``, ``_entity_count``,
...) and swaps them on ``switch_world``. driftframe needs a few things esper
has no public function for: whether any entity gained or lost a component
since a given moment (one identity check per system per step), which
component classes exist, the entity ids alive and the next one (a save), and
making an entity with a given id (a load). Every such access is a function
here, so an esper release that renames a global breaks this file (and
``tests/test_esper_adapter.py``), not the world; :func:`check` says at import
which global is missing.

Structure probe: :class:`Probe` is never a component of any entity, so
``esper.get_component(Probe)`` is an empty list that esper caches until the
next structural change (``_cache_dirty``) and then hands out anew; holding the
list returned at one moment, ``structure_unchanged(probe, name)`` tells in one
call whether anything was added or removed in world ``name`` since.
"""
from __future__ import annotations

import itertools
import re
from typing import Any, Iterable

import esper

#: esper's module globals this file reads or writes (checked at import, :func:`check`).
USED = ("_cache_dirty", "_get_component_cache", "_components", "_entities", "_dead_entities", "_entity_count",
        "current_world", "switch_world", "list_worlds", "delete_world")


def check() -> None:
    """Raise ImportError naming esper's version and the missing names if esper lacks what this file uses."""
    missing = [n for n in USED if not hasattr(esper, n)]
    if missing:
        raise ImportError(f"esper {getattr(esper, '__version__', '?')} lacks {', '.join(missing)}, which "
                          "driftframe's esper adapter uses (driftframe is tested with esper 3.x)")


check()


class Probe:
    """Never a component of any entity: esper hands out a new (empty) list for it after every structural
    change, so its identity tells in one call whether anything was added or removed."""


# -- world contexts -----------------------------------------------------------------------------------

def current() -> str:
    """The name of esper's current world context."""
    return esper.current_world


def exists(name: str) -> bool:
    return name in esper.list_worlds()


def switch(name: str) -> None:
    """Make world context ``name`` current (esper makes it if it does not exist)."""
    if esper.current_world != name:
        esper.switch_world(name)


def delete(name: str) -> None:
    """Delete world context ``name`` and everything in it (the current context becomes "default")."""
    if esper.current_world == name:
        esper.switch_world("default")
    if name in esper.list_worlds():
        esper.delete_world(name)


# -- structure (in the current context) ------------------------------------------------------------------

def probe() -> list:
    """The current probe list (see the module's text)."""
    return esper.get_component(Probe)


def structure_unchanged(probe: list | None, name: str) -> bool:
    """World ``name`` is current, esper's cache is clean and holds ``probe``: no entity gained or lost a
    component since ``probe`` was taken. The fast path of every system of every step."""
    return (not esper._cache_dirty and esper._get_component_cache.get(Probe) is probe
            and esper.current_world == name)


def ready(name: str, probe: list | None) -> bool:
    """The start of a step of world ``name``: make it current, finish deleting the entities marked dead
    (``esper.clear_dead_entities``), then :func:`structure_unchanged` (one call, not three: a small
    scene's step is mostly such calls)."""
    if esper.current_world != name:
        esper.switch_world(name)
    if esper._dead_entities:
        esper.clear_dead_entities()
    return not esper._cache_dirty and esper._get_component_cache.get(Probe) is probe


def component_types() -> list[type]:
    """Every component class some entity had since esper last dropped it (some may have no holder now)."""
    return [c for c in esper._components if isinstance(c, type)]


def holders(cls: type) -> set[int]:
    """The entities that have a ``cls`` component (live or pending deletion); an empty set if none."""
    return esper._components.get(cls, set())


def live_entities() -> list[int]:
    """Every entity id alive (not pending deletion), ascending."""
    dead = esper._dead_entities
    return sorted(e for e in esper._entities if e not in dead)


def next_entity() -> int:
    """esper's next entity id (its counter, read without taking one)."""
    m = re.fullmatch(r"count\((\d+)\)", repr(esper._entity_count))
    if m is None:
        raise RuntimeError(f"esper's entity counter is not an itertools.count: {esper._entity_count!r}")
    return int(m.group(1))


def delete_all_entities() -> None:
    """Delete every entity of the current context now."""
    for e in list(esper._entities):
        esper.delete_entity(e, immediate=True)
    esper.clear_dead_entities()


def create_with_ids(entities: Iterable[tuple[int, Iterable[Any]]], next_id: int) -> None:
    """Make each ``(id, components)`` entity with exactly that id, then set the next id to ``next_id``
    (above every id given). A load puts saved entities back under their own ids."""
    for e, comps in entities:
        esper._entity_count = itertools.count(e)
        esper.create_entity(*comps)
    esper._entity_count = itertools.count(next_id)
