"""The checking mode: a system that touches what it did not declare is an error, at the line that touches it.

A system declares what it ``reads`` and ``writes`` (components, resource
types, event types; and the components it ``requires``). The schedule orders
by those declarations and warns when two unordered systems conflict, so a
declaration that lies makes both wrong. In the checking mode (the tests run
in it: ``DRIFTFRAME_CHECK_ACCESS=1``, set by ``tests/conftest.py``; or
:func:`enable`), while a system's ``process`` runs, each of these is checked
against its declaration and an undeclared type is an :class:`AccessError`
naming the system, the type and the call. A system that declares anything
(``reads``, ``writes`` or ``requires``) is held to all of it; one that
declares nothing at all (a quick test's system) is not checked.

* ``world.table(T)``, ``world.columns(T)``, ``world.query(T, ...)`` and a
  query's ``refresh()``;
* esper's getters and setters (``esper.get_components``,
  ``component_for_entity``, ``try_component``, ``has_component``,
  ``add_component``, ``remove_component``, ...), by whoever calls them
  (a helper a system calls counts as the system);
* a type-keyed resource read or written (``world.resources[TimeWarp]``: a
  write must be in ``writes``), and an event emitted (in ``writes``).

Off, it costs one test per system per step. A table a system keeps from an
earlier call, and string-keyed resources, are not seen.
"""
from __future__ import annotations

import functools
import os
import sys
from typing import Any, Callable

import esper

ENV = "DRIFTFRAME_CHECK_ACCESS"
#: Whether worlds check their systems' access (read by the world at every step).
enabled = os.environ.get(ENV, "") not in ("", "0")
#: ``(world name, schedule entry)`` of the system whose ``process`` runs now, in the checking mode.
running: Any = None
# calls from these modules are the world's own bookkeeping (a reconcile, a save), not a system's access
_INTERNAL = frozenset({"esper", "driftframe.framework.world", "driftframe.framework.store",
                       "driftframe.framework.save", "driftframe.framework.esper_adapter",
                       "driftframe.framework.access_check", "driftframe.framework.resources",
                       "driftframe.framework.table_sync", "driftframe.framework.state_hash"})


class AccessError(RuntimeError):
    """A system touched a component, resource or event type it does not declare in reads/writes."""


def enable(on: bool = True) -> None:
    """Switch the checking mode on (or off) for every world, from the next step."""
    global enabled
    enabled = bool(on)
    if enabled:
        _install()


def touched(t: Any, how: str, write: bool = False, world: str | None = None) -> None:
    """The running system (if any, and of ``world`` when given) touches type ``t`` by ``how``: raise
    :class:`AccessError` unless it declares it (in ``writes`` when ``write``)."""
    run = running
    if run is None or (world is not None and run[0] != world):
        return
    entry = run[1]
    name = t if isinstance(t, str) else getattr(t, "__name__", repr(t))
    if name in (entry.written if write else entry.declared):
        return
    where = "writes" if write else "reads (or writes)"
    raise AccessError(f"system {entry.name!r} ({type(entry.system).__name__}) touches {name} through {how} "
                      f"but does not declare it: add {name} to its {where}")


def _types(name: str, args: tuple) -> tuple:
    if name in ("get_component", "get_components"):
        return args
    if name == "add_component":
        return (type(args[1]),) if len(args) > 1 else ()
    return args[1:]                         # (entity, T, ...): component_for_entity, try_component, has_components...


def _wrap(fn: Callable[..., Any], write: bool) -> Callable[..., Any]:
    name = fn.__name__

    @functools.wraps(fn)
    def checked(*args: Any, **kwargs: Any) -> Any:
        if running is not None and sys._getframe(1).f_globals.get("__name__") not in _INTERNAL:
            for t in _types(name, args):
                touched(t, f"esper.{name}", write)
        return fn(*args, **kwargs)
    checked.__wrapped_by_access_check__ = True        # type: ignore[attr-defined]
    return checked


_READERS = ("get_component", "get_components", "component_for_entity", "try_component", "try_components",
            "has_component", "has_components")
_WRITERS = ("add_component", "remove_component")


def _install() -> None:
    """Put the checking wrappers in esper's module (once; they pass through when no system runs)."""
    for names, write in ((_READERS, False), (_WRITERS, True)):
        for n in names:
            fn = getattr(esper, n)
            if not getattr(fn, "__wrapped_by_access_check__", False):
                setattr(esper, n, _wrap(fn, write))


if enabled:
    _install()
