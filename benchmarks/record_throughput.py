"""How fast does recording go: frames written per second to MP4, GIF and PNGs, beside bare render + read-back?

The scene is the demo's: a ship flying through 50 drifting, spinning
asteroids (50 scaled variants of one sphere), chase camera, skybox, at
1280x720. Each run builds a fresh world and records ``F`` frames with
:func:`framework.recorder.record` (one fixed step per frame); the time
includes finishing the file (ffmpeg's last frames, the GIF's write). The
baseline is the same loop with no writer: ``world.step()``,
``world.render()``, RGBA read-back. ffmpeg encodes in its own process and a
writer thread feeds it, so encoding overlaps rendering; on 2 cores they
compete for the same CPUs.

    python -m benchmarks.record_throughput [--quick]
"""
from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import figure, parser, save_chart, table, write_section
from components.body import AngularVelocity, Transform, Velocity
from components.camera import Camera
from components.render import ModelRef
from framework import frame as fr
from framework.gl import create_context, renderer
from framework.recorder import record
from framework.world import World
from systems.movement import MovementSystem
from systems.render import attach
from systems.spin import SpinSystem

NAME = "record_throughput"
SIZE = (1280, 720)


def build(ctx, seed: int = 3) -> World:
    """The demo-like scene: ship at 4 m/s through 50 asteroids within 60 m, chase camera."""
    w = World()
    w.add_system(MovementSystem())
    w.add_system(SpinSystem())
    ship = w.create_entity(Transform((0.0, 0.0, -20.0)), Velocity((0.5, 0.2, 4.0)), ModelRef("ship"))
    w.create_entity(Camera(target=ship, mode="chase"))
    attach(w, ctx, SIZE)
    cache = w.resources["model_cache"]
    rng = np.random.default_rng(seed)
    n = 50
    for k, r in enumerate(rng.uniform(1.0, 5.0, n)):
        cache.variant(f"asteroid_{k}", "sphere", scale=float(r))
    w.create_entities(
        Transform.bulk(n, position=rng.uniform(-60.0, 60.0, (n, 3)),
                       orientation=fr.quat_from_rotvec(rng.normal(0.0, 1.0, (n, 3)))),
        Velocity.bulk(n, linear=rng.normal(0.0, 1.0, (n, 3))),
        AngularVelocity.bulk(n, angular=rng.normal(0.0, 0.5, (n, 3))),
        [ModelRef(f"asteroid_{k}") for k in range(n)])
    return w


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


def recorded(ctx, frames: int, path: Path, **kw) -> tuple[float, int]:
    """Frames per second of a whole recording, and the bytes written."""
    w = build(ctx)
    w.step()
    w.render()                                      # warm-up, as for the baseline
    res = record(w, path, frames=frames, progress=False, **kw)
    w.close()
    size = sum(f.stat().st_size for f in path.iterdir()) if path.is_dir() else path.stat().st_size
    return res.frames / res.seconds, size


def main(argv=None) -> None:
    args = parser(__doc__.splitlines()[0]).parse_args(argv)
    frames = 20 if args.quick else 120
    repeats = 1 if args.quick else 3
    ctx = create_context()
    modes = {
        "render + read-back (no writer)": None,
        "MP4, H.264 preset veryfast, crf 20 (default)": ("clip.mp4", {}),
        "MP4, H.264 preset medium, crf 20": ("clip.mp4", {"preset": "medium"}),
        "GIF, 640x360": ("clip.gif", {}),
        "PNG frames (zlib level 1)": ("frames", {}),
    }
    rows, fps_of = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        base = statistics.median(bare(ctx, frames) for _ in range(repeats))
        fps_of["render + read-back (no writer)"] = base
        rows.append(["render + read-back (no writer)", base, 1.0, "-"])
        print(f"{'render + read-back':>36}: {base:6.1f} frames/s")
        for label, spec in modes.items():
            if spec is None:
                continue
            name, kw = spec
            runs = []
            for k in range(repeats):
                runs.append(recorded(ctx, frames, Path(tmp) / f"{k}_{name}", **kw))
            fps = statistics.median(r[0] for r in runs)
            per_frame = statistics.median(r[1] for r in runs) / frames
            fps_of[label] = fps
            rows.append([label, fps, fps / base, f"{per_frame / 1024:.1f} KiB"])
            print(f"{label:>36}: {fps:6.1f} frames/s  ({fps / base:.2f} of bare)  {per_frame / 1024:.1f} KiB/frame")

    fig, ax = figure(figsize=(8, 3.8))
    labels = list(fps_of)
    ax.barh(range(len(labels)), [fps_of[k] for k in labels], color=["grey"] + ["C0"] * (len(labels) - 1))
    ax.set_yticks(range(len(labels)), labels, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel(f"frames per second written (median of {repeats} x {frames} frames)")
    ax.set_title(f"Recording at {SIZE[0]}x{SIZE[1]}, 50 asteroids, {renderer(ctx).split(' (')[0]}")
    for i, k in enumerate(labels):
        ax.text(fps_of[k], i, f" {fps_of[k]:.1f}", va="center", fontsize=8)
    save_chart(fig, NAME)
    body = "\n".join([
        f"{frames} frames per run, median of {repeats} runs, a fresh world each run; the recording time "
        "includes finishing the file. `share` = frames/s relative to the bare render + read-back loop "
        "measured in the same process.",
        "",
        table(["output", "frames/s", "share of bare", "size per frame"], rows),
    ])
    write_section(NAME, "Recording throughput", body)
    ctx.release()


if __name__ == "__main__":
    main()
