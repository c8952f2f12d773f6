"""A batch's summary: a CSV row per run, a Markdown report, and one chart of the collected stats.

:func:`write` puts ``summary.csv``, ``summary.md`` and ``summary.png`` in
the output folder, each written to a temporary name and moved into place.
The chart shows the *distribution* of energy drift (and of momentum drift
and contacts when they were collected), one histogram per group of runs
(demo or scene, and the overrides), on a symmetric log axis whose middle bin
holds the runs that kept energy to the last bit. It needs matplotlib (the
``batch`` extra); without it the CSV and the Markdown are still written and
the caller is told why there is no chart.

While the batch runs, :class:`Journal` appends each run as it ends to
``journal.jsonl`` (a JSON line: the spec's hash, the result) and to
``summary.csv``; :func:`read_journal` and :func:`resumed` give
``driftframe batch --resume`` the runs it can skip.
"""
from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
import statistics
from pathlib import Path

import numpy as np

from driftframe.batch import Outcome, Result

STAGES = ("input", "control", "movement", "spin", "collision", "camera", "render", "record")
COLUMNS = ["index", "status", "demo", "scene", "seed", "seconds", "fps", "size", "camera", "sky", "overrides",
           "output", "state_hash", "steps", "frames", "energy_drift", "momentum_drift", "contacts",
           "energy_start", "energy_end", "wall_seconds"] + [f"{s}_seconds" for s in STAGES] + ["error"]
#: Drifts below this are shown as zero (the linear middle of the symmetric log axis): less than one
#: rounding of a double, relative to the quantity itself.
LINEAR = 1e-16


def group(spec) -> str:
    """The group a run is charted and summarised in: its demo or scene, and its overrides."""
    what = spec.demo if spec.demo is not None else spec.scene
    return what + "".join(f" {k}={v}" for k, v in sorted(spec.overrides.items()))


def rows(outcome: Outcome) -> list[dict]:
    return [_row(i, res) for i, res in enumerate(outcome.results) if res is not None]


def _row(i: int, res) -> dict:
    s = res.spec
    row = {"index": i, "demo": s.demo or "", "scene": s.scene or "", "seed": s.seed, "seconds": s.seconds,
           "fps": s.fps if s.output else "", "size": f"{s.size[0]}x{s.size[1]}" if s.output else "",
           "camera": s.camera or "", "sky": s.sky if s.output else "",
           "overrides": " ".join(f"{k}={v}" for k, v in sorted(s.overrides.items())),
           "output": s.output or "", "wall_seconds": f"{res.wall_seconds:.3f}"}
    if isinstance(res, Result):
        st = res.stats
        row.update(status="ok", state_hash=res.state_hash, steps=res.steps, frames=res.frames,
                   energy_drift=_g(st.get("energy_drift")), momentum_drift=_g(st.get("momentum_drift")),
                   contacts=st.get("contacts", ""), energy_start=_g(st.get("energy_start")),
                   energy_end=_g(st.get("energy_end")), error="")
        for stage, took in st.get("stage_seconds", {}).items():
            row[f"{stage}_seconds"] = f"{took:.6f}"
    else:
        row.update(status="failed", error=res.error)
    return row


def _g(v) -> str:
    return "" if v is None else repr(float(v))


def _atomic_write(path: Path, write) -> None:
    """``write(file)`` into memory, then the bytes to ``path`` whole or not at all (:mod:`framework.output`:
    a part file beside it, moved into place, the umask's permissions). The summary is the batch's own:
    replaced on each run (a journal from an earlier batch needs --resume or --overwrite first)."""
    from driftframe.framework.output import write_file

    buf = io.BytesIO()
    write(buf)
    write_file(path, buf.getvalue(), overwrite=True, what="batch summary")


def write_csv(outcome: Outcome, path: Path) -> Path:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for row in rows(outcome):
        w.writerow(row)
    _atomic_write(path, lambda f: f.write(buf.getvalue().encode()))
    return path


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return "0" if v == 0 else f"{v:.3g}"
    return str(v)


