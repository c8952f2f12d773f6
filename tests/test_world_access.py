"""The checking mode (framework/access_check.py, on in every test: conftest.py) and the schedule's ambiguity
warning: a system is held to its reads/writes, and unordered systems whose access conflicts are named."""
import warnings

import esper
import numpy as np
import pytest

from driftframe.components.body import AngularVelocity, Mass, Transform, Velocity
from driftframe.components.collision import CollisionEvent
from driftframe.framework import access_check
from driftframe.framework.access_check import AccessError
from driftframe.framework.warp import TimeWarp
from driftframe.framework.world import ScheduleAmbiguityWarning, World
from driftframe.systems.movement import MovementSystem


def _hit():
    return CollisionEvent(1, 1, 0.0, 0.0, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0.0)


def test_the_tests_run_in_the_checking_mode():
    assert access_check.enabled


class Probe(esper.Processor):
    """Reads Velocity and writes Mass, then does ``self.touch(world)``."""
    reads = (Velocity,)
    writes = (Mass,)

    def __init__(self, touch):
        self.touch = touch

    def process(self, dt):
        self.touch(self.world)


UNDECLARED = {
    "world.table": lambda w: w.table(Transform),
    "world.columns": lambda w: w.columns(Transform),
    "world.query": lambda w: w.query(Velocity, Transform),
    "esper.get_components": lambda w: esper.get_components(Velocity, AngularVelocity),
    "esper.get_component": lambda w: esper.get_component(Transform),
    "esper.component_for_entity": lambda w: esper.component_for_entity(1, Transform),
    "esper.try_component": lambda w: esper.try_component(1, Transform),
    "esper.has_component": lambda w: esper.has_component(1, Transform),
    "esper.add_component": lambda w: esper.add_component(1, AngularVelocity()),
    "esper.remove_component": lambda w: esper.remove_component(1, Velocity),       # a read, not a write
    "world.resources[...]": lambda w: w.resources[TimeWarp],
    "world.resources.get(...)": lambda w: w.resources.get(TimeWarp),
    "world.emit": lambda w: w.emit(_hit()),
}


@pytest.mark.parametrize("how", sorted(UNDECLARED))
def test_a_system_touching_what_it_does_not_declare_is_an_error_naming_it(world, how):
    world.create_entity(Transform(), Velocity(), Mass(1.0))
    world.add_system(Probe(UNDECLARED[how]))
    with pytest.raises(AccessError, match=rf"system 'probe' \(Probe\) touches \w+ through {how.replace('[', '.').replace(']', '.').replace('(', '.').replace(')', '.')} "
                                          r"but does not declare it: add \w+ to its"):
        world.step()


def test_what_a_system_declares_it_may_touch_in_every_way(world):
    e = world.create_entity(Transform(), Velocity(), Mass(1.0))

    def touch(w):
        w.columns(Velocity).linear
        w.query(Velocity).refresh()
        esper.component_for_entity(e, Mass).kg = 2.0
        esper.remove_component(e, Mass)
        esper.add_component(e, Mass(3.0))
    world.add_system(Probe(touch))
    world.step()
    assert world.columns(Mass).kg[0] == 3.0


def test_a_write_must_be_in_writes_a_read_declaration_is_not_enough(world):
    class Reader(esper.Processor):
        reads = (TimeWarp,)

        def process(self, dt):
            self.world.resources.get(TimeWarp)                   # a read: fine
            self.world.resources[TimeWarp] = TimeWarp()          # a write: not declared

    world.add_system(Reader())
    with pytest.raises(AccessError, match=r"touches TimeWarp through world.resources\[...\] = .* its writes"):
        world.step()


def test_outside_a_system_and_in_a_subscriber_nothing_is_checked(world):
    seen = []

    class Emitter(esper.Processor):
        writes = (CollisionEvent,)

        def process(self, dt):
            self.world.emit(_hit())

    def on_hit(event):                    # a subscriber is the user's code, not the emitting system
        seen.append(len(world.columns(Transform).entities))
    world.create_entity(Transform())
    world.subscribe(CollisionEvent, on_hit)
    world.add_system(Emitter())
    world.step()
    assert seen == [1]
    world.table(Transform), esper.get_components(Transform)       # user code between steps


def test_a_system_that_declares_nothing_is_not_held_to_anything(world):
    class Quick(esper.Processor):
        def process(self, dt):
            esper.get_components(Transform)
    world.add_system(Quick())
    world.step()


def test_an_error_in_a_checked_system_leaves_no_system_marked_running(world):
    world.add_system(Probe(lambda w: w.table(Transform)))
    with pytest.raises(AccessError):
        world.step()
    assert access_check.running is None
    esper.get_components(Transform)                              # not attributed to the failed system


def test_describe_prints_components_resources_and_events_a_system_declares(world):
    class Governor(esper.Processor):
        reads = (Velocity,)
        writes = (TimeWarp, CollisionEvent)

        def process(self, dt):
            pass
    world.add_system(Governor())
    text = world.describe()
    assert "reads:  Velocity\n" in text and "writes: TimeWarp, CollisionEvent\n" in text


def _system(name, writes, reads=()):
    return type(name, (esper.Processor,), {"reads": reads, "writes": writes, "process": lambda self, dt: None})()


def test_unordered_systems_whose_writes_conflict_get_a_warning_naming_both():
    w = World()
    w.add_system(_system("Wind", (Velocity,)), after="commit")
    with pytest.warns(ScheduleAmbiguityWarning, match=r"systems 'wind' and 'drag' both touch Velocity, one writing "
                                                      r"it, and nothing orders them: give one after='wind'"):
        w.add_system(_system("Drag", (), reads=(Velocity,)), after="commit")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        w.add_system(_system("Gust", (Velocity,)), after="wind", before="drag")   # ordered: no warning
        w.add_system(_system("Tally", (Mass,)), after="commit")                   # no conflict
        w.add_system(_system("Hook", (Velocity,)), before="movement")             # before commit's Velocity
    w.close()


def test_the_built_in_scenes_have_no_ambiguous_systems():
    from driftframe.app import make_world

    with warnings.catch_warnings():
        warnings.simplefilter("error", ScheduleAmbiguityWarning)
        for demo in ("orbit", "asteroids"):
            made = make_world(demo, seed=0)
            (made[0] if isinstance(made, tuple) else made).close()


def test_the_standard_step_runs_checked_without_error():
    w = World()
    w.add_system(MovementSystem())
    w.create_entities(Transform.bulk(3), Velocity.bulk(3, linear=np.ones((3, 3))))
    w.step(2)
    np.testing.assert_allclose(w.columns(Transform).position, 2 * w.dt * np.ones((3, 3)))
    w.close()
