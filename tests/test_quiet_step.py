"""The quiet-step test (framework/quiet_step.py) agrees with the solver: a step it calls quiet is one the
solver leaves unchanged, and every step in which the solver finds a contact or an overlap it calls busy."""
import numpy as np

from driftframe.framework import contact
from driftframe.framework.quiet_step import quiet_all_pairs

DT = 1.0 / 60.0


def _scene(rng, n):
    x = rng.uniform(-2.0, 2.0, (n, 3))
    u = rng.uniform(-6.0, 6.0, (n, 3)) * rng.integers(0, 2, (n, 1))     # some bodies at rest
    r = rng.uniform(0.1, 0.6, n)
    inv = np.where(rng.random(n) < 0.15, 0.0, 1.0 / rng.uniform(0.5, 3.0, n))
    e = np.ones(n)
    live = rng.random(n) > 0.05
    return x, u, r, inv, e, live


def test_quiet_means_the_solver_changes_nothing_and_busy_means_it_finds_something():
    rng = np.random.default_rng(7)
    seen = {True: 0, False: 0}
    for trial in range(600):
        n = int(rng.integers(2, 9))
        x, u, r, inv, e, live = _scene(rng, n)
        pi, pj = contact.all_pairs(n)
        quiet = quiet_all_pairs(x, u, r, inv, live, pi, pj, DT)
        seen[bool(quiet)] += 1
        x_in, u_in = x.copy(), u.copy()
        changed, ev, ev_n, ev_x, stats, flags = contact.solve_all_pairs(
            x, u, r, inv, e, live, np.full(n, -np.inf), 0.0, pi, pj, DT, contact.TC * DT, contact.CAP, None)
        found = bool(changed.any() or len(ev) or flags or stats[contact.S_OVERLAPS] or stats[contact.S_CONTACTS])
        assert quiet == (not found), (trial, quiet, stats, flags)
        if quiet:
            assert np.array_equal(x, x_in) and np.array_equal(u, u_in)
    assert seen[True] > 100 and seen[False] > 100          # both kinds of step were tried


def test_a_pair_that_meets_near_the_end_of_the_step_is_busy():
    # closing at 2 m/s, the gap is 1.98 dt m: they touch at t = 0.99 dt
    x = np.array([[0.0, 0, 0], [1.0 + 1.98 * DT, 0, 0]])
    u = np.array([[1.0, 0, 0], [-1.0, 0, 0]])
    r, inv, live = np.full(2, 0.5), np.ones(2), np.ones(2, np.bool_)
    pi, pj = contact.all_pairs(2)
    assert not quiet_all_pairs(x, u, r, inv, live, pi, pj, DT)
    x[1, 0] += 0.04 * DT                                    # 2 % of a step further: they meet next step
    assert quiet_all_pairs(x, u, r, inv, live, pi, pj, DT)


def test_the_listed_quiet_step_leaves_a_field_where_the_all_pairs_solver_does():
    """A field of 60 (the neighbour list's path, and its quiet steps) ends bit for bit where the same field
    stepped with every pair a candidate ends (the all-pairs solver on every step that is not quiet)."""
    import driftframe as df
    from driftframe.framework import placement

    rng = np.random.default_rng(3)
    r = rng.uniform(0.25, 0.75, 60)
    side = ((4 / 3 * np.pi * r ** 3).sum() / 0.2) ** (1 / 3)
    x = placement.place(rng, r, placement.in_box((0, 0, 0), (side, side, side)))
    v = rng.uniform(-3, 3, (60, 3))
    hashes, contacts = [], []
    for broadphase in ("auto", "all"):
        w = df.World(dt=DT)
        w.add_system(df.MovementSystem())
        cs = w.add_system(df.CollisionSystem(broadphase=broadphase))
        w.create_entities(df.Transform.bulk(60, position=x), df.Velocity.bulk(60, linear=v),
                          df.Mass.bulk(60, kg=r ** 3), df.SphereCollider.bulk(60, radius=r))
        n = 0
        for _ in range(240):
            w.step()
            n += cs.stats["contacts"]
        hashes.append(w.state_hash())
        contacts.append(n)
        w.close()
    assert contacts[0] == contacts[1] > 20                 # contacts happened, the same ones
    assert hashes[0] == hashes[1]
