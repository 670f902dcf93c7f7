"""A run directory, read: the one interface through which the report (and any other reader)
sees a run.

:func:`read_run` loads ``runs/<name>/`` -- ``study.yaml`` (the study as run), the journal (the
records; a torn last line skipped) rebuilt into the results table, ``final.csv`` when the run
wrote one -- into a :class:`Run`. The selection rules a reader needs to agree with the run
are re-exported here from where they are defined, so that a reader imports this module only:
:func:`design_key`, :func:`design_params`, :func:`pareto_front`, :func:`knee_of`,
:func:`screening_dominators`, :func:`merge_duplicates`, :func:`best_designs`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .columns import csv_column, from_csv_columns, to_csv_columns

from .defaults import planned_designs
from .design import design_key, design_mechanism, design_params, measure_settings
from .verify import SINGULARITY_FLOOR, estimate_of
from .final import (best_designs, design_keys, knee_of, merge_duplicates, pareto_front, recommendation_order,
                    screening_dominators)
from .journal import read_journal
from .polish import read_polish
from .schedule import structure_schedule
from .spec import ResolvedStudy, StudyError, load_study
from .structure_space import STRUCTURE
from .tables import results_table
from .view import (MAX_FRONT_DESIGNS, N_CLOUD, N_POSES, design_values, design_view, front_choice, read_view,
                   rounded, sorted_front, trajectory_of, view_key)
from ..common import columns as derived

__all__ = ["Run", "RunDirError", "read_run", "read_final", "to_csv_columns", "measure_settings", "design_key", "design_keys", "design_params", "design_mechanism", "pareto_front", "knee_of",
           "screening_dominators", "merge_duplicates", "best_designs", "recommendation_order", "estimate_of",
           "SINGULARITY_FLOOR", "read_view", "design_view", "design_values", "view_key", "front_choice", "sorted_front",
           "trajectory_of", "rounded", "MAX_FRONT_DESIGNS", "N_POSES", "N_CLOUD"]


class RunDirError(StudyError):
    """A directory that is not a readable run (missing, no study.yaml, no designs yet)."""


@dataclass
class Run:
    """A run directory as read by :func:`read_run`: the study as run, ``table`` (results.csv's
    rows: the reference first, then the run designs by trial), ``final`` (final.csv, or None)
    and ``budget`` (the designs the run plans: :func:`~parasynth.study.defaults.planned_designs`;
    None for NLopt, which may stop early; for a study over structures the schedule's total given
    the stored designs, and ``plan``, the schedule's :class:`~parasynth.study.schedule.Plan`)."""

    study: ResolvedStudy
    table: pd.DataFrame
    final: pd.DataFrame | None
    run_dir: Path
    budget: int | None
    plan: object = None  # a study over structures: its schedule's Plan (study.schedule)
    polish: dict | None = None  # polish.json of a run with optimizer.polish (study.polish)

    @property
    def n_run(self) -> int:
        """Designs of the run (the reference not counted)."""
        return int((self.table["source"] == "run").sum()) if len(self.table) else 0

    @property
    def partial(self) -> bool:
        """True when the run holds fewer designs than its budget (an interrupted run); a run whose
        polish finished is complete (a local polish may converge before its budget is spent)."""
        if self.polish is not None:
            return self.polish.get("status") != "done"
        return self.budget is not None and self.n_run < self.budget

    @property
    def partial_reason(self) -> str:
        if not self.partial:
            return ""
        if self.polish is not None:
            return f"the polish did not finish ({self.n_run} designs evaluated; interrupted run?)"
        return f"{self.n_run} of {self.budget} planned designs evaluated (interrupted run?)"

    @property
    def expected(self) -> int | None:
        """Same as :attr:`budget`."""
        return self.budget


def read_run(run_dir) -> Run:
    """Load a run directory; :class:`RunDirError` when there is no run to read."""
    run_dir = Path(run_dir)
    if not run_dir.exists():
        raise RunDirError(f"run directory {str(run_dir)!r} does not exist; run the study first (parasynth run STUDY.yaml)")
    sy = run_dir / "study.yaml"
    if not sy.exists():
        raise RunDirError(f"{str(run_dir)!r} is not a run directory (no study.yaml); run the study first")
    try:
        study = load_study(sy)
    except StudyError as e:
        raise RunDirError(f"{sy}: {e}") from None
    records = read_journal(run_dir)
    if not records:
        raise RunDirError(f"{str(run_dir)!r} holds no evaluated designs yet; run (or resume) the study")
    _check_structures(study, records, run_dir)
    table = results_table(study, records)
    final = None
    if (run_dir / "final.csv").exists():
        final = read_final(study, run_dir / "final.csv")
    schedule = structure_schedule(study)
    if schedule is not None:  # the designs its schedule plans, given the stored ones
        return Run(study, table, final, run_dir, schedule.plan(records).total, schedule.plan(records))
    return Run(study, table, final, run_dir, planned_designs(study), polish=read_polish(run_dir))


def _check_structures(study, records, run_dir: Path) -> None:
    """A study over structures: every journal record names one of the study's structures.
    :class:`RunDirError` (a damaged run) for a record with another structure or none: the
    schedule would not count it, the tables would show a structure the study does not have,
    and exporting it would build another mechanism."""
    if getattr(study, "structures", None) is None:
        return
    choices = tuple(study.space.by_name[STRUCTURE].choices)
    for r in records:
        s = r.values.get(STRUCTURE)
        if s not in choices:
            what = f"names the structure {s!r}" if STRUCTURE in r.values else "names no structure"
            raise RunDirError(f"{run_dir / 'journal.jsonl'}: the {r.source} design of trial {r.trial} {what}, not one "
                              f"of the study's structures ({', '.join(choices)}): the journal is damaged or belongs to "
                              f"another study; remove or repair that line, or start a new run (--out)")


def read_final(study, path) -> pd.DataFrame:
    """``final.csv`` of a run as written by the final re-evaluation; raises
:class:`RunDirError` naming the file and the line for a file that is not
    such a table (not CSV, missing columns, text where numbers belong, unknown sources)."""
    path = Path(path)
    try:
        df = pd.read_csv(path)
        df = from_csv_columns(study, df)
    except pd.errors.EmptyDataError:
        raise RunDirError(f"{path}: the file is empty; delete it and run the study again with --resume to redo "
                          f"the final re-evaluation") from None
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise RunDirError(f"{path}: not a table of re-evaluated designs ({first}); delete it and run the study again "
                          f"with --resume to redo the final re-evaluation") from None
    labels = [o.label for o in study.objectives]
    need = ["source"] + labels + [derived.stderr(lab) for lab in labels]
    missing = [c for c in need if c not in df.columns]
    if missing:
        missing = [csv_column(study, c) for c in missing]
        raise RunDirError(f"{path}: line 1 (the header) lacks the column(s) {', '.join(missing)}; this is not the "
                          f"final.csv of this study -- delete it and run the study again with --resume")
    bad = ~df["source"].isin(["best", "reference"])
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise RunDirError(f"{path}: line {i + 2}: source is {df['source'].iloc[i]!r}, not 'best' or 'reference'")
    cons = [c.label for c in study.constraints]
    numeric = (labels + [derived.stderr(lab) for lab in labels] + [c for c in cons + [derived.stderr(x) for x in cons]
                                                              if c in df]
               + [c for c in ("trial", "samples", "repeats", "home_margin") if c in df])
    for c in numeric:
        vals = pd.to_numeric(df[c], errors="coerce")
        wrong = vals.isna() & df[c].notna()
        if c in labels or c in ("trial",):
            wrong |= df[c].isna()
        if wrong.any():
            i = int(np.flatnonzero(wrong.to_numpy())[0])
            raise RunDirError(f"{path}: line {i + 2}: column {csv_column(study, c)} holds {df[c].iloc[i]!r}, "
                              f"not a number")
        df[c] = vals
    for c in ("verified", "recommended"):
        if c in df:
            df[c] = df[c].map(lambda x: str(x).strip().lower() in ("true", "1", "yes"))
    if "verification" in df:
        df["verification"] = df["verification"].fillna("").astype(str)
    return df
