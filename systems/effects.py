"""Impacts you can see: sparks and a flash at every contact (a CollisionEvent, or a SurfaceContact with a
well's surface), and the engine's plume while it thrusts.

Pure presentation: the system reads the frame's events and the player's
throttle and draws additive points into the render target; it never writes
a component, so the simulation (and its state hash) is the same with or
without it. Everything is deterministic: a burst's random numbers come from
a generator seeded with the contact's step and entities, the plume's from the
step count, and particles age in simulated time, so the same run gives the
same frames.

* **sparks**: ``n = 6 + 30 s`` points (``s`` = loudness in [0, 1], the
  closing speed the impulse took out over 6 m/s, as the sound's), flying
  from the contact point at ``k (1 + 5 s) m/s`` times a random factor, in
  random directions biased along the contact normal both ways (the two
  surfaces), yellow-white fading to red over 0.3-0.8 s; ``k`` is the smaller
  body's radius in metres (0.1 to 2): a billiard ball's sparks are a pebble's,
  a boulder's bigger; a spark is ``k (0.15 + 0.25 s)`` m across;
* **flash**: one large white point at the contact for 0.12 s, its size
  ``k (0.5 + 1.5 s)`` m, fading quadratically;
* **plume**: while the player's ``|throttle| > 0``, 14 points along 3 m behind
  the ship's tail (blue-white at the nozzle, orange at the end), jittered.

Points are sized in metres and drawn ``f_px size / depth`` pixels across
(from 1.5 to a sixteenth of the frame's height), round, with a soft edge, faded within 1.5 m of
the eye; depth test on and depth writes off,
so a rock in front hides a spark behind it.
"""
from __future__ import annotations

import esper
import moderngl
import numpy as np

from driftframe.components.body import Mass, Transform
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.components.control import FlightInput, Player
from driftframe.components.gravity import SurfaceContact
from driftframe.framework import frame as fr
from driftframe.framework.gl import RenderTarget

_VS = """
#version 330
uniform mat4 u_view_proj;      // projection * view rotation: positions are eye-relative
uniform float u_px;            // pixels per metre at 1 m depth
uniform float u_max_px;        // the largest point, pixels (1/16 of the frame's height)
in vec3 in_pos;                // eye-relative, m
in vec4 in_colour;             // RGB and intensity
in float in_size;              // m
out vec4 v_colour;
void main() {
    gl_Position = u_view_proj * vec4(in_pos, 1.0);
    gl_PointSize = clamp(u_px * in_size / max(gl_Position.w, 1e-3), 1.5, u_max_px);
    // fade what is within a few metres of the eye (a hit on the ship seen from its cockpit)
    v_colour = vec4(in_colour.rgb, in_colour.a * smoothstep(0.2, 1.5, gl_Position.w));
}
"""

_FS = """
#version 330
in vec4 v_colour;
out vec4 f_colour;
void main() {
    vec2 d = gl_PointCoord * 2.0 - 1.0;
    float r2 = dot(d, d);
    if (r2 > 1.0) discard;
    float a = v_colour.a * (1.0 - r2) * (1.0 - r2);     // soft round point
    f_colour = vec4(v_colour.rgb * a, 1.0);
}
"""

#: Particles alive at most (older ones go first).
MAX_PARTICLES = 4096
_FLOATS = 8          # x y z, r g b intensity, size


