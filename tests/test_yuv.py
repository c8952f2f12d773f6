"""framework.yuv: RGBA (GL order) to NV12, BT.709 limited range, in integers."""
from __future__ import annotations

import numpy as np
import pytest

from driftframe.framework.yuv import BandedNV12, nv12_size, rgba_to_nv12

KR, KB = 0.2126, 0.0722
KG = 1 - KR - KB


def reference(rgba_gl: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Y, Cb, Cr in floating point, straight from the BT.709 definitions (image order: top row first)."""
    img = rgba_gl[::-1, :, :3].astype(np.float64)             # GL rows run bottom up
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    y = 16 + 219 / 255 * (KR * r + KG * g + KB * b)
    h, w = r.shape
    m = img.reshape(h // 2, 2, w // 2, 2, 3).mean(axis=(1, 3))  # each chroma sample: a 2x2 block's mean
    ly = KR * m[..., 0] + KG * m[..., 1] + KB * m[..., 2]
    cb = 128 + 224 / 255 * (m[..., 2] - ly) / (2 * (1 - KB))
    cr = 128 + 224 / 255 * (m[..., 0] - ly) / (2 * (1 - KR))
    return y, cb, cr


def planes(nv12: np.ndarray, w: int, h: int):
    y = nv12[:w * h].reshape(h, w)
    uv = nv12[w * h:].reshape(h // 2, w // 2, 2)
    return y, uv[..., 0], uv[..., 1]


def test_matches_the_bt709_definition_to_the_rounding():
    rng = np.random.default_rng(3)
    w, h = 38, 22                                               # not a multiple of 4 or 8: no SIMD-width luck
    rgba = rng.integers(0, 256, (h, w, 4), dtype=np.uint8)
    got = planes(rgba_to_nv12(rgba.tobytes(), w, h), w, h)
    for name, g, exact in zip("Y Cb Cr".split(), got, reference(rgba)):
        err = g.astype(np.float64) - exact
        assert np.abs(err).max() <= 0.51, name                 # the exact value, rounded (fixed point: 0.006)
        assert (g == np.round(exact)).mean() > 0.98, name


def test_extremes_land_on_the_limited_range_ends():
    w, h = 4, 2
    for colour, expect in (((0, 0, 0), (16, 128, 128)), ((255, 255, 255), (235, 128, 128)),
                           ((0, 0, 255), (32, 240, 118)), ((255, 0, 0), (63, 102, 240))):
        rgba = np.zeros((h, w, 4), np.uint8)
        rgba[..., :3] = colour
        y, cb, cr = planes(rgba_to_nv12(rgba, w, h), w, h)
        assert (int(y[0, 0]), int(cb[0, 0]), int(cr[0, 0])) == expect, colour
        assert np.ptp(y) == 0 and np.ptp(cb) == 0 and np.ptp(cr) == 0


def test_rows_are_flipped_from_gl_order():
    w, h = 8, 6
    rgba = np.zeros((h, w, 4), np.uint8)
    rgba[-1, :, :3] = 255                                       # GL's last row is the image's top row
    y, cb, cr = planes(rgba_to_nv12(rgba, w, h), w, h)
    assert (y[0] == 235).all() and (y[1:] == 16).all()
    assert (cb == 128).all() and (cr == 128).all()              # grey: the half-white block is still grey


def test_alpha_is_ignored_and_out_is_reused():
    rng = np.random.default_rng(4)
    w, h = 16, 8
    a = rng.integers(0, 256, (h, w, 4), dtype=np.uint8)
    b = a.copy()
    b[..., 3] = 255 - b[..., 3]
    out = np.full(nv12_size(w, h), 7, np.uint8)
    assert rgba_to_nv12(a, w, h, out) is out
    np.testing.assert_array_equal(out, rgba_to_nv12(b, w, h))


def test_unaligned_input_gives_the_same_bytes():
    rng = np.random.default_rng(5)
    w, h = 10, 4
    raw = rng.integers(0, 256, w * h * 4 + 1, dtype=np.uint8)
    shifted = raw[1:]                                           # one byte off a 4-byte boundary
    assert shifted.ctypes.data % 4
    np.testing.assert_array_equal(rgba_to_nv12(shifted, w, h), rgba_to_nv12(shifted.copy(), w, h))


@pytest.mark.parametrize("w, h, msg", [(5, 4, "even width and height, got 5x4"),
                                       (4, 3, "even width and height, got 4x3"),
                                       (0, 2, "even width and height, got 0x2")])
def test_bad_sizes_are_named(w, h, msg):
    with pytest.raises(ValueError, match=msg):
        rgba_to_nv12(b"\0" * 64, w, h)


def test_wrong_lengths_are_named():
    with pytest.raises(ValueError, match="expected 128 bytes of RGBA for 8x4, got 127"):
        rgba_to_nv12(b"\0" * 127, 8, 4)
    with pytest.raises(ValueError, match="out must be a contiguous uint8 array of 48 bytes, got 47"):
        rgba_to_nv12(b"\0" * 128, 8, 4, out=np.empty(47, np.uint8))


@pytest.mark.parametrize("band_rows", [2, 4, 6, 22])
def test_bands_give_the_bytes_of_the_whole_frame(band_rows):
    rng = np.random.default_rng(6)
    w, h = 38, 22                                               # 22 rows in bands of 4 or 6: a short last band
    rgba = rng.integers(0, 256, (h, w, 4), dtype=np.uint8)
    conv = BandedNV12(w, h, band_bytes=band_rows * w * 4)
    assert [(y, n) for y, n, _ in conv.bands] == [(y, min(band_rows, h - y)) for y in range(0, h, band_rows)]
    out = np.full(nv12_size(w, h), 7, np.uint8)
    for y, n, band in reversed(conv.bands):                     # any order: each band has its own rows
        band[:] = rgba[y:y + n].reshape(-1)
        conv.convert(y, out)
    np.testing.assert_array_equal(out, rgba_to_nv12(rgba, w, h))


def test_banded_sizes_and_outputs_are_checked():
    with pytest.raises(ValueError, match="even width and height, got 7x4"):
        BandedNV12(7, 4)
    conv = BandedNV12(8, 4, band_bytes=1)                       # at least two rows a band
    assert [(y, n) for y, n, _ in conv.bands] == [(0, 2), (2, 2)]
    with pytest.raises(ValueError, match="out must be a contiguous uint8 array of 48 bytes, got 47"):
        conv.convert(0, np.empty(47, np.uint8))
    with pytest.raises(ValueError, match=r"no band starts at row 1; they start at \[0, 2\]"):
        conv.convert(1, np.empty(48, np.uint8))
