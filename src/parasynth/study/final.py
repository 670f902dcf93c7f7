"""Final stage of a study: the designs a run recommends and their re-evaluation.

* :func:`merge_duplicates` -- identical designs (same design-variable values) evaluated more
  than once (Optuna may propose a design twice) become one row with their ``count``;
* :func:`pareto_front` -- the non-dominated feasible designs, duplicates merged; the report
  and the re-evaluation use this one definition;
* :func:`knee_of` -- the recommended design: the knee of that front
  (:func:`parasynth.report.pareto.knee_index`);
* :func:`best_designs` -- the feasible designs a run recommends: for one objective the best
  ``k``; for several, ``k`` designs spread along the front by crowding distance
  (:func:`spread_by_crowding`);
* :func:`reevaluate_best` -- those designs, the knee (always) and the reference evaluated
  again with ``final_samples`` samples and ``final_repeats`` seeds, written to ``final.csv``
  (mean and standard error of each objective, ``knee`` and ``count`` columns).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..report.pareto import knee_index, pareto_mask, to_min
from .evaluate import Evaluator
from .spec import ResolvedStudy

__all__ = ["best_designs", "reevaluate_best", "merge_duplicates", "pareto_front", "knee_of", "crowding_distance",
           "spread_by_crowding", "design_key"]


def design_key(study: ResolvedStudy, row) -> tuple:
    """Identity of a design: its design-variable values (floats to 12 significant digits, so
    that a value read back from CSV matches the one evaluated)."""
    out = []
    for v in study.variables:
        x = row[v.name]
        if isinstance(x, (float, np.floating)) and np.isfinite(x):
            x = float(f"{float(x):.12g}")
        elif isinstance(x, (np.integer,)):
            x = int(x)
        out.append(x)
    return tuple(out)


def merge_duplicates(study: ResolvedStudy, df: pd.DataFrame) -> pd.DataFrame:
    """One row per distinct design (the first evaluated, by row order) with ``count``: how many
    rows of ``df`` hold that design. An existing ``count`` column is summed."""
    if not len(df):
        out = df.copy()
        out["count"] = pd.Series(dtype=int)
        return out
    keys = [design_key(study, r) for _, r in df.iterrows()]
    weights = df["count"].to_numpy(int) if "count" in df else np.ones(len(df), int)
    first, counts = {}, {}
    for pos, (k, w) in enumerate(zip(keys, weights)):
        if k not in first:
            first[k] = pos
        counts[k] = counts.get(k, 0) + int(w)
    order = sorted(first.values())
    out = df.iloc[order].copy()
    out["count"] = [counts[keys[p]] for p in order]
    return out


def _feasible(df: pd.DataFrame) -> pd.DataFrame:
    if not len(df):
        return df
    return df[df["feasible"].astype(bool) & (df["status"] == "ok")]


def pareto_front(study: ResolvedStudy, df: pd.DataFrame) -> pd.DataFrame:
    """Non-dominated feasible designs of ``df`` (mixed senses), duplicates merged (``count``)."""
    ok = merge_duplicates(study, _feasible(df))
    if not len(ok):
        return ok
    labels = [o.label for o in study.objectives]
    mask = pareto_mask(ok[labels].to_numpy(float), [o.goal for o in study.objectives])
    return ok[mask]


def knee_of(study: ResolvedStudy, front: pd.DataFrame):
    """The knee (recommended design) of a front as returned by :func:`pareto_front`; ``None``
    for an empty front."""
    if not len(front):
        return None
    Fm = to_min(front[[o.label for o in study.objectives]].to_numpy(float), [o.goal for o in study.objectives])
    return front.iloc[knee_index(Fm)]


def crowding_distance(F: np.ndarray) -> np.ndarray:
    """NSGA-II crowding distance of the rows of ``F`` (n, m): per objective, the rows sorted by
    it, the two extremes get infinity and every other row the gap between its neighbours
    divided by the objective's range; distances summed over the objectives. An objective with
    zero range contributes nothing. Ties in an objective are ordered by row index."""
    F = np.asarray(F, dtype=float)
    n, m = F.shape
    d = np.zeros(n)
    if n <= 2:
        return np.full(n, np.inf)
    for j in range(m):
        order = np.lexsort((np.arange(n), F[:, j]))
        col = F[order, j]
        span = col[-1] - col[0]
        d[order[0]] = d[order[-1]] = np.inf
        if span > 0:
            d[order[1:-1]] += (col[2:] - col[:-2]) / span
    return d


def spread_by_crowding(F: np.ndarray, k: int) -> np.ndarray:
    """Indices (ascending) of ``k`` rows of a front ``F`` spread along it: repeatedly drop the
    row with the smallest crowding distance among those left (recomputed after each drop;
    on a tie the later row goes), as in NSGA-II's truncation with recomputed crowding. The
    extremes of every objective stay as long as ``k`` allows."""
    F = np.asarray(F, dtype=float)
    keep = list(range(len(F)))
    if k <= 0:
        return np.array([], int)
    while len(keep) > k:
        d = crowding_distance(F[keep])
        worst = min(range(len(keep)), key=lambda i: (d[i], -i))
        keep.pop(worst)
    return np.array(keep, int)


def best_designs(study: ResolvedStudy, df: pd.DataFrame, k: int = 5) -> pd.DataFrame:
    """Feasible designs a run recommends, duplicates merged (``count`` column).

    One objective: the ``k`` best, best first. Several: the non-dominated feasible set
    (:func:`pareto_front`); when it holds more than ``k`` designs, ``k`` of them spread along
    it by crowding distance (:func:`spread_by_crowding`), in the order of the first objective.
    ``k = 0``: every design of the front."""
    objs = study.objectives
    if len(objs) == 1:
        ok = merge_duplicates(study, _feasible(df))
        o = objs[0]
        ok = ok.sort_values(o.label, ascending=(o.goal == "minimize"), kind="stable")
        return ok.head(k) if k else ok
    front = pareto_front(study, df)
    if k and len(front) > k:
        Fm = to_min(front[[o.label for o in objs]].to_numpy(float), [o.goal for o in objs])
        front = front.iloc[spread_by_crowding(Fm, k)]
    o = objs[0]
    return front.sort_values(o.label, ascending=(o.goal == "minimize"), kind="stable")


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


def final_candidates(study: ResolvedStudy, table: pd.DataFrame) -> pd.DataFrame:
    """The run designs the final re-evaluation covers: every completed design for a sweep (read
    as a curve), otherwise :func:`best_designs` with ``final_top``; the knee of the front is
    added when it is not among them. Column ``knee`` marks it."""
    ev = study.evaluation
    runs = table[table["source"] == "run"] if len(table) else table
    if study.optimizer.kind == "sweep":
        best = merge_duplicates(study, runs[runs["status"] == "ok"])
    else:
        best = best_designs(study, runs, k=ev.get("final_top", 5))
    best = best.copy()
    best["knee"] = False
    knee = knee_of(study, pareto_front(study, runs))
    if knee is not None:
        kk = design_key(study, knee)
        hit = [design_key(study, r) == kk for _, r in best.iterrows()]
        if any(hit):
            best.loc[best.index[int(np.argmax(hit))], "knee"] = True
        else:
            row = knee.to_frame().T
            row["knee"] = True
            best = pd.concat([best, row])
    return best


def reevaluate_best(study: ResolvedStudy, evaluator: Evaluator, table: pd.DataFrame, out_dir: Path) -> pd.DataFrame:
    """Re-evaluate the final candidates (:func:`final_candidates`: the best feasible designs and
    the knee) and the reference with ``final_samples`` samples and ``final_repeats`` seeds
    (``seed + 1000 + j``): mean and standard error of each objective, written to
    ``final.csv`` (columns ``source`` (best | reference), ``trial``, the design variables,
    ``<objective>`` and ``<objective>_stderr``, ``feasible``, ``samples``, ``repeats``,
    ``knee``, ``count``)."""
    ev = study.evaluation
    best = final_candidates(study, table)
    ref = table[table["source"] == "reference"] if len(table) else table
    rows = []
    for src, df in (("best", best), ("reference", ref.head(1))):
        for _, row in df.iterrows():
            values = {v.name: row[v.name] for v in study.variables} if src == "best" else dict(study.reference)
            recs = [evaluator.evaluate(values, n=ev["final_samples"], seed=ev["seed"] + 1000 + j)
                    for j in range(ev["final_repeats"])]
            out = {"source": src, "trial": int(row["trial"])}
            out.update({v.name: values.get(v.name) for v in study.variables})
            for o in study.objectives:
                vals = np.array([r.objectives.get(o.label, np.nan) for r in recs], float)
                fin = vals[np.isfinite(vals)]
                out[o.label] = float(fin.mean()) if len(fin) else np.nan
                out[f"{o.label}_stderr"] = float(fin.std(ddof=1) / np.sqrt(len(fin))) if len(fin) > 1 else np.nan
            out["feasible"] = all(r.feasible for r in recs)
            out["samples"] = ev["final_samples"]
            out["repeats"] = ev["final_repeats"]
            out["knee"] = bool(row.get("knee", False)) if src == "best" else False
            out["count"] = int(row.get("count", 1)) if src == "best" else 1
            rows.append(out)
    df = pd.DataFrame(rows)
    df.to_csv(out_dir / "final.csv", index=False)
    return df
