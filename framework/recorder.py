"""Off-screen recording: one rendered frame per simulated frame, to MP4, GIF or PNG frames.

::

    from driftframe.framework.recorder import record
    result = record(world, "out/asteroids.mp4", frames=600)     # 10 s at dt = 1/60
    result.frames, result.interrupted, result.path

The world must have rendering attached (:func:`systems.render.attach`). Each
frame: ``before_step(world, step)`` (scripted input) and ``world.step()``,
``steps_per_frame`` times; then ``world.render()`` (every render- and
record-stage system: models, skybox, a HUD...) and the frame is read back.
Nothing reads the wall clock, so the same scene and seed give the same frames.

Formats, from the path (or ``format=``):

* ``.mp4`` — H.264 (libx264, 4:2:0), encoded in this process by FFmpeg's
  libraries through PyAV (``av``, whose wheels bundle x264): preset
  ``ultrafast`` with CABAC and the deblocking filter back on, crf 26 by
  default (:data:`X264_PRESET`, :data:`X264_TUNING`, :data:`X264_CRF`). On
  the demos that is at least the quality (luma PSNR) of ``veryfast`` at crf
  20 for 0.5-0.7 of its encoder CPU and files 1.7-3.3 times as large
  (``benchmarks/record_throughput.py``): on a 2-core machine shared with a
  software renderer, encoder CPU is recording speed. Frames are converted to
  NV12 (BT.709, limited range; the video is tagged so) by
  :mod:`framework.yuv` on the calling thread as they are read back, in
  bands of rows that stay in the core's cache, and handed to a writer
  thread, which encodes them (x264 runs without the GIL) while the caller
  steps and draws the next. ``yuv="gpu"`` converts in a shader instead,
  ``yuv="ffmpeg"`` hands RGBA to FFmpeg's scaler; both measured slower.
  Flags pin everything that could vary (thread count, ``+bitexact``, no
  metadata): the same frames give the same bytes on every run. Width and
  height must be even.
* ``.gif`` — scaled by ``gif_scale`` (default 1/2: GIF is for previews), 256
  colours per frame (Pillow's fast octree, no dithering), looping, written
  frame by frame as they come (memory stays at a frame or two, however long
  the recording). GIF delays are whole 1/100 s, so each frame's end time is
  rounded to 1/100 s and its delay is the difference: the delays add up to
  the exact length (a 60 fps GIF gets 2, 1, 2, 2, 1, 2... cs). Players slow
  down delays under 2/100 s, so a frame that would get 1 cs is merged into
  the frame before it (above 50 fps some frames are dropped; the length
  stays exact). Identical consecutive frames are merged too.
* a directory — numbered PNGs ``frame_000000.png``, ``frame_000001.png``...
  A path names a directory when it ends in ``/`` or is an existing
  directory; a path without a suffix is refused (``-o clip`` is more often a
  forgotten ``.mp4`` than a wish for a folder of PNGs).

Motion blur (``motion_blur=N``, with ``interpolate=`` an object that poses
the scene between fixed steps, e.g.
:class:`driftframe.systems.motion_blur.SubframePoses`): each frame is the
average of N renders at evenly spaced times across the frame's interval, the
last at the frame's own time. A wheel spinning at the frame rate is then a
blur, not a still wheel (the wagon-wheel effect). The simulation is not
touched: the poses are restored after each frame, so the state and every
later frame are the same as without blur. Integer averaging: deterministic.

Safety: the output goes to a temporary name beside the target
(``.NAME.<pid>.<random>.part...``) and is moved into place only when
complete (:mod:`framework.output`, shared by everything that writes). An existing output is refused unless ``overwrite=True``.
Ctrl-C, SIGTERM and SIGHUP stop rendering at the end of the frame being made
(a second one at once), finish a valid, shorter file and report
``interrupted=True`` with the signal's number in ``signal`` (and say so on
stderr); any other failure removes everything it wrote and raises
(:class:`RecordingError` for a failed write: a full disk, the encoder failing).
A process killed outright (SIGKILL) cannot clean up: the next recording to
the same output removes temporary files whose process is gone. An unknown
format, an unwritable path or bad arguments raise before anything is
rendered or stepped.
"""
from __future__ import annotations

