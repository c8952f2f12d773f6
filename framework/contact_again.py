"""F_AGAIN: keeping a step's inputs and putting them back, so that it can be run again (compiled kernels)."""
from __future__ import annotations

import numpy as np

from driftframe.framework.kernels import kernel

# F_AGAIN: a step is run again from its inputs as they came. What it changes: x and u of the bodies it
# moved (_solve keeps their rows before it first changes them: O(moved), not O(n) a step), t_last (shifted
# in place: (t - now) + now is not t in every bit, so a copy) and, with the list, swept. blo and bhi need
# none: the rows of bodies swept at the start are made again from x and u, the others are not read.

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True, inline="always")
def _put_rows(x, u, changed, x_in, u_in):
    for b in range(changed.shape[0]):
        if changed[b]:
            for d in range(3):
                x[b, d] = x_in[b, d]
                u[b, d] = u_in[b, d]


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def keep_pairs(x, u, t_last, lst):
    keep = np.empty(t_last.shape[0], np.float64)
    for k in range(t_last.shape[0]):
        keep[k] = t_last[k]
    return keep


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def put_back_pairs(keep, x, u, t_last, lst, changed, x_in, u_in):
    _put_rows(x, u, changed, x_in, u_in)
    for k in range(t_last.shape[0]):
        t_last[k] = keep[k]


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def keep_listed(x, u, t_last, lst):
    return t_last.copy(), lst[0].copy()


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def put_back_listed(keep, x, u, t_last, lst, changed, x_in, u_in):
    _put_rows(x, u, changed, x_in, u_in)
    for k in range(t_last.shape[0]):
        t_last[k] = keep[0][k]
        lst[0][k] = keep[1][k]


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def keep_nothing(x, u, t_last, lst):
    """The variants with the jam path never end a step with F_AGAIN."""
    return None


@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def put_back_nothing(keep, x, u, t_last, lst, changed, x_in, u_in):
    pass

