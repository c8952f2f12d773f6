"""Free flight of a few bodies in one compiled call: ``x1 = x0 + v0 dt`` (m), the movement stage's prediction.

:func:`driftframe.framework.step.advance` writes the same update with two numpy
calls (``v0 dt`` into ``x1``, then ``+ x0``); for a handful of bodies each
call costs more than the arithmetic, and the compiled loop stays ahead at
every size measured (docs/design/costs.md), so the movement stage moves
every contiguous group without an Acceleration with it.
The same bits as numpy's: each element is one rounded product and one
rounded sum, ``(v0 dt) + x0`` (IEEE addition commutes exactly), and numba
without ``fastmath`` never contracts the two into a fused multiply-add.
"""
from __future__ import annotations

from driftframe.framework.kernels import kernel


@kernel(error_model="numpy", no_cfunc_wrapper=True)
def free_flight(x0, v0, dt, x1):
    """``x1[i] = x0[i] + v0[i] dt`` for every row (``(n, 3)`` arrays, m and m/s; ``dt`` s), in place."""
    for i in range(x0.shape[0]):
        for k in range(3):
            x1[i, k] = v0[i, k] * dt + x0[i, k]
