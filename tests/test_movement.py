"""MovementSystem: free bodies move v t; thrust matches the closed form."""
import numpy as np

from driftframe.components.body import Acceleration, Transform, Velocity
from driftframe.systems.movement import MovementSystem


def test_free_body_moves_v_times_t(world):
    world.add_system(MovementSystem())
    v = np.array([3.0, -2.0, 0.5])
    e = world.create_entity(Transform((1.0, 2.0, 3.0)), Velocity(v))
    world.step(600)
    import esper
    pos = esper.component_for_entity(e, Transform).position
    np.testing.assert_allclose(pos, [1.0, 2.0, 3.0] + v * 600 * world.dt, rtol=0, atol=1e-11)
    np.testing.assert_array_equal(esper.component_for_entity(e, Velocity).linear, v)


def test_constant_thrust_matches_closed_form(world):
    world.add_system(MovementSystem())
    a = np.array([0.0, 0.0, 9.5])
    v0 = np.array([1.0, 0.0, -4.0])
    e = world.create_entity(Transform(), Velocity(v0), Acceleration(a))
    world.step(240)
    import esper
    t = 240 * world.dt
    np.testing.assert_allclose(esper.component_for_entity(e, Transform).position, v0 * t + 0.5 * a * t * t,
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(esper.component_for_entity(e, Velocity).linear, v0 + a * t, rtol=1e-12)


def test_exact_even_for_one_huge_step(world):
    """x = v dt + a dt^2/2 is exact per step, so one 10 s step equals ten thousand small ones."""
    world.dt = 10.0
    world.add_system(MovementSystem())
    import esper
    e = world.create_entity(Transform(), Velocity((2.0, 0, 0)), Acceleration((0, 1.0, 0)))
    world.step()
    np.testing.assert_allclose(esper.component_for_entity(e, Transform).position, [20.0, 50.0, 0.0])


def test_many_bodies_each_move_their_own_velocity(world):
    world.add_system(MovementSystem())
    rng = np.random.default_rng(3)
    n = 1000
    p, v = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    ids = world.create_entities(Transform.bulk(n, position=p), Velocity.bulk(n, linear=v))
    # and a few made one by one, interleaved with deletions, so rows are not contiguous
    extra = [world.create_entity(Transform((i, 0, 0)), Velocity((0, i, 0))) for i in range(5)]
    world.delete_entity(ids[10])
    world.step(10)
    import esper
    for k in (0, 11, 999):
        np.testing.assert_allclose(esper.component_for_entity(ids[k], Transform).position,
                                   p[k] + v[k] * 10 * world.dt, atol=1e-13)
    for i, e in enumerate(extra):
        np.testing.assert_allclose(esper.component_for_entity(e, Transform).position,
                                   [i, i * 10 * world.dt, 0], atol=1e-13)


def test_a_plain_per_entity_system_sees_and_changes_the_same_data(world):
    """A user's esper loop and the vectorised system share storage."""
    import esper

    class Bump(esper.Processor):
        stage = "control"

        def process(self, dt):
            for _, (vel,) in esper.get_components(Velocity):
                vel.linear = vel.linear + (1.0, 0.0, 0.0)   # per entity, through the component

    world.add_system(Bump())
    world.add_system(MovementSystem())
    e = world.create_entity(Transform(), Velocity((0.0, 0.0, 0.0)))
    world.step(2)
    # step 1: v=1, x=dt; step 2: v=2, x=dt+2dt
    np.testing.assert_allclose(esper.component_for_entity(e, Transform).position, [3 * world.dt, 0, 0])


def test_adding_a_component_later_is_picked_up(world):
    import esper
    world.add_system(MovementSystem())
    e = world.create_entity(Transform())
    world.step()
    esper.add_component(e, Velocity((1.0, 0, 0)))
    world.step()
    np.testing.assert_allclose(esper.component_for_entity(e, Transform).position, [world.dt, 0, 0])
    esper.remove_component(e, Velocity)
    world.step()
    np.testing.assert_allclose(esper.component_for_entity(e, Transform).position, [world.dt, 0, 0])
