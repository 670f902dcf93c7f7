"""The result tables of a run directory: ``results.csv`` and ``results.parquet``, rebuilt from
the records (the journal or an Optuna storage)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from .columns import to_csv_columns
from .evaluate import Record
from .spec import ResolvedStudy
from ..common import columns as derived

__all__ = ["results_table", "write_tables"]


def results_table(study: ResolvedStudy, records: list[Record]) -> pd.DataFrame:
    """One row per record: ``trial``, ``source``, the design variables, the objectives, each
    design constraint and its ``<label>_margin``, for each robust one ``<label>_nominal`` and
    ``<label>_robust_se``, ``feasible``, ``status``, ``error``, ``seed``,
    ``samples``, ``time_s``; the reference first, then the run designs by trial."""
    rows = []
    # a robust objective or constraint: its nominal value and the standard error of the robust one
    robust = [x.label for x in (*study.objectives, *study.constraints) if getattr(x, "robust", None) is not None]
    for r in records:
        row = {"trial": r.trial, "source": r.source}
        for v in study.variables:
            row[v.name] = r.values.get(v.name)
        for o in study.objectives:
            row[o.label] = r.objectives.get(o.label, np.nan)
        for c in study.constraints:
            row[c.label] = r.constraint_values.get(c.label, np.nan)
            row[derived.margin(c.label)] = r.margins.get(c.label, np.nan)
        for label in robust:
            info = r.robust.get(label) or {}
            row[derived.nominal(label)] = info.get("nominal", np.nan)
            se = info.get("stderr")
            row[derived.robust_se(label)] = np.nan if se is None else se
        row.update(feasible=r.feasible, status=r.status, error=r.error, seed=r.seed, samples=r.samples,
                   time_s=r.time_s)
        rows.append(row)
    cols = (["trial", "source"] + [v.name for v in study.variables] + [o.label for o in study.objectives]
            + sum(([c.label, derived.margin(c.label)] for c in study.constraints), [])
            + sum(([derived.nominal(lb), derived.robust_se(lb)] for lb in robust), [])
            + ["feasible", "status", "error", "seed", "samples", "time_s"])
    df = pd.DataFrame(rows, columns=cols)
    if len(df):
        df = df.sort_values(["source", "trial"], ascending=[False, True], kind="stable").reset_index(drop=True)
    return df


def write_tables(study: ResolvedStudy, out_dir: Path, records: list[Record]) -> pd.DataFrame:
    """Write ``results.csv`` (atomically) and ``results.parquet`` (when pyarrow is there)."""
    out_dir = Path(out_dir)
    df = results_table(study, records)
    tmp = out_dir / "results.csv.tmp"
    to_csv_columns(study, df).to_csv(tmp, index=False)  # unit suffixes in the names (SI values)
    os.replace(tmp, out_dir / "results.csv")
    try:
        df2 = df.copy()
        for v in study.variables:  # mixed-type object columns do not go to Parquet
            if df2[v.name].dtype == object:
                df2[v.name] = df2[v.name].astype(str)
        df2.to_parquet(out_dir / "results.parquet", index=False)
    except ImportError:
        pass
    return df
