"""Per-step hash logs: identical runs agree line for line; one flipped bit is found at its step."""
import esper
import numpy as np
import pytest

from driftframe.app import make_world
from driftframe.components.body import Velocity
from driftframe.framework.hashlog import attach_hash_log, first_divergence, read_hash_log


def _run(path, steps=90, nudge_after=None):
    world, _ = make_world("asteroids", seed=1)
    try:
        attach_hash_log(world, path)
        for k in range(steps):
            if k == nudge_after:
                world.activate()
                ent, vel = sorted(esper.get_component(Velocity), key=lambda p: p[0])[5]
                v = vel.linear.copy()
                v[0] = np.nextafter(v[0], np.inf)           # one ulp: the smallest change there is
                vel.linear = v
            world.step()
    finally:
        world.close()                                       # closes the log's file
    return path


def test_identical_runs_give_identical_logs(tmp_path):
    a = _run(tmp_path / "a.txt")
    b = _run(tmp_path / "b.txt")
    assert first_divergence(a, b) is None
    lines = read_hash_log(a)
    assert [s for s, _ in lines] == list(range(1, 91))
    assert len({h for _, h in lines}) == 90                # every step's state is distinct


def test_one_ulp_changed_after_step_37_is_found_at_step_38(tmp_path):
    a = _run(tmp_path / "a.txt")
    b = _run(tmp_path / "b.txt", nudge_after=37)
    d = first_divergence(a, b)
    assert d.step == 38 and d.a != d.b
    assert "part ways at step 38" in str(d)


def test_a_shorter_log_is_reported_where_it_ends(tmp_path):
    a = _run(tmp_path / "a.txt", steps=50)
    b = _run(tmp_path / "b.txt", steps=40)
    d = first_divergence(a, b)
    assert d.step == 41 and d.b is None
    assert "second log ends after step 40" in str(d)


def test_a_malformed_log_names_the_file_and_line(tmp_path):
    p = tmp_path / "x.txt"
    p.write_text("1 abc\nhello\n")
    with pytest.raises(ValueError, match=r"x.txt: line 2 is not 'STEP HASH'"):
        read_hash_log(p)
