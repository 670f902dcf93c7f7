"""Warnings a designer should act on, shared by the report and the terminal summary.

* a recommended or best design on a design variable's bound (within ``BOUND_TOL`` of the
  variable's range): the optimum may lie beyond the box, widen the variable's bounds;
* a recommended or best design near a bound (within ``NEAR_BOUND_TOL``) whose objectives
  improve towards it (a local trend fitted to the nearest designs of the run, see
  :func:`near_bound_warnings`): a global optimiser stops near an optimum on a bound, not at it;
* a design whose feasible workspace reaches the faces of the sampled box (feasible samples
  within ``FACE_TOL`` of a coordinate's range from a face, more than ``FACE_SHARE`` of them):
  the box cuts the workspace, so volumes and extents measure the box; widen
  ``evaluation.ranges``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..measures.display import fmt_number, fmt_quantity, quantity_unit, reference_name
from ..measures.objectives import _WS_SETTINGS, workspace_of
from ..measures.objectives import get as get_measure
from ..study.rundir import design_key, design_mechanism, measure_settings

__all__ = ["design_roles", "design_warnings", "bound_warnings", "near_bound_warnings", "face_warnings", "BOUND_TOL",
           "NEAR_BOUND_TOL", "TREND_NEIGHBOURS", "FACE_TOL", "FACE_SHARE"]

#: A design lies on a bound when within this share of the variable's range from it.
BOUND_TOL = 0.01
#: A design lies near a bound when within this share of the variable's range from it; the report
#: warns when the objectives improve towards the bound there (:func:`near_bound_warnings`).
NEAR_BOUND_TOL = 0.05
#: Designs nearest to the checked one (unit cube of the numeric variables) the local trend is
#: fitted to (fewer when the run has fewer feasible designs).
TREND_NEIGHBOURS = 12
#: Width of the layer at each face of the sampled box, as a share of the coordinate's range.
FACE_TOL = 0.01
#: Share of the feasible samples in the face layers above which the report warns. A feasible
#: set well inside the box puts none there; one that fills a box uniformly puts about
#: 2 * FACE_TOL per coordinate there.
FACE_SHARE = 0.005


def _named_designs(study, knee, front) -> list[tuple[str, object]]:
    """(name, row) of the designs the report recommends: the knee (or the best design) and
    the best design of each objective on the front."""
    out = []
    several = len(study.objectives) > 1
    if knee is not None:
        out.append((f"the recommended design (trial {int(knee['trial'])})", knee))
    if several and front is not None and len(front):
        for o in study.objectives:
            col = front[o.label].astype(float)
            i = col.idxmax() if o.goal == "maximize" else col.idxmin()
            row = front.loc[i]
            if knee is not None and int(row["trial"]) == int(knee["trial"]):
                continue
            out.append((f"the best {o.label} design (trial {int(row['trial'])})", row))
    return out


def bound_warnings(study, knee_row, front: pd.DataFrame | None = None, tol: float = BOUND_TOL) -> list[str]:
    """A recommended (``knee_row``) or best design (of each objective on ``front``) with a
    variable within ``tol`` of its range from a bound."""
    out = []
    for name, row in _named_designs(study, knee_row, front):
        hits = []
        for v in study.variables:
            if v.type == "categorical" or v.low is None or v.high is None or v.name not in row:
                continue
            x = float(row[v.name])
            u = quantity_unit(study, v.name)
            if v.log and v.low > 0 and x > 0:
                s = (np.log(x) - np.log(v.low)) / (np.log(v.high) - np.log(v.low))
            else:
                s = (x - v.low) / (v.high - v.low)
            if s <= tol:
                hits.append(f"{v.name} = {fmt_quantity(x, u)} at its lower bound {fmt_quantity(v.low, u)} "
                            f"({study.variable_path(v.name)}.low)")
            elif s >= 1 - tol:
                hits.append(f"{v.name} = {fmt_quantity(x, u)} at its upper bound {fmt_quantity(v.high, u)} "
                            f"({study.variable_path(v.name)}.high)")
        if hits:
            out.append(f"{name} lies on a bound of the design variables: " + "; ".join(hits)
                       + ". The best design may lie beyond it: widen the bound if the design allows it.")
    return out


def _share(v, x: float) -> float:
    if v.log and v.low > 0 and x > 0:
        return (np.log(x) - np.log(v.low)) / (np.log(v.high) - np.log(v.low))
    return (x - v.low) / (v.high - v.low)


def _trend_towards(study, runs: pd.DataFrame, row, v, side: int, numeric: list) -> list[str] | None:
    """The objectives (labels) that a local trend says improve from ``row`` towards the bound
    of ``v`` on ``side`` (-1 lower, +1 upper); None when the trend cannot be fitted.

    The trend: over the :data:`TREND_NEIGHBOURS` feasible designs nearest to ``row`` (unit
    cube of the numeric variables), least squares of each objective (as "larger is better") on
    the numeric variables, with a square term in ``v`` when there are enough designs; an
    objective improves towards the bound when the fitted value at the bound is better than at
    the design and the fitted slope at the design points the same way."""
    ok = runs[(runs["status"] == "ok") & runs["feasible"].astype(bool)]
    ok = ok.dropna(subset=[w.name for w in numeric] + [o.label for o in study.objectives])
    if len(ok) < len(numeric) + 2:
        return None
    U = np.column_stack([[_share(w, float(x)) for x in ok[w.name]] for w in numeric])
    u0 = np.array([_share(w, float(row[w.name])) for w in numeric])
    near = np.argsort(np.linalg.norm(U - u0, axis=1), kind="stable")[:max(TREND_NEIGHBOURS, len(numeric) + 2)]
    U = U[near] - u0
    j = numeric.index(v)
    quad = len(near) >= len(numeric) + 4
    A = np.column_stack([np.ones(len(U)), U] + ([U[:, j] ** 2] if quad else []))
    ub = (0.0 if side < 0 else 1.0) - u0[j]  # the bound, relative to the design
    better = []
    for o in study.objectives:
        h = ok[o.label].to_numpy(float)[near] * (1.0 if o.goal == "maximize" else -1.0)
        coef, *_ = np.linalg.lstsq(A, h, rcond=None)
        b, c = coef[1 + j], (coef[-1] if quad else 0.0)
        slope_towards = b * side
        gain = b * ub + c * ub ** 2  # fitted value at the bound minus at the design
        if slope_towards > 0 and gain > 0:
            better.append(o.label)
    return better


def near_bound_warnings(study, knee_row, front: pd.DataFrame | None = None, runs: pd.DataFrame | None = None,
                        tol: float = NEAR_BOUND_TOL, on_bound: float = BOUND_TOL) -> list[str]:
    """A recommended or best design with a variable within ``tol`` of its range from a bound
    (but farther than ``on_bound``: :func:`bound_warnings` speaks of those) where every objective
    improves towards the bound by the local trend of the run's designs ``runs``
    (:func:`_trend_towards`)."""
    if runs is None or not len(runs):
        return []
    numeric = [w for w in study.variables if w.type != "categorical" and w.low is not None and w.high is not None
               and w.name in runs]
    out = []
    for name, row in _named_designs(study, knee_row, front):
        hits = []
        for v in numeric:
            if v.name not in row or pd.isna(row[v.name]):
                continue
            x = float(row[v.name])
            s = _share(v, x)
            side = -1 if s <= tol else (1 if s >= 1 - tol else 0)
            if side == 0 or min(s, 1 - s) <= on_bound:
                continue
            better = _trend_towards(study, runs, row, v, side, numeric)
            if better is None or len(better) < len(study.objectives):
                continue
            u = quantity_unit(study, v.name)
            bound, key = (v.low, "low") if side < 0 else (v.high, "high")
            hits.append(f"{v.name} = {fmt_quantity(x, u)} is {100 * min(s, 1 - s):.1f} % of its range from its "
                        f"{'lower' if side < 0 else 'upper'} bound {fmt_quantity(bound, u)} "
                        f"({study.variable_path(v.name)}.{key}) and {', '.join(better)} improve"
                        f"{'s' if len(better) == 1 else ''} towards it")
        if hits:
            out.append(f"{name} lies near a bound of the design variables: " + "; ".join(hits)
                       + " (a local trend of the nearest designs). The optimum may lie at or beyond the bound: widen "
                       "it if the design allows it, or refine the design (optimizer.polish).")
    return out


def _uses_workspace(study) -> object | None:
    """The first objective or design constraint that samples the workspace, or None."""
    for m in list(study.objectives) + list(study.constraints):
        if "ranges" in get_measure(m.name).settings:
            return m
    return None


def face_fraction_of(study, values: dict) -> dict | None:
    """Face shares of the workspace of the design ``values`` with the study's evaluation
    settings (as its first workspace measure sees them): ``{"total": share, "z high": ...}``;
    None when the study samples no workspace or the design cannot be built."""
    m = _uses_workspace(study)
    if m is None:
        return None
    try:
        mech = design_mechanism(study, dict(values))
        kw = {k: x for k, x in measure_settings(study, m.name, m.settings).items() if k in _WS_SETTINGS}
        ws = workspace_of(mech, **kw)
    except (ValueError, ArithmeticError):
        return None
    if ws.n_feasible == 0:
        return None
    return {"total": ws.face_fraction(FACE_TOL), **ws.face_fractions(FACE_TOL)}


def face_warnings(study, knee_row, share: float = FACE_SHARE) -> list[str]:
    """The recommended design (``knee_row``) or the reference design whose feasible samples
    reach the faces of the sampled box."""
    if _uses_workspace(study) is None:
        return []
    designs = []
    knee = knee_row
    if knee is not None:
        designs.append((f"the recommended design (trial {int(knee['trial'])})",
                        {v.name: knee[v.name] for v in study.variables}))
    if study.reference:
        designs.append((reference_name(study), dict(study.reference)))
    out = []
    for name, values in designs:
        f = face_fraction_of(study, values)
        if f is None or f["total"] <= share:
            continue
        faces = sorted(((k, x) for k, x in f.items() if k != "total" and x > 0), key=lambda kx: -kx[1])
        where = ", ".join(f"{k} {fmt_number(100 * x, 2)} %" for k, x in faces[:4])
        out.append(f"the workspace of {name} reaches the faces of the sampled box: {fmt_number(100 * f['total'], 2)} % "
                   f"of its feasible samples lie within {fmt_number(100 * FACE_TOL)} % of a coordinate's range "
                   f"from a face ({where}). The box cuts the workspace, so its volume and extents measure the box "
                   f"too: widen evaluation.ranges.")
    return out


def design_warnings(study, knee_row, front: pd.DataFrame | None, runs: pd.DataFrame | None = None) -> list[str]:
    """Every warning of :mod:`parasynth.report.checks` for the recommended design
    ``knee_row``, the non-dominated ``front`` and the designs ``runs`` of a run (a failing check
    is skipped: a warning must not cost the report)."""
    out = []
    for check in (lambda: bound_warnings(study, knee_row, front), lambda: near_bound_warnings(study, knee_row, front, runs),
                  lambda: face_warnings(study, knee_row)):
        try:
            out += check()
        except Exception:  # noqa: BLE001 - best effort
            continue
    return out


def design_roles(study, rows: pd.DataFrame, knee_key=None, front: pd.DataFrame | None = None) -> list[str]:
    """Why each row of a set of front designs is listed: ``recommended`` (the recommended design
    of several objectives), ``best <label>`` (the best value of that objective over ``front``, the
    whole run's non-dominated designs; without ``front``, over ``rows``), ``best <label> of those
    listed`` (best among ``rows`` but not over ``front``), else ``on the front``. One objective:
    ``best <label>`` for the run's best row, ``rank k`` for the others."""
    objs = study.objectives
    out = []
    best_of, best_listed = {}, {}
    for o in objs:
        col = rows[o.label].astype(float)
        if len(col) and col.notna().any():
            best_listed[o.label] = col.idxmax() if o.goal == "maximize" else col.idxmin()
        if front is not None and len(front) and front[o.label].notna().any():
            fc = front[o.label].astype(float)
            best_of[o.label] = float(fc.max() if o.goal == "maximize" else fc.min())
    for rank, (i, r) in enumerate(rows.iterrows(), start=1):
        tags = []
        if len(objs) > 1 and knee_key is not None and design_key(study, r) == knee_key:
            tags.append("recommended")
        run_best, listed_best = [], []
        for o in objs:
            if best_listed.get(o.label) != i:
                continue
            if front is None or (o.label in best_of and float(r[o.label]) == best_of[o.label]):
                run_best.append(o.label)
            else:
                listed_best.append(o.label)
        if run_best:
            tags.append("best " + " and ".join(run_best))
        if listed_best:
            tags.append("best " + " and ".join(listed_best) + " of those listed")
        if not tags:
            tags.append("on the front" if len(objs) > 1 else f"rank {rank}")
        out.append(", ".join(tags))
    return out
