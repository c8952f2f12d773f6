"""World: declared stage order, per-stage profile, bulk creation, and a state hash for determinism."""
import esper
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from driftframe.components.body import AngularVelocity, Mass, Transform, Velocity
from driftframe.framework.world import FRAME_STAGES, STEP_STAGES, World
from driftframe.systems.movement import MovementSystem
from driftframe.systems.spin import SpinSystem


class Recorder(esper.Processor):
    def __init__(self, name, log, stage):
        self.name, self.log, self.stage = name, log, stage

    def process(self, dt):
        self.log.append(self.name)


def test_stages_run_in_declared_order_whatever_the_adding_order(world):
    log = []
    for stage in reversed(STEP_STAGES + FRAME_STAGES):
        world.add_system(Recorder(stage, log, stage))
    world.step()
    assert log == list(STEP_STAGES)
    log.clear()
    world.render()
    assert log == list(FRAME_STAGES)


def test_unknown_stage_is_rejected(world):
    with pytest.raises(ValueError, match="'physics'"):
        world.add_system(Recorder("x", [], "physics"))


def test_profile_records_each_stage(world):
    world.add_system(MovementSystem())
    world.create_entity(Transform(), Velocity((1, 0, 0)))
    world.step(3)
    assert world.profile["movement"] > 0
    assert world.profile["collision"] == 0.0
    assert world.profile_total["movement"] >= world.profile["movement"]


def test_time_is_steps_times_dt_never_the_wall_clock(world):
    world.step(90)
    assert world.step_count == 90
    assert world.time == 90 * world.dt


def _scene(seed, order=1):
    w = World()
    w.add_system(MovementSystem())
    w.add_system(SpinSystem())
    rng = np.random.default_rng(seed)
    n = 200
    w.create_entities(Transform.bulk(n, position=rng.normal(size=(n, 3))),
                      Velocity.bulk(n, linear=rng.normal(size=(n, 3))),
                      AngularVelocity.bulk(n, angular=rng.normal(size=(n, 3))))
    w.step(120)
    h = w.state_hash()
    w.close()
    return h


def test_two_runs_of_the_same_scene_hash_the_same():
    assert _scene(5) == _scene(5)


def test_any_change_changes_the_hash(world):
    e = world.create_entity(Transform(), Velocity((1.0, 0, 0)))
    before = world.state_hash()
    esper.component_for_entity(e, Velocity).linear = (np.nextafter(1.0, 2.0), 0, 0)   # one ulp
    assert world.state_hash() != before
    assert _scene(5) != _scene(6)


def test_hash_ignores_where_rows_live_in_the_tables():
    def build(pad):
        w = World()
        junk = [Velocity((9, 9, 9)) for _ in range(pad)]   # occupy rows first
        w.create_entity(Transform((1, 2, 3)), Velocity((4, 5, 6)))
        h = w.state_hash()
        assert len(junk) == pad           # (kept alive until here, so their rows stay taken)
        w.close()
        return h
    assert build(0) == build(37)


def test_bulk_creation_of_100k_bodies(world):
    n = 100_000
    rng = np.random.default_rng(0)
    ids = world.create_entities(Transform.bulk(n, position=rng.normal(size=(n, 3))),
                                Velocity.bulk(n, linear=rng.normal(size=(n, 3))),
                                AngularVelocity.bulk(n, angular=rng.normal(size=(n, 3))),
                                Mass.bulk(n, kg=np.full(n, 2.0)))
    assert len(ids) == n == len(esper.get_components(Transform, Velocity, AngularVelocity, Mass))


def test_create_entities_rejects_lists_of_different_length(world):
    with pytest.raises(ValueError, match="differ in length"):
        world.create_entities(Transform.bulk(2), Velocity.bulk(3))


def test_worlds_are_independent():
    a, b = World(), World()
    try:
        a.create_entity(Transform())
        b.activate()
        assert esper.get_component(Transform) == []
        a.activate()
        assert len(esper.get_component(Transform)) == 1
    finally:
        a.close()
        b.close()


