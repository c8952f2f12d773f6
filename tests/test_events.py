"""Events survive the frame: every fixed step's events since the last rendered frame, plus subscriptions."""
import esper
import numpy as np

from driftframe.components.body import Transform, Velocity
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.systems.collision import CollisionSystem
from driftframe.systems.movement import MovementSystem


class FrameReader(esper.Processor):
    """A render-stage reader: what it sees each frame."""

    stage = "render"

    def __init__(self):
        self.seen = []

    def process(self, dt):
        self.seen.append(list(self.world.events))


def _head_on(world, reader=None):
    world.add_system(MovementSystem())
    world.add_system(CollisionSystem())
    if reader is not None:
        world.add_system(reader)
    # surfaces 1.01 m apart, closing at 2 m/s: they touch at t = 0.505 s, inside step 30 at 60 Hz
    world.create_entity(Transform((-1.505, 0, 0)), Velocity((1, 0, 0)), SphereCollider(1.0))
    world.create_entity(Transform((1.505, 0, 0)), Velocity((-1, 0, 0)), SphereCollider(1.0))


def test_a_frame_of_two_steps_sees_the_contact_of_either_step(world):
    reader = FrameReader()
    _head_on(world, reader)
    for _ in range(20):                # 30 fps recording: two fixed steps per rendered frame
        world.step(1)
        world.step(1)
        world.render()
    contacts = [ev for frame in reader.seen for ev in frame if isinstance(ev, CollisionEvent)]
    assert len(contacts) == 1
    ev = contacts[0]
    assert ev.step == 30 and np.isclose(ev.time, 0.505) and np.isclose(ev.step_time, 0.505 - 30 / 60)


def test_events_are_double_buffered(world):
    reader = FrameReader()
    _head_on(world, reader)
    world.step(31)
    world.render()
    assert len(world.events) == 1
    world.step()
    assert world.events == [] and len(world.previous_events) == 1


def test_a_world_that_renders_nothing_keeps_the_last_step_calls_events(world):
    _head_on(world)
    world.step(31)
    assert [type(e) for e in world.events] == [CollisionEvent]
    world.step(1)
    assert world.events == []


def test_subscribers_are_called_at_once_with_each_event(world):
    got = []
    unsubscribe = world.subscribe(CollisionEvent, lambda ev: got.append((world.step_count, ev.a, ev.b)))
    _head_on(world)
    world.step(31)
    assert got == [(30, 1, 2)]
    unsubscribe()
    world.step(200)                    # they fly apart; nothing more would come anyway
    assert len(got) == 1


def test_emit_reaches_subscribers_of_that_type_only(world):
    class Damage:
        pass
    hits = []
    world.subscribe(Damage, hits.append)
    world.emit(Damage())
    world.emit("not a damage")
    assert len(hits) == 1 and len(world.events) == 2
