"""The model cache: every mesh's GPU buffers built once; variants share them and add a scale.

A *model* is what :class:`components.render.ModelRef` names. There are two kinds:

* a **base model** (:meth:`ModelCache.define`) owns a :class:`MeshSet`: one
  mesh, or the same shape at several levels of detail (coarsest first);
* a **variant** (:meth:`ModelCache.variant`) points at a base's
  :class:`MeshSet` — the *same* vertex and index buffers — and adds a scale
  ``S = diag(sx, sy, sz)`` (and optionally its own colour). Fifty asteroid
  sizes are fifty variants of ``"sphere"`` and still one vertex buffer per
  level of detail.

GPU buffers are made lazily, the first time :meth:`ModelCache.buffers` is
asked for a mesh set, and never again: each level gets one vertex buffer
(interleaved ``x y z nx ny nz`` float32) and one index buffer (uint32).
:attr:`ModelCache.buffers_created` counts them.

Models from files: :meth:`ModelCache.load` defines a base model from an OBJ
or glTF file (:func:`framework.meshes.load_mesh`, the ``assets`` extra),
recentred on its centre of mass; its variants share its buffers like the
sphere's. :func:`declare_model_file` names one for a world before any GL
exists, as :func:`declare_variant` does for variants.

Built-in models (defined by every cache unless ``builtins=False``):

* ``"sphere"`` — unit-radius icosphere, levels 0..4 (20 .. 5,120 triangles), grey;
* ``"ship"`` — the swept-wing ship (:func:`framework.meshes.ship_hull`), nose
  along +z (forward), light blue;
* ``"box"`` — a unit cube (side 1 m), grey: scaled variants make table tops,
  walls, slabs;
* ``"skybox"`` — the unit line cube with a 4 x 4 grid on each face, green;
* ``"rock0"`` .. ``"rock3"`` — four rock shapes (:func:`framework.meshes.rock_lods`: lumps,
  craters, stretched, flat-shaded), each inside the unit sphere, four levels of detail each:
  fifty asteroid sizes are variants of four rocks and still four vertex buffers per level.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from driftframe.framework import meshes, validate

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from driftframe.framework.world import World

GREY = (0.62, 0.60, 0.58)
SHIP_BLUE = (0.55, 0.75, 1.0)
SKY_GREEN = (0.15, 0.85, 0.25)
ROCK_GREY = (0.55, 0.50, 0.45)


def check_colour(name: str, colour) -> np.ndarray:
    """An RGB colour, three numbers in [0, 1]."""
    c = validate.vector(name, colour, (3,))
    if ((c < 0) | (c > 1)).any():
        raise ValueError(f"{name} must be RGB numbers in [0, 1], got {c.tolist()}")
    return c


def check_scale(name: str, scale) -> np.ndarray:
    """A positive finite scale: one number (uniform) or three (x, y, z)."""
    if np.ndim(scale) == 0:
        return np.full(3, validate.scalar(name, scale, positive=True))
    s = validate.vector(name, scale, (3,))
    if not (s > 0).all():
        raise ValueError(f"{name} must be > 0 on every axis, got {s.tolist()}")
    return s


def check_texture(name: str, texture) -> np.ndarray:
    """An image (H, W, 3 or 4) uint8, top row first, made RGBA; a clear error otherwise."""
    t = np.asarray(texture)
    if t.dtype != np.uint8 or t.ndim != 3 or t.shape[2] not in (3, 4) or min(t.shape[:2]) < 1 \
            or max(t.shape[:2]) > 8192:
        raise ValueError(f"{name} must be an (H, W, 3 or 4) uint8 image of at most 8192 x 8192, "
                         f"got {t.dtype} {t.shape}")
    if t.shape[2] == 3:
        t = np.concatenate([t, np.full(t.shape[:2] + (1,), 255, np.uint8)], axis=2)
    return np.ascontiguousarray(t)


class MeshSet:
    """One shape at one or more levels of detail, coarsest first, its texture, and its GPU objects once built.

    ``texture``: a base-colour image (H, W, 3 or 4) uint8, top row first, which every level's
    ``uvs`` index; None for an untextured shape. ``normal_map``: a tangent-space normal map, the same
    kind of image (glTF's convention), for levels with ``tangents``; a plain white texture stands in
    for a missing base colour.
    """

    def __init__(self, name: str, lods, texture=None, normal_map=None):
        if isinstance(lods, meshes.Mesh):
            lods = (lods,)
        lods = tuple(lods)
        if not lods or not all(isinstance(m, meshes.Mesh) for m in lods):
            raise TypeError(f"model {name!r}: give a Mesh or a sequence of Mesh (coarsest first), got {lods!r}")
        modes = {m.mode for m in lods}
        if len(modes) != 1:
            raise ValueError(f"model {name!r}: all levels must share one mode, got {sorted(modes)}")
        errors = np.array([m.lod_error for m in lods])
        if np.any(np.diff(errors) > 0):
            raise ValueError(f"model {name!r}: levels must go from coarse to fine "
                             f"(lod_error non-increasing), got {errors.tolist()}")
        self.name = name
        self.lods = lods
        self.mode = lods[0].mode
        #: Relative geometric error of each level (see framework.meshes).
        self.lod_errors = errors
        #: Bounding radius of the finest level, m (all levels lie inside it).
        self.radius = max(m.radius for m in lods)
        #: One (vertex buffer, index buffer) per level, once built.
        self.gpu: tuple | None = None
        #: The base-colour image (H, W, 4) uint8, or None; its GL texture once built.
        self.texture = None if texture is None else check_texture(f"model {name!r} texture", texture)
        self.gpu_texture = None
        if self.texture is not None and any(m.uvs is None for m in lods):
            raise ValueError(f"model {name!r}: a texture needs uvs on every level of its mesh")
        #: The tangent-space normal map (H, W, 4) uint8, or None; its GL texture once built.
        self.normal_map = None if normal_map is None else check_texture(f"model {name!r} normal_map", normal_map)
        self.gpu_normal_map = None
        if self.normal_map is not None:
            if any(m.tangents is None for m in lods):
                raise ValueError(f"model {name!r}: a normal map needs tangents on every level of its mesh "
                                 "(framework.meshes.tangent_frames makes them from the uvs)")
            if self.texture is None:
                self.texture = np.full((1, 1, 4), 255, np.uint8)


@dataclass(frozen=True, eq=False)
class Model:
    """A cache entry: the shared :class:`MeshSet` plus this entry's scale and colour.

    The model matrix of an entity drawn with it is ``T R S``: ``S`` is
    ``diag(scale)``, ``R`` the entity's orientation, ``T`` its position.
    """

    name: str
    meshes: MeshSet
    #: Per-axis scale, local frame (dimensionless; the mesh is in metres).
    scale: np.ndarray
    #: RGB in [0, 1] (a ModelRef may override it per entity).
    colour: np.ndarray
    #: The base model this variant points at (its own name for a base model).
    base: str

    @property
    def radius(self) -> float:
        """Bounding radius after scaling, m."""
        return float(self.meshes.radius * self.scale.max())

    @property
    def scale_matrix(self) -> np.ndarray:
        """4x4 ``S``."""
        return np.diag([*self.scale, 1.0])


class ModelVariants(dict):
    """The world's declared model variants, ``world.resources[ModelVariants]``: name -> ``(base, scale,
    colour)``, made into :class:`ModelCache` entries when rendering is attached (:func:`declare_variant`)."""

    published_by = "made by declare_variant(world, name, ...) (a scene's build)"
    #: Not in a save: the scene's build declares them again.
    saved = False


class ModelFiles(dict):
    """The world's declared model files, ``world.resources[ModelFiles]``: name -> ``(path, colour,
    shading)``, read when rendering is attached (:func:`declare_model_file`)."""

    published_by = "made by declare_model_file(world, name, path) (a scene's build)"
    #: Not in a save: the scene's build declares them again.
    saved = False


class ModelCache:
    """Named models over shared GPU meshes, for one GL context.

    ``define(name, mesh_or_levels, colour=...)`` adds a base model;
    ``variant(name, base, scale=..., colour=...)`` adds an entry that shares
    the base's buffers; ``get(name)`` looks one up (a clear error lists the
    known names); ``buffers(model)`` returns its per-level ``(vbo, ibo)``
    pairs, building them on first use only. ``release()`` frees every buffer.
    """

    published_by = "made by attach_rendering(world)"
    #: Not in a save: GPU buffers, made again when rendering is attached.
    saved = False

    def __init__(self, ctx, *, builtins: bool = True):
        self.ctx = ctx
        self._models: dict[str, Model] = {}
        self._sets: list[MeshSet] = []
        #: GL buffers this cache has created (vertex + index), over its lifetime.
        self.buffers_created = 0
        if builtins:
            self.define("sphere", meshes.sphere_lods(), colour=GREY)
            self.define("ship", meshes.ship_hull(), colour=SHIP_BLUE)
            self.define("box", meshes.box(), colour=GREY)
            self.define("skybox", meshes.line_cube(4), colour=SKY_GREEN)
            for k in range(meshes.ROCK_SHAPES):
                self.define(f"rock{k}", meshes.rock_lods(k), colour=ROCK_GREY)

    # -- entries -----------------------------------------------------------------
    def _check_name(self, name) -> str:
        validate.text("a model name", name)
        return name

    def define(self, name: str, lods, *, colour=GREY, texture=None, normal_map=None) -> Model:
        """Add a base model from one :class:`~framework.meshes.Mesh` or several levels (coarsest first).

        ``texture``: a base-colour image (H, W, 3 or 4) uint8, top row first, which the meshes' ``uvs``
        index (``(0, 0)`` its top-left corner); the drawn colour is ``colour * texel * light``.
        ``normal_map``: a tangent-space normal map indexed the same way (the meshes need ``tangents``):
        the light falls on its normals instead of the mesh's.
        """
        name = self._check_name(name)
        if name in self._models:
            raise ValueError(f"model {name!r} is defined already")
        mesh_set = MeshSet(name, lods, texture, normal_map)
        model = Model(name, mesh_set, np.ones(3), check_colour(f"model {name!r} colour", colour), name)
        self._sets.append(mesh_set)
        self._models[name] = model
        return model

    def load(self, name: str, path, *, colour=None, shading: str = "smooth") -> Model:
        """Define base model ``name`` from a model file (OBJ, glTF, GLB), centred on its centre of mass.

        See :func:`framework.meshes.load_model`; errors name the file. The file's texture
        coordinates and base-colour texture are kept (``colour`` then tints it; default white), else
        the model is ``colour`` (default grey). Scaled variants of it (:meth:`variant`) share its
        vertex and index buffers and its texture.
        """
        name = self._check_name(name)
        if name in self._models:
            raise ValueError(f"model {name!r} is defined already")
        mesh, texture, normal_map = meshes.load_model(path, name, shading=shading)
        if colour is None:
            colour = GREY if texture is None else (1.0, 1.0, 1.0)
        return self.define(name, mesh, colour=colour, texture=texture, normal_map=normal_map)

    def variant(self, name: str, base: str, *, scale=1.0, colour=None) -> Model:
        """An entry sharing ``base``'s vertex and index buffers, scaled by ``scale`` (one or three numbers).

        A variant of a variant multiplies the scales. Asking again for the
        same name with the same base, scale and colour returns the existing
        entry; different parameters under an existing name are an error.
        """
        name = self._check_name(name)
        parent = self.get(base)
        s = parent.scale * check_scale(f"variant {name!r} scale", scale)
        c = parent.colour if colour is None else check_colour(f"variant {name!r} colour", colour)
        old = self._models.get(name)
        if old is not None:
            if old.meshes is parent.meshes and np.array_equal(old.scale, s) and np.array_equal(old.colour, c):
                return old
            raise ValueError(f"model {name!r} exists already with another base, scale or colour")
        model = Model(name, parent.meshes, s, c, parent.base)
        self._models[name] = model
        return model

    def get(self, name: str) -> Model:
        """The model called ``name``; an unknown name is an error that lists the known ones."""
        try:
            return self._models[name]
        except (KeyError, TypeError):
            known = ", ".join(sorted(self._models)[:20]) + (", ..." if len(self._models) > 20 else "")
            raise KeyError(f"unknown model {name!r}; known models: {known}") from None

    def __contains__(self, name) -> bool:
        return name in self._models

    @property
    def names(self) -> list[str]:
        return sorted(self._models)

    @property
    def mesh_sets(self) -> tuple[MeshSet, ...]:
        """Every base model's mesh set, in definition order (the render system's draw order)."""
        return tuple(self._sets)

    # -- GPU buffers ---------------------------------------------------------------
    def buffers(self, model) -> tuple:
        """``((vbo, ibo), ...)`` per level of a :class:`Model`'s (or a :class:`MeshSet`'s) meshes.

        Built on the first call for that mesh set, then the same buffers every time.
        """
        ms = model if isinstance(model, MeshSet) else model.meshes
        if ms.gpu is None:
            built = []
            for mesh in ms.lods:
                vbo = self.ctx.buffer(mesh.interleaved().tobytes())
                ibo = self.ctx.buffer(mesh.indices.tobytes())
                self.buffers_created += 2
                built.append((vbo, ibo))
            ms.gpu = tuple(built)
        return ms.gpu

    def texture(self, model):
        """The GL texture of a :class:`Model`'s (or a :class:`MeshSet`'s) base-colour image, built on
        first use (mipmapped, repeating), or None for an untextured model."""
        ms = model if isinstance(model, MeshSet) else model.meshes
        if ms.texture is None:
            return None
        if ms.gpu_texture is None:
            ms.gpu_texture = self._image(ms.texture)
        return ms.gpu_texture

    def normal_texture(self, model):
        """The GL texture of a model's normal map, built on first use as :meth:`texture`, or None."""
        ms = model if isinstance(model, MeshSet) else model.meshes
        if ms.normal_map is None:
            return None
        if ms.gpu_normal_map is None:
            ms.gpu_normal_map = self._image(ms.normal_map)
        return ms.gpu_normal_map

    def _image(self, rgba):
        import moderngl

        h, w = rgba.shape[:2]
        tex = self.ctx.texture((w, h), 4, rgba.tobytes())
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        return tex

    @property
    def buffers_alive(self) -> int:
        """GL buffers held now."""
        return sum(2 * len(ms.gpu) for ms in self._sets if ms.gpu is not None)

    def release(self) -> None:
        """Free every GPU buffer (entries stay; buffers are rebuilt on next use). Safe to call twice."""
        for ms in self._sets:
            if ms.gpu is not None:
                for vbo, ibo in ms.gpu:
                    vbo.release()
                    ibo.release()
                ms.gpu = None
            if ms.gpu_texture is not None:
                ms.gpu_texture.release()
                ms.gpu_texture = None
            if ms.gpu_normal_map is not None:
                ms.gpu_normal_map.release()
                ms.gpu_normal_map = None


