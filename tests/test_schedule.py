"""The open schedule: built-in stage order, after/before for user systems, cycles named, describe()."""
import esper
import pytest

from driftframe.components.body import Transform, Velocity
from driftframe.framework.world import FRAME_STAGES, STEP_STAGES, ScheduleError, World, system_name
from driftframe.systems.collision import CollisionSystem
from driftframe.systems.movement import MovementSystem


class Logged(esper.Processor):
    def __init__(self, name, log, stage=None, after=(), before=()):
        self.name, self.log, self.stage = name, log, stage
        self.after, self.before = after, before

    def process(self, dt):
        self.log.append(self.name)


def test_stages_run_in_declared_order_whatever_the_adding_order(world):
    log = []
    for stage in reversed(STEP_STAGES + FRAME_STAGES):
        world.add_system(Logged(stage, log, stage))
    world.step()
    assert log == list(STEP_STAGES)
    log.clear()
    world.render()
    assert log == list(FRAME_STAGES)


def test_a_users_damage_system_runs_after_collision_and_before_the_camera(world):
    log = []
    world.add_system(Logged("camera", log, "camera"))
    world.add_system(Logged("damage", log), after="collision")
    world.add_system(Logged("collision", log, "collision"))
    world.add_system(Logged("movement", log, "movement"))
    world.step()
    assert log == ["movement", "collision", "damage", "camera"]


def test_before_and_after_order_systems_inside_one_stage(world):
    log = []
    world.add_system(Logged("b", log, "control"))
    world.add_system(Logged("a", log, "control"), before="b")
    world.add_system(Logged("c", log, "control"), after=("a", "b"))
    world.step()
    assert log == ["a", "b", "c"]


def test_a_system_class_can_be_named_as_a_constraint(world):
    log = []
    world.add_system(MovementSystem())
    world.add_system(Logged("probe", log), after=MovementSystem, before="spin")
    order = [type(s).__name__ for stage in world.systems.values() for s in stage]
    assert order.index("MovementSystem") < order.index("Logged")


def test_a_cycle_is_an_error_naming_its_systems(world):
    log = []
    world.add_system(Logged("a", log))
    world.add_system(Logged("b", log, after="a"))
    with pytest.raises(ScheduleError, match=r"cycle: a -> b -> c -> a"):
        world.add_system(Logged("c", log, after="b", before="a"))
    world.step()                                   # the refused system left nothing behind
    assert log == ["a", "b"]


def test_a_constraint_against_the_stage_order_is_a_cycle(world):
    with pytest.raises(ScheduleError, match="cycle"):
        world.add_system(Logged("early", [], "collision", before="movement"))
        world.add_system(Logged("movement", [], "movement"))


def test_unknown_names_and_stages_are_errors_that_list_what_exists(world):
    world.add_system(Logged("damage", []), after="collision")
    with pytest.raises(ScheduleError, match=r"no system or stage named 'colision'.*systems: commit, damage"):
        world.add_system(Logged("x", []), after="colision")
    with pytest.raises(ScheduleError, match="unknown stage 'physics'"):
        world.add_system(Logged("y", [], "physics"))
    with pytest.raises(ScheduleError, match="mix per-step and per-frame"):
        world.add_system(Logged("z", []), after="collision", before="render")


def test_reads_and_writes_must_be_component_classes(world):
    class Bad(esper.Processor):
        reads = ("Velocity", 3)

        def process(self, dt):
            pass
    with pytest.raises(TypeError, match=r"Bad.reads must hold component, resource or event classes.*got 3"):
        world.add_system(Bad())


def test_describe_prints_the_order_and_each_systems_access(world):
    world.add_system(CollisionSystem())
    world.add_system(MovementSystem())
    text = world.describe()
    assert text.index("movement") < text.index("collision") < text.index("commit")
    assert "reads:  Transform, Velocity, Acceleration\n      writes: StepContext" in text
    assert "stage: commit\n      reads:  StepContext\n      writes: Transform, Velocity" in text


def test_system_names_default_to_snake_case_without_system():
    class DamageOverTimeSystem:
        pass
    assert system_name(DamageOverTimeSystem()) == "damage_over_time"
    assert system_name(MovementSystem()) == "movement"


def test_removed_systems_stop_running(world):
    log = []
    s = world.add_system(Logged("x", log, "control"))
    world.remove_system(s)
    world.step()
    assert log == []


def test_the_profile_has_a_line_per_stage_and_per_user_system(world):
    world.add_system(MovementSystem())
    world.add_system(Logged("damage", []), after="collision")
    world.create_entity(Transform(), Velocity((1, 0, 0)))
    world.step(3)
    assert world.profile["movement"] > 0 and "damage" in world.profile
    assert world.profile_total["movement"] >= world.profile["movement"]


