"""A system with nothing to do is not called (issue 20): the world's plan of the systems that have work,
made once per change of entities, of the schedule or of the resources, and World.wake()."""
import esper

from driftframe.components.body import Transform, Velocity
from driftframe.framework.input import Press, Track
from driftframe.framework.warp import TimeWarp
from driftframe.systems.input import InputSystem
from driftframe.systems.warp import WarpGovernorSystem


def _count(system):
    """Wrap ``system.process`` to count its calls (the world looks it up at every call)."""
    calls = []
    real = system.process

    def process(dt):
        calls.append(dt)
        real(dt)
    system.process = process
    return calls


def test_the_input_system_without_pilot_track_or_recorder_is_not_called_until_a_key_is_pressed(world):
    inputs = world.add_system(InputSystem())
    calls = _count(inputs)
    fired = []
    inputs.handlers["switch_camera"] = fired.append
    world.step(3)
    assert calls == []
    assert world.profile["input"] == 0.0
    inputs.press("switch_camera")                     # (press() tells the world: World.wake)
    world.step()
    assert len(calls) == 1 and fired == [world]
    assert world.profile["input"] > 0.0


def test_the_input_system_with_a_track_runs_every_step(world):
    inputs = world.add_system(InputSystem())
    calls = _count(inputs)
    world.step()
    assert calls == []
    inputs.track = Track([Press(1.0, "switch_camera")])
    world.step(2)
    assert len(calls) == 2


def test_the_warp_governor_runs_only_in_a_world_with_a_time_warp(world):
    governor = world.add_system(WarpGovernorSystem())
    calls = _count(governor)
    world.step(2)
    assert calls == []
    warp = world.resources[TimeWarp] = TimeWarp()
    warp.limit, warp.reason = 5, "stale"
    world.step()
    assert len(calls) == 1
    assert (warp.limit, warp.reason) == (None, "")    # (1x asked: the governor lifts any limit)
    del world.resources[TimeWarp]
    world.step()
    assert len(calls) == 1


class _Needs(esper.Processor):
    """Requires a Velocity; removes the Velocity of ``victim`` when told to."""

    def __init__(self, name, stage, log, victim=None):
        self.name, self.stage, self.log, self.victim = name, stage, log, victim
        self.requires = (Transform, Velocity)
        self.writes = (Velocity,) if victim is not None else ()

    def process(self, dt):
        self.log.append(self.name)
        if self.victim is not None and esper.has_component(self.victim, Velocity):
            esper.remove_component(self.victim, Velocity)


def test_a_system_made_idle_by_an_earlier_one_in_the_same_step_is_not_called_and_reads_zero(world):
    log = []
    ent = world.create_entity(Transform(), Velocity())
    world.add_system(_Needs("first", "movement", log, victim=ent))
    world.add_system(_Needs("second", "spin", log))
    world.step()
    assert log == ["first"]                           # second lost its work mid-step
    assert world.profile["movement"] > 0.0 and world.profile["spin"] == 0.0
    world.step()
    assert log == ["first"]                           # both idle now


def test_a_system_added_between_steps_runs_in_the_next(world):
    log = []
    world.create_entity(Transform(), Velocity())
    world.add_system(_Needs("first", "movement", log))
    world.step()
    world.add_system(_Needs("second", "spin", log))
    world.step()
    assert log == ["first", "first", "second"]


def test_wake_reads_a_changed_requires_without_a_change_of_entities(world):
    log = []
    world.create_entity(Transform())
    s = world.add_system(_Needs("s", "movement", log))
    world.step()
    assert log == []
    s.requires = (Transform,)
    world.step()
    assert log == []                                  # the plan holds until something changes...
    world.wake()
    world.step()
    assert log == ["s"]                               # ...or the world is told


def test_an_empty_world_with_the_standard_systems_calls_only_the_commit():
    import numpy as np

    from driftframe.app import simulation_systems
    from driftframe.components.collision import SphereCollider
    from driftframe.framework.world import World
    from driftframe.systems.collision import CollisionSystem

    w = World()
    try:
        for s in simulation_systems():
            w.add_system(s)
        w.prepare()
        w.step(2)
        assert [k for k, v in w.profile.items() if v] == ["commit"]
        ents = w.create_entities(Transform.bulk(2, position=np.array([[-1.0, 0, 0], [1.0, 0, 0]])),
                                 Velocity.bulk(2, linear=np.array([[60.0, 0, 0], [-60.0, 0, 0]])),
                                 SphereCollider.bulk(2, radius=np.full(2, 0.5)))
        w.step()                                      # they meet within this step
        cs = w.get_system(CollisionSystem)
        assert w.profile["collision"] > 0 and cs.stats["contacts"] == 1
        for e in ents:
            w.delete_entity(e)
        w.step()                                      # it lets its colliders go: its stats read 0 again
        assert cs.stats["contacts"] == 0 and cs.stats["pairs"] == 0
        w.create_entity(Transform())                  # (a change of entities: the plan is made anew)
        w.step()
        assert w.profile["collision"] == 0.0
    finally:
        w.close()
