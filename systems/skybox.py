"""The skybox: a cube of green lines around the eye (the default), or a procedural starfield.

Both are fixed in world orientation and drawn with the view's *rotation
only* (no translation), so turning the camera shows in them and moving the
camera does not: they stand for things infinitely far away. Both are drawn
at the far plane (depth ``z/w = 1``) with depth test ``<=`` and depth writes
off, after the models: the sky appears only where nothing else was drawn.

* :class:`SkyboxSystem` — the articles' cube of green lines: each vertex is
  pushed to the far plane (``gl_Position = clip.xyww``).
* :class:`StarfieldSystem` — a cube-map texture of stars and a faint galactic
  band, made once at start by :func:`starfield_faces` from the scene's seed
  (its own ``"textures"`` stream, :func:`texture_rng`, so it never changes
  the scene's own random numbers), then sampled along each pixel's view
  direction by one full-screen triangle. Same seed, same sky, byte for byte.
"""
from __future__ import annotations

import math
import zlib

import esper
import moderngl
import numpy as np

from driftframe.framework import validate
from driftframe.framework.gl import RenderTarget
from driftframe.framework.model_cache import ModelCache, check_colour

VERTEX_SHADER = """
#version 330
uniform mat4 u_view_proj;      // projection * view rotation (no translation)
in vec3 in_position;
void main() {
    vec4 clip = u_view_proj * vec4(in_position, 1.0);
    gl_Position = clip.xyww;   // depth 1: at infinity, behind everything
}
"""

FRAGMENT_SHADER = """
#version 330
uniform vec3 u_colour;
out vec4 f_colour;
void main() {
    f_colour = vec4(u_colour, 1.0);
}
"""


class SkyboxSystem(esper.Processor):
    """Reads the render system's view rotation and projection; writes the skybox lines into its target.

    ``clip = P V_rot p`` with ``V_rot`` the view without translation; drawn at
    depth 1 behind every model. ``model``: the cache's line model to draw
    (default ``"skybox"``, a unit cube with a 4 x 4 grid per face);
    ``colour``: RGB (default: the model's green). Its ``after`` names the type of the
    render system it is given, so the world runs it after the models whatever the adding order.
    """

    stage = "render"
    reads = ()          # the render system's view (no components)
    writes = (RenderTarget,)

    def __init__(self, ctx, cache: ModelCache, render, *, model: str = "skybox", colour=None):
        self.ctx = ctx
        self.render = render
        self.after = (type(render),)    # the scheduler runs it after the models it draws behind
        m = cache.get(model)
        if m.meshes.mode != "lines":
            raise ValueError(f"SkyboxSystem: model {model!r} must be made of lines, got {m.meshes.mode!r}")
        self.colour = tuple((m.colour if colour is None else check_colour("skybox colour", colour)).tolist())
        self.scale = m.scale
        vbo, ibo = cache.buffers(m)[-1]
        self._prog = ctx.program(vertex_shader=VERTEX_SHADER, fragment_shader=FRAGMENT_SHADER)
        self._vao = ctx.vertex_array(self._prog, [(vbo, "3f 12x", "in_position")],
                                     index_buffer=ibo, index_element_size=4)

    def process(self, dt: float) -> None:
        if self._prog is None:
            raise RuntimeError("SkyboxSystem was released (world closed)")
        r = self.render
        vp = r.projection @ r.view_rotation_only @ np.diag([*self.scale, 1.0])
        self._prog["u_view_proj"].write(vp.astype(np.float32).T.tobytes())
        self._prog["u_colour"].value = self.colour
        ctx = self.ctx
        r.target.use()
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "<="
        fbo = r.target.fbo
        fbo.depth_mask = False
        try:
            self._vao.render(moderngl.LINES)
        finally:
            fbo.depth_mask = True
            ctx.depth_func = "<"

    def release(self) -> None:
        """Free the program and vertex array (the line buffers belong to the model cache)."""
        if self._prog is not None:
            self._vao.release()
            self._prog.release()
        self._prog = self._vao = None


