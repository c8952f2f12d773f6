"""How fast does recording go: frames written per second to MP4, GIF and PNGs, beside bare render + read-back?

The scene is the ``asteroids`` demo exactly as ``driftframe record`` runs it
(scripted flight through 50 scaled asteroids, collisions, chase and cockpit
cameras, skybox, HUD, sparks and the engine's plume, sound cues) at 1280x720.
Each run builds a fresh world and records ``F`` frames with
:func:`framework.recorder.record` (one fixed step per frame; an MP4 with
its AAC sound track unless a row says otherwise); the time includes
finishing the file (ffmpeg's last frames, the GIF's trailer). The baseline
(issue 25's "bare render loop") is the loop with no writer and neither
effects nor sound: ``world.step()``, ``world.render()``, RGBA read-back;
beside it the same loop of the world that is recorded. A writer thread encodes (x264 through
PyAV, in this process, without the GIL), so encoding overlaps rendering; on
2 cores they compete for the same CPUs, so what counts is the CPU each
frame costs in all. The default MP4 path converts each frame to NV12 on
the calling thread as it reads it back, in bands that stay in the cache
(:mod:`framework.yuv`), and x264 only encodes, ultrafast + CABAC +
deblocking, deadzone 6 and a keyframe every 60 frames at crf 26; beside
it: the same without the sound track, the same with the x264 settings from
before issue 25, the same encoded in an ffmpeg process fed
on a pipe (before in-process encoding), the same with each frame read
whole and then converted (before bands), the conversion in a shader
(``yuv="gpu"``) or by FFmpeg's scaler (``yuv="ffmpeg"``), the recorder
before issue 11 (RGBA piped to ffmpeg, which converts, x264 veryfast +
subme 1 at crf 20), veryfast with the CPU conversion, motion blur, GIF and
PNG frames. The piped rows use the ffmpeg of the ``imageio-ffmpeg`` wheel
(the ``bench`` extra).

A second table weighs the encoder settings against each other on three
demos, from the same NV12 frames: x264's CPU a frame (the recorder's own
encoder), the bytes, and the luma PSNR of the decoded video against its
input. That is what chose the default preset and crf.

    python -m benchmarks.record_throughput [--quick]
"""
from __future__ import annotations

import contextlib
import os
import resource
import statistics
import tempfile
import textwrap
import time
from unittest import mock
from pathlib import Path

import numpy as np

from benchmarks.common import figure, parser, save_chart, table, write_section
from driftframe.components.body import AngularVelocity, Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.render import ModelRef
from driftframe.framework import frame as fr
from driftframe.framework import record_sinks, recorder
from driftframe.framework.gl import RenderTarget, create_context, renderer
from driftframe.framework.model_cache import ModelCache
from driftframe.framework.recorder import record
from driftframe.framework.world import World
from driftframe.systems.movement import MovementSystem
from driftframe.rendering import attach
from driftframe.systems.spin import SpinSystem

NAME = "record_throughput"
#: What the default MP4 recording must keep of the bare loop's frame rate (issue 11).
MP4_BAR = 0.8
#: What a recording with effects and its sound track must keep of the bare render loop's frame rate (issue 25).
RECORD_BAR = 0.75
SIZE = (1280, 720)


def build(ctx, seed: int = 1, *, effects: bool = True, sound: bool = True) -> World:
    """The ``asteroids`` demo as ``driftframe record`` runs it (scripted flight, HUD, sparks and plume, sound
    cues), rendering attached; ``effects=False, sound=False``: the bare render loop's world, as before issue 25.

    Falls back to a similar hand-built scene (ship through 50 drifting,
    spinning asteroids, chase camera) if the demo modules are not there.
    """
    try:
        from driftframe.app import attach_rendering, make_world
    except ImportError:
        return _fallback(ctx, seed)
    w, _ = make_world("asteroids", seed=seed)
    attach_rendering(w, ctx, size=SIZE, own_context=False, effects=effects, sound=sound)
    return w


def _has_effects(w: World) -> bool:
    from driftframe.systems.effects import EffectsSystem

    return w.get_system(EffectsSystem) is not None


def _audio_streams(path: Path) -> int:
    """How many sound tracks the MP4 at ``path`` has (FFmpeg's demuxer, through PyAV)."""
    import av

    with av.open(str(path)) as f:
        return len(f.streams.audio)


