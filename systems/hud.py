"""The heads-up display: prograde / retrograde markers, speed, spin rate, camera and assist state;
in a scene with gravity also the orbit readouts and the predicted orbit line (``systems/readouts.py``)."""
from __future__ import annotations

from pathlib import Path

import esper
import moderngl
import numpy as np

from driftframe.components.body import AngularVelocity, Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.autopilot import Autopilot
from driftframe.components.control import FlightInput, Player, RotationAssist
from driftframe.components.gravity import GravityWell
from driftframe.components.render import ModelRef
from driftframe.framework.gl import RenderTarget
from driftframe.framework.model_cache import ModelCache
from driftframe.framework.orbit_state import OrbitState
from driftframe.framework.warp import TimeWarp

TEXT_COLOUR = (0.80, 1.00, 0.80, 1.0)
PROGRADE_COLOUR = (0.85, 1.00, 0.30, 1.0)
RETROGRADE_COLOUR = (1.00, 0.55, 0.20, 1.0)
ORBIT_COLOUR = (0.35, 0.75, 1.00, 0.9)
SHIP_MARK_COLOUR = (0.55, 0.85, 1.00, 0.9)
TARGET_MARK_COLOUR = (1.00, 0.85, 0.35, 0.9)
#: The player's ship (and its autopilot's target) drawn smaller than this (pixels across) gets a mark:
#: corner brackets round the ship, a diamond round the target.
SHIP_MARK_PX = 24.0
#: Below this speed (m/s) there is no direction of travel to mark.
MIN_SPEED = 1e-3

_VS = """
#version 330
uniform vec2 size;                // viewport, pixels
uniform bool textured;
in vec2 in_pos;                   // pixels, origin top-left, y down
in vec2 in_uv;                    // texture coordinates; untextured: (depth z/w in [-1, 1], 0)
out vec2 uv;
void main() {
    uv = in_uv;
    gl_Position = vec4(in_pos.x / size.x * 2.0 - 1.0, 1.0 - in_pos.y / size.y * 2.0,
                       textured ? 0.0 : in_uv.x, 1.0);
}
"""
_FS = """
#version 330
uniform sampler2D atlas;
uniform vec4 colour;
uniform bool textured;
in vec2 uv;
out vec4 frag;
void main() {
    float a = textured ? texture(atlas, uv).r : 1.0;
    frag = vec4(colour.rgb, colour.a * a);
}
"""


#: The HUD font: a subset of DejaVu Sans shipped with driftframe (framework/fonts/LICENSE.txt).
FONT_FILE = Path(__file__).resolve().parent.parent / "framework" / "fonts" / "DejaVuSans-HUD.ttf"
#: Characters the atlas holds: printable Latin-1, some Greek (Δ, μ, π, ω...), arrows and maths signs;
#: anything else is drawn as "?".
CHARS = "".join(chr(c) for c in [*range(0x20, 0x7F), *range(0xA1, 0x100), 0x0394, 0x03A9, 0x03B1, 0x03B2,
                                 0x03B3, 0x03B4, 0x03B5, 0x03B8, 0x03BB, 0x03BC, 0x03C0, 0x03C3, 0x03C4, 0x03C9,
                                 0x2190, 0x2191, 0x2192, 0x2193, 0x2022, 0x2026, 0x2212, 0x2248, 0x2260, 0x2264,
                                 0x2265, 0x221E, 0x2013, 0x2014])