import functools
import io
import itertools
import math
import os
import queue
import shutil
import signal
import sys
import threading
import time
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np

from driftframe.framework import warp as time_warp
from driftframe.framework.output import (OutputExistsError, check_name, check_output_file, new_part, no_space, publish,
                                         remove_stale_parts)  # noqa: F401 - remove_stale_parts: public here too
from driftframe.framework.gl import current

FORMATS = ("mp4", "gif", "png")
_SUFFIXES = {".mp4": "mp4", ".gif": "gif"}
_PNG_NAME = "frame_{:06d}.png"
X264_PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower", "veryslow")
#: The default x264 preset. Measured on the demos at 1280x720 (``benchmarks/record_throughput.py``):
#: ultrafast (with :data:`X264_TUNING`) at crf 26 matched or beat veryfast + subme 1 at crf 20 (the
#: previous default) in luma PSNR on every demo for 0.5-0.7 of its encoder CPU; the price is files 1.7-3.3
#: times as large (asteroids: 3.6 against 1.4 KiB a frame, about 1.8 Mbit/s at 720p60).
X264_PRESET = "ultrafast"
#: x264 threads, pinned: the encoded bytes depend on it, so it must not follow the machine's cores. One:
#: x264 then runs on the recorder's writer thread, beside the render, and at ultrafast one thread keeps
#: up; on 2 cores two threads only competed with the renderer (1280x720: 0.67 of bare with 2, 0.73 with 1,
#: measured while x264 ran in an ffmpeg process).
X264_THREADS = 1
#: Per-preset x264 settings beyond the preset. ultrafast turns off CABAC and the deblocking filter; at
#: these bit rates both cost little CPU (3.0 against 2.9 ms a 720p frame) and are worth having: CABAC
#: saves 13 % of the bits at the same quality, the deblocking filter another 2 % and 0.7 dB.
X264_TUNING = {"ultrafast": {"x264-params": "cabac=1:deblock=0,0"}}
#: Default crf per preset (others: :data:`X264_DEFAULT_CRF`): what gives ultrafast the quality of veryfast at 20.
X264_CRF = {"ultrafast": 26}
X264_DEFAULT_CRF = 20
#: How MP4 frames reach x264 (``record(yuv=...)``): converted on the CPU by :mod:`framework.yuv` (the
#: default), in a shader, or by FFmpeg's scaler (libswscale) from RGBA.
YUV_PATHS = ("cpu", "gpu", "ffmpeg")
#: Signals that stop a recording the way Ctrl-C does (SIGINT arrives as KeyboardInterrupt).
STOP_SIGNALS = tuple(s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)) if s)
#: Most sub-frames averaged into one frame.
MAX_MOTION_BLUR = 64


class RecordingError(RuntimeError):
    """Writing the output failed (a full disk, the encoder failing); nothing half-written was kept."""


