"""Final stage of a study: the designs a run recommends and their re-evaluation.

* :func:`merge_duplicates` -- identical designs (same design-variable values) evaluated more
  than once (Optuna may propose a design twice) become one row with their ``count``;
* :func:`pareto_front` -- the non-dominated feasible designs, duplicates merged; the report
  and the re-evaluation use this one definition;
* :func:`knee_of` -- the recommended design: the knee of that front
  (:func:`parasynth.common.pareto.knee_index`);
* :func:`best_designs` -- the feasible designs a run recommends: for one objective the best
  ``k``; for several, ``k`` designs spread along the front by crowding distance
  (:func:`parasynth.common.pareto.spread_by_crowding`);
* :func:`screening_dominators` -- the feasible designs that dominate the paper's reference
  design on the single-sample values, the ones by the largest normalised margin first;
* :func:`reevaluate_best` -- those designs, the knee (always), up to
  ``max(3, final_top)`` screening dominators and the reference evaluated again with
  ``final_samples`` samples and ``final_repeats`` seeds, written to ``final.csv`` (mean and
  standard error of each objective, ``knee``, ``role``, ``dominates_reference_screen`` and
  ``count`` columns), so that the paper-design verdict is decided on the designs the
  screening says beat it, not only on the front's spread.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..common.pareto import (compare_with_noise, crowding_distance, dominators_of, knee_index, knee_order,
                             non_dominated_ranks, pareto_mask, spread_by_crowding, to_min)
from .view import write_view
from .columns import to_csv_columns
from .design import design_key
from .evaluate import Evaluator
from .spec import ResolvedStudy
from .verify import NOISE_Z, SINGULARITY_FLOOR, VERIFY_LIMIT, Verification, estimate_of, verify
from ..common import columns as derived

__all__ = ["best_designs", "reevaluate_best", "recommendation_order", "structure_candidates", "screening_dominators", "final_candidates", "n_screen_dominators", "merge_duplicates", "pareto_front", "knee_of", "crowding_distance",
           "spread_by_crowding", "design_key", "design_keys"]  # crowding_distance, spread_by_crowding (parasynth.common.pareto) and
# design_key (study.design) are re-exported here for existing imports.


def design_keys(study: ResolvedStudy, df: pd.DataFrame) -> list:
    """:func:`design_key` of every row of ``df``, in order: the rows read as dicts of the
    variables' columns (a row of ``iterrows`` costs a pandas Series: ~1 s for the front and
    candidates of a 1,000-design study); a column missing from ``df`` is an absent value, as
    for a row."""
    cols = [v.name for v in study.variables if v.name in df.columns]
    return [design_key(study, r) for r in df[cols].to_dict("records")]


def merge_duplicates(study: ResolvedStudy, df: pd.DataFrame) -> pd.DataFrame:
    """One row per distinct design (the first evaluated, by row order) with ``count``: how many
    rows of ``df`` hold that design. An existing ``count`` column is summed."""
    if not len(df):
        out = df.copy()
        out["count"] = pd.Series(dtype=int)
        return out
    keys = design_keys(study, df)
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


def n_screen_dominators(final_top: int) -> int:
    """How many screening dominators of the reference the final re-evaluation adds at most:
    ``max(3, final_top)`` (a handful even when few front designs are asked for)."""
    return max(3, int(final_top))


def screening_dominators(study: ResolvedStudy, table: pd.DataFrame) -> pd.DataFrame:
    """Distinct feasible run designs that dominate the reference design on the single-sample
    values of ``table`` (the reference row: ``source == "reference"``, status ok), ordered by
    their normalised margin, largest first.

    Margin (assumption, stated so it can be checked): in objectives turned into minimisation
    and normalised by their range over the feasible run designs, ``min_j (r_j - f_j)`` -- how
    much the design is better than the reference in its *least* improved objective (the
    negated additive epsilon of that single design); ties broken by the sum of the normalised
    improvements, then by row order. Designs better by a large margin everywhere are the most
    likely to stay better once re-evaluated. Columns as ``table`` plus ``count`` and
    ``screen_margin``. Empty without a usable reference."""
    runs = table[table["source"] == "run"] if len(table) else table
    ref = table[(table["source"] == "reference") & (table["status"] == "ok")] if len(table) else table
    ok = merge_duplicates(study, _feasible(runs))
    labels = [o.label for o in study.objectives]
    senses = [o.goal for o in study.objectives]
    if not len(ok) or not len(ref):
        out = ok.iloc[:0].copy()
        out["screen_margin"] = pd.Series(dtype=float)
        return out
    Fm = to_min(ok[labels].to_numpy(float), senses)
    r = to_min(ref.iloc[[0]][labels].to_numpy(float), senses)[0]
    fin = np.all(np.isfinite(Fm), axis=1)
    if not np.all(np.isfinite(r)) or not fin.any():
        out = ok.iloc[:0].copy()
        out["screen_margin"] = pd.Series(dtype=float)
        return out
    span = Fm[fin].max(axis=0) - Fm[fin].min(axis=0)
    span = np.where(span > 0, span, 1.0)
    dom = fin & dominators_of(Fm, r)
    idx = np.flatnonzero(dom)
    gain = (r - Fm[idx]) / span
    least, total = gain.min(axis=1), gain.sum(axis=1)
    order = np.lexsort((np.arange(len(idx)), -total, -least))
    out = ok.iloc[idx[order]].copy()
    out["screen_margin"] = least[order]
    return out


def final_candidates(study: ResolvedStudy, table: pd.DataFrame) -> pd.DataFrame:
    """The run designs the final re-evaluation covers: every completed design for a sweep (read
    as a curve), otherwise :func:`best_designs` with ``final_top``; the knee of the front is
    added when it is not among them, and so are up to :func:`n_screen_dominators` designs that
    dominate the reference on the single-sample values (:func:`screening_dominators`, largest
    margin first), so that the paper-design verdict decides on them too.

    Columns: ``knee`` marks the knee; ``role`` says why a design is re-evaluated (``best``: the
    best / crowding spread of the front, or a sweep point; ``knee``: added as the knee;
    ``screen``: added as a screening dominator of the reference; ``structure``: added as the
    best design of a structure, or on the reference structure's front, in a study over structures,
    :func:`structure_candidates`); ``dominates_reference_screen``
    marks every candidate that dominates the reference on the single-sample values, whatever
    its role."""
    ev = study.evaluation
    runs = table[table["source"] == "run"] if len(table) else table
    if study.optimizer.plugin.lists_designs:
        best = merge_duplicates(study, runs[runs["status"] == "ok"])
    else:
        best = best_designs(study, runs, k=ev.get("final_top", 5))
    best = best.copy()
    best["knee"] = False
    best["role"] = "best"
    keys = [design_key(study, r) for _, r in best.iterrows()]
    knee = knee_of(study, pareto_front(study, runs))
    if knee is not None:
        kk = design_key(study, knee)
        if kk in keys:
            best.loc[best.index[keys.index(kk)], "knee"] = True
        else:
            row = knee.to_frame().T
            row["knee"], row["role"] = True, "knee"
            best = pd.concat([best, row])
            keys.append(kk)
    screen = screening_dominators(study, table)
    screen_keys = [design_key(study, r) for _, r in screen.iterrows()]
    if not study.optimizer.plugin.lists_designs:
        limit = n_screen_dominators(ev.get("final_top", 5))
        # The ``limit`` dominators by the largest margin are all re-evaluated: those already
        # among the candidates keep their role, the others are added.
        for (_, r), k in list(zip(screen.iterrows(), screen_keys))[:limit]:
            if k in keys:
                continue
            row = r.drop(labels=["screen_margin"]).to_frame().T
            row["knee"], row["role"] = False, "screen"
            best = pd.concat([best, row])
            keys.append(k)
    for row in structure_candidates(study, runs):
        k = design_key(study, row)
        if k not in keys:
            row = row.to_frame().T
            row["knee"], row["role"] = False, "structure"
            best = pd.concat([best, row])
            keys.append(k)
    sk = set(screen_keys)
    best["dominates_reference_screen"] = [k in sk for k in keys]
    best["knee"] = best["knee"].astype(bool)
    return best


def structure_candidates(study: ResolvedStudy, runs: pd.DataFrame) -> list:
    """For a study over structures, the designs re-evaluated besides the combined front's: the
    knee of every structure's own front (its best design) and, for the reference structure,
    ``final_top`` designs spread along its own front, so that the verdict on the reference
    structure compares re-evaluated designs of every structure. Rows of ``runs``."""
    setup = getattr(study, "structures", None)
    if setup is None or not len(runs) or "structure" not in runs:
        return []
    out = []
    for label in setup.labels:
        mine = runs[runs["structure"] == label]
        if label == setup.reference:
            out += [r for _, r in best_designs(study, mine, k=study.evaluation.get("final_top", 5)).iterrows()]
        knee = knee_of(study, pareto_front(study, mine))
        if knee is not None:
            out.append(knee)
    return out


def recommendation_order(study: ResolvedStudy, runs: pd.DataFrame) -> pd.DataFrame:
    """The distinct feasible designs of ``runs`` in the order a recommendation walks them until
    one passes verification (:mod:`parasynth.study.verify`): one objective, best first; several,
    the non-dominated front in knee order (:func:`parasynth.common.pareto.knee_order`: the knee
    first), then the next front in its knee order, and so on. Its first row is
    :func:`knee_of` of :func:`pareto_front` (the best design for one objective)."""
    ok = merge_duplicates(study, _feasible(runs))
    objs = study.objectives
    if not len(ok):
        return ok
    if len(objs) == 1:
        o = objs[0]
        return ok.sort_values(o.label, ascending=(o.goal == "minimize"), kind="stable")
    Fm = to_min(ok[[o.label for o in objs]].to_numpy(float), [o.goal for o in objs])
    ranks = non_dominated_ranks(Fm)
    order = []
    for r in np.unique(ranks):
        idx = np.flatnonzero(ranks == r)
        order += list(idx[knee_order(Fm[idx])])
    return ok.iloc[order]


def _screened_constraints(study: ResolvedStudy, row) -> dict:
    return {c.label: float(row[c.label]) for c in study.constraints
            if c.label in row and pd.notna(row[c.label])}


def _needs_seeds(study: ResolvedStudy) -> bool:
    """Whether any objective or constraint depends on the sample's seed (else a re-evaluation over
    seeds repeats the run's own values)."""
    return any(estimate_of(x) in ("statistic", "extreme") for x in (*study.objectives, *study.constraints))


