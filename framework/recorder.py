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

Formats, from the path:

* ``.mp4`` — H.264 (libx264, yuv420p) through the ffmpeg that the
  ``imageio-ffmpeg`` wheel ships (x264 preset ``veryfast``, crf 20 by
  default). ffmpeg runs in its own process, so encoding
  overlaps rendering. Flags pin everything that could vary (thread count,
  ``+bitexact``, no metadata): the same frames give the same bytes on every
  run. Width and height must be even.
* ``.gif`` — Pillow, scaled by ``gif_scale`` (default 1/2: GIF is for
  previews), 256 colours per frame without dithering, looping. GIF delays are
  in 1/100 s and players slow down delays under 2/100 s, so a 60 fps GIF
  plays at 50 fps. Pillow merges identical consecutive frames into one longer
  frame.
* a directory (a path with no suffix, ending in ``/``, or an existing
  directory) — numbered PNGs ``frame_000000.png``, ``frame_000001.png``...

Safety: the output goes to a temporary name beside the target and is moved
into place (``os.replace``) only when complete. Ctrl-C (KeyboardInterrupt)
stops rendering, finishes a valid, shorter file and reports
``interrupted=True`` (and says so on stderr); any other failure removes
everything it wrote and re-raises. An unknown format, an unwritable path or
bad arguments raise before anything is rendered or stepped.
"""
from __future__ import annotations

import math
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np

FORMATS = ("mp4", "gif", "png")
_SUFFIXES = {".mp4": "mp4", ".gif": "gif"}
_PNG_NAME = "frame_{:06d}.png"
X264_PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower", "veryslow")
#: x264 threads, pinned: the encoded bytes depend on it, so it must not follow the machine's cores.
X264_THREADS = 2


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
    #: True if Ctrl-C stopped it early.
    interrupted: bool
    #: (width, height) of the frames written, pixels.
    size: tuple[int, int]

    @property
    def frames_per_second(self) -> float:
        """Frames written per wall-clock second."""
        return self.frames / self.seconds if self.seconds > 0 else math.inf


def output_format(path) -> str:
    """``"mp4"``, ``"gif"`` or ``"png"`` (a directory of frames) for ``path``; a clear error otherwise."""
    text = os.fspath(path)
    p = Path(text)
    if text.endswith(("/", os.sep)) or p.is_dir() or p.suffix == "":
        return "png"
    fmt = _SUFFIXES.get(p.suffix.lower())
    if fmt is None:
        hint = " (a .png path is a single image: give a directory for numbered PNG frames)" \
            if p.suffix.lower() == ".png" else ""
        raise ValueError(f"unknown output format {p.suffix!r} for {text!r}{hint}; "
                         "use .mp4, .gif, or a directory for numbered PNG frames")
    return fmt


# -- writers: each writes to a temporary path, then is finished or aborted ---------------------
class _Sink:
    """Receives raw RGBA frames, bottom row first (GL order)."""

    def __init__(self, tmp: Path, size: tuple[int, int], fps: Fraction):
        self.tmp = tmp
        self.size = size
        self.fps = fps
        self.count = 0

    def write(self, raw: bytes) -> None:
        raise NotImplementedError

    def finish(self) -> None:
        """Complete the temporary output (a valid file with the frames written so far)."""

    def abort(self) -> None:
        """Stop and delete the temporary output."""
        if self.tmp.is_dir():
            shutil.rmtree(self.tmp, ignore_errors=True)
        else:
            self.tmp.unlink(missing_ok=True)


class _FFmpegSink(_Sink):
    """H.264 MP4 through imageio-ffmpeg's bundled ffmpeg, fed raw RGBA on a pipe."""

    def __init__(self, tmp, size, fps, *, crf: int, preset: str):
        super().__init__(tmp, size, fps)
        import imageio_ffmpeg

        w, h = size
        cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-hide_banner", "-nostdin", "-loglevel", "error",
               "-f", "rawvideo", "-pix_fmt", "rgba", "-s", f"{w}x{h}", "-r", str(fps), "-i", "pipe:0",
               "-an", "-vf", "vflip",                   # GL rows come bottom-up
               "-c:v", "libx264", "-preset", preset, "-crf", str(crf), "-pix_fmt", "yuv420p",
               "-threads", str(X264_THREADS),           # the bitstream depends on the thread count
               "-fflags", "+bitexact", "-flags:v", "+bitexact", "-map_metadata", "-1",
               "-f", "mp4", str(tmp)]
        self._log = tempfile.TemporaryFile()
        # own session: Ctrl-C in a terminal reaches Python, not ffmpeg, which we then close cleanly
        self._proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                      stderr=self._log, start_new_session=True)

    def _error(self, what: str) -> RuntimeError:
        self._log.seek(0)
        tail = self._log.read().decode(errors="replace").strip()[-2000:]
        return RuntimeError(f"ffmpeg {what} (exit code {self._proc.poll()}): {tail or 'no message'}")

    def write(self, raw: bytes) -> None:
        try:
            self._proc.stdin.write(raw)
        except (BrokenPipeError, OSError):
            self._proc.wait()
            raise self._error("stopped while receiving frames") from None
        self.count += 1

    def finish(self) -> None:
        try:
            self._proc.stdin.close()
        except (BrokenPipeError, OSError):
            pass
        code = self._proc.wait()
        if code != 0:
            raise self._error("failed to finish the video")
        self._log.close()

    def abort(self) -> None:
        if self._proc.poll() is None:
            self._proc.kill()
        self._proc.wait()
        try:
            self._proc.stdin.close()
        except (BrokenPipeError, OSError):
            pass
        self._log.close()
        super().abort()