def markdown(outcome: Outcome, *, title: str, chart: str | None) -> str:
    done, failed = outcome.done, outcome.failures
    lines = [f"# {title}", "",
             f"{len(outcome.results)} runs {outcome.place}: {len(done)} ok, {len(failed)} failed; "
             f"{outcome.wall_seconds:.1f} s wall time.", ""]
    if outcome.signal is not None:
        from driftframe.batch import signal_name
        missing = len(outcome.results) - len(done) - len(failed)
        lines += [f"Stopped by {signal_name(outcome.signal)}: {missing} runs did not run (or were stopped "
                  "and left nothing); `driftframe batch --resume` runs them.", ""]
    elif outcome.halted is not None:
        missing = len(outcome.results) - len(done) - len(failed)
        lines += [f"Stopped: {outcome.halted}. {missing} runs did not run (or were stopped and left "
                  "nothing); free some space, then `driftframe batch --resume` runs them.", ""]
    groups: dict[str, list] = {}
    for res in outcome.results:
        if res is not None:
            groups.setdefault(group(res.spec), []).append(res)
    head = ["group", "runs", "failed", "energy drift: median", "max abs", "momentum drift: max",
            "contacts: median", "wall s: median"]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, rs in groups.items():
        ok = [r for r in rs if isinstance(r, Result)]

        def pick(key):
            return [r.stats[key] for r in ok if key in r.stats]
        e, p, c = pick("energy_drift"), pick("momentum_drift"), pick("contacts")
        lines.append("| " + " | ".join([
            name, str(len(rs)), str(len(rs) - len(ok)),
            _fmt(statistics.median(e)) if e else "-", _fmt(max(map(abs, e))) if e else "-",
            _fmt(max(p)) if p else "-", _fmt(statistics.median(c)) if c else "-",
            _fmt(statistics.median(r.wall_seconds for r in ok)) if ok else "-"]) + " |")
    lines.append("")
    if chart:
        lines += [f"![distribution of the collected stats]({chart})", ""]
    lines += ["## Runs", "", "| # | run | status | energy drift | momentum drift | contacts | hash | output |",
              "|---|---|---|---|---|---|---|---|"]
    for i, res in enumerate(outcome.results):
        if res is None:
            continue
        if isinstance(res, Result):
            st = res.stats
            lines.append(f"| {i} | {res.spec.label} | ok | {_fmt(st.get('energy_drift'))} | "
                         f"{_fmt(st.get('momentum_drift'))} | {_fmt(st.get('contacts'))} | "
                         f"`{res.state_hash[:12]}` | {os.path.basename(res.output) if res.output else '-'} |")
        else:
            lines.append(f"| {i} | {res.spec.label} | **failed** | - | - | - | - | - |")
    if failed:
        lines += ["", "## Failures", ""]
        for res in failed:
            lines += [f"### {res.spec.where or res.spec.label}", "", f"`{res.error}`", "", "```",
                      res.traceback.rstrip(), "```", ""]
    return "\n".join(lines) + "\n"


def _symlog_bins(values) -> list[float]:
    """Histogram edges for a symmetric log axis: two per decade, one linear bin around zero.

    Only the positive side when no value is negative (a size, such as the momentum drift).
    """
    top = max((abs(v) for v in values), default=1.0)
    hi = max(math.ceil(math.log10(max(top, LINEAR))) + 1, -15)
    pos = [10.0 ** (k / 2) for k in range(-32, 2 * hi + 1)]
    if min(values, default=0.0) >= 0:
        return [-LINEAR] + pos
    return [-p for p in reversed(pos)] + pos


