"""A system object is scheduled once (issue 22): adding it again is an error naming it, the schedule is left
as it was, and another object of the same class is welcome."""
import esper
import pytest

from driftframe.components.body import Transform
from driftframe.framework.world import World


class Count(esper.Processor):
    """Reads nothing; writes nothing.  Counts its calls."""
    reads = (Transform,)
    writes = ()

    def __init__(self):
        self.calls = 0

    def process(self, dt):
        self.calls += 1


def test_adding_the_same_system_object_twice_is_an_error_naming_it():
    world = World()
    try:
        once = world.add_system(Count(), after="commit")
        with pytest.raises(ValueError, match=r"system 'count' \(Count\) is in this world already: a system object "
                                             r"is added once \(make another to run it twice\)"):
            world.add_system(once, before="movement")
        with pytest.raises(ValueError, match="is in this world already"):
            world.add_system(once, name="count_again")                   # under another name too
        world.create_entity(Transform())
        world.step(3)
        assert once.calls == 3                                          # still in once, where it was
        assert [e.system for e in world._order["step"]].count(once) == 1
        other = world.add_system(Count(), name="count_2", after="count")
        world.step()
        assert (once.calls, other.calls) == (4, 1)
    finally:
        world.close()
