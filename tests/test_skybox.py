"""The skybox: green lines (or a starfield) at infinity, turned by the view's rotation, untouched by its translation."""
from __future__ import annotations

import esper
import numpy as np
import pytest

from driftframe.components.body import Transform
from driftframe.components.camera import Camera
from driftframe.components.render import ModelRef
from driftframe.framework import frame as fr
from driftframe.framework import meshes
from driftframe.framework.model_cache import ModelCache
from driftframe.framework.scene import Seed
from driftframe.framework.world import World
from driftframe.systems import camera as cs
from driftframe.rendering import attach

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
        cache = w.resources[ModelCache]
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


# -- the starfield ------------------------------------------------------------------------------
from driftframe.systems import skybox as sb  # noqa: E402


def test_starfield_texture_is_the_same_for_a_seed_and_differs_between_seeds():
    a = sb.starfield_faces(sb.texture_rng(3), 64, 800)
    b = sb.starfield_faces(sb.texture_rng(3), 64, 800)
    c = sb.starfield_faces(sb.texture_rng(4), 64, 800)
    assert a.shape == (6, 64, 64, 3) and a.dtype == np.uint8
    np.testing.assert_array_equal(a, b)
    assert (a != c).any(axis=-1).mean() > 0.05
    # stars: a few bright points on a dark sky, on every face
    assert np.median(a) < 12 and all((f.max(axis=-1) > 60).sum() >= 3 for f in a)