def _reevaluate_one(study: ResolvedStudy, evaluator: Evaluator, values: dict, row, src: str) -> tuple[dict, Verification]:
    """The final.csv row of one design and its verification."""
    ev = study.evaluation
    n = ev.get("final_samples") or ev["n"]
    recs = ([evaluator.evaluate(values, n=n, seed=ev["seed"] + 1000 + j) for j in range(ev["final_repeats"])]
            if _needs_seeds(study) else [])
    screened = _screened_constraints(study, row)
    ver = verify(study, values, recs, screened=screened, floor=ev.get("singularity_floor", SINGULARITY_FLOOR))
    out = {"source": src, "trial": int(row["trial"])}
    out.update({v.name: values.get(v.name) for v in study.variables})
    for o in study.objectives:
        if estimate_of(o) in ("grid", "exact") or not recs:
            # exact on its grid or without a sample: the run's own value, no spread to state
            out[o.label] = float(row[o.label]) if pd.notna(row.get(o.label)) else np.nan
            out[derived.stderr(o.label)] = 0.0
            continue
        vals = np.array([r.objectives.get(o.label, np.nan) for r in recs], float)
        fin = vals[np.isfinite(vals)]
        out[o.label] = float(fin.mean()) if len(fin) else np.nan
        out[derived.stderr(o.label)] = float(fin.std(ddof=1) / np.sqrt(len(fin))) if len(fin) > 1 else np.nan
    by_label = {c.label: c for c in ver.checks if c.label}
    for c in study.constraints:
        chk = by_label.get(c.label)
        out[c.label] = chk.value if chk is not None else np.nan
        out[derived.stderr(c.label)] = chk.stderr if chk is not None and chk.kind == "statistic" else np.nan
    home = [c for c in ver.checks if not c.label]
    out["home_margin"] = home[0].value if home else np.nan
    out["feasible"] = all(r.feasible for r in recs) if recs else bool(row.get("feasible", True))
    out["samples"] = n if recs else int(row.get("samples", ev["n"]))
    out["repeats"] = len(recs) if recs else 0
    out["verified"] = ver.passed
    out["verification"] = ver.reason(study)
    return out, ver