class Interrupted(KeyboardInterrupt):
    """A stop signal (SIGTERM, SIGHUP) during a recording: handled like Ctrl-C."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


@dataclass(frozen=True)
class RecordResult:
    """What :func:`record` wrote."""

    #: The file or directory written (None if an interrupt came before the first frame).
    path: Path | None
    #: "mp4", "gif" or "png".
    format: str
    #: Frames written (fewer than ``requested`` after an interrupt).
    frames: int
    requested: int
    #: Wall-clock seconds the recording took (for information only).
    seconds: float
    #: True if Ctrl-C or a stop signal ended it early.
    interrupted: bool
    #: (width, height) of the frames written, pixels (a GIF's reduced size).
    size: tuple[int, int]
    #: The signal that stopped it (signal.SIGINT for Ctrl-C), or None.
    signal: int | None = None

    @property
    def frames_per_second(self) -> float:
        """Frames written per wall-clock second."""
        return self.frames / self.seconds if self.seconds > 0 else math.inf


def output_format(path) -> str:
    """``"mp4"``, ``"gif"`` or ``"png"`` (a directory of frames) for ``path``; a clear error otherwise."""
    text = os.fspath(path)
    p = Path(text)
    if text.endswith(("/", os.sep)) or p.is_dir():
        return "png"
    if p.suffix == "":
        raise ValueError(f"output {text!r} has no suffix: give NAME.mp4 or NAME.gif, or {text + '/'!r} "
                         "(a trailing slash) for a directory of numbered PNG frames")
    fmt = _SUFFIXES.get(p.suffix.lower())
    if fmt is None:
        hint = " (a .png path is a single image: give a directory for numbered PNG frames)" \
            if p.suffix.lower() == ".png" else ""
        raise ValueError(f"unknown output format {p.suffix!r} for {text!r}{hint}; "
                         "use .mp4, .gif, or a directory for numbered PNG frames")
    return fmt


_no_space = no_space


# -- writers: each writes to a temporary path, then is finished or aborted ---------------------
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
    without the GIL, so x264 works while the caller steps and draws. In this
    process a frame reaches x264 without a copy through a pipe into a second
    process, and without that process's reader and hand-offs between its
    threads: against the ffmpeg command fed on a pipe that this sink
    replaced (the same x264, the same settings), 0.4-0.8 ms less CPU a frame
    in all, and 0.85-0.89 of the bare loop's frame rate against 0.83-0.85
    (asteroids at 1280x720 on 2 cores; three runs of 5-11 interleaved
    rounds; paired, 1.04 times the frame rate over 11 rounds).
    """

    def __init__(self, tmp, size, fps, *, crf: int, preset: str, pixel_format: str = "rgba"):
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
            VideoReformatter().reformat, format="yuv420p", dst_colorspace="ITU709", dst_color_range="MPEG")
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
            except BaseException:
                self._out.close()
                raise
        except av.FFmpegError as e:
            raise self._failed("could not start", e) from None
        self._stream = stream

    @staticmethod
    def _failed(what: str, e: BaseException) -> BaseException:
        if _no_space(e):
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

    def finish(self) -> None:
        self._mux(None)                                 # x264's last frames
        try:
            self._out.close()                           # the index (moov) goes at the end
        except self._av.FFmpegError as e:
            raise self._failed("failed to finish the video", e) from None

    def abort(self) -> None:
        try:
            self._out.close()
        except Exception:   # noqa: BLE001 - a full disk fails the close too: delete anyway
            pass
        super().abort()


