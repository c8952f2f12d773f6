"""The look of the demos: rock meshes (shared by their scaled variants), the default sky."""
from __future__ import annotations

import numpy as np
import pytest

from driftframe.framework import meshes
from driftframe.framework.model_cache import ModelCache, ModelVariants


def test_rocks_are_bounded_by_the_unit_sphere_centred_on_their_mass_and_not_round():
    for k in range(meshes.ROCK_SHAPES):
        lods = meshes.rock_lods(k)
        assert [m.primitive_count for m in lods] == [20 * 4 ** lv for lv in meshes.ROCK_LEVELS]
        assert max(m.radius for m in lods) == pytest.approx(1.0, abs=1e-6)      # the collision sphere bounds it
        fine = lods[-1]
        f = np.arange(len(fine.vertices)).reshape(-1, 3)
        volume, centre = meshes.volume_centroid(fine.vertices.astype(np.float64), f)
        assert np.abs(centre).max() < 1e-5                                        # spins about its mass
        assert volume > 0                                                         # wound outward
        r = np.linalg.norm(fine.vertices, axis=1)
        assert r.min() < 0.75 * r.max()                                           # lumpy and stretched
    # seeded: the same shape each time, another seed another shape
    a, b = meshes.rock_lods(0)[-1], meshes.rock_lods(1)[-1]
    assert not np.array_equal(a.vertices, b.vertices)
    meshes.rock_lods.cache_clear()
    np.testing.assert_array_equal(meshes.rock_lods(0)[-1].vertices, a.vertices)
    with pytest.raises(ValueError, match="rock seed must be an int >= 0, got -1"):
        meshes.rock_lods(-1)


@pytest.mark.gl
def test_fifty_rock_variants_share_one_vertex_buffer_per_shape_and_level(ctx):
    from driftframe.framework.model_cache import ModelCache

    cache = ModelCache(ctx)
    try:
        before = cache.buffers_created
        variants = [cache.variant(f"asteroid_{i}", f"rock{i % meshes.ROCK_SHAPES}", scale=0.5 + 0.1 * i)
                    for i in range(50)]
        vbos = {id(vbo) for v in variants for vbo, _ in cache.buffers(v)}
        levels = len(meshes.ROCK_LEVELS)
        assert len(vbos) == meshes.ROCK_SHAPES * levels
        assert cache.buffers_created - before == 2 * meshes.ROCK_SHAPES * levels   # vertex + index, once each
        assert cache.buffers(variants[0]) is cache.buffers(variants[4])             # same shape: same buffers
    finally:
        cache.release()


def test_the_asteroids_are_rocks_and_the_rotation_demo_keeps_the_green_lines():
    from driftframe import demos
    from driftframe.app import make_world
    from driftframe.rendering import default_sky

    world, demo = make_world("asteroids", seed=0)
    try:
        bases = {base for name, (base, _, _) in world.resources[ModelVariants].items()
                 if name.startswith("asteroid_")}
        assert bases == {f"rock{k}" for k in range(meshes.ROCK_SHAPES)}
    finally:
        world.close()
    assert default_sky(demos.load("asteroids")) == "starfield"
    assert default_sky(demos.load("rotation")) == "lines"


@pytest.mark.gl
def test_a_contact_shows_sparks_the_same_every_run_and_the_simulation_does_not_see_them():
    from driftframe.app import attach_rendering, make_world
    from driftframe.systems.effects import EffectsSystem

    def run(effects):
        world, _ = make_world("cradle")
        try:
            render = attach_rendering(world, size=(64, 48), hud=False, sky="lines", sound=False, effects=effects)
            world.step(61)                           # the striker hits the row at t = 1.0 s (step 60)
            world.render()
            fx = world.get_system(EffectsSystem)
            return render.read_rgba().copy(), world.state_hash(), fx.drawn if fx else 0
        finally:
            world.close()

    (a, ha, n), (b, hb, _), (bare, h0, _) = run(True), run(True), run(False)
    assert n > 6                                     # a burst of sparks and a flash
    np.testing.assert_array_equal(a, b)              # deterministic
    assert ha == hb == h0                            # presentation only
    assert np.any(a != bare)


