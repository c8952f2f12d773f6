"""Static shapes (issue 25): what do the billiards demo's box cushions cost against its old sphere cushions?

* **Warm step**: the billiards demo (``make_world("billiards")``, seed 0) stepped 120 steps, then the CPU
  time of this process over the next 1,680 steps (to 30 s), per step; the old table (218 fixed spheres
  of radius 4 m, 0.4 m apart, as the demo built its cushions before issue 25) the same way.
* **Cold compile**: in a fresh ``NUMBA_CACHE_DIR`` (a subprocess each), the CPU time of one call of the
  static-shape solver (``solve_static``: two balls and a plane) and of the all-pairs solver
  (``solve_all_pairs``: two balls), each alone; and the demo's first step (``make_world`` then one
  ``step``), which with box cushions always calls the solver (no quiet-step test for shapes).

Run: ``python -m benchmarks.static_shapes`` (``--quick``: one run of each, not three; prints a table;
docs/bench/static_shapes.md has figures).
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

import numpy as np

_OLD = """
import numpy as np
from driftframe.components.body import Transform
from driftframe.components.collision import BoxCollider, SphereCollider
from driftframe.demos import billiards as b
build = b.build
def old(world, rng):
    build(world, rng)
    import esper
    for e, _ in list(esper.get_component(BoxCollider)):
        world.remove_component(e, BoxCollider)
    hx, hz = b.TABLE[0] / 2, b.TABLE[1] / 2
    cx, cz = b.CENTRE
    xs = cx + np.arange(-hx, hx + 1e-9, 0.4)
    zs = cz + np.arange(-hz, hz + 1e-9, 0.4)
    rows = [np.column_stack([xs, 0 * xs, np.full_like(xs, cz + s * (hz + 4.0))]) for s in (-1, 1)]
    rows += [np.column_stack([np.full_like(zs, cx + s * (hx + 4.0)), 0 * zs, zs]) for s in (-1, 1)]
    c = np.vstack(rows)
    world.create_entities(Transform.bulk(len(c), position=c), SphereCollider.bulk(len(c), radius=np.full(len(c), 4.0)))
b.build = old
"""

_WARM = """
import time
{old}
from driftframe.app import make_world
w, _ = make_world("billiards", seed=0)
w.step(120)
t = time.process_time()
w.step(1680)
print((time.process_time() - t) / 1680 * 1e6)
"""

_SOLVER = """
import time
import numpy as np
from driftframe.framework import contact
x = np.array([[0.0, 0, 0], [1.0, 0, 0]]); u = np.array([[1.0, 0, 0], [-1.0, 0, 0]])
pi, pj = contact.all_pairs(2)
inp = contact.StepInputs(x, u, np.full(2, 0.5), np.ones(2), np.ones(2), np.ones(2, np.bool_), np.full(2, -np.inf),
                         0.0, pi, pj, 1 / 60, 1e-6 / 60, 8, None)
t = time.process_time()
if {static}:
    from driftframe.framework.static_shapes import PLANE, SHAPE_COLS
    from driftframe.systems.static_step import solve_with_shapes
    class Shapes:
        table = np.zeros((1, SHAPE_COLS)); e = np.ones(1); entities = np.array([9]); _buffers = None
        def pairs(self, pi, pj, n):
            return np.array([0, 0, 1], np.int64), np.array([1, 2, 2], np.int64)
    s = Shapes(); s.table[0, 0] = PLANE; s.table[0, 4:7] = (0, 1, 0); s.table[0, 13] = -5.0
    solve_with_shapes(inp, s)
else:
    contact.solve_step(inp)
print(time.process_time() - t)
"""

_FIRST = """
import time
{old}
from driftframe.app import make_world
t = time.process_time()
w, _ = make_world("billiards", seed=0)
w.step()
print(time.process_time() - t)
"""


def _run(code: str, cache: str | None = None) -> float:
    env = dict(os.environ)
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = cache
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.split()[-1])


def _cold(code: str) -> float:
    with tempfile.TemporaryDirectory() as cache:
        return _run(code, cache)


def main(repeats: int = 3) -> None:
    rows = []
    for name, old in (("box cushions (now)", ""), ("sphere cushions (before)", _OLD)):
        _run(_WARM.format(old=old))                           # fill the cache first
        warm = [_run(_WARM.format(old=old)) for _ in range(repeats)]
        first = [_cold(_FIRST.format(old=old)) for _ in range(repeats)]
        rows.append((name, float(np.median(warm)), float(np.median(first))))
    print("| table | warm CPU us/step (steps 120-1800), median | cold first step CPU s, median |")
    print("|---|---|---|")
    for name, warm, first in rows:
        print(f"| {name} | {warm:.1f} | {first:.2f} |")
    for static in (True, False):
        t = [_cold(_SOLVER.format(static=static)) for _ in range(repeats)]
        print(f"cold compile, {'solve_static' if static else 'solve_all_pairs'} alone: "
              f"{float(np.median(t)):.2f} s CPU (median of {repeats}: {', '.join(f'{v:.2f}' for v in t)})")


if __name__ == "__main__":
    t0 = time.perf_counter()
    main(1 if "--quick" in sys.argv[1:] else 3)               # --quick: one run of each
    print(f"({time.perf_counter() - t0:.0f} s)")
