"""Drawing every Transform + ModelRef entity: instanced, level of detail, view culling, lit.

Setting up rendering for a world is one call (:func:`driftframe.rendering.attach`; a game calls
:func:`driftframe.attach_rendering`, which adds the HUD, effects and sound too)::

    from driftframe.rendering import attach
    render = attach(world, ctx=None, size=(1280, 720))   # ctx=None: a new off-screen EGL context
    world.step(); world.render()
    rgba = render.read_rgba()        # (720, 1280, 4) uint8, top row first

:func:`attach` adds the :class:`~systems.camera.CameraSystem` (stage
``"camera"``, every fixed step), this :class:`RenderSystem` and the
:class:`~systems.skybox.SkyboxSystem` (stage ``"render"``, in that order),
and fills the typed resources ``world.resources[ModelCache]``,
``world.resources[RenderTarget]`` and ``world.resources[ContextHandle]``
(``.ctx`` is the ``moderngl.Context``; ``world.close()`` releases the
context only if attach created it).

A later system in stage ``"render"`` (a HUD) draws on top of the same frame: it
declares ``writes = (RenderTarget,)``, is added with
``after=driftframe.rendering.drawn_before(world)`` (the schedule warns about two
drawers nothing orders), and reads ``render.ctx``, ``render.target`` (``.fbo``, ``.size``,
``.use()``), ``render.view``, ``render.projection``,
``render.view_projection`` and ``render.viewport`` — all set for the frame
being drawn — and sets the GL state it needs (this system leaves depth test
on, face culling off). The recorder reads the frame after every render-stage
system has run.

What the system does each frame, with numpy over whole columns (the per-entity
Python work happens only when esper's query result changes: then entities are
grouped by mesh):

* model matrix ``T R S``: ``S`` from the model (variant) scale, ``R`` from the
  orientation quaternion, ``T`` the position *relative to the eye* (computed
  in float64, so float32 on the GPU keeps its precision far from the origin;
  the view matrix on the GPU is then the rotation only);
* view culling: a bounding sphere outside any of the six frustum planes is
  not drawn;
* level of detail: projected radius ``r_px = r f_px / (z - r)`` (``f_px`` =
  pixels per unit at 1 m, ``z`` the depth along the view); the coarsest level
  whose relative error ``eps`` keeps ``eps r_px <= lod_tolerance_px`` is used
  (see :mod:`framework.meshes`);
* one instanced draw call per (mesh, level) for all its entities; per-instance
  data (mat4 model + RGB) is one float32 array uploaded at once;
* light: ``colour (ambient + fill (1 - n . l) / 2 + (1 - ambient) max(n . l, 0))``,
  with ``l`` the unit direction *towards* a distant light (world frame): a
  diffuse key light plus a hemisphere ambient term that is ``ambient`` on
  normals facing the light and ``ambient + fill`` on normals facing straight
  away from it (light scattered back from the far side). Without ``fill`` a
  body seen against the light is a near-black disc; with it its dark side is
  brightest at the centre and darkens to the outline, so it still reads as a
  sphere, and the lit side is unchanged (1 where ``n = l``).
"""
from __future__ import annotations

import math

import esper
import moderngl
import numpy as np

from driftframe.components.body import Transform
from driftframe.components.camera import Camera
from driftframe.components.render import ModelRef
from driftframe.framework import frame as fr
from driftframe.framework import validate
from driftframe.framework.gl import RenderTarget
from driftframe.framework.model_cache import ModelCache, check_colour
from driftframe.framework.store import to_indices
from driftframe.systems import camera_rig as camera_sys

