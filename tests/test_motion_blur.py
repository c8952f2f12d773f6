"""Sub-frame poses for motion blur: between fixed steps, exact for free flight and spin, state restored bit for bit."""
from fractions import Fraction

import numpy as np

from driftframe.components.body import AngularVelocity, Transform, Velocity
from driftframe.framework import frame as fr
from driftframe.systems.motion_blur import SubframePoses
from driftframe.systems.movement import MovementSystem
from driftframe.systems.spin import SpinSystem


def _frame_of_two_steps(world):
    poses = SubframePoses()
    poses.start(world)
    for _ in range(2):
        world.step()
        poses.after_step(world)
    return poses


def test_poses_between_steps_follow_the_flight_and_the_spin(world):
    world.add_system(MovementSystem())
    world.add_system(SpinSystem())
    w = 2 * np.pi * 60 * 0.75                        # 3/4 turn per step: slerp would go the short way back
    mover = world.create_entity(Transform((1.0, 2.0, 3.0)), Velocity((6.0, 0.0, -3.0)))
    spinner = world.create_entity(Transform((0.0, 0.0, 0.0)), AngularVelocity((0.0, 0.0, w)))
    poses = _frame_of_two_steps(world)
    after = world.columns(Transform)
    end_pos, end_q = after.position, after.orientation
    dt = world.dt
    for s, steps_in in ((Fraction(1, 4), 0.5), (Fraction(1, 2), 1.0), (Fraction(3, 4), 1.5)):
        poses.pose(world, s)
        cols = world.columns(Transform, [mover, spinner])
        np.testing.assert_allclose(cols.position[0], np.array([1.0, 2.0, 3.0]) + steps_in * dt * np.array([6.0, 0.0, -3.0]),
                                   rtol=0, atol=1e-12)
        expected = fr.quat_from_axis_angle((0.0, 0.0, 1.0), w * steps_in * dt)
        assert abs(abs(float(np.dot(cols.orientation[1], expected))) - 1.0) < 1e-12
    poses.pose(world, Fraction(1))                  # the end of the frame is the stepped state itself
    poses.restore(world)
    cols = world.columns(Transform)
    assert cols.position.tobytes() == end_pos.tobytes() and cols.orientation.tobytes() == end_q.tobytes()


def test_a_frame_where_entities_appear_is_not_blurred(world):
    world.add_system(MovementSystem())
    ent = world.create_entity(Transform((0.0, 0.0, 0.0)), Velocity((1.0, 0.0, 0.0)))
    poses = SubframePoses()
    poses.start(world)
    world.step()
    world.create_entity(Transform((5.0, 0.0, 0.0)))
    poses.after_step(world)
    before = world.columns(Transform).position
    poses.pose(world, Fraction(1, 2))               # nothing moves: the frame shows the stepped state
    assert world.columns(Transform).position.tobytes() == before.tobytes()
    assert world.columns(Transform, [ent]).position[0, 0] == world.dt
