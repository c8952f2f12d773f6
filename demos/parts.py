"""Reusable compositions shared by the demos: the player ship, a camera, a fixed viewpoint.

Each returns an entity id; each is only components put together.
"""
from __future__ import annotations

import numpy as np

from driftframe.components.body import Acceleration, AngularVelocity, Mass, Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.collision import SphereCollider
from driftframe.components.control import FlightControl, FlightInput, Player, RotationAssist
from driftframe.components.render import ModelRef
from driftframe.framework import frame as fr
from driftframe.framework import placement
from driftframe.framework.meshes import ROCK_SHAPES


def ship(world, *, mode: str = "momentum", position=(0.0, 0.0, 0.0), forward=(0.0, 0.0, 1.0),
         velocity=(0.0, 0.0, 0.0), thrust: float = 6.0, assist: str = "all", collides: bool = True) -> int:
    """The player's pyramid ship: flight controls, kill-rotation assist, 1 m collision sphere, 10 t."""
    parts = [Player(), Transform(position, fr.look_rotation(forward)), Velocity(velocity), AngularVelocity(),
             Acceleration(), Mass(10_000.0), ModelRef("ship"), FlightInput(),
             FlightControl(mode=mode, thrust=thrust, turn_rate=1.2, angular_accel=1.5),
             RotationAssist(max_decel=2.0, axes=assist)]
    if collides:
        parts.append(SphereCollider(radius=1.0))
    return world.create_entity(*parts)


def chase_camera(world, target: int, mode: str = "chase", **settings) -> int:
    """A camera entity following ``target`` (cockpit or chase; switchable at run time)."""
    return world.create_entity(Camera(target=target, mode=mode, **settings))


def viewpoint(world, position, look_at, up=(0.0, 1.0, 0.0), **settings) -> int:
    """A fixed eye (a body with no velocity) and a cockpit camera on it: for table-top scenes."""
    pos = np.asarray(position, dtype=float)
    eye = world.create_entity(Transform(pos, fr.look_rotation(np.asarray(look_at, float) - pos, up)))
    world.create_entity(Camera(target=eye, mode="cockpit", **settings))
    return eye


def balls(world, positions, velocities, radius: float, *, mass: float = 1.0, colour=None,
          model: str = "sphere") -> list[int]:
    """Equal elastic balls (``model`` scaled to ``radius`` by a declared variant) at ``positions``."""
    from driftframe.framework.model_cache import declare_variant

    n = len(positions)
    name = declare_variant(world, f"{model}_r{radius:g}", model, scale=radius)
    return world.create_entities(
        Transform.bulk(n, position=np.asarray(positions, float)),
        Velocity.bulk(n, linear=np.asarray(velocities, float)),
        Mass.bulk(n, kg=np.full(n, float(mass))),
        SphereCollider.bulk(n, radius=np.full(n, float(radius))),
        [ModelRef(name, colour=colour)] * n)


def asteroid_field(world, rng, n: int, *, inner: float, outer: float, radii=(0.5, 3.0),
                   speed: float = 1.0, spin: float = 0.4, variants: int = 50, density: float = 2000.0,
                   centre=(0.0, 0.0, 0.0), keep_clear=()) -> list[int]:
    """``n`` asteroids in a spherical shell about ``centre`` (m), sizes drawn from ``variants`` scaled rocks.

    Each variant is one of the model cache's four rock shapes scaled to its collision radius:
    the rock lies inside its collision sphere (collisions stay spheres, the rock's bounding one).

    Mass = density * 4/3 pi r^3 (kg); random drift velocity (~``speed`` m/s)
    and spin (~``spin`` rad/s). Asteroids never overlap each other, nor the
    spheres ``keep_clear`` (``((x, y, z), radius), ...``), at spawn.
    """
    from driftframe.framework.model_cache import declare_variant

    sizes = np.sort(rng.uniform(*radii, variants))
    # the look: variant i is rock shape i mod 4, each inside its collision sphere (no draw from rng)
    names = [declare_variant(world, f"asteroid_{i}", f"rock{i % ROCK_SHAPES}", scale=float(r),
                             colour=tuple(np.clip(rng.uniform(0.4, 0.6) * (1 + rng.normal(0, 0.04, 3)), 0, 1))) for i, r in enumerate(sizes)]
    kind = rng.integers(0, variants, n)
    r = sizes[kind]
    clear_at = np.array([c for c, _ in keep_clear], float).reshape(-1, 3)
    clear_r = np.array([cr for _, cr in keep_clear], float)
    pos = placement.place(rng, r, placement.in_shell(inner, outer, centre), gap=0.1,
                          avoid=(clear_at, clear_r))                     # no overlaps at spawn
    vel = rng.normal(0.0, speed / np.sqrt(3), (n, 3))
    w = rng.normal(0.0, spin / np.sqrt(3), (n, 3))
    q = fr.quat_from_rotvec(rng.normal(size=(n, 3)))
    return world.create_entities(
        Transform.bulk(n, position=pos, orientation=q), Velocity.bulk(n, linear=vel),
        AngularVelocity.bulk(n, angular=w), Mass.bulk(n, kg=density * 4 / 3 * np.pi * r ** 3),
        SphereCollider.bulk(n, radius=r), [ModelRef(names[k]) for k in kind])