VERTEX_SHADER = """
#version 330
uniform mat4 u_view_proj;          // projection * view rotation: positions are eye-relative
#ifdef PER_DRAW
uniform mat4 u_model;
uniform vec3 u_colour;
#define MODEL u_model
#define COLOUR u_colour
#else
in mat4 in_model;                  // per instance: T R S, translation relative to the eye
in vec3 in_colour;                 // per instance: RGB
#define MODEL in_model
#define COLOUR in_colour
#endif
in vec3 in_position;
in vec3 in_normal;
out vec3 v_normal;
out vec3 v_colour;
#ifdef TEXTURED
in vec2 in_uv;                     // texture coordinates, (0, 0) the image's top-left
out vec2 v_uv;
#endif
#ifdef NORMAL_MAPPED
in vec4 in_tangent;                // glTF's: xyz along increasing u, w the bitangent's handedness
out vec3 v_tangent;
out float v_handed;
#endif
void main() {
    gl_Position = u_view_proj * (MODEL * vec4(in_position, 1.0));
#ifdef TEXTURED
    v_uv = in_uv;
#endif
    // normals transform by (R S)^-T = R S^-1 = (R S) S^-2; |column i| of R S is s_i
    mat3 m = mat3(MODEL);
    vec3 s2 = vec3(dot(m[0], m[0]), dot(m[1], m[1]), dot(m[2], m[2]));
    v_normal = m * (in_normal / s2);
#ifdef NORMAL_MAPPED
    v_tangent = m * in_tangent.xyz;    // a direction along the surface: it transforms by R S itself
    v_handed = in_tangent.w;
#endif
    v_colour = COLOUR;
}
"""

FRAGMENT_SHADER = """
#version 330
uniform vec3 u_to_light;           // unit vector towards the light, world frame
uniform float u_ambient;           // fraction of light everywhere
uniform float u_fill;              // hemisphere fill: extra light on normals facing away from the light
uniform int u_lit;                 // 0 for lines: flat colour
in vec3 v_normal;
in vec3 v_colour;
out vec4 f_colour;
#ifdef TEXTURED
uniform sampler2D u_texture;       // base colour, uploaded top row first: v = 0 is the top
in vec2 v_uv;
#endif
#ifdef NORMAL_MAPPED
uniform sampler2D u_normal_map;    // tangent space (glTF): x along u, y up the image, z out; 0..1 for -1..1
in vec3 v_tangent;
in float v_handed;
#endif
void main() {
    float shade = 1.0;
    if (u_lit != 0) {
        vec3 n = normalize(v_normal);
#ifdef NORMAL_MAPPED
        // the map's normal in the surface's frame: t (made perpendicular to n), b = w (n x t), n
        vec3 t = normalize(v_tangent - n * dot(n, v_tangent));
        vec3 mapped = texture(u_normal_map, v_uv).xyz * 2.0 - 1.0;
        n = normalize(mapped.x * t + mapped.y * cross(n, t) * v_handed + mapped.z * n);
#endif
        float nl = dot(n, u_to_light);
        // hemisphere ambient (u_ambient towards the light, u_ambient + u_fill away from it) + diffuse
        shade = u_ambient + u_fill * (0.5 - 0.5 * nl) + (1.0 - u_ambient) * max(nl, 0.0);
    }
#ifdef TEXTURED
    f_colour = vec4(v_colour * texture(u_texture, v_uv).rgb * shade, 1.0);
#else
    f_colour = vec4(v_colour * shade, 1.0);
#endif
}
"""

#: Floats per instance: a column-major mat4 and an RGB colour.
INSTANCE_FLOATS = 19


#: The shaders' defines for a mesh set's maps: none, a base-colour texture, a texture and a normal map.
_MAP_DEFINES = ([], ["TEXTURED"], ["TEXTURED", "NORMAL_MAPPED"])


def _maps(mesh_set) -> int:
    """0: no image; 1: a base-colour texture; 2: a texture and a normal map (a program each)."""
    return 0 if mesh_set.texture is None else 1 if mesh_set.normal_map is None else 2


def _with_define(src: str, *defines: str) -> str:
    """``src`` with ``#define NAME`` lines after its ``#version`` line."""
    head, rest = src.split("\n", 2)[1], src.split("\n", 2)[2]
    return head + "\n" + "".join(f"#define {d}\n" for d in defines) + rest


class _Group:
    """Entities sharing one mesh set: their table rows and per-entity constants."""

    __slots__ = ("mesh_set", "entities", "t_rows", "scale", "colour", "radius")

    def __init__(self, mesh_set, entities, t_rows, scale, colour):
        self.mesh_set = mesh_set
        self.entities = entities                    # (n,) int64
        self.t_rows = t_rows                        # (n,) rows into Transform's table
        self.scale = scale                          # (n, 3) float64
        self.colour = colour.astype(np.float32)     # (n, 3)
        self.radius = mesh_set.radius * scale.max(axis=1)   # (n,) bounding radius, m


