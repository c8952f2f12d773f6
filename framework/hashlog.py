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

from driftframe.framework.inputfile import InputFileError, open_regular
from driftframe.framework.output import PartFile


class HashLogSystem(esper.Processor):
    """Reads every component (``world.state_hash()``); writes one ``STEP HASH`` line per step to a file.

    It runs after the camera stage (after every system of the step, added
    before or after it), so the hash is of the finished step. The log is
    written to a part file beside ``path`` (:mod:`framework.output`), made at
    once (an unwritable folder fails before the first step), and moved into
    place by ``world.close()`` or :meth:`release`: complete up to the last
    whole step, however the run ended. An existing ``path`` is refused
    unless ``overwrite``.

    A failed write (a full disk) does not stop the run: the log stops, its
    part file is removed and :attr:`error` says why, naming the file (the
    command line reports it after the run, whose other outputs are kept).
    """

    stage = None
    after = ("camera",)
    reads = ()          # every component, through world.state_hash()
    writes = ()

    def __init__(self, path, *, overwrite: bool = False):
        self.path = Path(path)
        self._file = PartFile(self.path, overwrite=overwrite, what="hash log", buffering=1 << 16)
        #: Lines written.
        self.lines = 0
        #: Why the log was not kept (an :class:`~framework.output.OutputError`), or None.
        self.error: OSError | None = None
        #: Where the finished log is, once released (None before, or when it failed).
        self.written: Path | None = None

    def process(self, dt: float) -> None:
        if self.error is not None:
            return
        w = self.world
        try:
            self._file.write(f"{w.step_count + 1} {w.state_hash()}\n")
        except OSError as e:
            self.error = e
            return
        self.lines += 1

    def release(self) -> None:
        """Move the log into place (once); a failure goes to :attr:`error`, never raised from here."""
        if self.error is not None or self.written is not None:
            return
        try:
            self.written = self._file.commit()
        except OSError as e:
            self._file.discard()
            self.error = e


def attach_hash_log(world, path, *, overwrite: bool = False) -> HashLogSystem:
    """Add a :class:`HashLogSystem` after every system of the step; ``world.close()`` finishes its file."""
    return world.add_system(HashLogSystem(path, overwrite=overwrite))


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


#: Largest hash log read: 512 MiB. A line is at most ~45 bytes ("STEP" + a 32-digit hex hash), so this is
#: over 10,000,000 steps, the most a recording may take (``driftframe.cli.MAX_STEPS``).
HASH_LOG_CAP = 512 << 20
#: Longest line: a step number and a hash, with room.
_LINE_CAP = 256


def iter_hash_log(path):
    """``(step, hash)`` line by line from a log file, without holding it (see :data:`HASH_LOG_CAP`).

    A ValueError (an :class:`~framework.inputfile.InputFileError`) names the
    file, the line and the text when the file cannot be read or is malformed.
    """
    where = str(path)
    with open_regular(path, HASH_LOG_CAP, "hash log") as f:
        n = read = 0
        while True:
            try:
                raw = f.readline(_LINE_CAP + 1)
            except OSError as e:
                raise InputFileError(f"{where}: cannot read the hash log ({e.strerror or e})") from None
            if not raw:
                return
            n += 1
            read += len(raw)
            if read > HASH_LOG_CAP:
                raise InputFileError(f"{where}: the hash log is over the limit of {HASH_LOG_CAP >> 20} MiB")
            if len(raw) > _LINE_CAP:
                raise InputFileError(f"{where}: line {n} is not 'STEP HASH': longer than {_LINE_CAP} bytes")
            try:
                line = raw.decode("utf-8")
            except UnicodeDecodeError:
                raise InputFileError(f"{where}: line {n} is not 'STEP HASH': {raw[:80]!r} is not text "
                                     "(a binary file?)") from None
            parts = line.split()
            # ASCII digits only: "²".isdigit() is true, yet int("²") fails
            if len(parts) != 2 or not (parts[0].isascii() and parts[0].isdigit()) or not parts[1].isascii():
                raise InputFileError(f"{where}: line {n} is not 'STEP HASH': {line.rstrip(chr(10))[:80]!r}")
            yield int(parts[0]), parts[1]


def read_hash_log(path) -> list[tuple[int, str]]:
    """``[(step, hash), ...]`` from a log file; a ValueError naming the file and line if it is malformed."""
    return list(iter_hash_log(path))


def first_divergence(a, b) -> Divergence | None:
    """The first step where hash logs ``a`` and ``b`` (paths, or lists of ``(step, hash)``) differ.

    None when they agree line for line and have the same length. Files are
    read line by line in step, so two long logs need no memory.
    """
    la = iter_hash_log(a) if isinstance(a, (str, Path)) else iter(list(a))
    lb = iter_hash_log(b) if isinstance(b, (str, Path)) else iter(list(b))
    n = 0
    last = 0
    end = object()
    while True:
        ea, eb = next(la, end), next(lb, end)
        if ea is end and eb is end:
            return None
        if ea is end or eb is end:
            step = last + 1 if n else 1
            return Divergence(step, None if ea is end else ea[1], None if eb is end else eb[1])
        (sa, ha), (sb, hb) = ea, eb
        if sa != sb:
            raise ValueError(f"the logs are not aligned: step {sa} in {a} against step {sb} in {b}"
                             if isinstance(a, (str, Path)) else
                             f"the logs are not aligned: step {sa} against step {sb}")
        if ha != hb:
            return Divergence(sa, ha, hb)
        n += 1
        last = sa


def count_steps(path) -> int:
    """Lines in a hash log (checked as :func:`iter_hash_log` checks them)."""
    return sum(1 for _ in iter_hash_log(path))
