"""billiards — a break: the cue ball into a triangle of fifteen touching balls, on a table, seen from overhead."""
import numpy as np

from driftframe.components.body import Transform
from driftframe.components.camera import Camera
from driftframe.components.render import ModelRef
from driftframe.demos.parts import balls
from driftframe.framework.input import Track
from driftframe.framework.model_cache import declare_variant

TITLE = "Billiards"
DESCRIPTION = "a perfectly elastic break: cue ball into a 15-ball triangle, on a table, overhead camera"
SEEDED = False     # build() draws nothing from rng: every seed gives the same scene (the CLI says so)
SECONDS = 6.0
SCRIPT = Track(())
R = 0.5            # ball radius, m
SPEED = 12.0       # cue ball speed, m/s
TABLE = (28.0, 15.0)   # felt, x by z, m: the overhead view's width; no friction, so balls roll off it in the end


def rack(radius: float = R) -> np.ndarray:
    """Centres of a 15-ball triangle of touching balls, apex at the origin, opening along +x (y = 0 plane)."""
    rows = []
    for row in range(5):
        for k in range(row + 1):
            rows.append((row * radius * np.sqrt(3), 0.0, (k - row / 2) * 2 * radius))
    return np.array(rows)


def build(world, rng):
    triangle = rack()
    balls(world, triangle, np.zeros_like(triangle), R, colour=(0.85, 0.2, 0.15))
    balls(world, [(-8.0, 0.0, 0.0)], [(SPEED, 0.0, 0.0)], R, colour=(0.95, 0.95, 0.92), model="sphere")
    # the table: a felt slab whose top is where the balls touch it (y = -R), on a wider wooden frame
    felt = declare_variant(world, "felt", "box", scale=(TABLE[0], 0.2, TABLE[1]), colour=(0.08, 0.42, 0.2))
    frame = declare_variant(world, "table_frame", "box", scale=(TABLE[0] + 1.6, 0.6, TABLE[1] + 1.6),
                            colour=(0.36, 0.2, 0.1))
    table = world.create_entity(Transform((1.5, -R - 0.1, 0.0)), ModelRef(felt))
    world.create_entity(Transform((1.5, -R - 0.31, 0.0)), ModelRef(frame))
    # overhead: 16 m straight above the table's centre, +x (the break's direction) to the right of the picture
    world.create_entity(Camera(target=table, mode="overhead", overhead_height=16.0 + R + 0.1,
                               overhead_up=(0.0, 0.0, 1.0), cycle=("overhead",), fov=55.0))
