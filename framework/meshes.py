"""Meshes built from vertex lists and indices (never triangle strips), with normals.

A :class:`Mesh` is CPU data only: ``vertices`` and ``normals`` (N, 3) float32
in the model's local frame (metres; +x right, +y up, +z forward), ``indices``
(M,) uint32 into them, and a ``mode``: ``"triangles"`` (M = 3 per triangle,
wound counter-clockwise seen from outside, so ``(b - a) x (c - a)`` points
out) or ``"lines"`` (M = 2 per segment). :mod:`framework.model_cache` turns
them into GPU buffers once.

The meshes the framework builds itself:

* :func:`icosphere` — a unit sphere at several levels of detail. Level ``L``
  subdivides an icosahedron ``L`` times: ``20 * 4**L`` triangles, every vertex
  on the sphere, normal = position. :func:`sphere_lods` returns levels
  ``0..4`` (20 .. 5,120 triangles) with each level's geometric error.
* :func:`ship_hull` — the player ship: a swept-wing dart lofted through five
  cross-sections (a canopy hump, delta wings, a tail fin), nose along local
  +z (the body's forward vector), flat-shaded so each facet catches the
  light on its own, and centred on its centre of mass (:func:`volume_centroid`).
* :func:`pyramid` — the articles' ship: a four-sided pyramid whose apex (the
  nose) points along local +z, centred on its centre of mass (a solid
  pyramid's centroid is 1/4 of the way from base to apex), flat-shaded.
* :func:`rock_lods` — a rock: a seeded noise-displaced icosphere (lumps and craters),
  stretched, flat-shaded, bounded by the unit sphere, at four levels of detail.
* :func:`box` — a flat-shaded cuboid centred on the origin (a table top, a
  wall); its scaled variants share its buffers.
* :func:`line_cube` — the skybox: the edges of a unit cube (side 1, centred),
  optionally with a grid of lines on each face.

:func:`flat_shaded` turns any closed triangle list into a flat-shaded
:class:`Mesh`, and :func:`volume_centroid` gives a closed surface's volume
and centre of mass (uniform density) from signed tetrahedra.

Models from files: :func:`load_mesh` reads an OBJ, glTF (``.gltf``) or
binary glTF (``.glb``) file with trimesh (the optional ``assets`` extra:
``pip install 'driftframe[assets]'``) and returns a :class:`Mesh` moved so
that its centre of mass (trimesh's mass properties, uniform density) is the
origin: a body spins about its centre of mass, so a model that is not
centred on it would wobble round the point the body turns about. The
coordinates are taken as they are (metres; +z the model's front, as in
glTF; +y up).

Level of detail: a flat triangle lies inside the sphere; its largest gap to
the true surface, relative to the radius, is ``eps = 1 - min over faces of the
distance from the centre to the face's plane``. A sphere of projected radius
``r_px`` pixels drawn at a level with error ``eps`` misses the true outline by
at most ``eps * r_px`` pixels. Because a sphere's vertex normal equals its
position, the interpolated per-pixel normal is the true sphere normal in the
direction of the drawn point; the drawn point sits up to ``eps r`` inside the
surface, so that direction is off by about ``eps tan(i)`` rad (``i`` = angle
between the view ray and the surface normal): shading errors stay small in
the middle of a disc and grow towards its outline. The render system picks
the coarsest level whose ``eps * r_px`` is under its tolerance
(``benchmarks/render_lod.py`` measures the resulting image error).
"""
from __future__ import annotations

import functools
from typing import NamedTuple
from dataclasses import dataclass, field, replace

import numpy as np

from driftframe.framework import validate

MODES = ("triangles", "lines")


