"""The render system: T R S model matrices, instancing, culling, level of detail, lighting, frame hand-off."""
from __future__ import annotations

import math

import esper
import numpy as np
import pytest

from driftframe.components.body import Transform
from driftframe.components.camera import Camera
from driftframe.components.render import ModelRef
from driftframe.framework import frame as fr
from driftframe.framework.gl import ContextHandle, RenderTarget
from driftframe.framework.model_cache import ModelCache
from driftframe.framework.world import World
from driftframe.systems import camera as cs
from driftframe.rendering import attach
from driftframe.systems.render import RenderSystem

pytestmark = pytest.mark.gl

W, H, FOV = 320, 240, 60.0
F_PX = 0.5 * H / math.tan(math.radians(FOV / 2))           # pixels per metre at 1 m depth


@pytest.fixture
def make(ctx):
    """make(**render_options) -> (world, eye entity, render system): an eye at the origin looking along +z."""
    worlds = []

    def build(size=(W, H), skybox=False, **options):
        w = World()
        worlds.append(w)
        eye = w.create_entity(Transform())
        w.create_entity(Camera(target=eye, mode="cockpit", fov=FOV, near=0.1, far=1000.0))
        render = attach(w, ctx, size, skybox=skybox, **options)
        return w, eye, render

    yield build
    for w in worlds:
        w.close()


def frame(w, render):
    w.render()
    return render.read_rgba()