def _whole_image_starfield(rng, size, stars):
    """The cube map as first written: every sum on one (6, size, size, 3) float image. starfield_faces's reference."""
    band = rng.normal(size=3)
    band /= np.linalg.norm(band)
    across = sb.face_directions(size) @ band
    lumps = rng.normal(size=(40, 3))
    lumps -= np.outer(lumps @ band, band) * 0.9
    lumps /= np.linalg.norm(lumps, axis=1, keepdims=True)
    weight = rng.uniform(0.3, 1.0, len(lumps))
    k = 4 if size % 4 == 0 else 1
    coarse = sb.face_directions(size // k)
    patch = np.zeros(coarse.shape[:-1])
    for c, wgt in zip(lumps, weight):
        patch += wgt * np.exp(6.0 * (coarse @ c - 1.0))
    patch = patch.repeat(k, axis=1).repeat(k, axis=2)
    glow = np.exp(-0.5 * (across / 0.16) ** 2) * (0.35 + patch / max(patch.max(), 1e-12))
    img = glow[..., None] * np.array([0.030, 0.032, 0.045])
    n_band = stars // 3
    u = rng.normal(size=(stars, 3))
    v = rng.normal(size=(n_band, 3))
    v -= np.outer(v @ band, band) * (1.0 - rng.uniform(0.0, 0.25, n_band))[:, None]
    dirs = np.vstack([u, v])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    bright = np.concatenate([rng.pareto(2.2, stars) * 0.10 + 0.05, rng.pareto(3.0, n_band) * 0.06 + 0.03])
    bright = np.minimum(bright, 3.0)
    warm = rng.uniform(0.0, 1.0, len(dirs)) ** 2
    tint = np.column_stack([0.80 + 0.20 * warm, 0.85 + 0.05 * warm, 1.0 - 0.45 * warm])
    face, row, col = sb.direction_to_texel(dirs, size)
    r0, c0 = np.floor(row).astype(int), np.floor(col).astype(int)
    flat = img.reshape(-1, 3)
    for di in (-1, 0, 1, 2):
        for dj in (-1, 0, 1, 2):
            rr, cc = r0 + di, c0 + dj
            ok = (rr >= 0) & (rr < size) & (cc >= 0) & (cc < size)
            wgt = np.exp(-((rr - row) ** 2 + (cc - col) ** 2) / (2 * 0.6 ** 2)) * bright
            idx = (face * size + rr) * size + cc
            for ch in range(3):
                np.add.at(flat[:, ch], idx[ok], (wgt * tint[:, ch])[ok])
    return (np.clip(img, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


@pytest.mark.parametrize("seed, size, stars", [(0, 64, 800), (5, 128, 3000), (2, 33, 200), (9, 16, 0)])
def test_starfield_faces_equal_the_whole_image_sum_byte_for_byte(seed, size, stars):
    """Face by face, without a (6, size, size, 3) float image, the bytes are the plain formula's."""
    np.testing.assert_array_equal(sb.starfield_faces(sb.texture_rng(seed), size, stars),
                                  _whole_image_starfield(sb.texture_rng(seed), size, stars))


def test_the_default_starfield_of_seed_0_keeps_its_bytes():
    """The sky every recording shows by default: its digest from the whole-image code (before 2026-12-03)."""
    import hashlib
    faces = sb.starfield_faces(sb.texture_rng(0))
    assert hashlib.sha256(faces.tobytes()).hexdigest() == \
        "58d9f076d4f3cc767557e723a9bf010eb7eafba480a058ea637fa85f248729fa"


def test_the_textures_stream_is_not_the_scenes_stream():
    """The sky is made from its own stream: adding it does not change the random numbers a scene is built with."""
    scene = np.random.default_rng(5).random(8)
    sky = sb.texture_rng(5).random(8)
    assert not np.allclose(scene, sky)
    np.testing.assert_array_equal(sb.texture_rng(5).random(8), sky)
    with pytest.raises(ValueError, match="seed must be an int >= 0, got -1"):
        sb.texture_rng(-1)


def test_cube_map_directions_and_texels_are_inverse_in_opengl_face_order():
    d = sb.face_directions(16)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0)
    # the centre of face k looks along +x, -x, +y, -y, +z, -z
    centres = (d[:, 7, 7] + d[:, 8, 8]) / 2
    np.testing.assert_allclose(centres / np.linalg.norm(centres, axis=1, keepdims=True),
                               [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], atol=1e-12)
    face, row, col = sb.direction_to_texel(d.reshape(-1, 3), 16)
    k, i, j = np.meshgrid(np.arange(6), np.arange(16), np.arange(16), indexing="ij")
    np.testing.assert_array_equal(face, k.ravel())
    np.testing.assert_allclose(row, i.ravel(), atol=1e-9)
    np.testing.assert_allclose(col, j.ravel(), atol=1e-9)
    with pytest.raises(ValueError, match="starfield size must be an int in"):
        sb.starfield_faces(sb.texture_rng(0), 8)


def test_starfield_shows_each_texel_where_its_direction_projects(ctx):
    """A test cube map (a dark colour per face and one bright texel) drawn as the sky: GL's lookup agrees."""
    n = 32
    faces = np.zeros((6, n, n, 3), np.uint8)
    faces[..., 2] = (np.arange(6) * 40 + 20)[:, None, None]            # face k: blue 20 + 40 k
    target = np.array([0.5, 0.3, 0.81])
    target /= np.linalg.norm(target)
    f, r, c = sb.direction_to_texel(target[None], n)
    faces[f[0], int(round(r[0])), int(round(c[0]))] = 255
    texel_dir = sb.face_directions(n)[f[0], int(round(r[0])), int(round(c[0]))]
    w = World()
    try:
        eye = w.create_entity(Transform(orientation=fr.look_rotation((0.45, 0.25, 0.85))))
        w.create_entity(Camera(target=eye, mode="cockpit", fov=40.0))
        render = attach(w, ctx, (W, H), skybox=False)
        w.add_system(sb.StarfieldSystem(ctx, render, faces=faces))
        img = shot(w, render).astype(int)
        vp = render.projection @ render.view_rotation_only
        (x, y), = cs.world_to_pixels(texel_dir[None], vp, (W, H))[0]
        bright = np.argwhere(img[..., 0] > 120)                      # only the marked texel has red
        assert len(bright)
        assert np.abs(bright.mean(axis=0) - [y, x]).max() < 3.0, (bright.mean(axis=0), (x, y))
        # elsewhere each pixel shows the blue of the face its direction falls on
        for px in ([W // 4, H // 4], [3 * W // 4, 3 * H // 4], [10, H - 10]):
            ndc = np.array([(px[0] + 0.5) / W * 2 - 1, 1 - (px[1] + 0.5) / H * 2, 1.0, 1.0])
            d = np.linalg.inv(vp) @ ndc
            face, _, _ = sb.direction_to_texel((d[:3] / d[3])[None] / np.linalg.norm(d[:3] / d[3]), n)
            assert abs(img[px[1], px[0], 2] - (face[0] * 40 + 20)) <= 2, (px, face, img[px[1], px[0]])
    finally:
        w.close()


def test_starfield_is_fixed_in_world_orientation_and_drawn_behind_models(ctx):
    w = World()
    try:
        eye = w.create_entity(Transform(orientation=fr.quat_from_rotvec(np.array([0.2, 0.5, 0.1]))))
        w.create_entity(Camera(target=eye, mode="cockpit", fov=70.0))
        render = attach(w, ctx, (W, H), skybox=False)
        w.add_system(sb.StarfieldSystem(ctx, render, seed=2, size=128, stars=3000))
        tf = esper.component_for_entity(eye, Transform)
        before = shot(w, render)
        assert (before[..., :3].max(axis=-1) > 100).sum() >= 5          # stars in view
        tf.position = [1e4, -3e3, 2e4]
        np.testing.assert_array_equal(shot(w, render), before)           # moving does not move the sky
        tf.orientation = fr.quat_from_rotvec(np.array([0.2, 0.6, 0.1]))
        assert (shot(w, render) != before).any(axis=-1).mean() > 0.005   # turning does
        tf.position = [0.0, 0.0, 0.0]
        tf.orientation = fr.IDENTITY_QUAT
        w.create_entity(Transform((0.0, 0.0, 4.0)), ModelRef("sphere", colour=(1.0, 0.0, 0.0)))
        img = shot(w, render).astype(int)
        f_px = 0.5 * H / np.tan(np.radians(35.0))
        yy, xx = np.mgrid[0:H, 0:W] + 0.5
        disc = np.hypot(xx - W / 2, yy - H / 2) < f_px / np.sqrt(15.0) - 1.0
        assert (img[disc, 1] == 0).all() and (img[disc, 0] > 25).all()  # no star shows through the sphere
    finally:
        w.close()


def test_attach_keeps_the_line_cube_as_the_default_sky_and_makes_the_starfield_from_the_seed(ctx):
    def systems(**kw):
        w = World()
        w.resources[Seed] = Seed(9)
        eye = w.create_entity(Transform())
        w.create_entity(Camera(target=eye, mode="cockpit"))
        attach(w, ctx, (64, 48), **kw)
        got = (w.get_system(sb.SkyboxSystem), w.get_system(sb.StarfieldSystem))
        w.close()
        return got
    lines, stars = systems()
    assert lines is not None and stars is None
    lines, stars = systems(skybox="starfield")
    assert lines is None and stars.seed == 9
    assert systems(skybox=False) == (None, None)
    with pytest.raises(ValueError, match="skybox must be one of .*got 'nebula'"):
        systems(skybox="nebula")


def test_record_sky_starfield_is_repeatable_and_the_default_except_in_the_rotation_demo(tmp_path, ctx):
    from PIL import Image

    from driftframe.cli import main

    def first_frame(*args, demo="rotation"):
        out = tmp_path / f"run{len(list(tmp_path.iterdir()))}"
        assert main(["record", demo, "--seconds", "0.05", "--size", "160x90", "--quiet",
                     "-o", f"{out}/", *args]) == 0
        return np.asarray(Image.open(sorted(out.glob("*.png"))[0]).convert("RGB")).astype(int)

    default, lines = first_frame(), first_frame("--sky", "lines")
    stars_a, stars_b = first_frame("--sky", "starfield"), first_frame("--sky", "starfield")
    other_seed = first_frame("--sky", "starfield", "--seed", "1")
    np.testing.assert_array_equal(default, lines)
    np.testing.assert_array_equal(stars_a, stars_b)
    green = (lines[..., 1] > 2 * lines[..., 0] + 40) & (lines[..., 1] > 2 * lines[..., 2] + 40)
    assert green.sum() > 50 and not ((stars_a[..., 1] > 2 * stars_a[..., 0] + 40)
                                     & (stars_a[..., 1] > 2 * stars_a[..., 2] + 40)).any()
    # the rotation demo has no random parts: only the sky changes with the seed
    assert (stars_a != other_seed).any(axis=-1).sum() > 20
    # every other demo: the starfield unless --sky lines
    np.testing.assert_array_equal(first_frame(demo="cradle"), first_frame("--sky", "starfield", demo="cradle"))


def test_starfield_uses_mipmaps_only_where_the_view_shrinks_the_texture(ctx):
    """512 texels across 90 degrees: magnified in a 1280x720 frame (bilinear), shrunk in a 160x90 one (mipmaps)."""
    filters = {}
    for size in ((1280, 720), (160, 90)):
        w = World()
        try:
            eye = w.create_entity(Transform())
            w.create_entity(Camera(target=eye, mode="cockpit", fov=60.0))
            render = attach(w, ctx, size, skybox=False)
            stars = w.add_system(sb.StarfieldSystem(ctx, render, seed=0, size=512, stars=500))
            shot(w, render)
            filters[size] = stars._tex.filter, stars.mipmapped
        finally:
            w.close()
    import moderngl
    # (the mipmaps are made only where they are sampled: llvmpipe's mipmap pass costs ~0.08 s the first time)
    assert filters[(1280, 720)] == ((moderngl.LINEAR, moderngl.LINEAR), False)
    assert filters[(160, 90)] == ((moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR), True)


def test_a_recordings_starfield_is_as_fine_as_its_frame_and_widest_lens_need_and_a_window_gets_the_finest(ctx):
    import math

    import moderngl

    from driftframe.framework.gl import RenderTarget

    # the largest power of two (64..512) with size tan(fov / 2) <= height: magnified, no mipmaps
    assert sb.fitted_face_texels(720, math.tan(math.radians(30))) == 512
    assert sb.fitted_face_texels(180, math.tan(math.radians(30))) == 256      # 512 x 0.577 = 296 > 180
    assert sb.fitted_face_texels(90, math.tan(math.radians(30))) == 128
    assert sb.fitted_face_texels(10, 1.0) == 64
    with pytest.raises(ValueError, match="height 0 and tan"):
        sb.fitted_face_texels(0, 1.0)

    def starfield(size, fovs, screen=False):
        w = World()
        try:
            eye = w.create_entity(Transform())
            for fov in fovs:
                w.create_entity(Camera(target=eye, mode="cockpit", fov=fov))
            target = RenderTarget.screen(ctx, size) if screen else None
            render = attach(w, ctx, size, target=target, skybox="starfield")
            stars = w.get_system(sb.StarfieldSystem)
            if not screen:
                shot(w, render)
            return stars._texels, stars._tex.filter, stars.mipmapped
        finally:
            w.close()

    assert starfield((320, 180), [60.0]) == (256, (moderngl.LINEAR, moderngl.LINEAR), False)
    assert starfield((320, 180), [30.0, 90.0])[0] == 128          # the widest lens decides (tan 45 = 1)
    assert starfield((1280, 720), [60.0])[0] == 512
    assert starfield((320, 180), [60.0], screen=True)[0] == 512   # a window may grow


@pytest.mark.parametrize("kind", ["lines", "starfield"])
def test_a_sky_added_before_its_render_system_still_draws_behind_the_models(ctx, kind):
    from driftframe.framework.gl import RenderTarget
    from driftframe.systems.render import RenderSystem
    from driftframe.systems.skybox import SkyboxSystem, StarfieldSystem

    w = World()
    try:
        eye = w.create_entity(Transform())
        w.create_entity(Camera(target=eye, mode="cockpit", fov=70.0))
        w.create_entity(Transform((0.0, 0.0, 4.0)), ModelRef("sphere", colour=(1.0, 0.0, 0.0)))
        cache, target = ModelCache(ctx), RenderTarget(ctx, (64, 48))
        w.resources[ModelCache], w.resources[RenderTarget] = cache, target
        render = RenderSystem(ctx, cache, target)
        sky = (SkyboxSystem(ctx, cache, render) if kind == "lines"
               else StarfieldSystem(ctx, render, size=16, stars=50))
        w.add_system(sky)                       # first: its after= (the render system's type) orders it
        w.add_system(render)
        w.step()
        w.render()
        rgba = render.read_rgba()
        r, g, b = rgba[24, 32, :3].tolist()
        assert r > 100 and g < 10 and b < 10            # the sphere, not the sky painted over it
        names = [type(e.system).__name__ for e in w._order["frame"]]
        assert names.index("RenderSystem") < names.index(type(sky).__name__)
    finally:
        w.close()
