"""Running a study: the run directory and its result tables, the journal, resuming, and the
optimiser of the study's kind (:mod:`parasynth.study.optimizers`: one
:class:`~parasynth.study.optimizers.BaseOptimizer` per kind, run against a
:class:`~parasynth.study.problem.Problem`), then the polish of ``optimizer.polish``
(:mod:`parasynth.study.polish`: ``polish.json``).

Run directory (default ``runs/<study name>/``):

* ``study.yaml``: the study as run (a copy, so a run can be resumed and reported alone);
* ``journal.jsonl``: one JSON line per evaluated design, appended and flushed as soon as the
  design is evaluated -- the source of truth for sweeps and NLopt, a mirror of the storage
  for Optuna (see :mod:`parasynth.study.journal`: torn last lines, ``PARASYNTH_FSYNC``);
* ``run.lock``: held by the process running in the directory (one writer at a time; a
  crashed run does not leave it held);
* ``results.csv`` and ``results.parquet``: every evaluated design (one column per design
  variable, objective and design constraint named as in the YAML, ``<constraint>_margin``,
  ``feasible``, ``status``, ``error``, ``seed``, ``samples``, ``time_s``, ``trial``,
  ``source``); all values SI, and in ``results.csv`` every column with a unit names it as a
  suffix (``link_length_m``, ``volume_m3``; :mod:`parasynth.study.columns`); rewritten at most
  every few seconds during a run and at its end;
* ``final.csv``: the best designs re-evaluated with more samples and several seeds (mean and
  standard error of each objective);
* ``optuna.journal``: the embedded Optuna storage of an Optuna study, unless ``--storage`` /
  ``optimizer.storage`` names another one (see :mod:`parasynth.study.storage`).

Interrupts (Ctrl-C, SIGTERM): the design being evaluated is finished and recorded (a second
Ctrl-C drops it), the tables are written and the result says ``interrupted``.

Resuming (``resume=True``) reads the journal (a torn last line is cut away, with a message):

* a sweep skips the designs already evaluated (trial = index of the design in the grid);
* an NLopt run replays its deterministic path, answering already-evaluated points from the
  journal (trial = order of first evaluation);
* an Optuna run on the embedded storage rebuilds it without the trials the interruption left
  unfinished and continues; the sampler is seeded per trial from (seed, trial number), so the
  designs, the results table and the Pareto front equal those of the uninterrupted run. On
  SQLite the unfinished trials are marked failed instead (the trial numbers then differ from
  an uninterrupted run: complete, but not the same sequence); on a database server they are
  left to the heartbeat (other workers may be running).

Completed evaluations are neither lost nor repeated.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..measures.display import reference_name
from ..engine import COMPILING, announce_compile, warm_up
from .budget import budget_for_run, same_study
from .evaluate import Record
from .final import reevaluate_best
from .journal import Journal, RunLock, read_journal
from .optimizers import optimizer_class
from .polish import polish_budget, polish_run
from .problem import Problem, RunContext
from .signals import Interrupt
from .spec import ResolvedStudy, StudyError
from .tables import results_table, write_tables

__all__ = ["run_study", "RunResult", "results_table", "read_journal"]


@dataclass
class RunResult:
    out_dir: Path
    table: pd.DataFrame
    final: pd.DataFrame | None
    n_new: int
    n_total: int
    elapsed_s: float
    interrupted: bool = False
    new_records: list | None = None
    storage: str | None = None  # the storage URL when given explicitly (for the resume hint)

    def saved_counts(self) -> tuple[int, bool]:
        """(designs of the search saved in the run's table, whether the reference design is
        among them): the one count the summary and the interrupt message give."""
        t = self.table
        if not len(t):
            return 0, False
        return int((t["source"] == "run").sum()), bool((t["source"] == "reference").any())

    def summary(self, study: ResolvedStudy, details=()) -> str:
        """The counts line, then ``details`` (the report layer's recommendations:
        :func:`parasynth.report.summary.run_summary`), then where the results are."""
        t = self.table
        run = t[t["source"] == "run"] if len(t) else t
        n_new_run = sum(1 for r in self.new_records if r.source == "run") if self.new_records else self.n_new
        n_run, has_ref = self.saved_counts()
        ref = f" and {reference_name(study)}" if has_ref else ""
        lines = [f"study {study.name}: {n_run} designs evaluated{ref} ({n_new_run} in this run, "
                 f"{self.elapsed_s:.1f} s); {int(run['feasible'].sum()) if len(run) else 0} feasible, "
                 f"{int((run['status'] == 'failed').sum()) if len(run) else 0} failed"]
        lines += list(details)
        lines.append(f"results: {self.out_dir / 'results.csv'}")
        return "\n".join(lines)


# -- run directory -------------------------------------------------------------------------------------
def prepare_dir(study: ResolvedStudy, out_dir: Path, resume: bool, lock: RunLock | None = None) -> list[Record]:
    """Create or check the run directory; with ``lock`` it is acquired before anything is
    read. Returns the journal's records on resume (a torn last line cut away)."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise StudyError(f"run directory {str(out_dir)!r} is a file; choose a directory with --out")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise StudyError(f"cannot create the run directory {str(out_dir)!r}: {e.strerror or e}") from None
    if lock is not None:
        lock.acquire()
    existing = list(out_dir.glob("journal*.jsonl")) + list(out_dir.glob("optuna.journal"))
    if existing and not resume:
        raise StudyError(
            f"run directory {str(out_dir)!r} already holds results; pass --resume to continue that run "
            f"or --out to start a new one"
        )
    text = study.to_yaml()
    sy = out_dir / "study.yaml"
    if resume and sy.exists() and existing:
        if not same_study(sy.read_text(), text):
            raise StudyError(
                f"cannot resume: the study differs from the one run in {str(out_dir)!r} (compare with its study.yaml)"
            )
    tmp = out_dir / "study.yaml.tmp"
    tmp.write_text(text)
    os.replace(tmp, sy)
    return read_journal(out_dir, repair=True) if resume else []