def _fallback(ctx, seed: int) -> World:
    w = World()
    w.add_system(MovementSystem())
    w.add_system(SpinSystem())
    ship = w.create_entity(Transform((0.0, 0.0, -20.0)), Velocity((0.5, 0.2, 4.0)), ModelRef("ship"))
    w.create_entity(Camera(target=ship, mode="chase"))
    attach(w, ctx, SIZE)
    cache = w.resources[ModelCache]
    rng = np.random.default_rng(seed)
    n = 50
    for k, r in enumerate(rng.uniform(0.6, 3.5, n)):
        cache.variant(f"asteroid_{k}", "sphere", scale=float(r))
    w.create_entities(
        Transform.bulk(n, position=rng.uniform(-40.0, 40.0, (n, 3)),
                       orientation=fr.quat_from_rotvec(rng.normal(0.0, 1.0, (n, 3)))),
        Velocity.bulk(n, linear=rng.normal(0.0, 1.0, (n, 3))),
        AngularVelocity.bulk(n, angular=rng.normal(0.0, 0.5, (n, 3))),
        [ModelRef(f"asteroid_{k}") for k in range(n)])
    return w


def _cpu_seconds() -> float:
    """User + system time of this process and of its finished children (ffmpeg, in the piped rows)."""
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def bare(ctx, frames: int, **attach) -> float:
    """Frames per second of step + render + read-back, no writer; ``attach``: :func:`build`'s effects and sound."""
    w = build(ctx, **attach)
    target = w.resources[RenderTarget]
    w.step()
    w.render()
    target.read_raw()                               # warm-up: shaders, buffers
    t0 = time.perf_counter()
    for _ in range(frames):
        w.step()
        w.render()
        target.read_raw()
    fps = frames / (time.perf_counter() - t0)
    w.close()
    return fps


#: The module each swappable name is looked up in when record() runs: the sinks' or the record loop's.
_LOOKED_UP_IN = {"X264_TUNING": record_sinks, "_H264Sink": record_sinks, "_banded_nv12": recorder}


def _swapped(**attrs):
    """A context in which the recorder's named attributes are the values given (None: left as they are)."""
    stack = contextlib.ExitStack()
    for name, value in attrs.items():
        if value is not None:
            stack.enter_context(mock.patch.object(_LOOKED_UP_IN[name], name, value))
    return stack


def _args(options: dict) -> list[str]:
    """Encoder options as ffmpeg command-line arguments."""
    return [a for k, v in options.items() for a in (f"-{k}", v)]


class _PipedSink(record_sinks._Sink):
    """The MP4 sink before in-process encoding: the same x264 settings, through the ffmpeg command of the
    ``imageio-ffmpeg`` wheel (the ``bench`` extra), fed raw frames on a pipe widened to 1 MiB."""

    def __init__(self, tmp, size, fps, *, crf: int, preset: str, pixel_format: str = "rgba", audio: bool = False):
        import fcntl
        import subprocess

        import imageio_ffmpeg

        if audio:       # one pipe carries the frames; a second input would need its own feeder: not modelled
            raise SystemExit("the piped MP4 rows record without a sound track: pass audio=False")
        super().__init__(tmp, size, fps)
        self.pixel_format = pixel_format
        w, h = size
        tags = _args(record_sinks._BT709)
        convert = ["-vf", "vflip,scale=out_color_matrix=bt709:out_range=tv"] if pixel_format == "rgba" else []
        cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-nostdin", "-loglevel", "error",
               "-f", "rawvideo", "-pix_fmt", pixel_format, "-s", f"{w}x{h}", "-r", str(fps),
               *(tags if pixel_format == "nv12" else []), "-i", "pipe:0", "-an", *convert,
               "-c:v", "libx264", "-preset", preset, "-crf", str(crf), *_args(record_sinks.X264_TUNING.get(preset, {})),
               "-pix_fmt", "nv12" if pixel_format == "nv12" else "yuv420p",
               "-threads", str(record_sinks.X264_THREADS), *tags,
               "-fflags", "+bitexact", "-flags:v", "+bitexact", "-map_metadata", "-1", "-f", "mp4", str(tmp)]
        self._proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, start_new_session=True)
        with contextlib.suppress(OSError):
            fcntl.fcntl(self._proc.stdin.fileno(), getattr(fcntl, "F_SETPIPE_SZ", 1031), 1 << 20)

    def write(self, raw) -> None:
        self._proc.stdin.write(raw)
        self.count += 1

    def finish(self) -> None:
        self._proc.stdin.close()
        if self._proc.wait():
            raise SystemExit(f"ffmpeg failed: exit code {self._proc.returncode}")

    def abort(self) -> None:
        self._proc.kill()
        self._proc.wait()
        super().abort()


