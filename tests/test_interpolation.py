"""Smooth frames: poses drawn between the last two steps by alpha (lerp, slerp); recordings unaffected."""
import math

import esper
import numpy as np
import pytest

from driftframe.components.body import AngularVelocity, Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.render import ModelRef
from driftframe.framework import frame as fr
from driftframe.framework.world import World
from driftframe.systems.interpolation import Interpolator, PoseSnapshotSystem, attach_interpolation, slerp
from driftframe.systems.movement import MovementSystem
from driftframe.systems.spin import SpinSystem


def _angle(q):
    return 2 * math.atan2(np.linalg.norm(q[..., :3], axis=-1), q[..., 3])


def test_slerp_turns_at_a_constant_rate_along_the_shorter_arc():
    q0 = np.array([fr.IDENTITY_QUAT])
    q1 = fr.quat_from_axis_angle([0, 0, 1], 1.2)[None]
    for t in (0.0, 0.25, 0.5, 0.9, 1.0):
        q = slerp(q0, q1, t)
        np.testing.assert_allclose(q, fr.quat_from_axis_angle([0, 0, 1], 1.2 * t)[None], atol=1e-15)
    # -q1 is the same rotation: the blend must not take the 2 pi - 1.2 way round
    np.testing.assert_allclose(np.abs(slerp(q0, -q1, 0.5)), np.abs(fr.quat_from_axis_angle([0, 0, 1], 0.6)[None]),
                               atol=1e-15)
    # nearly equal quaternions (a slow spin): no 0/0, unit length
    q2 = fr.quat_from_axis_angle([1, 0, 0], 1e-9)[None]
    q = slerp(q0, q2, 0.5)
    assert abs(np.linalg.norm(q) - 1) < 1e-15 and _angle(q[0]) == pytest.approx(5e-10, rel=1e-6)


def _moving_world():
    w = World(dt=0.1)
    snap = w.add_system(PoseSnapshotSystem())
    w.add_system(MovementSystem())
    w.add_system(SpinSystem())
    a = w.create_entity(Transform((1.0, 2.0, 3.0)), Velocity((10.0, 0.0, -5.0)), AngularVelocity((0, 2.0, 0)))
    return w, snap, a


def test_blended_poses_lie_alpha_of_the_way_through_the_last_step():
    w, snap, a = _moving_world()
    interp = Interpolator(snap)
    w.step(3)
    tf = esper.component_for_entity(a, Transform)
    before = w.state_hash()
    for alpha in (0.0, 0.3, 0.75):
        interp.alpha = alpha
        pos, quat = interp.blend(np.array([a]), tf.position[None], tf.orientation[None])
        np.testing.assert_allclose(pos[0], [1 + 10 * 0.1 * (2 + alpha), 2, 3 - 5 * 0.1 * (2 + alpha)], atol=1e-12)
        assert _angle(quat[0]) == pytest.approx(2.0 * 0.1 * (2 + alpha), abs=1e-12)
    interp.alpha = 1.0
    pos, _ = interp.blend(np.array([a]), tf.position[None], tf.orientation[None])
    np.testing.assert_array_equal(pos[0], tf.position)          # alpha 1: the state after the step, bit for bit
    assert w.state_hash() == before                             # drawing between steps changes no state
    w.close()


