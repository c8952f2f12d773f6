"""The model cache: GPU buffers built once per mesh; variants share them and add a scale."""
from __future__ import annotations

import numpy as np
import pytest

from driftframe.framework import meshes
from driftframe.framework.model_cache import ModelCache

pytestmark = pytest.mark.gl


class CountingContext:
    """Wraps a moderngl context and counts the buffers it creates."""

    def __init__(self, ctx):
        self._ctx = ctx
        self.buffers = []

    def buffer(self, *args, **kwargs):
        buf = self._ctx.buffer(*args, **kwargs)
        self.buffers.append(buf)
        return buf

    def __getattr__(self, name):
        return getattr(self._ctx, name)


def test_fifty_asteroid_variants_make_one_sphere_vertex_buffer_per_level(ctx):
    counting = CountingContext(ctx)
    cache = ModelCache(counting)
    try:
        radii = np.linspace(0.5, 6.0, 50)
        variants = [cache.variant(f"asteroid_{i}", "sphere", scale=r) for i, r in enumerate(radii)]
        pairs = [cache.buffers(v) for v in variants]
        levels = len(meshes.SPHERE_LEVELS)
        assert len(counting.buffers) == 2 * levels             # one vertex + one index buffer per level
        assert cache.buffers_created == 2 * levels
        for p in pairs[1:]:
            assert all(a[0] is b[0] and a[1] is b[1] for a, b in zip(p, pairs[0]))
        vbo_ids = {vbo.glo for vbo, _ in pairs[0]}
        assert len(vbo_ids) == levels
        # each level's vertex buffer holds that level's vertices (x y z nx ny nz float32)
        for (vbo, ibo), mesh in zip(pairs[0], meshes.sphere_lods()):
            assert vbo.size == len(mesh.vertices) * 6 * 4
            assert ibo.size == len(mesh.indices) * 4
        # and the variants differ only by their scale
        np.testing.assert_allclose([v.radius for v in variants], radii)
        np.testing.assert_allclose(variants[7].scale_matrix, np.diag([radii[7]] * 3 + [1.0]))
        # another base model builds its own buffers, once
        cache.buffers(cache.get("ship"))
        cache.buffers(cache.variant("big_ship", "ship", scale=2.0))
        assert len(counting.buffers) == 2 * levels + 2
    finally:
        cache.release()


def test_variants_scale_and_colour_and_compose(ctx):
    cache = ModelCache(ctx)
    a = cache.variant("rock", "sphere", scale=(1.0, 2.0, 3.0), colour=(0.5, 0.2, 0.1))
    b = cache.variant("big_rock", "rock", scale=2.0)
    np.testing.assert_allclose(b.scale, [2.0, 4.0, 6.0])
    np.testing.assert_allclose(b.colour, [0.5, 0.2, 0.1])           # inherited
    assert b.meshes is a.meshes is cache.get("sphere").meshes
    assert b.base == "sphere"
    assert cache.variant("rock", "sphere", scale=(1.0, 2.0, 3.0), colour=(0.5, 0.2, 0.1)) is a   # idempotent
    with pytest.raises(ValueError, match="'rock' exists already"):
        cache.variant("rock", "sphere", scale=5.0)
    cache.release()


