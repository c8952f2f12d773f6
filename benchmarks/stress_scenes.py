"""Scenes of benchmarks/collision_stress.py (also used by tests/test_collision_bounds.py, smaller).

Each returns ``(x, v, r, m, e)`` arrays: positions (n, 3) m, velocities (n, 3) m/s, radii (n,) m,
masses (n,) kg (inf = immovable), restitution (n,).
"""
from __future__ import annotations

import math

import numpy as np

from driftframe.framework import placement


def gas(n: int, fraction: float, seed: int = 0, speed: float = 1.0, r: float = 0.5):
    """n equal spheres at a volume fraction, on a jittered cubic lattice (no overlap), random velocities."""
    rng = np.random.default_rng(seed)
    side_n = math.ceil(n ** (1 / 3))
    vol = n * 4 / 3 * math.pi * r ** 3 / fraction
    a = (vol ** (1 / 3)) / side_n                          # lattice spacing
    if a < 2 * r:
        raise ValueError(f"gas: fraction {fraction} is too dense for a cubic lattice")
    g = np.stack(np.meshgrid(*[np.arange(side_n)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n] * a
    x = g + rng.uniform(-1, 1, (n, 3)) * (0.5 * a - r) * 0.999
    v = rng.uniform(-1, 1, (n, 3)) * speed
    return x, v, np.full(n, r), np.ones(n), np.ones(n)


def converging(n: int, e: float, seed: int = 0, r: float = 0.5, speed: float = 5.0):
    """n spheres placed apart in a ball, all moving towards its centre."""
    rng = np.random.default_rng(seed)
    rad = np.full(n, r)
    R = (n * (2.2 * r) ** 3) ** (1 / 3)
    x = placement.place(rng, rad, placement.in_shell(0.0, R), gap=0.05 * r)
    d = np.linalg.norm(x, axis=1, keepdims=True)
    v = -speed * x / np.maximum(d, 1e-9)
    return x, v, rad, np.ones(n), np.full(n, e)


def crystal(kind: str, n_side: int, seed: int = 0, r: float = 0.5, speed: float = 1.0):
    """A touching crystal: simple cubic (n_side^3 spheres) or FCC (4 n_side^3), random velocities."""
    rng = np.random.default_rng(seed)
    g = np.stack(np.meshgrid(*[np.arange(n_side)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(float)
    if kind == "sc":
        x = g * (2 * r)
    elif kind == "fcc":
        a = 2 * r * math.sqrt(2)                           # nearest neighbours a / sqrt(2) = 2 r apart
        basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
        x = ((g[:, None, :] + basis[None]) * a).reshape(-1, 3)
    else:
        raise ValueError(kind)
    n = len(x)
    v = rng.uniform(-1, 1, (n, 3)) * speed
    return x, v, np.full(n, r), np.ones(n), np.ones(n)


def random_overlapping(n: int, fraction: float = 0.05, seed: int = 0, r: float = 0.5, speed: float = 1.0):
    """n spheres dropped uniformly at random in a cube at a volume fraction (they overlap)."""
    rng = np.random.default_rng(seed)
    side = (n * 4 / 3 * math.pi * r ** 3 / fraction) ** (1 / 3)
    x = rng.uniform(0, side, (n, 3))
    v = rng.uniform(-1, 1, (n, 3)) * speed
    return x, v, np.full(n, r), np.ones(n), np.ones(n)


def field(n: int, fraction: float = 0.05, seed: int = 0, speed: float = 3.0):
    """n spheres of radii 0.25..0.75 m placed apart (placement) at a volume fraction, random velocities."""
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.25, 0.75, n)
    side = ((4 / 3 * np.pi * r ** 3).sum() / fraction) ** (1 / 3)
    x = placement.place(rng, r, placement.in_box((0, 0, 0), (side, side, side)))
    v = rng.uniform(-1, 1, (n, 3)) * speed
    return x, v, r, r ** 3, np.ones(n)


def wedged(idle: int, seed: int = 0):
    """A sphere touching two immovable ones on a line, moving along it, plus ``idle`` bodies at rest far off."""
    rng = np.random.default_rng(seed)
    x = [(-1.0, 0, 0), (0.0, 0, 0), (1.0, 0, 0)]
    v = [(0, 0, 0), (1.0, 0.5, 0), (0, 0, 0)]
    m = [math.inf, 1.0, math.inf]
    if idle:
        side = (idle * 4 / 3 * math.pi * 0.125 / 0.05) ** (1 / 3)
        xi = placement.place(rng, np.full(idle, 0.5), placement.in_box((10, 10, 10), (10 + side,) * 3))
        x = np.concatenate([np.array(x), xi])
        v = np.concatenate([np.array(v, float), np.zeros((idle, 3))])
        m = np.concatenate([m, np.ones(idle)])
    x, v, m = np.asarray(x, float), np.asarray(v, float), np.asarray(m, float)
    return x, v, np.full(len(x), 0.5), m, np.ones(len(x))


def head_on():
    x = np.array([[-2.0, 0, 0], [2.0, 0, 0]])
    v = np.array([[1.0, 0, 0], [-1.0, 0, 0]])
    return x, v, np.full(2, 0.5), np.ones(2), np.ones(2)


def world_of(scene, *, broadphase="auto", **kw):
    """A World with movement + collision and the scene's bodies; returns (world, system, ids)."""
    from driftframe.components.body import Mass, Transform, Velocity
    from driftframe.components.collision import SphereCollider
    from driftframe.framework.world import World
    from driftframe.systems.collision import CollisionSystem
    from driftframe.systems.movement import MovementSystem

    x, v, r, m, e = scene
    n = len(x)
    w = World()
    w.add_system(MovementSystem())
    cs = w.add_system(CollisionSystem(broadphase=broadphase, **kw))
    ids = w.create_entities(Transform.bulk(n, position=x), Velocity.bulk(n, linear=v), Mass.bulk(n, kg=m),
                            SphereCollider.bulk(n, radius=r, restitution=e))
    return w, cs, ids
