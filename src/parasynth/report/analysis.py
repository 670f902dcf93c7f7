"""What a report states about a run, as typed values: the non-dominated front and its knee,
the hypervolume, the reference design's standing on single samples and, when ``final.csv``
holds them, the verdicts on the re-evaluated designs (beyond noise), and the warnings of
:mod:`parasynth.report.checks`. Reads a run only as :class:`parasynth.study.rundir.Run`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..common.pareto import (FAR_FENCE, NoisyComparison, ReferenceStanding, compare_with_noise, default_reference_point, hypervolume,
                             reference_standing, to_min)
from ..study.rundir import (Run, design_key, design_keys, knee_of, pareto_front, recommendation_order, screening_dominators,
                            sorted_front)
from .checks import design_warnings
from ..common import columns as derived

__all__ = ["Analysis", "FinalAnalysis", "Recommendation", "analyse", "passed_mask", "NOISE_Z"]


def _passed(row) -> bool:
    """Whether a re-evaluated design counts: it passed verification (final.csv's ``verified``),
    or, in a final.csv written before verification, it stayed feasible."""
    if "verified" in row.index and pd.notna(row["verified"]):
        return bool(row["verified"])
    return bool(row.get("feasible", True))


def passed_mask(fin: pd.DataFrame) -> pd.Series:
    """Rows of a final.csv that count in a verdict (:func:`_passed` of each)."""
    return pd.Series([_passed(r) for _, r in fin.iterrows()], index=fin.index, dtype=bool)

#: A difference between re-evaluated designs counts when it exceeds this many combined standard
#: errors (``write_report(..., noise_z=...)``).
NOISE_Z = 2.0


@dataclass
class FinalAnalysis:
    """The re-evaluated designs of ``final.csv`` compared with each other and with the
    reference design, beyond noise."""

    #: final.csv with the columns ``knee`` (the report's knee) and ``dominates_reference_screen``.
    table: pd.DataFrame
    #: its rows of source ``best``.
    best: pd.DataFrame
    #: row index of each best design -> trials of the best designs that dominate it beyond noise.
    dominated_by: dict[int, list[int]]
    #: number of distinct designs that dominate the reference on single-sample values.
    n_screen: int
    #: the re-evaluated reference design, if final.csv holds it.
    ref: pd.Series | None = None
    #: each best design (other than the reference itself) compared with the reference.
    vs_ref: list[tuple[pd.Series, NoisyComparison]] = field(default_factory=list)
    #: the re-evaluated row of the report's knee, if final.csv holds it.
    knee: pd.Series | None = None
    #: True when the run has a knee that final.csv does not hold (final.csv is older).
    knee_missing: bool = False
    #: re-evaluated designs that failed verification (they count in no verdict)
    unverified: pd.DataFrame | None = None


@dataclass
class Recommendation:
    """What the run recommends once verified (:mod:`parasynth.study.verify`).

    ``status``: ``verified`` (``row`` passed), ``none passed`` (no design of those re-checked
    passed: ``row`` is the first of the ranking, not to be built as it is), ``not verified``
    (final.csv is missing or older than verification: ``row`` is the knee or best design on
    single samples)."""

    status: str
    row: pd.Series | None = None
    #: the re-evaluated row of ``row`` in final.csv, if any
    final_row: pd.Series | None = None
    #: (trial, reason) of the designs ranked before ``row`` (or all re-checked, when none passed)
    #: that failed verification
    failed: list = field(default_factory=list)
    #: how many designs were verified
    checked: int = 0
    #: the first design of the ranking (the knee, or the best design), whether it passed or not
    first: pd.Series | None = None

    @property
    def verified(self) -> bool:
        return self.status == "verified"


@dataclass
class Analysis:
    """Front, knee, hypervolume, the reference design's standing and the re-evaluation
    verdicts of a loaded run (:func:`analyse`)."""

    #: the run's own designs (source ``run``) of the results table.
    runs: pd.DataFrame
    #: the distinct non-dominated feasible designs, best first in the first objective.
    front: pd.DataFrame
    labels: list[str]
    senses: list[str]
    noise_z: float
    #: the evaluated reference design (status ok), or None.
    ref_row: pd.Series | None = None
    #: the recommended design: the knee of the front (the best design for one objective).
    knee_row: pd.Series | None = None
    #: hypervolume of the front (SI, objectives as minimised), its reference point and its
    #: share of the box between the ideal and the reference point; None for one objective.
    hv: float | None = None
    hv_ref: np.ndarray | None = None
    hv_fraction: float | None = None
    #: the reference design among the feasible single samples.
    standing: ReferenceStanding | None = None
    final: FinalAnalysis | None = None
    warnings: list[str] = field(default_factory=list)
    #: the recommendation once verified (``knee_row`` is its row)
    recommendation: Recommendation | None = None


def analyse(run: Run, noise_z: float = NOISE_Z) -> Analysis:
    """Front, knee, hypervolume and the reference design's standing (single-sample screening
    and, when ``final.csv`` holds it, the re-evaluated verdict) of a loaded run."""
    study, t = run.study, run.table
    runs = t[t["source"] == "run"].copy()
    objs = study.objectives
    labels = [o.label for o in objs]
    senses = [o.goal for o in objs]
    ok = (runs["status"] == "ok").to_numpy()
    feas = (runs["feasible"].astype(bool)).to_numpy() & ok
    F = runs[labels].to_numpy(float)
    front = sorted_front(study, pareto_front(study, runs))  # best first in the first objective
    a = Analysis(runs=runs, front=front, labels=labels, senses=senses, noise_z=float(noise_z))
    ref = t[t["source"] == "reference"]
    a.ref_row = ref.iloc[0] if len(ref) and ref.iloc[0]["status"] == "ok" else None
    a.knee_row = knee_of(study, front)
    a.recommendation = _recommendation(run, a.knee_row)
    if a.recommendation.row is not None:
        a.knee_row = a.recommendation.row
    if len(front) and len(objs) > 1:
        Fm = to_min(front[labels].to_numpy(float), senses)
        Ffeas = to_min(F[feas], senses)
        refpt = default_reference_point(Ffeas, fence=FAR_FENCE)
        a.hv_ref = refpt
        a.hv = hypervolume(Fm, refpt)
        box = float(np.prod(refpt - Ffeas.min(axis=0)))
        a.hv_fraction = a.hv / box if box > 0 else float("nan")
    if a.ref_row is not None and feas.any():
        a.standing = reference_standing(F[feas], senses, np.ones(feas.sum(), bool),
                                        a.ref_row[labels].to_numpy(float), labels)
    a.final = _final_analysis(run, a.knee_row, noise_z)
    a.warnings = design_warnings(study, a.knee_row, front, a.runs)
    return a


def _recommendation(run: Run, first) -> Recommendation:
    """The recommendation final.csv records (column ``recommended``), the designs ranked before it
    that failed verification, or the knee / best design unverified when final.csv predates
    verification."""
    study, fin = run.study, run.final
    if first is None:
        return Recommendation("none passed" if fin is not None and "verified" in fin else "not verified", None)
    if fin is None or not len(fin) or "verified" not in fin or "recommended" not in fin:
        return Recommendation("not verified", first, first=first)
    best = fin[fin["source"] == "best"]
    runs = run.table[run.table["source"] == "run"]
    order = recommendation_order(study, runs)
    order_keys = design_keys(study, order)
    rank = {k: i for i, k in enumerate(order_keys)}
    checked = best.assign(_rank=[rank.get(design_key(study, r), len(rank)) for _, r in best.iterrows()])
    checked = checked.sort_values("_rank", kind="stable")
    picked = checked[checked["recommended"].astype(bool)]
    if len(picked):
        fr = picked.iloc[0]
        key = design_key(study, fr)
        row = order.iloc[order_keys.index(key)] if key in rank else None
        if row is None:  # the run table no longer holds it as a feasible design (an older final.csv)
            return Recommendation("not verified", first, first=first)
        failed = [(int(r["trial"]), str(r.get("verification", ""))) for _, r in checked.iterrows()
                  if not bool(r["verified"]) and r["_rank"] < fr["_rank"]]
        return Recommendation("verified", row, fr, failed, int(len(best)), first=first)
    failed = [(int(r["trial"]), str(r.get("verification", ""))) for _, r in checked.iterrows() if not bool(r["verified"])]
    kk = design_key(study, first)
    fr = next((r for _, r in best.iterrows() if design_key(study, r) == kk), None)
    return Recommendation("none passed", first, fr, failed, int(len(best)), first=first)


def _final_analysis(run: Run, knee_row, noise_z: float) -> FinalAnalysis | None:
    """Re-evaluated designs compared with each other and with the reference, beyond noise."""
    study, fin = run.study, run.final
    labels = [o.label for o in study.objectives]
    senses = [o.goal for o in study.objectives]
    need = labels + [derived.stderr(lab) for lab in labels] + ["source"]
    if fin is None or not len(fin) or any(c not in fin for c in need):
        return None
    fin = fin.copy()
    if "knee" not in fin:  # final.csv of an older run: find the knee by its design values
        kk = design_key(study, knee_row) if knee_row is not None else None
        fin["knee"] = [r["source"] == "best" and kk is not None and design_key(study, r) == kk for _, r in fin.iterrows()]
    fin["knee"] = fin["knee"].astype(bool)
    best = fin[fin["source"] == "best"]
    ref = fin[fin["source"] == "reference"]

    def mse(row):
        return row[labels].to_numpy(float), row[[derived.stderr(lab) for lab in labels]].to_numpy(float)

    dominated_by = {}
    for i, ri in best.iterrows():
        mi, si = mse(ri)
        # a design that failed verification (or, in a final.csv without it, is infeasible once
        # re-evaluated) dominates none
        dominated_by[i] = [int(rj["trial"]) for j, rj in best.iterrows()
                           if j != i and _passed(rj)
                           and compare_with_noise(*mse(rj), mi, si, senses, noise_z).verdict == "dominates"]
    # Which re-evaluated designs dominate the reference on the single-sample values: decided
    # from the run's table (the screening the report states), by design values.
    screen_keys = {design_key(study, r) for _, r in screening_dominators(study, run.table).iterrows()}
    fin["dominates_reference_screen"] = [r["source"] == "best" and design_key(study, r) in screen_keys
                                         for _, r in fin.iterrows()]
    best = fin[fin["source"] == "best"]
    out = FinalAnalysis(table=fin, best=best, dominated_by=dominated_by, n_screen=len(screen_keys),
                        unverified=best[[not _passed(r) for _, r in best.iterrows()]])
    if len(ref):
        r = ref.iloc[0]
        out.ref = r
        rk = design_key(study, r) if all(v.name in r and pd.notna(r[v.name]) for v in study.variables) else None
        mr, sr = mse(r)
        for i, row in best.iterrows():
            if rk is not None and design_key(study, row) == rk:
                continue  # the reference design itself among the re-evaluated ones
            if not _passed(row):
                continue  # a design that failed verification counts in no verdict
            out.vs_ref.append((row, compare_with_noise(*mse(row), mr, sr, senses, noise_z)))
    # The knee as the report computes it must be the one re-evaluated (final.csv may be older
    # than a resumed run's table).
    out.knee_missing = knee_row is not None
    if knee_row is not None:
        kk = design_key(study, knee_row)
        hit = [i for i, r in best.iterrows() if design_key(study, r) == kk]
        fin["knee"] = False
        if hit:
            out.knee, out.knee_missing = best.loc[hit[0]], False
            fin.loc[hit[0], "knee"] = True
    return out
