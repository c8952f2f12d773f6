"""RGBA frames to NV12 (H.264's 4:2:0 input) on the CPU, in integer arithmetic: the same bytes everywhere.

::

    from driftframe.framework.yuv import rgba_to_nv12
    nv12 = rgba_to_nv12(target.read_raw(), width, height)    # GL order in, top row first out

The recorder's default MP4 path (:mod:`framework.recorder`) reads each
frame back in bands of rows and converts each band at once, while it is
still in the core's cache (:class:`BandedNV12`), and hands x264 1.5 bytes
a pixel instead of 4, so it only encodes: a fraction of the CPU of FFmpeg's
own conversion (``docs/design/recorder.md``, "NV12").

The numbers are BT.709, limited ("TV") range, as the video is tagged:
``Y' = 16 + 219 (Kr R + Kg G + Kb B) / 255`` per pixel, and ``Cb``, ``Cr``
(``128 +/- 112``) of the mean of each 2x2 block, the same matrix and the
same box average as the shader path (``yuv="gpu"``). Coefficients are 16-bit
fixed point and every sum is rounded once, so a value is never more than
one step from the exact one, and integer arithmetic makes it the same on
every machine. The input is GL order (bottom row first): rows are read in
memory order and written flipped, so the flip is free.
"""
from __future__ import annotations

import sys

import numpy as np
from driftframe.framework.kernels import kernel

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


