"""Static planes and boxes against spheres: time of impact, contact normal (compiled kernels).

The solver's static-shape variant (:data:`.contact_solve.solve_static`) takes the shapes as one
``(m, SHAPE_COLS)`` float table ``S`` (built by :mod:`driftframe.systems.static_step`), row ``k``:

* ``S[k, KIND]``: :data:`PLANE` or :data:`BOX`;
* ``S[k, 1:4]``: the box's centre (m, world);
* ``S[k, 4:13]``: the box's rotation ``Q`` row-major (``world = Q local``: its columns are the box's
  axes); for a plane ``S[k, 4:7]`` is the unit outward normal ``n`` (world);
* ``S[k, 13:16]``: the box's half extents ``h`` (m); for a plane ``S[k, 13]`` is ``d``, the face
  being ``n . p = d``.

A sphere of radius ``r`` moves as ``p(t) = x + u t`` (the solver's path: the step's mean velocity).

**Plane.** The signed gap ``s(t) = n . p(t) - d - r`` is linear in ``t``: contact at
``t = t0 + s(t0) / (-n . u)`` when ``n . u < 0`` (approaching); ``s(t0) <= 0`` (touching, or behind
the face: the half-space is solid) and approaching is a contact now.

**Box.** The sphere's centre against the box grown by ``r`` (Minkowski sum), in the box's frame
``q = Q^T (p - c)``, ``w = Q^T u``. That rounded box is the union of three boxes (the box grown by
``r`` along one axis), twelve cylinders of radius ``r`` about the edges (each cut to its edge's length)
and eight spheres of radius ``r`` about the corners; each is convex, so the line meets it in one
interval, and the path enters the union at the earliest of the pieces' entries. No region test picks
a feature (the pieces overlap on their borders), so a path through an edge or corner cannot slip
between two features by a rounding. A path that starts within ``r`` of the box (touching) and
approaches is in contact now; the normal is ``q - clamp(q, -h, h)``, made unit and turned to the world.

**Starting inside.** The box is solid, as the plane's half-space is. A centre inside it takes the
normal of its nearest face (the axis of least ``h_a - |q_a|``, x before y before z on a tie; +a where
``q_a = 0``) and that depth, negative, as its distance; so a sphere that overlaps a shape at the start
(at spawn: :class:`~driftframe.systems.static_step.StaticShapes` reports it) is treated as two
overlapping spheres are: one moving deeper (into the plane, towards the nearest face's inside) bounces
at once, one impulse and no jump; one moving out is left to leave. Inside a box the nearest face is
read where the sphere's path starts in the step (or at its last contact), not followed along it.

Nothing here knows about entities; the approach rule is the solver's own
(``v_n < -APPROACH |u|``), and ``slack`` its ``TOUCH r / |v_n|`` capped at ``SLACK_MAX dt``.
"""
from __future__ import annotations

import math

from driftframe.framework.contact_heap import heap_push
from driftframe.framework.contact_params import APPROACH, S_PUSHED, SLACK_MAX, TOUCH
from driftframe.framework.kernels import kernel

