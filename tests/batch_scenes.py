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


def die_once(world, rng, marker: str = "", parent: int = 0):
    """In a pool worker (not the process ``parent``), the first time (no ``marker`` file yet): SIGKILL
    this process, as the out-of-memory killer would. Otherwise :func:`box`."""
    import os
    import signal
    if os.getpid() != parent and not os.path.exists(marker):
        open(marker, "w").close()
        os.kill(os.getpid(), signal.SIGKILL)
    box(world, rng)


def in_c_callback(world, rng, seconds: float = 20.0):
    """Python called back from C for ``seconds``, as numba's compiler calls back into Python through
    ctypes: an exception raised in there (a Ctrl-C's KeyboardInterrupt) is printed and dropped by
    ctypes, and C goes on calling back. Then :func:`box`."""
    import ctypes
    import time
    end = time.monotonic() + seconds
    compare = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)

    def cmp(a, b):
        if time.monotonic() < end:
            time.sleep(0.01)
        return 0

    keep = compare(cmp)
    values = (ctypes.c_int * 4096)()
    ctypes.CDLL(None).qsort(values, len(values), ctypes.sizeof(ctypes.c_int), keep)
    box(world, rng)