class _GifSink(_Sink):
    """Pillow GIF at reduced size; frames are quantised as they come and saved at the end."""

    def __init__(self, tmp, size, fps, *, scale: float):
        super().__init__(tmp, size, fps)
        w, h = size
        self.out_size = (max(1, round(w * scale)), max(1, round(h * scale)))
        self._frames = []

    def write(self, raw: bytes) -> None:
        from PIL import Image

        im = Image.frombuffer("RGBA", self.size, raw, "raw", "RGBA", 0, -1).convert("RGB")  # -1: flip rows
        if im.size != self.out_size:
            im = im.resize(self.out_size, Image.Resampling.BOX)
        self._frames.append(im.quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE))
        self.count += 1

    def finish(self) -> None:
        # GIF delays are whole 1/100 s; under 2/100 s many players slow down to 1/10 s
        delay_ms = 10 * max(2, round(100 / float(self.fps)))
        first, rest = self._frames[0], self._frames[1:]
        first.save(self.tmp, format="GIF", save_all=True, append_images=rest, duration=delay_ms, loop=0,
                   optimize=False)
        self._frames = []


class _PngSink(_Sink):
    """Numbered PNG frames in a temporary directory."""

    def write(self, raw: bytes) -> None:
        from PIL import Image

        im = Image.frombuffer("RGBA", self.size, raw, "raw", "RGBA", 0, -1).convert("RGB")
        im.save(self.tmp / _PNG_NAME.format(self.count), format="PNG", compress_level=1)
        self.count += 1


class _Writer:
    """Feeds a sink from a bounded queue on a background thread, so encoding overlaps rendering.

    GL stays on the caller's thread (a context works only there); the thread
    only sees bytes. An error in the thread is re-raised in the caller at the
    next ``put`` or at ``close``.
    """

    def __init__(self, sink: _Sink, depth: int = 3):
        self.sink = sink
        self._q: queue.Queue = queue.Queue(maxsize=depth)
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

    def put(self, raw: bytes) -> None:
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


def _prepare_path(path: Path, fmt: str) -> Path:
    """Check the target and create the temporary output beside it (proving it is writable)."""
    parent = path.parent
    if not parent.exists():
        raise FileNotFoundError(f"cannot write {str(path)!r}: directory {str(parent)!r} does not exist")
    if not parent.is_dir():
        raise NotADirectoryError(f"cannot write {str(path)!r}: {str(parent)!r} is not a directory")
    if fmt == "png":
        if path.exists() and not path.is_dir():
            raise FileExistsError(f"cannot write PNG frames to {str(path)!r}: it exists and is not a directory")
        if path.is_dir():
            foreign = [p.name for p in path.iterdir() if not (p.name.startswith("frame_") and p.suffix == ".png")]
            if foreign:
                raise FileExistsError(f"cannot write PNG frames to {str(path)!r}: it holds other files "
                                      f"({', '.join(sorted(foreign)[:5])}); give an empty or new directory")
    elif path.is_dir():
        raise IsADirectoryError(f"cannot write {str(path)!r}: it is a directory")
    try:
        if fmt == "png":
            return Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".part", dir=parent))
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".part{path.suffix}", dir=parent)
        os.close(fd)
        return Path(tmp)
    except OSError as e:
        raise PermissionError(f"cannot write {str(path)!r}: directory {str(parent)!r} is not writable "
                              f"({e.strerror or e})") from None


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _move_into_place(tmp: Path, path: Path, fmt: str) -> None:
    # mkstemp/mkdtemp made the temporary output private (0600/0700): give it the usual permissions
    mask = _umask()
    os.chmod(tmp, (0o777 if fmt == "png" else 0o666) & ~mask)
    if fmt == "png":
        for f in tmp.iterdir():
            os.chmod(f, 0o666 & ~mask)
    if fmt == "png" and path.is_dir():
        # swap the old frames directory out, the new one in, then delete the old one
        old = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".old", dir=path.parent))
        os.replace(path, old / "frames")
        os.replace(tmp, path)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(tmp, path)