def reevaluate_best(study: ResolvedStudy, evaluator: Evaluator, table: pd.DataFrame, out_dir: Path) -> pd.DataFrame:
    """Re-evaluate and verify the final candidates (:func:`final_candidates`: the best feasible
    designs, the knee and the screening dominators of the reference) and the reference with
    ``final_samples`` samples (the study's own count without it) and ``final_repeats`` seeds
    (``seed + 1000 + j``), then walk :func:`recommendation_order` until a design passes
    :func:`parasynth.study.verify.verify`, re-evaluating at most ``verify_designs`` designs
    beyond the candidates (role ``verify``); that design is the run's recommendation, unless a
    verified design dominates it beyond noise (then the dominating one, :data:`NOISE_Z`).

    Written to ``final.csv``: ``source`` (best | reference), ``trial``, the design variables,
    ``<objective>`` and ``<objective>_stderr`` (mean and standard error over the seeds; a grid
    or exact objective keeps the run's own value with standard error 0), ``<constraint>`` and
    ``<constraint>_stderr`` (the value verified: the mean of a statistic, the worst seed of an
    extreme), ``home_margin``, ``feasible``, ``samples``, ``repeats``, ``verified``,
    ``verification`` (``verified`` or what failed where), ``recommended``, ``knee``, ``role``
    (best | knee | screen | structure | verify | reference), ``dominates_reference_screen``,
    ``count``."""
    ev = study.evaluation
    best = final_candidates(study, table) if ev.get("final_top", 0) > 0 else table.iloc[:0].assign(
        knee=pd.Series(dtype=bool), role=pd.Series(dtype=str), dominates_reference_screen=pd.Series(dtype=bool))
    ref = table[table["source"] == "reference"] if len(table) else table
    rows, verdicts, keys = [], {}, []

    def add(row, src):
        values = {v.name: row[v.name] for v in study.variables} if src == "best" else dict(study.reference)
        if src == "best" and study.space.conditional:  # inactive variables are empty cells
            values = study.space.restrict(values)
        out, ver = _reevaluate_one(study, evaluator, values, row, src)
        out["recommended"] = False
        out["knee"] = bool(row.get("knee", False)) if src == "best" else False
        out["role"] = str(row.get("role", "best")) if src == "best" else "reference"
        out["dominates_reference_screen"] = bool(row.get("dominates_reference_screen", False)) if src == "best" else False
        out["count"] = int(row.get("count", 1)) if src == "best" else 1
        rows.append(out)
        if src == "best":
            k = design_key(study, row)
            keys.append(k)
            verdicts[k] = len(rows) - 1
        return out

    for _, row in best.iterrows():
        add(row, "best")
    runs = table[table["source"] == "run"] if len(table) else table
    pick = None
    extra = 0
    for _, row in recommendation_order(study, runs).iterrows():
        k = design_key(study, row)
        if k not in verdicts:
            if extra >= ev.get("verify_designs", VERIFY_LIMIT):
                break
            row = row.copy()
            row["knee"], row["role"], row["dominates_reference_screen"] = False, "verify", False
            add(row, "best")
            extra += 1
        if rows[verdicts[k]]["verified"]:
            pick = verdicts[k]
            break
    if pick is not None:
        pick = _undominated(study, rows, pick)
        rows[pick]["recommended"] = True
    for _, row in ref.head(1).iterrows():
        add(row, "reference")
    df = pd.DataFrame(rows)
    if df.empty:  # nothing feasible and no reference: the header alone, so the run still reports
        labels = [o.label for o in study.objectives]
        df = pd.DataFrame(columns=["source", "trial"] + labels + [derived.stderr(lab) for lab in labels])
    to_csv_columns(study, df).to_csv(out_dir / "final.csv", index=False)  # unit suffixes in the names
    write_view(study, df, pareto_front(study, runs), out_dir)  # the report's drawings (view.json)
    return df


def _undominated(study: ResolvedStudy, rows: list[dict], pick: int) -> int:
    """``pick``, or the verified re-evaluated design that dominates it beyond noise (followed until
    none does): a recommendation is never shown dominated by another design that passed."""
    labels = [o.label for o in study.objectives]
    senses = [o.goal for o in study.objectives]

    def mse(r):
        return (np.array([r[lab] for lab in labels], float),
                np.nan_to_num(np.array([r[derived.stderr(lab)] for lab in labels], float), nan=0.0))

    seen = {pick}
    while True:
        mi, si = mse(rows[pick])
        better = [j for j, r in enumerate(rows) if j != pick and r["source"] == "best" and r["verified"]
                  and compare_with_noise(*mse(r), mi, si, senses, NOISE_Z).verdict == "dominates"]
        if not better:
            return pick
        # the dominator that ranks first (its own row order: candidates, then the walk)
        nxt = better[0]
        if nxt in seen:
            return pick
        seen.add(nxt)
        pick = nxt
