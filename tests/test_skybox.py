"""The skybox: green lines at infinity, turned by the view's rotation, untouched by its translation."""
from __future__ import annotations

import esper
import numpy as np
import pytest

from driftframe.components.body import Transform
from driftframe.components.camera import Camera
from driftframe.components.render import ModelRef
from driftframe.framework import frame as fr
from driftframe.framework import meshes
from driftframe.framework.world import World
from driftframe.systems import camera as cs
from driftframe.systems.render import attach

pytestmark = pytest.mark.gl

W, H = 256, 192


@pytest.fixture
def sky(ctx):
    """(world, eye entity, render system) with only the skybox to draw."""
    w = World()
    eye = w.create_entity(Transform())
    w.create_entity(Camera(target=eye, mode="cockpit", fov=70.0))
    render = attach(w, ctx, (W, H))
    yield w, eye, render
    w.close()


def shot(w, render):
    w.step()                      # the camera system places the eye
    w.render()
    return render.read_rgba()


def test_skybox_does_not_change_when_the_camera_moves(sky):
    w, eye, render = sky
    tf = esper.component_for_entity(eye, Transform)
    tf.orientation = fr.quat_from_rotvec(np.array([0.2, 0.5, 0.1]))
    before = shot(w, render)
    assert (before[..., 1] > 100).sum() > 200          # there are lines in view
    for pos in ([3.0, -2.0, 1.0], [1e4, 5e3, -2e4]):
        tf.position = pos
        np.testing.assert_array_equal(shot(w, render), before)


def test_skybox_turns_when_the_camera_rotates(sky):
    w, eye, render = sky
    tf = esper.component_for_entity(eye, Transform)
    before = shot(w, render)
    tf.orientation = fr.quat_from_rotvec(np.array([0.0, np.radians(10.0), 0.0]))   # yaw 10 degrees
    after = shot(w, render)
    changed = np.any(before != after, axis=-1).mean()
    assert changed > 0.005
    # a yaw to the right moves the world's lines to the left on screen: the centre line is now left of it
    centre_row = after[H // 2 + 20, :, 1]
    cols = np.flatnonzero(centre_row > 100)
    x_line = cs.world_to_pixels(np.array([[0.0, 0.0, 1.0]]), render.projection @ render.view_rotation_only,
                                (W, H))[0][0, 0]
    assert x_line < W / 2 - 20 and np.min(np.abs(cols + 0.5 - x_line)) < 1.5


def test_skybox_lines_are_green(sky):
    w, eye, render = sky
    esper.component_for_entity(eye, Transform).orientation = fr.look_rotation((1.0, 0.7, 0.4))
    img = shot(w, render).astype(int)
    drawn = img[..., :3].max(axis=-1) > 0
    assert drawn.sum() > 200
    r, g, b = img[drawn, 0], img[drawn, 1], img[drawn, 2]
    assert (g >= 2 * r).all() and (g >= 2 * b).all() and g.max() > 180


def test_skybox_is_the_cube_whose_corners_project_where_expected(ctx):
    w = World()
    try:
        eye = w.create_entity(Transform(orientation=fr.look_rotation((1.0, 1.0, 1.0))))   # at a corner
        w.create_entity(Camera(target=eye, mode="cockpit", fov=70.0))
        render = attach(w, ctx, (W, H), skybox=False)
        cache = w.resources["model_cache"]
        cache.define("plain_cube", meshes.line_cube(1), colour=(0.0, 1.0, 0.0))
        from driftframe.systems.skybox import SkyboxSystem
        w.add_system(SkyboxSystem(ctx, cache, render, model="plain_cube"))
        img = shot(w, render)
        green = img[..., 1] > 100
        corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
        px, front = cs.world_to_pixels(corners, render.projection @ render.view_rotation_only, (W, H))
        inside = front & (px[:, 0] > 2) & (px[:, 0] < W - 2) & (px[:, 1] > 2) & (px[:, 1] < H - 2)
        assert inside.sum() >= 1
        for x, y in px[inside]:
            assert green[int(y) - 1:int(y) + 2, int(x) - 1:int(x) + 2].any()
        # the corner straight ahead joins three edges: points along them are drawn, the gaps between are not
        cx, cy = px[np.argmax(corners @ [1, 1, 1])]
        assert abs(cx - W / 2) < 1 and abs(cy - H / 2) < 1
        c = np.array([0.5, 0.5, 0.5])
        along = np.array([c - t * np.eye(3)[k] for k in range(3) for t in (0.05, 0.1, 0.2)])
        epx, _ = cs.world_to_pixels(along, render.projection @ render.view_rotation_only, (W, H))
        for x, y in epx:
            assert green[int(y) - 1:int(y) + 2, int(x) - 1:int(x) + 2].any()
        assert not green[H // 2 - 40: H // 2 - 8, W // 2 - 3: W // 2 + 4].any()     # between the upper edges
        assert not green[H // 2 + 8: H // 2 + 30, W // 2 - 30: W // 2 - 8].any()    # lower left
    finally:
        w.close()


def test_skybox_is_drawn_behind_every_model(sky):
    w, eye, render = sky
    w.create_entity(Transform((0.0, 0.0, 4.0)), ModelRef("sphere", colour=(1.0, 0.0, 0.0)))
    img = shot(w, render).astype(int)
    f_px = 0.5 * H / np.tan(np.radians(35.0))
    r_px = f_px / np.sqrt(4.0 ** 2 - 1.0)                 # the disc's radius in pixels
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    disc = np.hypot(xx - W / 2, yy - H / 2) < r_px - 1.0
    assert (img[disc, 0] > 25).all()                      # the sphere covers it
    assert (img[disc, 1] == 0).all()                    # no green line crosses the sphere
    # but the grid line through the middle of the view is there outside it
    assert (img[~disc, 1] > 100).sum() > 200
