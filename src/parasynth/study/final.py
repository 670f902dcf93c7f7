"""Final stage of a study: the best designs and their re-evaluation.

* :func:`best_designs` -- the feasible designs a run recommends;
* :func:`reevaluate_best` -- those designs (and the reference) evaluated again with
  ``final_samples`` samples and ``final_repeats`` seeds, written to ``final.csv``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .evaluate import Evaluator
from .spec import ResolvedStudy

__all__ = ["best_designs", "reevaluate_best"]


def best_designs(study: ResolvedStudy, df: pd.DataFrame, k: int = 5) -> pd.DataFrame:
    """Feasible designs, best first: by the objective for one objective, the non-dominated
    set (spread by crowding order) for several."""
    ok = df[(df["feasible"]) & (df["status"] == "ok")] if len(df) else df
    if not len(ok):
        return ok
    objs = study.objectives
    if len(objs) == 1:
        o = objs[0]
        return ok.sort_values(o.label, ascending=(o.goal == "minimize")).head(k)
    F = np.column_stack([ok[o.label].to_numpy(float) * (1 if o.goal == "minimize" else -1) for o in objs])
    nd = _non_dominated(F)
    front = ok.iloc[nd]
    return front.head(k) if k else front


def _non_dominated(F: np.ndarray) -> np.ndarray:
    """Indices of the non-dominated rows of F (minimisation)."""
    n = len(F)
    keep = np.ones(n, bool)
    for i in range(n):
        if not keep[i]:
            continue
        dominated = np.all(F <= F[i], axis=1) & np.any(F < F[i], axis=1)
        if dominated.any():
            keep[i] = False
    return np.flatnonzero(keep)


def reevaluate_best(study: ResolvedStudy, evaluator: Evaluator, table: pd.DataFrame, out_dir: Path) -> pd.DataFrame:
    """Re-evaluate the best feasible designs (and the reference) with ``final_samples``
    samples and ``final_repeats`` seeds: mean and standard error of each objective."""
    ev = study.evaluation
    runs = table[table["source"] == "run"]
    if study.optimizer.kind == "sweep":  # a sweep is read as a curve: every completed design
        best = runs[runs["status"] == "ok"].head(max(ev["final_top"], 1) * 1000)
    else:
        best = best_designs(study, runs, k=ev["final_top"])
    ref = table[table["source"] == "reference"]
    rows = []
    for src, df in (("best", best), ("reference", ref)):
        for _, row in df.iterrows():
            values = {v.name: row[v.name] for v in study.variables} if src == "best" else dict(study.reference)
            recs = [evaluator.evaluate(values, n=ev["final_samples"], seed=ev["seed"] + 1000 + j)
                    for j in range(ev["final_repeats"])]
            out = {"source": src, "trial": row["trial"]}
            out.update({v.name: values.get(v.name) for v in study.variables})
            for o in study.objectives:
                vals = np.array([r.objectives.get(o.label, np.nan) for r in recs], float)
                out[o.label] = float(np.nanmean(vals))
                out[f"{o.label}_stderr"] = float(np.nanstd(vals, ddof=1) / np.sqrt(len(vals))) if len(vals) > 1 else np.nan
            out["feasible"] = all(r.feasible for r in recs)
            out["samples"] = ev["final_samples"]
            out["repeats"] = ev["final_repeats"]
            rows.append(out)
    df = pd.DataFrame(rows)
    df.to_csv(out_dir / "final.csv", index=False)
    return df
