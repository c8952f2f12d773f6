"""The demos: one scene per module, each a small composition of components.

A demo module defines ``TITLE``, ``DESCRIPTION`` (one line), ``SECONDS``
(default recording length), ``SCRIPT`` (a :class:`framework.input.Track`
that shows what the demo is for), optionally ``SEEDED = False`` (its build draws
nothing from ``rng``) and ``SKY`` (``"lines"``: the articles' green line cube instead of the
starfield), and ``build(world, rng)``, which creates
its entities with components and nothing else. Behaviour lives in
``systems/``.
"""
from __future__ import annotations

import importlib

#: Demo names in the order ``driftframe list`` shows them.
NAMES = ("rotation", "spin", "asteroids", "billiards", "cradle", "swarm", "orbit")


def load(name: str):
    """The demo module called ``name``; a clear error listing the demos otherwise."""
    if name not in NAMES:
        raise LookupError(f"unknown demo {name!r}; demos: {', '.join(NAMES)}")
    return importlib.import_module(f"{__name__}.{name}")
