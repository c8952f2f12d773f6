"""Normal maps (issue 25): glTF-convention tangents from a mesh's uvs, a model file's normalTexture kept,
and the light falling on the map's normals (checked against n . l on screen)."""
from __future__ import annotations

import numpy as np
import pytest

from driftframe.framework import meshes
from driftframe.framework.model_cache import ModelCache


def _square():
    """A 2 m square in the z = 0 plane facing -z (an eye on -z sees +x to its right), uv (0, 0) top-left."""
    v = np.array([[-1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [-1.0, -1.0, 0.0]])
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    return v, f, uv


def _encode(n):
    n = np.asarray(n, float) / np.linalg.norm(n)
    return np.round((n * 0.5 + 0.5) * 255).astype(np.uint8)


# 16 x 16, whole quarters (tangent space, glTF: x along u, y up the image, z out of the surface):
# top-left tilted along +u, top-right along -u, bottom-left up the image, bottom-right down it
TILT = 0.6, 0.8
BUMPS = np.kron(np.array([[_encode((TILT[0], 0, TILT[1])), _encode((-TILT[0], 0, TILT[1]))],
                          [_encode((0, TILT[0], TILT[1])), _encode((0, -TILT[0], TILT[1]))]]),
                np.ones((8, 8, 1), np.uint8)).astype(np.uint8)
FLAT = np.tile(_encode((0, 0, 1)), (4, 4, 1)).astype(np.uint8)


def test_tangents_follow_u_and_their_sign_says_which_way_is_up_the_image():
    v, f, uv = _square()
    m = meshes.tangent_frames(meshes.flat_shaded("sq", v, f, uvs=uv))
    # the normal is -z; u grows along +x; up the image (v falling) is +y = w (n x t) with n x t = -y: w = -1
    np.testing.assert_allclose(m.tangents, np.tile([1.0, 0.0, 0.0, -1.0], (6, 1)), atol=1e-6)
    mirrored = meshes.tangent_frames(meshes.flat_shaded("sq", v, f, uvs=np.column_stack([uv[:, 0], 1 - uv[:, 1]])))
    np.testing.assert_allclose(mirrored.tangents[:, 3], 1.0)          # the image upside down: the other hand
    turned = meshes.tangent_frames(meshes.flat_shaded("sq", v, f, uvs=uv[:, ::-1]))   # u down the square
    np.testing.assert_allclose(turned.tangents[:, :3], np.tile([0.0, -1.0, 0.0], (6, 1)), atol=1e-6)
    # a sphere's tangents are unit and perpendicular to its normals
    s = meshes.icosphere(2)
    uvs = np.column_stack([np.arctan2(s.vertices[:, 0], s.vertices[:, 2]) / (2 * np.pi) + 0.5,
                           np.arccos(np.clip(s.vertices[:, 1], -1, 1)) / np.pi])
    t = meshes.tangent_frames(meshes.Mesh("s", s.vertices, s.normals, s.indices, uvs=uvs)).tangents
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1.0, atol=1e-5)
    assert np.abs(np.sum(t[:, :3] * s.normals, axis=1)).max() < 1e-5 and set(np.unique(t[:, 3])) <= {-1.0, 1.0}


def test_bad_tangents_are_named():
    v, f, uv = _square()
    with pytest.raises(ValueError, match=r"tangents must be finite with shape \(4, 4\)"):
        meshes.Mesh("sq", v, np.tile([0.0, 0.0, -1.0], (4, 1)), f.ravel(), uvs=uv, tangents=np.zeros((4, 3)))
    with pytest.raises(ValueError, match="without uvs"):
        meshes.Mesh("sq", v, np.tile([0.0, 0.0, -1.0], (4, 1)), f.ravel(), tangents=np.zeros((4, 4)))
    with pytest.raises(ValueError, match="tangents need triangles with uvs"):
        meshes.tangent_frames(meshes.box())


def _shot(ctx, world, define, light):
    from driftframe.app import attach_rendering
    from driftframe.components.body import Transform
    from driftframe.components.camera import Camera
    from driftframe.components.render import ModelRef
    from driftframe.framework import frame as fr

    eye = world.create_entity(Transform((0.0, 0.0, -3.0), fr.look_rotation((0.0, 0.0, 1.0))))
    world.create_entity(Camera(target=eye, mode="cockpit", fov=60.0))
    # no ambient, no fill: a pixel is 255 (n . l), n the map's normal, l the light
    render = attach_rendering(world, ctx, size=(64, 64), own_context=False, sky=False, hud=False, sound=False,
                              effects=False, ambient=0.0, fill=0.0, lod=False, light_direction=light)
    define(world.resources[ModelCache])
    world.create_entity(Transform(), ModelRef("square", colour=(1.0, 1.0, 1.0)))
    world.step(1)
    world.render()
    img = render.read_rgba()[:, :, :3].astype(int)
    return {"tl": img[20, 20], "tr": img[20, 43], "bl": img[43, 20], "br": img[43, 43]}


