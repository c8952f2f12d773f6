"""Off-screen recording: one rendered frame per simulated frame, to MP4, GIF or PNG frames.

::

    from driftframe.framework.recorder import record
    result = record(world, "out/asteroids.mp4", frames=600)     # 10 s at dt = 1/60
    result.frames, result.interrupted, result.path

The world must have rendering attached (:func:`driftframe.rendering.attach`). Each
frame: ``before_step(world, step)`` (scripted input) and ``world.step()``,
``steps_per_frame`` times; then ``world.render()`` (every render- and
record-stage system: models, skybox, a HUD...) and the frame is read back.
Nothing reads the wall clock, so the same scene and seed give the same frames.

Formats, from the path (or ``format=``):

* ``.mp4`` — H.264 (libx264, 4:2:0), encoded in this process by FFmpeg's
  libraries through PyAV (``av``, whose wheels bundle x264): preset
  ``ultrafast`` with CABAC and the deblocking filter back on, crf 26 by
  default (:data:`X264_PRESET`, :data:`X264_TUNING`, :data:`X264_CRF`): on a
  2-core machine shared with a software renderer, encoder CPU is recording
  speed, and these keep the demos' quality for larger files
  (``docs/design/recorder.md``). Frames are converted to NV12 (BT.709,
  limited range; the video is tagged so) by :mod:`framework.yuv` on the
  calling thread as they are read back, in bands of rows that stay in the
  core's cache, and handed to a writer thread, which encodes them (x264
  runs without the GIL) while the caller steps and draws the next.
  ``yuv="gpu"`` converts in a shader instead, ``yuv="ffmpeg"`` hands RGBA to
  FFmpeg's scaler (:mod:`framework.record_nv12`; both slower:
  ``docs/bench/record_throughput.md``). Flags pin everything that could vary
  (thread count, ``+bitexact``, no metadata): the same frames give the same
  bytes on every run. Width and height must be even.
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

This module is the record loop; the rest is in its siblings:
:mod:`framework.record_files` (formats, checks, part files),
:mod:`framework.record_sinks` (H.264, GIF, PNG), :mod:`framework.record_writer`
(the writer thread), :mod:`framework.record_nv12` (the three NV12 paths),
:mod:`framework.record_blur` (motion blur) and :mod:`framework.stop_signals`.
Their public names are importable from here too.
"""
from __future__ import annotations

import math
import os
import signal
import sys
import time
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Protocol

import numpy as np

from driftframe.framework import validate
from driftframe.framework import warp as time_warp
# the parts' public names (and the private ones the tests and benchmarks reach) are importable from here too
from driftframe.framework.output import OutputExistsError, no_space, remove_stale_parts  # noqa: F401
from driftframe.framework.record_blur import MAX_MOTION_BLUR, _blurred, check_blur  # noqa: F401
from driftframe.framework.record_files import (FORMATS, RecordingError, check_output, make_parent,  # noqa: F401
                                               move_into_place, output_format, prepare_path)
from driftframe.framework.record_nv12 import YUV_PATHS, _banded_nv12, _cpu_nv12, _YuvConverter
from driftframe.framework.record_sinks import (GIF_MAX_DELAY, X264_CRF, X264_DEFAULT_CRF, X264_PRESET,  # noqa: F401
                                               X264_PRESETS, X264_THREADS, X264_TUNING, _BT709, _GifSink, _H264Sink,
                                               _PngSink, _Sink, open_sink)
from driftframe.framework.audio import Soundtrack, frame_samples
from driftframe.framework.gl import RenderTarget
from driftframe.framework.record_writer import _Writer

if TYPE_CHECKING:
    from driftframe.framework.world import World
from driftframe.framework.stop_signals import STOP_SIGNALS, Interrupted, StopSignals, raise_interrupted  # noqa: F401
from driftframe.framework.stop_signals import signal_name as _signal_name


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


@dataclass(frozen=True)
class _Plan:
    """:func:`record`'s arguments, checked."""

    path: Path
    fmt: str
    frames: int
    steps_per_frame: int
    motion_blur: int
    rate: Fraction                  # playback frames per second, exact
    crf: int
    preset: str
    yuv: str
    gif_scale: float
    target: Any                     # the world's render target (framework.gl.RenderTarget)
    size: tuple[int, int]
    soundtrack: Any = None          # the world's framework.audio.Soundtrack, for an MP4 with a sound track

    @property
    def nv12(self) -> bool:
        """NV12 reaches x264 as it is (x264 only encodes); else RGBA, for FFmpeg's scaler."""
        return self.fmt == "mp4" and self.yuv != "ffmpeg"


class Interpolator(Protocol):
    """What ``record(interpolate=...)`` calls to pose the scene between fixed steps (motion blur), as
    :class:`driftframe.systems.motion_blur.SubframePoses` does."""

    def start(self, world: World) -> None: ...
    def after_step(self, world: World) -> None: ...
    def pose(self, world: World, s: float) -> None: ...
    def restore(self, world: World) -> None: ...