def declare_variant(world: World, name: str, base: str = "sphere", *, scale: ArrayLike = 1.0,
                    colour: ArrayLike | None = None) -> str:
    """Declare a model variant (a scaled entry sharing ``base``'s buffers); returns ``name``.

    Stored in ``world.resources[ModelVariants]`` until rendering is attached.
    """
    validate.text("variant name", name)
    check_scale(f"variant {name!r} scale", scale)
    if colour is not None:
        check_colour(f"variant {name!r} colour", colour)
    world.resources.setdefault(ModelVariants, ModelVariants())[name] = (base, scale, colour)
    return name


def declare_model_file(world: World, name: str, path: str | os.PathLike[str], *, colour: ArrayLike | None = None,
                       shading: str = "smooth") -> str:
    """Declare base model ``name`` read from ``path`` (OBJ, glTF, GLB) when rendering is attached; returns ``name``.

    Stored in ``world.resources[ModelFiles]``; the file is checked to
    exist now (a clear error naming it), read when the model cache is made.
    """
    from pathlib import Path

    validate.text("model name", name)
    p = Path(path)
    if p.suffix.lower() not in meshes.MODEL_FILES:
        raise ValueError(f"model file {str(p)!r}: unknown type {p.suffix or '(none)'!r}; "
                         f"driftframe reads {', '.join(meshes.MODEL_FILES)}")
    if not p.is_file():
        raise FileNotFoundError(f"model file {str(p)!r} not found")
    if colour is not None:
        check_colour(f"model {name!r} colour", colour)
    if shading not in ("smooth", "flat"):
        raise ValueError(f"model {name!r} shading must be 'smooth' or 'flat', got {shading!r}")
    world.resources.setdefault(ModelFiles, ModelFiles())[name] = (str(p), colour, shading)
    return name
