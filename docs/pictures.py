"""Remake the README's demo previews (docs/img/demo-<name>.gif) and stills (docs/img/still-<name>.png).

    .venv/bin/python docs/pictures.py            # all demos
    .venv/bin/python docs/pictures.py cradle     # one

Previews go through the recorder (as ``driftframe record`` would write them);
stills are single frames at the moments listed in :data:`STILLS`, chosen to
show what each demo is for.
"""
from __future__ import annotations

import sys
from pathlib import Path

from PIL import Image

from driftframe import demos
from driftframe.app import attach_rendering, make_world
from driftframe.framework.recorder import record

ROOT = Path(__file__).resolve().parent.parent
IMG = ROOT / "docs" / "img"

SIZE = (320, 180)
FPS = 12                     # 60 Hz simulation: 5 steps per frame
MAX_SECONDS = 8.0
STILL_SIZE = (640, 360)
#: demo -> ((seconds into the demo, sky, file suffix), ...): what each still shows
STILLS = {
    "rotation": ((8.5, "lines", ""),),                     # a roll while drifting among the beacons
    "spin": ((3.9, "lines", ""),),                         # a roll with some yaw: the tilted spin axis
    "asteroids": ((4.8, "lines", ""),                      # drifting side-on into the cluster: the chase view
                  (19.0, "starfield", "-starfield")),      #   looks where the ship goes; the starfield sky
    "billiards": ((1.4, "lines", ""),),                    # just after the break, on the table, overhead
    "cradle": ((3.0, "lines", ""),),                       # only the last ball has left
    "swarm": ((5.0, "lines", ""),),                        # against the light: the hemisphere fill
    "orbit": ((120.0, "lines", ""),),                      # closing on the station, the planet beside
}


def picture(name: str) -> Path:
    world, demo = make_world(name, seed=0)
    try:
        attach_rendering(world, size=SIZE)
        seconds = min(demo.SECONDS, MAX_SECONDS)
        out = IMG / f"demo-{name}.gif"
        res = record(world, out, frames=int(seconds * FPS), fps=FPS, steps_per_frame=60 // FPS,
                     gif_scale=1.0, progress=False, overwrite=True)
    finally:
        world.close()
    print(f"{res.path.relative_to(ROOT)}: {res.frames} frames, {res.path.stat().st_size / 1024:.0f} KiB")
    return res.path


def stills(name: str) -> list[Path]:
    made = []
    for seconds, sky, suffix in STILLS.get(name, ()):
        world, demo = make_world(name, seed=0)
        try:
            render = attach_rendering(world, size=STILL_SIZE, sky=sky)
            world.step(round(seconds / world.dt))
            world.render()
            out = IMG / f"still-{name}{suffix}.png"
            Image.fromarray(render.read_rgba()[..., :3]).save(out, optimize=True)
        finally:
            world.close()
        print(f"{out.relative_to(ROOT)}: {seconds:g} s, sky {sky}, {out.stat().st_size / 1024:.0f} KiB")
        made.append(out)
    return made


if __name__ == "__main__":
    for n in sys.argv[1:] or demos.NAMES:
        picture(n)
        stills(n)