TABLES_EVERY_S = 5.0


# -- running a study -------------------------------------------------------------------------------------
def run_study(study: ResolvedStudy, out_dir=None, resume: bool = False, n_trials: int | None = None,
              progress: bool = True, storage: str | None = None, workers: int | None = None,
              study_file=None) -> RunResult:
    """Run a resolved study; see the module docstring for the run directory.

    ``storage``: an Optuna storage URL (overrides ``optimizer.storage``); ``workers``: local
    worker processes for an Optuna study (default ``optimizer.workers`` / ``n_jobs``, 1).
    Sweeps and NLopt run in one process (a note is printed when more workers are asked for)."""
    if n_trials is not None and (not isinstance(n_trials, int) or isinstance(n_trials, bool) or n_trials < 1):
        raise StudyError(f"n_trials: a positive whole number of designs is needed, got {n_trials!r}")
    kind = study.optimizer.kind
    plugin = optimizer_class(kind)
    n_workers = _workers_of(study, workers)
    if not plugin.uses_storage:
        if storage:
            raise StudyError(f"--storage applies to Optuna studies; a {kind} run keeps its designs in the run "
                             f"directory's journal")
        if n_workers > 1:
            print(f"note: a {plugin.title} runs in one process; --workers applies to Optuna studies", file=sys.stderr)
            n_workers = 1
    out_dir = Path(out_dir or study.spec.output or Path("runs") / study.name)
    if resume and not out_dir.exists() and not (plugin.uses_storage and (storage or study.optimizer.storage)):
        raise StudyError(f"--resume: the run directory {str(out_dir)!r} does not exist, so there is nothing to "
                         f"resume; give the directory of the run (--out) or drop --resume to start a new run")
    study = budget_for_run(study, out_dir, resume, n_trials, note=lambda m: print(m, file=sys.stderr))
    if n_trials is not None and polish_budget(study) >= n_trials:
        raise StudyError(f"--n-trials: {n_trials} designs leave none to the global search after the "
                         f"{polish_budget(study)} of optimizer.polish.budget; give more")
    lock = RunLock(out_dir)
    try:
        previous = prepare_dir(study, out_dir, resume, lock=lock)
        return _run_locked(study, out_dir, previous, resume, n_trials, progress, storage, n_workers)
    finally:
        lock.release()


