"""How MP4 frames become NV12 (Y plane, then interleaved Cb Cr at half size), x264's input.

Three paths (``record(yuv=...)``): ``"cpu"`` (the default) reads the frame
back in bands of rows and converts each band at once with
:mod:`framework.yuv`; ``"gpu"`` converts in a shader and reads back the
planes; ``"ffmpeg"`` hands RGBA to FFmpeg's scaler in the sink
(:mod:`framework.record_sinks`). All use BT.709, limited range. The
pictures agree to within rounding; the bytes differ. Which is fastest where:
``docs/bench/record_throughput.md``.
"""
from __future__ import annotations

import itertools

import numpy as np

from driftframe.framework.gl import current

#: How MP4 frames reach x264 (``record(yuv=...)``): converted on the CPU by :mod:`framework.yuv` (the
#: default), in a shader, or by FFmpeg's scaler (libswscale) from RGBA.
YUV_PATHS = ("cpu", "gpu", "ffmpeg")


def _nv12_ring(size, depth: int):
    """NV12 frame buffers to use in turn: ``depth + 2``. The writer holds at most ``depth`` queued frames
    and the one it is writing, so a buffer is reused only after x264 has taken its frame."""
    from driftframe.framework.yuv import nv12_size

    return itertools.cycle([np.empty(nv12_size(*size), np.uint8) for _ in range(depth + 2)])


def _cpu_nv12(grab, size, depth: int):
    """A ``grab()`` that returns the RGBA frame ``grab()`` gives as NV12 (:func:`framework.yuv.rgba_to_nv12`).

    For frames made in memory (motion blur's average); a frame read from the
    target is converted as it is read (:func:`_banded_nv12`).
    """
    from driftframe.framework.yuv import rgba_to_nv12

    w, h = size
    ring = _nv12_ring(size, depth)

    def converted():
        return rgba_to_nv12(grab(), w, h, next(ring))

    return converted


def _banded_nv12(target, depth: int, band_bytes: int | None = None):
    """A ``grab()`` that reads the target's frame in bands of rows and converts each to NV12 at once.

    A band (:class:`framework.yuv.BandedNV12`) is converted while it is
    still in this core's cache. The bytes are the same as converting the
    whole frame after reading it.
    """
    from driftframe.framework.yuv import BandedNV12

    conv = BandedNV12(*target.size, band_bytes=band_bytes)   # None: yuv.BAND_BYTES
    ring = _nv12_ring(target.size, depth)
    read, convert, bands = target.read_rows_into, conv.convert, conv.bands

    def converted():
        out = next(ring)
        for y, n, band in bands:
            read(band, y, n)
            convert(y, out)
        return out

    return converted


# -- colour conversion on the GPU: x264 receives finished planes and only encodes --------------------
_FULLSCREEN_VS = """
#version 330
out vec2 v_uv;
void main() {                      // one triangle covering the viewport, no vertex buffer
    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
    v_uv = 0.5 * p + 0.5;
    gl_Position = vec4(p, 0.0, 1.0);
}
"""
# BT.709, limited ("TV") range, as the video is tagged: Y' = Kr R + Kg G + Kb B on 16..235,
# Cb = (B - Y') / (2 (1 - Kb)) and Cr = (R - Y') / (2 (1 - Kr)) on 16..240 around 128.
_YUV_COMMON = """
#version 330
uniform sampler2D u_rgb;           // the frame, GL order (bottom row first)
uniform vec2 u_size;               // frame size, px
const vec3 K = vec3(0.2126, 0.7152, 0.0722);
"""
_NV12_FS = _YUV_COMMON + """
// One fragment per 4x2 block of pixels, each pixel fetched once (llvmpipe pays per fragment and per fetch):
layout(location = 0) out vec4 f_y0;   // luma of the block's 4 pixels on image row 2y (top row first)
layout(location = 1) out vec4 f_y1;   // ... and on image row 2y + 1
layout(location = 2) out vec4 f_uv;   // (Cb, Cr) of its two 2x2 halves: a piece of NV12's chroma row
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    int r0 = int(u_size.y) - 1 - 2 * p.y;   // GL row (bottom up) of image row 2y: the flip happens here
    int x = 4 * p.x;
    vec3 a0 = texelFetch(u_rgb, ivec2(x, r0), 0).rgb, a1 = texelFetch(u_rgb, ivec2(x + 1, r0), 0).rgb;
    vec3 a2 = texelFetch(u_rgb, ivec2(x + 2, r0), 0).rgb, a3 = texelFetch(u_rgb, ivec2(x + 3, r0), 0).rgb;
    vec3 b0 = texelFetch(u_rgb, ivec2(x, r0 - 1), 0).rgb, b1 = texelFetch(u_rgb, ivec2(x + 1, r0 - 1), 0).rgb;
    vec3 b2 = texelFetch(u_rgb, ivec2(x + 2, r0 - 1), 0).rgb, b3 = texelFetch(u_rgb, ivec2(x + 3, r0 - 1), 0).rgb;
    f_y0 = (16.0 + 219.0 * vec4(dot(K, a0), dot(K, a1), dot(K, a2), dot(K, a3))) / 255.0;
    f_y1 = (16.0 + 219.0 * vec4(dot(K, b0), dot(K, b1), dot(K, b2), dot(K, b3))) / 255.0;
    // 4:2:0: each chroma sample is the mean of a 2x2 block
    vec3 c0 = 0.25 * (a0 + a1 + b0 + b1), c1 = 0.25 * (a2 + a3 + b2 + b3);
    float y0 = dot(K, c0), y1 = dot(K, c1);
    f_uv = vec4(128.0 + 224.0 * (c0.b - y0) / 1.8556, 128.0 + 224.0 * (c0.r - y0) / 1.5748,
                128.0 + 224.0 * (c1.b - y1) / 1.8556, 128.0 + 224.0 * (c1.r - y1) / 1.5748) / 255.0;
}
"""


