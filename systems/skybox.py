"""The skybox: a cube of green lines around the eye, fixed in world orientation.

It is drawn with the view's *rotation only* (no translation), so turning the
camera shows in it and moving the camera does not: it stands for things
infinitely far away. Each vertex is pushed to the far plane
(``gl_Position = clip.xyww``: depth ``z/w = 1``) and drawn with depth test
``<=`` and depth writes off, after the models: the lines appear only where
nothing else was drawn, and the fragments hidden behind models cost nothing.
"""
from __future__ import annotations

import esper
import moderngl
import numpy as np

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
    ``colour``: RGB (default: the model's green). Must run after the
    :class:`~systems.render.RenderSystem` it is given (``attach`` adds it so).
    """

    stage = "render"
    reads = ()          # the render system's view (no components)
    writes = ()

    def __init__(self, ctx, cache: ModelCache, render, *, model: str = "skybox", colour=None):
        self.ctx = ctx
        self.render = render
        m = cache.get(model)
        if m.meshes.mode != "lines":
            raise ValueError(f"SkyboxSystem: model {model!r} must be made of lines, got {m.meshes.mode!r}")
        self.colour = tuple((m.colour if colour is None else check_colour("skybox colour", colour)).tolist())
        self.scale = m.scale
        vbo, ibo = cache.buffers(m)[-1]
        self._prog = ctx.program(vertex_shader=VERTEX_SHADER, fragment_shader=FRAGMENT_SHADER)
        self._vao = ctx.vertex_array(self._prog, [(vbo, "3f 12x", "in_position")],
                                     index_buffer=ibo, index_element_size=4)
        self._drawn_frame = 0

    def process(self, dt: float) -> None:
        if self._prog is None:
            raise RuntimeError("SkyboxSystem was released (world closed)")
        r = self.render
        if r.frame == self._drawn_frame:
            raise RuntimeError("SkyboxSystem must run after its RenderSystem in the render stage "
                               "(systems.render.attach adds them in that order)")
        self._drawn_frame = r.frame
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
