"""Cockpit, chase and overhead cameras, the run-time switch, and the view / projection matrices."""
from __future__ import annotations

import math

import esper
import numpy as np
import pytest

from driftframe.components.body import Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.framework import frame as fr
from driftframe.framework.world import World
from driftframe.systems import camera as cs
from driftframe.systems.movement import MovementSystem


def fwd(q):
    return fr.rotate(np.asarray(q), fr.FORWARD)


def angle(a, b):
    a, b = np.asarray(a) / np.linalg.norm(a), np.asarray(b) / np.linalg.norm(b)
    return math.degrees(math.acos(np.clip(np.dot(a, b), -1.0, 1.0)))


def ship_world(velocity=(0.0, 0.0, 0.0), *, mode="chase", dt=1 / 60, **cam):
    w = World(dt=dt)
    q = fr.quat_from_rotvec(np.array([0.3, -0.5, 0.2]))           # some turned frame
    ship = w.create_entity(Transform((5.0, -2.0, 7.0), q), Velocity(velocity))
    eye = w.create_entity(Camera(target=ship, mode=mode, **cam))
    w.add_system(cs.CameraSystem())
    return w, ship, eye


def test_cockpit_camera_takes_the_ship_frame():
    w, ship, eye = ship_world(mode="cockpit", cockpit_offset=(0.0, 0.5, 1.0))
    w.step()
    st = esper.component_for_entity(ship, Transform)
    et = esper.component_for_entity(eye, Transform)
    np.testing.assert_allclose(et.orientation, st.orientation, atol=1e-15)
    np.testing.assert_allclose(et.position, st.position + 0.5 * st.up + 1.0 * st.forward, atol=1e-12)
    w.close()


def test_chase_camera_looks_along_the_velocity_not_the_nose():
    v = np.array([3.0, 0.0, -4.0])
    w, ship, eye = ship_world(v, smoothing=0.0, chase_distance=10.0, chase_height=2.0)
    w.step()
    st = esper.component_for_entity(ship, Transform)
    et = esper.component_for_entity(eye, Transform)
    assert angle(st.forward, v) > 30.0                               # the nose points elsewhere
    np.testing.assert_allclose(et.forward, v / 5.0, atol=1e-12)
    # behind the ship along the travel direction and above it along the eye's up
    np.testing.assert_allclose(et.position, st.position - 10.0 * et.forward + 2.0 * et.up, atol=1e-12)
    # the eye's up is the ship's up made perpendicular to the view
    up = st.up - np.dot(st.up, et.forward) * et.forward
    np.testing.assert_allclose(et.up, up / np.linalg.norm(up), atol=1e-12)
    w.close()


def test_chase_camera_falls_back_to_the_nose_when_nearly_at_rest():
    w, ship, eye = ship_world((0.0, 0.3, 0.0), smoothing=0.0, rest_speed=0.5)
    w.step()
    st = esper.component_for_entity(ship, Transform)
    np.testing.assert_allclose(esper.component_for_entity(eye, Transform).forward, st.forward, atol=1e-12)
    esper.component_for_entity(ship, Velocity).linear = (0.0, 0.7, 0.0)   # moving now
    w.step()
    np.testing.assert_allclose(esper.component_for_entity(eye, Transform).forward, [0, 1, 0], atol=1e-12)
    w.close()


@pytest.mark.parametrize("dt", [1 / 30, 1 / 60, 1 / 240])
def test_chase_smoothing_is_an_exact_first_order_lag_at_any_step(dt):
    """Turning towards a fixed goal, the angle left decays as exp(-t / tau) whatever dt is."""
    tau = 0.2
    w, ship, eye = ship_world((0.0, 0.0, 0.0), smoothing=tau, dt=dt)
    st = esper.component_for_entity(ship, Transform)
    st.orientation = fr.IDENTITY_QUAT
    w.step()                                                          # at rest: the eye looks along the nose
    np.testing.assert_allclose(esper.component_for_entity(eye, Transform).forward, [0, 0, 1], atol=1e-12)
    esper.component_for_entity(ship, Velocity).linear = (20.0, 0.0, 0.0)   # sudden sideways travel
    steps = round(0.5 / dt)
    w.step(steps)
    left = angle(esper.component_for_entity(eye, Transform).forward, [1, 0, 0])
    assert left == pytest.approx(90.0 * math.exp(-steps * dt / tau), rel=1e-7)
    w.close()


def test_chase_camera_smooths_out_jitter_in_the_velocity():
    w, ship, eye = ship_world((0.0, 0.0, 10.0), smoothing=0.25)
    w.step(30)
    vel = esper.component_for_entity(ship, Velocity)
    rng = np.random.default_rng(3)
    seen, given = [], []
    for _ in range(120):                                           # +-5 degrees of noise each step
        a = rng.uniform(-5, 5)
        vel.linear = (10 * math.sin(math.radians(a)), 0.0, 10 * math.cos(math.radians(a)))
        w.step()
        seen.append(angle(esper.component_for_entity(eye, Transform).forward, [0, 0, 1]))
        given.append(abs(a))
    rms = lambda x: math.sqrt(np.mean(np.square(x)))             # noqa: E731
    assert rms(seen) < 0.25 * rms(given)
    assert max(seen) < 0.4 * max(given)
    w.close()