@dataclass(frozen=True, eq=False)
class Mesh:
    """Vertex and index lists of one model, in local coordinates (m).

    ``vertices``/``normals``: (N, 3) float32; ``indices``: (M,) uint32;
    ``mode``: ``"triangles"`` (CCW from outside) or ``"lines"``. ``lod_error``
    is the largest gap between this mesh and the smooth shape it stands for,
    relative to ``radius`` (0 for exact shapes such as the pyramid).
    ``uvs``: (N, 2) float32 texture coordinates (glTF's convention: ``(0, 0)``
    the top-left of the image), or None for an untextured mesh.
    ``tangents``: (N, 4) float32, glTF's TANGENT (unit xyz along increasing u,
    perpendicular to the normal; w = +-1, the bitangent ``w (n x t)`` pointing
    up the image, towards decreasing v), for a normal map; None without one
    (:func:`tangent_frames` makes them from the uvs).
    """

    name: str
    vertices: np.ndarray
    normals: np.ndarray
    indices: np.ndarray
    mode: str = "triangles"
    lod_error: float = 0.0
    uvs: np.ndarray | None = None
    tangents: np.ndarray | None = None
    #: Bounding radius about the local origin, m (the largest |vertex|).
    radius: float = field(init=False)

    def __post_init__(self):
        if self.mode not in MODES:
            raise ValueError(f"Mesh {self.name!r}: mode must be one of {MODES}, got {self.mode!r}")
        v = np.array(self.vertices, dtype=np.float32)      # private copies, made read-only below
        n = np.array(self.normals, dtype=np.float32)
        i = np.array(self.indices)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
            raise ValueError(f"Mesh {self.name!r}: vertices must have shape (N, 3), N >= 1, got {v.shape}")
        if n.shape != v.shape:
            raise ValueError(f"Mesh {self.name!r}: normals must have the vertices' shape {v.shape}, got {n.shape}")
        if not (np.isfinite(v).all() and np.isfinite(n).all()):
            raise ValueError(f"Mesh {self.name!r}: vertices and normals must be finite")
        if i.ndim != 1 or i.dtype.kind not in "iu":
            raise ValueError(f"Mesh {self.name!r}: indices must be a 1-D integer array, got {i.dtype} {i.shape}")
        per = 3 if self.mode == "triangles" else 2
        if len(i) == 0 or len(i) % per:
            raise ValueError(f"Mesh {self.name!r}: {self.mode} need a non-zero multiple of {per} indices, "
                             f"got {len(i)}")
        if i.min() < 0 or i.max() >= len(v):
            raise ValueError(f"Mesh {self.name!r}: indices must be in [0, {len(v) - 1}], "
                             f"got [{int(i.min())}, {int(i.max())}]")
        i = i.astype(np.uint32)
        if self.uvs is not None:
            uv = np.array(self.uvs, dtype=np.float32)
            if uv.shape != (len(v), 2) or not np.isfinite(uv).all():
                raise ValueError(f"Mesh {self.name!r}: uvs must be finite with shape ({len(v)}, 2), got {uv.shape}")
            uv.flags.writeable = False
            object.__setattr__(self, "uvs", uv)
        if self.tangents is not None:
            t = np.array(self.tangents, dtype=np.float32)
            if self.uvs is None or t.shape != (len(v), 4) or not np.isfinite(t).all():
                raise ValueError(f"Mesh {self.name!r}: tangents must be finite with shape ({len(v)}, 4), on a "
                                 f"mesh with uvs, got {t.shape}{'' if self.uvs is not None else ' without uvs'}")
            t.flags.writeable = False
            object.__setattr__(self, "tangents", t)
        for arr in (v, n, i):
            arr.flags.writeable = False
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "normals", n)
        object.__setattr__(self, "indices", i)
        object.__setattr__(self, "radius", float(np.linalg.norm(v, axis=1).max()))

    @property
    def primitive_count(self) -> int:
        """Triangles (or line segments)."""
        return len(self.indices) // (3 if self.mode == "triangles" else 2)

    def interleaved(self) -> np.ndarray:
        """(N, 6) float32 rows ``x y z nx ny nz``, (N, 8) ``... u v`` with uvs, (N, 12) ``... tx ty tz tw`` with
        tangents too: the vertex buffer's layout."""
        cols = [self.vertices, self.normals] + [c for c in (self.uvs, self.tangents) if c is not None]
        return np.ascontiguousarray(np.hstack(cols), dtype=np.float32)

    def face_normals(self) -> np.ndarray:
        """Unnormalised ``(b - a) x (c - a)`` of each triangle (points out for CCW winding)."""
        if self.mode != "triangles":
            raise ValueError(f"Mesh {self.name!r} has no faces (mode {self.mode!r})")
        t = self.vertices.astype(np.float64)[self.indices.reshape(-1, 3)]
        return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])


