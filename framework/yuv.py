"""RGBA frames to NV12 (H.264's 4:2:0 input) on the CPU, in integer arithmetic: the same bytes everywhere.

::

    from driftframe.framework.yuv import rgba_to_nv12
    nv12 = rgba_to_nv12(target.read_raw(), width, height)    # GL order in, top row first out

The recorder's default MP4 path (:mod:`framework.recorder`): the caller's
thread converts each frame right after it is read back, while it is still
in that core's cache, and hands ffmpeg 1.5 bytes a pixel instead of 4, so
ffmpeg only encodes. Measured on the asteroids demo at 1280x720 on 2 cores
(``benchmarks/record_throughput.py``): this kernel takes about 1 ms a frame,
where ffmpeg's own conversion (swscale, with the flip) took 3.3 ms of CPU
and the pipe carried 2.7x the bytes.

The numbers are BT.709, limited ("TV") range, as the video is tagged:
``Y' = 16 + 219 (Kr R + Kg G + Kb B) / 255`` per pixel, and ``Cb``, ``Cr``
(``128 +/- 112``) of the mean of each 2x2 block, the same matrix and the
same box average as the shader path (``yuv="gpu"``). Coefficients are 16-bit
fixed point and every sum is rounded once, so a value is never more than
one step from the exact one, and integer arithmetic makes it the same on
every machine. The input is GL order (bottom row first): the flip is free,
rows are read in reverse.
"""
from __future__ import annotations

import sys

import numpy as np
from numba import njit

_S = 16                                        # fixed-point fraction bits
_KR, _KB = 0.2126, 0.0722
_KG = 1.0 - _KR - _KB


def _fx(v: float) -> int:
    return int(round(v * (1 << _S)))


# luma of one pixel: 16 + 219/255 (Kr R + Kg G + Kb B)
_YR, _YG, _YB = (_fx(219 / 255 * k) for k in (_KR, _KG, _KB))
_Y0 = (16 << _S) + (1 << (_S - 1))             # offset, plus a half for rounding
# chroma of a 2x2 block from the *sums* of its four R, G, B (hence 2 more bits of shift):
# Cb = 128 + 224/255 (B - Y) / (2 (1 - Kb)), Cr = 128 + 224/255 (R - Y) / (2 (1 - Kr)), Y = Kr R + Kg G + Kb B
_CB, _CR = 224 / 255 / (2 * (1 - _KB)), 224 / 255 / (2 * (1 - _KR))
_UR, _UG, _UB = _fx(-_KR * _CB), _fx(-_KG * _CB), _fx((1 - _KB) * _CB)
_VR, _VG, _VB = _fx((1 - _KR) * _CR), _fx(-_KG * _CR), _fx(-_KB * _CR)
_C0 = (128 << (_S + 2)) + (1 << (_S + 1))
# where R, G and B sit in a pixel read as one native uint32 (RGBA bytes in memory)
_SHIFT_R, _SHIFT_G, _SHIFT_B = (0, 8, 16) if sys.byteorder == "little" else (24, 16, 8)


@njit(cache=True, nogil=True, boundscheck=False)
def _nv12(src, dst, w, h):                         # pragma: no cover - compiled
    """``src``: (h, w) uint32, one RGBA pixel each, GL order. ``dst``: w h 3/2 uint8, NV12, top row first."""
    sr, sg, sb = _SHIFT_R, _SHIFT_G, _SHIFT_B       # compile-time constants
    uv0 = w * h
    for j in range(h // 2):
        a = src[h - 1 - 2 * j]                     # image row 2j (GL rows run bottom up)
        b = src[h - 2 - 2 * j]                     # image row 2j + 1
        ya = dst[2 * j * w:(2 * j + 1) * w]
        yb = dst[(2 * j + 1) * w:(2 * j + 2) * w]
        # one simple loop per row: each vectorises (whole pixels loaded as uint32, channels by shift)
        for i in range(w):
            p = np.int32(a[i])
            ya[i] = np.uint8((_YR * ((p >> sr) & 255) + _YG * ((p >> sg) & 255) + _YB * ((p >> sb) & 255)
                              + _Y0) >> _S)
        for i in range(w):
            p = np.int32(b[i])
            yb[i] = np.uint8((_YR * ((p >> sr) & 255) + _YG * ((p >> sg) & 255) + _YB * ((p >> sb) & 255)
                              + _Y0) >> _S)
        c = dst[uv0 + j * w:uv0 + (j + 1) * w]     # this block row's interleaved Cb Cr
        for i in range(w // 2):
            p0 = np.int32(a[2 * i])
            p1 = np.int32(a[2 * i + 1])
            q0 = np.int32(b[2 * i])
            q1 = np.int32(b[2 * i + 1])
            rs = ((p0 >> sr) & 255) + ((p1 >> sr) & 255) + ((q0 >> sr) & 255) + ((q1 >> sr) & 255)
            gs = ((p0 >> sg) & 255) + ((p1 >> sg) & 255) + ((q0 >> sg) & 255) + ((q1 >> sg) & 255)
            bs = ((p0 >> sb) & 255) + ((p1 >> sb) & 255) + ((q0 >> sb) & 255) + ((q1 >> sb) & 255)
            c[2 * i] = np.uint8((_UR * rs + _UG * gs + _UB * bs + _C0) >> (_S + 2))
            c[2 * i + 1] = np.uint8((_VR * rs + _VG * gs + _VB * bs + _C0) >> (_S + 2))


def nv12_size(width: int, height: int) -> int:
    """Bytes of one NV12 frame: a full-size Y plane and a half-size interleaved CbCr plane."""
    return width * height * 3 // 2


def rgba_to_nv12(rgba, width: int, height: int, out: np.ndarray | None = None) -> np.ndarray:
    """NV12 of an RGBA frame in GL order (bytes or an array of ``width * height * 4`` uint8).

    ``width`` and ``height`` must be even (4:2:0). ``out``: a uint8 array of
    :func:`nv12_size` bytes to write into (reuse one to save an allocation a
    frame); a new one otherwise. Returns ``out``.
    """
    w, h = int(width), int(height)
    if w <= 0 or h <= 0 or w % 2 or h % 2:
        raise ValueError(f"NV12 needs an even width and height, got {width}x{height}")
    src = np.frombuffer(rgba, np.uint8) if not isinstance(rgba, np.ndarray) else rgba.reshape(-1)
    if src.dtype != np.uint8 or src.size != w * h * 4:
        raise ValueError(f"expected {w * h * 4} bytes of RGBA for {w}x{h}, got {src.size} of {src.dtype}")
    if out is None:
        out = np.empty(nv12_size(w, h), np.uint8)
    elif out.dtype != np.uint8 or out.size != nv12_size(w, h) or not out.flags.c_contiguous:
        raise ValueError(f"out must be a contiguous uint8 array of {nv12_size(w, h)} bytes, "
                         f"got {out.size} of {out.dtype}")
    if src.ctypes.data % 4:                        # a uint32 view needs aligned memory (bytes objects are)
        src = src.copy()
    _nv12(src.view(np.uint32).reshape(h, w), out.reshape(-1), w, h)
    return out
