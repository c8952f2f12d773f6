"""Every demo builds, runs headless without NaN, has the entities it promises, and is deterministic."""
import esper
import numpy as np
import pytest

from driftframe import demos
from driftframe.components.body import AngularVelocity, Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.components.control import Player
from driftframe.components.render import ModelRef
from driftframe.app import make_world
from driftframe.framework import frame as fr
from driftframe.framework.model_cache import ModelVariants
from driftframe.systems import camera as cs

EXPECTED = {   # (bodies with a collider, players, cameras)
    "rotation": (244, 1, 1),     # 7 x 5 x 7 beacons but the one at the ship's start
    "spin": (12, 1, 1),
    "asteroids": (52, 1, 1),     # the ship, a pebble on its path, fifty asteroids
    "billiards": (16, 0, 1),     # 16 balls (the cushions are four static boxes)
    "cradle": (6, 0, 1),
    "swarm": (3001, 1, 1),
    "orbit": (0, 1, 1),
}


@pytest.mark.parametrize("name", demos.NAMES)
def test_demo_builds_and_runs_120_steps_without_nan(name):
    world, demo = make_world(name, seed=3)
    try:
        world.step(120)
        colliders, players, cameras = EXPECTED[name]
        assert len(esper.get_component(SphereCollider)) == colliders
        assert len(esper.get_component(Player)) == players
        assert len(esper.get_component(Camera)) == cameras
        for cls, field in ((Transform, "position"), (Transform, "orientation"), (Velocity, "linear"),
                           (AngularVelocity, "angular")):
            assert np.isfinite(getattr(world.columns(cls), field)).all(), (name, cls.__name__)
        for _, ref in esper.get_component(ModelRef):
            assert ref.name in ("ship",) or ref.name in world.resources[ModelVariants]
        assert demo.TITLE and demo.DESCRIPTION and demo.SECONDS > 0
    finally:
        world.close()


def test_every_demo_module_is_listed_and_unknown_names_are_rejected():
    import pkgutil
    found = {m.name for m in pkgutil.iter_modules(demos.__path__)} - {"parts"}
    assert found == set(demos.NAMES)
    with pytest.raises(LookupError, match="unknown demo 'pong'"):
        demos.load("pong")


def test_asteroids_are_fifty_scaled_variants_of_four_rocks():
    world, _ = make_world("asteroids", seed=0)
    try:
        variants = world.resources[ModelVariants]
        names = {ref.name for _, ref in esper.get_component(ModelRef) if ref.name.startswith("asteroid_")}
        assert len([1 for _, ref in esper.get_component(ModelRef) if ref.name.startswith("asteroid_")]) == 50
        assert {variants[n][0] for n in names} <= {"rock0", "rock1", "rock2", "rock3"}
        scales = {variants[n][1] for n in names}
        assert len(scales) > 20                    # many different sizes
    finally:
        world.close()


def test_same_seed_same_run_different_seed_different_scene():
    def run(seed):
        world, _ = make_world("asteroids", seed=seed)
        world.step(240)
        h = world.state_hash()
        world.close()
        return h
    assert run(4) == run(4)
    assert run(4) != run(5)


def test_asteroids_script_flies_and_switches_camera_both_ways():
    world, demo = make_world("asteroids", seed=0)
    try:
        from driftframe.systems.camera import active_camera
        modes = []
        for _ in range(int(demo.SECONDS * 60)):
            world.step()
            modes.append(active_camera(world)[1].mode)
        changes = sum(a != b for a, b in zip(modes, modes[1:]))
        assert changes >= 2 and "cockpit" in modes and "chase" in modes
        from driftframe.app import player
        assert np.linalg.norm(esper.component_for_entity(player(world), Velocity).linear) > 5.0
    finally:
        world.close()


def test_spin_script_builds_spin_then_the_assist_removes_it_exactly():
    world, demo = make_world("spin", seed=0)
    try:
        from driftframe.app import player
        me = player(world)
        world.step(int(6.5 * 60))
        assert np.linalg.norm(esper.component_for_entity(me, AngularVelocity).angular) > 0.5   # persists
        world.step(int(4.5 * 60))                                                                # assist on
        np.testing.assert_array_equal(esper.component_for_entity(me, AngularVelocity).angular, 0.0)
    finally:
        world.close()


def test_cradle_demo_passes_the_impulse_to_the_last_ball():
    world, demo = make_world("cradle", seed=0)
    try:
        world.step(int(demo.SECONDS * 60))
        v = np.array(sorted((esper.component_for_entity(e, Transform).position[0],
                             esper.component_for_entity(e, Velocity).linear[0])
                            for e, _ in esper.get_component(SphereCollider)))
        np.testing.assert_allclose(v[:-1, 1], 0.0, atol=1e-9)
        np.testing.assert_allclose(v[-1, 1], 3.0, rtol=1e-12)
    finally:
        world.close()


# -- what the asteroids recording shows: collisions projected into the camera of their frame ----------
SHOT = (1280, 720)          # the recording's default size, px