#: What the video says its numbers mean (x264's VUI and the MP4's colour atom).
_BT709 = {"colorspace": "bt709", "color_primaries": "bt709", "color_trc": "bt709", "color_range": "tv"}


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
        self._shown = None            # [block, start cs]: the frame on screen, delay still open
        self._ready = None            # [block, delay cs]: closed, not yet written
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
                im = im.reduce(w // ow)                 # a whole factor: block means, 4x faster than resize
            else:
                im = im.resize(self.out_size, Image.Resampling.BOX)
        # fast octree: 8x faster than median cut here, and its worst pixel error was smaller (15 vs 54 of 255)
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
        block, start = self._shown
        tail = self._end - start
        if tail < 2 and self._ready is not None:
            self._ready[1] += tail                      # too short to show: the frame before lasts longer
        else:
            self._close(block, max(tail, 1))
        self._emit(*self._ready)
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


class _Writer:
    """Feeds a sink from a bounded queue on a background thread, so encoding overlaps rendering.

    GL stays on the caller's thread (a context works only there); the thread
    only sees bytes. An error in the thread is re-raised in the caller at the
    next ``put`` or at ``close``.

    When the thread runs matters more than what it costs. moderngl's
    read-back holds the GIL while llvmpipe rasterises (both cores), so this
    thread hands frames on only while the caller steps and draws (one core),
    and x264 encodes then too. Measured on 2 cores, asteroids at 1280x720 (A/B
    runs against bare in the same process, 5-15 rounds each). Since x264
    runs in this thread (PyAV encodes without the GIL) instead of in an
    ffmpeg process fed on a pipe, a frame is no longer copied through the
    pipe nor read by a second process: 0.4-0.8 ms less CPU a frame
    (:class:`_H264Sink`). Measured while x264 ran in ffmpeg's process,
    and kept as lessons: releasing the GIL for
    that wait (glFinish through ctypes) or a shorter switch interval let the
    writes land during rasterisation and slowed it (0.67-0.71 of bare
    against 0.79-0.82). Converting on this thread (with a hand-off that
    waits for it to start), vmsplice instead of write, the conversion of the
    previous frame overlapping the flushed render, a writer that never takes
    the GIL (one numba loop, woken through a pipe, converting from its own
    read-back buffers and writing to ffmpeg itself), pinning ffmpeg to one
    core, x264 without CABAC, and ``LP_NUM_THREADS`` 3 or 4 were all within
    the noise or worse: the bare loop keeps 1.35 cores busy and the
    recording added about 3.3 ms of CPU a frame (x264 and ffmpeg 2.6,
    conversion 0.5, the pipe 0.2), about what the idle core can take.
    Feeding the pipe from the caller's thread instead (non-blocking, topped
    up between step and render) was slower too, 0.78 against 0.82 of bare
    in the same 11 rounds: a 1.4 MB frame into a 1 MiB pipe costs the
    caller 0.4-0.8 ms (a 1 MiB write alone 0.37 ms), more than the thread's
    hand-offs.
    """

    #: Frames queued for the thread at most (plus the one it is writing).
    DEPTH = 3

    def __init__(self, sink: _Sink):
        self.sink = sink
        self._q: queue.Queue = queue.Queue(maxsize=self.DEPTH)
        self._error: BaseException | None = None
        self._closed = False
        self._thread = threading.Thread(target=self._run, name="driftframe-recorder", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            item = self._q.get()
            if item is None:
                return
            if self._error is None:
                try:
                    self.sink.write(item)
                except BaseException as e:   # noqa: BLE001 - handed to the caller
                    self._error = e

    def put(self, raw) -> None:
        if self._error is not None:
            raise self._error
        self._q.put(raw)

    def close(self) -> None:
        """Wait until every queued frame is written; re-raise the thread's error if any. Idempotent."""
        if not self._closed:
            self._closed = True
            self._q.put(None)
            self._thread.join()
        if self._error is not None:
            raise self._error


# -- checks before anything is rendered ------------------------------------------------------------
def _positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an int >= 1, got {value!r}")
    return int(value)


def check_output(path, *, overwrite: bool = False, format: str | None = None, probe: bool = True) -> None:
    """Raise what :func:`record` would raise for ``path`` before it renders anything; leave nothing.

    An existing output without ``overwrite``, a missing folder, a directory
    where a file should be (and the reverse), a read-only file to replace, a
    name too long, and (``probe``) a folder where no file can be made (a part
    file is made there and removed: :func:`framework.output.check_output_file`).
    A caller with costly work before :func:`record` (building a world, a
    first run's compiling) checks first; :func:`record` checks again.
    """
    fmt = format or output_format(path)
    path = Path(os.fspath(path))
    parent = path.parent
    check_name(path)                                  # first: a name too long fails every later stat too
    if not parent.exists():
        raise FileNotFoundError(f"cannot write {str(path)!r}: directory {str(parent)!r} does not exist")
    if not parent.is_dir():
        raise NotADirectoryError(f"cannot write {str(path)!r}: {str(parent)!r} is not a directory")
    if fmt == "png":
        if path.exists() and not path.is_dir():
            raise FileExistsError(f"cannot write PNG frames to {str(path)!r}: it exists and is not a directory")
        if path.is_dir():
            names = os.listdir(path)
            foreign = [n for n in names if not (n.startswith("frame_") and n.endswith(".png"))]
            if foreign:
                raise FileExistsError(f"cannot write PNG frames to {str(path)!r}: it holds other files "
                                      f"({', '.join(sorted(foreign)[:5])}); give an empty or new directory")
            if names and not overwrite:
                raise OutputExistsError(f"{str(path)!r} holds PNG frames already; pass overwrite=True "
                                        "(--overwrite) to replace them")
    elif path.is_dir():
        raise IsADirectoryError(f"cannot write {str(path)!r}: it is a directory")
    elif path.exists() or path.is_symlink():
        if not overwrite:
            raise OutputExistsError(f"{str(path)!r} exists; pass overwrite=True (--overwrite) to replace it")
        if not path.stat().st_mode & 0o222:
            raise PermissionError(f"cannot replace {str(path)!r}: it is read-only (make it writable or "
                                  "delete it first)")
    # the rest (a name too long, a folder where nothing can be made) is the shared check's
    check_output_file(path, overwrite=True, folder=fmt == "png", probe=probe)


def _prepare_path(path: Path, fmt: str, overwrite: bool) -> Path:
    """Check the target and create the temporary output beside it (proving it is writable)."""
    check_output(path, overwrite=overwrite, format=fmt, probe=False)
    return new_part(path, folder=fmt == "png")


def _move_into_place(tmp: Path, path: Path, fmt: str, overwrite: bool) -> None:
    publish(tmp, path, overwrite=overwrite or fmt == "png", folder=fmt == "png")


def raise_interrupted(signum, frame):
    """A signal handler: SIGTERM and SIGHUP raise :class:`Interrupted`, as Python's own does for SIGINT.

    The command line holds it from its start, so a signal before or between
    the parts that stop gracefully (:class:`StopSignals`, which takes over
    from it) still ends in one line and exit status 128 + n, not a silent
    death; :class:`StopSignals` treats it as the default.
    """
    raise Interrupted(signum)


class StopSignals:
    """While active (main thread only), Ctrl-C, SIGTERM and SIGHUP ask the recording to stop.

    The first one only sets :attr:`requested`: the loop stops at the end of
    the frame it is in, so no system, writer or GL call is cut off halfway
    (an exception raised at any bytecode could leave the world half-stepped).
    A second one raises :class:`Interrupted` at once, for a frame that never
    ends. Signals whose handler is not the default (ignored under ``nohup``,
    or the application's own) are left alone. The command line also holds
    one while a first run compiles its kernels (``driftframe/cli.py``).
    """

    def __init__(self, enabled: bool):
        self._old: dict = {}
        self.requested: int | None = None
        self.finishing = False
        self.enabled = enabled and threading.current_thread() is threading.main_thread()

    def _handle(self, signum, frame):
        if self.requested is not None and not self.finishing:
            raise Interrupted(signum)
        self.requested = self.requested or signum

    def finish(self) -> None:
        """From now on every signal only sets :attr:`requested`: the outputs are being written, which is
        short and bounded, and a second Ctrl-C must not cut the file it is meant to keep."""
        self.finishing = True

    def __enter__(self):
        if self.enabled:
            defaults = {signal.SIGINT: signal.default_int_handler}
            for s in (signal.SIGINT, *STOP_SIGNALS):
                # only where nobody chose otherwise: under nohup, SIGHUP stays ignored
                if signal.getsignal(s) in (defaults.get(s, signal.SIG_DFL), raise_interrupted):
                    self._old[s] = signal.signal(s, self._handle)
        return self

    def __exit__(self, *exc):
        for s, old in self._old.items():
            signal.signal(s, old)
        self._old.clear()


def _signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def record(world, path, *, frames: int, fps: float | None = None, steps_per_frame: int = 1,
           progress: bool = True, before_step=None, gif_scale: float = 0.5, crf: int | None = None,
           preset: str = X264_PRESET, overwrite: bool = False, format: str | None = None,
           motion_blur: int = 1, interpolate=None, handle_signals: bool = True,
           yuv: str = "cpu") -> RecordResult:
    """Step, render and write ``frames`` frames of ``world`` to ``path`` (.mp4, .gif or a directory).

    ``fps``: playback rate (default ``1 / (dt * steps_per_frame)``: real
    time). ``steps_per_frame``: fixed steps between frames, times the world's time warp
    (:mod:`framework.warp`), read frame by frame.
    ``before_step(world, step_index)``: called before every step (scripted
    input). ``progress``: a tqdm bar on stderr. ``gif_scale``: GIF size
    factor. ``crf``/``preset``: x264 quality (0..51, lower is better; None:
    the preset's own default, :data:`X264_CRF`) and speed (default
    :data:`X264_PRESET`; ``preset="veryfast", crf=20`` gives files a third
    to a half the size for 1.9-2.6 times the encoder CPU; the trade for each
    demo is in ``benchmarks/record_throughput.py``). ``overwrite``: replace an
    existing output (refused otherwise). ``format``: ``"mp4"``, ``"gif"`` or
    ``"png"`` instead of guessing from the path (a ``Path`` cannot end in
    ``/``). ``motion_blur``: sub-frames averaged per frame (1: none), posed by
    ``interpolate`` (see the module docstring). ``handle_signals``: turn
    SIGTERM and SIGHUP into an interrupt while recording (main thread only).
    ``yuv``: for MP4, where frames become NV12: ``"cpu"`` (default,
    :mod:`framework.yuv` on this thread), ``"gpu"`` (a shader; an off-screen
    target whose width is a multiple of 4) or ``"ffmpeg"`` (RGBA handed to
    FFmpeg's scaler); the pictures agree to within rounding, the bytes differ.
    Returns a :class:`RecordResult`. See the module docstring for what
    happens on Ctrl-C and on failure.
    """
    frames = _positive_int("frames", frames)
    steps_per_frame = _positive_int("steps_per_frame", steps_per_frame)
    motion_blur = _positive_int("motion_blur", motion_blur)
    if motion_blur > MAX_MOTION_BLUR:
        raise ValueError(f"motion_blur must be at most {MAX_MOTION_BLUR} sub-frames, got {motion_blur}")
    if motion_blur > 1:
        for method in ("start", "after_step", "pose", "restore"):
            if not callable(getattr(interpolate, method, None)):
                raise TypeError("motion_blur needs interpolate=, an object with start/after_step/pose/restore "
                                f"(e.g. driftframe.systems.motion_blur.SubframePoses()), got {interpolate!r}")
    if fps is None:
        fps = 1.0 / (world.dt * steps_per_frame)
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.integer, np.floating)) \
            or not math.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be a finite number > 0, got {fps!r}")
    if before_step is not None and not callable(before_step):
        raise TypeError(f"before_step must be a function (world, step_index) or None, got {before_step!r}")
    if not 0 < gif_scale <= 1:
        raise ValueError(f"gif_scale must be in (0, 1], got {gif_scale!r}")
    if preset not in X264_PRESETS:
        raise ValueError(f"preset must be one of {', '.join(X264_PRESETS)}, got {preset!r}")
    if crf is None:
        crf = X264_CRF.get(preset, X264_DEFAULT_CRF)
    if isinstance(crf, bool) or not isinstance(crf, (int, np.integer)) or not 0 <= crf <= 51:
        raise ValueError(f"crf must be an int in [0, 51], got {crf!r}")
    if yuv not in YUV_PATHS:
        raise ValueError(f"yuv must be one of {', '.join(map(repr, YUV_PATHS))}, got {yuv!r}")
    target = world.resources.get("render_target")
    if target is None:
        raise LookupError("record: the world has no rendering; call driftframe.attach_rendering(world) first")
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path must be a str or os.PathLike, got {path!r}")
    if format is None:
        fmt = output_format(path)
    elif format in FORMATS:
        fmt = format
    else:
        raise ValueError(f"format must be one of {', '.join(FORMATS)} or None, got {format!r}")
    path = Path(os.fspath(path))
    size = tuple(target.size)
    if fmt == "mp4" and (size[0] % 2 or size[1] % 2):
        raise ValueError(f"H.264 (yuv420p) needs an even width and height, got {size[0]}x{size[1]}")
    rate = Fraction(fps).limit_denominator(10000)
    if rate <= 0:     # below 1/20000 fps the rate rounds to 0: every frame time would divide by it
        raise ValueError(f"fps must be at least 1/10000 (a frame every 2.8 h), got {fps!r}")
    if yuv == "gpu" and (fmt != "mp4" or getattr(target, "is_screen", True) or size[0] % 4):
        raise ValueError(f"yuv='gpu' needs an MP4 output from an off-screen target whose width is a multiple of 4, "
                         f"got {fmt} at {size[0]}x{size[1]}")
    nv12 = fmt == "mp4" and yuv != "ffmpeg"           # NV12 reaches x264 as it is: it only encodes

    from tqdm import tqdm

    check_name(path)                                  # (a name too long: refused before any folder is made)
    if not path.parent.exists() and not path.parent.is_symlink():
        # record(world, "out/mine.mp4") in a new folder makes the folder (after every other check, so a
        # refused call leaves nothing), as the command line makes its default out/
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise type(e)(f"cannot write {str(path)!r}: cannot create its directory "
                          f"{str(path.parent)!r} ({e.strerror})") from None
    # from the first file made to the last: SIGTERM / SIGHUP become an interrupt, never debris
    with StopSignals(handle_signals) as stop:
        tmp = _prepare_path(path, fmt, bool(overwrite))
        try:
            if fmt == "mp4":
                sink: _Sink = _H264Sink(tmp, size, rate, crf=int(crf), preset=preset,
                                        pixel_format="nv12" if nv12 else "rgba")
            elif fmt == "gif":
                sink = _GifSink(tmp, size, rate, scale=gif_scale)
            else:
                sink = _PngSink(tmp, size, rate)
        except BaseException:
            _Sink(tmp, size, rate).abort()
            raise
        grab = target.read_raw
        if motion_blur > 1:
            grab = _blurred(world, target, interpolate, motion_blur, steps_per_frame)
        converter = None
        if fmt == "mp4" and yuv == "gpu":
            try:
                converter = _YuvConverter(target)
            except BaseException:
                sink.abort()
                raise
            rgba, grab = grab, (converter.convert if motion_blur == 1 else lambda: converter.convert(rgba()))
        elif nv12:
            grab = _banded_nv12(target, _Writer.DEPTH) if motion_blur == 1 else \
                _cpu_nv12(grab, size, _Writer.DEPTH)

        t0 = time.perf_counter()
        done = 0
        stopped_by = None
        writer = _Writer(sink)
        bar = tqdm(total=frames, unit="frame", desc=f"recording {path.name}", disable=not progress,
                   dynamic_ncols=True, leave=True)
        try:
            try:
                for _ in range(frames):
                    if stop.requested is not None:      # a signal during the last frame: stop between frames
                        stopped_by = stop.requested
                        break
                    if motion_blur > 1:
                        interpolate.start(world)
                    # time warp multiplies the steps of each frame (read per frame: it can drop mid-recording)
                    for _ in range(steps_per_frame * time_warp.factor(world)):
                        if before_step is not None:
                            before_step(world, world.step_count)
                        world.step()
                        if motion_blur > 1:
                            interpolate.after_step(world)
                    if motion_blur == 1:
                        world.render()
                    writer.put(grab())
                    done += 1
                    bar.update(1)
                else:
                    if stop.requested is not None:      # it came during the very last frame
                        stopped_by = stop.requested
            except KeyboardInterrupt as e:              # a second signal, or Ctrl-C from scripted input
                stopped_by = getattr(e, "signum", signal.SIGINT)
            finally:
                bar.close()
            stop.finish()                                  # a second signal must not cut the file being finished
            writer.close()
            done = sink.count                              # what reached the output, to the frame
            if done == 0:
                sink.abort()
                final = None
            else:
                sink.finish()
                _move_into_place(tmp, path, fmt, bool(overwrite))
                final = path
        except BaseException as e:
            try:
                writer.close()
            except BaseException:   # noqa: BLE001 - the first error is the one to report
                pass
            sink.abort()
            if _no_space(e):
                raise RecordingError(f"cannot write {str(path)!r}: no space left on the device "
                                     f"({done} frames recorded, nothing kept)") from None
            if isinstance(e, OSError) and not isinstance(e, FileExistsError) and e.filename is not None:
                raise RecordingError(f"cannot write {str(path)!r}: {e.strerror or e} "
                                     f"({done} frames recorded, nothing kept)") from None
            raise
        finally:
            if converter is not None:
                converter.release()
        if stopped_by is None and stop.requested is not None:
            stopped_by = stop.requested                 # it came while the file was being finished
    seconds = time.perf_counter() - t0
    if stopped_by is not None:
        where = f"wrote {done} frames to {path}" if final else "nothing written"
        print(f"recording interrupted after {done} of {frames} frames ({_signal_name(stopped_by)}): {where}",
              file=sys.stderr)
    return RecordResult(final, fmt, done, frames, seconds, stopped_by is not None, sink.out_size, stopped_by)


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