def _workers_of(study, workers):
    if workers is not None:
        if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
            raise StudyError(f"--workers: a positive whole number of processes is needed, got {workers!r}")
        return workers
    opt = study.optimizer
    return max(int(getattr(opt, "workers", None) or 1), int(getattr(opt, "n_jobs", 1) or 1))


def _run_locked(study, out_dir, previous, resume, n_trials, progress, storage, n_workers) -> RunResult:
    problem = Problem(study)
    optimizer = optimizer_class(study.optimizer.kind)()
    t0 = time.perf_counter()
    records = list(previous)
    new = []
    last_tables = [time.monotonic()]

    with Interrupt(quiet=not progress) as guard:
        journal = None
        try:
            # Set up (and check) the optimiser's storage before any work, and reconcile the
            # journal with it (the storage is the record of an Optuna study).
            records[:] = optimizer.open(problem, out_dir, resume, n_trials, storage, records)

            n_warm = max(1, int(study.evaluation["n"]) // 2)  # not the run's sample count: no cache hit later
            if progress and study.evaluation.get("engine") != "numpy" and announce_compile():
                print_err(COMPILING)  # at once: the warm-up first runs its design on NumPy and imports numba
            warm_up(lambda: problem.evaluate(_warm_up_design(problem), n=n_warm, source="warm-up"),
                    progress=None if not progress else print_err, stop=lambda: guard.requested)
            journal = Journal(out_dir / "journal.jsonl")

            def record(rec: Record):
                journal.append(rec)
                records.append(rec)
                new.append(rec)
                now = time.monotonic()
                if now - last_tables[0] > TABLES_EVERY_S:
                    write_tables(study, out_dir, records)
                    last_tables[0] = now

            if guard.requested:
                pass
            elif study.reference is not None and not any(r.source == "reference" for r in records):
                with guard.evaluating():
                    rec = problem.evaluate(dict(study.reference), trial=-1, source="reference")
                record(rec)
                optimizer.stored_reference(rec)
            ctx = RunContext(records, record, progress=progress, guard=guard, n_trials=n_trials, out_dir=out_dir,
                             workers=n_workers, journal=journal)
            if not guard.requested:
                optimizer.run(problem, ctx)
            if not guard.requested:
                polish_run(problem, optimizer, ctx)
        except KeyboardInterrupt:
            guard.requested = True
        finally:
            if journal is not None:
                journal.close()
            if records:
                table = write_tables(study, out_dir, records)
            else:
                table = results_table(study, records)
        interrupted = guard.requested
    final = None
    runs_done = len(table) and (table["source"] == "run").any()
    if not interrupted and runs_done:  # re-evaluation and verification of the recommendation
        with Interrupt(quiet=not progress) as guard2:
            try:
                final = reevaluate_best(study, problem.evaluator, table, out_dir)
            except KeyboardInterrupt:
                interrupted = True
            interrupted = interrupted or guard2.requested
        if final is not None:
            optimizer.stored_final(out_dir)
    # New designs of this run, those of other workers on the same study included.
    before = {(r.source, r.trial) for r in previous}
    new = [r for r in records if (r.source, r.trial) not in before]
    return RunResult(out_dir, table, final, len(new), len(records), time.perf_counter() - t0, interrupted, new,
                     storage=optimizer.storage_url)


def _warm_up_design(problem: Problem) -> dict:
    """A design whose evaluation compiles what the run needs: the reference, else the first
    listed design, else the centre of the variable box (its record is not kept)."""
    if problem.reference is not None:
        return dict(problem.reference)
    if problem.study.optimizer.designs:
        return problem.designs()[0]
    return problem.space.centre()


def print_err(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)