def _visible(points, eye, vp, centres, radii, parties):
    """Which ``points`` a frame shows: in front, inside the frame, and not behind another sphere.

    A sphere hides a point when the segment from the eye to the point passes
    through it (spheres in ``parties[i]``, the bodies at point ``i``, do not count).
    """
    px, front = cs.world_to_pixels(points, vp, SHOT)
    inside = front & (px[:, 0] >= 0) & (px[:, 0] < SHOT[0]) & (px[:, 1] >= 0) & (px[:, 1] < SHOT[1])
    out = []
    for i, p in enumerate(points):
        seg = p - eye
        length = np.linalg.norm(seg)
        t = np.clip((centres - eye) @ seg / max(length, 1e-12) ** 2, 0.0, 1.0)      # closest point on the segment
        gap = np.linalg.norm(eye + t[:, None] * seg - centres, axis=1) - radii
        blocked = (gap < 0) & ~np.isin(np.arange(len(centres)), parties[i])
        out.append(bool(inside[i] and not blocked.any()))
    return np.array(out, bool)


def watch_asteroids(seed=0):
    """Run the asteroids demo headless with its cameras, as the recorder would frame it at 1280x720.

    Returns (fraction of frames with at least one field body in view, on-screen rock-rock
    collisions, on-screen ship-rock collisions, all collisions).
    """
    world, demo = make_world("asteroids", seed=seed)
    world.add_system(cs.CameraSystem())
    cs.update_cameras(world)
    from driftframe.app import player
    me = player(world)
    pending = []
    world.subscribe(CollisionEvent, pending.append)          # every contact, as the collision stage emits it
    seen = []                                                # (involves the ship, on screen)
    frames_with_field = 0
    steps = round(demo.SECONDS / world.dt)
    try:
        for _ in range(steps):
            world.step()
            # the frame after this step: the active camera as the camera stage left it
            ent, cam = cs.active_camera(world)
            tf = esper.component_for_entity(ent, Transform)
            vp = cs.perspective(cam.fov, SHOT[0] / SHOT[1], cam.near, cam.far) @ cs.view_matrix(
                tf.position, tf.orientation)
            f_px = 0.5 * SHOT[1] / cam.tan_half_fov
            cols = world.columns(SphereCollider)
            ids, radii = cols.entities, cols.radius
            centres = world.columns(Transform, ids).position
            field = ids != me
            drawn = radii.copy()
            if cam.mode == "cockpit":
                drawn[ids == cam.target] = 0.0     # the eye sits inside the ship, which is not drawn
            px_r = radii * f_px / np.maximum(np.linalg.norm(centres - tf.position, axis=1), 1e-9)
            shown = _visible(centres, tf.position, vp, centres, drawn, [[k] for k in range(len(ids))])
            frames_with_field += bool((shown & field & (px_r >= 1.0)).any())
            if pending:
                pts = np.array([ev.point for ev in pending])
                parties = [np.flatnonzero(np.isin(ids, (ev.a, ev.b))) for ev in pending]
                vis = _visible(pts, tf.position, vp, centres, drawn, parties)
                for ev, v, pa in zip(pending, vis, parties):
                    dist = np.linalg.norm(np.asarray(ev.point) - tf.position)
                    big_enough = radii[pa].min() * f_px / max(dist, 1e-9) >= 2.0     # a few pixels across
                    seen.append((me in (ev.a, ev.b), bool(v and big_enough)))
                pending.clear()
    finally:
        world.close()
    rock = sum(1 for ship_hit, on in seen if on and not ship_hit)
    ship_hits = sum(1 for ship_hit, on in seen if on and ship_hit)
    return frames_with_field / steps, rock, ship_hits, len(seen)


def test_asteroids_recording_keeps_the_field_in_view_and_shows_collisions_on_screen():
    in_view, rock, ship_hits, total = watch_asteroids(seed=0)
    assert in_view >= 0.9, f"field in view in {in_view:.0%} of frames"
    assert rock >= 3, f"{rock} of {total} asteroid-asteroid collisions on screen"
    assert ship_hits >= 1, f"{ship_hits} ship-asteroid collisions on screen"


def test_the_visibility_check_sees_off_screen_and_hidden_points():
    """The projection used above rejects points behind the eye, outside the frame, and behind a sphere."""
    eye = np.zeros(3)
    vp = cs.perspective(60.0, SHOT[0] / SHOT[1], 0.1, 1000.0) @ cs.view_matrix(eye, fr.look_rotation((0, 0, 1)))
    pts = np.array([[0.0, 0.0, 20.0], [0.0, 0.0, -20.0], [50.0, 0.0, 10.0], [0.0, 0.0, 40.0]])
    centres = np.array([[0.0, 0.0, 30.0]])        # a 2 m sphere between the eye and the last point
    got = _visible(pts, eye, vp, centres, np.array([2.0]), [[], [], [], []])
    assert got.tolist() == [True, False, False, False]
    assert _visible(pts[3:], eye, vp, centres, np.array([2.0]), [[0]]).tolist() == [True]   # its own body


