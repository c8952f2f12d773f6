"""How fast does recording go: frames written per second to MP4, GIF and PNGs, beside bare render + read-back?

The scene is the ``asteroids`` demo exactly as ``driftframe record`` runs it
(scripted flight through 50 scaled asteroids, collisions, chase and cockpit
cameras, skybox, HUD) at 1280x720. Each run builds a fresh world and records ``F`` frames with
:func:`framework.recorder.record` (one fixed step per frame); the time
includes finishing the file (ffmpeg's last frames, the GIF's trailer). The
baseline is the same loop with no writer: ``world.step()``,
``world.render()``, RGBA read-back. ffmpeg encodes in its own process and a
writer thread feeds it, so encoding overlaps rendering; on 2 cores they
compete for the same CPUs, so what counts is the CPU each frame costs in
all. The default MP4 path pipes RGBA to ffmpeg (which flips, converts and
encodes) with x264 veryfast and subme 1; beside it: the NV12 conversion in a
shader (`gpu_yuv=True`: ffmpeg only encodes; it helped only while other work
loaded the machine), x264 veryfast alone (the recorder before subme 1), the
medium preset, motion blur, GIF and PNG frames.

    python -m benchmarks.record_throughput [--quick]
"""
from __future__ import annotations

import os
import resource
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import figure, parser, save_chart, table, write_section
from driftframe.components.body import AngularVelocity, Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.render import ModelRef
from driftframe.framework import frame as fr
from driftframe.framework.gl import create_context, renderer
from driftframe.framework.recorder import record
from driftframe.framework.world import World
from driftframe.systems.movement import MovementSystem
from driftframe.systems.render import attach
from driftframe.systems.spin import SpinSystem

NAME = "record_throughput"
SIZE = (1280, 720)


def build(ctx, seed: int = 1) -> World:
    """The ``asteroids`` demo as ``driftframe record`` runs it (scripted flight, HUD), rendering attached.

    Falls back to a similar hand-built scene (ship through 50 drifting,
    spinning asteroids, chase camera) if the demo modules are not there.
    """
    try:
        from driftframe.app import attach_rendering, make_world
    except ImportError:
        return _fallback(ctx, seed)
    w, _ = make_world("asteroids", seed=seed)
    attach_rendering(w, ctx, size=SIZE, own_context=False)
    return w


def _fallback(ctx, seed: int) -> World:
    w = World()
    w.add_system(MovementSystem())
    w.add_system(SpinSystem())
    ship = w.create_entity(Transform((0.0, 0.0, -20.0)), Velocity((0.5, 0.2, 4.0)), ModelRef("ship"))
    w.create_entity(Camera(target=ship, mode="chase"))
    attach(w, ctx, SIZE)
    cache = w.resources["model_cache"]
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
    """User + system time of this process and of its finished children (ffmpeg)."""
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def bare(ctx, frames: int) -> float:
    """Frames per second of step + render + read-back, no writer."""
    w = build(ctx)
    target = w.resources["render_target"]
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


def recorded(ctx, frames: int, path, **kw) -> tuple[float, int]:
    """Frames per second of a whole recording, and the bytes written.

    ``_tuning``: x264 settings beyond the preset to use instead of the
    recorder's (``{}``: the preset alone, as before they were added).
    """
    from driftframe.framework import recorder
    from driftframe.systems.motion_blur import SubframePoses

    tuning = kw.pop("_tuning", None)
    if kw.get("motion_blur", 1) > 1:
        kw["interpolate"] = SubframePoses()
    w = build(ctx)
    w.step()
    w.render()                                      # warm-up, as for the baseline
    saved = recorder.X264_TUNING
    if tuning is not None:
        recorder.X264_TUNING = tuning
    try:
        res = record(w, path, frames=frames, progress=False, **kw)
    finally:
        recorder.X264_TUNING = saved
        w.close()
    path = Path(path)
    size = sum(f.stat().st_size for f in path.iterdir()) if path.is_dir() else path.stat().st_size
    return res.frames / res.seconds, size


