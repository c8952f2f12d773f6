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


# -- the worst cases of issue 24 (scenes the project had not seen), one function per class ------------------
def struck_crystal(n_side: int = 8, r: float = 0.5, speed: float = 5.0):
    """A touching FCC crystal at rest (``4 n_side^3`` spheres, each touching its 12 neighbours), struck
    once on a face by one more sphere, 0.005 r off it, at ``speed`` m/s: the impulse spreads through
    the whole island within the step it lands (tens of thousands of contacts)."""
    x, _, _, _, _ = crystal("fcc", n_side, r=r, speed=0.0)
    k = int(np.argmin(x[:, 0]))
    striker = x[k] - np.array([2 * r * 1.005, 0.0, 0.0])
    x = np.concatenate([x, striker[None]])
    v = np.zeros_like(x)
    v[-1] = (speed, 0.0, 0.0)
    return x, v, np.full(len(x), r), np.ones(len(x)), np.ones(len(x))


def fast_movers(n: int = 2000, n_fast: int = 5, speed: float = 300.0, seed: int = 0):
    """A slow field (:func:`field`, ``n`` bodies at 5 %, 1 m/s) crossed by ``n_fast`` of its own bodies
    sent through its centre at ``speed`` m/s (hundreds of m/s: tens of radii a step)."""
    x, v, r, m, e = field(n, 0.05, seed=seed, speed=1.0)
    centre = x.mean(axis=0)
    rng = np.random.default_rng(seed + 1)
    for k in rng.choice(n, n_fast, replace=False):
        d = centre - x[k]
        v[k] = speed * d / np.linalg.norm(d)
    return x, v, r, m, e


def jammed_clump(n_side: int = 8, r: float = 0.5, speed: float = 20.0, seed: int = 0):
    """A jammed clump: a touching FCC crystal (``4 n_side^3`` spheres, 12 neighbours each) whose spheres
    jostle at up to 0.1 m/s, hit by one fast sphere (``speed`` m/s) 0.01 r from a face ball: tens of
    thousands of contacts in the first step."""
    x, v, rad, m, e = crystal("fcc", n_side, seed=seed, r=r, speed=0.1)
    lo = x[np.argmin(x[:, 0])]
    striker = lo - np.array([2 * r * 1.005, 0.0, 0.0])
    x = np.concatenate([x, striker[None]])
    v = np.concatenate([v, [[speed, 0.0, 0.0]]])
    return x, v, np.full(len(x), r), np.ones(len(x)), np.ones(len(x))


def mixed_sizes(n: int = 4000, ratio: float = 300.0, seed: int = 0, r_small: float = 0.1):
    """One large sphere (radius ``ratio * r_small``) among ``n`` small ones at 5 % of the free volume,
    moving at 1 m/s; the large one drifts through them at 2 m/s."""
    rng = np.random.default_rng(seed)
    big = ratio * r_small
    r = np.full(n + 1, r_small)
    r[0] = big
    side = ((4 / 3 * np.pi * (r[1:] ** 3).sum() / 0.05) + (2 * big) ** 3) ** (1 / 3)
    x = placement.place(rng, r, placement.in_box((0, 0, 0), (side, side, side)))
    v = rng.uniform(-1, 1, (n + 1, 3))
    v[0] = (2.0, 0.0, 0.0)
    return x, v, r, r ** 3 / r_small ** 3, np.ones(n + 1)


def tunnel_sweep(n: int = 20, speed: float = 200.0):
    """A small fast sphere (r 0.1 m, ``speed`` m/s: 33 m a step) sent down a line of ``n`` spheres at rest,
    1 m apart, off their centres by half a radius: it hits the first and the rest follow."""
    x = np.zeros((n + 1, 3))
    x[1:, 0] = 5.0 + np.arange(n) * 1.0
    x[0] = (0.0, 0.2, 0.0)
    v = np.zeros((n + 1, 3))
    v[0] = (speed, 0.0, 0.0)
    r = np.full(n + 1, 0.3)
    r[0] = 0.1
    return x, v, r, np.ones(n + 1), np.ones(n + 1)


def grazing_pairs(n_pairs: int = 10, speed: float = 5.0):
    """``n_pairs`` head-on pairs whose paths pass 1e-9 of a diameter apart (a near miss: never a contact)
    and as many that just touch (a graze), 10 m apart from each other."""
    x, v = [], []
    for k in range(n_pairs):
        gap = 1.0 + (1e-9 if k % 2 else -1e-6)           # centres' closest distance / (r_a + r_b)
        y = 10.0 * k
        x += [(-3.0, y, 0.0), (3.0, y + gap, 0.0)]
        v += [(speed, 0.0, 0.0), (-speed, 0.0, 0.0)]
    n = 2 * n_pairs
    return np.array(x), np.array(v, float), np.full(n, 0.5), np.ones(n), np.ones(n)