# -- the procedural starfield ----------------------------------------------------------------
def texture_rng(seed: int) -> np.random.Generator:
    """The scene seed's ``"textures"`` stream: independent of ``default_rng(seed)``, which builds the scene."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an int >= 0, got {validate.shown(seed)}")
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(zlib.crc32(b"textures"),)))


# Each face's direction is linear in (1, tc, sc): d = FACE_BASIS[face] @ (1, tc, sc), the OpenGL cube-map table
# (e.g. +x: (1, -tc, -sc)); every entry is 0 or +-1, so the products are exact.
FACE_BASIS = np.array([
    [[1, 0, 0], [0, -1, 0], [0, 0, -1]],    # +x: ( 1, -tc, -sc)
    [[-1, 0, 0], [0, -1, 0], [0, 0, 1]],    # -x: (-1, -tc,  sc)
    [[0, 0, 1], [1, 0, 0], [0, 1, 0]],      # +y: (sc,   1,  tc)
    [[0, 0, 1], [-1, 0, 0], [0, -1, 0]],    # -y: (sc,  -1, -tc)
    [[0, 0, 1], [0, -1, 0], [1, 0, 0]],     # +z: (sc, -tc,   1)
    [[0, 0, -1], [0, -1, 0], [-1, 0, 0]],   # -z: (-sc, -tc, -1)
], dtype=np.float64)


def _texel_coords(size: int) -> tuple[np.ndarray, np.ndarray]:
    """(tc, sc), each (size, size): texel ``(i, j)``'s ``(2t - 1, 2s - 1)`` at its centre."""
    c = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    return np.meshgrid(c, c, indexing="ij")


