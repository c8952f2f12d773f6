"""billiards — a break: the cue ball into a triangle of fifteen touching balls, on a table with cushions (static
boxes), from above."""
import numpy as np

from driftframe.components.body import Transform
from driftframe.components.camera import Camera
from driftframe.components.collision import BoxCollider
from driftframe.components.render import ModelRef
from driftframe.demos.parts import balls
from driftframe.framework.input import Track
from driftframe.framework.model_cache import declare_variant

TITLE = "Billiards"
DESCRIPTION = "a perfectly elastic break: cue ball into a 15-ball triangle, on a table with cushions, from above"
SECONDS = 10.0
SCRIPT = Track(())
R = 0.5            # ball radius, m
SPEED = 12.0       # cue ball speed, m/s
TABLE = (28.0, 15.0)   # felt, x by z, m: the overhead view's width
CENTRE = (1.5, 0.0)    # the felt's centre, x and z, m
#: The cushions: four static boxes (BoxCollider), each the rail that is drawn, its inner face on the felt's
#: edge: RAIL m deep, RAIL_H m high, the long ones running past the corners so that no ball finds a gap.
#: A ball meets a cushion at the exact time of impact, like any contact; e = CUSHION_E (1: elastic).
RAIL, RAIL_H = 0.8, 0.65
CUSHION_E = 1.0
#: The break's angle varies with the seed: the cue ball's heading is turned by up to this, degrees.
BREAK_SPREAD = 1.5


def rack(radius: float = R) -> np.ndarray:
    """Centres of a 15-ball triangle of touching balls, apex at the origin, opening along +x (y = 0 plane)."""
    rows = []
    for row in range(5):
        for k in range(row + 1):
            rows.append((row * radius * np.sqrt(3), 0.0, (k - row / 2) * 2 * radius))
    return np.array(rows)


def cushions() -> list[tuple[tuple, tuple]]:
    """The four cushions as (centre, size) boxes, m: each inner face on the felt's edge, the top
    0.65 of a ball's height above the felt (y = -R), as a table's cushions are."""
    hx, hz = TABLE[0] / 2, TABLE[1] / 2
    cx, cz = CENTRE
    y = -R + RAIL_H / 2
    long = (TABLE[0] + 2 * RAIL, RAIL_H, RAIL)
    short = (RAIL, RAIL_H, TABLE[1])
    return [((cx, y, cz + side * (hz + RAIL / 2)), long) for side in (-1, 1)] + \
           [((cx + side * (hx + RAIL / 2), y, cz), short) for side in (-1, 1)]


def build(world, rng):
    triangle = rack()
    balls(world, triangle, np.zeros_like(triangle), R, colour=(0.85, 0.2, 0.15))
    angle = np.radians(rng.uniform(-BREAK_SPREAD, BREAK_SPREAD))
    balls(world, [(-8.0, 0.0, 0.0)], [(SPEED * np.cos(angle), 0.0, SPEED * np.sin(angle))], R,
          colour=(0.95, 0.95, 0.92), model="sphere")
    # the cushions: what is drawn is what the balls bounce off
    for centre, size in cushions():
        rail = declare_variant(world, "rail_x" if size[0] > size[2] else "rail_z", "box", scale=size,
                               colour=(0.05, 0.3, 0.14))
        world.create_entity(Transform(centre), ModelRef(rail),
                            BoxCollider(half_extents=np.array(size) / 2, restitution=CUSHION_E))
    # the table: a felt slab whose top is where the balls touch it (y = -R), on a wider wooden frame
    felt = declare_variant(world, "felt", "box", scale=(TABLE[0], 0.2, TABLE[1]), colour=(0.08, 0.42, 0.2))
    frame = declare_variant(world, "table_frame", "box", scale=(TABLE[0] + 1.6, 0.6, TABLE[1] + 1.6),
                            colour=(0.36, 0.2, 0.1))
    table = world.create_entity(Transform((CENTRE[0], -R - 0.1, CENTRE[1])), ModelRef(felt))
    world.create_entity(Transform((CENTRE[0], -R - 0.31, CENTRE[1])), ModelRef(frame))
    # overhead: 16 m straight above the table's centre, +x (the break's direction) to the right of the picture
    world.create_entity(Camera(target=table, mode="overhead", overhead_height=16.0 + R + 0.1,
                               overhead_up=(0.0, 0.0, 1.0), cycle=("overhead",), fov=55.0))
