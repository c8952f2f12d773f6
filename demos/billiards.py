"""billiards — a break: the cue ball into a triangle of fifteen touching balls, seen from above."""
import numpy as np

from driftframe.demos.parts import balls, viewpoint
from driftframe.framework.input import Track

TITLE = "Billiards"
DESCRIPTION = "a perfectly elastic break: cue ball into a 15-ball triangle, seen from above"
SECONDS = 6.0
SCRIPT = Track(())
R = 0.5            # ball radius, m
SPEED = 12.0       # cue ball speed, m/s


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
    viewpoint(world, (0.5, 16.0, 0.0), (0.5, 0.0, 0.0), up=(0.0, 0.0, 1.0), fov=55.0)
