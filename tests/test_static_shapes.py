"""A sphere that starts inside a box or behind a plane: reported once, as overlapping spheres are, and
resolved by the same rule (moving deeper: one bounce at once, no jump; moving out: left to leave); the
signed distances the report measures."""
from __future__ import annotations

import math
import warnings

import esper
import numpy as np
import pytest

from driftframe.components.body import Mass, Transform, Velocity
from driftframe.components.collision import BoxCollider, PlaneCollider, SphereCollider
from driftframe.framework import frame as fr
from driftframe.systems.static_step import StaticShapes, signed_distances
from test_static_colliders import hits, pos, systems, vel   # the same scene helpers

DT = 1.0 / 60.0


def ball(world, x, v=None, r=0.5, e=1.0, m=1.0):
    parts = [Transform(x), Mass(m), SphereCollider(r, e)]
    return world.create_entity(*parts, *([] if v is None else [Velocity(v)]))


def overlap_warnings(record):
    return [str(w.message) for w in record if "overlap a static shape" in str(w.message)]


def test_a_sphere_made_inside_a_box_is_reported_and_bounces_at_once_off_the_nearest_face(world):
    systems(world)
    # a slab 4 x 1 x 4 m: the centre (0.3, 0.2, -0.5) is 0.3 m under the top face (y = 0.5), deeper under
    # every other face; it moves down (deeper) and along x
    box = world.create_entity(Transform((0.0, 0.0, 0.0)), BoxCollider(half_extents=(2.0, 0.5, 2.0)))
    b = ball(world, (0.3, 0.2, -0.5), (1.0, -3.0, 0.0), r=0.25)
    seen = hits(world)
    with pytest.warns(RuntimeWarning) as rec:
        world.step()
    (text,) = overlap_warnings(rec)
    assert "1 spheres overlap" in text and f"entity {b} (radius 0.25 m)" in text
    assert f"reaches 0.55 m into box entity {box} (its centre inside)" in text      # 0.25 + 0.3 m
    (ev,) = seen
    assert ev.step_time == 0.0                                  # at once, where the step starts
    np.testing.assert_allclose(ev.normal, (0, -1, 0) if ev.a == b else (0, 1, 0), atol=1e-15)   # from a towards b
    assert ev.impulse == pytest.approx(2 * 3.0, rel=1e-14)     # e = 1, m = 1 kg: the normal part reversed
    np.testing.assert_array_equal(vel(b), (1.0, 3.0, 0.0))
    np.testing.assert_allclose(pos(b), (0.3 + DT, 0.2 + 3.0 * DT, -0.5), rtol=0, atol=1e-15)   # no jump
    with warnings.catch_warnings():
        warnings.simplefilter("error")                          # reported once
        world.step(30)
    assert len(seen) == 1                                       # it leaves through the top face, untouched
    np.testing.assert_array_equal(vel(b), (1.0, 3.0, 0.0))
    assert pos(b)[1] > 0.5 + 0.25


def test_a_sphere_inside_a_box_moving_out_is_left_to_leave(world):
    systems(world)
    world.create_entity(Transform((0.0, 0.0, 0.0)), BoxCollider(half_extents=(2.0, 0.5, 2.0)))
    b = ball(world, (0.0, -0.1, 1.0), (0.0, -2.0, 0.5), r=0.25)    # nearest face: the bottom; moving out of it
    seen = hits(world)
    with pytest.warns(RuntimeWarning, match="its centre inside"):
        world.step(40)
    assert seen == []
    np.testing.assert_array_equal(vel(b), (0.0, -2.0, 0.5))


def test_a_turned_box_takes_its_own_nearest_face(world):
    systems(world)
    # the box turned 90 degrees about z: its local x (the nearest face, 0.2 m thin) lies along world y
    q = fr.quat_from_axis_angle((0.0, 0.0, 1.0), math.pi / 2)
    world.create_entity(Transform((0.0, 0.0, 0.0), q), BoxCollider(half_extents=(0.2, 3.0, 3.0)))
    b = ball(world, (0.5, 0.05, 0.0), (0.0, -1.0, 0.0), r=0.1)
    with pytest.warns(RuntimeWarning, match="its centre inside"):
        world.step()
    np.testing.assert_allclose(vel(b), (0.0, 1.0, 0.0), atol=1e-15)   # reflected about world +y


