"""What an entity looks like: which cached model draws it, in which colour.

Cold data (a plain frozen dataclass): the render system groups entities by
model only when esper's query result changes, so a ``ModelRef`` is never
edited in place — to change how an entity looks, replace the component
(``esper.add_component(ent, ModelRef("ship"))``), which esper notices.
"""
from __future__ import annotations

from dataclasses import dataclass

from driftframe.framework import validate
from driftframe.framework.model_cache import check_colour


@dataclass(frozen=True)
class ModelRef:
    """Draw this entity (it needs a Transform) with the cached model ``name``.

    ``name``: a model in the world's :class:`framework.model_cache.ModelCache`
    (``"sphere"``, ``"ship"``, a variant such as ``"asteroid_7"``...).
    ``colour``: RGB in [0, 1] for this entity, or None for the model's colour.
    The model matrix is ``T R S``: the entity's position and orientation, the
    model's scale.
    """

    name: str
    colour: tuple[float, float, float] | None = None

    def __post_init__(self):
        validate.text("ModelRef.name", self.name, "a non-empty model name (str)")
        if self.colour is not None:
            object.__setattr__(self, "colour", tuple(check_colour("ModelRef.colour", self.colour).tolist()))