def record(world: World, path: str | os.PathLike[str], *, frames: int, fps: float | None = None,
           steps_per_frame: int = 1, progress: bool = True,
           before_step: Callable[[World, int], object] | None = None, gif_scale: float = 0.5,
           crf: int | None = None, preset: str = X264_PRESET, overwrite: bool = False, format: str | None = None,
           motion_blur: int = 1, interpolate: Interpolator | None = None, handle_signals: bool = True,
           yuv: str = "cpu", audio: bool = True) -> RecordResult:
    """Step, render and write ``frames`` frames of ``world`` to ``path`` (.mp4, .gif or a directory).

    ``fps``: playback rate (default ``1 / (dt * steps_per_frame)``: real
    time). ``steps_per_frame``: fixed steps between frames, times the world's time warp
    (:mod:`framework.warp`), read frame by frame.
    ``before_step(world, step_index)``: called before every step (scripted
    input). ``progress``: a tqdm bar on stderr. ``gif_scale``: GIF size
    factor. ``crf``/``preset``: x264 quality (0..51, lower is better; None:
    the preset's own default, :data:`X264_CRF`) and speed (default
    :data:`X264_PRESET`; ``preset="veryfast", crf=20`` gives smaller files
    for more encoder CPU: the trade for each demo is in
    ``docs/bench/record_throughput.md``). ``overwrite``: replace an
    existing output (refused otherwise). ``format``: ``"mp4"``, ``"gif"`` or
    ``"png"`` instead of guessing from the path (a ``Path`` cannot end in
    ``/``). ``motion_blur``: sub-frames averaged per frame (1: none), posed by
    ``interpolate`` (see the module docstring). ``handle_signals``: turn
    SIGTERM and SIGHUP into an interrupt while recording (main thread only).
    ``audio``: an MP4 of a world with a soundtrack (:func:`systems.sound.attach`;
    ``attach_rendering`` adds one) gets an AAC track of its sounds, one block of
    samples per frame (:mod:`framework.audio`); False leaves it out.
    ``yuv``: for MP4, where frames become NV12: ``"cpu"`` (default,
    :mod:`framework.yuv` on this thread), ``"gpu"`` (a shader; an off-screen
    target whose width is a multiple of 4) or ``"ffmpeg"`` (RGBA handed to
    FFmpeg's scaler); the pictures agree to within rounding, the bytes differ.
    Returns a :class:`RecordResult`. See the module docstring for what
    happens on Ctrl-C and on failure.
    """
    plan = _checked(world, path, frames=frames, fps=fps, steps_per_frame=steps_per_frame, before_step=before_step,
                    gif_scale=gif_scale, crf=crf, preset=preset, format=format, motion_blur=motion_blur,
                    interpolate=interpolate, yuv=yuv, audio=audio)
    make_parent(plan.path)
    # from the first file made to the last: SIGTERM / SIGHUP become an interrupt, never debris
    with StopSignals(handle_signals) as stop:
        tmp = prepare_path(plan.path, plan.fmt, bool(overwrite))
        sink = open_sink(plan.fmt, tmp, plan.size, plan.rate, crf=plan.crf, preset=plan.preset, nv12=plan.nv12,
                         gif_scale=gif_scale, audio=plan.soundtrack is not None)
        try:
            grab, converter = _frame_source(world, plan, interpolate)
        except BaseException:
            sink.abort()
            raise
        t0 = time.perf_counter()
        try:
            done, stopped_by, final = _write(world, plan, sink, tmp, grab, stop, before_step=before_step,
                                             interpolate=interpolate, progress=progress, overwrite=bool(overwrite))
        finally:
            if converter is not None:
                converter.release()
        if stopped_by is None and stop.requested is not None:
            stopped_by = stop.requested                 # it came while the file was being finished
    seconds = time.perf_counter() - t0
    if stopped_by is not None:
        where = f"wrote {done} frames to {plan.path}" if final else "nothing written"
        print(f"recording interrupted after {done} of {plan.frames} frames ({_signal_name(stopped_by)}): {where}",
              file=sys.stderr)
    return RecordResult(final, plan.fmt, done, plan.frames, seconds, stopped_by is not None, sink.out_size,
                        stopped_by)


def _positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an int >= 1, got {value!r}")
    return int(value)