def _whole_frame_nv12(target, depth: int):
    """The NV12 path as it was before bands: read the whole frame, then convert it."""
    return recorder._cpu_nv12(target.read_raw, target.size, depth)


def recorded(ctx, frames: int, path, **kw) -> tuple[float, int]:
    """Frames per second of a whole recording, and the bytes written.

    Every recording's world has the effects system, and an MP4 made with
    ``audio`` (record()'s default) must come out with its sound track:
    checked on each run, so the rows measure what they say.

    ``_tuning``: x264 settings beyond the preset to use instead of the
    recorder's (``{}``: the preset alone, as before they were added).
    ``_whole``: read each frame whole and then convert it, as before bands.
    ``_piped``: encode in ffmpeg's process, fed on a pipe, as before in-process encoding.
    """
    from driftframe.systems.motion_blur import SubframePoses

    swaps = _swapped(X264_TUNING=kw.pop("_tuning", None),
                     _banded_nv12=_whole_frame_nv12 if kw.pop("_whole", False) else None,
                     _H264Sink=_PipedSink if kw.pop("_piped", False) else None)
    if kw.get("motion_blur", 1) > 1:
        kw["interpolate"] = SubframePoses()
    w = build(ctx)
    if not _has_effects(w):
        raise SystemExit("the recorded world has no EffectsSystem: attach_rendering(effects=True) changed?")
    w.step()
    w.render()                                      # warm-up, as for the baseline
    try:
        with swaps:
            res = record(w, path, frames=frames, progress=False, **kw)
    finally:
        w.close()
    path = Path(path)
    if path.suffix == ".mp4" and _audio_streams(path) != int(kw.get("audio", True)):
        raise SystemExit(f"{path.name}: {_audio_streams(path)} sound tracks, audio={kw.get('audio', True)}")
    size = sum(f.stat().st_size for f in path.iterdir()) if path.is_dir() else path.stat().st_size
    return res.frames / res.seconds, size


#: Labels of the two loops with no writer, and of the default recording, that the bars compare.
BARE = "bare render loop: step + render + read-back, no effects, no sound (no writer; as before issue 25)"
LOOP = "step + render + read-back with effects and sound cues (no writer): the recorded world's own loop"
DEFAULT = ("MP4 (default): sparks, plume and an AAC sound track; NV12 on the CPU in bands, x264 in this process "
           "(ultrafast + CABAC + deblock + deadzone 6 + keyint 60, crf 26)")

NO_AUDIO = "MP4: the default without its sound track (--no-audio)"


def _modes() -> dict[str, tuple[str, dict]]:
    """Each row: ("bare", build()'s effects and sound) for a loop with no writer, else (output name, record()'s
    keywords; ``_piped``/``_whole``/``_tuning``: the variants of :func:`recorded`)."""
    before = {"preset": "veryfast", "crf": 20, "_tuning": {"veryfast": {"x264-params": "subme=1"}}}
    return {
        BARE: ("bare", {"effects": False, "sound": False}),
        LOOP: ("bare", {}),
        DEFAULT: ("clip.mp4", {}),
        NO_AUDIO: ("clip.mp4", {"audio": False}),
        "MP4: the default x264 settings before issue 25's deadzone and keyint (ultrafast + CABAC + deblock)":
            ("clip.mp4", {"_tuning": {"ultrafast": {"x264-params": "cabac=1:deblock=0,0"}}}),
        "MP4: the default, but x264 in ffmpeg's process, fed on a pipe (before in-process encoding; no sound "
        "track)": ("clip.mp4", {"_piped": True, "audio": False}),
        "MP4: the default, each frame read whole, then converted (before bands)": ("clip.mp4", {"_whole": True}),
        "MP4: NV12 from a shader (yuv='gpu'), the same x264": ("clip.mp4", {"yuv": "gpu"}),
        "MP4: RGBA, FFmpeg's scaler converts (yuv='ffmpeg'), the same x264": ("clip.mp4", {"yuv": "ffmpeg"}),
        "MP4: NV12 on the CPU, x264 veryfast + subme 1, crf 20": ("clip.mp4", dict(before)),
        "MP4 as before issue 11: RGBA piped, ffmpeg converts, x264 veryfast + subme 1, crf 20 (no sound track)":
            ("clip.mp4", dict(before, yuv="ffmpeg", _piped=True, audio=False)),
        "MP4, --motion-blur 4": ("clip.mp4", {"motion_blur": 4}),
        "GIF, 640x360 (streamed)": ("clip.gif", {}),
        "PNG frames (zlib level 1)": ("frames/", {}),
    }