@kernel(nogil=True, boundscheck=False)
def _nv12(src, src2, dst, w, h, m0):               # pragma: no cover - compiled
    """GL rows ``m0 .. m0 + len(src) - 1`` of a ``w`` x ``h`` frame into their place in ``dst``.

    ``src``: (rows, w) uint32, one RGBA pixel each, GL order (bottom row
    first); ``src2``: the same memory as (rows, w / 2) uint64, two pixels
    each. ``m0`` and the row count are even: each GL row pair is one image
    row pair (2j, 2j + 1) and one chroma row j. ``dst``: the whole NV12
    frame, w h 3/2 uint8, top row first. Rows are read in memory order
    (the prefetcher's): the flip is in where they are written.
    """
    sr, sg, sb = _SHIFT_R, _SHIFT_G, _SHIFT_B       # compile-time constants
    uv0 = w * h
    for k in range(src.shape[0] // 2):
        b = src[2 * k]                             # GL row m0 + 2k: image row 2j + 1
        a = src[2 * k + 1]                         # GL row m0 + 2k + 1: image row 2j
        j = h // 2 - 1 - (m0 // 2 + k)
        ya = dst[2 * j * w:(2 * j + 1) * w]
        yb = dst[(2 * j + 1) * w:(2 * j + 2) * w]
        # one simple loop per row: each vectorises (whole pixels loaded as uint32, channels by shift)
        for i in range(w):
            p = np.int32(b[i])
            yb[i] = np.uint8((_YR * ((p >> sr) & 255) + _YG * ((p >> sg) & 255) + _YB * ((p >> sb) & 255)
                              + _Y0) >> _S)
        for i in range(w):
            p = np.int32(a[i])
            ya[i] = np.uint8((_YR * ((p >> sr) & 255) + _YG * ((p >> sg) & 255) + _YB * ((p >> sb) & 255)
                              + _Y0) >> _S)
        # chroma: a 2x2 block is one uint64 (two pixels) from each row: contiguous loads, no gathers
        a2 = src2[2 * k + 1]
        b2 = src2[2 * k]
        c = dst[uv0 + j * w:uv0 + (j + 1) * w]     # this block row's interleaved Cb Cr
        for i in range(w // 2):
            p = np.int64(a2[i])
            q = np.int64(b2[i])
            rs = ((p >> sr) & 255) + ((p >> (sr + 32)) & 255) + ((q >> sr) & 255) + ((q >> (sr + 32)) & 255)
            gs = ((p >> sg) & 255) + ((p >> (sg + 32)) & 255) + ((q >> sg) & 255) + ((q >> (sg + 32)) & 255)
            bs = ((p >> sb) & 255) + ((p >> (sb + 32)) & 255) + ((q >> sb) & 255) + ((q >> (sb + 32)) & 255)
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
    w, h = _even_size(width, height)
    src = np.frombuffer(rgba, np.uint8) if not isinstance(rgba, np.ndarray) else rgba.reshape(-1)
    if src.dtype != np.uint8 or src.size != w * h * 4:
        raise ValueError(f"expected {w * h * 4} bytes of RGBA for {w}x{h}, got {src.size} of {src.dtype}")
    if out is None:
        out = np.empty(nv12_size(w, h), np.uint8)
    flat = _checked_out(out, w, h)
    if src.ctypes.data % 8:                        # the uint64 view needs aligned memory (bytes objects are)
        src = src.copy()
    _nv12(*_read_only(src.view(np.uint32).reshape(h, w), src.view(np.uint64).reshape(h, w // 2)), flat, w, h, 0)
    return out


#: RGBA bytes a band of :class:`BandedNV12` holds by default: inside the L2 cache of current x86 cores
#: (512 KiB-2 MiB); 1280x720 in 8 bands. Band sizes measured: ``docs/design/recorder.md``, "NV12".
BAND_BYTES = 512 << 10


class BandedNV12:
    """Converts a frame to NV12 band by band, as it is read back in bands of rows (GL order, bottom first).

    ::

        conv = BandedNV12(width, height)
        for first_row, rows, band in conv.bands:          # band: a writable buffer of rows x width RGBA
            target.read_rows_into(band, first_row, rows)
            conv.convert(first_row, out)                   # out: an nv12_size() uint8 array

    Once every band is converted, ``out`` holds the same bytes as
    :func:`rgba_to_nv12` of the whole frame. A band of ``band_bytes`` (an
    even number of rows; :data:`BAND_BYTES` by default) is converted while
    it is still in the core's cache; a whole read-back 720p frame (3.7 MB)
    has left it by then.
    """

    def __init__(self, width: int, height: int, band_bytes: int | None = None):
        self.width, self.height = w, h = _even_size(width, height)
        rows = max(2, min(h, int(BAND_BYTES if band_bytes is None else band_bytes) // (w * 4)) & ~1)
        self._buf = np.empty(rows * w * 4, np.uint8)
        self.bands: list[tuple[int, int, np.ndarray]] = []
        self._views: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for y in range(0, h, rows):
            n = min(rows, h - y)
            band = self._buf[:n * w * 4]
            self.bands.append((y, n, band))
            self._views[y] = _read_only(band.view(np.uint32).reshape(n, w), band.view(np.uint64).reshape(n, w // 2))

    def convert(self, first_row: int, out: np.ndarray) -> None:
        """Convert the band that starts at ``first_row`` (read into its buffer) into its rows of ``out``."""
        try:
            u32, u64 = self._views[first_row]
        except (KeyError, TypeError):
            raise ValueError(f"no band starts at row {first_row!r}; they start at {list(self._views)}") from None
        _nv12(u32, u64, _checked_out(out, self.width, self.height), self.width, self.height, first_row)


def _read_only(*views: np.ndarray) -> tuple:
    """``views`` marked read-only (their memory stays writable through its other views): the kernel only
    reads them, and numba types a read-only array apart from a writable one, so every caller (a frame
    given as bytes is read-only; a band buffer or an array is not) hands it the one type, one compile."""
    for v in views:
        v.flags.writeable = False
    return views


def _even_size(width, height) -> tuple[int, int]:
    w, h = int(width), int(height)
    if w <= 0 or h <= 0 or w % 2 or h % 2:
        raise ValueError(f"NV12 needs an even width and height, got {width}x{height}")
    return w, h


def _checked_out(out: np.ndarray, w: int, h: int) -> np.ndarray:
    """``out`` as the flat NV12 array of a ``w`` x ``h`` frame; a clear error if it cannot be one."""
    if not isinstance(out, np.ndarray) or out.dtype != np.uint8 or out.size != nv12_size(w, h) \
            or not out.flags.c_contiguous:
        raise ValueError(f"out must be a contiguous uint8 array of {nv12_size(w, h)} bytes, "
                         f"got {getattr(out, 'size', out)!r} of {getattr(out, 'dtype', type(out).__name__)}")
    return out.reshape(-1)
