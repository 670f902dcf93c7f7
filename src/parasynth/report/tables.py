"""The report's tables for people: values in the study's display units (mm, deg, cm^3, ...)
named in the headers, numbers as strings without float noise."""

from __future__ import annotations

import pandas as pd

from ..measures.display import Unit, fmt_mean_se, fmt_number, fmt_value, quantity_unit, reference_short
from ..study.rundir import estimate_of
from .analysis import FinalAnalysis
from .checks import design_roles
from ..common import columns as derived

__all__ = ["display_table", "final_display_table", "unit", "is_number_col"]


def unit(study, name) -> Unit:
    """The display unit of a variable, objective or constraint of ``study``."""
    return quantity_unit(study, name)


def is_number_col(study, name) -> bool:
    """False for a categorical variable without a quantity kind (shown as text)."""
    v = next((v for v in study.variables if v.name == name), None)
    return v is None or v.type != "categorical" or bool(v.kind)


def display_table(study, df: pd.DataFrame, constraints: bool = True) -> pd.DataFrame:
    """A results table for people: display units per quantity (mm, deg, cm^3, N, ...) named in
    the headers, numbers as strings with 4 significant digits (no float noise); ``count``
    (merged duplicates) shown as ``evaluations``."""
    out = pd.DataFrame(index=df.index)
    if "trial" in df:
        out["trial"] = [fmt_number(int(x)) for x in df["trial"]]
    if "count" in df:
        out["evaluations"] = [fmt_number(int(x)) for x in df["count"]]
    cols = [v.name for v in study.variables] + [o.label for o in study.objectives]
    if constraints:
        cols += [c.label for c in study.constraints]
    for c in cols:
        if c not in df:
            continue
        u = unit(study, c)
        if is_number_col(study, c):
            out[u.label(c)] = [fmt_value(x, u) for x in df[c]]
        else:
            out[c] = [str(x) for x in df[c]]
    if "feasible" in df:
        out["feasible"] = ["yes" if bool(x) else "no" for x in df["feasible"]]
    return out


def final_display_table(study, fa: FinalAnalysis) -> pd.DataFrame:
    """The re-evaluation table for people: role, trial, evaluations, design variables and each
    objective as ``mean ± standard error`` in display units, and the re-evaluated designs that
    dominate each one beyond noise."""
    fin = fa.table
    rows = []
    best_rows = fin[fin["source"] == "best"]
    why = dict(zip(best_rows.index, design_roles(study, best_rows))) if len(best_rows) else {}
    for i, r in fin.iterrows():
        other = "sweep point" if study.optimizer.plugin.lists_designs else why.get(i, "best")
        if "recommended" in fin:  # verified (docs/verification.md)
            recommended, rec = bool(r["recommended"]), "recommended (verified)"
            if bool(r["knee"]) and not recommended:
                other = "knee (not recommended)"
        else:  # a final.csv written before verification: the knee, unverified
            recommended = bool(r["knee"])
            rec = "recommended (knee)" if len(study.objectives) > 1 else "recommended (best)"
        role = other
        if r["source"] == "best" and bool(r.get("dominates_reference_screen", False)):
            role = f"dominates {reference_short(study)} (screening)"
        row = {"design": (reference_short(study) if r["source"] == "reference" else (rec if recommended else role)),
               "trial": fmt_number(int(r["trial"]))}
        if "count" in fin:
            row["evaluations"] = fmt_number(int(r["count"])) if r["source"] == "best" else ""
        for v in study.variables:
            u = unit(study, v.name)
            row[u.label(v.name)] = fmt_value(r[v.name], u) if is_number_col(study, v.name) else str(r[v.name])
        for o in study.objectives:
            u = unit(study, o.label)
            if estimate_of(o) in ("grid", "exact"):  # not resampled: the run's own value
                row[u.label(o.label)] = fmt_value(r[o.label], u)
            else:
                row[u.label(o.label)] = fmt_mean_se(r[o.label], r[derived.stderr(o.label)], u)
        row["feasible"] = "yes" if bool(r.get("feasible", True)) else "no"
        if "verified" in fin:
            row["verification"] = str(r.get("verification", "")) or ("verified" if bool(r["verified"]) else "failed")
        if r["source"] == "best":
            d = fa.dominated_by.get(i, [])
            row["dominated by (beyond noise)"] = ", ".join(f"trial {t}" for t in d) if d else "none"
        else:
            row["dominated by (beyond noise)"] = ", ".join(f"trial {int(x['trial'])}" for x, c in fa.vs_ref
                                                           if c.verdict == "dominates") or "none"
        rows.append(row)
    return pd.DataFrame(rows)