def _measure(ctx, modes: dict, frames: int, repeats: int) -> tuple[dict, dict]:
    """Per row, each round's (frames/s, bytes) and CPU ms a frame."""
    samples: dict[str, list] = {label: [] for label in modes}
    cpu: dict[str, list] = {label: [] for label in modes}
    with tempfile.TemporaryDirectory() as tmp:
        # interleaved: each round runs every mode once, so a busy spell on the machine hits all of them
        for k in range(repeats):
            for m, (label, (name, kw)) in enumerate(modes.items()):
                c0 = _cpu_seconds()
                if name == "bare":
                    samples[label].append((bare(ctx, frames, **kw), 0))
                else:
                    samples[label].append(recorded(ctx, frames, f"{tmp}/{k}_{m}_{name}", **dict(kw)))
                cpu[label].append((_cpu_seconds() - c0) / frames * 1e3)
    return samples, cpu


def _paired(runs: list, base: list) -> tuple[float, float]:
    """Median and worst over rounds of each run's frames/s over ``base``'s in the same round (a busy spell
    slows both)."""
    ratios = [r[0] / b[0] for r, b in zip(runs, base)]
    return statistics.median(ratios), min(ratios)


def main(argv=None) -> None:
    args = parser(__doc__.splitlines()[0]).parse_args(argv)
    frames = 20 if args.quick else 240
    repeats = 1 if args.quick else 5
    ctx = create_context()
    modes = _modes()
    load_start = os.getloadavg()[0]
    samples, cpu = _measure(ctx, modes, frames, repeats)
    load_end = os.getloadavg()[0]
    rows, fps_of, shares, own = [], {}, {}, {}
    ms_of = {label: statistics.median(c) for label, c in cpu.items()}
    cpu_share = ms_of[BARE] / ms_of[DEFAULT]
    for label, runs in samples.items():
        fps = statistics.median(r[0] for r in runs)
        fps_of[label] = fps
        spread = f"{min(r[0] for r in runs):.1f}-{max(r[0] for r in runs):.1f}"
        shares[label], own[label] = _paired(runs, samples[BARE]), _paired(runs, samples[LOOP])
        share = f"{shares[label][0]:.2f} (worst {shares[label][1]:.2f})"
        of_own = f"{own[label][0]:.2f} (worst {own[label][1]:.2f})"
        ms = f"{statistics.median(cpu[label]):.1f}"
        per_frame = statistics.median(r[1] for r in runs) / frames
        rows.append([label, fps, spread, share, of_own, ms,
                     "-" if modes[label][0] == "bare" else f"{per_frame / 1024:.2f} KiB"])
        print(f"{label[:90]:>90}: {fps:6.1f} frames/s  ({share} of bare, {ms} ms CPU a frame)")

    qrows, points = encoder_quality(ctx, 30 if args.quick else 120)
    fig, (ax, bx) = figure(1, 2, figsize=(13, 1.5 + 0.5 * len(modes)), gridspec_kw={"width_ratios": [1.25, 1]})
    labels = list(fps_of)
    ax.barh(range(len(labels)), [fps_of[k] for k in labels], color=["grey"] * 2 + ["C0"] * (len(labels) - 2))
    ax.set_yticks(range(len(labels)), ["\n".join(textwrap.wrap(k, 44)) for k in labels], fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel(f"frames per second written (median of {repeats} x {frames} frames)")
    ax.set_title(f"Recording asteroids at {SIZE[0]}x{SIZE[1]} ({renderer(ctx).split(' (')[0]})", fontsize=10)
    for i, k in enumerate(labels):
        ax.text(fps_of[k], i, f" {fps_of[k]:.1f}", va="center", fontsize=7)
    ax.set_xlim(0, 1.12 * max(fps_of.values()))
    # the encoder's trade: CPU against quality, one line per demo through its settings
    marks = dict(zip([s[0] for s in SETTINGS], "os^vXDP"))
    for c, demo in enumerate(dict.fromkeys(p[0] for p in points)):
        mine = [p for p in points if p[0] == demo]
        for _, label, cpu_ms, psnr, _ in mine:
            big = "(default)" in label
            bx.plot(cpu_ms, psnr, marks[label], color=f"C{c}", ms=9 if big else 5,
                    mfc=f"C{c}" if big else "none", label=label if c == 0 else None)
        bx.text(mine[0][2], mine[0][3], f"  {demo}", color=f"C{c}", fontsize=8, va="center")
    bx.set_xlabel("x264 CPU a frame, ms (1280x720)")
    bx.set_ylabel("luma PSNR, dB (mean over frames)")
    bx.set_title("Encoder settings: CPU against quality (filled: the default)", fontsize=10)
    bx.legend(fontsize=6.5, loc="upper right")
    save_chart(fig, NAME)
    body = "\n".join([
        f"{frames} frames (the first {frames / 60:g} s of the demo: 10 collisions, 42 steps of thrust) per run, "
        f"median of {repeats} interleaved runs, a fresh world each run; the recording time includes finishing "
        "the file. Every mode steps the simulation (collisions included) and draws the HUD; every recording's "
        "world draws the sparks, flashes and engine plume (systems/effects.py) and collects the sound cues "
        "(systems/sound.py), and every MP4 but the rows marked otherwise carries the AAC sound track synthesised "
        "from them (checked on each run: the benchmark stops if a recording lacks either). "
        "`share of bare` = frames/s relative to the bare render loop (step + render + read-back, no effects, "
        "no sound, no writer), measured in the same process: the median over rounds of each run's frames/s "
        "divided by the bare loop's in the same round, and the worst round; `share of own loop` the same against "
        "the loop of the world that is recorded (effects and sound cues on, no writer). "
        "`CPU a frame` = processor time of this process and its ffmpeg (where one runs) together per frame "
        "(world building included), which depends less on other work than the wall time does; on 2 cores "
        "what a recording costs in all is what bounds its speed. The range column shows how much runs varied, "
        "from the slowest run to the fastest: the 2 cores were shared with other work (load average "
        f"{load_start:.1f} at the start, {load_end:.1f} at the end).",
        "",
        table(["output", "frames/s", "range", "share of bare", "share of own loop", "CPU a frame, ms",
               "size per frame"], rows),
        "",
        f"Bar (issue 25): recording with effects and sound at least {RECORD_BAR:g} of the bare render loop "
        f"(median share over rounds): **{'met' if shares[DEFAULT][0] >= RECORD_BAR else 'not met'}** "
        f"({shares[DEFAULT][0]:.2f}; worst round {shares[DEFAULT][1]:.2f}). "
        f"Bar (issue 11): the default MP4 at least {MP4_BAR:g} of its own world's loop: "
        f"**{'met' if own[DEFAULT][0] >= MP4_BAR else 'not met'}** ({own[DEFAULT][0]:.2f}; worst round "
        f"{own[DEFAULT][1]:.2f}). The share moves from run to run with other work "
        "on the machine, both ways: load slows the recording's extra threads, and a quiet machine makes the "
        "bare loop fastest, leaving the least idle CPU beside it. "
        f"In CPU, which load moves less: the bare loop's CPU a frame over the recording's is {cpu_share:.2f}, "
        "the share a recording would keep with all its work in series on one core (its writer thread "
        "overlapping nothing). Where the recording's CPU goes beyond the bare loop, a frame: "
        f"sparks, plume and sound cues {ms_of[LOOP] - ms_of[BARE]:+.1f} ms, the AAC track "
        f"{ms_of[DEFAULT] - ms_of[NO_AUDIO]:+.1f} ms, converting and encoding the video "
        f"{ms_of[NO_AUDIO] - ms_of[LOOP]:+.1f} ms (medians of the rows above; differences of a few tenths "
        "are within the rounds' spread).",
    ])
    body += "\n".join([
        "", "",
        "**Encoder settings against each other.** Each demo's first frames at "
        f"{SIZE[0]}x{SIZE[1]}, converted to NV12 once; each setting encodes the same frames through the "
        "recorder's own encoder (x264 through PyAV, in this process). *x264 CPU a frame* is the processor "
        "time of those encodes (it depends little on other work); *PSNR* is of the luma of the decoded video against the NV12 it was given, mean over "
        "frames (worst frame in brackets). ultrafast + CABAC + deblock at crf 26 was chosen as the cheapest "
        "setting that gives every demo at least the PSNR of the recorder's previous default (veryfast + subme 1, "
        "crf 20); issue 25 added the smaller deadzone and the keyframe every 60 frames against streaks on black "
        "(docs/bench/dark_video.md).",
        "",
        table(["demo", "x264 setting", "x264 CPU a frame, ms", "x CPU of before", "size per frame",
               "x size of before", "luma PSNR, dB"], qrows),
    ])
    write_section(NAME, "Recording throughput", body)
    ctx.release()


#: Encoder settings weighed by :func:`encoder_quality`: (label, preset, crf, x264 tuning or None for the recorder's).
SETTINGS = (
    ("veryfast + subme 1, crf 20 (before)", "veryfast", 20, {"veryfast": {"x264-params": "subme=1"}}),
    ("veryfast, crf 20", "veryfast", 20, {}),
    ("superfast, crf 24", "superfast", 24, {}),
    ("ultrafast, crf 26", "ultrafast", 26, {}),
    ("ultrafast + CABAC + deblock, crf 26 (before issue 25)", "ultrafast", 26,
     {"ultrafast": {"x264-params": "cabac=1:deblock=0,0"}}),
    ("ultrafast + CABAC + deblock + deadzone 6 + keyint 60, crf 26 (default)", "ultrafast", 26, None),
    ("ultrafast + CABAC + deblock + deadzone 6 + keyint 60, crf 30", "ultrafast", 30, None),
)


def _nv12_frames(ctx, demo: str, frames: int) -> list[np.ndarray]:
    from driftframe.app import attach_rendering, make_world
    from driftframe.framework.yuv import rgba_to_nv12

    w, _ = make_world(demo, seed=1)
    attach_rendering(w, ctx, size=SIZE, own_context=False)
    target = w.resources[RenderTarget]
    out = []
    try:
        for _ in range(frames):
            w.step()
            w.render()
            out.append(rgba_to_nv12(target.read_raw(), *SIZE))
    finally:
        w.close()
    return out


def _encode(nv12: list[np.ndarray], path: Path, preset: str, crf: int, tuning) -> tuple[float, int]:
    """x264 CPU seconds a frame and bytes, through the recorder's own encoder (in this process)."""
    with _swapped(X264_TUNING=tuning):
        c0 = resource.getrusage(resource.RUSAGE_SELF)
        sink = record_sinks._H264Sink(path, SIZE, 60, crf=crf, preset=preset, pixel_format="nv12")
        for f in nv12:
            sink.write(f)
        sink.finish()
        c1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (c1.ru_utime + c1.ru_stime - c0.ru_utime - c0.ru_stime) / len(nv12)
    return cpu, path.stat().st_size


def _luma_psnr(nv12: list[np.ndarray], path: Path) -> tuple[float, float]:
    import av

    w, h = SIZE
    with av.open(str(path)) as video:                  # FFmpeg's H.264 decoder; the luma plane as it is
        dec = np.stack([f.to_ndarray(format="nv12")[:h] for f in video.decode(video=0)])
    if len(dec) != len(nv12):
        raise SystemExit(f"{path.name}: decoded {len(dec)} frames, encoded {len(nv12)}")
    src = np.stack(nv12)[:, :w * h].reshape(-1, h, w).astype(np.float32)
    mse = ((src - dec) ** 2).mean(axis=(1, 2))
    psnr = 10 * np.log10(255.0 ** 2 / np.maximum(mse, 1e-10))
    return float(psnr.mean()), float(psnr.min())


def encoder_quality(ctx, frames: int) -> tuple[list[list], list[tuple]]:
    """Table rows, and (demo, setting, x264 ms a frame, mean PSNR, bytes a frame) for the chart."""
    rows, points = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for demo in ("asteroids", "swarm", "billiards"):
            nv12 = _nv12_frames(ctx, demo, frames)
            base = None
            for label, preset, crf, tuning in SETTINGS:
                path = Path(tmp) / f"{demo}.mp4"
                # CPU: the best of 3 encodes (a busy spell only adds); bytes and pictures are the same each time
                cpu = min(_encode(nv12, path, preset, crf, tuning)[0] for _ in range(3))
                size = path.stat().st_size / frames
                mean, worst = _luma_psnr(nv12, path)
                base = base or (cpu, size)
                rows.append([demo, label, f"{cpu * 1e3:.2f}", f"{cpu / base[0]:.2f}", f"{size / 1024:.2f} KiB",
                             f"{size / base[1]:.2f}", f"{mean:.1f} ({worst:.1f})"])
                points.append((demo, label, cpu * 1e3, mean, size))
                print(f"{demo:>10} {label:>48}: x264 {cpu * 1e3:5.2f} ms a frame, {size / 1024:6.2f} KiB, "
                      f"PSNR {mean:.1f} ({worst:.1f}) dB")
    return rows, points


if __name__ == "__main__":
    main()