def test_switch_camera_cycles_cockpit_and_chase_and_changes_the_view():
    w, ship, eye = ship_world((1.0, 2.0, 2.0), mode="cockpit", smoothing=0.5)
    w.step()
    st = esper.component_for_entity(ship, Transform)
    cockpit_view = cs.view_matrix(st.position, st.orientation)
    et = esper.component_for_entity(eye, Transform)
    np.testing.assert_allclose(cs.view_matrix(et.position, et.orientation), cockpit_view, atol=1e-12)

    assert cs.switch_camera(w) == "chase"
    cam = esper.component_for_entity(eye, Camera)
    d = np.array([1.0, 2.0, 2.0]) / 3.0
    q = fr.look_rotation(d, st.up)
    expected = cs.view_matrix(st.position + fr.rotate(q, np.array([0.0, cam.chase_height, -cam.chase_distance])), q)
    # applied at once, without waiting for the smoothing
    np.testing.assert_allclose(cs.view_matrix(et.position, et.orientation), expected, atol=1e-12)
    # the view looks along the velocity: it maps the travel direction to the eye's -z
    np.testing.assert_allclose(expected[:3, :3] @ d, [0, 0, -1], atol=1e-12)

    assert cs.switch_camera(w) == "cockpit"
    np.testing.assert_allclose(cs.view_matrix(et.position, et.orientation), cockpit_view, atol=1e-12)
    assert cs.switch_camera(w, "chase") == "chase" and cs.switch_camera(w, "chase") == "chase"
    with pytest.raises(ValueError, match="Camera.mode must be one of"):
        cs.switch_camera(w, "orbit")
    w.close()


def test_overhead_camera_looks_straight_down_on_the_target_with_its_up_at_the_top():
    w, ship, eye = ship_world((1.0, 0.0, 0.5), mode="overhead", overhead_height=16.0, overhead_up=(1.0, 0.0, 0.0))
    w.add_system(MovementSystem())
    start = esper.component_for_entity(ship, Transform).position.copy()
    w.step(30)
    st = esper.component_for_entity(ship, Transform)
    et = esper.component_for_entity(eye, Transform)
    np.testing.assert_allclose(st.position, start + np.array([1.0, 0.0, 0.5]) * 0.5, atol=1e-12)   # it moved
    np.testing.assert_allclose(et.position, st.position + [0.0, 16.0, 0.0], atol=1e-12)           # and the eye too
    np.testing.assert_allclose(fwd(et.orientation), [0.0, -1.0, 0.0], atol=1e-12)
    # the target projects to the centre of the picture; world +x (overhead_up) is up on screen, +z to the left
    vp = cs.perspective(60.0, 4 / 3, 0.1, 100.0) @ cs.view_matrix(et.position, et.orientation)
    px, front = cs.world_to_pixels(np.array([st.position, st.position + [1.0, 0, 0], st.position + [0, 0, 1.0]]),
                                   vp, (320, 240))
    assert front.all()
    np.testing.assert_allclose(px[0], [160.0, 120.0], atol=1e-9)
    assert px[1, 1] < 110 and abs(px[1, 0] - 160) < 1e-9            # +x: towards the top
    assert px[2, 0] < 150 and abs(px[2, 1] - 120) < 1e-9            # +z: to the left (seen from above)
    # turning the target does not turn the view
    before = cs.view_matrix(et.position, et.orientation)
    st.orientation = fr.quat_from_rotvec(np.array([0.0, 1.2, 0.4]))
    w.step()
    after = cs.view_matrix(et.position, et.orientation)
    np.testing.assert_allclose(after[:3, :3], before[:3, :3], atol=1e-12)
    w.close()


def test_switch_steps_through_the_cameras_own_cycle():
    w, ship, eye = ship_world(mode="overhead", cycle=("overhead", "chase"))
    assert cs.switch_camera(w) == "chase"
    assert cs.switch_camera(w) == "overhead"
    et = esper.component_for_entity(eye, Transform)
    np.testing.assert_allclose(fwd(et.orientation), [0.0, -1.0, 0.0], atol=1e-12)   # placed at once
    w.close()
    # the default cycle is cockpit <-> chase: an overhead camera switched without a mode goes to cockpit
    w, ship, eye = ship_world(mode="overhead")
    assert [cs.switch_camera(w) for _ in range(3)] == ["cockpit", "chase", "cockpit"]
    assert cs.switch_camera(w, "overhead") == "overhead"
    w.close()
    w, ship, eye = ship_world(mode="overhead", cycle=("overhead",))
    assert cs.switch_camera(w) == "overhead"           # a one-mode cycle stays put
    w.close()