def chart(outcome: Outcome, path: Path, *, title: str) -> Path:
    """The summary chart; ImportError when matplotlib is missing."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = outcome.done
    panels = [(k, label) for k, label in (
        ("energy_drift", "energy drift (E_end - E_start) / E_start"),
        ("momentum_drift", "momentum drift |P_end - P_start| / sum m|v|"),
        ("contacts", "contacts per run"))
        if any(k in r.stats for r in ok)]
    fig, axes = plt.subplots(1, max(1, len(panels)), figsize=(4.6 * max(1, len(panels)), 3.6), squeeze=False)
    groups: dict[str, list] = {}
    for r in ok:
        groups.setdefault(group(r.spec), []).append(r)
    for ax, (key, label) in zip(axes[0], panels):
        allv = [r.stats[key] for r in ok if key in r.stats]
        if key == "contacts":
            lo, hi = min(allv), max(allv)
            bins = range(int(lo), int(hi) + 2, max(1, (int(hi) - int(lo) + 1) // 30 or 1))
        else:
            bins = _symlog_bins(allv)
            ax.set_xscale("symlog", linthresh=LINEAR, linscale=0.5)
            if bins[0] > -2 * LINEAR:           # a size (never negative): start the axis at zero
                ax.set_xlim(0, bins[-1])
        for k, (name, rs) in enumerate(groups.items()):
            vals = [r.stats[key] for r in rs if key in r.stats]
            ax.hist(vals, bins=bins, histtype="stepfilled", alpha=0.45, color=f"C{k}", label=name,
                    edgecolor=f"C{k}")
        ax.set_xlabel(label, fontsize=8)
        ax.set_ylabel("runs")
        ax.tick_params(labelsize=7)
    if not panels:
        axes[0][0].text(0.5, 0.5, "no run finished", ha="center", va="center")
    axes[0][0].legend(fontsize=7, loc="upper left") if panels and groups else None
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()

    def save(f):
        fig.savefig(f, format="png", dpi=100)
    try:
        _atomic_write(path, save)
    finally:
        plt.close(fig)
    return path


def write(outcome: Outcome, out_dir, *, title: str) -> tuple[list[Path], str | None]:
    """Write the summary files; (paths written, a note when the chart could not be made).

    A chart that cannot be written (a full disk) leaves the CSV and the report without it, then raises
    its :class:`~framework.output.OutputError`: the text is what matters.
    """
    out_dir = Path(out_dir)
    written = [write_csv(outcome, out_dir / "summary.csv")]
    note = None
    chart_name = None
    failed = None
    try:
        written.append(chart(outcome, out_dir / "summary.png", title=title))
        chart_name = "summary.png"
    except ImportError:
        note = "no chart: matplotlib is not installed (pip install 'driftframe[batch]')"
    except OSError as e:
        failed = e
    md = markdown(outcome, title=title, chart=chart_name)
    path = out_dir / "summary.md"
    _atomic_write(path, lambda f: f.write(md.encode()))
    written.insert(1, path)
    if failed is not None:
        raise failed
    return written, note


# -- the journal: each run as it ends -------------------------------------------------------------
JOURNAL = "journal.jsonl"


def _jsonable(v):
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return v


class Journal:
    """Each finished run, appended the moment it ends: a JSON line in ``journal.jsonl`` (what
    ``--resume`` reads back) and a row in ``summary.csv``. A stop, a crash or SIGKILL loses at most the
    line being written; :func:`read_journal` skips a torn last line. A write that fails (a full disk) is
    cut back to the last whole line and raised as an :class:`~framework.output.OutputError` naming the
    file. The summary files are written again, whole and in run order, at the end (:func:`write`)."""

    def __init__(self, out_dir, *, append: bool):
        out_dir = Path(out_dir)
        self.path = out_dir / JOURNAL
        self.csv_path = out_dir / "summary.csv"
        self._json = self._csv = -1
        try:
            self._json = _open_log(self.path, append)
            self._csv = _open_log(self.csv_path, False)
            buf = io.StringIO()
            csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n").writeheader()
            _append(self._csv, self.csv_path, buf.getvalue())
        except BaseException:
            self.close()
            raise

    def add(self, index: int, res, *, again: bool = True) -> None:
        """Append ``res``, the run at ``index``; ``again=False``: a resumed run, in the journal already
        (its CSV row only)."""
        if again:
            _append(self._json, self.path, json.dumps(_journal_row(index, res), separators=(",", ":")) + "\n")
        buf = io.StringIO()
        csv.DictWriter(buf, fieldnames=COLUMNS, extrasaction="ignore", lineterminator="\n").writerow(_row(index, res))
        _append(self._csv, self.csv_path, buf.getvalue())

    def close(self) -> None:
        for fd in (self._json, self._csv):
            if fd >= 0:
                os.close(fd)
        self._json = self._csv = -1


def _open_log(path: Path, append: bool) -> int:
    """A file appended to as the batch runs (``0666 & ~umask``, as ``open()`` makes it); its descriptor."""
    from driftframe.framework.output import OutputError

    flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | (0 if append else os.O_TRUNC) | getattr(os, "O_CLOEXEC", 0)
    try:
        return os.open(path, flags, 0o666)
    except OSError as e:
        what = "batch journal" if path.name == JOURNAL else "batch summary"
        raise OutputError(e.errno, f"cannot write the {what} {str(path)!r}: {e.strerror or e}") from None


def _append(fd: int, path: Path, text: str) -> None:
    """``text`` appended whole, or the file cut back to where it was and an OutputError naming it: a full
    disk never leaves a torn line for the next one to be glued to (--resume would lose both)."""
    from driftframe.framework.output import OutputError, no_space

    data = memoryview(text.encode("utf-8"))
    start = os.lseek(fd, 0, os.SEEK_END)
    try:
        while data:
            data = data[os.write(fd, data):]
    except OSError as e:
        with contextlib.suppress(OSError):
            os.ftruncate(fd, start)
        why = "no space left on the device" if no_space(e) else (e.strerror or str(e))
        what = "batch journal" if path.name == JOURNAL else "batch summary"
        raise OutputError(e.errno, f"cannot write the {what} {str(path)!r}: {why}") from None


def _journal_row(index: int, res) -> dict:
    spec = res.spec
    row = {"index": index, "hash": spec.content_hash(), "label": spec.label, "ok": res.ok,
           "wall_seconds": res.wall_seconds}
    if isinstance(res, Result):
        row.update(state_hash=res.state_hash, steps=res.steps, frames=res.frames, output=res.output,
                   stats=_jsonable(res.stats))
    else:
        row.update(error=res.error, traceback=res.traceback)
    return row


def read_journal(path) -> dict:
    """The journal's finished runs, ``{spec hash: row}`` (the last row of a hash wins); {} if none."""
    rows: dict = {}
    try:
        f = open(path, encoding="utf-8")
    except FileNotFoundError:
        return rows
    with f:
        for line in f:
            try:
                row = json.loads(line)
                rows[row["hash"]] = row
            except (ValueError, KeyError, TypeError):
                continue                        # a line torn by a kill: that run is simply run again
    return rows


def resumed(specs, rows: dict) -> dict:
    """``{index: Result}`` of the runs a resumed batch skips: a journal row with the spec's hash that
    finished ok, and, for a recording, its output still there."""
    out = {}
    for i, spec in enumerate(specs):
        row = rows.get(spec.content_hash())
        if row is None or not row.get("ok") or (spec.output is not None and not os.path.exists(spec.output)):
            continue
        out[i] = Result(spec, row["state_hash"], row["steps"], row["stats"], row["output"], row["frames"],
                        row["wall_seconds"])
    return out