def _blurred(world, target, poses, n: int, steps_per_frame: int):
    """A ``grab()`` that renders ``n`` sub-frames across the frame's interval and returns their average.

    Sub-frame ``j`` (0..n-1) shows the scene at fraction ``(j + 1) / n`` of
    the interval since the previous frame: the last one is the frame itself.
    Sums in uint16 (64 x 255 fits), then ``(sum + n // 2) // n`` in place:
    integer arithmetic, the same bytes on every run (and 4-5x faster than
    uint32, whose division numpy does slowly).
    """
    w, h = target.size
    acc = np.zeros(w * h * 4, np.uint16)
    half, count = np.uint16(n // 2), np.uint16(n)

    def grab():
        acc[:] = 0
        try:
            for j in range(n):
                poses.pose(world, Fraction(j + 1, n))
                world.render()
                np.add(acc, np.frombuffer(target.read_raw(), np.uint8), out=acc, casting="unsafe")
        finally:
            poses.restore(world)
        np.add(acc, half, out=acc)
        np.floor_divide(acc, count, out=acc)
        return acc.astype(np.uint8).tobytes()

    return grab


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

    FFmpeg's own RGBA -> YUV conversion and flip cost more than the
    encoding did; here one shader pass does both, into three RGBA8 targets a
    quarter as wide and half as high (even luma rows, odd luma rows, chroma),
    read back without conversion (1.5 bytes per pixel instead of 4). Needs a
    width that is a multiple of 4 and an even height. (Reading the previous
    frame's planes while this one converts was tried: on llvmpipe it was no
    faster, 4.1 against 3.9 ms a frame, so the conversion is read at once.)
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


def steps_per_frame(fps: float, dt: float, *, name: str = "fps") -> int:
    """Whole simulation steps per recorded frame: ``fps`` must divide the simulation rate ``1/dt``.

    A recording is one frame per ``k`` fixed steps, never a frame between
    steps; a ValueError (naming ``name`` and the rates that work) otherwise.
    """
    ratio = 1.0 / (fps * dt)
    k = round(ratio)
    if k < 1 or abs(ratio - k) > 1e-9:
        rate = 1.0 / dt
        ok = ", ".join(f"{rate / n:g}" for n in range(1, 7) if abs(rate / n - round(rate / n)) < 1e-9)
        raise ValueError(f"{name} must divide the {rate:g} Hz simulation rate ({ok}, ...), got {fps:g}")
    return k
