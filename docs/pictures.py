"""Remake the README's demo previews (docs/img/demo-<name>.gif) with the recorder.

    .venv/bin/python docs/pictures.py            # all demos
    .venv/bin/python docs/pictures.py cradle     # one
"""
from __future__ import annotations

import sys
from pathlib import Path

from driftframe import demos
from driftframe.app import attach_rendering, make_world
from driftframe.framework.recorder import record

ROOT = Path(__file__).resolve().parent.parent

SIZE = (320, 180)
FPS = 12                     # 60 Hz simulation: 5 steps per frame
MAX_SECONDS = 8.0


def picture(name: str) -> Path:
    world, demo = make_world(name, seed=0)
    try:
        attach_rendering(world, size=SIZE)
        seconds = min(demo.SECONDS, MAX_SECONDS)
        out = ROOT / "docs" / "img" / f"demo-{name}.gif"
        res = record(world, out, frames=int(seconds * FPS), fps=FPS, steps_per_frame=60 // FPS,
                     gif_scale=1.0, progress=False)
    finally:
        world.close()
    print(f"{res.path.relative_to(ROOT)}: {res.frames} frames, {res.path.stat().st_size / 1024:.0f} KiB")
    return res.path


if __name__ == "__main__":
    for n in sys.argv[1:] or demos.NAMES:
        picture(n)