class FontAtlas:
    """:data:`CHARS` rasterised once from :data:`FONT_FILE` (FreeType, through Pillow) into one texture."""

    COLUMNS = 16

    def __init__(self, ctx, pixel_size: int):
        from PIL import Image, ImageDraw, ImageFont

        font = ImageFont.truetype(str(FONT_FILE), size=pixel_size)
        ascent, descent = font.getmetrics()
        self.index = {c: i for i, c in enumerate(CHARS)}
        self.advance = {ch: float(font.getlength(ch)) for ch in CHARS}
        # a cell holds the widest glyph's ink (some overhang their advance) and the line's height
        ink = max(font.getbbox(c)[2] for c in CHARS)
        self.cell = (int(np.ceil(max(max(self.advance.values()), ink))) + 2, ascent + descent + 2)
        rows = -(-len(CHARS) // self.COLUMNS)
        cw, ch_ = self.cell
        img = Image.new("L", (cw * self.COLUMNS, ch_ * rows), 0)
        draw = ImageDraw.Draw(img)
        for i, c in enumerate(CHARS):
            draw.text(((i % self.COLUMNS) * cw + 1, (i // self.COLUMNS) * ch_ + 1), c, fill=255, font=font)
        self.image_size = img.size
        self.line_height = ch_
        self.texture = ctx.texture(img.size, 1, img.tobytes())
        self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)

    def quads(self, text: str, x: float, y: float) -> np.ndarray:
        """Two triangles per character, rows of (x, y, u, v) in pixels, top-left at (x, y)."""
        cw, ch = self.cell
        iw, ih = self.image_size
        out = []
        pen = x
        for c in text:
            if c not in self.index:
                c = "?"
            i = self.index[c]
            u0, v0 = (i % self.COLUMNS) * cw / iw, (i // self.COLUMNS) * ch / ih
            u1, v1 = u0 + cw / iw, v0 + ch / ih
            x0, y0, x1, y1 = pen - 1, y - 1, pen - 1 + cw, y - 1 + ch
            out += [(x0, y0, u0, v0), (x1, y0, u1, v0), (x1, y1, u1, v1),
                    (x0, y0, u0, v0), (x1, y1, u1, v1), (x0, y1, u0, v1)]
            pen += self.advance[c]
        return np.array(out, dtype="f4").reshape(-1, 4)

    def release(self):
        self.texture.release()


def project_direction(direction, view_rotation_only: np.ndarray, projection: np.ndarray, size) -> np.ndarray | None:
    """Pixel (x right, y down) where a world *direction* (a point at infinity) appears, or None if behind.

    ``clip = P @ R_view @ (d, 0)``: translation does not matter for a point
    at infinity, so the marker is the same in cockpit and chase views for the
    same viewing direction.
    """
    d = np.append(np.asarray(direction, dtype=float), 0.0)
    clip = projection @ (view_rotation_only @ d)
    if clip[3] <= 1e-12:
        return None
    ndc = clip[:2] / clip[3]
    w, h = size
    return np.array([(ndc[0] + 1.0) * 0.5 * w, (1.0 - ndc[1]) * 0.5 * h])


def _segments_to_triangles(segments: np.ndarray, width: float) -> np.ndarray:
    """Thick lines: each segment (x0, y0, x1, y1) becomes a quad ``width`` px wide, as (x, y, 0, 0) rows."""
    p0, p1 = segments[:, :2], segments[:, 2:]
    d = p1 - p0
    n = np.stack([-d[:, 1], d[:, 0]], 1) / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9)
    off = n * (width / 2)
    a, b, c, e = p0 + off, p1 + off, p1 - off, p0 - off
    tri = np.stack([a, b, c, a, c, e], 1).reshape(-1, 2)
    return np.hstack([tri, np.zeros_like(tri)]).astype("f4")


def marker_segments(centre, radius: float, kind: str) -> np.ndarray:
    """Line segments of a marker at ``centre``: prograde = circle with three ticks, retrograde = circle with an X,
    ship = four corner brackets of a square (the player's ship, where it is too small to see), target = a
    diamond (the autopilot's target, likewise)."""
    cx, cy = centre
    if kind == "target":
        k = radius * 1.2
        corners = np.array([[cx, cy - k], [cx + k, cy], [cx, cy + k], [cx - k, cy], [cx, cy - k]])
        return np.hstack([corners[:-1], corners[1:]])
    if kind == "ship":
        k, e = radius, radius * 0.45
        return np.array([[x0, y0, x0 + sx * e, y0] for x0, sx in ((cx - k, 1), (cx + k, -1)) for y0 in (cy - k, cy + k)]
                        + [[x0, y0, x0, y0 + sy * e] for x0 in (cx - k, cx + k) for y0, sy in ((cy - k, 1), (cy + k, -1))],
                        float)
    t = np.linspace(0, 2 * np.pi, 25)
    circle = np.stack([cx + radius * np.cos(t), cy + radius * np.sin(t)], 1)
    segs = [np.hstack([circle[:-1], circle[1:]])]
    if kind == "prograde":
        for ang in (0.0, np.pi, -np.pi / 2):       # left, right, up ticks
            u = np.array([np.cos(ang), np.sin(ang)])
            segs.append(np.hstack([centre + u * radius, centre + u * radius * 1.8])[None])
    else:
        k = radius * 0.7
        segs.append(np.array([[cx - k, cy - k, cx + k, cy + k], [cx - k, cy + k, cx + k, cy - k]]))
    return np.vstack(segs)


class HudSystem(esper.Processor):
    """Reads the Player's (or camera target's) Velocity and AngularVelocity, the active Camera,
    the render system's matrices; writes HUD pixels over the frame.

    Draws the prograde marker where the velocity direction projects, the
    retrograde marker opposite, and text: camera, speed (m/s), spin rate
    (rad/s), assist state; with a gravity well, the orbit readouts (apoapsis,
    periapsis, period and the time to each, an impact warning, the closest
    approach to the autopilot's target, the aid's status, the warp and why it
    dropped) and the predicted orbit as a line. Runs in stage "render" after every other drawer of the
    frame (``attach_rendering`` adds it with ``after=drawn_before(world)``: the scene, sky and effects)
    so it is on top, in the window and in recordings alike.
    """

    stage = "render"
    reads = (Player, Camera, Transform, Velocity, AngularVelocity, RotationAssist, FlightInput, GravityWell,
             Autopilot, ModelRef, OrbitState, TimeWarp, ModelCache)   # (the orbit readouts: OrbitState, the warp)
    writes = (RenderTarget,)

    def __init__(self, render, *, font_px: int | None = None):
        self.render = render
        ctx = render.ctx
        self.ctx = ctx
        h = render.size[1]
        # a 36th of the frame's height (20 px at 720p, 10 at 360p), never under 8 px: at 640x360 the orbit
        # readouts (ten lines) cover about a sixth of the frame
        self.font = FontAtlas(ctx, font_px or max(8, round(h / 36)))
        self.prog = ctx.program(vertex_shader=_VS, fragment_shader=_FS)
        self.vbo = ctx.buffer(reserve=4 * 4 * 6 * 512, dynamic=True)
        self.vao = ctx.vertex_array(self.prog, [(self.vbo, "2f 2f", "in_pos", "in_uv")])
        #: What the last frame showed (for tests and tools): marker pixels and the text lines.
        self.last: dict = {}
        #: Extra lines drawn in the bottom-left corner (a window's F3 overlay), or None.
        self.overlay: list[str] | None = None

    def _subject(self):
        players = sorted(e for e, _ in esper.get_component(Player))
        if players:
            return players[0]
        cam = esper.try_component(self.render.camera_entity, Camera) if self.render.camera_entity else None
        if cam is None or cam.target_lost or not esper.entity_exists(cam.target):
            return None
        return cam.target

    def lines(self, ent) -> list[str]:
        """The text lines for subject entity ``ent`` (the Player, or the camera's target)."""
        cam = esper.try_component(self.render.camera_entity, Camera) if self.render.camera_entity else None
        vel = esper.try_component(ent, Velocity) if ent is not None else None
        spin = esper.try_component(ent, AngularVelocity) if ent is not None else None
        out = [f"CAMERA  {cam.mode if cam else '-'}"]
        if cam is not None and cam.target_lost:
            out.append(f"TARGET LOST (entity {cam.target}): holding the last view")
        if vel is not None:                  # a fixed viewpoint (billiards, cradle) has no speed to show
            out.append(f"SPEED   {np.linalg.norm(vel.linear):7.2f} m/s")
        if spin is not None:
            out.append(f"SPIN    {np.linalg.norm(spin.angular):7.3f} rad/s")
        assist = esper.try_component(ent, RotationAssist) if ent is not None else None
        if assist is not None:
            inp = esper.try_component(ent, FlightInput)
            on = assist.engaged or (inp is not None and inp.kill_rotation)
            out.append(f"ASSIST  {'ON' if on else 'off'} ({assist.axes})")
        if ent is not None and esper.has_component(ent, Transform) and esper.has_component(ent, Velocity):
            from driftframe.systems import readouts
            out += readouts.lines(self.world, ent)         # orbit, target, autopilot, warp (none without)
        return out

    def _small_ship(self, ent, size):
        """Pixel centre of ``ent``'s model (the subject's, its target's) where drawn under :data:`SHIP_MARK_PX` across
        (a chase camera far back, an orbit seen from afar), so it is never lost; else None. Not from the
        cockpit it is seen from."""
        r = self.render
        ref = esper.try_component(ent, ModelRef) if ent is not None else None
        tf = esper.try_component(ent, Transform) if ref is not None else None
        cam = esper.try_component(r.camera_entity, Camera) if r.camera_entity else None
        if tf is None or ref.name not in r.cache or (cam is not None and cam.mode == "cockpit" and cam.target == ent):
            return None
        clip = r.view_projection @ np.append(tf.position, 1.0)
        if clip[3] <= 0:
            return None
        w, h = size
        across = 2.0 * r.cache.get(ref.name).radius * 0.5 * h * r.projection[1, 1] / clip[3]   # pixels
        px = np.array([(clip[0] / clip[3] + 1) * 0.5 * w, (1 - clip[1] / clip[3]) * 0.5 * h])
        if across >= SHIP_MARK_PX or not (0 <= px[0] <= w and 0 <= px[1] <= h):
            return None
        return px

    def _orbit_line(self, ent, size) -> np.ndarray:
        """Pixel segments (x0, y0, x1, y1, z0, z1) of ``ent``'s predicted orbit, with the full view-projection
        (so the line is right in the cockpit and the chase camera alike), and each end's depth ``z/w``;
        empty without a well."""
        from driftframe.systems import readouts
        if ent is None or not (esper.has_component(ent, Transform) and esper.has_component(ent, Velocity)):
            return np.empty((0, 6))
        pts = readouts.predicted_orbit(self.world, ent)
        if pts is None:
            return np.empty((0, 6))
        clip = np.hstack([pts, np.ones((len(pts), 1))]) @ self.render.view_projection.T
        front = clip[:, 3] > 1e-9
        w, h = size
        px = np.stack([(clip[:, 0] / clip[:, 3] + 1) * 0.5 * w, (1 - clip[:, 1] / clip[:, 3]) * 0.5 * h], 1)
        # beyond the far plane (a planet's orbit seen from far) the line still shows: z clamped into the depth range
        z = np.clip(clip[:, 2] / np.where(front, clip[:, 3], 1.0), -1.0, 1.0)
        keep = front[:-1] & front[1:]                         # segments wholly in front of the eye
        segs = np.hstack([px[:-1], px[1:], z[:-1, None], z[1:, None]])[keep]
        far = np.abs(segs[:, :4]).max(axis=1) < 8 * max(w, h) if len(segs) else np.zeros(0, bool)
        return segs[far]

    def _draw(self, data: np.ndarray, colour, textured: bool) -> None:
        if not len(data):
            return
        raw = data.astype("f4").tobytes()
        if len(raw) > self.vbo.size:
            self.vbo.orphan(len(raw))
        self.vbo.write(raw)
        self.prog["colour"].value = colour
        self.prog["textured"].value = textured
        self.vao.render(moderngl.TRIANGLES, vertices=len(data))

    def process(self, dt: float) -> None:
        r = self.render
        w, h = r.size
        r.target.use()
        ctx = self.ctx
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        self.prog["size"].value = (float(w), float(h))
        self.font.texture.use(0)
        self.prog["atlas"].value = 0

        ent = self._subject()
        if ent is not None and not esper.entity_exists(ent):
            ent = None
        vel = esper.try_component(ent, Velocity) if ent is not None else None
        markers = {}
        radius = max(6.0, h / 60)
        if vel is not None and np.linalg.norm(vel.linear) > MIN_SPEED:
            d = vel.linear / np.linalg.norm(vel.linear)
            for kind, sign, colour in (("prograde", 1.0, PROGRADE_COLOUR), ("retrograde", -1.0, RETROGRADE_COLOUR)):
                px = project_direction(sign * d, r.view_rotation_only, r.projection, (w, h))
                if px is not None and -radius <= px[0] <= w + radius and -radius <= px[1] <= h + radius:
                    markers[kind] = px
                    self._draw(_segments_to_triangles(marker_segments(px, radius, kind), 2.0), colour, False)
        ship_px = self._small_ship(ent, (w, h))
        if ship_px is not None:
            markers["ship"] = ship_px
            self._draw(_segments_to_triangles(marker_segments(ship_px, radius, "ship"), 2.0), SHIP_MARK_COLOUR, False)
        ap = esper.try_component(ent, Autopilot) if ent is not None else None
        aim_px = self._small_ship(ap.target, (w, h)) if ap is not None and ap.target is not None \
            and esper.entity_exists(ap.target) else None
        if aim_px is not None:
            markers["target"] = aim_px
            self._draw(_segments_to_triangles(marker_segments(aim_px, radius, "target"), 2.0), TARGET_MARK_COLOUR,
                       False)
        orbit = self._orbit_line(ent, (w, h))
        if len(orbit):
            # depth-tested against the scene (the planet hides the far side of the orbit), no depth writes
            tri = _segments_to_triangles(orbit[:, :4], 1.5)
            tri[:, 2] = orbit[:, [4, 5, 5, 4, 5, 4]].reshape(-1)    # corners a b c a c e: ends 0 1 1 0 1 0
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.depth_func = "<="
            r.target.fbo.depth_mask = False
            try:
                self._draw(tri, ORBIT_COLOUR, False)
            finally:
                r.target.fbo.depth_mask = True
                ctx.depth_func = "<"
                ctx.disable(moderngl.DEPTH_TEST)
            orbit = orbit[:, :4]
        text = self.lines(ent)
        pad = self.font.line_height // 2
        quads = [self.font.quads(line, pad, pad + i * self.font.line_height) for i, line in enumerate(text)]
        if self.overlay:
            top = h - pad - len(self.overlay) * self.font.line_height
            quads += [self.font.quads(line, pad, top + i * self.font.line_height)
                      for i, line in enumerate(self.overlay)]
        self._draw(np.vstack(quads), TEXT_COLOUR, True)
        ctx.disable(moderngl.BLEND)
        self.last = {"markers": markers, "text": text, "overlay": list(self.overlay or []), "orbit": orbit}

    def release(self) -> None:
        """Release the program, buffers and font texture (``world.close()`` calls it; idempotent)."""
        if self.prog is None:
            return
        for obj in (self.vao, self.vbo, self.prog):
            obj.release()
        self.font.release()
        self.vao = self.vbo = self.prog = None
