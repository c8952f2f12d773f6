"""The two-body (Kepler) problem, solved exactly and vectorised over many bodies.

A body moving only under a point mass ``mu`` (m^3/s^2) follows a conic. Given
its state ``(r0, v0)`` relative to the mass, :func:`propagate` returns the
state after ``dt`` seconds for every eccentricity — circle, ellipse, radial,
parabola, hyperbola — with one formula, the *universal variable* formulation
(Battin 1987, ch. 4; Vallado, *Fundamentals of Astrodynamics*, alg. 8)::

    alpha   = 2/|r0| - |v0|^2/mu            (1/a: > 0 ellipse, 0 parabola, < 0 hyperbola)
    sigma0  = r0.v0 / sqrt(mu)
    psi     = alpha chi^2
    sqrt(mu) dt = chi^3 c3(psi) + sigma0 chi^2 c2(psi) + |r0| chi (1 - psi c3(psi))   (*)

``chi`` (the universal anomaly, m^(1/2)) solves (*); ``c2, c3`` are Stumpff's
functions. Position and velocity follow from the Lagrange coefficients::

    r = f r0 + g v0,     f = 1 - chi^2 c2 / |r0|,       g = dt - chi^3 c3 / sqrt(mu)
    v = fd r0 + gd v0,   fd = sqrt(mu) chi (psi c3 - 1) / (|r| |r0|),   gd = 1 - chi^2 c2 / |r|

(*) is solved by Laguerre's method of order 5 (Conway 1986), which converges
from a rough first guess for any conic where Newton's method can cycle, then
polished by Newton steps. The derivatives of the right side of (*) in ``chi``
are ``|r|`` and ``dr/dchi = sigma0 (1 - psi c2) + (1 - alpha |r0|) chi (1 - psi c3)``.

Accuracy: an elliptic ``dt`` is first reduced modulo the period, so the work
and the rounding do not grow with the time propagated; energy and angular
momentum come back to a few units of the last place (``tests/test_kepler.py``,
``benchmarks/orbit_accuracy.py``). Stumpff's functions use their series near
``psi = 0`` (where ``1 - cos`` and ``x - sin x`` cancel) and half-angle forms
elsewhere.

Everything here works on arrays of shape ``(n, 3)`` (states) and ``(n,)`` or
scalars (``mu``, ``dt``): no components, no systems. This module is the one
import; the code is in one module per concept:

* :mod:`~driftframe.framework.kepler_universal`: Stumpff's functions, the solver of
  (*), :class:`Epoch` and :func:`propagate` (numpy);
* :mod:`~driftframe.framework.kepler_kernels`: the same solution compiled (numba),
  one body at a time, taken by :meth:`Epoch.at` from :data:`COMPILED_MIN` bodies on,
  and the swept boxes of :func:`arc_boxes`;
* :mod:`~driftframe.framework.kepler_elements`: :func:`elements`, :func:`closest_approach`,
  :func:`orbit_points`;
* :mod:`~driftframe.framework.kepler_contacts`: :func:`time_to_radius`,
  :func:`time_to_touch`, :func:`time_to_touch_paths`, :func:`arc_boxes`.
"""
from __future__ import annotations

from driftframe.framework.kepler_contacts import (TOUCH_ITERATIONS, arc_boxes, time_to_radius, time_to_touch,
                                                  time_to_touch_paths)
from driftframe.framework.kepler_elements import Elements, closest_approach, elements, orbit_points
from driftframe.framework.kepler_kernels import _stumpff1
from driftframe.framework.kepler_universal import (COMPILED_MIN, TWO_PI, Epoch, _dot, _norm, next_chi, period,
                                                   propagate, solve_universal, stumpff)

__all__ = ["COMPILED_MIN", "TOUCH_ITERATIONS", "TWO_PI", "Elements", "Epoch", "arc_boxes", "closest_approach",
           "elements", "next_chi", "orbit_points", "period", "propagate", "solve_universal", "stumpff",
           "time_to_radius", "time_to_touch", "time_to_touch_paths", "_dot", "_norm", "_stumpff1"]
