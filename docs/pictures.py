"""Remake the README's demo previews (docs/img/demo-<name>.gif), stills (docs/img/still-<name>.png) and the
before/after picture of the look (docs/img/look-before-after.png).

    .venv/bin/python docs/pictures.py            # all demos, and the before/after picture
    .venv/bin/python docs/pictures.py cradle     # one

Previews go through the recorder (as ``driftframe record`` would write them);
stills are single frames at the moments listed in :data:`STILLS`, chosen to
show what each demo is for, each with the demo's own sky (None) unless it says.
"""
from __future__ import annotations

import sys
from pathlib import Path

from PIL import Image

from driftframe import demos
from driftframe.app import attach_rendering, make_world
from driftframe.framework.model_cache import ModelVariants
from driftframe.framework.recorder import record

ROOT = Path(__file__).resolve().parent.parent
IMG = ROOT / "docs" / "img"

SIZE = (320, 180)
FPS = 12                     # 60 Hz simulation: 5 steps per frame
MAX_SECONDS = 8.0
STILL_SIZE = (640, 360)
#: demo -> ((seconds into the demo, sky, file suffix), ...): what each still shows
STILLS = {
    "rotation": ((8.5, None, ""),),                        # a roll while drifting among the beacons (lines)
    "spin": ((3.9, None, ""),),                            # a roll with some yaw: the tilted spin axis
    "asteroids": ((4.8, None, ""),                         # drifting side-on into the cluster: the chase view
                  (9.1, None, "-impact")),                 #   looks where the ship goes; the pebble hit
    "billiards": ((1.4, None, ""),),                       # just after the break, between the cushions
    "cradle": ((1.1, None, ""),),                          # just after the striker's hit: sparks where it landed
    "swarm": ((5.0, None, ""),),                           # against the light: the hemisphere fill
    "orbit": ((120.0, None, ""),),                         # closing on the station, the planet beside
}
#: The before/after picture: asteroids at this moment, the articles' look (spheres, the green line cube, no
#: effects) on the left, today's (rocks, the starfield, sparks) on the right.
BEFORE_AFTER = ("asteroids", 9.1)


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


def before_after() -> Path:
    """One picture: the same frame in the articles' look and in today's, side by side."""
    name, seconds = BEFORE_AFTER
    frames = []
    for old in (True, False):
        world, demo = make_world(name, seed=0)
        try:
            if old:                    # every rock variant back on the sphere, as the articles drew them
                variants = world.resources[ModelVariants]
                for key, (base, scale, colour) in list(variants.items()):
                    if base.startswith("rock"):
                        variants[key] = ("sphere", scale, colour)
            render = attach_rendering(world, size=STILL_SIZE, sky="lines" if old else None, effects=not old)
            world.step(round(seconds / world.dt))
            world.render()
            frames.append(Image.fromarray(render.read_rgba()[..., :3]))
        finally:
            world.close()
    w, h = STILL_SIZE
    out_img = Image.new("RGB", (2 * w + 8, h), (255, 255, 255))
    out_img.paste(frames[0], (0, 0))
    out_img.paste(frames[1], (w + 8, 0))
    out = IMG / "look-before-after.png"
    out_img.save(out, optimize=True)
    print(f"{out.relative_to(ROOT)}: {name} at {seconds:g} s, before | after")
    return out


if __name__ == "__main__":
    for n in sys.argv[1:] or demos.NAMES:
        picture(n)
        stills(n)
    if not sys.argv[1:]:
        before_after()
