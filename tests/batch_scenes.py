"""Scenes named by import path in tests/test_batch.py (``"batch_scenes:box"``): plain functions
``func(world, rng, **overrides)``, importable by spawned workers too (pytest puts tests/ on sys.path,
and spawn hands sys.path to its children)."""
import numpy as np

from driftframe.demos.parts import balls, viewpoint


def box(world, rng, n: int = 24, speed: float = 4.0, fail: bool = False):
    """``n`` 0.4 m balls on a jittered grid, random velocities: a few contacts in a fraction of a second."""
    if fail:
        raise RuntimeError("box: asked to fail")
    side = int(np.ceil(n ** (1 / 3)))
    grid = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n] * 1.0
    pos = grid + rng.uniform(-0.05, 0.05, (n, 3))
    vel = rng.normal(0.0, speed, (n, 3))
    balls(world, pos, vel, 0.4)
    viewpoint(world, (side / 2, side / 2, -8.0), (side / 2, side / 2, side / 2))


def not_a_function():
    pass


NOT_CALLABLE = 3


def env_probe(world, rng):
    """Fails on purpose, naming the worker's LP_NUM_THREADS: how a test reads a worker's environment."""
    import os
    raise RuntimeError(f"LP_NUM_THREADS={os.environ.get('LP_NUM_THREADS')}")