def test_built_in_access_declarations_match_what_the_systems_touch():
    """Run each standard system in a full scene, spying on what it queries and what it changes."""
    import copy

    from driftframe.app import make_world
    from driftframe.framework.store import Columnar

    world, _ = make_world("asteroids", seed=1)
    try:
        world.step(40)                               # mid-flight: thrust and spin are on
        touched = set()
        real = {name: getattr(esper, name) for name in
                ("get_component", "get_components", "try_component", "component_for_entity", "try_components")}

        def spy(name):
            def wrapped(*args, **kw):
                for a in args:
                    if isinstance(a, type):
                        touched.add(a)
                return real[name](*args, **kw)
            return wrapped
        real_query = World.query

        def query(self, *types, optional=()):
            touched.update(types + tuple(optional))
            return real_query(self, *types, optional=optional)
        for entry in list(world._order["step"]):
            system = entry.system
            touched.clear()
            before = {cls: copy.deepcopy(t.data) for cls, t in world._tables.items()}
            try:
                for name in real:
                    setattr(esper, name, spy(name))
                World.query = query
                world.activate()
                world.sync()
                system.process(world.dt)
            finally:
                for name, fn in real.items():
                    setattr(esper, name, fn)
                World.query = real_query
            changed = {cls for cls, t in world._tables.items()
                       if cls in before and any((before[cls][f][: t.size] != t.data[f][: t.size]).any()
                                                for f in t.data)}
            # a declaration may name a class (the framework's commit names the components it writes)
            named = {c for c in touched | changed if c.__name__ in set(system.reads) | set(system.writes)}
            declared = set(system.reads) | set(system.writes) | named
            touched = {c for c in touched if getattr(c, "__module__", "") != "driftframe.framework.world"}
            assert touched <= declared, \
                (type(system).__name__, touched - declared)
            writes = set(system.writes) | {c for c in changed if c.__name__ in system.writes}
            assert {c for c in changed if issubclass(c, Columnar)} <= writes, \
                (type(system).__name__, changed - writes)
    finally:
        world.close()


# -- idle systems: `requires` --------------------------------------------------------------------
class Needs(Logged):
    requires = (Transform, Velocity)


def test_a_system_no_entity_has_work_for_is_not_called_until_one_has(world):
    log = []
    world.add_system(Needs("needs", log, "movement"))
    world.add_system(Logged("always", log, "spin"))
    ent = world.create_entity(Transform())
    world.step(2)
    assert log == ["always", "always"]
    assert world.profile["movement"] == 0.0
    world.add_component(ent, Velocity((1, 0, 0)))
    world.step()
    assert log[-2:] == ["needs", "always"]
    esper.remove_component(ent, Velocity)            # esper's own call: seen at the next sync
    log.clear()
    world.step()
    assert log == ["always"]


def test_a_system_made_busy_by_an_earlier_system_of_the_same_step_runs_in_that_step(world):
    log = []
    ent = world.create_entity(Transform())

    class Adder(Logged):
        def process(self, dt):
            super().process(dt)
            if esper.try_component(ent, Velocity) is None:
                esper.add_component(ent, Velocity())
    world.add_system(Needs("needs", log, "spin"))
    world.add_system(Adder("adder", log, "movement"))
    world.step()
    assert log == ["adder", "needs"]


def test_requires_must_hold_component_classes(world):
    bad = Logged("bad", [], "movement")
    bad.requires = ("Velocity",)
    with pytest.raises(TypeError, match="requires must hold component classes, got 'Velocity'"):
        world.add_system(bad)


def test_the_standard_systems_with_nothing_to_do_are_not_called_in_a_scene_of_colliders(monkeypatch):
    """A head-on pair with the standard systems: only movement's prediction, collision, the commit (and
    the cheap input and warp checks) run."""
    import numpy as np

    from driftframe.app import simulation_systems
    from driftframe.components.collision import SphereCollider
    from driftframe.systems.assist import RotationAssistSystem
    from driftframe.systems.autopilot import AutopilotSystem
    from driftframe.systems.control import ControlSystem
    from driftframe.systems.gravity import GravitySystem
    from driftframe.systems.spin import SpinSystem

    w = World()
    try:
        for s in simulation_systems():
            w.add_system(s)
        w.create_entities(Transform.bulk(2, position=np.array([[-2.0, 0, 0], [2.0, 0, 0]])),
                          Velocity.bulk(2, linear=np.array([[1.0, 0, 0], [-1.0, 0, 0]])),
                          SphereCollider.bulk(2, radius=np.full(2, 0.5)))
        w.prepare()
        called = []
        for cls in (SpinSystem, ControlSystem, RotationAssistSystem, AutopilotSystem, GravitySystem):
            monkeypatch.setattr(cls, "process", lambda self, dt, cls=cls: called.append(cls.__name__))
        w.step(100)                                     # through the contact at 1.5 s
        assert called == []
        assert w.columns(Velocity).linear[:, 0].tolist() == [-1.0, 1.0]
    finally:
        w.close()