class RenderSystem(esper.Processor):
    """Reads Transform, ModelRef, the active Camera and the ModelCache; writes the RenderTarget's pixels.

    ``ctx``: moderngl context; ``cache``: the :class:`ModelCache`; ``target``:
    the :class:`RenderTarget`. Options: ``lod`` / ``cull`` (level of detail
    and view culling, on by default), ``instanced`` (False: one draw call per
    entity — the baseline the benchmark compares with), ``lod_tolerance_px``
    (largest allowed outline error of a level, pixels), ``light_direction``
    (towards the light, world frame), ``ambient`` (0..1), ``fill`` (0..1,
    hemisphere fill on the side away from the light; 0 = the plain
    ambient + diffuse model), ``clear_colour`` (RGB). ``camera``: a camera entity to use instead of the first active one.

    After each frame: ``view``, ``projection``, ``view_projection`` (4x4
    float64, world -> clip), ``view_rotation_only`` (the same without the
    eye's translation), ``eye_position``, ``camera_entity``, ``viewport``,
    ``size`` and ``stats`` (draw calls, instances drawn, culled, per-level
    counts) describe it.
    """

    stage = "render"
    reads = (Transform, ModelRef, Camera, ModelCache)
    writes = (RenderTarget,)        # pixels only: the camera stage alone places the eye

    def __init__(self, ctx, cache: ModelCache, target: RenderTarget, *, lod: bool = True, cull: bool = True,
                 instanced: bool = True, lod_tolerance_px: float = 0.5,
                 light_direction=(-0.45, 0.65, -0.6), ambient: float = 0.12, fill: float = 0.3,
                 clear_colour=(0.0, 0.0, 0.0), camera: int | None = None):
        self.ctx = ctx
        self.cache = cache
        self.target = target
        self.lod = bool(lod)
        self.cull = bool(cull)
        self.instanced = bool(instanced)
        self.lod_tolerance_px = validate.scalar("lod_tolerance_px", lod_tolerance_px, positive=True)
        light = validate.vector("light_direction", light_direction)
        if not np.linalg.norm(light) > 0:
            raise ValueError(f"light_direction must be a non-zero vector, got {light.tolist()}")
        self.light_direction = light / np.linalg.norm(light)
        self.ambient = validate.scalar("ambient", ambient, lo=0.0, hi=1.0)
        self.fill = validate.scalar("fill", fill, lo=0.0, hi=1.0)
        self.clear_colour = tuple(check_colour("clear_colour", clear_colour).tolist())
        self.camera = camera
        #: Optional hook ``blend(entities, positions, orientations) -> (positions, orientations)``
        #: giving the poses to draw (a window's interpolation, :mod:`systems.interpolation`); None: as they are.
        self.poses = None
        # (per draw, maps: 0 none, 1 a texture, 2 and a normal map) -> program; the instanced plain one is
        # the common case
        self._progs = {(per_draw, maps): ctx.program(
            vertex_shader=_with_define(VERTEX_SHADER, *(["PER_DRAW"] * per_draw + _MAP_DEFINES[maps])),
            fragment_shader=_with_define(FRAGMENT_SHADER, *_MAP_DEFINES[maps]))
            for per_draw in (False, True) for maps in (0, 1, 2)}
        for per_draw in (False, True):
            self._progs[per_draw, 2]["u_texture"].value = 0
            self._progs[per_draw, 2]["u_normal_map"].value = 1
        self._prog = self._progs[False, False]
        self._rows = None                # the world's Query of (Transform, ModelRef), once added
        self._groups: list[_Group] = []
        self._stale = False
        # (id(mesh_set), level) -> [instance buffer, capacity in instances, vao]; per-draw vaos apart
        self._inst: dict = {}
        self._draw_vaos: dict = {}
        #: Frames drawn so far.
        self.frame = 0
        self.view = np.eye(4)
        self.projection = np.eye(4)
        self.view_projection = np.eye(4)
        self.view_rotation_only = np.eye(4)
        self.eye_position = np.zeros(3)
        self.camera_entity: int | None = None
        self.stats: dict = {}

    # -- frame description ------------------------------------------------------------
    @property
    def size(self) -> tuple[int, int]:
        return self.target.size

    @property
    def viewport(self) -> tuple[int, int, int, int]:
        return self.target.viewport

    def read_rgba(self) -> np.ndarray:
        """The current frame, ``(H, W, 4)`` uint8, top row first."""
        return self.target.read_rgba()

    # -- per-entity constants, rebuilt only when esper's query changes ---------------------
    def _regroup(self) -> None:
        q = self._rows
        ents = q.entities
        if not len(ents):
            self._groups = []
            return
        t_rows, refs = to_indices(q.rows(Transform)), q.rows(ModelRef)
        models = {}
        for ent, ref in zip(ents.tolist(), refs):
            if ref.name not in models:
                try:
                    models[ref.name] = self.cache.get(ref.name)
                except KeyError as e:
                    raise ValueError(f"ModelRef on entity {ent}: {e.args[0]}") from None
        names = list(models)                                      # distinct models, first-seen order
        name_index = {n: i for i, n in enumerate(names)}
        m_idx = np.fromiter((name_index[r.name] for r in refs), np.intp, len(refs))
        scales = np.array([models[n].scale for n in names])[m_idx]
        colours = np.array([models[n].colour for n in names])[m_idx]
        override = [i for i, r in enumerate(refs) if r.colour is not None]
        if override:
            colours[override] = np.array([refs[i].colour for i in override])
        # variants share their base's mesh set: one group (one instanced draw per level) per set
        sets: list = []
        set_of_name = []
        for n in names:
            ms = models[n].meshes
            k = next((i for i, s in enumerate(sets) if s is ms), None)
            if k is None:
                sets.append(ms)
                k = len(sets) - 1
            set_of_name.append(k)
        e_set = np.array(set_of_name, np.intp)[m_idx]
        groups = []
        for k, ms in enumerate(sets):
            members = np.flatnonzero(e_set == k)
            groups.append(_Group(ms, ents[members], t_rows[members], scales[members], colours[members]))
        # a fixed draw order: the order the mesh sets were defined in the cache
        order = {id(ms): k for k, ms in enumerate(self.cache.mesh_sets)}
        groups.sort(key=lambda g: order.get(id(g.mesh_set), len(order)))
        self._groups = groups

    # -- GL objects ----------------------------------------------------------------------
    @staticmethod
    def _vertex_layout(mesh_set) -> tuple:
        """The vertex buffer's format and attribute names (``in_uv`` for a textured mesh, ``in_tangent`` for
        a normal-mapped one); the columns a program does not read are skipped."""
        m = mesh_set.lods[0]
        maps = _maps(mesh_set)
        if maps == 2:
            return ("3f 3f 2f 4f", "in_position", "in_normal", "in_uv", "in_tangent")
        skip = 4 * (2 * (m.uvs is not None and maps == 0) + 4 * (m.tangents is not None))
        return ("3f 3f" + (" 2f" if maps else "") + (f" {skip}x" if skip else ""), "in_position", "in_normal",
                *(["in_uv"] if maps else []))

    def _vao(self, group: _Group, level: int, n: int):
        key = (id(group.mesh_set), level)
        slot = self._inst.get(key)
        if slot is None or slot[1] < n:
            if slot is not None:
                slot[0].release()
                slot[2].release()
            cap = max(64, 1 << (max(n, 1) - 1).bit_length())
            buf = self.ctx.buffer(reserve=cap * INSTANCE_FLOATS * 4, dynamic=True)
            vbo, ibo = self.cache.buffers(group.mesh_set)[level]
            vao = self.ctx.vertex_array(
                self._progs[False, _maps(group.mesh_set)],
                [(vbo, *self._vertex_layout(group.mesh_set)), (buf, "16f 3f/i", "in_model", "in_colour")],
                index_buffer=ibo, index_element_size=4)
            slot = [buf, cap, vao]
            self._inst[key] = slot
        return slot

    def _draw_vao(self, group: _Group, level: int):
        key = (id(group.mesh_set), level)
        vao = self._draw_vaos.get(key)
        if vao is None:
            vbo, ibo = self.cache.buffers(group.mesh_set)[level]
            vao = self.ctx.vertex_array(self._progs[True, _maps(group.mesh_set)],
                                        [(vbo, *self._vertex_layout(group.mesh_set))],
                                        index_buffer=ibo, index_element_size=4)
            self._draw_vaos[key] = vao
        return vao

    def release(self) -> None:
        """Free programs, vertex arrays and instance buffers. Safe to call twice."""
        for buf, _, vao in self._inst.values():
            vao.release()
            buf.release()
        for vao in self._draw_vaos.values():
            vao.release()
        self._inst.clear()
        self._draw_vaos.clear()
        for prog in self._progs.values():
            prog.release()
        self._progs.clear()
        self._prog = None

    # -- the frame -------------------------------------------------------------------------
    def _camera(self) -> tuple[int, Camera, np.ndarray, np.ndarray]:
        """The camera drawn from: entity, Camera, eye position and orientation (read, never written)."""
        if self.camera is not None:
            ent = self.camera
            cam = esper.try_component(ent, Camera) if esper.entity_exists(ent) else None
            if cam is None:
                raise ValueError(f"RenderSystem.camera: entity {validate.shown(ent)} has no Camera")
        else:
            ent, cam = camera_sys.active_camera(self.world)
        # a camera made since the last step has no eye yet: drawn from its snapped pose, which the
        # camera stage (its only writer) gives it at the next step
        eye, q_eye = camera_sys.placed_pose(ent, cam)
        return ent, cam, eye, q_eye

    def process(self, dt: float) -> None:
        if self._prog is None:
            raise RuntimeError("RenderSystem was released (world closed)")
        ent_cam, cam, eye, q_eye = self._camera()
        if self.poses is not None:
            eye, q_eye = self.poses.blend_one(ent_cam, eye, q_eye)
        w, h = self.target.size
        aspect = w / h
        rot = np.eye(4)
        rot[:3, :3] = camera_sys.view_rotation(q_eye)
        proj = camera_sys.perspective(cam.fov, aspect, cam.near, cam.far)
        self.camera_entity = ent_cam
        self.eye_position = eye
        self.view = camera_sys.view_matrix(eye, q_eye)
        self.projection = proj
        self.view_projection = proj @ self.view
        self.view_rotation_only = rot
        self.frame += 1

        ctx = self.ctx
        self.target.use()
        ctx.clear(*self.clear_colour, 1.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.depth_func = "<"
        ctx.front_face = "cw"          # the view flips z: outward CCW triangles appear clockwise
        ctx.cull_face = "back"

        vp_rot = (proj @ rot).astype(np.float32)
        for prog in self._progs.values():
            prog["u_view_proj"].write(vp_rot.T.tobytes())          # GL wants column-major
            prog["u_to_light"].value = tuple(self.light_direction)
            prog["u_ambient"].value = self.ambient
            prog["u_fill"].value = self.fill

        if self._rows is None:
            self._rows = self.world.query(Transform, ModelRef)
        if self._rows.refresh() or self._stale:
            self._stale = True           # stays set if _regroup raises (an unknown model): retried next frame
            self._regroup()
            self._stale = False
        skip = cam.target if cam.mode == "cockpit" else None   # do not draw the ship we sit in
        r_eye = fr.quat_to_matrix(q_eye)                          # columns right, up, forward
        f_px = 0.5 * h / cam.tan_half_fov                         # pixels per metre at 1 m depth
        stats = {"draw_calls": 0, "instances": 0, "culled": 0, "levels": {}}
        table = self.world.table(Transform)
        pos_all = table.data["position"]
        q_all = table.data["orientation"]
        for g in self._groups:
            pos_g, q_g = pos_all[g.t_rows], q_all[g.t_rows]
            if self.poses is not None:
                pos_g, q_g = self.poses.blend(g.entities, pos_g, q_g)
            rel = pos_g - eye                                     # eye-relative, float64, m
            keep = np.ones(len(rel), bool) if skip is None else g.entities != skip
            c = rel @ r_eye                                       # (right, up, forward) coords, m
            r = g.radius
            if self.cull:
                keep &= self._in_frustum(c, r, cam, aspect)
            stats["culled"] += int(len(rel) - keep.sum())
            idx = np.flatnonzero(keep)
            if not len(idx):
                continue
            n_levels = len(g.mesh_set.lods)
            if self.lod and n_levels > 1:
                depth = np.maximum(c[idx, 2] - r[idx], cam.near)  # nearest point's depth, >= near
                r_px = r[idx] * f_px / depth
                err = g.mesh_set.lod_errors
                with np.errstate(divide="ignore"):
                    limit = np.where(err > 0, self.lod_tolerance_px / err, np.inf)   # largest r_px per level
                level = np.minimum(np.searchsorted(limit, r_px, side="left"), n_levels - 1)
            else:
                level = np.full(len(idx), n_levels - 1)
            inst = self._instance_data(g, idx, rel, q_g)
            order = np.argsort(level, kind="stable")
            counts = np.bincount(level, minlength=n_levels)
            inst = inst[order]
            start = 0
            mode = moderngl.LINES if g.mesh_set.mode == "lines" else moderngl.TRIANGLES
            lit = 0 if g.mesh_set.mode == "lines" else 1
            maps = _maps(g.mesh_set)
            prog_draw = self._progs[True, maps]
            self._progs[False, maps]["u_lit"].value = lit
            prog_draw["u_lit"].value = lit
            if maps:
                self.cache.texture(g.mesh_set).use(0)
            if maps == 2:
                self.cache.normal_texture(g.mesh_set).use(1)
            for lv in range(n_levels):
                n = int(counts[lv])
                if not n:
                    continue
                block = inst[start:start + n]
                start += n
                if self.instanced:
                    buf, _, vao = self._vao(g, lv, n)
                    buf.write(block.tobytes())
                    vao.render(mode, instances=n)
                    stats["draw_calls"] += 1
                else:
                    vao = self._draw_vao(g, lv)
                    u_model, u_colour = prog_draw["u_model"], prog_draw["u_colour"]
                    for row in block:
                        u_model.write(row[:16].tobytes())
                        u_colour.write(row[16:19].tobytes())
                        vao.render(mode)
                    stats["draw_calls"] += n
                stats["instances"] += n
                key = f"{g.mesh_set.name}[{lv}]"
                stats["levels"][key] = stats["levels"].get(key, 0) + n
        ctx.disable(moderngl.CULL_FACE)
        ctx.front_face = "ccw"
        self.stats = stats

    @staticmethod
    def _in_frustum(c: np.ndarray, r: np.ndarray, cam: Camera, aspect: float) -> np.ndarray:
        """Bounding spheres (centre ``c`` in right/up/forward eye coords, radius ``r``) touching the view.

        Each side plane passes through the eye; for half-angle ``a`` its
        outward normal is ``(cos a, 0, -sin a)`` (right side; likewise left,
        top, bottom). A sphere is outside when its signed distance to any
        plane exceeds ``r``, or it lies wholly nearer than ``near`` or
        farther than ``far``.
        """
        ty = cam.tan_half_fov
        tx = ty * aspect
        # unit normals of the side planes: (1, 0, -t) / sqrt(1 + t^2)
        kx = 1.0 / math.sqrt(1.0 + tx * tx)
        ky = 1.0 / math.sqrt(1.0 + ty * ty)
        x, y, z = c[:, 0], c[:, 1], c[:, 2]
        zx = z * tx
        zy = z * ty
        return ((z + r > cam.near) & (z - r < cam.far)
                & ((x - zx) * kx < r) & ((-x - zx) * kx < r)
                & ((y - zy) * ky < r) & ((-y - zy) * ky < r))

    @staticmethod
    def _instance_data(g: _Group, idx: np.ndarray, rel: np.ndarray, q_g: np.ndarray) -> np.ndarray:
        """(n, 19) float32: column-major ``T R S`` (eye-relative T) and RGB, for entities ``idx`` of ``g``.

        ``rel`` and ``q_g`` are the group's eye-relative positions and orientations, aligned with ``g``.
        """
        m = fr.quat_to_matrix(q_g[idx]) * g.scale[idx][:, None, :]   # R S: column j scaled by s_j
        n = len(idx)
        out = np.empty((n, INSTANCE_FLOATS), np.float32)
        out[:, 0:3] = m[:, :, 0]
        out[:, 4:7] = m[:, :, 1]
        out[:, 8:11] = m[:, :, 2]
        out[:, 12:15] = rel[idx]
        out[:, [3, 7, 11]] = 0.0
        out[:, 15] = 1.0
        out[:, 16:19] = g.colour[idx]
        return out


def read_rgba(world) -> np.ndarray:
    """The world's current frame (``world.resources[RenderTarget]``), (H, W, 4) uint8, top row first."""
    try:
        target = world.resources[RenderTarget]
    except KeyError:
        raise LookupError("no rendering: call driftframe.attach_rendering(world) first") from None
    return target.read_rgba()