def test_bad_names_and_values_are_clear_errors(ctx):
    cache = ModelCache(ctx)
    with pytest.raises(KeyError, match=r"unknown model 'astroid'; known models: .*sphere"):
        cache.get("astroid")
    with pytest.raises(KeyError, match="unknown model 'rokc'"):
        cache.variant("x", "rokc")
    with pytest.raises(ValueError, match=r"variant 'x' scale must be > 0, got -1.0"):
        cache.variant("x", "sphere", scale=-1.0)
    with pytest.raises(ValueError, match="must be > 0 on every axis"):
        cache.variant("x", "sphere", scale=(1.0, 0.0, 1.0))
    with pytest.raises(ValueError, match=r"colour must be RGB numbers in \[0, 1\]"):
        cache.variant("x", "sphere", colour=(2.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="defined already"):
        cache.define("sphere", meshes.icosphere(1))
    with pytest.raises(ValueError, match="coarse to fine"):
        cache.define("backwards", [meshes.icosphere(2), meshes.icosphere(0)])


def test_release_frees_the_buffers_and_they_are_rebuilt_on_next_use(ctx):
    cache = ModelCache(ctx)
    cache.buffers(cache.get("sphere"))
    assert cache.buffers_alive == 2 * len(meshes.SPHERE_LEVELS)
    cache.release()
    assert cache.buffers_alive == 0
    cache.release()
    cache.buffers(cache.get("sphere"))
    assert cache.buffers_created == 4 * len(meshes.SPHERE_LEVELS)
    cache.release()


# -- models from files ------------------------------------------------------------------------------
def need_trimesh():
    """trimesh, or a skip where the 'assets' extra is not installed (CI installs it: there a failure)."""
    import os
    if os.environ.get("CI"):
        import trimesh
        return trimesh
    return pytest.importorskip("trimesh", reason="the 'assets' extra (trimesh) is not installed")


def rock_file(path):
    """An off-centre, lopsided closed solid (a box with one corner pulled out), written as GLB."""
    trimesh = need_trimesh()
    box = trimesh.creation.box((2.0, 1.0, 3.0))
    v = box.vertices.copy()
    v[np.argmax(v.sum(axis=1))] *= 2.5                       # the (+, +, +) corner
    trimesh.Trimesh(v + [10.0, 0.0, -4.0], box.faces).export(str(path))
    return path


def test_a_loaded_model_gets_scaled_variants_that_share_its_buffers(ctx, tmp_path):
    path = rock_file(tmp_path / "rock.glb")
    counting = CountingContext(ctx)
    cache = ModelCache(counting, builtins=False)
    try:
        base = cache.load("rock", path, colour=(0.5, 0.4, 0.3))
        np.testing.assert_allclose(meshes.volume_centroid(base.meshes.lods[0].vertices,
                                                          base.meshes.lods[0].indices)[1], 0.0, atol=1e-5)
        sizes = [0.5, 1.0, 2.5]
        variants = [cache.variant(f"rock_{i}", "rock", scale=s) for i, s in enumerate(sizes)]
        pairs = [cache.buffers(v) for v in variants]
        assert len(counting.buffers) == 2 and cache.buffers_created == 2       # one vertex + one index buffer
        assert all(p[0][0] is pairs[0][0][0] and p[0][1] is pairs[0][0][1] for p in pairs)
        np.testing.assert_allclose([v.radius for v in variants], np.array(sizes) * base.radius)
        assert all(v.base == "rock" for v in variants)
        np.testing.assert_allclose(variants[1].colour, [0.5, 0.4, 0.3])
        # nothing half-made: a bad file leaves no entry, a taken name is refused before reading
        with pytest.raises(FileNotFoundError, match="gone.obj' not found"):
            cache.load("gone", tmp_path / "gone.obj")
        assert "gone" not in cache
        with pytest.raises(ValueError, match="'rock' is defined already"):
            cache.load("rock", path)
    finally:
        cache.release()


def test_a_declared_model_file_is_loaded_when_rendering_is_attached_and_drawn(ctx, tmp_path, world):
    from driftframe.app import attach_rendering
    from driftframe.components.body import Transform
    from driftframe.components.camera import Camera
    from driftframe.components.render import ModelRef
    from driftframe.framework import frame as fr
    from driftframe.framework.model_cache import declare_model_file, declare_variant
    from driftframe.framework.world import World

    path = rock_file(tmp_path / "rock.glb")
    w = World()
    try:
        declare_model_file(w, "rock", path, colour=(1.0, 0.5, 0.0))
        declare_variant(w, "big_rock", "rock", scale=2.0)
        eye = w.create_entity(Transform((0.0, 0.0, -20.0), fr.look_rotation((0.0, 0.0, 1.0))))
        w.create_entity(Camera(target=eye, mode="cockpit"))
        w.create_entity(Transform((-4.0, 0.0, 0.0)), ModelRef("rock"))
        w.create_entity(Transform((4.0, 0.0, 0.0)), ModelRef("big_rock"))
        render = attach_rendering(w, ctx, size=(160, 90), hud=False, sky=False)
        w.step()
        w.render()
        img = render.read_rgba().astype(int)
        orange = (img[..., 0] > 2 * img[..., 2] + 20) & (img[..., 0] > 40)
        left, right = orange[:, :80].sum(), orange[:, 80:].sum()
        assert left > 20 and right > 3 * left                      # both drawn; the variant twice the size
        assert render.stats["draw_calls"] == 1                     # one mesh: one instanced call for both
    finally:
        w.close()
    with pytest.raises(FileNotFoundError, match="nope.glb' not found"):
        declare_model_file(world, "x", tmp_path / "nope.glb")