def tangent_frames(mesh: Mesh) -> Mesh:
    """``mesh`` with glTF tangents made from its positions, normals and uvs (for a normal map).

    Per triangle, with edges e1, e2 and their uv steps (du1, dv1), (du2, dv2):
    ``dP/du = (dv2 e1 - dv1 e2) / r`` and ``dP/dv = (du1 e2 - du2 e1) / r``, r = du1 dv2 - du2 dv1
    (dimensionless uv). Each vertex sums its triangles' (area-weighted: unnormalised) dP/du and dP/dv;
    the tangent is dP/du made perpendicular to the normal (Gram-Schmidt) and unit; w = +1 where
    ``n x t`` points up the image (along -dP/dv: glTF's v runs down), else -1. A triangle with no uv
    area adds nothing; a vertex left without a tangent takes any unit vector perpendicular to its normal.
    """
    if mesh.mode != "triangles" or mesh.uvs is None:
        raise ValueError(f"Mesh {mesh.name!r}: tangents need triangles with uvs")
    f = mesh.indices.reshape(-1, 3).astype(np.int64)
    p = mesh.vertices.astype(np.float64)
    uv = mesh.uvs.astype(np.float64)
    e1, e2 = p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]
    d1, d2 = uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]
    r = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(r) > 1e-20
    inv = np.where(ok, 1.0 / np.where(ok, r, 1.0), 0.0)[:, None]
    w = np.linalg.norm(np.cross(e1, e2), axis=1)[:, None] * inv       # each triangle weighted by its area
    du = (d2[:, 1:2] * e1 - d1[:, 1:2] * e2) * w
    dv = (d1[:, 0:1] * e2 - d2[:, 0:1] * e1) * w
    tu, tv = np.zeros_like(p), np.zeros_like(p)
    for k in range(3):
        np.add.at(tu, f[:, k], du)
        np.add.at(tv, f[:, k], dv)
    n = mesh.normals.astype(np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    t = tu - n * np.sum(tu * n, axis=1, keepdims=True)
    length = np.linalg.norm(t, axis=1)
    lost = length < 1e-12
    if lost.any():                                   # no uv gradient: any perpendicular will do
        a = np.where(np.abs(n[lost, 0:1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        t[lost] = np.cross(n[lost], a)
        length = np.linalg.norm(t, axis=1)
    t /= length[:, None]
    sign = np.where(np.sum(np.cross(n, t) * -tv, axis=1) < 0.0, -1.0, 1.0)
    return replace(mesh, tangents=np.column_stack([t, sign]))


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    p = (1.0 + 5.0 ** 0.5) / 2.0   # golden ratio: the 12 vertices are (0, +-1, +-p) cycled
    v = np.array([[-1, p, 0], [1, p, 0], [-1, -p, 0], [1, -p, 0],
                  [0, -1, p], [0, 1, p], [0, -1, -p], [0, 1, -p],
                  [p, 0, -1], [p, 0, 1], [-p, 0, -1], [-p, 0, 1]], dtype=np.float64)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
                  [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
                  [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
                  [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], dtype=np.int64)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    # orient every face counter-clockwise seen from outside: (b - a) x (c - a) along the outward direction
    t = v[f]
    outward = np.einsum("ij,ij->i", np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), t.sum(axis=1)) > 0
    f[~outward] = f[~outward][:, ::-1]
    return v, f


def _subdivide(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split each triangle into 4 through its edge midpoints (pushed onto the sphere); shared edges share midpoints."""
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])          # (3F, 2), face-major per edge slot
    key = np.sort(edges, axis=1)
    uniq, inverse = np.unique(key, axis=0, return_inverse=True)
    mid = v[uniq[:, 0]] + v[uniq[:, 1]]
    mid /= np.linalg.norm(mid, axis=1, keepdims=True)
    m = (len(v) + inverse.reshape(3, -1)).T                                       # (F, 3): mid of edges 01, 12, 20
    a, b, c = f.T
    ab, bc, ca = m.T
    faces = np.concatenate([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1),
                            np.stack([ca, bc, c], 1), np.stack([ab, bc, ca], 1)])
    return np.concatenate([v, mid]), faces


def sphere_error(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Largest gap between a unit-sphere triangulation and the sphere: ``1 - min plane distance``."""
    t = vertices[faces]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return float(1.0 - np.abs(np.einsum("ij,ij->i", n, t[:, 0])).min())


@functools.lru_cache(maxsize=None)
def icosphere(level: int) -> Mesh:
    """Unit sphere: an icosahedron subdivided ``level`` times (``20 * 4**level`` triangles)."""
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or not 0 <= level <= 7:
        raise ValueError(f"icosphere level must be an int in [0, 7], got {level!r}")
    v, f = _icosahedron()
    for _ in range(int(level)):
        v, f = _subdivide(v, f)
    return Mesh(f"icosphere{level}", v, v, f.ravel(), "triangles", lod_error=sphere_error(v, f))


#: Levels of detail of the shared sphere mesh: 20, 80, 320, 1,280, 5,120 triangles.
SPHERE_LEVELS = (0, 1, 2, 3, 4)


def sphere_lods(levels=SPHERE_LEVELS) -> tuple[Mesh, ...]:
    """The sphere at each level, coarsest first (their ``lod_error`` decreases)."""
    return tuple(icosphere(level) for level in levels)


@functools.lru_cache(maxsize=16)           # bounded: a cache, never a leak
def pyramid(length: float = 2.0, width: float = 1.2, height: float = 0.5) -> Mesh:
    """The player ship: apex (nose) on local +z, rectangular base ``width`` x ``height`` (m) behind it.

    ``length`` is base-to-apex. The origin is the solid's centre of mass, a
    quarter of the way from the base to the apex: base at ``z = -length/4``,
    nose at ``z = 3 length/4``. Flat-shaded: each face has its own vertices.
    """
    for name, val in (("length", length), ("width", width), ("height", height)):
        if not (np.isfinite(val) and val > 0):
            raise ValueError(f"pyramid {name} must be a finite number > 0, got {validate.shown(val)}")
    zb, za = -0.25 * length, 0.75 * length
    w, h = 0.5 * width, 0.5 * height
    apex = np.array([0.0, 0.0, za])
    # base corners seen from behind (looking along +z): right-up, left-up, left-down, right-down
    ru, lu, ld, rd = (np.array(p) for p in ([w, h, zb], [-w, h, zb], [-w, -h, zb], [w, -h, zb]))
    tris = [(apex, lu, ru), (apex, ru, rd), (apex, rd, ld), (apex, ld, lu),   # sides
            (ru, lu, ld), (ru, ld, rd)]                                         # base, facing -z
    verts, norms = [], []
    for a, b, c in tris:
        n = np.cross(b - a, c - a)
        if np.dot(n, (a + b + c) / 3.0) < 0:      # keep CCW-from-outside whatever the corner order above
            b, c = c, b
            n = -n
        verts += [a, b, c]
        norms += [n / np.linalg.norm(n)] * 3
    return Mesh("pyramid", np.array(verts), np.array(norms), np.arange(len(verts)), "triangles")


def volume_centroid(vertices, faces) -> tuple[float, np.ndarray]:
    """Volume (m^3) and centre of mass of the solid a closed, outward-wound triangle surface bounds.

    Each triangle ``(a, b, c)`` and the origin span a tetrahedron of signed
    volume ``a . (b x c) / 6`` and centroid ``(a + b + c) / 4``; their
    volume-weighted sum is the solid's centroid (uniform density), wherever
    the origin is. A negative volume means the faces are wound inwards.
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = v[np.asarray(faces).reshape(-1, 3)]
    vol = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])) / 6.0
    total = float(vol.sum())
    if not abs(total) > 0:
        raise ValueError("volume_centroid: the surface encloses no volume (not closed, or flat)")
    return total, (vol[:, None] * t.sum(axis=1)).sum(axis=0) / (4.0 * total)


def flat_shaded(name: str, vertices, faces, *, recentre: bool = False, uvs=None) -> Mesh:
    """A flat-shaded :class:`Mesh` from shared vertices and (F, 3) CCW-from-outside faces.

    Every face gets its own three vertices, each with the face's unit normal
    (and its vertices' ``uvs``, when given). ``recentre``: shift the vertices so
    the solid's centre of mass (see :func:`volume_centroid`) is the origin.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if recentre:
        v = v - volume_centroid(v, f)[1]
    t = v[f]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    if not (length > 0).all():
        raise ValueError(f"Mesh {name!r}: {int((length == 0).sum())} faces have no area")
    n = np.repeat(n / length, 3, axis=0)
    uv = None if uvs is None else np.asarray(uvs, dtype=np.float64)[f].reshape(-1, 2)
    return Mesh(name, t.reshape(-1, 3), n, np.arange(3 * len(f)), "triangles", uvs=uv)


@functools.lru_cache(maxsize=16)           # bounded: a cache, never a leak
def box(sx: float = 1.0, sy: float = 1.0, sz: float = 1.0) -> Mesh:
    """A cuboid ``sx`` x ``sy`` x ``sz`` (m) centred on the origin, faces along the axes, flat-shaded."""
    for name, val in (("sx", sx), ("sy", sy), ("sz", sz)):
        if not (np.isfinite(val) and val > 0):
            raise ValueError(f"box {name} must be a finite number > 0, got {validate.shown(val)}")
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]) * [sx, sy, sz]
    # corner k has x = bit 2, y = bit 1, z = bit 0; each face's quad in CCW order seen from outside
    quads = [(0, 1, 3, 2), (4, 6, 7, 5),      # -x, +x
             (0, 4, 5, 1), (2, 3, 7, 6),      # -y, +y
             (0, 2, 6, 4), (1, 5, 7, 3)]      # -z, +z
    faces = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return flat_shaded("box", corners, faces)


#: The ship's cross-sections, nose to tail: (z, [(x, y), ...] right half from the top round to the bottom), m.
#: The left half mirrors it. Top: a canopy hump, then a tail fin; the widest point of each: the wing tip.
_HULL = (
    (0.95, [(0.0, 0.16), (0.13, 0.08), (0.20, 0.0), (0.12, -0.07), (0.0, -0.11)]),
    (0.25, [(0.0, 0.36), (0.24, 0.16), (0.50, 0.0), (0.22, -0.11), (0.0, -0.19)]),
    (-0.40, [(0.0, 0.30), (0.28, 0.13), (0.95, -0.02), (0.28, -0.11), (0.0, -0.19)]),
    (-0.75, [(0.0, 0.62), (0.22, 0.11), (1.00, -0.02), (0.24, -0.09), (0.0, -0.16)]),
)
_NOSE_Z = 1.65


@functools.lru_cache(maxsize=1)
def ship_hull() -> Mesh:
    """The player ship: a swept-wing dart 2.4 m long, 2 m across the wings, nose along +z, centred on its mass.

    Lofted through :data:`_HULL`'s cross-sections (each the same number of
    points round the long axis, so consecutive sections join with quads and
    the surface is closed), a point at the nose and a flat tail plate;
    flat-shaded; the origin moved to the solid's centre of mass.
    """
    rings = []
    for z, half in _HULL:
        right = [(x, y) for x, y in half]
        left = [(-x, y) for x, y in reversed(half[1:-1])]
        rings.append([(x, y, z) for x, y in right + left])        # top, right side down to the bottom, left up
    k = len(rings[0])
    verts = [(0.0, 0.0, _NOSE_Z)] + [p for ring in rings for p in ring]
    tail = len(verts)
    verts.append((0.0, 0.0, rings[-1][0][2]))
    ring = lambda r, i: 1 + r * k + (i % k)                          # noqa: E731
    faces = [(0, ring(0, i + 1), ring(0, i)) for i in range(k)]      # nose cone
    for r in range(len(rings) - 1):
        for i in range(k):
            a, b, c, d = ring(r, i), ring(r, i + 1), ring(r + 1, i + 1), ring(r + 1, i)
            # split each quad along the mirror image of its partner's diagonal: the hull stays symmetric
            faces += [(a, b, c), (a, c, d)] if i < k // 2 else [(a, b, d), (b, c, d)]
    faces += [(tail, ring(len(rings) - 1, i), ring(len(rings) - 1, i + 1)) for i in range(k)]
    v = np.array(verts)
    f = np.array(faces)
    if volume_centroid(v, f)[0] < 0:                                  # make the winding outward, whichever it was
        f = f[:, ::-1]
    return flat_shaded("ship", v, f, recentre=True)


#: The built-in rock shapes (``"rock0"`` .. ``"rock3"`` in every model cache) and their levels of detail.
ROCK_SHAPES = 4
ROCK_LEVELS = (1, 2, 3, 4)


def rock_radius(d: np.ndarray, seed: int) -> np.ndarray:
    """Radius of rock ``seed`` along unit directions ``d`` (N, 3), before the rock is scaled to fit.

    ``r(d) = 1 + lumps + craters``: lumps are three octaves of random plane waves
    ``a cos(f d.c + phase)`` (6, 12 and 24 waves, amplitudes 0.10 / 0.04 / 0.015 over
    sqrt(count), frequencies 1.5 / 3.5 / 8 rad); craters are 3-6 bowls ``depth (x^2 - 1)`` for
    ``x = angle / size < 1`` with a raised rim ``0.3 depth exp(-((x - 1) / 0.25)^2)``. A smooth
    function of direction: every level of detail samples the same surface.
    """
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(0x726F636B,)))   # "rock"
    r = np.ones(len(d))
    for count, amp, freq in ((6, 0.10, 1.5), (12, 0.04, 3.5), (24, 0.015, 8.0)):
        c = rng.normal(size=(count, 3))
        c /= np.linalg.norm(c, axis=1, keepdims=True)
        phase = rng.uniform(0.0, 2.0 * np.pi, count)
        r += amp / np.sqrt(count) * np.cos(freq * (d @ c.T) + phase).sum(axis=1)
    n = int(rng.integers(3, 7))
    c = rng.normal(size=(n, 3))
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    size = rng.uniform(0.25, 0.55, n)                     # angular radius of each crater, rad
    depth = rng.uniform(0.04, 0.09, n)
    x = np.arccos(np.clip(d @ c.T, -1.0, 1.0)) / size
    r += (np.where(x < 1.0, x * x - 1.0, 0.0) * depth + 0.3 * depth * np.exp(-((x - 1.0) / 0.25) ** 2)).sum(axis=1)
    return r


@functools.lru_cache(maxsize=ROCK_SHAPES)
def rock_lods(seed: int, levels=ROCK_LEVELS) -> tuple[Mesh, ...]:
    """Rock ``seed``: a noise-displaced icosphere (:func:`rock_radius`) at each level, coarsest first.

    Each level is the icosphere of that level with every vertex pushed out to
    ``rock_radius`` along its direction, stretched by a random ``diag(1, 0.7-0.95,
    0.55-0.85)`` in a random frame (no rock is round), moved so the finest level's centre of
    mass is the origin and scaled so the farthest vertex of any level is 1 m from it: the unit
    sphere bounds the rock, and a variant scaled to a collider's radius fits inside that sphere
    (collisions stay spheres). Flat-shaded: each facet catches the light on its own.
    ``lod_error`` is the icosphere level's (the chord error of a smooth surface of that size).
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"rock seed must be an int >= 0, got {validate.shown(seed)}")
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(0x73686170,)))   # "shap"
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    stretch = q @ np.diag([1.0, rng.uniform(0.7, 0.95), rng.uniform(0.55, 0.85)]) @ q.T
    shapes = []
    for level in levels:
        base = icosphere(level)
        d = base.vertices.astype(np.float64)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        shapes.append(((d * rock_radius(d, seed)[:, None]) @ stretch, base.indices.reshape(-1, 3).astype(np.int64),
                       base.lod_error))
    centre = volume_centroid(*shapes[-1][:2])[1]
    reach = max(np.linalg.norm(v - centre, axis=1).max() for v, _, _ in shapes)
    out = []
    for level, (v, f, err) in zip(levels, shapes):
        m = flat_shaded(f"rock{seed}_{level}", (v - centre) / reach, f)
        out.append(Mesh(m.name, m.vertices, m.normals, m.indices, "triangles", lod_error=err))
    return tuple(out)


@functools.lru_cache(maxsize=16)
def line_cube(divisions: int = 1) -> Mesh:
    """A cube of side 1 centred on the origin, as line segments.

    ``divisions = 1``: its 12 edges. ``divisions = d > 1``: each face also
    carries a ``d`` x ``d`` grid, so some lines are in view whichever way a
    camera inside it looks. Shared edges appear once. Normals are zero (lines
    are not lit).
    """
    if isinstance(divisions, bool) or not isinstance(divisions, (int, np.integer)) or not 1 <= divisions <= 64:
        raise ValueError(f"line_cube divisions must be an int in [1, 64], got {divisions!r}")
    d = int(divisions)
    ticks = np.arange(d + 1)                        # grid coordinates 0..d map to -1/2 .. +1/2
    segs = set()
    for axis in range(3):                           # the segment runs along `axis`
        o1, o2 = [a for a in range(3) if a != axis]
        for i in ticks:
            for j in ticks:
                if i not in (0, d) and j not in (0, d):
                    continue                         # inside the cube, not on a face
                a = [0, 0, 0]
                b = [0, 0, 0]
                a[o1] = b[o1] = i
                a[o2] = b[o2] = j
                a[axis], b[axis] = 0, d
                segs.add((tuple(a), tuple(b)))
    points = sorted({p for s in segs for p in s})
    index = {p: k for k, p in enumerate(points)}
    idx = np.array([[index[a], index[b]] for a, b in sorted(segs)], dtype=np.uint32).ravel()
    v = np.array(points, dtype=np.float64) / d - 0.5
    return Mesh(f"line_cube{d}", v, np.zeros_like(v), idx, "lines")


#: File types :func:`load_mesh` reads (trimesh's loaders for them).
MODEL_FILES = (".obj", ".gltf", ".glb")


class LoadedModel(NamedTuple):
    """What :func:`load_model` reads from a model file."""

    #: The triangle mesh, recentred; with uvs where the file has a texture, tangents where a normal map.
    mesh: Mesh
    #: The base-colour image (H, W, 4) uint8, top row first, or None.
    texture: np.ndarray | None
    #: The tangent-space normal map (H, W, 4) uint8, top row first (glTF's: x right, y up the image,
    #: z out of the surface, each as 0..255 for -1..1), or None.
    normal_map: np.ndarray | None


def load_mesh(path, name: str | None = None, *, shading: str = "smooth") -> Mesh:
    """A triangle :class:`Mesh` from an OBJ / glTF / GLB file, recentred on its centre of mass
    (:func:`load_model` without the images)."""
    return load_model(path, name, shading=shading).mesh


def load_model(path, name: str | None = None, *, shading: str = "smooth") -> LoadedModel:
    """``(mesh, texture, normal_map)`` from an OBJ / glTF / GLB file: the triangle :class:`Mesh`, recentred
    on its centre of mass, with its texture coordinates, its base-colour texture as an (H, W, 4) uint8
    array (top row first), or None when the file has none, and its normal map likewise (glTF's
    normalTexture; trimesh reads none from OBJ; the mesh then has :func:`tangent_frames`; glTF's normal
    ``scale`` is taken as 1). Other material maps are not read.

    All the file's geometry is joined into one mesh (node transforms
    applied). ``shading``: ``"smooth"`` (trimesh's area-weighted vertex
    normals on shared vertices) or ``"flat"`` (every face its own normal).
    The origin becomes the solid's centre of mass when the surface is closed
    (``trimesh.Trimesh.is_volume``; inward-wound closed files are turned the
    right way out first), else the area centroid of the surface (an open
    sheet has no volume to weigh): see :func:`mesh_centre`.

    A missing file, an unknown file type, a file trimesh cannot parse or
    one without triangles is a clear error that names the file; a missing
    trimesh says which extra to install.
    """
    if shading not in ("smooth", "flat"):
        raise ValueError(f"load_mesh shading must be 'smooth' or 'flat', got {shading!r}")
    mesh = _read_trimesh(path)
    uv, texture, normal_map = _maps(mesh, path)
    centre = mesh_centre(mesh)
    v = np.asarray(mesh.vertices, dtype=np.float64) - centre
    f = np.asarray(mesh.faces, dtype=np.int64)
    label = name or _stem(path)
    if shading == "flat":
        out = flat_shaded(label, v, f, uvs=uv)
    else:
        out = Mesh(label, v, np.asarray(mesh.vertex_normals, dtype=np.float64), f.ravel(), "triangles", uvs=uv)
    return LoadedModel(out if normal_map is None else tangent_frames(out), texture, normal_map)


def _maps(mesh, path) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """The trimesh mesh's per-vertex UVs, base-colour image (glTF's baseColorTexture, OBJ's map_Kd) and
    normal map (glTF's normalTexture), each None where missing (the UVs too when there is no image);
    the images as (H, W, 4) uint8 (greyscale and RGB made RGBA)."""
    visual = getattr(mesh, "visual", None)
    uv = getattr(visual, "uv", None)
    material = getattr(visual, "material", None)
    images = [getattr(material, "baseColorTexture", None) or getattr(material, "image", None),
              getattr(material, "normalTexture", None)]
    if uv is None or len(uv) != len(mesh.vertices) or all(im is None for im in images):
        return None, None, None
    out = []
    for im, what in zip(images, ("texture", "normal map")):
        try:
            out.append(None if im is None else np.asarray(im.convert("RGBA"), dtype=np.uint8))
        except Exception as e:                     # an image Pillow cannot decode: name the file
            raise ValueError(f"model file {str(path)!r}: its {what} could not be read: {e}") from None
    # glTF's v runs down the image; trimesh gives OpenGL's (v up), so flip it back to glTF's
    uv = np.asarray(uv, dtype=np.float64).copy()
    uv[:, 1] = 1.0 - uv[:, 1]
    return uv, out[0], out[1]


def mesh_centre(mesh) -> np.ndarray:
    """Centre of mass of a trimesh mesh (uniform density) if it bounds a volume, else its area centroid."""
    if mesh.is_watertight and mesh.is_winding_consistent and mesh.volume < 0:
        mesh.invert()                              # closed but wound inwards: the same solid, outside out
    if mesh.is_volume:
        return np.asarray(mesh.center_mass, dtype=np.float64)
    return np.asarray(mesh.centroid, dtype=np.float64)


def _stem(path) -> str:
    from pathlib import Path
    return Path(path).stem or "model"


def _read_trimesh(path):
    from pathlib import Path

    p = Path(path)
    if p.suffix.lower() not in MODEL_FILES:
        raise ValueError(f"model file {str(p)!r}: unknown type {p.suffix or '(none)'!r}; "
                         f"driftframe reads {', '.join(MODEL_FILES)}")
    if not p.is_file():
        raise FileNotFoundError(f"model file {str(p)!r} not found" if not p.exists()
                                else f"model file {str(p)!r} is not a file")
    try:
        import trimesh
    except ImportError:
        raise ImportError(f"loading model file {str(p)!r} needs trimesh, the 'assets' extra: "
                          "pip install 'driftframe[assets]'") from None
    try:
        mesh = trimesh.load(str(p), force="mesh", process=True)
    except Exception as e:                         # trimesh's parsers raise many kinds; name the file
        raise ValueError(f"model file {str(p)!r} could not be read as {p.suffix.lower()[1:].upper()}: "
                         f"{type(e).__name__}: {e}") from None
    faces = getattr(mesh, "faces", None)
    if faces is None or len(faces) == 0:
        raise ValueError(f"model file {str(p)!r} has no triangles (empty, or not a {p.suffix.lower()[1:].upper()} "
                         "mesh)")
    v = np.asarray(mesh.vertices)
    if not np.isfinite(v).all():
        raise ValueError(f"model file {str(p)!r} has non-finite vertex coordinates")
    return mesh