@pytest.mark.gl
def test_the_hud_font_has_latin_1_and_the_signs_a_flight_needs(ctx):
    from driftframe.systems.hud import FontAtlas

    font = FontAtlas(ctx, 18)
    try:
        atlas = np.frombuffer(font.texture.read(), np.uint8).reshape(font.image_size[1], font.image_size[0])
        cw, ch = font.cell

        def ink(c):
            i = font.index[c]
            r, k = divmod(i, font.COLUMNS)
            return atlas[r * ch:(r + 1) * ch, k * cw:(k + 1) * cw].astype(int)

        question = ink("?")
        for c in "Δ°×±→éßµ½ÅΩπ≈":
            assert c in font.index and ink(c).sum() > 0 and not np.array_equal(ink(c), question), c
        assert not np.array_equal(ink("Δ"), ink("A"))
        assert len(font.quads("Δv 12 m/s → 45°", 0, 0)) == 6 * 15          # two triangles a character
    finally:
        font.release()


@pytest.mark.gl
def test_the_planet_hides_the_far_side_of_the_predicted_orbit(ctx, world):
    from driftframe.app import attach_rendering
    from driftframe.components.body import AngularVelocity, Transform, Velocity
    from driftframe.components.camera import Camera
    from driftframe.components.control import Player
    from driftframe.components.gravity import GravityWell
    from driftframe.components.render import ModelRef
    from driftframe.framework import frame as fr
    from driftframe.framework.model_cache import declare_variant
    from driftframe.systems import readouts
    from driftframe.systems.gravity import GravitySystem
    from driftframe.systems.hud import ORBIT_COLOUR

    mu, R = 3.75e6, 1000.0
    world.add_system(GravitySystem())
    world.create_entity(Transform(), GravityWell(mu=mu, radius=R),
                        ModelRef(declare_variant(world, "planet", "sphere", scale=R, colour=(0.8, 0.3, 0.2))))
    ship = world.create_entity(Player(), Transform((1100.0, 0.0, 0.0)), Velocity((0.0, 0.0, -np.sqrt(mu / 1100))),
                               AngularVelocity(), ModelRef("ship"))
    eye_at = np.array([0.0, 900.0, 3600.0])                # above the orbit's plane, looking at the planet
    eye = world.create_entity(Transform(eye_at, fr.look_rotation(-eye_at, (0.0, 1.0, 0.0))))
    world.create_entity(Camera(target=eye, mode="cockpit", fov=60.0, far=20_000.0))
    W, H = 200, 150
    render = attach_rendering(world, ctx, size=(W, H), own_context=False, sky=False, sound=False, effects=False)
    world.step(1)
    world.render()
    img = render.read_rgba()[:, :, :3].astype(int)
    pts = readouts.predicted_orbit(world, ship)
    clip = np.hstack([pts, np.ones((len(pts), 1))]) @ render.view_projection.T
    px = np.stack([(clip[:, 0] / clip[:, 3] + 1) * 0.5 * W, (1 - clip[:, 1] / clip[:, 3]) * 0.5 * H], 1)
    # hidden: the segment from the eye to the point passes through the planet (a ray-sphere test)
    d = pts - eye_at
    t = np.clip(-(eye_at @ d.T) / np.einsum("ij,ij->i", d, d), 0.0, 1.0)
    hidden = np.linalg.norm(eye_at + t[:, None] * d, axis=1) < R * 0.98
    orbit = np.array(ORBIT_COLOUR[:3]) * 255
    shown = np.array([np.abs(img[int(round(y)), int(round(x))] - orbit).max() < 60
                      for x, y in px], bool)
    assert hidden.sum() > 10 and (~hidden).sum() > 10
    assert shown[~hidden].mean() > 0.5          # the near side is drawn
    assert shown[hidden].mean() < 0.1           # the far side is behind the planet


@pytest.mark.gl
@pytest.mark.parametrize("distance, marked", [(300.0, True), (6.0, False)])
def test_a_ship_too_small_to_see_gets_brackets_and_a_near_one_none(ctx, world, distance, marked):
    from driftframe.app import attach_rendering
    from driftframe.components.body import AngularVelocity, Transform, Velocity
    from driftframe.components.camera import Camera
    from driftframe.components.control import Player
    from driftframe.components.render import ModelRef
    from driftframe.systems.hud import HudSystem, SHIP_MARK_COLOUR

    ship = world.create_entity(Player(), Transform(), Velocity((0.0, 0.0, 1.0)), AngularVelocity(), ModelRef("ship"))
    world.create_entity(Camera(target=ship, mode="chase", chase_distance=distance, chase_height=0.0, far=1e4))
    render = attach_rendering(world, ctx, size=(160, 90), own_context=False, sky=False, sound=False, effects=False)
    world.step(1)
    world.render()
    hud = world.get_system(HudSystem)
    assert ("ship" in hud.last["markers"]) is marked
    if marked:
        x, y = hud.last["markers"]["ship"]
        assert abs(x - 80) < 2 and abs(y - 45) < 2                  # on the ship, mid-frame
        img = render.read_rgba()[:, :, :3].astype(int)
        colour = np.array(SHIP_MARK_COLOUR[:3]) * 255
        assert (np.abs(img - colour).max(axis=2) < 70).sum() > 20     # the brackets are drawn


