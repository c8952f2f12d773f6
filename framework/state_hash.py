"""A World's state as one hash: what a determinism test pins and a hash log compares step by step.

:func:`state_hash` is BLAKE2 over the exact bytes of every simulated number,
as Box2D's ``test_determinism.c`` hashes its bodies after N steps. Two runs of
the same scene with the same inputs give the same hash; any difference in any
bit of any simulated component changes it. Entity order and table row
placement do not matter: values are gathered per entity id, in ascending
order. Presentation is left out: components whose class says
``presentation = True`` (a Camera) and every component of their entities
(the camera's eye), so a headless run and a rendered run of the same bodies
hash the same. ``World.state_hash`` calls it.
"""
from __future__ import annotations

import dataclasses
import hashlib
from typing import TYPE_CHECKING

import esper
import numpy as np

from driftframe.framework import esper_adapter as ea
from driftframe.framework.store import Columnar

if TYPE_CHECKING:
    from driftframe.framework.world import World


def describe(comp) -> str:
    """Stable text of a plain (non-columnar) component: its fields, never its address."""
    if dataclasses.is_dataclass(comp):
        return repr(dataclasses.astuple(comp))
    fields = getattr(comp, "__dict__", None)
    return repr(sorted(fields.items())) if fields else ""


def state_hash(world: World) -> str:
    """BLAKE2 hash (16 bytes, hex) of ``world``'s step count and simulated components (see above)."""
    world.sync()
    h = hashlib.blake2b(digest_size=16)
    h.update(str(world.step_count).encode())
    kinds = sorted(ea.component_types(), key=lambda c: (c.__module__, c.__qualname__))
    skip: set[int] = set()
    for cls in kinds:
        if getattr(cls, "presentation", False):
            skip.update(ea.holders(cls))
    for cls in kinds:
        if getattr(cls, "presentation", False):
            continue
        ents = np.array(sorted(e for e in ea.holders(cls) if e not in skip), np.int64)
        h.update(cls.__qualname__.encode())
        h.update(ents.tobytes())
        if issubclass(cls, Columnar):
            table = world._table(cls)
            rows = table.rows_of(ents)
            for name in cls._fields:
                h.update(np.ascontiguousarray(table.data[name][rows]).tobytes())
        else:
            for e in ents.tolist():
                h.update(describe(esper.component_for_entity(e, cls)).encode())
    return h.hexdigest()
