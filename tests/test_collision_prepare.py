"""CollisionSystem.prepare() rehearses the first step's solver on copies (systems/collision.py's _rehearse), and
World.prepare() then runs the step's built-in stages dry (framework/world.py's _rehearse): the steps after it
are the same, bit for bit, as without prepare(), and no user system runs in it."""
from __future__ import annotations

import numpy as np
import pytest

from driftframe.components.body import Mass, Transform, Velocity
from driftframe.components.collision import CollisionEvent, SphereCollider
from driftframe.framework import placement
from driftframe.framework.world import World
from driftframe.systems.collision import CollisionSystem
from driftframe.systems.movement import MovementSystem


def _crystal(side):
    """A touching simple cubic crystal (unit spheres' diameter apart), random velocities: all in contact."""
    g = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(float)
    n = len(g)
    return g, np.random.default_rng(1).uniform(-1, 1, (n, 3)), np.full(n, 0.5), np.ones(n)


def _converging(n, e):
    """``n`` spheres apart in a ball, all at 60 m/s towards its centre (restitution ``e``)."""
    rng = np.random.default_rng(2)
    r = np.full(n, 0.5)
    x = placement.place(rng, r, placement.in_shell(0.0, (n * 1.1 ** 3) ** (1 / 3)), gap=0.025)
    return x, -60.0 * x / np.maximum(np.linalg.norm(x, axis=1, keepdims=True), 1e-9), r, np.full(n, e)


def _fast_movers(n):
    """A field of ``n`` at 5 % crossed by three of its own bodies at 200 m/s (swept off the list)."""
    rng = np.random.default_rng(3)
    r = rng.uniform(0.25, 0.75, n)
    side = ((4 / 3 * np.pi * r ** 3).sum() / 0.05) ** (1 / 3)
    x = placement.place(rng, r, placement.in_box((0, 0, 0), (side, side, side)))
    v = rng.uniform(-1, 1, (n, 3))
    for k in range(3):
        d = x.mean(axis=0) - x[k]
        v[k] = 200.0 * d / np.linalg.norm(d)
    return x, v, r, np.ones(n)


SCENES = {
    "touching crystal of 27 (all pairs)": lambda: _crystal(3),
    "touching crystal of 216 (neighbour list)": lambda: _crystal(6),
    "200 converging, e = 0 (the jam path)": lambda: _converging(200, 0.0),
    "field of 500, three fast (swept bodies)": lambda: _fast_movers(500),
}


@pytest.mark.parametrize("name", list(SCENES))
def test_prepare_rehearses_the_first_step_and_changes_nothing(name, monkeypatch):
    def run(prepared):
        x, v, r, e = SCENES[name]()
        w = World()
        w.add_system(MovementSystem())
        cs = w.add_system(CollisionSystem())
        n = len(x)
        w.create_entities(Transform.bulk(n, position=x), Velocity.bulk(n, linear=v), Mass.bulk(n, kg=np.ones(n)),
                          SphereCollider.bulk(n, radius=r, restitution=e))
        rehearsed = []
        rehearse = cs._rehearse

        def carried():
            # what the system carries into the step: the last contacts, the list, the gathered state
            nl = cs._list
            arrays = (cs._t_last, nl.swept, nl.centre, nl.skin, nl.reach, nl._order, nl._lo_x, nl.i, nl.j,
                      cs._layout.state.x, cs._layout.state.u) if cs._uses_list(n) else (cs._t_last,)
            return [a.tobytes() for a in arrays] + [cs._stick]

        def watched(*a):
            before = carried()
            rehearse(*a)
            rehearsed.append(carried() == before)
        monkeypatch.setattr(cs, "_rehearse", watched)
        events = []
        w.subscribe(CollisionEvent, lambda ev: events.append((ev.step, ev.a, ev.b, ev.time, ev.impulse)))
        if prepared:
            before = w.state_hash()
            w.prepare()
            assert w.state_hash() == before and rehearsed == [True]   # it ran, and changed nothing
        stats = []
        for _ in range(8):
            w.step()
            stats.append((cs.stats["contacts"], cs.stats["swept"], cs.stats["waves"]))   # (builds: prepare's)
        out = w.state_hash(), events, stats, cs._stick
        w.close()
        return out

    with_prepare, without = run(True), run(False)
    assert with_prepare[2][0][0] > 0                                  # the first step has contacts
    assert with_prepare == without


def _pair_world(gap: float, n_extra: int = 0):
    """Two spheres head on, ``gap`` m between their surfaces, closing at 2 m/s, and ``n_extra`` spheres
    at rest in a row far off (more than 32 colliders: the neighbour list's path)."""
    x = [(-0.5 - gap / 2, 0.0, 0.0), (0.5 + gap / 2, 0.0, 0.0)] + [(10.0 + 3.0 * k, 50.0, 0.0) for k in range(n_extra)]
    v = [(1.0, 0.0, 0.0), (-1.0, 0.0, 0.0)] + [(0.0, 0.01 * (k % 3), 0.0) for k in range(n_extra)]
    n = len(x)
    w = World()
    w.add_system(MovementSystem())
    cs = w.add_system(CollisionSystem())
    w.create_entities(Transform.bulk(n, position=np.array(x)), Velocity.bulk(n, linear=np.array(v)),
                      Mass.bulk(n, kg=np.ones(n)), SphereCollider.bulk(n, radius=np.full(n, 0.5),
                                                                        restitution=np.ones(n)))
    return w, cs


class _Counter:
    """A user's system: counts its calls (a dry step must never call it)."""

    stage = "collision"
    reads = ()
    writes = ()

    def __init__(self):
        self.calls = 0

    def process(self, dt):
        self.calls += 1


@pytest.mark.parametrize("extra", [0, 40], ids=["all pairs", "neighbour list"])
@pytest.mark.parametrize("gap", [0.5, 0.02], ids=["quiet first step", "contact in the first step"])
def test_the_dry_steps_change_nothing_and_run_no_user_system(extra, gap, monkeypatch):
    """World.prepare's dry steps (World._rehearse): the built-in movement, collision (where the first step is
    quiet) and commit stages run, a user's system does not; the state, the step count, the events and the profile totals are as they were;
    every step after is the same, bit for bit, as without prepare()."""
    def run(prepared):
        w, cs = _pair_world(gap, extra)
        user = w.add_system(_Counter(), after="collision")
        calls = {"CollisionSystem": 0, "MovementSystem": 0}
        for system in (cs, w.get_system(MovementSystem)):
            inner = system.process

            def counted(dt, inner=inner, name=type(system).__name__):
                calls[name] += 1
                inner(dt)
            monkeypatch.setattr(system, "process", counted)
        hashes, events = [], []
        w.subscribe(CollisionEvent, lambda ev: events.append((ev.step, ev.a, ev.b, ev.time, ev.impulse)))
        if prepared:
            w.step(0)                                        # (the events' double buffer as a step leaves it)
            before = (w.state_hash(), w.step_count, list(w.events), dict(w.profile_total))
            w.prepare()
            assert (w.state_hash(), w.step_count, list(w.events), dict(w.profile_total)) == before
            assert user.calls == 0 and not w.step_context.open
            # the collision stage runs dry only where the coming step is quiet
            assert calls["MovementSystem"] >= 1
            assert calls["CollisionSystem"] == (calls["MovementSystem"] if gap > 0.1 else 0)
        for _ in range(30):
            w.step()
            hashes.append(w.state_hash())
        assert user.calls == 30
        w.close()
        return hashes, events

    with_prepare, without = run(True), run(False)
    assert with_prepare == without
    assert with_prepare[1]                                    # the pair meets within the 30 steps