def _expected(light, tilts):
    """255 max(n . l, 0) of each quarter: n = (tx t + ty b + tz n0) with t = +x, b = +y, n0 = -z."""
    l = np.asarray(light, float) / np.linalg.norm(light)
    out = {}
    for k, (a, b) in tilts.items():
        n = np.array([a, b, -np.sqrt(max(0.0, 1 - a * a - b * b))])
        out[k] = 255 * max(float(n @ l), 0.0)
    return out


QUARTERS = {"tl": (TILT[0], 0.0), "tr": (-TILT[0], 0.0), "bl": (0.0, TILT[0]), "br": (0.0, -TILT[0])}
LIGHTS = [(1.0, 0.0, -1.0), (0.0, 1.0, -1.0)]     # from the right of the picture; from its top


@pytest.mark.gl
@pytest.mark.parametrize("light", LIGHTS)
def test_the_light_falls_on_the_normal_maps_normals(ctx, world, light):
    v, f, uv = _square()
    mesh = meshes.tangent_frames(meshes.flat_shaded("square", v, f, uvs=uv))
    got = _shot(ctx, world, lambda cache: cache.define("square", mesh, colour=(1.0, 1.0, 1.0), normal_map=BUMPS),
                light)
    want = _expected(light, QUARTERS)
    for k in QUARTERS:
        np.testing.assert_allclose(got[k], [want[k]] * 3, atol=6, err_msg=k)
    # the shading responds to the map: the quarter tilted towards the light is the brightest by far
    lit = max(want, key=want.get)
    assert got[lit][0] > 250 and min(g[0] for g in got.values()) < 60


@pytest.mark.gl
def test_a_flat_normal_map_shades_as_the_mesh_does(ctx, world):
    v, f, uv = _square()
    mesh = meshes.tangent_frames(meshes.flat_shaded("square", v, f, uvs=uv))
    got = _shot(ctx, world, lambda cache: cache.define("square", mesh, normal_map=FLAT, colour=(1, 1, 1)), LIGHTS[0])
    for k in QUARTERS:
        np.testing.assert_allclose(got[k], [255 / np.sqrt(2)] * 3, atol=4, err_msg=k)
    cache = world.resources[ModelCache]
    with pytest.raises(ValueError, match="a normal map needs tangents on every level"):
        cache.define("bare", meshes.flat_shaded("bare", v, f, uvs=uv), normal_map=FLAT)


@pytest.mark.gl
def test_a_glb_models_normal_texture_is_read_and_lights_the_model(ctx, world, tmp_path):
    trimesh = pytest.importorskip("trimesh")
    from PIL import Image

    v, f, uv = _square()
    material = trimesh.visual.material.PBRMaterial(baseColorTexture=Image.new("RGB", (4, 4), (255, 255, 255)),
                                                   normalTexture=Image.fromarray(BUMPS))
    tm = trimesh.Trimesh(v, f, process=False,
                         visual=trimesh.visual.TextureVisuals(uv=np.column_stack([uv[:, 0], 1.0 - uv[:, 1]]),
                                                              material=material))
    path = tmp_path / "bumps.glb"
    tm.export(path)
    loaded = meshes.load_model(path)
    assert loaded.normal_map is not None and loaded.mesh.tangents is not None
    np.testing.assert_array_equal(loaded.normal_map[:, :, :3], BUMPS)
    got = _shot(ctx, world, lambda cache: cache.load("square", path, shading="flat"), LIGHTS[1])
    want = _expected(LIGHTS[1], QUARTERS)
    for k in QUARTERS:
        np.testing.assert_allclose(got[k], [want[k]] * 3, atol=6, err_msg=k)


@pytest.mark.gl
@pytest.mark.parametrize("texture", [None, np.full((2, 2, 3), 255, np.uint8)])
def test_a_mesh_with_tangents_but_no_normal_map_draws_as_before(ctx, world, texture):
    v, f, uv = _square()
    mesh = meshes.tangent_frames(meshes.flat_shaded("square", v, f, uvs=uv))
    assert mesh.interleaved().shape == (6, 12)           # x y z, normal, u v, tangent: columns skipped as needed
    got = _shot(ctx, world, lambda cache: cache.define("square", mesh, texture=texture, colour=(1, 1, 1)), LIGHTS[0])
    for k in QUARTERS:
        np.testing.assert_allclose(got[k], [255 / np.sqrt(2)] * 3, atol=4, err_msg=k)