def main(argv=None) -> None:
    args = parser(__doc__.splitlines()[0]).parse_args(argv)
    frames = 20 if args.quick else 240
    repeats = 1 if args.quick else 5
    ctx = create_context()
    modes = {
        "step + render + read-back (no writer)": None,
        "MP4 (default): RGBA piped, ffmpeg converts, x264 veryfast + subme 1": ("clip.mp4", {}),
        "MP4: NV12 from a shader (gpu_yuv), x264 veryfast + subme 1": ("clip.mp4", {"gpu_yuv": True}),
        "MP4 as before: RGBA piped, ffmpeg converts, x264 veryfast": ("clip.mp4", {"gpu_yuv": False,
                                                                           "_tuning": {}}),
        "MP4, preset medium": ("clip.mp4", {"preset": "medium"}),
        "MP4, --motion-blur 4": ("clip.mp4", {"motion_blur": 4}),
        "GIF, 640x360 (streamed)": ("clip.gif", {}),
        "PNG frames (zlib level 1)": ("frames/", {}),
    }
    rows, fps_of = [], {}
    samples: dict[str, list] = {label: [] for label in modes}
    cpu: dict[str, list] = {label: [] for label in modes}
    load_start = os.getloadavg()[0]
    bare_label = "step + render + read-back (no writer)"
    with tempfile.TemporaryDirectory() as tmp:
        # interleaved: each round runs every mode once, so a busy spell on the machine hits all of them
        for k in range(repeats):
            for m, (label, spec) in enumerate(modes.items()):
                c0 = _cpu_seconds()
                if spec is None:
                    samples[label].append((bare(ctx, frames), 0))
                else:
                    name, kw = spec
                    samples[label].append(recorded(ctx, frames, f"{tmp}/{k}_{m}_{name}",
                                                   **dict(kw)))
                cpu[label].append((_cpu_seconds() - c0) / frames * 1e3)
    base = statistics.median(s[0] for s in samples[bare_label])
    for label, runs in samples.items():
        fps = statistics.median(r[0] for r in runs)
        fps_of[label] = fps
        spread = f"{min(r[0] for r in runs):.1f}-{max(r[0] for r in runs):.1f}"
        # each run against the bare loop of its own round: a busy spell slows both
        paired = [r[0] / b[0] for r, b in zip(runs, samples[bare_label])]
        share = f"{statistics.median(paired):.2f} (worst {min(paired):.2f})"
        ms = f"{statistics.median(cpu[label]):.1f}"
        if modes[label] is None:
            rows.append([label, fps, spread, "1", ms, "-"])
        else:
            per_frame = statistics.median(r[1] for r in runs) / frames
            rows.append([label, fps, spread, share, ms, f"{per_frame / 1024:.2f} KiB"])
        print(f"{label:>60}: {fps:6.1f} frames/s  ({share} of bare, {ms} ms CPU a frame)")

    fig, ax = figure(figsize=(8, 3.8))
    labels = list(fps_of)
    ax.barh(range(len(labels)), [fps_of[k] for k in labels], color=["grey"] + ["C0"] * (len(labels) - 1))
    ax.set_yticks(range(len(labels)), labels, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel(f"frames per second written (median of {repeats} x {frames} frames)")
    ax.set_title(f"Recording the asteroids demo at {SIZE[0]}x{SIZE[1]}, {renderer(ctx).split(' (')[0]}")
    for i, k in enumerate(labels):
        ax.text(fps_of[k], i, f" {fps_of[k]:.1f}", va="center", fontsize=8)
    save_chart(fig, NAME)
    body = "\n".join([
        f"{frames} frames (the first {frames / 60:g} s of the demo) per run, median of {repeats} interleaved "
        "runs, a fresh world each run; the recording time includes finishing the file. Every mode steps the "
        "simulation (collisions included) and draws the HUD. `share of bare` = frames/s relative to the "
        "step + render + read-back loop with no writer, measured in the same process: the median over rounds "
        "of each run's frames/s divided by the bare loop's in the same round, and the worst round. `CPU a frame` "
        "= processor time of this process and ffmpeg together per frame (world building included), which "
        "depends less on other work than the wall time does; on 2 cores what a recording costs in all is what "
        "bounds its speed. The range column shows how much runs varied, from the slowest run to the fastest: "
        f"the 2 cores were shared with other work (load average {load_start:.1f} at the start, "
        f"{os.getloadavg()[0]:.1f} at the end).",
        "",
        table(["output", "frames/s", "range", "share of bare", "CPU a frame, ms", "size per frame"], rows),
    ])
    write_section(NAME, "Recording throughput", body)
    ctx.release()


if __name__ == "__main__":
    main()