def test_billiards_is_seen_from_an_overhead_camera_above_a_table_under_every_ball():
    world, demo = make_world("billiards", seed=0)
    try:
        world.add_system(cs.CameraSystem())
        world.step()
        ent, cam = cs.active_camera(world)
        assert cam.mode == "overhead" and cs.switch_camera(world) == "overhead"     # it stays overhead
        eye = esper.component_for_entity(ent, Transform)
        np.testing.assert_allclose(fr.rotate(eye.orientation, fr.FORWARD), [0.0, -1.0, 0.0], atol=1e-12)
        variants = world.resources[ModelVariants]
        slabs = [(esper.component_for_entity(e, Transform).position, variants[ref.name][1])
                 for e, ref in esper.get_component(ModelRef) if ref.name in ("felt", "table_frame")]
        assert slabs, "no table"
        top = max(p[1] + s[1] / 2 for p, s in slabs)
        balls = np.array([esper.component_for_entity(e, Transform).position for e, _ in esper.get_component(SphereCollider)
                          if esper.has_component(e, Velocity)])            # (the balls: what moves)
        assert len(balls) == 16
        np.testing.assert_allclose(top, balls[:, 1].min() - demo.R, atol=1e-12)       # the balls rest on it
        (p, s), = [(p, s) for p, s in slabs if np.isclose(p[1] + s[1] / 2, top)]
        assert (np.abs(balls[:, [0, 2]] - p[[0, 2]]) < np.array(s)[[0, 2]] / 2 - demo.R).all()
    finally:
        world.close()


@pytest.mark.gl
def test_billiards_frame_shows_felt_between_the_balls(ctx):
    from driftframe.app import attach_rendering
    world, demo = make_world("billiards", seed=0)
    try:
        render = attach_rendering(world, ctx, size=(320, 180), hud=False)
        world.step()
        world.render()
        img = render.read_rgba()[..., :3].astype(int)
        # a point on the table between the cue ball and the rack, and the corners of the view inside the table
        pts = np.array([[-4.0, -demo.R, 0.0], [1.5 - 12.0, -demo.R, -6.0], [1.5 + 12.0, -demo.R, 6.0]])
        px, front = cs.world_to_pixels(pts, render.view_projection, render.size)
        assert front.all()
        for x, y in px.astype(int):
            r, g, b = img[y, x]
            assert g > 2 * r and g > 2 * b and g > 60, (x, y, img[y, x])
        assert render.stats["levels"].get("box[0]") == 6          # the felt, the frame, four rails: one box mesh
    finally:
        world.close()


def _spheres_in_picture(eye: Transform, cam: Camera, centres, radii, size) -> tuple[np.ndarray, float]:
    """Which spheres lie wholly inside the picture of ``size`` seen from ``eye`` (between its four side planes,
    beyond the near plane), and the largest share of the half-height any of them reaches.

    In the eye's axes (x right, y up, z forward) the top plane is y = t z (t = tan(fov / 2)): a sphere of
    radius r is inside it when (t z - y) / sqrt(1 + t^2) >= r; the sides likewise with t times the aspect.
    """
    local = (np.asarray(centres) - eye.position) @ fr.quat_to_matrix(eye.orientation)
    t_y = np.tan(np.radians(cam.fov) / 2)
    t_x = t_y * size[0] / size[1]
    inside = local[:, 2] - radii > cam.near
    for k, t in ((0, t_x), (1, t_y)):
        inside &= (t * local[:, 2] - np.abs(local[:, k])) / np.sqrt(1 + t * t) >= radii
    reach = float(np.max((np.abs(local[:, 1]) + radii) / (t_y * local[:, 2])))
    return inside, reach


def test_swarm_overhead_camera_keeps_the_ship_and_all_3000_rocks_in_the_picture():
    """As the asteroids' overhead view (Camera.frame): the eye stands over the whole field, looking straight
    down, near enough that the field fills most of the picture's height; at 150 m over the ship (before) it
    stood inside the field, rocks behind it and beside it."""
    world, demo = make_world("swarm", seed=0)
    try:
        world.activate()
        (cam_ent, cam), = esper.get_component(Camera)
        ids = [e for e, _ in cam.frame]
        assert len(ids) == demo.COUNT and cam.target not in ids
        done = 0
        for seconds in (0.0, 4.0, 8.0, 11.9):         # the ship's burn, turn and second burn (it leaves the field)
            world.step(round(seconds / world.dt) - done)
            done = round(seconds / world.dt)
            cs.switch_camera(world, "overhead", camera=cam_ent)
            eye = esper.component_for_entity(cam_ent, Transform)
            np.testing.assert_allclose(fr.rotate(eye.orientation, fr.FORWARD), [0.0, -1.0, 0.0], atol=1e-12)
            centres = np.vstack([world.columns(Transform, ids).position,
                                 esper.component_for_entity(cam.target, Transform).position])
            radii = np.append(world.columns(SphereCollider, ids).radius, 0.0)
            inside, reach = _spheres_in_picture(eye, cam, centres, radii, (640, 360))
            assert inside.all(), f"{(~inside).sum()} of {len(inside)} bodies out of the picture at {seconds} s"
            assert reach > 0.6, f"the field fills only {reach:.0%} of the half-height at {seconds} s: too far"
    finally:
        world.close()
