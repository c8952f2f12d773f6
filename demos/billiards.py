"""billiards — a break: the cue ball into a triangle of fifteen touching balls, on a table with cushions, from above."""
import numpy as np

from driftframe.components.body import Transform
from driftframe.components.camera import Camera
from driftframe.components.collision import SphereCollider
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
#: The cushions: rows of fixed spheres (a collider without a Velocity is immovable) of radius CUSHION_R m,
#: SPACING m apart, just outside the felt, so that only a sliver of each stands over the table's edge: the
#: rail is flat to within CUSHION_R - sqrt(CUSHION_R^2 - SPACING^2 / 4) = 5 mm, and a ball bounces off it
#: elastically (e = 1) like any contact, continuous and order-independent.
CUSHION_R, SPACING = 4.0, 0.4
#: The break's angle varies with the seed: the cue ball's heading is turned by up to this, degrees.
BREAK_SPREAD = 1.5


def rack(radius: float = R) -> np.ndarray:
    """Centres of a 15-ball triangle of touching balls, apex at the origin, opening along +x (y = 0 plane)."""
    rows = []
    for row in range(5):
        for k in range(row + 1):
            rows.append((row * radius * np.sqrt(3), 0.0, (k - row / 2) * 2 * radius))
    return np.array(rows)


def cushion_centres() -> np.ndarray:
    """Centres of the cushions' fixed spheres: four rows, each sphere's inner surface on the felt's edge."""
    hx, hz = TABLE[0] / 2, TABLE[1] / 2
    cx, cz = CENTRE
    xs = cx + np.arange(-hx, hx + 1e-9, SPACING)
    zs = cz + np.arange(-hz, hz + 1e-9, SPACING)
    rows = [np.column_stack([xs, np.zeros_like(xs), np.full_like(xs, cz + side * (hz + CUSHION_R))]) for side in (-1, 1)]
    rows += [np.column_stack([np.full_like(zs, cx + side * (hx + CUSHION_R)), np.zeros_like(zs), zs]) for side in (-1, 1)]
    return np.vstack(rows)


def build(world, rng):
    triangle = rack()
    balls(world, triangle, np.zeros_like(triangle), R, colour=(0.85, 0.2, 0.15))
    angle = np.radians(rng.uniform(-BREAK_SPREAD, BREAK_SPREAD))
    balls(world, [(-8.0, 0.0, 0.0)], [(SPEED * np.cos(angle), 0.0, SPEED * np.sin(angle))], R,
          colour=(0.95, 0.95, 0.92), model="sphere")
    centres = cushion_centres()
    world.create_entities(Transform.bulk(len(centres), position=centres),
                          SphereCollider.bulk(len(centres), radius=np.full(len(centres), CUSHION_R)))
    # what the cushions look like: four rails over the felt's edges (the spheres themselves are not drawn)
    # (their tops 0.65 of a ball's height above the felt, as a table's cushions are)
    for name, size, at in (("rail_x", (TABLE[0] + 1.6, 0.65, 0.8), [(0.0, 1.0), (0.0, -1.0)]),
                           ("rail_z", (0.8, 0.65, TABLE[1]), [(1.0, 0.0), (-1.0, 0.0)])):
        rail = declare_variant(world, name, "box", scale=size, colour=(0.05, 0.3, 0.14))
        for sx, sz in at:
            world.create_entity(Transform((CENTRE[0] + sx * (TABLE[0] / 2 + 0.4), -R + 0.325,
                                           CENTRE[1] + sz * (TABLE[1] / 2 + 0.4))), ModelRef(rail))
    # the table: a felt slab whose top is where the balls touch it (y = -R), on a wider wooden frame
    felt = declare_variant(world, "felt", "box", scale=(TABLE[0], 0.2, TABLE[1]), colour=(0.08, 0.42, 0.2))
    frame = declare_variant(world, "table_frame", "box", scale=(TABLE[0] + 1.6, 0.6, TABLE[1] + 1.6),
                            colour=(0.36, 0.2, 0.1))
    table = world.create_entity(Transform((CENTRE[0], -R - 0.1, CENTRE[1])), ModelRef(felt))
    world.create_entity(Transform((CENTRE[0], -R - 0.31, CENTRE[1])), ModelRef(frame))
    # overhead: 16 m straight above the table's centre, +x (the break's direction) to the right of the picture
    world.create_entity(Camera(target=table, mode="overhead", overhead_height=16.0 + R + 0.1,
                               overhead_up=(0.0, 0.0, 1.0), cycle=("overhead",), fov=55.0))