def test_camera_without_a_target_is_a_clear_error(world):
    with pytest.raises(ValueError, match="a camera without a target"):
        Camera()
    world.add_system(cs.CameraSystem())
    world.create_entity(Camera(target=999))
    with pytest.raises(ValueError, match="target entity 999 does not exist"):
        world.step()


def test_camera_target_without_a_transform_is_a_clear_error(world):
    world.add_system(cs.CameraSystem())
    body = world.create_entity(Velocity((1.0, 0.0, 0.0)))
    world.create_entity(Camera(target=body))
    with pytest.raises(ValueError, match=f"target entity {body} has no Transform"):
        world.step()


def test_no_active_camera_is_a_clear_error(world):
    with pytest.raises(LookupError, match="no active Camera"):
        cs.switch_camera(world)


@pytest.mark.parametrize("kw, msg", [
    ({"fov": 0.0}, "Camera.fov must be in"), ({"fov": 180.0}, "Camera.fov must be in"),
    ({"near": 0.0}, "Camera.near must be > 0"), ({"near": 10.0, "far": 5.0}, "Camera.far must be > Camera.near"),
    ({"mode": "orbit"}, "Camera.mode must be one of"), ({"smoothing": -1.0}, "Camera.smoothing must be >= 0"),
    ({"chase_height": math.nan}, "Camera.chase_height must not be NaN"), ({"target": True}, "entity id"),
    ({"overhead_height": 0.0}, "Camera.overhead_height must be > 0"),
    ({"overhead_up": (0.0, 2.0, 0.0)}, r"Camera.overhead_up must have a part across world y.*\[0.0, 2.0, 0.0\]"),
    ({"overhead_up": (0.0, 0.0, 0.0)}, "Camera.overhead_up must have a part across world y"),
    ({"cycle": ()}, "Camera.cycle must name at least one mode"),
    ({"cycle": ("cockpit", "orbit")}, r"Camera.cycle: modes must be among .* got 'orbit'"),
])
def test_camera_rejects_bad_settings(kw, msg):
    kw = {"target": 1, **kw}
    with pytest.raises((ValueError, TypeError), match=msg):
        Camera(**kw)


def test_view_matrix_maps_the_eye_frame_to_opengl_eye_space():
    q = fr.quat_from_rotvec(np.array([0.1, 0.7, -0.3]))
    pos = np.array([1.0, 2.0, 3.0])
    v = cs.view_matrix(pos, q)
    r = fr.quat_to_matrix(q)
    h = lambda p: (v @ np.append(p, 1.0))[:3]                    # noqa: E731
    np.testing.assert_allclose(h(pos), 0.0, atol=1e-12)
    np.testing.assert_allclose(h(pos + r[:, 2]), [0, 0, -1], atol=1e-12)   # forward -> -z
    np.testing.assert_allclose(h(pos + r[:, 0]), [1, 0, 0], atol=1e-12)    # right -> +x
    np.testing.assert_allclose(h(pos + r[:, 1]), [0, 1, 0], atol=1e-12)    # up -> +y


def test_perspective_projects_like_a_pinhole_and_maps_near_far_to_depth_range():
    w_px, h_px, fov = 320, 240, 60.0
    proj = cs.perspective(fov, w_px / h_px, 0.1, 100.0)
    view = cs.view_matrix(np.zeros(3), fr.IDENTITY_QUAT)
    f_px = 0.5 * h_px / math.tan(math.radians(fov / 2))
    pts = np.array([[0.0, 0.0, 10.0], [2.0, 1.0, 10.0], [-3.0, -4.0, 20.0], [0.0, 0.0, -5.0]])
    px, front = cs.world_to_pixels(pts, proj @ view, (w_px, h_px))
    np.testing.assert_array_equal(front, [True, True, True, False])
    expected = np.column_stack([160 + f_px * pts[:3, 0] / pts[:3, 2], 120 - f_px * pts[:3, 1] / pts[:3, 2]])
    np.testing.assert_allclose(px[:3], expected, atol=1e-9)
    for z, ndc in ((0.1, -1.0), (100.0, 1.0)):
        clip = proj @ view @ np.array([0.0, 0.0, z, 1.0])
        assert clip[2] / clip[3] == pytest.approx(ndc)


def test_slerp_takes_the_short_way_and_ends_exactly():
    a = fr.IDENTITY_QUAT
    b = fr.quat_from_rotvec(np.array([0.0, 2.0, 0.0]))
    np.testing.assert_allclose(cs.slerp(a, b, 0.5), fr.quat_from_rotvec(np.array([0.0, 1.0, 0.0])), atol=1e-12)
    np.testing.assert_allclose(cs.slerp(a, -b, 1.0), b * np.sign(np.dot(cs.slerp(a, -b, 1.0), b)), atol=1e-12)
    np.testing.assert_allclose(cs.slerp(a, -b, 0.5), fr.quat_from_rotvec(np.array([0.0, 1.0, 0.0])), atol=1e-12)
