"""A world's resources: shared per-world services and state, keyed by their type.

bevy keeps one value per type (``Res<Time>``); so does ``world.resources``:
``world.resources[TimeWarp]``, ``world.resources[OrbitState]``. A type key
says what the value is, a typo is an error at import rather than a silent
miss, and a system names the type in its ``reads``/``writes`` like a
component (the checking mode holds it to that: :mod:`.access_check`).
:meth:`World.resource` is the typed accessor: ``world.resource(TimeWarp)`` is a
``TimeWarp`` to a type checker, and a missing one is a KeyError that says who
publishes it.

A resource type may say, as class attributes, who makes it
(``published_by``: text for that error) and whether a save holds it
(``saved = False``: a handle or what the scene's build makes again, as the
model cache; see :mod:`.save`).

The framework's own resources are all typed: ``TimeWarp``, ``OrbitState``,
``Soundtrack``, ``ModelCache``, ``RenderTarget``, ``ContextHandle``,
``ModelFiles``, ``ModelVariants``, ``Seed`` and ``SceneRecipe``. The names
they had before (``"seed"``, ``"model_cache"``, ``"render_target"``,
``"gl"``, ``"demo"``, ``"make_world"``) are an error that names the type
(:data:`RENAMED`), read or written, rather than a silent miss. A string key
of your own still works, unchecked: a type is better.
"""
from __future__ import annotations

from typing import Any, Iterable, TypeVar

from driftframe.framework import access_check

T = TypeVar("T")


def publisher(key: Any, writers: Iterable[str] = ()) -> str:
    """Who makes resource ``key``: the systems that declare it in ``writes``, else its ``published_by``."""
    writers = list(writers)
    if writers:
        return f"{' and '.join(writers)} {'writes' if len(writers) == 1 else 'write'} it"
    hint = getattr(key, "published_by", None)
    if isinstance(hint, str) and hint:
        return hint
    return "no system of this world declares it in its writes"


#: The string keys the framework's resources had, and the type that keys each now (for the error).
RENAMED = {"seed": "Seed (driftframe.framework.scene.Seed; .value is the int)",
           "demo": "SceneRecipe (driftframe.framework.scene.SceneRecipe; .scene is the demo)",
           "make_world": "SceneRecipe (driftframe.framework.scene.SceneRecipe; .manifest() is the dict)",
           "model_cache": "ModelCache (driftframe.framework.model_cache.ModelCache)",
           "render_target": "RenderTarget (driftframe.framework.gl.RenderTarget)",
           "gl": "ContextHandle (driftframe.framework.gl.ContextHandle)"}


def renamed(key: Any) -> None:
    """Raise a KeyError when ``key`` is one of the framework's old string keys (:data:`RENAMED`)."""
    if isinstance(key, str) and key in RENAMED:
        raise KeyError(f"world.resources[{key!r}] is keyed by its type now: world.resources[{RENAMED[key]}]")


def key_name(key: Any) -> str:
    return key.__name__ if isinstance(key, type) else repr(key)


class Resources(dict):
    """``world.resources``: a dict keyed by type (or, the old way, by name). A missing type key is a
    KeyError naming the type and who publishes it. The world it belongs to names itself in the error."""

    def __init__(self, world_name: str = "", writers: Any = None) -> None:
        super().__init__()
        self._world_name = world_name
        self._writers = writers          # a function: key -> names of the systems that declare it in writes

    def __missing__(self, key: Any) -> Any:
        renamed(key)
        writers = self._writers(key) if self._writers is not None else ()
        where = f"world {self._world_name!r}" if self._world_name else "this world"
        raise KeyError(f"{where} has no {key_name(key)} resource: {publisher(key, writers)}")

    def get(self, key: Any, default: Any = None) -> Any:
        if type(key) is str:
            renamed(key)
        return super().get(key, default)

    def __setitem__(self, key: Any, value: Any) -> None:
        if type(key) is str:
            renamed(key)
        super().__setitem__(key, value)

    def __contains__(self, key: object) -> bool:
        if type(key) is str:
            renamed(key)
        return super().__contains__(key)


class CheckedResources(Resources):
    """:class:`Resources` in the checking mode: a type key read or written while a system runs must be
    declared in that system's ``reads``/``writes`` (string keys are not checked)."""

    def __getitem__(self, key: Any) -> Any:
        if isinstance(key, type):
            access_check.touched(key, "world.resources[...]")
        return super().__getitem__(key)

    def get(self, key: Any, default: Any = None) -> Any:
        if isinstance(key, type):
            access_check.touched(key, "world.resources.get(...)")
        return super().get(key, default)

    def __setitem__(self, key: Any, value: Any) -> None:
        if isinstance(key, type):
            access_check.touched(key, "world.resources[...] =", write=True)
        super().__setitem__(key, value)

    def setdefault(self, key: Any, default: Any = None) -> Any:
        if isinstance(key, type):
            access_check.touched(key, "world.resources.setdefault(...)", write=True)
        return super().setdefault(key, default)

    def pop(self, key: Any, *default: Any) -> Any:
        if isinstance(key, type):
            access_check.touched(key, "world.resources.pop(...)", write=True)
        return super().pop(key, *default)