def face_directions(size: int) -> np.ndarray:
    """(6, size, size, 3) unit view directions of every cube-map texel centre, OpenGL face order.

    Faces +x, -x, +y, -y, +z, -z; texel ``(row i, column j)`` has
    ``s = (j + 0.5)/size``, ``t = (i + 0.5)/size`` and ``(sc, tc) = (2s - 1, 2t - 1)``
    map to directions as the OpenGL cube-map table says (e.g. +x: ``(1, -tc, -sc)``), :data:`FACE_BASIS`.
    """
    tc, sc = _texel_coords(size)
    d = np.stack([np.ones_like(sc), tc, sc], -1) @ FACE_BASIS.transpose(0, 2, 1)[:, None]
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def direction_to_texel(d: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Face index, row and column (floats, texel units) where unit directions ``d`` (N, 3) land."""
    d = np.asarray(d, dtype=np.float64)
    ax = np.argmax(np.abs(d), axis=1)
    neg = d[np.arange(len(d)), ax] < 0
    face = 2 * ax + neg
    x, y, z = d.T
    ma = np.abs(d[np.arange(len(d)), ax])
    # (sc, tc) per face, the inverse of face_directions
    sc = np.select([face == 0, face == 1, face == 2, face == 3, face == 4], [-z, z, x, x, x], -x)
    tc = np.select([face == 0, face == 1, face == 2, face == 3, face == 4], [-y, -y, z, -z, -y], -y)
    col = (sc / ma + 1.0) * 0.5 * size - 0.5
    row = (tc / ma + 1.0) * 0.5 * size - 0.5
    return face, row, col


HAZE = np.array([0.030, 0.032, 0.045])     # the band's faint blue-grey haze, RGB at glow 1


def band_glow(band: np.ndarray, lumps: np.ndarray, weight: np.ndarray, size: int) -> np.ndarray:
    """(6, size, size) glow of the galactic band with pole ``band``: ``exp(-(d . n)^2 / 2w^2) (0.35 + patch)``.

    ``w = 0.16`` rad; ``patch`` is the sum of von Mises lumps ``weight exp(6 (d . lump - 1))``,
    scaled to a maximum of 1. Face by face on (size, size) planes: ``d . n = (p . (1, tc, sc)) / |(1, tc, sc)|``
    with ``p = n FACE_BASIS[face]``, so no (6, size, size, 3) array of directions is made.
    """
    # the patches are broad (about 25 degrees): work them out on a 4x coarser grid, each value covers 4x4 texels
    k = 4 if size % 4 == 0 else 1
    coarse = face_directions(size // k)
    patch = np.zeros(coarse.shape[:-1])
    for c, wgt in zip(lumps, weight):                 # patch += wgt exp(6 (d . c - 1)), in place
        e = coarse @ c
        e -= 1.0
        e *= 6.0
        patch += np.multiply(wgt, np.exp(e, out=e), out=e)
    lift = 0.35 + patch / max(patch.max(), 1e-12)
    tc, sc = _texel_coords(size)
    norm = np.sqrt(1.0 + tc * tc + sc * sc)          # |(1, tc, sc)|, the same on every face
    glow = np.empty((6, size, size))
    tmp = np.empty((size, size))
    for f, p in enumerate(band @ FACE_BASIS):         # p: d . n = (p0 + p1 tc + p2 sc) / norm
        g = glow[f]
        np.multiply(tc, p[1], out=g)
        g += p[0]
        g += np.multiply(sc, p[2], out=tmp)
        g /= norm
        g /= 0.16
        g *= g
        g *= -0.5
        np.exp(g, out=g)
        g.reshape(size // k, k, size // k, k)[...] *= lift[f][:, None, :, None]
    return glow


def starfield_faces(rng: np.random.Generator, size: int = 512, stars: int = 9000) -> np.ndarray:
    """(6, size, size, 3) uint8 cube-map faces: ``stars`` stars and a faint galactic band.

    Stars: directions uniform on the sphere, plus a third as many again
    crowded towards a random great circle (the band); brightness from a
    power law (few bright, many faint); colour from blue-white to orange.
    Each is a small Gaussian splat (sigma 0.6 texel) added to its face.
    The band: a soft glow ``exp(-(d . n)^2 / 2w^2)`` broken up by a few dozen
    broad random patches, very dim against the stars (:func:`band_glow`). Only numpy and ``rng``:
    the same generator state gives the same bytes.
    """
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or not 16 <= size <= 4096:
        raise ValueError(f"starfield size must be an int in [16, 4096], got {validate.shown(size)}")
    if isinstance(stars, bool) or not isinstance(stars, (int, np.integer)) or not 0 <= stars <= 1_000_000:
        raise ValueError(f"starfield stars must be an int in [0, 1000000], got {validate.shown(stars)}")
    size, stars = int(size), int(stars)
    band = rng.normal(size=3)
    band /= np.linalg.norm(band)                     # the band's pole
    # glow: band profile times patchiness (von Mises lumps centred near the band)
    lumps = rng.normal(size=(40, 3))
    lumps -= np.outer(lumps @ band, band) * 0.9       # mostly in the band's plane
    lumps /= np.linalg.norm(lumps, axis=1, keepdims=True)
    weight = rng.uniform(0.3, 1.0, len(lumps))
    glow = band_glow(band, lumps, weight, size)
    # stars: uniform ones, and extra faint ones crowded towards the band
    n_band = stars // 3
    u = rng.normal(size=(stars, 3))
    v = rng.normal(size=(n_band, 3))
    v -= np.outer(v @ band, band) * (1.0 - rng.uniform(0.0, 0.25, n_band))[:, None]
    dirs = np.vstack([u, v])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    bright = np.concatenate([rng.pareto(2.2, stars) * 0.10 + 0.05, rng.pareto(3.0, n_band) * 0.06 + 0.03])
    bright = np.minimum(bright, 3.0)
    warm = rng.uniform(0.0, 1.0, len(dirs)) ** 2                        # most stars white-blue, a few orange
    tint = np.column_stack([0.80 + 0.20 * warm, 0.85 + 0.05 * warm, 1.0 - 0.45 * warm])
    # the haze alone, texel = round(255 glow HAZE): glow <= 1.35 and HAZE <= 0.045, so nothing to clip
    out = np.empty((6, size, size, 3), np.uint8)
    buf = np.empty((size, size))
    for f in range(6):                               # a face at a time: the buffer is reused while cached
        for ch, c in enumerate(HAZE):
            np.multiply(glow[f], c, out=buf)
            buf *= 255.0
            buf += 0.5
            out[f, :, :, ch] = buf                   # float -> uint8 truncates: + 0.5 rounds
    # the texels under a star's 4 x 4 splat (all 16 offsets at once, offset-major as the sum's order below)
    face, row, col = direction_to_texel(dirs, size)
    r0, c0 = np.floor(row).astype(int), np.floor(col).astype(int)
    rr = r0 + np.array([-1, 0, 1, 2])[:, None, None]             # (4, 1, n) rows
    cc = c0 + np.array([-1, 0, 1, 2])[None, :, None]             # (1, 4, n) columns
    wgt = np.exp(-((rr - row) ** 2 + (cc - col) ** 2) / (2 * 0.6 ** 2)) * bright     # (4, 4, n)
    ok = ((rr >= 0) & (rr < size) & (cc >= 0) & (cc < size)).ravel()
    texel = ((face * size + rr) * size + cc).ravel()[ok]
    star = np.broadcast_to(np.arange(len(dirs)), wgt.shape).ravel()[ok]
    wgt = wgt.ravel()[ok]
    # each lit texel: its haze plus the splats in the order above (as the whole-image sum made them), clipped to 1
    covered = np.zeros(6 * size * size, bool)
    covered[texel] = True
    lit = np.flatnonzero(covered)                    # the lit texels, ascending; slot: their place in img
    slot = np.empty(6 * size * size, np.int32)
    slot[lit] = np.arange(len(lit), dtype=np.int32)
    slot = slot[texel]
    img = glow.reshape(-1)[lit, None] * HAZE
    for ch in range(3):
        np.add.at(img[:, ch], slot, wgt * tint[star, ch])
    out.reshape(-1, 3)[lit] = (np.clip(img, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    return out


STAR_VERTEX_SHADER = """
#version 330
uniform mat4 u_inv_view_proj;  // (projection * view rotation)^-1: clip -> direction
out vec3 v_dir;
void main() {
    // one triangle covering the screen: (-1,-1), (3,-1), (-1,3)
    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
    vec4 far = u_inv_view_proj * vec4(p, 1.0, 1.0);
    v_dir = far.xyz / far.w;
    gl_Position = vec4(p, 1.0, 1.0);   // depth 1: at infinity, behind everything
}
"""

STAR_FRAGMENT_SHADER = """
#version 330
uniform samplerCube u_sky;
in vec3 v_dir;
out vec4 f_colour;
void main() {
    f_colour = vec4(texture(u_sky, normalize(v_dir)).rgb, 1.0);
}
"""


#: The starfield's texels a face at most: a 1280x720 frame at 60 degrees magnifies it (about 1.2 pixels a
#: texel), and a window, which may grow, always gets it.
FACE_TEXELS = 512


def fitted_face_texels(height: int, tan_half_fov: float) -> int:
    """Texels a face for a frame ``height`` pixels high seen through a lens of ``tan(fov / 2)`` (the widest
    the scene has): the largest power of two from 64 to :data:`FACE_TEXELS` that the lens still magnifies.

    Mid-screen a face of ``size`` texels spans ``size / 2`` texels per unit of ``tan``, the frame
    ``height / (2 tan(fov / 2))`` pixels: texels per pixel ``size tan(fov / 2) / height``, at most 1 here.
    A magnified sky needs no mipmaps (:meth:`StarfieldSystem.process`), and each halving makes the cube map
    a quarter of the work: a 320x180 preview at 60 degrees takes 256 texels, each star's 0.6-texel splat
    then about 0.6 of a pixel, as at 1280x720 with 512."""
    if not (height >= 1 and math.isfinite(tan_half_fov) and tan_half_fov > 0.0):
        raise ValueError(f"fitted_face_texels: height {height!r} and tan(fov / 2) {tan_half_fov!r} must be positive")
    size = FACE_TEXELS
    while size > 64 and size * tan_half_fov > height:
        size //= 2
    return size


class StarfieldSystem(esper.Processor):
    """Reads the render system's view rotation and projection; writes the starfield into its target.

    The cube map (:func:`starfield_faces` with :func:`texture_rng` of
    ``seed``, ``size`` texels a face, :data:`FACE_TEXELS` by default (:func:`fitted_face_texels` gives a
    fixed-size recording's); or ``faces``, any (6, N, N, 3) uint8
    array in OpenGL face order) is made and uploaded once, here. Each
    frame one full-screen triangle at depth 1 looks up the sky along
    ``(P V_rot)^-1 (x, y, 1, 1)``, the pixel's view direction, behind every
    model. Its ``after`` names the type of the render system it is given, so the world runs it
    after the models whatever the adding order.
    """

    stage = "render"
    reads = ()          # the render system's view (no components)
    writes = (RenderTarget,)

    def __init__(self, ctx, render, *, seed: int = 0, size: int = FACE_TEXELS, stars: int = 9000, faces=None):
        self.ctx = ctx
        self.render = render
        self.after = (type(render),)    # the scheduler runs it after the models it draws behind
        self.seed = seed
        if faces is None:
            faces = starfield_faces(texture_rng(seed), size, stars)
        faces = np.ascontiguousarray(faces)
        if faces.dtype != np.uint8 or faces.ndim != 4 or faces.shape[0] != 6 or faces.shape[1] != faces.shape[2] \
                or faces.shape[3] != 3:
            raise ValueError(f"StarfieldSystem faces must be (6, N, N, 3) uint8, got {faces.dtype} {faces.shape}")
        self._tex = ctx.texture_cube((faces.shape[1], faces.shape[1]), 3, faces.tobytes())
        # the mipmaps are made at the first frame that samples them (process): llvmpipe compiles its mipmap
        # pass on first use (its cost: commit 9948656), which a frame that magnifies the sky never needs
        self.mipmapped = False
        self._texels = faces.shape[1]
        self._filter = None
        self._prog = ctx.program(vertex_shader=STAR_VERTEX_SHADER, fragment_shader=STAR_FRAGMENT_SHADER)
        self._vao = ctx.vertex_array(self._prog, [])

    def process(self, dt: float) -> None:
        if self._prog is None:
            raise RuntimeError("StarfieldSystem was released (world closed)")
        r = self.render
        # texels per pixel mid-screen: (size/2) / f_px, f_px = projection[1, 1] h/2 pixels per unit.
        # Magnified (< 1, a 1280x720 frame): plain bilinear; minified (small previews): mipmaps, so
        # stars do not sparkle in and out as the view turns. On llvmpipe the mipmapped lookup costs
        # about twice the bilinear one, so it is used only where it changes the picture.
        texels_per_px = 0.5 * self._texels / (0.5 * r.size[1] * r.projection[1, 1])
        wanted = (moderngl.LINEAR_MIPMAP_LINEAR if texels_per_px > 1.0 else moderngl.LINEAR, moderngl.LINEAR)
        if wanted != self._filter:
            if wanted[0] == moderngl.LINEAR_MIPMAP_LINEAR and not self.mipmapped:
                self._tex.build_mipmaps()
                self.mipmapped = True
            self._tex.filter = self._filter = wanted
        inv = np.linalg.inv(r.projection @ r.view_rotation_only)
        self._prog["u_inv_view_proj"].write(inv.astype(np.float32).T.tobytes())
        ctx = self.ctx
        r.target.use()
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "<="
        fbo = r.target.fbo
        fbo.depth_mask = False
        self._tex.use(0)
        try:
            self._vao.render(moderngl.TRIANGLES, vertices=3)
        finally:
            fbo.depth_mask = True
            ctx.depth_func = "<"

    def release(self) -> None:
        """Free the texture, program and vertex array."""
        if self._prog is not None:
            self._vao.release()
            self._prog.release()
            self._tex.release()
        self._prog = self._vao = self._tex = None
