"""Where a recording's frames go: H.264 MP4 (x264 through PyAV), a streamed GIF, or numbered PNGs.

Each sink writes to a temporary path (:mod:`framework.record_files`) and is
then finished (a valid file with the frames so far) or aborted (deleted).
``write`` runs on the writer thread (:mod:`framework.record_writer`). Why
the defaults are what they are, with the figures: ``docs/design/recorder.md``.
"""
from __future__ import annotations

import functools
import io
import math
import shutil
from fractions import Fraction
from pathlib import Path

import numpy as np

from driftframe.framework.output import no_space
from driftframe.framework.record_files import RecordingError

_PNG_NAME = "frame_{:06d}.png"
X264_PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower", "veryslow")

#: The default x264 preset: with :data:`X264_TUNING` at crf 26, the cheapest encoder CPU that keeps the
#: demos' quality, for larger files (docs/design/recorder.md, "x264 settings").
X264_PRESET = "ultrafast"
#: x264 threads, pinned: the encoded bytes depend on it, so it must not follow the machine's cores. One:
#: x264 then runs on the recorder's writer thread beside the render, and at ultrafast one thread keeps up.
X264_THREADS = 1
#: Per-preset x264 settings beyond the preset. ultrafast turns off CABAC and the deblocking filter; both
#: are turned back on (``deblock=0,0``: on, at offsets 0): fewer bits and a better picture for little CPU
#: (docs/design/recorder.md). Against streaks on black (issue 25): a smaller quantiser deadzone (6, as
#: ``--tune grain``; ultrafast has no trellis, so the deadzone decides which small coefficients survive)
#: keeps the faint corrections dark areas need, and a keyframe every 60 frames (1 s at 60 fps; x264's
#: default is 250) clears the error P-frames pile up there. 0.3 as many streaks, for ~1 % of a
#: recording's CPU and ~30 % more bytes (docs/bench/dark_video.md).
X264_TUNING = {"ultrafast": {"x264-params": "cabac=1:deblock=0,0:deadzone-inter=6:deadzone-intra=6:keyint=60"}}
#: Default crf per preset (others: :data:`X264_DEFAULT_CRF`): what gives ultrafast the quality of veryfast at 20.
X264_CRF = {"ultrafast": 26}
X264_DEFAULT_CRF = 20
#: What the video says its numbers mean (x264's VUI and the MP4's colour atom).
_BT709 = {"colorspace": "bt709", "color_primaries": "bt709", "color_trc": "bt709", "color_range": "tv"}


class _Sink:
    """Receives raw frames in ``pixel_format`` (RGBA, bottom row first: GL order)."""

    pixel_format = "rgba"

    def __init__(self, tmp: Path, size: tuple[int, int], fps: Fraction):
        self.tmp = tmp
        self.size = size
        self.out_size = size
        self.fps = fps
        self.count = 0

    def write(self, raw) -> None:
        raise NotImplementedError

    def write_audio(self, samples) -> None:
        """A block of mono float32 sound samples (only a sink opened with a sound track takes them)."""
        raise NotImplementedError(f"{type(self).__name__} has no sound track")

    def finish(self) -> None:
        """Complete the temporary output (a valid file with the frames written so far)."""

    def abort(self) -> None:
        """Stop and delete the temporary output."""
        if self.tmp.is_dir():
            shutil.rmtree(self.tmp, ignore_errors=True)
        else:
            self.tmp.unlink(missing_ok=True)