# 16 x 16 texels: quarters red (top-left), green, blue, white; whole quarters, so filtering keeps their middles
CHECKER = np.kron(np.array([[[255, 0, 0], [0, 255, 0]],
                            [[0, 0, 255], [255, 255, 255]]]), np.ones((8, 8, 1))).astype(np.uint8)


def _square(uv_top_left=(0.0, 0.0)):
    """A 2 m square in the z = 0 plane facing -z (towards an eye on -z), uvs (0, 0) at its top-left."""
    v = np.array([[-1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [-1.0, -1.0, 0.0]])  # the eye's right is +x
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) + np.asarray(uv_top_left)
    f = np.array([[0, 1, 2], [0, 2, 3]])                     # (b - a) x (c - a) along -z: facing the eye
    return v, f, uv


def _shot(ctx, world, model, colour=(1.0, 1.0, 1.0)):
    from driftframe.app import attach_rendering
    from driftframe.components.body import Transform
    from driftframe.components.camera import Camera
    from driftframe.components.render import ModelRef
    from driftframe.framework import frame as fr

    eye = world.create_entity(Transform((0.0, 0.0, -3.0), fr.look_rotation((0.0, 0.0, 1.0))))
    world.create_entity(Camera(target=eye, mode="cockpit", fov=60.0))
    render = attach_rendering(world, ctx, size=(64, 64), own_context=False, sky=False, hud=False, sound=False,
                              effects=False, ambient=1.0, fill=0.0, lod=False)      # unlit: colour = texel
    model(world.resources[ModelCache])
    world.create_entity(Transform(), ModelRef("square", colour=colour))
    world.step(1)
    world.render()
    return render.read_rgba()[:, :, :3].astype(int)


@pytest.mark.gl
def test_a_textured_procedural_mesh_shows_its_texels_the_right_way_up(ctx, world):
    v, f, uv = _square()
    img = _shot(ctx, world, lambda cache: cache.define("square", meshes.flat_shaded("square", v, f, uvs=uv),
                                                        colour=(1.0, 1.0, 1.0), texture=CHECKER))
    # the square spans about 37 px mid-frame; each quarter shows its texel (linear filtering blends the middles)
    q = {"top-left": img[20, 20], "top-right": img[20, 43], "bottom-left": img[43, 20], "bottom-right": img[43, 43]}
    np.testing.assert_allclose(q["top-left"], [255, 0, 0], atol=12)
    np.testing.assert_allclose(q["top-right"], [0, 255, 0], atol=12)
    np.testing.assert_allclose(q["bottom-left"], [0, 0, 255], atol=12)
    np.testing.assert_allclose(q["bottom-right"], [255, 255, 255], atol=12)
    cache = world.resources[ModelCache]
    with pytest.raises(ValueError, match="model 'bare': a texture needs uvs on every level"):
        cache.define("bare", meshes.box(), texture=CHECKER)
    with pytest.raises(ValueError, match=r"model 'flat' texture must be an \(H, W, 3 or 4\) uint8 image"):
        cache.define("flat", meshes.flat_shaded("flat", v, f, uvs=uv), texture=np.zeros((4, 4), np.uint8))


@pytest.mark.gl
def test_a_glb_model_keeps_its_uvs_and_base_colour_texture(ctx, world, tmp_path):
    trimesh = pytest.importorskip("trimesh")
    from PIL import Image

    v, f, uv = _square()
    # a closed model is what load_model centres on its mass; a flat square is centred on its area: the same here
    tm = trimesh.Trimesh(v, f, process=False,
                         visual=trimesh.visual.TextureVisuals(uv=np.column_stack([uv[:, 0], 1.0 - uv[:, 1]]),
                                                              image=Image.fromarray(CHECKER)))
    path = tmp_path / "square.glb"
    tm.export(path)
    mesh, texture, _ = meshes.load_model(path)
    assert mesh.uvs is not None and texture.shape == (16, 16, 4)
    np.testing.assert_array_equal(texture[:, :, :3], CHECKER)
    img = _shot(ctx, world, lambda cache: cache.load("square", path))
    np.testing.assert_allclose(img[20, 20], [255, 0, 0], atol=12)           # red top-left, as in the image
    np.testing.assert_allclose(img[43, 20], [0, 0, 255], atol=12)


