"""Per-step hash logs: find the first step where two runs of a scene part ways.

``driftframe play DEMO --hash-log a.txt`` and ``driftframe record DEMO --hash-log
b.txt`` write one line per fixed step, ``STEP HASH``: the number of steps
taken and :meth:`World.state_hash` after that step (every component, exact
bits). Two runs of the same scene with the same input give the same lines;
:func:`first_divergence` (``driftframe diverge a.txt b.txt``) names the first
step where they differ, which is where to look for the cause (an input that
was not recorded, a system that reads the wall clock, an order that changed).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import esper


class HashLogSystem(esper.Processor):
    """Reads every component (``world.state_hash()``); writes one ``STEP HASH`` line per step to a file.

    It runs after the camera stage (after every system of the step, added
    before or after it), so the hash is of the finished step. The file is
    opened at once (an unwritable path fails before the first step) and closed
    by ``world.close()`` or :meth:`release`.
    """

    stage = None
    after = ("camera",)
    reads = ()          # every component, through world.state_hash()
    writes = ()

    def __init__(self, path):
        self.path = Path(path)
        self._file = open(self.path, "w", buffering=1 << 16)
        #: Lines written.
        self.lines = 0

    def process(self, dt: float) -> None:
        w = self.world
        self._file.write(f"{w.step_count + 1} {w.state_hash()}\n")
        self.lines += 1

    def release(self) -> None:
        if not self._file.closed:
            self._file.close()


def attach_hash_log(world, path) -> HashLogSystem:
    """Add a :class:`HashLogSystem` after every system of the step; ``world.close()`` closes its file."""
    return world.add_system(HashLogSystem(path))


@dataclass(frozen=True)
class Divergence:
    """Where two hash logs first differ."""

    #: Steps taken when the states first differ (the line's STEP), or where the shorter log ends.
    step: int
    #: The two lines' hashes there (None: that log has ended).
    a: str | None
    b: str | None

    def __str__(self) -> str:
        if self.a is None or self.b is None:
            which = "first" if self.a is None else "second"
            return f"the {which} log ends after step {self.step - 1}; the logs agree until then"
        return f"the runs part ways at step {self.step}: {self.a} != {self.b}"


def read_hash_log(path) -> list[tuple[int, str]]:
    """``[(step, hash), ...]`` from a log file; a ValueError naming the file and line if it is malformed."""
    out = []
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise ValueError(f"{path}: cannot read the hash log ({e.strerror or e})") from None
    for n, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if len(parts) != 2 or not parts[0].isdigit():
            raise ValueError(f"{path}: line {n} is not 'STEP HASH': {line[:80]!r}")
        out.append((int(parts[0]), parts[1]))
    return out


def first_divergence(a, b) -> Divergence | None:
    """The first step where hash logs ``a`` and ``b`` (paths, or lists of ``(step, hash)``) differ.

    None when they agree line for line and have the same length.
    """
    la = read_hash_log(a) if isinstance(a, (str, Path)) else list(a)
    lb = read_hash_log(b) if isinstance(b, (str, Path)) else list(b)
    for (sa, ha), (sb, hb) in zip(la, lb):
        if sa != sb:
            raise ValueError(f"the logs are not aligned: step {sa} against step {sb}")
        if ha != hb:
            return Divergence(sa, ha, hb)
    if len(la) != len(lb):
        n = min(len(la), len(lb))
        step = (la[n - 1][0] + 1) if n else 1
        return Divergence(step, la[n][1] if len(la) > n else None, lb[n][1] if len(lb) > n else None)
    return None
