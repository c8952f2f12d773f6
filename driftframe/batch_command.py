"""``driftframe batch``: the command (its options are in :mod:`driftframe.cli`; the grid file in
:mod:`driftframe.batch_file`; the runs in :mod:`driftframe.batch`; the summary and the journal in
:mod:`driftframe.batch_report`).
"""
from __future__ import annotations

import os
import sys

from driftframe.cli import UsageError, _compile


def cmd_batch(args) -> int:
    from pathlib import Path

    from driftframe import batch, batch_file, batch_report

    spec_path = Path(args.spec)
    # scenes are named by import path ('mymod:func'), found in the current folder too, as `python -m` would;
    # but after the installed packages: a tqdm.py or av.py lying here must not replace the real one
    here = os.getcwd()
    sys.path[:] = [p for p in sys.path if p not in ("", here)] + [here]
    scheduler = args.scheduler
    if args.jobs is not None and (scheduler is not None or args.scheduler_file is not None):
        raise UsageError("-j and --scheduler exclude each other: the cluster's workers decide")
    if scheduler is not None and args.scheduler_file is not None:
        raise UsageError("give --scheduler or --scheduler-file, not both")
    if scheduler is None and args.scheduler_file is None and args.jobs is None:
        scheduler = os.environ.get("DASK_SCHEDULER_ADDRESS") or None     # as dask's own Client() reads it
    out_dir = Path(args.output) if args.output else Path("out") / spec_path.stem
    journal_path = out_dir / batch_report.JOURNAL
    client = None
    try:
        # every check before any run: the file, each entry, the output folder, the scheduler
        specs = batch_file.load(spec_path, out_dir.resolve(), check=False, overwrite=args.overwrite)
        if journal_path.exists() and not (args.resume or args.overwrite):
            raise batch.SpecError(f"{journal_path} exists: a batch ran into {str(out_dir)!r} before; pass "
                                  "--resume to continue it or --overwrite to start again")
        specs = batch.check_all(specs, outputs=False)      # each entry; the outputs' names, not their folders
        skip = batch_report.resumed(specs, batch_report.read_journal(journal_path)) if args.resume else {}
        if scheduler is not None or args.scheduler_file is not None:
            client = batch.connect(scheduler, scheduler_file=args.scheduler_file)
            batch.check_versions(client)
            link = batch.dashboard(client)
            if link:
                print(f"driftframe: dashboard: {link}", file=sys.stderr)
        specs = batch_file.prepare(specs, out_dir, overwrite=args.overwrite, done=skip.keys(), checked=True)
    except batch.SpecError as e:
        if client is not None:
            client.close()
        raise UsageError(str(e)) from None
    except BaseException:
        if client is not None:
            client.close()
        raise
    from tqdm import tqdm

    todo = [i for i in range(len(specs)) if i not in skip]
    from driftframe import warmup
    from driftframe.framework import kernels
    if client is None and batch.plan_jobs(specs, args.jobs)[0] > 1 and not kernels.is_warm():
        # once, before the workers start: each then loads the kernels instead of all compiling them at
        # the same time into one cache (numba's cache is not safe against concurrent writers)
        _compile(warmup.warm, args.quiet)
    journal = None
    try:
        journal = batch_report.Journal(out_dir, append=args.resume)
        for i in sorted(skip):
            journal.add(i, skip[i], again=False)
    except OSError as e:                # a full disk before any run: nothing ran, nothing was lost
        if journal is not None:
            journal.close()
        if client is not None:
            client.close()
        print(f"driftframe: error: {e}; no run started", file=sys.stderr)
        return 1
    if skip:
        tqdm.write(f"driftframe: resuming: {len(skip)} of {len(specs)} runs are done already (journal.jsonl)",
                   file=sys.stderr)
    unjournalled: list = []             # finished while the journal could not be written (a full disk)

    def report(k, res):
        if isinstance(res, batch.Failure):
            tqdm.write(f"driftframe: run failed: {res.spec.where or res.spec.label}\n{res.traceback.rstrip()}",
                       file=sys.stderr)
        if unjournalled:
            unjournalled.append((todo[k], res))
            return
        try:
            journal.add(todo[k], res)
        except OSError:
            unjournalled.append((todo[k], res))
            raise                       # run_all halts the batch on a full disk

    aborted = None
    try:
        part = batch.run_all([specs[i] for i in todo], jobs=args.jobs, scheduler=client, progress=not args.quiet,
                             on_done=report, retries=args.retries)
    except batch.Aborted as e:
        print(f"driftframe: aborted ({batch.signal_name(e.signum)}): the runs that finished are in "
              f"{journal_path} (--resume continues); no summary written", file=sys.stderr)
        aborted = e.signum
    finally:
        try:
            while unjournalled:             # the stopped runs' part files are gone now: there may be room
                journal.add(*unjournalled[0])
                unjournalled.pop(0)
        except OSError:
            pass
        journal.close()
        if client is not None:
            client.close()
    if aborted is not None:
        # at once: a run cut in a compile leaves numba's and LLVM's state to an interpreter teardown of
        # 0.5-0.8 s; the journal is closed, the workers ended, the part files removed: nothing is left to do
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(128 + aborted)
    results = [skip.get(i) for i in range(len(specs))]
    for k, i in enumerate(todo):
        results[i] = part.results[k]
    outcome = batch.Outcome(results, part.signal, part.wall_seconds, part.jobs, part.where, part.halted)
    finished = len(outcome.done) + len(outcome.failures)
    if outcome.halted is not None:
        n = len(unjournalled)
        lost = f"; {n} finished run{'s are' if n > 1 else ' is'} missing from {journal_path}: --resume " \
            "--overwrite runs them again" if n else ""
        print(f"driftframe: error: {outcome.halted}; the batch stopped: {finished} of {len(specs)} runs "
              f"finished, their outputs whole (free some space, then --resume runs the rest{lost})",
              file=sys.stderr)
    try:
        written, note = batch_report.write(outcome, out_dir, title=f"{spec_path.name}: {len(specs)} runs")
    except OSError as e:
        tail = "" if outcome.halted else f"; {finished} of {len(specs)} runs finished (their outputs are whole; " \
            "--resume runs the rest)"
        print(f"driftframe: error: {e}{tail}", file=sys.stderr)
        return outcome.exit_status or 1
    if note:
        print(f"driftframe: {note}", file=sys.stderr)
    if outcome.halted is not None:
        print(f"driftframe: wrote {', '.join(str(p) for p in written)}", file=sys.stderr)
    elif outcome.interrupted:
        print(f"driftframe: interrupted ({batch.signal_name(outcome.signal)}): {finished} of {len(specs)} runs "
              f"finished (their outputs are whole; --resume runs the rest); wrote "
              f"{', '.join(str(p) for p in written)}", file=sys.stderr)
    else:
        print(f"{len(outcome.done)} of {len(specs)} runs ok, {len(outcome.failures)} failed, {outcome.place} "
              f"in {outcome.wall_seconds:.1f} s; wrote {', '.join(str(p) for p in written)}")
    return outcome.exit_status