def test_entities_born_in_the_step_are_drawn_where_they_are_and_a_change_outside_a_step_resyncs():
    w, snap, a = _moving_world()
    interp = Interpolator(snap)
    w.step(1)
    b = w.create_entity(Transform((5.0, 5.0, 5.0)), Velocity((1.0, 0, 0)))
    w.step(1)                                                   # b moved 0.1 in this step, a 1.0
    interp.alpha = 0.5
    ents = np.array([a, b])
    w.activate()
    pos = np.array([esper.component_for_entity(e, Transform).position for e in ents])
    quat = np.array([esper.component_for_entity(e, Transform).orientation for e in ents])
    got, _ = interp.blend(ents, pos, quat)
    np.testing.assert_allclose(got[0], pos[0] - [0.5, 0, -0.25])   # a: half a step back
    np.testing.assert_allclose(got[1], [5.05, 5, 5])                # b was in the snapshot of step 2
    c = w.create_entity(Transform((9.0, 0, 0)))
    got, _ = interp.blend(np.array([c]), np.array([[9.0, 0, 0]]), np.array([fr.IDENTITY_QUAT]))
    np.testing.assert_array_equal(got[0], [9.0, 0, 0])             # not in the snapshot: as it is
    snap.take()                                                     # e.g. the camera switched while paused
    got, _ = interp.blend(ents, pos, quat)
    np.testing.assert_array_equal(got, pos)                         # no blend across the jump
    w.close()


@pytest.mark.gl
def test_the_frame_drawn_at_alpha_is_the_frame_of_the_blended_scene(ctx):
    """Render hook end to end: interpolating eye and body by 0.5 draws the picture of the midpoint scene."""
    from driftframe.rendering import attach

    def scene(eye_at, ball_at, eye_v, ball_v):
        w = World(dt=1 / 60)
        w.add_system(MovementSystem())
        eye = w.create_entity(Transform(eye_at), Velocity(eye_v))
        w.create_entity(Camera(target=eye, mode="cockpit", fov=60.0, near=0.1, far=1000.0))
        w.create_entity(Transform(ball_at), Velocity(ball_v), ModelRef("sphere", colour=(1.0, 0.5, 0.2)))
        return w, attach(w, ctx, (160, 120), skybox=True)

    w, render = scene((0, 0, 0), (0, 0, 10), (0, 30, 0), (120, 0, 0))   # per step: eye 0.5 m up, ball 2 m right
    hook = attach_interpolation(w, render)
    w.step(1)
    hook.alpha = 0.5
    w.render()
    blended = render.read_rgba()
    hook.alpha = 1.0
    w.render()
    after = render.read_rgba()
    w.close()
    w2, render2 = scene((0, 0.25, 0), (1.0, 0, 10), (0, 0, 0), (0, 0, 0))  # the midpoint, drawn as it is
    w2.step(1)
    w2.render()
    mid = render2.read_rgba()
    w2.close()
    assert not np.array_equal(blended, after)
    np.testing.assert_array_equal(blended, mid)


@pytest.mark.parametrize("hz", [144.0, 75.0, 50.0])
def test_a_constant_velocity_is_drawn_moving_evenly_at_any_display_rate(hz):
    """With the loop's alpha, the drawn position is x(t - dt) at every frame: no judder at 144, 75 or 50 Hz."""
    from driftframe.framework.loop import FixedStepLoop

    w = World(dt=1 / 60)
    snap = w.add_system(PoseSnapshotSystem())
    w.add_system(MovementSystem())
    body = w.create_entity(Transform(), Velocity((6.0, 0.0, 0.0)))
    t = [0.0]
    loop = FixedStepLoop(w, lambda: t[0])
    interp = Interpolator(snap)
    err_smooth, err_raw = [], []
    for k in range(1, 400):
        t[0] = k / hz
        loop.tick()
        if w.step_count < 1:
            continue
        interp.alpha = loop.alpha
        tf = esper.component_for_entity(body, Transform)
        drawn, _ = interp.blend(np.array([body]), tf.position[None], tf.orientation[None])
        want = 6.0 * (t[0] - w.dt)                            # one step behind the present, exactly
        err_smooth.append(abs(drawn[0, 0] - want))
        err_raw.append(abs(tf.position[0] - 6.0 * t[0]))       # the state after the last step, as drawn before
    assert max(err_smooth) < 1e-9
    assert max(err_raw) > 0.5 * 6.0 / 60                      # without it: up to a whole step's jump
    w.close()
