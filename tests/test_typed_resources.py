"""The framework's resources are keyed by type (issue 22): the scene's Seed and SceneRecipe, and rendering's
ModelCache, RenderTarget and ContextHandle. Their old string names are an error naming the type; the
systems that touch them declare them, so describe() shows them, the checking mode holds systems to them,
and the drawers of a frame are ordered by after=, never by the adding order."""
import warnings

import esper
import pytest

from driftframe.app import attach_rendering, make_world
from driftframe.framework.access_check import AccessError
from driftframe.framework.gl import ContextHandle, RenderTarget
from driftframe.framework.model_cache import ModelCache
from driftframe.framework.resources import RENAMED
from driftframe.framework.scene import SceneRecipe, Seed, seed_of
from driftframe.framework.world import ScheduleAmbiguityWarning, World
from driftframe.systems.skybox import StarfieldSystem


def test_make_world_keys_the_seed_and_the_recipe_by_type():
    world, demo = make_world("spin", seed=4)
    try:
        assert world.resource(Seed) == Seed(4) and seed_of(world) == 4
        recipe = world.resource(SceneRecipe)
        assert recipe.scene is demo and recipe.manifest() == {
            "name": "spin", "seed": 4, "scripted": True, "collision": "continuous", "track": False,
            "builder": "driftframe.app:make_world"}
        assert not any(isinstance(k, str) for k in dict(world.resources))       # no string key left
    finally:
        world.close()


def test_a_world_built_by_hand_has_no_seed_and_says_who_makes_one():
    w = World()
    assert seed_of(w) == 0 and seed_of(w, 3) == 3
    with pytest.raises(KeyError, match=r"has no Seed resource: driftframe.make_world sets it"):
        w.resource(Seed)
    w.resources[Seed] = Seed(9)
    assert seed_of(w) == 9
    w.close()


@pytest.mark.parametrize("bad", [-1, 1.5, True, "3"])
def test_a_seed_that_is_not_an_int_at_least_zero_is_an_error_naming_it(bad):
    with pytest.raises(ValueError, match=r"Seed must be an int >= 0, got"):
        Seed(bad)


@pytest.mark.parametrize("name", sorted(RENAMED))
def test_an_old_string_name_read_or_written_is_an_error_naming_its_type(name):
    w = World()
    new = RENAMED[name].split(" ")[0]
    message = rf"world.resources\['{name}'\] is keyed by its type now: world.resources\[{new} "
    for touch in (lambda: w.resources[name], lambda: w.resources.get(name), lambda: name in w.resources):
        with pytest.raises(KeyError, match=message):
            touch()
    with pytest.raises(KeyError, match=message):
        w.resources[name] = 1
    assert dict(w.resources) == {}
    w.close()


def _frame_systems(world):
    return [type(e.system).__name__ for e in world._order["frame"]]


@pytest.mark.gl
def test_attach_rendering_keys_its_resources_by_type_and_orders_every_drawer_with_after(ctx):
    with warnings.catch_warnings():
        warnings.simplefilter("error", ScheduleAmbiguityWarning)        # every drawer ordered: no warning
        world, _ = make_world("orbit", seed=2)
        try:
            render = attach_rendering(world, ctx, (64, 48), sky="starfield")
            assert world.resource(RenderTarget) is render.target and world.resource(ModelCache) is render.cache
            assert world.resource(ContextHandle).ctx is ctx
            assert world.get_system(StarfieldSystem).seed == 2                  # its cube map from the Seed
            assert _frame_systems(world) == ["RenderSystem", "StarfieldSystem", "EffectsSystem", "HudSystem",
                                             "SoundSystem"]
            text = world.describe()
            assert "RenderSystem" in text and "reads:  Transform, ModelRef, Camera, ModelCache\n" in text
            assert text.count("writes: RenderTarget\n") == 4               # render, starfield, effects, HUD
            assert text.endswith("resources: ContextHandle, ModelCache, ModelVariants, OrbitState, RenderTarget, "
                                 "SceneRecipe, Seed, Soundtrack\n")
            world.step()
            world.render()
        finally:
            world.close()


@pytest.mark.gl
def test_a_drawer_added_without_an_order_is_named_and_one_after_the_drawers_is_not(ctx):
    class Overlay(esper.Processor):
        stage = "render"
        reads = ()
        writes = (RenderTarget,)

        def process(self, dt):
            pass

    from driftframe.rendering import attach, drawn_before

    w = World()
    try:
        attach(w, ctx, (32, 32))
        with warnings.catch_warnings(record=True) as got:
            warnings.simplefilter("always")
            w.add_system(Overlay())
        named = sorted(str(g.message).split(",")[0] for g in got if g.category is ScheduleAmbiguityWarning)
        assert named == ["systems 'render' and 'overlay' both touch RenderTarget",
                         "systems 'skybox' and 'overlay' both touch RenderTarget"]
        with warnings.catch_warnings():
            warnings.simplefilter("error", ScheduleAmbiguityWarning)
            w.add_system(Overlay(), name="overlay_2", after=drawn_before(w))
        assert _frame_systems(w)[-1] == "Overlay"
    finally:
        w.close()


def test_a_system_reading_a_rendering_resource_it_does_not_declare_is_an_error():
    class Peek(esper.Processor):
        reads = ()

        def process(self, dt):
            self.world.resources.get(ModelCache)

    class Reader(esper.Processor):
        reads = (ModelCache, Seed)

        def process(self, dt):
            self.world.resources.get(ModelCache), self.world.resources.get(Seed)

    w = World()
    try:
        w.add_system(Reader())
        w.step()
        w.add_system(Peek())
        with pytest.raises(AccessError, match=r"system 'peek' \(Peek\) touches ModelCache"):
            w.step()
    finally:
        w.close()
