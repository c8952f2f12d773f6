"""Error messages show plain numbers: a numpy scalar or array given by the user is shown as ``1.5`` or
``[1.0, 2.0]``, never as ``np.float64(1.5)`` or ``array([1., 2.])``."""
import inspect
import re

import numpy as np
import pytest

import driftframe as df
from driftframe.framework.validate import shown

NUMPY_REPR = re.compile(r"np\.(float|int|uint|bool|str)\w*\(|array\(|dtype=")
BAD = [np.float64(-1.5), np.float64(np.nan), np.float32(-2.0), np.int64(-3), np.float64(np.inf),
       np.array([1.0, np.nan]), np.array(5.0)]
COMPONENTS = ["Transform", "Velocity", "AngularVelocity", "Acceleration", "Mass", "SphereCollider", "Camera",
              "ModelRef", "FlightInput", "FlightControl", "RotationAssist", "GravityWell", "Autopilot", "FlightPlan",
              "Hold", "Press"]


def _message(fn, *args, **kwargs) -> str:
    try:
        fn(*args, **kwargs)
    except (TypeError, ValueError) as e:
        return str(e)
    return ""


def test_shown_gives_plain_python_numbers():
    assert shown(np.float64(1.5)) == "1.5"
    assert shown(np.int64(-3)) == "-3"
    assert shown(np.array([1.0, 2.0])) == "[1.0, 2.0]"
    assert shown((np.float32(0.5), 2)) == "(0.5, 2)"
    assert shown("prograde") == "'prograde'"
    assert shown(np.zeros(1000)) == "array of shape (1000,)"


@pytest.mark.parametrize("name", COMPONENTS)
def test_a_component_given_numpy_values_names_them_as_plain_numbers(name):
    cls = getattr(df, name)
    # a columnar component takes its fields (Transform.position, ...); the others their signature's names
    params = list(getattr(cls, "_fields", {})) or [
        p.name for p in inspect.signature(cls).parameters.values()
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    refused = 0
    for param in params:
        for bad in BAD:
            args = (0.0, 1.0) if name in ("Hold", "Press") and param not in ("start", "end", "time") else ()
            msg = _message(cls, *args, **{param: bad})
            refused += bool(msg)
            assert not NUMPY_REPR.search(msg), f"{name}({param}={bad!r}): {msg}"
    assert refused > 0                                          # the walk reached the checks


def test_functions_given_numpy_values_name_them_as_plain_numbers():
    rng = np.random.default_rng(0)
    msgs = [_message(df.in_shell, np.float64(-1.5), 10.0), _message(df.in_shell, 0.0, np.float64(np.nan)),
            _message(df.place, rng, np.ones(2), df.in_box((0, 0, 0), (9, 9, 9)), gap=np.float64(-1.0)),
            _message(df.declare_variant, df.World(), "rock", colour=np.float64(0.5)),
            _message(df.make_world, "spin", seed=np.int64(-1)),
            _message(df.InputSystem, np.float64(1.0))]
    assert all(msgs), msgs
    assert [m for m in msgs if NUMPY_REPR.search(m)] == []
    assert "-1.5" in msgs[0] and "nan" in msgs[1] and "-1.0" in msgs[2]
    assert "driftframe.Track" in msgs[5] and "framework." not in msgs[5]      # the public name, not the module