def test_bad_dt_is_rejected():
    with pytest.raises(ValueError, match="dt must be > 0"):
        World(dt=0.0)
    with pytest.raises(ValueError, match="dt"):
        World(dt=float("nan"))


# -- the short path of a small scene is the general path, bit for bit ------------------------------
def _body(kind, x, v, r):
    from driftframe.components.body import Acceleration
    from driftframe.components.collision import SphereCollider

    comps = [Transform(tuple(x)), Velocity(tuple(v))]
    if kind != "free":
        comps.append(SphereCollider(float(r)))
    if kind == "spinning":
        comps.append(AngularVelocity((0.5, -1.0, 2.0)))
    if kind == "thrusting":
        comps.append(Acceleration((0.0, 3.0, -1.0)))
    return comps


def _standard_world():
    from driftframe.app import simulation_systems

    w = World()
    for s in simulation_systems():
        w.add_system(s)
    return w


def _general_step(bodies: list, step: int) -> list:
    """One step the general way: a new world, new systems, nothing cached from any step before; the
    bodies (lists of components, in entity order) go in as copies and come back as copies."""
    import copy

    w = _standard_world()
    try:
        ids = [w.create_entity(*map(copy.copy, comps)) for comps in bodies]
        w.step_count = step
        w.step()
        return [list(map(copy.copy, esper.components_for_entity(e))) for e in ids]
    finally:
        w.close()


@st.composite
def _small_scene(draw):
    """2-8 bodies crowded in a box, fast enough to meet within a few steps; some spin, some thrust,
    some are not colliders (moved by the movement system); restitution 1, so the TC model's history
    (which a new world starts without) changes nothing."""
    n = draw(st.integers(2, 8))
    fl = dict(allow_nan=False, allow_infinity=False)
    x = draw(st.lists(st.tuples(*[st.floats(-2.0, 2.0, **fl)] * 3), min_size=n, max_size=n))
    v = draw(st.lists(st.tuples(*[st.floats(-30, 30, **fl)] * 3), min_size=n, max_size=n))
    r = draw(st.lists(st.floats(0.1, 0.6, **fl), min_size=n, max_size=n))
    kinds = draw(st.lists(st.sampled_from(["ball", "spinning", "thrusting", "free"]), min_size=n, max_size=n))
    return x, v, r, kinds


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_small_scene())
def test_a_small_scene_steps_to_the_same_bits_on_the_short_path_as_on_the_general_one(scene):
    """The short path (idle systems skipped, rows, layout, buffers and columns kept while the entities
    stay the same) against a new world for every step; the entities change mid-run, through the world
    and through esper's own calls."""
    import warnings

    x, v, r, kinds = scene
    short = _standard_world()
    try:
        ids = [short.create_entity(*_body(k, *b)) for k, b in zip(kinds, zip(x, v, r))]
        general = [_body(k, *b) for k, b in zip(kinds, zip(x, v, r))]
        short.prepare()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)          # (bodies may spawn overlapping)
            for k in range(8):
                if k == 3:
                    short.delete_entity(ids.pop(0))
                    del general[0]
                    for kind, b in (("ball", ((0.0, 3.0, 0.0), (0.0, -40.0, 0.0), 0.4)),
                                    ("free", ((1.0, 1.0, 1.0), (2.0, 0.0, 0.0), 0.0))):
                        ids.append(short.create_entity(*_body(kind, *b)))
                        general.append(_body(kind, *b))
                if k == 5:
                    short.activate()
                    esper.add_component(ids[0], AngularVelocity((0.0, 0.0, 1.0)))
                    general[0].append(AngularVelocity((0.0, 0.0, 1.0)))
                short.step()
                general = _general_step(general, k)
                short.activate()
                for e, comps in zip(ids, general):
                    mine = {type(c): c for c in esper.components_for_entity(e)}
                    assert {type(c): c for c in comps} == mine, (k, e)
    finally:
        short.close()
