"""Input checks shared by every public constructor.

Each check raises ``ValueError`` (or ``TypeError``) whose message names the
argument and repeats the bad value, so a user sees *which* number was wrong.
"""
from __future__ import annotations

import math

import numpy as np


def _plain(value: object) -> object:
    """``value`` with numpy scalars and arrays as Python numbers and lists (a message shows ``1.5``, not
    ``np.float64(1.5)``; ``[1.0, 2.0]``, not ``array([1., 2.])``), inside lists and tuples too."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)) and type(value) in (list, tuple):
        return type(value)(_plain(v) for v in value)
    return value


def shown(value: object) -> str:
    """``value`` as an error message shows it: its repr with plain Python numbers, or its shape if large."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value).bit_length() > 80:
        return f"an integer of about {int(abs(value).bit_length() * 0.30103) + 1} digits"   # log10(2) digits a bit
    try:
        arr = np.asarray(value)
    except (OverflowError, ValueError):
        return f"a {type(value).__name__}"
    if arr.size > 12:
        return f"array of shape {arr.shape}"
    return repr(_plain(value))


_show = shown


def vector(name: str, value, shape=(3,), *, allow_inf: bool = False) -> np.ndarray:
    """Return ``value`` as a float64 array of ``shape``; reject NaN and (unless allowed) inf."""
    try:
        arr = np.array(value, dtype=np.float64)
    except OverflowError:
        raise ValueError(f"{name} holds a number too large for a float (over 1.8e308)") from None
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be numbers of shape {shape}, got {_show(value)}") from None
    if arr.shape != tuple(shape):
        raise ValueError(f"{name} must have shape {tuple(shape)}, got shape {arr.shape}: {_show(value)}")
    if np.isnan(arr).any():
        raise ValueError(f"{name} must not contain NaN, got {_show(value)}")
    if not allow_inf and np.isinf(arr).any():
        raise ValueError(f"{name} must be finite, got {_show(value)}")
    return arr


def scalar(name: str, value, *, positive: bool = False, nonnegative: bool = False,
           allow_inf: bool = False, lo: float | None = None, hi: float | None = None) -> float:
    """Return ``value`` as a float after range checks that name the argument."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number, got {_show(value)}")
    try:
        x = float(value)
    except OverflowError:     # an int past 1.8e308
        raise ValueError(f"{name} is too large for a float (over 1.8e308), got {_show(value)}") from None
    if math.isnan(x):
        raise ValueError(f"{name} must not be NaN, got {x!r}")
    if math.isinf(x) and not allow_inf:
        raise ValueError(f"{name} must be finite, got {x!r}")
    if positive and not x > 0:
        raise ValueError(f"{name} must be > 0, got {x!r}")
    if nonnegative and not x >= 0:
        raise ValueError(f"{name} must be >= 0, got {x!r}")
    if lo is not None and x < lo or hi is not None and x > hi:
        raise ValueError(f"{name} must be in [{lo}, {hi}], got {x!r}")
    return x


def array(name: str, value, shape_tail=(3,), n: int | None = None, *, allow_inf: bool = False,
          positive: bool = False, lo: float | None = None, hi: float | None = None) -> np.ndarray:
    """Validate a column of values, shape ``(n, *shape_tail)``; the message gives the first bad row."""
    try:
        arr = np.array(value, dtype=np.float64)
    except OverflowError:
        raise ValueError(f"{name} holds a number too large for a float (over 1.8e308)") from None
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be an array of numbers, got {type(value).__name__}") from None
    if arr.ndim != 1 + len(shape_tail) or arr.shape[1:] != tuple(shape_tail):
        raise ValueError(f"{name} must have shape (N, {', '.join(map(str, shape_tail))})"
                         .replace(", )", ")") + f", got {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name} has {arr.shape[0]} rows, expected {n}")
    flat = arr.reshape(arr.shape[0], -1)
    bad = np.isnan(flat).any(axis=1)
    if not allow_inf:
        bad |= np.isinf(flat).any(axis=1)
    if positive:
        bad |= ~(flat > 0).all(axis=1)
    if lo is not None:
        bad |= (flat < lo).any(axis=1)
    if hi is not None:
        bad |= (flat > hi).any(axis=1)
    if bad.any():
        need = "finite" if not allow_inf else "not NaN"
        if positive:
            need += " and > 0"
        if lo is not None or hi is not None:
            need += f" and in [{lo}, {hi}]"
        rows(name, arr, bad, need, row_ndim=len(shape_tail))
    return arr


def rows(name: str, values, bad, need: str, *, row_ndim: int = 0, detail=None) -> None:
    """The one "first bad row" check: a ValueError ``name[i] must be NEED, got V`` for the first ``i``
    where ``bad`` is true; nothing when none is.

    ``values``: one row or a column of rows, each ``row_ndim``-dimensional (0: numbers, shown as floats;
    1: vectors, quaternions; ...); one row alone gives ``name must be ...``. ``detail(i)``: text to add
    after the value (``" with length 2.0"``)."""
    bad = np.atleast_1d(np.asarray(bad))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        column = np.ndim(values) > row_ndim
        where = f"[{i}]" if column else ""
        row = np.asarray(values)[i] if column else values
        got = repr(float(np.asarray(row))) if row_ndim == 0 else _show(row)
        raise ValueError(f"{name}{where} must be {need}, got {got}{detail(i) if detail else ''}")


def choice(name: str, value, options: tuple):
    """``value`` when it is one of ``options``; else a ValueError naming ``name``, the options and the value."""
    if value not in options:
        raise ValueError(f"{name} must be one of {options}, got {shown(value)}")
    return value


def a_class(name: str, value, example: str = ""):
    """``value`` when it is a class; else a TypeError naming ``name`` (with an ``example`` of one) and the
    value."""
    if not isinstance(value, type):
        eg = f" (e.g. {example})" if example else ""
        raise TypeError(f"{name} must be a class{eg}, got {shown(value)}")
    return value


def text(name: str, value, what: str = "a non-empty str") -> str:
    """``value`` when it is a non-empty str; else a TypeError naming ``name``, ``what`` it must be and the
    value."""
    if not isinstance(value, str) or not value:
        raise TypeError(f"{name} must be {what}, got {shown(value)}")
    return value


def function(name: str, value, *, optional: bool = False, what: str = "callable"):
    """``value`` when it can be called (or is None, when ``optional``); else a TypeError naming ``name``,
    what it must be and the value."""
    if value is None and optional:
        return None
    if not callable(value):
        raise TypeError(f"{name} must be {what}{' or None' if optional else ''}, got {shown(value)}")
    return value


def entity_id(name: str, value, *, optional: bool = False) -> int | None:
    """``value`` as an entity id (a Python or numpy integer >= 0, not a bool), or None when ``optional``;
    else a TypeError naming ``name`` and the value."""
    if value is None and optional:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 0:
        raise TypeError(f"{name} must be an entity id (int >= 0){' or None' if optional else ''}, got {shown(value)}")
    return int(value)
