"""What a world was built from, as typed resources: the scene's seed and the recipe that builds it again.

``world.resources[Seed]`` is the scene's seed: :func:`driftframe.make_world` sets it, and what a later step
generates from it (the starfield's cube map: :func:`systems.skybox.texture_rng`) derives its own stream
from it, so the scene's own random numbers do not change. A world you build yourself sets it if it wants
one: ``world.resources[Seed] = Seed(7)``. A save holds it (it is data).

``world.resources[SceneRecipe]`` is how :func:`driftframe.make_world` made the world: the scene's name,
seed and options, the function that builds it (a save names it, and ``World.load`` calls it:
:mod:`framework.save`) and the scene itself (its module, or the function of a ``module:function`` scene).
A save does not hold it as a resource: the save's ``scene`` field is its :meth:`SceneRecipe.manifest`,
and the rebuild makes it again.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from driftframe.framework import validate


@dataclass(frozen=True)
class Seed:
    """The scene's seed, an int >= 0 (``world.resources[Seed].value``)."""

    value: int
    #: Who makes it (named when a world has none: :meth:`World.resource`).
    published_by = "driftframe.make_world sets it; a world built by hand sets world.resources[Seed] = Seed(n)"

    def __post_init__(self) -> None:
        v = self.value
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise ValueError(f"Seed must be an int >= 0, got {validate.shown(v)}")


def seed_of(world: Any, default: int = 0) -> int:
    """The world's seed (``world.resources[Seed].value``), or ``default`` when it has none."""
    seed = world.resources.get(Seed)
    return default if seed is None else seed.value


@dataclass(frozen=True, eq=False)
class SceneRecipe:
    """How :func:`driftframe.make_world` built a world: ``make_world(name, seed=seed, scripted=scripted,
    collision=collision)`` through ``builder`` (``"module:function"``); ``track``: it flew a track of its
    own (a rebuild cannot make that again). ``scene``: the scene it built (a demo module, or the scene
    function's wrapper), whose ``SKY`` says the default sky."""

    name: str
    seed: int
    scripted: bool
    collision: str
    track: bool
    builder: str
    scene: Any = field(default=None, repr=False)
    published_by = "driftframe.make_world sets it; a world built by hand has none"
    saved = False           # code (the scene's module): the rebuild makes it again; a save's "scene" field names it

    def manifest(self) -> dict:
        """The save's ``scene`` field: the recipe without the scene's code (see :mod:`framework.save`)."""
        return {"name": self.name, "seed": self.seed, "scripted": self.scripted, "collision": self.collision,
                "track": self.track, "builder": self.builder}
