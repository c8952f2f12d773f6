"""A cube map's mipmaps made with numpy and written through the GL library, instead of ``glGenerateMipmap``.

Why: on llvmpipe (Mesa's software GL: the tests, a headless server) the first ``glGenerateMipmap`` of a
process compiles the driver's blit shaders with LLVM, ~0.08 s of CPU, more than the starfield's whole
texture costs to make. The levels made here are llvmpipe's own, byte for byte: each texel of level k + 1 is
the bilinear sample at the centre of its 2 x 2 texels of level k, which llvmpipe computes in 8-bit fixed
point as rounded halvings, rows first: ``((a + b + 1) >> 1 + (c + d + 1) >> 1 + 1) >> 1`` (checked against
its ``glGenerateMipmap`` read back, seeds 0-5, sizes 16-512; tests/test_skybox.py compares drawn frames).

moderngl (5.13) writes only level 0 of a cube map, so the other levels go through ``glTexImage2D`` of the
process's ``libGL.so.1`` (ctypes: the library moderngl's EGL and GLX contexts use on Linux), to the context
current on this thread, and the GL state it touches (active unit, cube-map binding, unpack alignment and
buffer) is put back. Where that cannot be done (no ``libGL.so.1``, a size that is no power of two, a GL
error) :func:`write_levels` returns False and the caller builds them the usual way.
"""
from __future__ import annotations

import ctypes

import numpy as np

_TEXTURE_CUBE_MAP, _POSITIVE_X = 0x8513, 0x8515
_ACTIVE_TEXTURE, _TEXTURE_BINDING_CUBE_MAP = 0x84E0, 0x8514
_UNPACK_ALIGNMENT, _PIXEL_UNPACK_BUFFER, _PIXEL_UNPACK_BUFFER_BINDING = 0x0CF5, 0x88EC, 0x88EF
_TEXTURE_INTERNAL_FORMAT = 0x1003
_FORMATS = {1: 0x1903, 2: 0x8227, 3: 0x1907, 4: 0x1908}     # GL_RED, GL_RG, GL_RGB, GL_RGBA
_UNSIGNED_BYTE = 0x1401

_gl = None          # libGL.so.1, loaded at the first write (False: not there)


def levels(faces: np.ndarray) -> list[np.ndarray]:
    """Levels 1, 2, ... down to 1 x 1 of the (6, n, n, c) uint8 cube map ``faces`` (n a power of two)."""
    out = []
    cur = faces
    while cur.shape[1] > 1:
        a = cur.astype(np.uint16)
        top = a[:, 0::2, 0::2] + a[:, 0::2, 1::2]
        top += 1
        top >>= 1
        bottom = a[:, 1::2, 0::2] + a[:, 1::2, 1::2]
        bottom += 1
        bottom >>= 1
        top += bottom
        top += 1
        top >>= 1
        cur = top.astype(np.uint8)
        out.append(cur)
    return out


def _library():
    global _gl
    if _gl is None:
        try:
            _gl = ctypes.CDLL("libGL.so.1")
            for name in ("glGetIntegerv", "glBindBuffer", "glPixelStorei", "glBindTexture", "glActiveTexture",
                         "glGetTexLevelParameteriv", "glTexImage2D"):
                getattr(_gl, name)                # AttributeError where the library lacks one
            _gl.glGetError.restype = ctypes.c_uint
        except (OSError, AttributeError):
            _gl = False
    return _gl


def _int(gl, name: int) -> int:
    v = ctypes.c_int(0)
    gl.glGetIntegerv(name, ctypes.byref(v))
    return v.value


def write_levels(texture, faces: np.ndarray) -> bool:
    """Write :func:`levels` of ``faces`` (its level 0, already in ``texture``, a moderngl ``TextureCube``) as
    levels 1, 2, ... of ``texture``; its context must be current. False (nothing written) where this cannot
    be done: then ``texture.build_mipmaps()``."""
    n = faces.shape[1]
    gl = _library()
    if not gl or faces.dtype != np.uint8 or n & (n - 1) or faces.shape[3] not in _FORMATS:
        return False
    for _ in range(16):                          # errors left by earlier calls are not ours
        if gl.glGetError() == 0:
            break
    unit, bound = _int(gl, _ACTIVE_TEXTURE), _int(gl, _TEXTURE_BINDING_CUBE_MAP)
    alignment, unpack = _int(gl, _UNPACK_ALIGNMENT), _int(gl, _PIXEL_UNPACK_BUFFER_BINDING)
    gl.glBindBuffer(_PIXEL_UNPACK_BUFFER, 0)     # (data from memory, not from a buffer)
    gl.glPixelStorei(_UNPACK_ALIGNMENT, 1)
    gl.glBindTexture(_TEXTURE_CUBE_MAP, texture.glo)
    internal = ctypes.c_int(0)
    gl.glGetTexLevelParameteriv(_POSITIVE_X, 0, _TEXTURE_INTERNAL_FORMAT, ctypes.byref(internal))
    fmt = _FORMATS[faces.shape[3]]
    try:
        if gl.glGetError() != 0:                 # the texture is not this context's
            return False
        for k, level in enumerate(levels(faces), 1):
            m = level.shape[1]
            for f in range(6):
                data = np.ascontiguousarray(level[f])
                gl.glTexImage2D(_POSITIVE_X + f, k, internal.value, m, m, 0, fmt, _UNSIGNED_BYTE,
                                ctypes.c_void_p(data.ctypes.data))
        return gl.glGetError() == 0
    finally:
        gl.glBindTexture(_TEXTURE_CUBE_MAP, bound)
        gl.glActiveTexture(unit)
        gl.glPixelStorei(_UNPACK_ALIGNMENT, alignment)
        gl.glBindBuffer(_PIXEL_UNPACK_BUFFER, unpack)
