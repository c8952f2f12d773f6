"""The compiled free flight (framework/free_flight.py) gives advance()'s bits; a fused multiply-add would not."""
from fractions import Fraction

import numpy as np

from driftframe.framework.free_flight import free_flight
from driftframe.framework.step import advance


def _cases(n=20000, seed=1):
    rng = np.random.default_rng(seed)
    x0 = rng.standard_normal((n, 3)) * 10.0 ** rng.integers(-8, 9, (n, 3))
    v0 = rng.standard_normal((n, 3)) * 10.0 ** rng.integers(-8, 9, (n, 3))
    special = [0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, -1e308, 1e308]
    k = len(special)
    x0[:k * k, 0] = np.repeat(special, k)           # every pair of special values, both ways
    v0[:k * k, 0] = np.tile(special, k)
    return x0, v0


def _bits(a):
    return np.ascontiguousarray(a).view(np.int64)


def test_free_flight_is_advance_bit_for_bit_including_signed_zeros_infinities_and_nans():
    x0, v0 = _cases()
    for dt in (1.0 / 60.0, 1e-3, 0.1234567, 7.0):
        with np.errstate(all="ignore"):             # (inf - inf, 1e308 * 7: numpy's warnings, the same values)
            want, _ = advance(x0, v0, None, dt)                   # x0 + v0 dt
            out = np.empty_like(x0)
            advance(x0, v0, None, np.array(dt), out=(out, None))  # the movement stage's numpy path
        got = np.full_like(x0, 99.0)
        free_flight(x0, v0, dt, got)
        assert (_bits(got) == _bits(want)).all() and (_bits(got) == _bits(out)).all()
    assert np.signbit(got[1, 0]) == np.signbit(0.0 + (-0.0) * 7.0)  # -0.0 * dt + 0.0 is +0.0, as numpy says


def test_a_fused_multiply_add_would_differ_on_these_inputs():
    # the test above can fail: on these values the once-rounded v0 dt + x0 (an FMA) differs from the
    # twice-rounded one often
    x0, v0 = _cases(400, seed=2)
    dt = 1.0 / 60.0
    got = np.empty_like(x0)
    free_flight(x0, v0, dt, got)
    v, x = v0[70:].ravel(), x0[70:].ravel()                    # (past the special values)
    fused = np.array([float(Fraction(a) * Fraction(dt) + Fraction(b)) for a, b in zip(v, x)])
    differ = fused != got[70:].ravel()
    assert differ.sum() > 10


def test_free_flight_writes_every_row_of_a_view_and_nothing_else():
    col = np.zeros((8, 3))
    x0 = col[:3]
    v0 = np.arange(9.0).reshape(3, 3)
    buf = np.full((4, 3), -1.0)
    free_flight(x0, v0, 0.5, buf[:3])
    assert (buf[:3] == v0 * 0.5).all() and (buf[3] == -1.0).all()


def test_the_entry_point_is_the_kernel_for_those_types_and_a_plain_function_is_its_own():
    from driftframe.framework import kernels
    x0, v0 = _cases(100, seed=3)
    run = kernels.entry(free_flight, (x0, v0, 0.25, np.empty_like(x0)))
    assert run is not free_flight and callable(run)
    a, b = np.empty_like(x0), np.empty_like(x0)
    with np.errstate(all="ignore"):
        run(x0, v0, 0.25, a)
        free_flight(x0, v0, 0.25, b)
    assert (_bits(a) == _bits(b)).all()
    assert kernels.entry(free_flight, (x0, v0, 0.25, a)) is run       # found, not compiled again

    def plain(x):
        return x
    assert kernels.entry(plain, (1.0,)) is plain                      # (NUMBA_DISABLE_JIT: no dispatcher)
