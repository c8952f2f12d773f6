"""Shared helpers for benchmarks: median timing, tables, charts, the machine line."""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
IMG = ROOT / "docs" / "img"
TABLES = ROOT / "docs" / "bench"


def parser(description: str) -> argparse.ArgumentParser:
    """An argument parser with the flags every benchmark takes."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--quick", action="store_true", help="a fast smoke run (few sizes, few repeats)")
    return p


def median_time(fn, *, repeats: int = 7, number: int = 1, warmup: int = 1) -> float:
    """Median over ``repeats`` of the mean seconds per call of ``fn`` over ``number`` calls."""
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        samples.append((time.perf_counter() - t0) / number)
    return statistics.median(samples)


def machine() -> str:
    """One line describing where the figures were measured."""
    return (f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"{platform.system()} {platform.release()}")


def table(headers: list[str], rows: list[list]) -> str:
    """A GitHub markdown table; floats are shown with 3 significant digits."""
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.3g}"
        return str(v)
    out = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    out += ["| " + " | ".join(fmt(v) for v in r) + " |" for r in rows]
    return "\n".join(out)


QUICK_NOTE = " (quick smoke run, not the reported figures)"


def write_section(name: str, title: str, body: str, *, quick: bool = False, started: float | None = None) -> Path:
    """Write ``docs/bench/<name>.md``: a titled section with the machine line and the chart link.

    ``quick`` marks the title as a smoke run; ``started`` (a ``perf_counter``
    value) adds the run time to the line printed about what was written.
    """
    TABLES.mkdir(parents=True, exist_ok=True)
    title += QUICK_NOTE if quick else ""
    chart = IMG / f"{name}.png"
    text = f"## {title}\n\nMeasured on {machine()}; `python -m benchmarks.{name}`.\n\n{body.strip()}\n"
    if chart.exists():
        text += f"\n![{title}](img/{name}.png)\n"
    path = TABLES / f"{name}.md"
    path.write_text(text)
    took = f" ({time.perf_counter() - started:.0f} s)" if started is not None else ""
    wrote = f"docs/bench/{name}.md" + (f", docs/img/{name}.png" if chart.exists() else "")
    print(f"[{name}] wrote {wrote}{took}")
    return path


def figure(*args, **kwargs):
    """A matplotlib figure on the Agg backend (no display needed)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt.subplots(*args, **kwargs)


def save_chart(fig, name: str) -> Path:
    IMG.mkdir(parents=True, exist_ok=True)
    path = IMG / f"{name}.png"
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    import matplotlib.pyplot as plt
    plt.close(fig)
    return path


def have_pybullet() -> bool:
    """Whether pybullet (the `compare` extra), the peer of the collision benchmarks, is installed.

    Looked up, not imported: startup.py measures pybullet's import in a fresh process."""
    import importlib.util
    return importlib.util.find_spec("pybullet") is not None


def pybullet_spheres(scene, dt: float):
    """``scene = (x, v, r, m, e)`` as free spheres in a new pybullet world tuned elastic; returns ``(pb, cid, ids)``.

    No gravity, no friction, damping or sleeping; one fixed step of ``dt``, no sub-steps, no restitution
    threshold and no position correction (contactERP 0). Bullet multiplies the two restitutions: sqrt(e)
    each gives the pair e. An infinite mass is Bullet's static body (mass 0).
    """
    import math

    import pybullet as pb

    x, v, r, m, e = scene
    cid = pb.connect(pb.DIRECT)
    pb.setGravity(0, 0, 0, physicsClientId=cid)
    pb.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0, restitutionVelocityThreshold=0.0,
                                 contactERP=0.0, physicsClientId=cid)
    ids, shapes = [], {}
    for xi, vi, ri, mi, ei in zip(x, v, r, m, e):
        key = float(ri)
        if key not in shapes:
            shapes[key] = pb.createCollisionShape(pb.GEOM_SPHERE, radius=key, physicsClientId=cid)
        b = pb.createMultiBody(baseMass=0.0 if not math.isfinite(mi) else float(mi),
                               baseCollisionShapeIndex=shapes[key], basePosition=xi.tolist(),
                               useMaximalCoordinates=True, physicsClientId=cid)
        pb.changeDynamics(b, -1, restitution=math.sqrt(float(ei)), lateralFriction=0.0, spinningFriction=0.0,
                          rollingFriction=0.0, linearDamping=0.0, angularDamping=0.0,
                          activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=cid)
        pb.resetBaseVelocity(b, vi.tolist(), [0, 0, 0], physicsClientId=cid)
        ids.append(b)
    return pb, cid, ids