@pytest.mark.parametrize("into, v_after", [(True, (0.5, 2.0, 0.0)), (False, (0.5, 2.0, 0.0))])
def test_a_sphere_behind_a_plane_bounces_when_moving_deeper_and_leaves_when_moving_out(world, into, v_after):
    systems(world)
    floor = world.create_entity(Transform((0.0, 0.0, 0.0)), PlaneCollider(normal=(0.0, 1.0, 0.0)))
    v = (0.5, -2.0 if into else 2.0, 0.0)
    b = ball(world, (0.0, -1.0, 0.0), v)                          # centre 1 m behind the face
    seen = hits(world)
    with pytest.warns(RuntimeWarning) as rec:
        world.step(60)
    (text,) = overlap_warnings(rec)
    assert f"entity {b} (radius 0.5 m) reaches 1.5 m behind plane entity {floor}" in text
    assert len(seen) == (1 if into else 0)
    np.testing.assert_array_equal(vel(b), v_after)


def test_a_sphere_touching_a_shape_is_not_an_overlap_and_a_resting_one_is_not_checked(world):
    systems(world)
    world.create_entity(Transform((0.0, 0.0, 0.0)), BoxCollider(half_extents=(2.0, 0.5, 2.0)))
    world.create_entity(Transform((0.0, -3.0, 0.0)), PlaneCollider(normal=(0.0, 1.0, 0.0)))
    ball(world, (0.0, 0.75, 0.0), (1.0, 0.0, 0.0), r=0.25)           # on the top face: touching
    ball(world, (5.0, -2.5, 0.0), (1.0, 0.0, 0.0), r=0.5)           # on the plane
    ball(world, (-1.0, 0.0, 0.0), r=0.25)                           # inside, but a fixed obstacle: passes
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        world.step(10)


def test_the_overlap_is_checked_again_after_a_change_of_the_scene(world):
    systems(world)
    wall = world.create_entity(Transform((10.0, 0.0, 0.0)), PlaneCollider(normal=(-1.0, 0.0, 0.0)))
    b = ball(world, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        world.step(2)
    esper.component_for_entity(wall, Transform).position = (0.2, 0.0, 0.0)   # moved onto the ball
    with pytest.warns(RuntimeWarning) as rec:
        world.step()
    (text,) = overlap_warnings(rec)
    assert f"entity {b} (radius 0.5 m)" in text and f"behind plane entity {wall} (its centre outside)" in text
    assert vel(b)[0] == -1.0                                          # moving deeper: bounced at once


def test_signed_distances_match_the_geometry_of_planes_and_turned_boxes():
    from driftframe.framework.world import World

    with World() as w:
        q = fr.quat_from_axis_angle((0.0, 1.0, 0.0), math.pi / 2)    # local x -> world -z, local z -> world x
        w.create_entity(Transform((1.0, 2.0, 3.0), q), BoxCollider(half_extents=(1.0, 2.0, 3.0)))
        w.create_entity(Transform((0.0, 0.0, 0.0)), PlaneCollider(normal=(0.0, 0.0, 2.0), offset=1.0))
        shapes = StaticShapes(w)
        assert shapes.present()
        S = shapes.refresh().table
        x = np.array([[1.0, 2.0, 3.0],           # the box's centre: 1 m under its nearest (local x) faces
                      [1.0, 2.0, 4.5],           # 1.5 m along local -x: 0.5 m outside that face
                      [5.0, 5.0, 5.0],           # off a corner (local q = (-2, 3, 4); past by (1, 1, 1))
                      [1.0, 2.0, 3.5]])          # 0.5 m under the local -x face
        d = signed_distances(S, x)
        np.testing.assert_allclose(d[:, 0], [-1.0, 0.5, math.sqrt(3.0), -0.5], atol=1e-12)
        np.testing.assert_allclose(d[:, 1], x[:, 2] - 1.0, atol=1e-15)     # the plane z = 1
