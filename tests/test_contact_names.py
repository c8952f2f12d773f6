"""solve_step's inputs, outputs, stats and flags have names (issue 22): StepInputs in, StepResult out, a
StepStats record field by field over the solvers' stats array, and one bit per flag."""
import numpy as np

from driftframe.framework import contact
from driftframe.framework import contact_params as cp

#: The stats array's index constants, in the order of StepStats' fields.
INDICES = ("S_PAIRS", "S_CONTACTS", "S_WAVES", "S_SWEPT", "S_OVERLAPS", "S_WORST_I", "S_WORST_J", "S_WORST",
           "S_SEQUENTIAL", "S_POPPED", "S_PUSHED", "S_BACK")


def test_every_entry_of_the_stats_array_has_a_field_of_step_stats_at_its_index():
    assert len(contact.StepStats._fields) == cp.N_STATS == len(INDICES)
    assert [getattr(cp, name) for name in INDICES] == list(range(cp.N_STATS))
    assert contact.StepStats._fields[cp.S_CONTACTS] == "contacts"
    assert contact.StepStats._fields[cp.S_BACK] == "put_back"


def test_each_flag_is_its_own_bit():
    flags = {name: getattr(cp, name) for name in dir(cp) if name.startswith("F_")}
    assert set(flags) == {"F_JAM", "F_TC", "F_CAP", "F_STICK", "F_LIMIT", "F_REBUILD", "F_AGAIN"}
    values = sorted(flags.values())
    assert all(v > 0 and v & (v - 1) == 0 for v in values)                 # powers of two
    assert len(set(values)) == len(values)


def test_a_head_on_pair_comes_back_as_a_named_result():
    """Two balls closing at 2 m/s, 3 m apart between surfaces: they meet at t = 1.5 s of a 2 s step."""
    dt = 2.0
    inputs = contact.StepInputs(
        x=np.array([[-2.0, 0, 0], [2.0, 0, 0]]), u=np.array([[1.0, 0, 0], [-1.0, 0, 0]]), r=np.full(2, 0.5),
        inv=np.ones(2), e=np.ones(2), live=np.ones(2, np.bool_), t_last=np.full(2, -np.inf), now=0.0,
        pi=np.array([0], np.int64), pj=np.array([1], np.int64), dt=dt, t_c=contact.TC * dt, cap=contact.CAP,
        lst=None)
    res = contact.solve_step(inputs)
    assert isinstance(res, contact.StepResult) and isinstance(res.stats, contact.StepStats)
    assert res.stats.pairs == 1 and res.stats.contacts == 1 and res.stats.waves == 1
    assert res.stats.overlaps == 0 and res.stats.worst_i == -1
    assert res.flags == 0 and not res.stick
    assert res.changed.tolist() == [True, True]
    assert res.events.shape == (1, 4) and res.events[0, 2] == 1.5         # i, j, time from the step's start, J
    np.testing.assert_allclose(res.normals[0], [1.0, 0, 0])
    np.testing.assert_allclose(inputs.u, [[-1.0, 0, 0], [1.0, 0, 0]])     # an elastic swap, in place