def test_billiards_keeps_every_ball_on_the_table_for_30_s_and_the_break_varies_with_the_seed():
    import esper

    from driftframe.app import make_world
    from driftframe.components.body import Transform, Velocity
    from driftframe.demos import billiards as table

    def run(seed, steps):
        world, _ = make_world("billiards", seed=seed)
        try:
            balls = sorted(e for e, _ in esper.get_component(Velocity))
            v0 = np.array([esper.component_for_entity(e, Velocity).linear for e in balls])
            lo = np.array([table.CENTRE[0] - table.TABLE[0] / 2, table.CENTRE[1] - table.TABLE[1] / 2]) + table.R
            hi = np.array([table.CENTRE[0] + table.TABLE[0] / 2, table.CENTRE[1] + table.TABLE[1] / 2]) - table.R
            worst = 0.0
            for _ in range(steps // 60):
                world.step(60)
                p = np.array([esper.component_for_entity(e, Transform).position for e in balls])
                worst = max(worst, float(np.max(p[:, [0, 2]] - hi)), float(np.max(lo - p[:, [0, 2]])))
                assert np.all(p[:, 1] == 0.0)
            v = np.array([esper.component_for_entity(e, Velocity).linear for e in balls])
            return v0, v, worst
        finally:
            world.close()

    v0, v, worst = run(0, 30 * 60)
    assert len(v0) == 16
    assert worst <= 0.006                       # on the felt (the rail is flat to 5 mm between its spheres)
    e0, e1 = 0.5 * (v0 ** 2).sum(), 0.5 * (v ** 2).sum()
    assert abs(e1 - e0) <= 1e-12 * e0           # e = 1 on the cushions and between balls: energy kept
    assert np.count_nonzero(np.linalg.norm(v, axis=1) > 0.1) >= 8    # still rolling about, not parked
    other = run(1, 60)[0]
    assert not np.array_equal(other[-1], v0[-1])                   # the cue ball's heading follows the seed


@pytest.mark.gl
def test_the_orbit_hud_covers_at_most_a_sixth_of_a_640x360_frame(ctx):
    from driftframe.app import attach_rendering, make_world
    from driftframe.systems.hud import HudSystem

    world, _ = make_world("orbit")
    try:
        attach_rendering(world, ctx, size=(640, 360), own_context=False, sound=False, effects=False)
        world.step(15 * 60)                      # the readouts, the target and the autopilot's line
        world.render()
        hud = world.get_system(HudSystem)
        text, font = hud.last["text"], hud.font
        assert len(text) >= 9 and any(line.startswith("CLOSEST") for line in text)
        width = max(sum(font.advance.get(c, font.advance["?"]) for c in line) for line in text) + font.line_height
        height = (len(text) + 1) * font.line_height
        assert width * height <= 640 * 360 / 6, (width, height)
    finally:
        world.close()


@pytest.mark.gl
def test_a_touchdown_on_a_wells_surface_shows_sparks_under_the_body(ctx, world):
    from driftframe.app import attach_rendering
    from driftframe.components.body import Transform
    from driftframe.components.camera import Camera
    from driftframe.components.gravity import SurfaceContact
    from driftframe.framework import frame as fr
    from driftframe.systems.effects import EffectsSystem

    well = world.create_entity(Transform())
    body = world.create_entity(Transform((0.0, 101.0, 0.0)))
    eye = world.create_entity(Transform((0.0, 101.0, -20.0), fr.look_rotation((0.0, 0.0, 1.0))))
    world.create_entity(Camera(target=eye, mode="cockpit"))
    attach_rendering(world, ctx, size=(64, 48), own_context=False, sky=False, hud=False, sound=False)
    world.step()
    world.emit(SurfaceContact(body, well, world.time, 5.0, 4.0))
    world.render()
    fx = world.get_system(EffectsSystem)
    assert fx.drawn > 20                                  # a burst and its flash
    np.testing.assert_allclose(fx._p[-1], (0.0, 100.0, 0.0))   # the flash: on the surface under the body
