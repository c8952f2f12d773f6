"""HUD: the prograde marker sits where the velocity projects on screen; text reports speed and camera."""
import numpy as np
import pytest

from driftframe.components.body import AngularVelocity, Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.control import Player
from driftframe.components.render import ModelRef
from driftframe.framework import frame as fr
from driftframe.app import attach_rendering
from driftframe.systems.hud import HudSystem, PROGRADE_COLOUR, project_direction

pytestmark = pytest.mark.gl


def _scene(world, ctx, velocity, mode="cockpit", size=(320, 240)):
    ship = world.create_entity(Player(), Transform((0, 0, 0), fr.look_rotation((0.2, 0.1, 1.0))),
                               Velocity(velocity), AngularVelocity((0, 0.3, 0)), ModelRef("ship"))
    world.create_entity(Camera(target=ship, mode=mode, fov=70.0))
    render = attach_rendering(world, ctx, size=size, own_context=False)
    world.render()
    return render, world.get_system(HudSystem)


def _independent_pixel(render, direction):
    """Project a far point along ``direction`` with the full view-projection (translation included)."""
    p = np.append(render.eye_position + 1e7 * np.asarray(direction) / np.linalg.norm(direction), 1.0)
    clip = render.view_projection @ p
    ndc = clip[:2] / clip[3]
    w, h = render.size
    return np.array([(ndc[0] + 1) / 2 * w, (1 - ndc[1]) / 2 * h])


@pytest.mark.parametrize("mode", ["cockpit", "chase"])
def test_prograde_marker_sits_where_the_velocity_projects(world, ctx, mode):
    v = np.array([1.5, -0.6, 4.0])
    render, hud = _scene(world, ctx, v, mode)
    got = hud.last["markers"]["prograde"]
    np.testing.assert_allclose(got, _independent_pixel(render, v), atol=1e-3)
    # and the marker is drawn there: prograde-coloured pixels on its ring
    img = render.read_rgba()[:, :, :3].astype(int)
    radius = max(6.0, render.size[1] / 60)
    ring = [(int(round(got[1] + radius * np.sin(a))), int(round(got[0] + radius * np.cos(a))))
            for a in np.linspace(0.3, 6.0, 12)]
    target = np.array(PROGRADE_COLOUR[:3]) * 255
    hits = sum(np.abs(img[y, x] - target).max() < 60 for y, x in ring)
    assert hits >= 6, hits
    assert "retrograde" not in hud.last["markers"]          # behind the camera: not drawn


def test_in_chase_view_the_prograde_marker_is_at_the_centre(world, ctx):
    """The chase camera looks along the velocity, so the direction of travel is the screen centre."""
    render, hud = _scene(world, ctx, (3.0, 0.0, 0.5), "chase")
    np.testing.assert_allclose(hud.last["markers"]["prograde"], np.array(render.size) / 2, atol=0.5)


def test_text_reports_camera_speed_and_spin(world, ctx):
    _, hud = _scene(world, ctx, (3.0, 4.0, 0.0))
    text = "\n".join(hud.last["text"])
    assert "CAMERA  cockpit" in text
    assert "5.00 m/s" in text
    assert "0.300 rad/s" in text


def test_no_markers_at_rest(world, ctx):
    _, hud = _scene(world, ctx, (0.0, 0.0, 0.0))
    assert hud.last["markers"] == {}


def test_project_direction_behind_the_eye_is_none():
    proj = np.eye(4)
    proj[3] = [0, 0, -1, 0]                 # w = -z_view: in front means z_view < 0
    assert project_direction((0, 0, 1.0), np.eye(4), proj, (100, 100)) is None
    np.testing.assert_allclose(project_direction((0, 0, -1.0), np.eye(4), proj, (100, 100)), [50, 50])


def test_a_fixed_viewpoint_shows_only_the_camera(world, ctx):
    eye = world.create_entity(Transform((0, 0, -5.0)))
    world.create_entity(Camera(target=eye, mode="cockpit"))
    attach_rendering(world, ctx, size=(160, 120), own_context=False)
    world.render()
    assert world.get_system(HudSystem).last["text"] == ["CAMERA  cockpit"]


@pytest.mark.parametrize("mode", ["cockpit", "chase"])
def test_orbit_readouts_and_the_predicted_orbit_line_in_both_cameras(world, ctx, mode):
    from driftframe.components.gravity import GravityWell
    from driftframe.systems.gravity import GravitySystem
    from driftframe.systems.hud import ORBIT_COLOUR

    mu, R = 3.986e14, 6.371e6
    world.add_system(GravitySystem())
    world.create_entity(Transform((0, 0, 0)), GravityWell(mu=mu, radius=R))
    r = 7e6
    # nose along the velocity, the planet below: the orbit ahead curves down across the view
    ship = world.create_entity(Player(), Transform((r, 0, 0), fr.look_rotation((0, 0.95, 0.3), (1, 0, 0))),
                               Velocity((0, 7.6e3, 0)), AngularVelocity(), ModelRef("ship"))
    world.create_entity(Camera(target=ship, mode=mode, fov=70.0))
    render = attach_rendering(world, ctx, size=(320, 240), own_context=False)
    world.step(1)
    world.render()
    hud = world.get_system(HudSystem)
    assert any(line.startswith("APO") for line in hud.last["text"])
    assert any(line.startswith("PERIOD") for line in hud.last["text"])
    segs = hud.last["orbit"]
    assert len(segs) > 5
    img = render.read_rgba()[:, :, :3].astype(int)
    target = np.array(ORBIT_COLOUR[:3]) * 255
    on = 0
    for x0, y0, x1, y1 in segs[:: max(1, len(segs) // 20)]:
        x, y = int(round((x0 + x1) / 2)), int(round((y0 + y1) / 2))
        if 0 <= x < 320 and 0 <= y < 240:
            on += np.abs(img[y, x] - target).max() < 90
    assert on >= 3, on