def _checked(world, path, *, frames, fps, steps_per_frame, before_step, gif_scale, crf, preset, format,
             motion_blur, interpolate, yuv, audio=True) -> _Plan:
    """:func:`record`'s arguments checked, before anything is made: a clear error for the first bad one."""
    frames = _positive_int("frames", frames)
    steps_per_frame = _positive_int("steps_per_frame", steps_per_frame)
    motion_blur = _positive_int("motion_blur", motion_blur)
    check_blur(motion_blur, interpolate)
    if fps is None:
        fps = 1.0 / (world.dt * steps_per_frame)
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.integer, np.floating)) \
            or not math.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be a finite number > 0, got {fps!r}")
    validate.function("before_step", before_step, optional=True, what="a function (world, step_index)")
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
    target = world.resources.get(RenderTarget)
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
    size = tuple(target.size)
    if fmt == "mp4" and (size[0] % 2 or size[1] % 2):
        raise ValueError(f"H.264 (yuv420p) needs an even width and height, got {size[0]}x{size[1]}")
    # exact for ints; a float's exact binary value (np.float32 too, which Fraction takes only as a float)
    rate = Fraction(int(fps) if isinstance(fps, (int, np.integer)) else float(fps)).limit_denominator(10000)
    if rate <= 0:     # below 1/20000 fps the rate rounds to 0: every frame time would divide by it
        raise ValueError(f"fps must be at least 1/10000 (a frame every 2.8 h), got {fps!r}")
    if yuv == "gpu" and (fmt != "mp4" or getattr(target, "is_screen", True) or size[0] % 4):
        raise ValueError(f"yuv='gpu' needs an MP4 output from an off-screen target whose width is a multiple of 4, "
                         f"got {fmt} at {size[0]}x{size[1]}")
    soundtrack = world.resources.get(Soundtrack) if audio and fmt == "mp4" else None
    return _Plan(Path(os.fspath(path)), fmt, frames, steps_per_frame, motion_blur, rate, int(crf), preset, yuv,
                 gif_scale, target, size, soundtrack)


def _frame_source(world, plan: _Plan, interpolate):
    """``(grab, converter)``: ``grab()`` gives the next frame as the sink takes it (after the frame's render,
    or rendering its own sub-frames for motion blur); ``converter`` is the GPU path's, to release, or None."""
    target = plan.target
    grab = target.read_raw
    if plan.motion_blur > 1:
        grab = _blurred(world, target, interpolate, plan.motion_blur, plan.steps_per_frame)
    if plan.fmt == "mp4" and plan.yuv == "gpu":
        converter = _YuvConverter(target)
        if plan.motion_blur == 1:
            return converter.convert, converter
        rgba = grab
        return (lambda: converter.convert(rgba())), converter
    if plan.nv12:
        if plan.motion_blur == 1:
            return _banded_nv12(target, _Writer.DEPTH), None
        return _cpu_nv12(grab, plan.size, _Writer.DEPTH), None
    return grab, None


def _write(world, plan: _Plan, sink: _Sink, tmp: Path, grab, stop: StopSignals, *, before_step, interpolate,
           progress: bool, overwrite: bool):
    """The record loop: step, render and hand each frame to the writer, then finish and publish the output.

    Returns ``(frames written, the signal that stopped it or None, the path written or None)``; on any
    other failure everything written is removed and the error raised (a failed write as
    :class:`RecordingError`).
    """
    from tqdm import tqdm

    blur = plan.motion_blur > 1
    done = 0
    stopped_by = None
    writer = _Writer(sink)
    bar = tqdm(total=plan.frames, unit="frame", desc=f"recording {plan.path.name}", disable=not progress,
               dynamic_ncols=True, leave=True)
    try:
        try:
            for _ in range(plan.frames):
                if stop.requested is not None:          # a signal during the last frame: stop between frames
                    stopped_by = stop.requested
                    break
                if blur:
                    interpolate.start(world)
                # time warp multiplies the steps of each frame (read per frame: it can drop mid-recording)
                for _ in range(plan.steps_per_frame * time_warp.factor(world)):
                    if before_step is not None:
                        before_step(world, world.step_count)
                    world.step()
                    if blur:
                        interpolate.after_step(world)
                if not blur:
                    world.render()
                writer.put(grab())
                if plan.soundtrack is not None:       # the frame's sounds, sample-exact in the frame's time
                    writer.put_audio(plan.soundtrack.take(frame_samples(plan.rate, done), world.time))
                done += 1
                bar.update(1)
            else:
                if stop.requested is not None:          # it came during the very last frame
                    stopped_by = stop.requested
        except KeyboardInterrupt as e:                  # a second signal, or Ctrl-C from scripted input
            stopped_by = getattr(e, "signum", signal.SIGINT)
        finally:
            bar.close()
        stop.finish()                                   # a second signal must not cut the file being finished
        writer.close()
        done = sink.count                               # what reached the output, to the frame
        if done == 0:
            sink.abort()
            return done, stopped_by, None
        sink.finish()
        move_into_place(tmp, plan.path, plan.fmt, overwrite)
        return done, stopped_by, plan.path
    except BaseException as e:
        try:
            writer.close()
        except BaseException:   # noqa: BLE001 - the first error is the one to report
            pass
        sink.abort()
        if no_space(e):
            raise RecordingError(f"cannot write {str(plan.path)!r}: no space left on the device "
                                 f"({done} frames recorded, nothing kept)") from None
        if isinstance(e, OSError) and not isinstance(e, FileExistsError) and e.filename is not None:
            raise RecordingError(f"cannot write {str(plan.path)!r}: {e.strerror or e} "
                                 f"({done} frames recorded, nothing kept)") from None
        raise


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
