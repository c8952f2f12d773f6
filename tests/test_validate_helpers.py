"""validate's helpers for the checks that were written inline (issue 22): a class, a function, a name, and the
one first-bad-row check over rows of any dimension. Each error names the argument and shows the value."""
import numpy as np
import pytest

from driftframe.framework import validate
from driftframe.framework.frame import check_unit_quat
from driftframe.framework.world import World


def test_a_class_passes_a_class_and_names_what_is_not_one():
    assert validate.a_class("key", int) is int
    with pytest.raises(TypeError, match=r"^key must be a class \(e.g. TimeWarp\), got 'warp'$"):
        validate.a_class("key", "warp", "TimeWarp")
    with pytest.raises(TypeError, match=r"^key must be a class, got 3$"):
        validate.a_class("key", 3)


def test_function_passes_a_callable_and_none_only_when_optional():
    assert validate.function("clock", len) is len
    assert validate.function("hook", None, optional=True) is None
    with pytest.raises(TypeError, match=r"^clock must be a function returning seconds, got 1.5$"):
        validate.function("clock", 1.5, what="a function returning seconds")
    with pytest.raises(TypeError, match=r"^hook must be callable or None, got 'f'$"):
        validate.function("hook", "f", optional=True)
    with pytest.raises(TypeError, match=r"^hook must be callable, got None$"):
        validate.function("hook", None)


@pytest.mark.parametrize("bad", ["", None, 7, b"rock"])
def test_text_refuses_what_is_not_a_non_empty_str(bad):
    with pytest.raises(TypeError, match=r"^model name must be a non-empty str, got "):
        validate.text("model name", bad)
    assert validate.text("model name", "rock") == "rock"


def test_rows_names_the_first_bad_row_of_numbers_and_of_vectors():
    validate.rows("m", np.array([1.0, 2.0]), np.array([False, False]), "> 0")          # nothing bad: no error
    with pytest.raises(ValueError, match=r"^m\[1\] must be > 0, got -2.0$"):
        validate.rows("m", np.array([1.0, -2.0, -3.0]), np.array([False, True, True]), "> 0")
    with pytest.raises(ValueError, match=r"^m must be > 0, got 0.0$"):
        validate.rows("m", 0, True, "> 0")                                        # one number: no index
    x = np.array([[0.0, 0, 0], [1.0, np.nan, 0]])
    with pytest.raises(ValueError, match=r"^x\[1\] must be finite, got \[1.0, nan, 0.0\]$"):
        validate.rows("x", x, np.isnan(x).any(axis=1), "finite", row_ndim=1)
    with pytest.raises(ValueError, match=r"^x must be finite, got \[1.0, nan, 0.0\] \(row 0\)$"):
        validate.rows("x", x[1], np.isnan(x[1]).any(), "finite", row_ndim=1, detail=lambda i: f" (row {i})")


def test_array_and_the_quaternion_check_give_rows_messages():
    with pytest.raises(ValueError, match=r"^r\[1\] must be finite and > 0, got -1.0$"):
        validate.array("r", [1.0, -1.0], (), positive=True)
    with pytest.raises(ValueError, match=r"^q\[1\] must be a unit quaternion \(x, y, z, w\), got "
                                         r"\[0.0, 0.0, 0.0, 0.0\] with length 0.0$"):
        check_unit_quat("q", [[0, 0, 0, 1.0], [0, 0, 0, 0.0]])
    with pytest.raises(ValueError, match=r"^q must be a unit quaternion \(x, y, z, w\), got "
                                         r"\[0.0, 0.0, 0.0, 2.0\] with length 2.0$"):
        check_unit_quat("q", (0, 0, 0, 2.0))


def test_the_world_checks_its_keys_and_callbacks_with_them():
    world = World()
    try:
        with pytest.raises(TypeError, match=r"resource\(key\): key must be a class \(e.g. TimeWarp\), got 'warp'"):
            world.resource("warp")
        with pytest.raises(TypeError, match=r"subscribe: event_type must be a class"):
            world.subscribe("hit", print)
        with pytest.raises(TypeError, match=r"subscribe: callback must be callable, got 3"):
            world.subscribe(int, 3)
        with pytest.raises(TypeError, match=r"a query's type must be a class \(e.g. Transform\), got 'Transform'"):
            world.query("Transform")
    finally:
        world.close()
