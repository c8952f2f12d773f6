"""framework/validate.py's shared checks: each error names the argument and shows the bad value."""
from __future__ import annotations

import numpy as np
import pytest

from driftframe.framework import validate


def test_choice_returns_a_listed_value_and_names_the_options_and_the_bad_one():
    assert validate.choice("Camera.mode", "chase", ("cockpit", "chase")) == "chase"
    with pytest.raises(ValueError, match=r"Camera.mode must be one of \('cockpit', 'chase'\), got 'orbit'"):
        validate.choice("Camera.mode", "orbit", ("cockpit", "chase"))
    with pytest.raises(ValueError, match=r"got \[1, 2\]"):          # an unhashable value is a clear error too
        validate.choice("mode", [1, 2], ("a",))


@pytest.mark.parametrize("value", [0, 7, np.int64(7), np.uint32(3)])
def test_entity_id_takes_python_and_numpy_integers_as_int(value):
    got = validate.entity_id("Camera.target", value)
    assert got == int(value) and type(got) is int


@pytest.mark.parametrize("value", [True, np.bool_(False), -1, 1.0, "3", None])
def test_entity_id_rejects_bools_negatives_floats_strings_and_none(value):
    with pytest.raises(TypeError, match=r"Camera.target must be an entity id \(int >= 0\), got "):
        validate.entity_id("Camera.target", value)


def test_an_optional_entity_id_is_none_or_an_id():
    assert validate.entity_id("GravityWell.parent", None, optional=True) is None
    assert validate.entity_id("GravityWell.parent", np.int64(2), optional=True) == 2
    with pytest.raises(TypeError, match=r"GravityWell.parent must be an entity id \(int >= 0\) or None, got -3"):
        validate.entity_id("GravityWell.parent", -3, optional=True)


def test_the_components_use_them():
    from driftframe.components.autopilot import Autopilot
    from driftframe.components.camera import Camera
    from driftframe.components.gravity import GravityWell
    with pytest.raises(TypeError, match=r"Autopilot.target must be an entity id \(int >= 0\) or None, got 'x'"):
        Autopilot(mode="prograde", target="x")
    assert Camera(target=np.int64(4)).target == 4
    with pytest.raises(TypeError, match="GravityWell.parent must be an entity id"):
        GravityWell(mu=1.0, radius=1.0, parent=1.5)


def test_rows_names_the_first_bad_row_of_a_column_and_a_bad_scalar():
    import numpy as np
    import pytest

    from driftframe.framework import validate

    validate.rows("Mass.kg", np.array([1.0, 2.0]), np.array([False, False]), "> 0")     # none bad: nothing
    with pytest.raises(ValueError, match=r"^Mass\.kg\[2\] must be > 0, got -1\.0$"):
        validate.rows("Mass.kg", np.array([1.0, 2.0, -1.0, -3.0]), np.array([False, False, True, True]), "> 0")
    with pytest.raises(ValueError, match=r"^radius must be > 0, got 0\.0$"):
        validate.rows("radius", np.float64(0.0), True, "> 0")
