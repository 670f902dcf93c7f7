"""The report of a study with robust measures (``robust:`` blocks, parasynth.measures.robustness): nominal
and robust values side by side for the chosen designs, the loss from nominal to robust, the
standard error of every robust value that has one, and for each robust objective the nominal
optimum against the robust optimum.

* :func:`robust_table` -- one row per chosen design (the robust optimum and the nominal optimum
  of each robust objective, the front's designs, the reference): its design values and, for
  each robust objective or constraint, its nominal value, its robust value (``± se``) and the
  loss (nominal minus robust, and in per cent of the nominal);
* :func:`robust_verdict` -- for each robust objective: how much the nominal optimum (the design
  best by the nominal value) loses under scatter, and whether the robust optimum (best by the
  robust value) loses less and ends better, beyond the standard errors;
* :func:`robust_sections` -- the sections for :mod:`parasynth.report.render`.

Reads the run only as :class:`parasynth.study.rundir.Run` (the results table's
``<label>_nominal`` and ``<label>_robust_se`` columns).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..measures.display import fmt_mean_se, fmt_number, fmt_quantity
from ..study.rundir import Run, design_key
from .analysis import Analysis
from .tables import unit
from ..common import columns as derived

__all__ = ["robust_items", "robust_table", "robust_verdict", "robust_sections"]


def robust_items(study) -> list:
    """The objectives and design constraints of ``study`` that carry a robust block."""
    return [x for x in (*study.objectives, *study.constraints) if getattr(x, "robust", None) is not None]


def _ok(run: Run) -> pd.DataFrame:
    t = run.table
    return t[(t["status"] == "ok")].copy()


def _nominally_feasible(study, df) -> np.ndarray:
    """(n,) bool: every design constraint met by its nominal value (a robust constraint's
    ``<label>_nominal``, the others' own value)."""
    ok = (df["status"] == "ok").to_numpy().copy()
    for c in study.constraints:
        col = derived.nominal(c.label) if getattr(c, "robust", None) is not None else c.label
        v = df[col].to_numpy(float)
        with np.errstate(invalid="ignore"):
            if c.min is not None:
                ok &= v >= c.min
            if c.max is not None:
                ok &= v <= c.max
    return ok


def _best(study, df, goal, col, nominal: bool = False):
    """The design best by column ``col`` among the feasible ones: feasible as run (robust
    constraints by their robust value, chance constraints by their probability), or with
    ``nominal`` by the nominal values of the constraints."""
    feas = _nominally_feasible(study, df) if nominal else df["feasible"].astype(bool).to_numpy()
    d = df[feas & np.isfinite(df[col].to_numpy(float))]
    if not len(d):
        return None
    i = d[col].astype(float).idxmax() if goal == "maximize" else d[col].astype(float).idxmin()
    return d.loc[i]


def _kind(name: str) -> str:
    """The quantity kind of a tolerance: an angle for joint axes and angular parameters."""
    return "angle" if name == "axis_tolerance" or name.endswith(("_angles", "_rotation", "_angle")) else "length"


def _describe(item) -> str:
    rm = item.robust
    tols = ", ".join(f"{k} ±{fmt_quantity(v, _kind(k))}" for k, v in (*rm.param_tolerances, *rm.leg_tolerances) if v)
    p = getattr(item, "probability", None)
    if p is not None:
        what = f"the fraction of draws within the bound, at least {fmt_number(p)} (a chance constraint)"
    else:
        what = {"mean": "the mean", "worst": "the least favourable draw",
                "first_order": "the nominal value worsened by sum |sensitivity| × tolerance (first order)"
                }.get(rm.statistic, f"the {fmt_number(100 * rm.level)} % quantile" if rm.level is not None else "")
    draws = "" if rm.statistic == "first_order" and p is None else f" over {rm.samples} scatter draws (seed {rm.seed})"
    return f"**{item.label}** ({item.name}): {what}{draws}; tolerances {tols}."


def _loss(nominal, robust):
    d = float(nominal) - float(robust)
    pct = 100.0 * d / abs(float(nominal)) if nominal and np.isfinite(nominal) else math.nan
    return d, pct


def robust_table(run: Run, a: Analysis) -> pd.DataFrame:
    """The chosen designs with nominal and robust values side by side (display strings)."""
    study = run.study
    items = robust_items(study)
    df = _ok(run)
    picks = []
    for o in study.objectives:
        if getattr(o, "robust", None) is None:
            continue
        for role, col, nom in ((f"robust optimum of {o.label}", o.label, False),
                               (f"nominal optimum of {o.label}", derived.nominal(o.label), True)):
            r = _best(study, df[df["source"] == "run"], o.goal, col, nom)
            if r is not None:
                picks.append((role, r))
    for _, r in a.front.head(6).iterrows():
        picks.append(("front", r))
    if a.ref_row is not None:
        picks.append(("reference", a.ref_row))
    seen, rows = {}, []
    for role, r in picks:
        key = design_key(study, r)
        if key in seen:
            if role not in rows[seen[key]]["role"]:
                rows[seen[key]]["role"] += f"; {role}"
            continue
        row = {"role": role}
        for v in study.variables:
            row[v.name] = fmt_quantity(r[v.name], unit(study, v.name)) if isinstance(r[v.name], (int, float, np.floating)) \
                else str(r[v.name])
        for x in items:
            u = unit(study, derived.nominal(x.label))
            ur = unit(study, x.label)
            nom, rob = r.get(derived.nominal(x.label), np.nan), r.get(x.label, np.nan)
            se = r.get(derived.robust_se(x.label), np.nan)
            row[f"{x.label} nominal"] = fmt_quantity(nom, u)
            row[f"{x.label} robust"] = (fmt_mean_se(rob, se, ur, with_unit=True) if np.isfinite(se)
                                        else fmt_quantity(rob, ur))
            if getattr(x, "probability", None) is None:
                d, pct = _loss(nom, rob)
                row[f"{x.label} loss"] = f"{fmt_quantity(d, u)} ({fmt_number(pct, 3)} %)" if np.isfinite(d) else ""
        seen[key] = len(rows)
        rows.append(row)
    return pd.DataFrame(rows)


def robust_verdict(run: Run) -> list[str]:
    """One paragraph per robust objective: the nominal optimum's loss under scatter against the
    robust optimum's, and whether the robust optimum is better under scatter beyond the
    standard errors (or by the same design)."""
    study = run.study
    df = _ok(run)
    df = df[df["source"] == "run"]
    out = []
    for o in study.objectives:
        if getattr(o, "robust", None) is None:
            continue
        rb = _best(study, df, o.goal, o.label)
        nb = _best(study, df, o.goal, derived.nominal(o.label), nominal=True)
        if rb is None or nb is None:
            continue
        u = unit(study, o.label)
        sgn = 1.0 if o.goal == "maximize" else -1.0

        def desc(r):
            vals = ", ".join(fmt_quantity(r[v.name], unit(study, v.name)) if isinstance(r[v.name], (int, float, np.floating))
                             else str(r[v.name]) for v in study.variables)
            d, pct = _loss(r[derived.nominal(o.label)], r[o.label])
            se = r.get(derived.robust_se(o.label), np.nan)
            return vals, fmt_quantity(r[derived.nominal(o.label)], u), fmt_mean_se(r[o.label], se, u, with_unit=True) \
                if np.isfinite(se) else fmt_quantity(r[o.label], u), d, pct

        nv, nn, nr, nd, npct = desc(nb)
        text = (f"**{o.label}**: the nominal optimum ({nv}, the best nominal value among the designs that meet "
                f"every constraint nominally) has {nn} nominally and {nr} under scatter: it loses "
                f"{fmt_quantity(sgn * nd, u)} ({fmt_number(sgn * npct, 3)} %). ")
        fails = [f"{c.label} holds in {fmt_number(100 * float(nb[c.label]), 3)} % of the draws (at least "
                 f"{fmt_number(100 * c.probability, 3)} % asked)"
                 for c in study.constraints if getattr(c, "probability", None) is not None
                 and float(nb[c.label]) < c.probability]
        fails += [f"{c.label} misses its bound under scatter" for c in study.constraints
                  if getattr(c, "robust", None) is not None and getattr(c, "probability", None) is None
                  and float(nb.get(derived.margin(c.label), 0.0)) < 0]
        if fails:
            text += "Under scatter it is not feasible: " + "; ".join(fails) + ". "
        if design_key(study, rb) == design_key(study, nb):
            text += "The robust optimum is the same design: the scatter does not change the choice."
        else:
            rv, rn, rr, rd, rpct = desc(rb)
            diff = float(rb[o.label]) - float(nb[o.label])
            se = math.hypot(float(np.nan_to_num(rb.get(derived.robust_se(o.label), 0.0))),
                            float(np.nan_to_num(nb.get(derived.robust_se(o.label), 0.0))))
            beyond = se > 0 and abs(diff) > 2.0 * se
            noise = (" (beyond twice the combined standard error)." if beyond else
                     " (within twice the combined standard error: not a difference the draws resolve)."
                     if se > 0 else ".")
            if fails:
                text += (f"The robust optimum ({rv}) is feasible as built: it has {rn} nominally and {rr} under "
                         f"scatter (it loses {fmt_quantity(sgn * rd, u)}, {fmt_number(sgn * rpct, 3)} %); keeping the "
                         f"constraints as built costs {fmt_quantity(abs(diff), u)} of {o.label} under scatter against "
                         f"the nominal optimum" + noise)
            else:
                text += (f"The robust optimum ({rv}) has {rn} nominally and {rr} under scatter: it loses "
                         f"{fmt_quantity(sgn * rd, u)} ({fmt_number(sgn * rpct, 3)} %), "
                         f"{'less' if sgn * rd < sgn * nd else 'more'} than the nominal optimum, and ends "
                         f"{fmt_quantity(abs(diff), u)} {'better' if sgn * diff > 0 else 'worse'} under scatter"
                         + noise)
        out.append(text)
    return out


def robust_sections(run: Run, a: Analysis) -> list[tuple[str, str, pd.DataFrame | None]]:
    """The robustness section (title, text, table) of a study with robust measures; none
    otherwise."""
    study = run.study
    items = robust_items(study)
    if not items:
        return []
    text = ("Measures evaluated under manufacturing scatter (parameters drawn within their tolerances and the "
            "description rebuilt; per-leg errors evaluated on the mechanism as built: actuators held at their "
            "nominal values, the actual pose from the perturbed closure). The same draws serve every design.\n\n"
            + "\n\n".join(_describe(x) for x in items))
    verdict = robust_verdict(run)
    if verdict:
        text += "\n\n" + "\n\n".join(verdict)
    text += ("\n\nThe table: nominal and robust values of the chosen designs, the loss from nominal to robust, "
             "and the standard error of each robust value that has one (± over the scatter draws).")
    return [("Robustness under manufacturing scatter", text, robust_table(run, a))]
