"""A World's lifecycle edges: copies and pickles refused (never a copy sharing esper's world), a step that
raises marks the world broken until a save is loaded, typed resources."""
import copy
import pickle

import esper
import numpy as np
import pytest

from driftframe.components.body import Transform, Velocity
from driftframe.framework.warp import TimeWarp
from driftframe.framework.world import World, WorldBrokenError
from driftframe.systems.movement import MovementSystem


def _hundred() -> World:
    w = World()
    w.add_system(MovementSystem())
    n = 100
    w.create_entities(Transform.bulk(n, position=np.arange(3 * n, dtype=float).reshape(n, 3)),
                      Velocity.bulk(n, linear=np.ones((n, 3))))
    w.step(3)
    return w


@pytest.mark.parametrize("how", [copy.copy, copy.deepcopy, lambda w: pickle.loads(pickle.dumps(w))],
                         ids=["copy", "deepcopy", "pickle"])
def test_a_world_is_never_copied_half_way_and_the_error_says_what_to_use(how):
    w = _hundred()
    before = w.state_hash()
    with pytest.raises(TypeError, match=r"cannot be (copied|pickled).*world\.save\(path\) then World\.load\(path\)"):
        how(w)
    assert w.state_hash() == before
    assert len(w.columns(Transform).entities) == 100      # nothing was shared and then deleted
    w.close()


def test_save_and_load_is_the_independent_copy(tmp_path):
    w = _hundred()
    w.save(tmp_path / "copy.npz")
    c = World.load(tmp_path / "copy.npz", build=lambda: World().add_system(MovementSystem()).world)
    assert c.state_hash() == w.state_hash()
    c.close()                                               # closing the copy leaves the original whole
    assert len(w.columns(Transform).entities) == 100
    w.step()
    w.close()


class Boom(esper.Processor):
    """Moves every body by 1 m (a change), then raises while ``fail`` is set."""
    stage = "collision"
    reads = (Transform,)
    writes = (Transform,)

    def __init__(self) -> None:
        self.fail = False

    def process(self, dt: float) -> None:
        for _, t in esper.get_component(Transform):
            t.position = t.position + 1.0
        if self.fail:
            raise ValueError("boom at the wall")


def test_a_step_that_raised_after_systems_ran_breaks_the_world_until_a_save_is_loaded(tmp_path):
    w = _hundred()
    boom = w.add_system(Boom())
    w.step()
    w.save(tmp_path / "good.npz")
    good = w.state_hash()
    boom.fail = True
    with pytest.raises(ValueError, match="boom at the wall"):        # the original error reaches the caller
        w.step()
    assert w.step_count == 4 and w.broken is not None
    half = w.state_hash()
    assert half != good                                          # movement's prediction and the boom moved it
    boom.fail = False
    with pytest.raises(WorldBrokenError, match=r"cannot step: world .* is broken: in step 5, system 'boom' "
                                               r"\(Boom\) raised ValueError: boom at the wall") as err:
        w.step()                                                 # a retry never steps the systems twice
    assert isinstance(err.value.__cause__, ValueError)
    assert w.state_hash() == half and w.step_count == 4
    with pytest.raises(WorldBrokenError, match="cannot save"):
        w.save(tmp_path / "half.npz")
    w.restore(tmp_path / "good.npz")                             # a load makes it whole
    assert w.broken is None and w.state_hash() == good
    w.step()
    assert w.step_count == 5
    w.close()


def test_a_raise_before_any_system_ran_leaves_the_world_whole(world):
    class Shy(esper.Processor):
        requires = (Velocity,)          # idle: no entity has a Velocity, so it never runs

        def process(self, dt: float) -> None:
            raise AssertionError("not called")
    world.add_system(Shy())
    world.step()
    assert world.broken is None


def test_typed_resources_and_the_accessor_that_names_who_publishes_them(world):
    with pytest.raises(KeyError, match=r"has no TimeWarp resource: made at 1x by driftframe.framework.warp.of"):
        world.resource(TimeWarp)

    class Score:
        pass

    class Scorer(esper.Processor):
        writes = (Score,)

        def process(self, dt: float) -> None:
            pass
    world.add_system(Scorer())
    with pytest.raises(KeyError, match=r"has no Score resource: system 'scorer' \(Scorer\) writes it"):
        world.resource(Score)
    with pytest.raises(KeyError, match="has no Score resource"):
        world.resources[Score]
    world.resources[Score] = s = Score()
    assert world.resource(Score) is s
    world.resources[Score] = 3
    with pytest.raises(TypeError, match=r"resources\[Score\] holds a int, not a Score"):
        world.resource(Score)
    assert world.resources.get("score", 0) == 0                 # a name of one's own still works
    with pytest.raises(KeyError, match=r"world.resources\['seed'\] is keyed by its type now: "
                                       r"world.resources\[Seed \(driftframe.framework.scene.Seed"):
        world.resources.get("seed", 0)                          # a framework resource's old name: an error
