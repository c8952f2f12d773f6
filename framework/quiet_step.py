"""A quiet step: no two colliders of a small scene touch, overlap or meet within it.

Most steps of a small scene (a pair closing over a second, a rack before the
cue ball arrives) have no contact. The solver finds that out too, but only
after setting up its event loop (heap, scratch arrays, the last-contact
times made relative to ``now`` and back), which costs more than the test
itself when there are a handful of pairs. :func:`quiet_all_pairs` is that
test alone, with the solver's own pair rule (:func:`contact_toi.toi` and the
overlap test of its first pass), so a step it calls quiet is one the solver
would have left unchanged: no contact, no event, no flag, no overlap report.
"""
from __future__ import annotations

import math

from driftframe.framework.contact_bodies import gather_bodies
from driftframe.framework.contact_params import TOUCH
from driftframe.framework.contact_toi import toi
from driftframe.framework.kernels import kernel


@kernel(error_model="numpy", no_cfunc_wrapper=True)
def quiet_all_pairs(x, u, r, inv, live, pi, pj, dt):
    """True when no candidate pair ``(pi[p], pj[p])`` of live bodies, not both immovable, overlaps now
    (centres closer than ``(r_i + r_j)(1 - TOUCH)``) or meets within ``[0, dt]`` on the paths
    ``x + u t`` (``toi`` >= 0: the solver's first pass would push a contact). Stops at the first
    such pair: a busy step costs little more than reading that pair."""
    for p in range(pi.shape[0]):
        i, j = pi[p], pj[p]
        if not (live[i] and live[j]) or inv[i] + inv[j] == 0.0:
            continue
        dx = x[j, 0] - x[i, 0]
        dy = x[j, 1] - x[i, 1]
        dz = x[j, 2] - x[i, 2]
        R = r[i] + r[j]
        Rt = R * (1.0 - TOUCH)
        if dx * dx + dy * dy + dz * dz < Rt * Rt:
            return False                                  # overlapping: the solver reports it
        si = math.sqrt(u[i, 0] * u[i, 0] + u[i, 1] * u[i, 1] + u[i, 2] * u[i, 2])
        sj = math.sqrt(u[j, 0] * u[j, 0] + u[j, 1] * u[j, 1] + u[j, 2] * u[j, 2])
        tp, _ = toi(dx, dy, dz, u[j, 0] - u[i, 0], u[j, 1] - u[i, 1], u[j, 2] - u[i, 2],
                    R, inv[i] + inv[j], si + sj, 0.0, dt)
        if tp >= 0.0:
            return False
    return True


@kernel(error_model="numpy", no_cfunc_wrapper=True)
def gather_quiet(pos, vel, acc, kg, rad, rest, idx, dt, b3, a, b1, live, pairs):
    """:func:`contact_bodies.gather_bodies` and then, when every body is valid and one moves,
    :func:`quiet_all_pairs` over the pairs ``pairs[0], pairs[1]``, in one call (a small scene's step
    otherwise pays the call twice). The arrays come packed, so that the call takes 13 arguments, not 23
    (numba's dispatch costs per argument, docs/design/costs.md; this call is most of a quiet step of a few bodies):
    ``idx`` rows ``t_idx, v_idx, a_idx, m_idx, c_idx``; ``b3`` rows ``x0, v0, x, u`` (each ``(n, 3)``);
    ``b1`` rows ``inv, r, e``. Returns ``(bad, moving, quiet)``; ``quiet`` is False when it was not tested."""
    x, u = b3[2], b3[3]
    inv, r = b1[0], b1[1]
    bad, moving = gather_bodies(pos, vel, acc, kg, rad, rest, idx[0], idx[1], idx[2], idx[3], idx[4], dt,
                                b3[0], b3[1], a, inv, r, b1[2], x, u, live)
    quiet = False
    if bad == 0 and moving:
        quiet = quiet_all_pairs(x, u, r, inv, live, pairs[0], pairs[1], dt)
    return bad, moving, quiet


@kernel(error_model="numpy", no_cfunc_wrapper=True)
def write_changed(changed, t_idx, v_idx, x, u, a, dt, pos, vel):
    """The end of the step of each body ``k`` a contact changed (``changed[k]``) that has a Velocity
    (``v_idx[k] >= 0``), into the step context: ``pos[t_idx[k]] = x[k] + u[k] dt`` (m) and
    ``vel[v_idx[k]] = u[k] + (dt/2) a[k]`` (m/s; ``u[k]`` where ``a`` has no rows: no body accelerates),
    the same operations in the same order as numpy's on those rows, so the same bits. The contact step of
    a small scene otherwise spends more in numpy's fancy indexing (eight calls, each tens of microseconds
    with cold caches) than in its solver. Returns how many bodies it wrote."""
    h = 0.5 * dt
    has_a = a.shape[0] > 0
    done = 0
    for k in range(changed.shape[0]):
        if not changed[k] or v_idx[k] < 0:
            continue
        t, v = t_idx[k], v_idx[k]
        for c in range(3):
            uc = u[k, c]
            pos[t, c] = x[k, c] + uc * dt
            vel[v, c] = uc + h * a[k, c] if has_a else uc
        done += 1
    return done