_OPTS = dict(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
_INF = math.inf
# _MINMAX: min and max of two floats are written as conditionals, ``max(a, b)`` as ``b if b > a else a``
# (what Python's and numba's give, NaN included): numba compiles its min and max as functions of their
# own per signature, typed again at every call (a cold compile's cost: docs/bench/compile.md).

#: The table's columns, and the kinds.
SHAPE_COLS = 16
KIND = 0
PLANE = 0.0
BOX = 1.0


@kernel(**_OPTS)
def _local(S, k, vx, vy, vz):
    """``Q^T v`` of box ``k`` (a world vector into its frame)."""
    return (S[k, 4] * vx + S[k, 7] * vy + S[k, 10] * vz,
            S[k, 5] * vx + S[k, 8] * vy + S[k, 11] * vz,
            S[k, 6] * vx + S[k, 9] * vy + S[k, 12] * vz)


@kernel(**_OPTS)
def _slab(q, w, lo, hi, a, b):
    """The interval ``[a, b]`` of ``tau`` narrowed to ``lo <= q + w tau <= hi``."""
    if w == 0.0:
        if q < lo or q > hi:
            return _INF, -_INF
        return a, b
    t1 = (lo - q) / w
    t2 = (hi - q) / w
    if t1 > t2:
        t1, t2 = t2, t1
    return (t1 if t1 > a else a), (t2 if t2 < b else b)         # max(a, t1), min(b, t2) (see _MINMAX)


@kernel(**_OPTS)
def _round(ex, ey, ez, wx, wy, wz, r, a, b):
    """The interval ``[a, b]`` narrowed to ``|e + w tau| <= r`` (e, w: two or three components; a
    cylinder passes ez = wz = 0)."""
    A = wx * wx + wy * wy + wz * wz
    B = ex * wx + ey * wy + ez * wz
    C = ex * ex + ey * ey + ez * ez - r * r
    if A == 0.0:
        if C > 0.0:
            return _INF, -_INF
        return a, b
    disc = B * B - A * C
    if disc < 0.0:
        return _INF, -_INF
    sq = math.sqrt(disc)
    # the two roots without cancellation: q = -(B + sign(B) sq); roots q / A and C / q
    qq = -(B + sq) if B >= 0.0 else -(B - sq)
    if qq == 0.0:
        return (0.0 if 0.0 > a else a), (0.0 if 0.0 < b else b)
    t1 = qq / A
    t2 = C / qq
    if t1 > t2:
        t1, t2 = t2, t1
    return (t1 if t1 > a else a), (t2 if t2 < b else b)


@kernel(**_OPTS)
def box_entry(qx, qy, qz, wx, wy, wz, hx, hy, hz, r, limit):
    """The earliest ``tau`` in ``[0, limit]`` at which ``q + w tau`` comes within ``r`` of the box
    ``[-h, h]`` (its frame), entering it from outside; inf when it does not."""
    # the grown box [-(h + r), h + r] bounds every piece: most paths end here
    a, b = _slab(qx, wx, -hx - r, hx + r, 0.0, limit)
    a, b = _slab(qy, wy, -hy - r, hy + r, a, b)
    a, b = _slab(qz, wz, -hz - r, hz + r, a, b)
    if a > b:
        return _INF
    best = _INF
    # the three boxes grown along one axis (faces)
    for ax in range(3):
        gx = r if ax == 0 else 0.0
        gy = r if ax == 1 else 0.0
        gz = r if ax == 2 else 0.0
        a, b = _slab(qx, wx, -hx - gx, hx + gx, 0.0, limit)
        a, b = _slab(qy, wy, -hy - gy, hy + gy, a, b)
        a, b = _slab(qz, wz, -hz - gz, hz + gz, a, b)
        if a <= b and a < best:
            best = a
    # the twelve edges: a cylinder about each, cut to the edge's length
    for sa in (-1.0, 1.0):
        for sb in (-1.0, 1.0):
            a, b = _slab(qx, wx, -hx, hx, 0.0, limit)                     # edges along x
            a, b = _round(qy - sa * hy, qz - sb * hz, 0.0, wy, wz, 0.0, r, a, b)
            if a <= b and a < best:
                best = a
            a, b = _slab(qy, wy, -hy, hy, 0.0, limit)                     # along y
            a, b = _round(qx - sa * hx, qz - sb * hz, 0.0, wx, wz, 0.0, r, a, b)
            if a <= b and a < best:
                best = a
            a, b = _slab(qz, wz, -hz, hz, 0.0, limit)                     # along z
            a, b = _round(qx - sa * hx, qy - sb * hy, 0.0, wx, wy, 0.0, r, a, b)
            if a <= b and a < best:
                best = a
            for sc in (-1.0, 1.0):                                       # the corners
                a, b = _round(qx - sa * hx, qy - sb * hy, qz - sc * hz, wx, wy, wz, r, 0.0, limit)
                if a <= b and a < best:
                    best = a
    return best


@kernel(**_OPTS)
def _inside(S, k, qx, qy, qz):
    """Box ``k``'s nearest face to a point ``q`` inside it (its frame): the face's unit outward normal
    (world) and minus the point's depth under it (m), ``-(h_a - |q_a|)`` for the axis ``a`` of least depth."""
    a = 0
    depth = S[k, 13] - abs(qx)
    dy = S[k, 14] - abs(qy)
    dz = S[k, 15] - abs(qz)
    side = -1.0 if qx < 0.0 else 1.0
    if dy < depth:
        a, depth, side = 1, dy, -1.0 if qy < 0.0 else 1.0
    if dz < depth:
        a, depth, side = 2, dz, -1.0 if qz < 0.0 else 1.0
    # column a of Q (row-major at S[k, 4:13]) is the box's axis a in world coordinates
    return side * S[k, 4 + a], side * S[k, 7 + a], side * S[k, 10 + a], -depth


@kernel(**_OPTS)
def outward(S, k, px, py, pz):
    """The unit outward normal of shape ``k`` at the sphere centre ``p`` (world), and the centre's
    signed distance from the shape's surface (m, < 0 inside); inside a box its nearest face's."""
    if S[k, KIND] == PLANE:
        nx, ny, nz = S[k, 4], S[k, 5], S[k, 6]
        return nx, ny, nz, nx * px + ny * py + nz * pz - S[k, 13]
    qx, qy, qz = _local(S, k, px - S[k, 1], py - S[k, 2], pz - S[k, 3])
    hx, hy, hz = S[k, 13], S[k, 14], S[k, 15]
    mx = -hx if -hx > qx else qx                   # clamp(q, -h, h) = min(max(q, -h), h) (see _MINMAX)
    my = -hy if -hy > qy else qy
    mz = -hz if -hz > qz else qz
    gx = qx - (hx if hx < mx else mx)
    gy = qy - (hy if hy < my else my)
    gz = qz - (hz if hz < mz else mz)
    dist = math.sqrt(gx * gx + gy * gy + gz * gz)
    if dist == 0.0:
        return _inside(S, k, qx, qy, qz)
    gx, gy, gz = gx / dist, gy / dist, gz / dist
    return (S[k, 4] * gx + S[k, 5] * gy + S[k, 6] * gz,
            S[k, 7] * gx + S[k, 8] * gy + S[k, 9] * gz,
            S[k, 10] * gx + S[k, 11] * gy + S[k, 12] * gz, dist)


@kernel(**_OPTS)
def static_toi(px, py, pz, ux, uy, uz, r, spd, S, k, t, dt):
    """Earliest contact in ``[t, dt]`` of a sphere (radius ``r``, path ``p + u t'``, speed ``spd``) with
    shape ``k``; ``(time, slack)``, or ``(-1, 0)`` when none."""
    cx = px + ux * t
    cy = py + uy * t
    cz = pz + uz * t
    nx, ny, nz, dist = outward(S, k, cx, cy, cz)
    vn = nx * ux + ny * uy + nz * uz                      # outward speed (< 0: approaching)
    if S[k, KIND] == PLANE:
        if not (vn < -APPROACH * spd):
            return -1.0, 0.0
        gap = dist - r
        tc = t if gap <= 0.0 else t + gap / -vn
    elif dist <= r:
        if not (vn < -APPROACH * spd):                     # touching or inside, and separating
            return -1.0, 0.0
        tc = t
    else:
        qx, qy, qz = _local(S, k, cx - S[k, 1], cy - S[k, 2], cz - S[k, 3])
        wx, wy, wz = _local(S, k, ux, uy, uz)
        tau = box_entry(qx, qy, qz, wx, wy, wz, S[k, 13], S[k, 14], S[k, 15], r, dt - t)
        if tau == _INF:
            return -1.0, 0.0
        tc = t + tau
        nx, ny, nz, dist = outward(S, k, px + ux * tc, py + uy * tc, pz + uz * tc)
        vn = nx * ux + ny * uy + nz * uz
        if not (vn < -APPROACH * spd):
            return -1.0, 0.0                               # a graze: the paths touch and part
    if tc > dt:
        return -1.0, 0.0
    slack = TOUCH * r / -vn
    if slack > SLACK_MAX * dt:
        slack = SLACK_MAX * dt
    return tc, slack


@kernel(**_OPTS, inline="always")
def static_heap(H, hn, PI, PJ, P, x, u, r, live, spd, dt, S, ns):
    """Add to the heap rows ``H[:hn]`` the first contact of every sphere-shape pair (``PJ[p] >= ns``:
    shape ``PJ[p] - ns``) from t = 0; returns the new row count (``H`` has a row for every pair)."""
    for p in range(P):
        i, j = PI[p], PJ[p]
        if j < ns or not live[i]:
            continue
        tp, sl = static_toi(x[i, 0], x[i, 1], x[i, 2], u[i, 0], u[i, 1], u[i, 2], r[i], spd[i], S, j - ns, 0.0, dt)
        if tp >= 0.0:
            H[hn, 0], H[hn, 1], H[hn, 2], H[hn, 3] = tp, p, 0.0, sl
            hn += 1
    return hn


# The solver's pieces (:mod:`.contact_solve`, its ``_STATIC`` branches). The step's ones are pasted into it
# (inline="always"): compiled on their own, each would relink and re-optimise static_toi and what it calls.
@kernel(**_OPTS)
def shapes_start(H, hn, PI, PJ, P, x, u, r, live, spd, dt, S, n):
    """``(ns, hn)``: the first shape's body index (the shapes are the last ``len(S)`` bodies), and the
    heap's rows with every sphere-shape pair's first contact added (:func:`static_heap`)."""
    ns = n - S.shape[0]
    return ns, static_heap(H, hn, PI, PJ, P, x, u, r, live, spd, dt, S, ns)


@kernel(**_OPTS)
def shape_contact(S, k, x, u, i, t):
    """The contact normal from sphere ``i`` to shape ``k`` at ``t`` (minus the shape's outward normal)
    and the normal relative velocity ``n . (0 - u_i)`` (< 0: approaching)."""
    ox, oy, oz, _ = outward(S, k, x[i, 0] + u[i, 0] * t, x[i, 1] + u[i, 1] * t, x[i, 2] + u[i, 2] * t)
    return -ox, -oy, -oz, ox * u[i, 0] + oy * u[i, 1] + oz * u[i, 2]


@kernel(**_OPTS)
def shape_push(H, hn, p, v, x, u, r, spd, live, S, i, k, t, dt, stats):
    """Push pair ``p`` (version ``v``: sphere ``i``, shape ``k``) with its next contact from ``t``, if any
    (``H`` has room); returns the heap's rows."""
    if live[i]:
        tp, sl = static_toi(x[i, 0], x[i, 1], x[i, 2], u[i, 0], u[i, 1], u[i, 2], r[i], spd[i], S, k, t, dt)
        if tp >= 0.0:
            heap_push(H, hn, tp, p, v, sl)
            hn += 1
            stats[S_PUSHED] += 1
    return hn