def sphere_mask(centre, radius, size=(W, H), f_px=F_PX):
    """Pixels whose centre ray (from the eye at the origin, looking along +z) hits the sphere."""
    w, h = size
    xs = (np.arange(w) + 0.5 - w / 2) / f_px
    ys = -(np.arange(h) + 0.5 - h / 2) / f_px
    d = np.stack(np.broadcast_arrays(xs[None, :], ys[:, None], np.ones((h, w))), -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    c = np.asarray(centre, float)
    t = d @ c
    miss2 = c @ c - t * t                                     # squared distance of the centre from the ray
    return (miss2 < radius * radius) & (t > 0)


def sphere_normals(centre, radius, size=(W, H), f_px=F_PX):
    """Unit surface normal where each pixel's centre ray first hits the sphere (NaN where it misses)."""
    w, h = size
    xs = (np.arange(w) + 0.5 - w / 2) / f_px
    ys = -(np.arange(h) + 0.5 - h / 2) / f_px
    d = np.stack(np.broadcast_arrays(xs[None, :], ys[:, None], np.ones((h, w))), -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    c = np.asarray(centre, float)
    t = d @ c
    with np.errstate(invalid="ignore"):
        t_hit = t - np.sqrt(radius * radius - (c @ c - t * t))
    return (t_hit[..., None] * d - c) / radius


def centroid(mask):
    ys, xs = np.nonzero(mask)
    return np.array([xs.mean() + 0.5, ys.mean() + 0.5])


def lit(img, level=8):
    return img[..., :3].max(axis=-1) > level


def test_sphere_straight_ahead_is_a_centred_disc_of_the_projected_size(make):
    w, _, render = make()
    w.create_entity(Transform((0.0, 0.0, 10.0)), ModelRef("sphere"))
    img = frame(w, render)
    mask = lit(img)
    np.testing.assert_allclose(centroid(mask), [W / 2, H / 2], atol=0.15)
    # angular radius asin(r/d) projects to f_px tan(asin(r/d)) = f_px r / sqrt(d^2 - r^2) pixels
    expected_r = F_PX * 1.0 / math.sqrt(10.0 ** 2 - 1.0)
    assert math.sqrt(mask.sum() / math.pi) == pytest.approx(expected_r, abs=0.4)
    truth = sphere_mask((0, 0, 10), 1.0)
    assert (mask & truth).sum() / (mask | truth).sum() > 0.96


@pytest.mark.parametrize("centre", [(3.0, -2.0, 10.0), (-4.0, 2.5, 8.0), (0.0, 4.0, 12.0)])
def test_off_axis_sphere_lands_where_the_projection_says(make, centre):
    w, _, render = make()
    w.create_entity(Transform(centre), ModelRef("sphere"))
    mask = lit(frame(w, render))
    truth = sphere_mask(centre, 1.0)
    np.testing.assert_allclose(centroid(mask), centroid(truth), atol=0.25)
    assert (mask & truth).sum() / (mask | truth).sum() > 0.95
    # and the render system's own matrices agree: the centre projects inside the disc
    px, front = cs.world_to_pixels(np.array([centre]), render.view_projection, render.size)
    assert front[0] and mask[int(px[0, 1]), int(px[0, 0])]


def test_sphere_is_shaded_by_the_directional_light(make):
    to_light = np.array([-1.0, 1.0, -1.0]) / math.sqrt(3)      # up, left, towards the eye
    w, _, render = make(light_direction=to_light, ambient=0.1, fill=0.0)
    w.create_entity(Transform((0.0, 0.0, 10.0)), ModelRef("sphere", colour=(1.0, 1.0, 1.0)))
    img = frame(w, render)[..., 0].astype(float)
    mask = lit(frame(w, render))
    c = np.round(centroid(mask)).astype(int)
    # the centre faces the eye (n = -forward): shade = a + (1 - a) max(n . l, 0)
    expected = 255 * (0.1 + 0.9 * (1 / math.sqrt(3)))
    assert img[c[1] - 1:c[1] + 1, c[0] - 1:c[0] + 1].mean() == pytest.approx(expected, abs=3.0)
    # the brightest point is up and to the left; the side away from the light shows only the ambient
    ys, xs = np.nonzero(img == img[mask].max())
    assert xs.mean() < c[0] - 5 and ys.mean() < c[1] - 5
    assert img[mask].max() == pytest.approx(255, abs=2)
    assert img[mask].min() == pytest.approx(25.5, abs=2)


def test_hemisphere_fill_keeps_a_sphere_seen_against_the_light_readable(make):
    """Light straight from behind the sphere: without the fill it is one flat ambient disc."""
    to_light = np.array([0.0, 0.0, 1.0])                       # behind the sphere, as seen from the eye
    shots = {}
    for fill in (0.0, 0.3):
        w, _, render = make(light_direction=to_light, ambient=0.12, fill=fill)
        w.create_entity(Transform((0.0, 0.0, 10.0)), ModelRef("sphere", colour=(1.0, 1.0, 1.0)))
        shots[fill] = frame(w, render)[..., 0].astype(float)
    truth = sphere_mask((0, 0, 10), 1.0)
    inner = sphere_mask((0, 0, 10), 0.97)                       # away from the outline's partial pixels
    flat, filled = shots[0.0], shots[0.3]
    np.testing.assert_allclose(flat[inner], 255 * 0.12, atol=1.5)   # no shape at all
    # with the fill: n . l = -1 at the centre (ambient + fill), rising to 0 at the outline (ambient + fill/2)
    cy, cx = H // 2, W // 2
    assert filled[cy - 1:cy + 1, cx - 1:cx + 1].mean() == pytest.approx(255 * (0.12 + 0.3), abs=3.0)
    n = sphere_normals((0, 0, 10), 1.0)
    expected = 255 * (0.12 + 0.3 * (0.5 - 0.5 * n[..., 2]))
    np.testing.assert_allclose(filled[inner], expected[inner], atol=3.0)
    ring = inner & ~sphere_mask((0, 0, 10), 0.9)
    assert filled[ring].mean() < filled[cy, cx] - 15            # darker towards the outline: it reads round
    assert (filled[~truth] == 0).all()


def test_fill_leaves_the_lit_side_alone(make):
    to_light = np.array([0.0, 0.0, -1.0])                      # from the eye: the visible side faces the light
    shots = []
    for fill in (0.0, 0.3):
        w, _, render = make(light_direction=to_light, ambient=0.12, fill=fill)
        w.create_entity(Transform((0.0, 0.0, 10.0)), ModelRef("sphere", colour=(1.0, 1.0, 1.0)))
        shots.append(frame(w, render)[..., 0].astype(float))
    cy, cx = H // 2, W // 2
    assert shots[0][cy, cx] == pytest.approx(255, abs=1) and shots[1][cy, cx] == pytest.approx(255, abs=1)
    inner = sphere_mask((0, 0, 10), 0.9)
    # n . l = c near the centre: the fill adds 0.3 (1 - c) / 2, at most 0.3 * (1 - 0.43) / 2 = 0.09 inside r = 0.9
    diff = shots[1][inner] - shots[0][inner]
    assert diff.min() >= -1 and diff.max() <= 255 * 0.09 + 2


def test_entity_colour_overrides_the_model_colour(make):
    w, _, render = make()
    w.create_entity(Transform((-2.0, 0.0, 10.0)), ModelRef("sphere"))
    w.create_entity(Transform((2.0, 0.0, 10.0)), ModelRef("sphere", colour=(1.0, 0.0, 0.0)))
    img = frame(w, render).astype(int)
    left, right = img[H // 2, W // 2 - 41], img[H // 2, W // 2 + 41]
    assert right[0] > 60 and right[1] == 0 and right[2] == 0
    assert abs(left[0] - left[1]) < 10 and left[1] > 30


def test_ship_nose_points_along_its_forward_vector(make):
    from driftframe.framework.meshes import ship_hull
    hull = ship_hull()
    w, eye, render = make()
    eye_tf = esper.component_for_entity(eye, Transform)
    eye_tf.position = (0.0, 12.0, 0.0)                                  # above, looking down
    eye_tf.orientation = fr.look_rotation((0.0, -1.0, 0.0), (0.0, 0.0, 1.0))
    w.step()                                                            # the camera system moves the eye
    for nose in ([1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [-0.6, 0.0, 0.8]):
        ship = w.create_entity(Transform((0.0, 0.0, 0.0), fr.look_rotation(nose)), ModelRef("ship"))
        mask = lit(frame(w, render))
        tip = np.array([nose]) * hull.vertices[:, 2].max()              # the nose, ahead of the centre of mass
        tail = np.array([nose]) * hull.vertices[:, 2].min()
        (tip_px, tail_px), _ = cs.world_to_pixels(np.vstack([tip, tail]), render.view_projection, render.size)
        axis = (tip_px - tail_px) / np.linalg.norm(tip_px - tail_px)
        ys, xs = np.nonzero(mask)
        pts = np.column_stack([xs + 0.5, ys + 0.5])
        far = pts[np.argmax((pts - tail_px) @ axis)]
        # the drawn tip is where the projected nose is (its last pixel or two are thinner than a pixel)
        assert np.linalg.norm(far - tip_px) < 3.0, (nose, far, tip_px)
        # and the mask is wide at the tail, narrow at the nose
        along = (pts - tail_px) @ axis
        length = np.linalg.norm(tip_px - tail_px)
        across = np.abs((pts - tail_px) @ np.array([-axis[1], axis[0]]))
        assert across[along < 0.2 * length].max() > 3 * across[along > 0.8 * length].max()
        w.delete_entity(ship)


def test_entities_sharing_a_mesh_are_drawn_in_one_instanced_call(make):
    w, _, render = make(lod=False, cull=False)
    cache = w.resources[ModelCache]
    rng = np.random.default_rng(5)
    for i in range(50):
        cache.variant(f"asteroid_{i}", "sphere", scale=float(rng.uniform(0.3, 1.5)))
        w.create_entity(Transform(rng.uniform(-8, 8, 3) + [0, 0, 30]), ModelRef(f"asteroid_{i}"))
    w.create_entity(Transform((0.0, -2.0, 8.0)), ModelRef("ship"))
    frame(w, render)
    assert render.stats["draw_calls"] == 2                 # all 50 asteroids in one call, the ship in another
    assert render.stats["instances"] == 51
    assert render.stats["levels"] == {"sphere[4]": 50, "ship[0]": 1}
    render.lod = True
    frame(w, render)
    levels_used = len([k for k in render.stats["levels"] if k.startswith("sphere")])
    assert render.stats["draw_calls"] == levels_used + 1   # one call per level of detail in use


def scattered(w, n=300, seed=9, spread=60.0):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-spread, spread, (n, 3))
    for i, (p, r) in enumerate(zip(pos, rng.uniform(0.3, 3.0, n))):
        name = f"rock_{i}"
        w.resources[ModelCache].variant(name, "sphere", scale=float(r))
        w.create_entity(Transform(p), ModelRef(name))
    return n


def test_culling_skips_what_is_outside_the_view_without_changing_the_image(make):
    w1, _, r1 = make(cull=False, lod=False)
    w2, _, r2 = make(cull=True, lod=False)
    n = scattered(w1)
    scattered(w2)
    a, b = frame(w1, r1), frame(w2, r2)
    assert r2.stats["culled"] > n // 2                      # most of a sphere of rocks is out of view
    assert r2.stats["instances"] + r2.stats["culled"] == n
    assert r1.stats["instances"] == n
    np.testing.assert_array_equal(a, b)


def test_level_of_detail_uses_coarse_spheres_far_away_and_keeps_the_image(make):
    w1, _, full = make(lod=False)
    w2, _, lod = make(lod=True)
    for w in (w1, w2):
        w.create_entity(Transform((0.0, 0.0, 2.5)), ModelRef("sphere"))      # big and near
        for k in range(8):
            w.create_entity(Transform((k * 4.0 - 14.0, 3.0, 150.0)), ModelRef("sphere"))   # specks far away
    a, b = frame(w1, full).astype(int), frame(w2, lod).astype(int)
    assert lod.stats["levels"] == {"sphere[0]": 8, "sphere[4]": 1}
    assert np.abs(a - b)[..., :3].mean() < 0.05                              # mean error, grey levels
    assert (np.abs(a - b)[..., :3].max(axis=-1) > 40).sum() < 10             # a few outline pixels at most


def test_instanced_and_per_entity_draws_give_the_same_picture(make):
    w1, _, inst = make()
    w2, _, each = make(instanced=False)
    n = scattered(w1, 100, spread=30.0)
    scattered(w2, 100, spread=30.0)
    a, b = frame(w1, inst).astype(int), frame(w2, each).astype(int)
    assert each.stats["draw_calls"] == each.stats["instances"] > 5
    assert inst.stats["draw_calls"] < 6
    assert inst.stats["instances"] == each.stats["instances"] <= n
    assert np.abs(a - b).mean() < 0.1


def test_cockpit_camera_does_not_draw_the_ship_it_sits_in(make):
    w, eye, render = make()
    esper.add_component(eye, ModelRef("ship"))
    w.create_entity(Transform((0.0, 0.0, 10.0)), ModelRef("sphere"))
    frame(w, render)
    assert render.stats["levels"] == {"sphere[2]": 1}
    cs.switch_camera(w, "chase")
    frame(w, render)
    assert render.stats["instances"] == 2


def test_a_later_render_system_draws_on_top_of_the_same_frame(make):
    w, _, render = make(skybox=True)
    w.create_entity(Transform((0.0, 0.0, 10.0)), ModelRef("sphere"))

    class Hud:
        stage = "render"

        def process(self, dt):
            r = w.get_system(RenderSystem)
            r.target.use()
            r.ctx.scissor = (0, r.size[1] - 10, 10, 10)           # GL's y from the bottom: the top-left corner
            r.ctx.clear(1.0, 0.0, 1.0, 1.0)
            r.ctx.scissor = None
            self.seen = (r.view_projection.copy(), r.viewport, r.size)

    hud = w.add_system(Hud())
    img = frame(w, render)
    np.testing.assert_array_equal(img[:10, :10].reshape(-1, 4), [[255, 0, 255, 255]] * 100)
    assert not (img[10:, 10:, 0] == 255).all()
    vp, viewport, size = hud.seen
    assert viewport == (0, 0, W, H) and size == (W, H)
    px, _ = cs.world_to_pixels(np.array([[0.0, 0.0, 10.0]]), vp, size)
    np.testing.assert_allclose(px[0], [W / 2, H / 2], atol=1e-9)


def test_same_scene_renders_to_identical_bytes(make):
    imgs = []
    for _ in range(2):
        w, _, render = make(skybox=True)
        scattered(w, 200, seed=1, spread=40.0)
        imgs.append(frame(w, render))
    np.testing.assert_array_equal(imgs[0], imgs[1])


def test_groups_are_rebuilt_only_when_entities_change(make):
    w, _, render = make()
    w.create_entity(Transform((0.0, 0.0, 10.0)), ModelRef("sphere"))
    frame(w, render)
    version = render._rows.version
    for _ in range(3):
        frame(w, render)
    assert render._rows.version == version
    w.create_entity(Transform((2.0, 0.0, 10.0)), ModelRef("ship"))
    frame(w, render)
    assert render._rows.version == version + 1
    assert render.stats["instances"] == 2


def test_unknown_model_and_missing_camera_are_clear_errors(ctx, make):
    w, _, render = make()
    bad = w.create_entity(Transform((0.0, 0.0, 5.0)), ModelRef("astroid"))
    with pytest.raises(ValueError, match=f"ModelRef on entity {bad}: unknown model 'astroid'; known models"):
        w.render()
    w.resources[ModelCache].variant("astroid", "sphere", scale=2.0)   # fixed: drawn on the next frame
    w.render()
    assert render.stats["instances"] == 1
    w2 = World()
    try:
        attach(w2, ctx, (32, 32))
        with pytest.raises(LookupError, match="no active Camera"):
            w2.render()
        with pytest.raises(ValueError, match="attached to this world already"):
            attach(w2, ctx, (32, 32))
    finally:
        w2.close()


def test_attach_fills_the_world_resources_and_close_releases_them(ctx):
    w = World()
    render = attach(w, ctx, (64, 48))
    res = dict(w.resources)
    assert list(res) == [ModelCache, RenderTarget, ContextHandle]           # (their release order on close)
    assert res[ContextHandle].ctx is ctx and not res[ContextHandle].owned
    assert res[RenderTarget].size == (64, 48) and render.target is res[RenderTarget]
    assert [type(s).__name__ for s in w.systems["render"]] == ["RenderSystem", "SkyboxSystem"]
    assert [type(s).__name__ for s in w.systems["camera"]] == ["CameraSystem"]
    w.close()
    assert res[RenderTarget].fbo is None and res[ModelCache].buffers_alive == 0
    assert ctx.version_code >= 330                          # the shared context lives on


def test_a_camera_made_after_attach_is_drawn_from_its_target_and_only_the_camera_stage_places_it(make):
    w, eye, render = make()
    w.create_entity(Transform((0.0, 0.0, 10.0)), ModelRef("sphere", colour=(1.0, 1.0, 1.0)))
    before = frame(w, render)
    for ent, cam in list(esper.get_component(Camera)):
        cam.active = False
    second = w.create_entity(Camera(target=eye, mode="cockpit", fov=FOV, near=0.1, far=1000.0))
    np.testing.assert_array_equal(frame(w, render), before)          # the same eye, snapped on the target
    assert render.camera_entity == second
    assert esper.try_component(second, Transform) is None             # render wrote nothing
    w.step()
    assert esper.try_component(second, Transform) is not None          # the camera stage did
