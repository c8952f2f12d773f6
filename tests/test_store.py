"""Columnar storage: component objects view into per-class tables; rows recycle; bulk creation validates."""
import gc
import math

import esper
import numpy as np
import pytest

from driftframe.components.body import AngularVelocity, Mass, Transform, Velocity
from driftframe.framework.store import RowCache, as_index


def test_component_fields_are_views_into_the_table():
    v = Velocity((1.0, 2.0, 3.0))
    v.linear[1] = 5.0
    np.testing.assert_array_equal(Velocity._table.data["linear"][v._row], [1.0, 5.0, 3.0])
    Velocity._table.data["linear"][v._row, 2] = -1.0
    np.testing.assert_array_equal(v.linear, [1.0, 5.0, -1.0])


def test_rows_are_recycled_when_components_die():
    gc.collect()
    table = Velocity._table
    v = Velocity((1.0, 0, 0))
    row, size = v._row, table.size
    del v
    gc.collect()
    assert row in table.free
    reused = [Velocity((7.0, 0, 0)) for _ in range(len(table.free))]
    assert table.size == size                      # no new rows while recycled ones were free
    assert row in [r._row for r in reused]
    np.testing.assert_array_equal(reused[-1].linear, [7.0, 0, 0])


def test_table_growth_keeps_values():
    first = Velocity((4.0, 5.0, 6.0))
    many = Velocity.bulk(5000, linear=np.ones((5000, 3)))
    np.testing.assert_array_equal(first.linear, [4.0, 5.0, 6.0])
    assert all(np.array_equal(m.linear, [1, 1, 1]) for m in many[::997])


def test_bulk_rows_are_contiguous_and_become_a_slice():
    comps = AngularVelocity.bulk(10, angular=np.arange(30.0).reshape(10, 3))
    idx = as_index(np.array([c._row for c in comps]))
    assert isinstance(idx, slice)
    np.testing.assert_array_equal(AngularVelocity._table.data["angular"][idx], np.arange(30.0).reshape(10, 3))


@pytest.mark.parametrize("bad,match", [
    (np.array([[0, 0, 0], [0, np.nan, 0]]), r"Velocity.linear\[1\] must be finite"),
    (np.array([[0, 0, 0], [np.inf, 0, 0]]), r"Velocity.linear\[1\] must be finite"),
    (np.zeros((2, 2)), r"shape \(N, 3\)"),
])
def test_bulk_rejects_bad_rows_naming_the_first(bad, match):
    with pytest.raises(ValueError, match=match):
        Velocity.bulk(2, linear=bad)


def test_bulk_mass_rejects_zero_and_negative_but_allows_infinite():
    with pytest.raises(ValueError, match=r"Mass.kg\[2\] must be > 0.*got -1.0"):
        Mass.bulk(3, kg=np.array([1.0, 2.0, -1.0]))
    m = Mass.bulk(2, kg=np.array([1.0, math.inf]))
    assert m[1].kg == math.inf and m[1].inverse == 0.0


def test_row_cache_rebuilds_only_when_the_query_changes(world):
    cache = RowCache()
    world.create_entity(Transform(), Velocity())
    assert cache.update(esper.get_components(Transform, Velocity))
    assert not cache.update(esper.get_components(Transform, Velocity))
    world.create_entity(Transform(), Velocity())
    assert cache.update(esper.get_components(Transform, Velocity))
    assert len(cache.entities) == 2


def test_unknown_field_and_too_many_arguments_are_clear_errors():
    with pytest.raises(TypeError, match="no field 'speed'"):
        Velocity(speed=3)
    with pytest.raises(TypeError, match="at most 1 positional"):
        Velocity((1, 2, 3), (4, 5, 6))