class EffectsSystem(esper.Processor):
    """Reads the frame's CollisionEvent, Mass, the player's Transform and FlightInput; writes points into
    the RenderTarget (see the module docstring). ``render``: the render system it draws after (the world's
    other drawers, a sky: :func:`driftframe.rendering.drawn_before`, which ``attach_rendering`` passes)."""

    stage = "render"
    reads = (CollisionEvent, SurfaceContact, Mass, SphereCollider, Transform, FlightInput, Player)
    writes = (RenderTarget,)

    def __init__(self, render):
        self.render = render
        self.after = (type(render),)    # over the models it lights up, under the HUD added after it
        ctx = render.ctx
        self.ctx = ctx
        self._prog = ctx.program(vertex_shader=_VS, fragment_shader=_FS)
        self._buf = ctx.buffer(reserve=MAX_PARTICLES * _FLOATS * 4, dynamic=True)
        self._vao = ctx.vertex_array(self._prog, [(self._buf, "3f 4f 1f", "in_pos", "in_colour", "in_size")])
        # particles: start position (m, world), velocity (m/s), birth and life (s), colour, size (m)
        self._p = np.zeros((0, 3))
        self._v = np.zeros((0, 3))
        self._born = np.zeros(0)
        self._life = np.zeros(0)
        self._rgb = np.zeros((0, 3))
        self._size = np.zeros(0)
        self._heard_step = -1
        #: Particles drawn in the last frame.
        self.drawn = 0

    def _add(self, p, v, born, life, rgb, size) -> None:
        self._p = np.vstack([self._p, p])[-MAX_PARTICLES:]
        self._v = np.vstack([self._v, v])[-MAX_PARTICLES:]
        self._born = np.concatenate([self._born, born])[-MAX_PARTICLES:]
        self._life = np.concatenate([self._life, life])[-MAX_PARTICLES:]
        self._rgb = np.vstack([self._rgb, rgb])[-MAX_PARTICLES:]
        self._size = np.concatenate([self._size, size])[-MAX_PARTICLES:]

    def _burst(self, ev: CollisionEvent) -> None:
        inv = sum(_inverse_mass(e) for e in (ev.a, ev.b))
        k = min(2.0, max(0.1, min(_radius(ev.a), _radius(ev.b))))   # the smaller body's radius sets the scale, m
        self._sparks(np.asarray(ev.point, float), np.asarray(ev.normal, float), ev.time, ev.impulse * inv, k,
                     [max(ev.step, 0), ev.a, ev.b])

    def _touchdown(self, ev: SurfaceContact) -> None:
        """A body bouncing off a well's surface: sparks where it touched (under its centre, towards the
        well), scaled by the body's radius, as loud as the sound's (twice the radial speed)."""
        tf = esper.try_component(ev.entity, Transform) if esper.entity_exists(ev.entity) else None
        well = esper.try_component(ev.well, Transform) if esper.entity_exists(ev.well) else None
        if tf is None or well is None:
            return
        out = tf.position - well.position
        if not np.linalg.norm(out) > 0:
            return
        n = out / np.linalg.norm(out)
        r = _radius(ev.entity)
        self._sparks(tf.position - n * r, n, ev.time, 2.0 * abs(ev.normal_speed), min(2.0, max(0.1, r)),
                     [int(round(ev.time * 1e6)), ev.entity, ev.well])

    def _sparks(self, point, normal, time: float, strength: float, k: float, seed) -> None:
        s = min(1.0, (max(strength, 0.0) / 6.0) ** 0.6)
        rng = np.random.default_rng(seed)
        n = int(6 + 30 * s)
        d = rng.normal(size=(n, 3)) + np.outer(np.where(rng.random(n) < 0.5, 1.5, -1.5), normal)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        speed = k * (1.0 + 5.0 * s) * rng.uniform(0.3, 1.0, n)
        hot = rng.uniform(0.0, 1.0, (n, 1))
        rgb = np.array([1.0, 0.85, 0.45]) * (1 - hot) + np.array([1.0, 1.0, 0.9]) * hot
        self._add(np.tile(point, (n, 1)), d * speed[:, None], np.full(n, time), rng.uniform(0.3, 0.8, n),
                  rgb, np.full(n, k * (0.15 + 0.25 * s)))
        self._add(point[None], np.zeros((1, 3)), [time], [0.12], [[1.0, 0.95, 0.85]], [k * (0.5 + 1.5 * s)])

    def _plume(self, now: float, step: int) -> list[np.ndarray]:
        out = []
        for ent, (_, flight, tf) in esper.get_components(Player, FlightInput, Transform):
            level = abs(float(flight.throttle))
            if level <= 0.0:
                continue
            rng = np.random.default_rng([step, ent])
            back = -np.sign(flight.throttle) * fr.rotate(tf.orientation, fr.FORWARD)
            k = np.arange(14) / 13.0
            pos = tf.position + np.outer(1.1 + 3.0 * level * k, back) + rng.normal(0.0, 0.06, (14, 3))
            rgb = np.array([0.6, 0.8, 1.0]) * (1 - k[:, None]) + np.array([1.0, 0.5, 0.15]) * k[:, None]
            inten = (1.0 - 0.8 * k) * (0.7 + 0.3 * level)
            size = 0.55 - 0.25 * k
            out.append(np.column_stack([pos, rgb, inten, size]))
        return out

    def process(self, dt: float) -> None:
        world = self.world
        if world.step_count != self._heard_step:        # each contact once (motion blur renders a frame again)
            self._heard_step = world.step_count
            for ev in world.events:
                if isinstance(ev, CollisionEvent):
                    self._burst(ev)
                elif isinstance(ev, SurfaceContact):
                    self._touchdown(ev)
        now = world.time
        age = now - self._born
        alive = age < self._life
        if not alive.all():
            self._p, self._v, self._born = self._p[alive], self._v[alive], self._born[alive]
            self._life, self._rgb, self._size = self._life[alive], self._rgb[alive], self._size[alive]
            age = age[alive]
        fade = np.clip(1.0 - age / np.maximum(self._life, 1e-9), 0.0, 1.0)
        pos = self._p + self._v * age[:, None]
        cool = np.column_stack([np.ones_like(fade), fade, fade ** 2])          # white-yellow to red
        rows = [np.column_stack([pos, self._rgb * cool, fade ** 2, self._size])] if len(fade) else []
        rows += self._plume(now, world.step_count)
        if not rows:
            self.drawn = 0
            return
        data = np.vstack(rows)[-MAX_PARTICLES:]
        r = self.render
        data[:, :3] -= r.eye_position                  # eye-relative, in float64 before float32
        self._buf.write(data.astype(np.float32).tobytes())
        vp = (r.projection @ r.view_rotation_only).astype(np.float32)
        self._prog["u_view_proj"].write(vp.T.tobytes())
        self._prog["u_px"].value = float(0.5 * r.size[1] * r.projection[1, 1])
        self._prog["u_max_px"].value = max(2.0, r.size[1] / 16.0)
        ctx = self.ctx
        r.target.use()
        ctx.enable(moderngl.DEPTH_TEST | moderngl.BLEND | moderngl.PROGRAM_POINT_SIZE)
        ctx.blend_func = moderngl.ONE, moderngl.ONE                          # additive: light adds up
        fbo = r.target.fbo
        fbo.depth_mask = False
        try:
            self._vao.render(moderngl.POINTS, vertices=len(data))
        finally:
            fbo.depth_mask = True
            ctx.disable(moderngl.BLEND | moderngl.PROGRAM_POINT_SIZE)
            ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        self.drawn = len(data)

    def release(self) -> None:
        """Free the program, buffer and vertex array. Safe to call twice."""
        if self._prog is not None:
            self._vao.release()
            self._buf.release()
            self._prog.release()
        self._prog = self._vao = self._buf = None


def _radius(ent: int) -> float:
    c = esper.try_component(ent, SphereCollider) if esper.entity_exists(ent) else None
    return 1.0 if c is None else float(c.radius)


def _inverse_mass(ent: int) -> float:
    m = esper.try_component(ent, Mass) if esper.entity_exists(ent) else None
    return 1.0 if m is None else m.inverse