class _H264Sink(_Sink):
    """H.264 MP4, encoded in this process by FFmpeg's libraries through PyAV (its wheels bundle libx264).

    ``write`` runs on the recorder's writer thread. PyAV encodes and muxes
    without the GIL, so x264 works while the caller steps and draws, and a
    frame reaches x264 without a copy into a second process.
    """

    def __init__(self, tmp, size, fps, *, crf: int, preset: str, pixel_format: str = "rgba", audio: bool = False):
        super().__init__(tmp, size, fps)
        import av
        from av.video.reformatter import VideoReformatter

        self._av = av
        self.pixel_format = pixel_format
        w, h = size
        # NV12 frames were converted (and flipped) already: x264 takes them as they are, no scaler at all.
        # RGBA rows come bottom-up (GL order): flipped, then converted by FFmpeg's scaler with the same
        # matrix (BT.709, limited range) as framework.yuv and the GPU's.
        self._shape = (h * 3 // 2, w) if pixel_format == "nv12" else (h, w, 4)
        self._to_yuv = None if pixel_format == "nv12" else functools.partial(
            VideoReformatter().reformat, format="yuv420p", dst_colorspace="ITU709",  # type: ignore[arg-type]
            dst_color_range="MPEG")               # (by name: PyAV 14 takes no enum here, whatever its stubs say)
        options = {"preset": preset, "crf": str(crf), **X264_TUNING.get(preset, {}),
                   "flags": "+bitexact",                # no version strings that could vary
                   **_BT709}                            # say what the numbers mean, so players do not guess
        try:
            self._out = av.open(str(tmp), "w", format="mp4", options={"fflags": "+bitexact"})
            try:
                stream = self._out.add_stream("libx264", rate=fps, options=options)
                stream.width, stream.height = w, h
                stream.pix_fmt = "nv12" if pixel_format == "nv12" else "yuv420p"
                stream.thread_count = X264_THREADS      # the bitstream depends on the thread count
                self._sound = _SoundTrack(av, self._out) if audio else None
            except BaseException:
                self._out.close()
                raise
        except av.FFmpegError as e:
            raise self._failed("could not start", e) from None
        self._stream = stream

    @staticmethod
    def _failed(what: str, e: BaseException) -> BaseException:
        if no_space(e):
            return e                                    # record() names the output and what was kept
        return RecordingError(f"the H.264 encoder {what}: {e}")

    def _mux(self, frame) -> None:
        try:
            for packet in self._stream.encode(frame):
                self._out.mux(packet)
        except self._av.FFmpegError as e:
            raise self._failed("failed while receiving frames" if frame is not None else
                               "failed to finish the video", e) from None

    def write(self, raw) -> None:
        pixels = np.frombuffer(raw, np.uint8).reshape(self._shape)
        if self._to_yuv is None:
            frame = self._av.VideoFrame.from_numpy_buffer(pixels, format="nv12")
        else:
            rgba = self._av.VideoFrame.from_ndarray(np.ascontiguousarray(pixels[::-1]), format="rgba")
            frame = self._to_yuv(rgba)
        frame.pts = self.count                          # in 1/fps: the codec's time base
        self._mux(frame)
        self.count += 1

    def write_audio(self, samples) -> None:
        if self._sound is None:
            super().write_audio(samples)
        try:
            self._sound.write(samples)
        except self._av.FFmpegError as e:
            raise self._failed("(AAC) failed while receiving sound", e) from None

    def finish(self) -> None:
        self._mux(None)                                 # x264's last frames
        try:
            if self._sound is not None:
                self._sound.finish()
            self._out.close()                           # the index (moov) goes at the end
        except self._av.FFmpegError as e:
            raise self._failed("failed to finish the video", e) from None

    def abort(self) -> None:
        try:
            self._out.close()
        except Exception:   # noqa: BLE001 - a full disk fails the close too: delete anyway
            pass
        super().abort()



class _SoundTrack:
    """An MP4's AAC-LC sound track (FFmpeg's own AAC encoder), mono at :data:`framework.audio.RATE` Hz.

    Blocks of any length are cut into the encoder's frames (1,024 samples), each stamped with its
    first sample's index, so the packets depend only on the samples: the same bytes every run.
    The last frame may be short (AAC allows it): the track ends with the last sample given.
    """

    BITRATE = 96_000

    def __init__(self, av, out):
        from driftframe.framework.audio import RATE

        self._av = av
        self._out = out
        self.stream = out.add_stream("aac", rate=RATE)
        self.stream.layout = "mono"
        self.stream.bit_rate = self.BITRATE
        self.stream.codec_context.flags |= 1 << 23      # AV_CODEC_FLAG_BITEXACT
        self._held = np.zeros(0, np.float32)
        self._pts = 0
        #: Samples given so far.
        self.samples = 0

    def _encode(self, block) -> None:
        frame = self._av.AudioFrame.from_ndarray(np.ascontiguousarray(block, np.float32)[None, :],
                                                 format="fltp", layout="mono")
        frame.sample_rate = self.stream.rate
        frame.pts = self._pts
        self._pts += block.shape[0]
        for packet in self.stream.encode(frame):
            self._out.mux(packet)

    def write(self, samples) -> None:
        samples = np.asarray(samples, np.float32).ravel()
        self.samples += len(samples)
        held = np.concatenate([self._held, samples]) if len(self._held) else samples
        size = self.stream.codec_context.frame_size or 1024
        whole = len(held) // size * size
        for a in range(0, whole, size):
            self._encode(held[a:a + size])
        self._held = held[whole:].copy()

    def finish(self) -> None:
        if len(self._held):
            self._encode(self._held)
            self._held = np.zeros(0, np.float32)
        for packet in self.stream.encode(None):
            self._out.mux(packet)


# GIF blocks (GIF89a spec): '!' extension, ',' image descriptor, ';' trailer.
def _gif_image_block(data: bytes) -> bytes:
    """From a one-frame GIF: image descriptor with its colour table as a *local* table, and the LZW data."""
    if data[:3] != b"GIF":
        raise ValueError("not a GIF")
    packed = data[10]
    pos = 13
    table, bits = b"", 0
    if packed & 0x80:
        bits = packed & 7
        n = 3 << (bits + 1)
        table, pos = data[pos:pos + n], pos + n
    while True:
        kind = data[pos]
        if kind == 0x21:                                # an extension: label, then sub-blocks until 0
            pos += 2
            while data[pos]:
                pos += data[pos] + 1
            pos += 1
        elif kind == 0x2C:
            desc, ipacked = data[pos + 1:pos + 9], data[pos + 9]
            pos += 10
            if ipacked & 0x80:
                bits = ipacked & 7
                n = 3 << (bits + 1)
                table, pos = data[pos:pos + n], pos + n
            start = pos
            pos += 1                                    # LZW minimum code size
            while data[pos]:
                pos += data[pos] + 1
            pos += 1
            # local colour table flag + its size; interlace off; the frame's own palette
            return b"," + desc + bytes([0x80 | bits]) + table + data[start:pos]
        else:
            raise ValueError(f"unexpected GIF block 0x{kind:02x}")


#: The longest delay one GIF frame holds: a 16-bit count of 1/100 s (655.35 s).
GIF_MAX_DELAY = 0xFFFF


class _GifSink(_Sink):
    """GIF at reduced size, streamed: each frame is quantised, encoded and written as it comes.

    Holds at most two encoded frames (``held``): the one on screen, whose
    delay is not known until the next distinct frame arrives, and the one
    before it, so a too-short last frame can still be merged into it.
    """

    def __init__(self, tmp, size, fps, *, scale: float):
        super().__init__(tmp, size, fps)
        w, h = size
        self.out_size = (max(1, round(w * scale)), max(1, round(h * scale)))
        self._fp = open(tmp, "wb")
        ow, oh = self.out_size
        # header without a global colour table (each frame carries its own), then loop forever
        self._fp.write(b"GIF89a" + ow.to_bytes(2, "little") + oh.to_bytes(2, "little") + b"\x00\x00\x00"
                       + b"\x21\xff\x0bNETSCAPE2.0\x03\x01\x00\x00\x00")
        self._end = 0                 # end time of the last frame received, 1/100 s
        self._shown: list | None = None   # [block, start cs]: the frame on screen, delay still open
        self._ready: list | None = None   # [block, delay cs]: closed, not yet written
        #: Encoded frames held in memory now, and the most at any time (bounded: 2).
        self.held = 0
        self.max_held = 0
        #: Delays written so far, 1/100 s.
        self.delays: list[int] = []

    def _end_cs(self, i: int) -> int:
        """End time of frame ``i`` (0-based) in whole 1/100 s, rounded half up: exact rational arithmetic."""
        return math.floor(Fraction(100 * (i + 1)) / self.fps + Fraction(1, 2))

    def _encode(self, raw) -> bytes:
        from PIL import Image

        im = Image.frombuffer("RGBA", self.size, raw, "raw", "RGBA", 0, -1).convert("RGB")  # -1: flip rows
        if im.size != self.out_size:
            w, h = self.size
            ow, oh = self.out_size
            if w % ow == 0 and h % oh == 0 and w // ow == h // oh:
                im = im.reduce(w // ow)                 # a whole factor: block means, cheaper than a resize
            else:
                im = im.resize(self.out_size, Image.Resampling.BOX)
        # fast octree: cheaper than median cut, and no worse a picture (docs/design/recorder.md, "GIF")
        im = im.quantize(256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
        buf = io.BytesIO()
        im.save(buf, format="GIF", optimize=False, interlace=False)
        return _gif_image_block(buf.getvalue())

    def _close(self, block: bytes, delay: int) -> None:
        if self._ready is not None:
            self._emit(*self._ready)
        self._ready = [block, delay]

    def _emit(self, block: bytes, delay: int) -> None:
        # graphics control extension: disposal 1 (keep), the delay in 1/100 s. The field is 16 bits: a
        # picture shown longer than 655.35 s is written as n equal copies (each over 327 s, none too short)
        n = -(-delay // GIF_MAX_DELAY)
        for k in range(n):
            part = delay * (k + 1) // n - delay * k // n
            self._fp.write(b"\x21\xf9\x04\x04" + part.to_bytes(2, "little") + b"\x00\x00" + block)
            self.delays.append(part)

    def _count_held(self) -> None:
        self.held = (self._shown is not None) + (self._ready is not None)
        self.max_held = max(self.max_held, self.held)

    def write(self, raw) -> None:
        block = self._encode(raw)
        start, self._end = self._end, self._end_cs(self.count)
        shown = self._shown
        if shown is None:
            self._shown = [block, start]
        elif block != shown[0] and start - shown[1] >= 2:
            self._close(shown[0], start - shown[1])
            self._shown = [block, start]
        # else: the same picture, or the one on screen would get under 2 cs: it stays on screen
        self.count += 1
        self._count_held()
        self._fp.flush()

    def finish(self) -> None:
        assert self._shown is not None                  # record() finishes only a sink with frames
        block, start = self._shown
        tail = self._end - start
        if tail < 2 and self._ready is not None:
            self._ready[1] += tail                      # too short to show: the frame before lasts longer
        else:
            self._close(block, max(tail, 1))
        self._emit(*self._ready)                        # type: ignore[misc]  # set by either branch
        self._shown = self._ready = None
        self._count_held()
        self._fp.write(b";")
        self._fp.close()

    def abort(self) -> None:
        try:
            self._fp.close()
        except OSError:
            pass                                        # a full disk fails the last flush too: delete anyway
        super().abort()


class _PngSink(_Sink):
    """Numbered PNG frames in a temporary directory."""

    def write(self, raw) -> None:
        from PIL import Image

        im = Image.frombuffer("RGBA", self.size, raw, "raw", "RGBA", 0, -1).convert("RGB")
        im.save(self.tmp / _PNG_NAME.format(self.count), format="PNG", compress_level=1)
        self.count += 1



def open_sink(fmt: str, tmp: Path, size: tuple[int, int], fps: Fraction, *, crf: int, preset: str, nv12: bool,
              gif_scale: float, audio: bool = False) -> _Sink:
    """The sink for ``fmt`` (``"mp4"``, ``"gif"``, ``"png"``) writing to ``tmp``; if it cannot start, ``tmp`` is
    removed and the error raised. ``nv12``: MP4 frames come converted (else RGBA, for FFmpeg's scaler).
    ``audio``: the MP4 gets a sound track (:class:`_SoundTrack`)."""
    try:
        if fmt == "mp4":
            return _H264Sink(tmp, size, fps, crf=crf, preset=preset, pixel_format="nv12" if nv12 else "rgba",
                             audio=audio)
        if fmt == "gif":
            return _GifSink(tmp, size, fps, scale=gif_scale)
        return _PngSink(tmp, size, fps)
    except BaseException:
        _Sink(tmp, size, fps).abort()
        raise