class _YuvConverter:
    """Turns the render target's frame into NV12 (Y plane, then interleaved Cb Cr at half size) on the GPU.

    One shader pass converts and flips, into three RGBA8 targets a quarter
    as wide and half as high (even luma rows, odd luma rows, chroma), read
    back without conversion (1.5 bytes per pixel instead of 4). Needs a
    width that is a multiple of 4 and an even height. The planes are read
    at once: reading the previous frame's while this one converts was no
    faster on llvmpipe (docs/design/recorder.md).
    """

    def __init__(self, target):
        import moderngl

        ctx = target.ctx
        with current(ctx):                         # (its objects are the target's context's)
            w, h = target.size
            self.ctx, self.target, self.size = ctx, target, (w, h)
            self._rgb = ctx.texture((w, h), 4)
            self._rgb.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._planes = [ctx.texture((w // 4, h // 2), 4) for _ in range(3)]
            self._fbo = ctx.framebuffer(color_attachments=self._planes)
            self._prog = ctx.program(vertex_shader=_FULLSCREEN_VS, fragment_shader=_NV12_FS)
            self._prog["u_rgb"].value = 0
            self._prog["u_size"].value = (float(w), float(h))
            self._vao = ctx.vertex_array(self._prog, [])
            self._state = moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND
            self._triangles = moderngl.TRIANGLES

    def convert(self, rgba: bytes | None = None) -> np.ndarray:
        """NV12 of the target's current frame (or of ``rgba``, GL order, e.g. a motion-blurred average).

        A new uint8 array each call (the writer thread may still hold the last one).
        """
        ctx = self.ctx
        with current(ctx):
            if rgba is None:
                ctx.copy_framebuffer(self._rgb, self.target.fbo)
            else:
                self._rgb.write(rgba)
            self._rgb.use(0)
            w, h = self.size
            # a plain pass: the render system sets depth test and culling again at the start of each frame
            ctx.disable(self._state)
            self._fbo.use()
            ctx.viewport = (0, 0, w // 4, h // 2)
            self._vao.render(self._triangles, vertices=3)
            out = np.empty(w * h * 3 // 2, np.uint8)
            luma = out[:w * h].reshape(h // 2, 2, w)            # rows 2y and 2y + 1 from the two luma targets
            for j in range(2):
                luma[:, j, :] = np.frombuffer(self._fbo.read(components=4, attachment=j, alignment=1),
                                              np.uint8).reshape(h // 2, w)
            out[w * h:] = np.frombuffer(self._fbo.read(components=4, attachment=2, alignment=1), np.uint8)
            self.target.use()
            return out

    def release(self) -> None:
        with current(self.ctx):
            for obj in (self._vao, self._prog, self._fbo, *self._planes, self._rgb):
                obj.release()
        self._planes = []

