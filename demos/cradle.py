"""cradle — Newton's cradle: five touching balls struck by a sixth; only the last one leaves."""
import numpy as np

from driftframe.demos.parts import balls, viewpoint
from driftframe.framework.input import Track

TITLE = "Newton's cradle"
DESCRIPTION = "five touching balls and a striker: the impulse passes through and only the last ball leaves"
SEEDED = False     # build() draws nothing from rng: every seed gives the same scene (the CLI says so)
SECONDS = 5.0
SCRIPT = Track(())
R = 0.5


def build(world, rng):
    row = np.array([(2 * R * k, 0.0, 0.0) for k in range(5)])
    balls(world, row, np.zeros_like(row), R, colour=(0.8, 0.8, 0.85))
    balls(world, [(-4.0, 0.0, 0.0)], [(3.0, 0.0, 0.0)], R, colour=(0.95, 0.75, 0.2), model="sphere")
    viewpoint(world, (4.0, 2.0, -14.0), (4.0, 0.0, 0.0), fov=50.0)