def record(world, path, *, frames: int, fps: float | None = None, steps_per_frame: int = 1,
           progress: bool = True, before_step=None, gif_scale: float = 0.5, crf: int = 20,
           preset: str = "veryfast") -> RecordResult:
    """Step, render and write ``frames`` frames of ``world`` to ``path`` (.mp4, .gif or a directory).

    ``fps``: playback rate (default ``1 / (dt * steps_per_frame)``: real
    time). ``steps_per_frame``: fixed steps between frames.
    ``before_step(world, step_index)``: called before every step (scripted
    input). ``progress``: a tqdm bar on stderr. ``gif_scale``: GIF size
    factor. ``crf``/``preset``: x264 quality (0..51, lower is better) and
    speed (``"veryfast"`` recorded the asteroids demo 1.2-1.6x faster than
    ``"medium"`` on 2 cores, for files of about the same size at the same
    crf; see ``benchmarks/record_throughput.py``). Returns a :class:`RecordResult`. See the module docstring for what
    happens on Ctrl-C and on failure.
    """
    frames = _positive_int("frames", frames)
    steps_per_frame = _positive_int("steps_per_frame", steps_per_frame)
    if fps is None:
        fps = 1.0 / (world.dt * steps_per_frame)
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.integer, np.floating)) \
            or not math.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be a finite number > 0, got {fps!r}")
    if before_step is not None and not callable(before_step):
        raise TypeError(f"before_step must be a function (world, step_index) or None, got {before_step!r}")
    if not 0 < gif_scale <= 1:
        raise ValueError(f"gif_scale must be in (0, 1], got {gif_scale!r}")
    if isinstance(crf, bool) or not isinstance(crf, int) or not 0 <= crf <= 51:
        raise ValueError(f"crf must be an int in [0, 51], got {crf!r}")
    if preset not in X264_PRESETS:
        raise ValueError(f"preset must be one of {', '.join(X264_PRESETS)}, got {preset!r}")
    target = world.resources.get("render_target")
    if target is None:
        raise LookupError("record: the world has no render target; call systems.render.attach(world, ...) first")
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path must be a str or os.PathLike, got {path!r}")
    fmt = output_format(path)
    path = Path(os.fspath(path))
    size = tuple(target.size)
    if fmt == "mp4" and (size[0] % 2 or size[1] % 2):
        raise ValueError(f"H.264 (yuv420p) needs an even width and height, got {size[0]}x{size[1]}")
    rate = Fraction(fps).limit_denominator(10000)

    tmp = _prepare_path(path, fmt)
    try:
        if fmt == "mp4":
            sink: _Sink = _FFmpegSink(tmp, size, rate, crf=crf, preset=preset)
        elif fmt == "gif":
            sink = _GifSink(tmp, size, rate, scale=gif_scale)
        else:
            sink = _PngSink(tmp, size, rate)
    except BaseException:
        _Sink(tmp, size, rate).abort()
        raise
    out_size = getattr(sink, "out_size", size)

    from tqdm import tqdm

    t0 = time.perf_counter()
    writer = _Writer(sink)
    done = 0
    interrupted = False
    bar = tqdm(total=frames, unit="frame", desc=f"recording {path.name}", disable=not progress,
               dynamic_ncols=True, leave=True)
    try:
        try:
            for _ in range(frames):
                for _ in range(steps_per_frame):
                    if before_step is not None:
                        before_step(world, world.step_count)
                    world.step()
                world.render()
                writer.put(target.read_raw())
                done += 1
                bar.update(1)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            bar.close()
        writer.close()
        if done == 0:
            sink.abort()
            final = None
        else:
            sink.finish()
            _move_into_place(tmp, path, fmt)
            final = path
    except BaseException:
        try:
            writer.close()
        except BaseException:   # noqa: BLE001 - the first error is the one to report
            pass
        sink.abort()
        raise
    seconds = time.perf_counter() - t0
    if interrupted:
        where = f"wrote {done} frames to {path}" if final else "nothing written"
        print(f"recording interrupted after {done} of {frames} frames: {where}", file=sys.stderr)
    return RecordResult(final, fmt, done, frames, seconds, interrupted, out_size)
