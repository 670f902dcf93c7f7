"""What the report says: its sections (title, text, table) built from a loaded run and its
:class:`~parasynth.report.analysis.Analysis`, shared by the HTML and Markdown templates.
Text marks bold as ``**...**`` and paragraphs by blank lines; tables hold display strings."""

from __future__ import annotations

import re

import importlib.metadata as md
import platform
import time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..measures.display import fmt_mean_se, fmt_number, fmt_quantity, reference_name
from ..measures.objectives import usable_workspace_of
from ..study.rundir import Run, design_key, design_mechanism, estimate_of, measure_settings
from .analysis import Analysis, FinalAnalysis
from .summary import reevaluated_text
from .tables import display_table, final_display_table
from .verdict import recommendation_section
from .tables import is_number_col as _is_number_col
from .tables import unit as _unit
from ..common import columns as derived

__all__ = ["Section", "Table", "sections", "INDEX_MEANINGS", "SHARE_MEASURES", "reading_text", "share_text"]

_MARGIN = ("the smallest singular value of the mechanism's wrench system with every actuation row of unit length "
           "and the constraint rows normalised (moments divided by the model's length scale): 0 at a singularity, "
           "where some platform motion is no longer held by the actuators and joints, at most 1 (wrenches mutually "
           "orthogonal); like the inverse of a condition number, 0.05 means the weakest direction is held about 20 "
           "times more weakly than by orthogonal wrenches")
_LTI = ("the local transmission index is the smaller of the input and output transmission indices, the cosines of "
        "the pressure angles between the force a leg transmits and the motion it drives: 1 is transmission without "
        "loss, 0 a singularity, and 0.7 (pressure angles within about 45.6 deg) the usual threshold of good "
        "transmission")

#: The definitions several meanings below share: given once in a report's reading paragraph.
_DEFINITIONS = (_MARGIN, _LTI)

#: One sentence on the meaning and the scale of each unitless measure, shown where the report
#: first names the study's measures (the summary). Every registered measure of unit "1" has one
#: (a test checks it).
INDEX_MEANINGS = {
    "singularity_margin_min": f"the smallest (or the set quantile of the) singularity margin over the workspace "
                              f"samples; the singularity margin is {_MARGIN}.",
    "home_singularity_margin": f"the singularity margin at the home pose, {_MARGIN}.",
    "singularity_margin": f"a floor on the singularity margin of every pose counted, {_MARGIN}.",
    "min_lti": f"the smallest (or the set quantile of the) local transmission index over the workspace samples; {_LTI}.",
    "mean_lti": f"the mean local transmission index over the workspace samples; {_LTI}.",
    "gci": "the global conditioning index, the mean over the workspace of the inverse condition number of the "
           "dimensionally homogeneous actuator Jacobian: 1 would be isotropic everywhere (every platform direction "
           "as easy to drive), near 0 the workspace lies close to singularities.",
    "workspace_fraction": "the share of the sampled task box that is feasible, from 0 (none) to 1 (all of it).",
    "workspace_face_fraction": "the share of the feasible samples within 1 % of a face of the sampled box, from 0 "
                               "to 1: above a few per cent the box cuts the workspace.",
    "xy_isotropy": "the smaller of the workspace's X and Y extents over the larger, from 0 to 1 (as wide as long).",
    "usable_workspace_fraction": "the usable volume over the feasible volume of the same grid, from 0 to 1: 0.5 "
                                 "means that half of the workspace lies beyond a singularity the platform cannot "
                                 "cross from home.",
    "force_decoupling_ratio": "the largest change of a driving-leg force per newton of grinding force: 0 is fully "
                              "decoupled, 1 a change as large as the grinding force itself.",
    "task_coverage": "the share of the task's required poses the design reaches within every limit and floor, "
                     "from 0 to 1 (1: every pose).",
    "task_margin_min": f"the smallest singularity margin over the task's feasible poses; the singularity margin is "
                       f"{_MARGIN}.",
    "task_condition_max": "the largest condition number of the actuator Jacobian over the task's poses, in SI units "
                          "(not made homogeneous): 1 is isotropic, it grows without bound towards a singularity; "
                          "its value depends on the units, so compare it only within one study.",
    "task_lti_min": f"the smallest local transmission index over the task's feasible poses; {_LTI}.",
    "task_path_followed": "the share of the task's path followed before the first sample that is infeasible, "
                          "crosses a singularity or changes the assembly mode, from 0 to 1 (1: all of it).",
}

#: Measures whose value is a share of a whole: the verdict states how the designs divide.
SHARE_MEASURES = ("usable_workspace_fraction", "workspace_fraction")


@dataclass
class Table:
    """A table as the report shows it: column names and rows of display strings."""

    columns: list[str]
    rows: list[list[str]]

    @classmethod
    def of(cls, df: pd.DataFrame) -> "Table":
        return cls([str(c) for c in df.columns], [[_cell(x) for x in r] for r in df.itertuples(index=False)])


def _cell(x) -> str:
    if isinstance(x, (float, np.floating)):
        return "" if np.isnan(x) else fmt_number(x)
    return str(x)


@dataclass
class Section:
    """A section of the report: ``text`` with ``**bold**`` and blank lines between
    paragraphs; ``table`` (None or empty: no table); ``study_yaml``: the study file as run is
    shown after the text."""

    title: str
    text: str
    table: Table | None = None
    study_yaml: str | None = None


def sections(run: Run, a: Analysis) -> list[Section]:
    """The report's sections in order; the last one (study file and software) goes after
    the figures."""
    out = []
    for title, text, table in _sections(run, a):
        t = Table.of(table) if table is not None and len(table) else None
        out.append(Section(title, text, t))
    out[-1].study_yaml = run.study.to_yaml()
    return out


def _versions() -> dict:
    out = {"python": platform.python_version()}
    for pkg in ("parasynth", "numpy", "scipy", "pandas", "optuna", "nlopt", "cvxpy", "matplotlib", "plotly"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    return out


def _sections(run: Run, a: Analysis) -> list[tuple[str, str, pd.DataFrame | None]]:
    """(title, text, table) triples shared by the HTML and Markdown renderers."""
    study, t = run.study, run.table
    runs, front = a.runs, a.front
    sec = []
    n_ok = int((runs["status"] == "ok").sum())
    n_feas = int((runs["feasible"].astype(bool) & (runs["status"] == "ok")).sum())
    ev = study.evaluation
    opt = study.optimizer
    elapsed = float(runs["time_s"].sum()) if len(runs) else 0.0
    mech = f"the {study.structures.motion} structures" if study.structures is not None else study.mechanism
    text = (f"Mechanism **{mech}**; optimiser **{opt.kind}** "
            f"({opt.algorithm or 'default'}); budget {run.expected or opt.maxeval or opt.n_trials or '-'}; "
            f"evaluation: {ev['method']} sampling, {ev['n']} samples, seed {ev['seed']}. "
            f"{len(runs)} designs evaluated ({n_ok} completed, {n_feas} feasible, "
            f"{len(runs) - n_ok} failed); evaluation time {elapsed:.1f} s.")
    if run.partial:
        text = f"**PARTIAL REPORT: {run.partial_reason}.** " + text
    if study.spec.description:
        text = study.spec.description.strip() + "\n\n" + text
    reading = reading_text(study)
    if reading:
        text += "\n\n" + reading
    sec.append(recommendation_section(run, a))
    sec.append(("Summary", text, None))
    if a.warnings:
        sec.append(("Warnings", "\n\n".join("**Warning:** " + w[:1].upper() + w[1:] for w in a.warnings), None))
    if len(study.objectives) > 1 and a.hv is not None and len(front) >= 2:
        refs = []
        for o, x in zip(study.objectives, a.hv_ref):
            val = x if o.goal == "minimize" else -x
            refs.append(f"{o.label} {fmt_quantity(val, _unit(study, o.label))}")
        units = [_unit(study, o.label) for o in study.objectives]
        sym = " x ".join(u.symbol for u in units if u.symbol)
        hv_disp = a.hv * float(np.prod([u.factor for u in units]))
        sec.append(("Hypervolume", f"Hypervolume of the feasible non-dominated set: {fmt_number(a.hv_fraction, 3)} "
                    f"of the box between the ideal point and the reference point (normalised: 1 would be a front "
                    f"at the ideal point; {fmt_number(hv_disp)}{' ' + sym if sym else ''} in display units). "
                    f"Reference point: the worst feasible value of each objective plus 10 % of its range, far outliers "
                    f"left out (beyond 3 interquartile ranges outside the quartiles): "
                    + ", ".join(refs) + ". It measures how much of the objective space the front covers; "
                    "compare it between runs of this study only.", None))
    if len(front):
        k = a.knee_row
        n_dup = int((front["count"] > 1).sum()) if "count" in front else 0
        txt = (f"{len(front)} distinct non-dominated feasible designs"
               + (f" ({n_dup} of them evaluated more than once: column evaluations)" if n_dup else "")
               + (". " + _recommended_words(a))
               + f": trial {int(k['trial'])}: " + ", ".join(_fmt_design(study, k))
               + " (single sample)")
        fa = a.final
        if fa is not None and fa.knee is not None:
            kr = fa.knee
            txt += ("; re-evaluated: " + ", ".join(f"{o.label} = {reevaluated_text(study, o, kr)}" for o in study.objectives))
        txt += "."
        if fa is not None:
            keys = {design_key(study, r): i for i, r in fa.best.iterrows()}
            notes = []
            for _, r in front.iterrows():
                i = keys.get(design_key(study, r))
                if i is not None and fa.dominated_by.get(i):
                    notes.append(f"trial {int(r['trial'])} (by " + ", ".join(f"trial {t}" for t in fa.dominated_by[i]) + ")")
            if notes:
                txt += (" On the re-evaluated values some of these designs are dominated beyond noise: "
                        + "; ".join(notes) + ".")
        if fa is not None and fa.unverified is not None and len(fa.unverified):
            failed = {design_key(study, r) for _, r in fa.unverified.iterrows()}
            names = [f"trial {int(r['trial'])}" for _, r in front.iterrows() if design_key(study, r) in failed]
            if names:
                txt += (" Of these, " + ", ".join(names) + (" fails" if len(names) == 1 else " fail")
                        + " verification (see Recommendation): not to be built as designed.")
        if fa is not None and fa.knee_missing:
            txt += (" final.csv does not hold this design (it was written before the run's last designs): its "
                    "re-evaluated values are not known; run the study again with --resume to redo the final stage.")
        sec.append(("Non-dominated designs", txt, display_table(study, front)))
    else:
        sec.append(("Non-dominated designs", "No feasible design was found.", None))
    shares = share_text(run, a)
    if a.ref_row is not None:
        sec.append((reference_name(study, capital=True), _paper_text(run, a) + ("\n\n" + shares if shares else ""),
                    display_table(study, t[t["source"] == "reference"])))
    elif shares and len(front):
        title, txt, table = sec[-1]
        sec[-1] = (title, txt + "\n\n" + shares, table)
    fa = a.final
    if fa is not None:
        fin = fa.table
        reps = int(fin["repeats"].max()) if "repeats" in fin and len(fin) else 0
        how = (f"Mean ± standard error over {reps} seed{'s' if reps != 1 else ''} with {int(fin['samples'].max())} samples each"
               if reps else "The run's own values (no objective or constraint depends on a seed)")
        sec.append(("Re-evaluation of the best designs",
                    f"{how}, for the best designs, the recommended design, the designs that dominate "
                    f"{reference_name(study)} on single samples by the largest normalised margin, the designs the "
                    f"verification walked (docs/verification.md) and {reference_name(study)}. A design is "
                    f"dominated beyond noise when another is better by more than {fmt_number(a.noise_z)} combined "
                    f"standard errors on some objective and worse by as much on none." + grid_note(run, a),
                    final_display_table(study, fa)))
    elif run.final is not None and len(run.final):
        sec.append(("Re-evaluation of the best designs", "final.csv (columns as written by the run):", run.final))
    pol = polish_section(run)
    if pol is not None:
        sec.append(pol)
    if study.constraints or (runs["status"] != "ok").any():
        rows = []
        for c in study.constraints:
            m = runs[derived.margin(c.label)]
            u = _unit(study, c.label)
            bounds = " and ".join(x for x in ((f"min {fmt_quantity(c.min, u)}" if c.min is not None else ""),
                                              (f"max {fmt_quantity(c.max, u)}" if c.max is not None else "")) if x)
            rows.append({"constraint": c.label, "measure": c.name, "bounds": bounds,
                         "violated": int((m < 0).sum()),
                         "smallest margin": fmt_quantity(float(m.min()), u) if len(m) else ""})
        failed = runs[runs["status"] != "ok"]
        txt = f"{len(failed)} designs failed to evaluate."
        if len(failed):
            errs = failed["error"].value_counts().head(5)
            txt += " Most frequent errors: " + "; ".join(f"{e} ({n}x)" for e, n in errs.items())
        sec.append(("Constraint violations", txt, pd.DataFrame(rows) if rows else None))
    v = _versions()
    sec.append(("Study and software", "Software: " + ", ".join(f"{k} {x}" for k, x in v.items())
                + f". Report written {time.strftime('%Y-%m-%d %H:%M:%S')}. Study file as run:", None))
    return sec


def polish_section(run: Run) -> tuple[str, str, pd.DataFrame | None] | None:
    """The "Polish" section of a run with ``optimizer.polish`` (its ``polish.json``): which
    design was polished, by which method and budget, where it moved and how each objective
    changed."""
    info, study = run.polish, run.study
    if not info or not info.get("start"):
        return None
    start, pol = info["start"], info.get("polished")
    head = (f"The {'best' if len(study.objectives) == 1 else 'recommended'} design of the global search "
            f"(trial {start['trial']}) was polished by a local {info['method'].upper()} search within the bounds "
            f"({info.get('evaluations', 0)} of {info['budget']} designs, trials from {info['first_trial']}).")
    if info.get("status") != "done":
        return ("Polish", head + " The polish was interrupted: resume the run to finish it.", None)
    if pol is None:
        return ("Polish", head + " " + (info.get("note") or "No better design was found") + ".", None)
    rows = []
    for name, m in info.get("moved", {}).items():
        u = _unit(study, name)
        rows.append({"variable": name, "start": fmt_quantity(m["from"], u), "polished": fmt_quantity(m["to"], u),
                     "moved": fmt_quantity(m["to"] - m["from"], u),
                     "share of range": f"{100 * m['share_of_range']:.2g} %"})
    changes = []
    for o in study.objectives:
        u = _unit(study, o.label)
        changes.append(f"{o.label} {fmt_quantity(start['objectives'][o.label], u)} -> "
                       f"{fmt_quantity(pol['objectives'][o.label], u)}")
    return ("Polish", head + f" Polished design: trial {pol['trial']}; " + ", ".join(changes) + ".",
            pd.DataFrame(rows) if rows else None)


def grid_note(run: Run, a: Analysis) -> str:
    """A sentence on the objectives exact on their grid (:meth:`Measure.estimate_of` ``grid``):
    not resampled, with the grid's cells and cell size for the recommended design, the
    resolution a finer grid could move them by (about a cell at each boundary)."""
    study = run.study
    grids = [o for o in study.objectives if estimate_of(o) == "grid"]
    if not grids or a.knee_row is None:
        return ""
    o = grids[0]
    try:
        mech = design_mechanism(study, {v.name: a.knee_row[v.name] for v in study.variables})
        u = usable_workspace_of(mech, **measure_settings(study, o.name, o.settings))
    except (ValueError, ArithmeticError, KeyError):
        return ""
    cells = " x ".join(str(int(c)) for c in u.shape)
    sizes = []
    for name, edges in zip(u.coordinates, u.edges):
        width = float(edges[1] - edges[0]) if len(edges) > 1 else float("nan")
        sizes.append(f"{name} {fmt_quantity(width, _unit_of_coordinate(name))}")
    labels = ", ".join(x.label for x in grids)
    return (f" {labels} {'is' if len(grids) == 1 else 'are'} exact on {'its' if len(grids) == 1 else 'their'} grid and "
            f"not resampled (± 0): {cells} cells of {', '.join(sizes)} for the recommended design; a finer grid may "
            "move the boundary by about one cell.")


def _unit_of_coordinate(name: str) -> str:
    return "length" if name in ("x", "y", "z") else "angle"


def _recommended_words(a: Analysis) -> str:
    several = len(a.labels) > 1
    rec = a.recommendation
    what = "knee of the front" if several else "the best"
    if rec is None or rec.status == "not verified":
        return f"Recommended ({what}, not verified)"
    if rec.status == "none passed":
        return f"No design passed verification; the {'knee' if several else 'best design'} on single samples"
    if rec.first is not None and int(rec.first["trial"]) != int(rec.row["trial"]):
        return "Recommended (the first design of the ranking that passed verification)"
    return f"Recommended ({what}, verified)"


def reading_text(study) -> str:
    """One sentence per unitless measure of the study (objectives, design constraints, an added
    singularity-margin floor) on its meaning and scale; empty when there is none."""
    items = [(o.label, o.name) for o in study.objectives] + [(c.label, c.name) for c in study.constraints]
    settings = {x.label: dict(x.settings or {}) for x in list(study.objectives) + list(study.constraints)}
    items += [(c.get("name", "singularity_margin"), c.get("type", "")) for c in
              (study.evaluation.get("added_constraints") or ())]
    out, seen, said, defined = [], set(), {}, set()
    for label, name in items:
        meaning = INDEX_MEANINGS.get(name)
        if meaning is None or (label, name) in seen:
            continue
        q = settings.get(label, {}).get("quantile")
        if meaning.startswith("the smallest (or the set quantile of the)"):
            which = f"the {fmt_number(100 * float(q), 3)} % quantile of the" if q else "the smallest"
            meaning = meaning.replace("the smallest (or the set quantile of the)", which, 1)
        seen.add((label, name))
        what = f"**{label}**" + (f" ({name})" if label != name else "")
        if meaning in said:  # the same measure under another label (a constraint on an objective's measure)
            out.append(f"{what}: the same measure as {said[meaning]}.")
            continue
        said[meaning] = label
        for definition in _DEFINITIONS:  # a definition given once, not again for every measure of it
            if definition in meaning:
                if definition in defined:
                    meaning = re.sub(r"(?:; the singularity margin is |; |, )" + re.escape(definition), "", meaning, 1)
                defined.add(definition)
        out.append(f"{what}: {meaning}")
    if not out:
        return ""
    return "Reading the unitless measures: " + " ".join(out)


def _pct_of(v) -> str:
    return f"{fmt_number(100 * float(v), 3)} %"


def share_text(run: Run, a: Analysis) -> str:
    """The verdict on each share objective (:data:`SHARE_MEASURES`): which designs keep the same
    share (and the variables that are equal in exactly those designs, e.g. every design with
    b2 = b4), the range of the others, the reference's and the recommended design's. On the
    re-evaluated values where the run has them, else on the single samples."""
    study = run.study
    shares = [o for o in study.objectives if o.name in SHARE_MEASURES]
    if not shares:
        return ""
    fa = a.final
    if fa is not None and len(fa.table):
        table, basis = fa.table, "re-evaluated"
    else:
        table, basis = a.runs[(a.runs["status"] == "ok")], "evaluated (single samples)"
    rows, keys = [], set()
    for _, r in table.sort_values("trial", key=lambda t: t.where(t >= 0, np.inf)).iterrows():
        k = design_key(study, r)
        if k in keys:
            continue
        keys.add(k)
        rows.append(r)
    if len(rows) < 2:
        return ""
    numeric = [v.name for v in study.variables if _is_number_col(study, v.name)]
    texts = []
    for o in shares:
        vals = np.array([float(r[o.label]) for r in rows])
        ok = np.isfinite(vals)
        groups = []
        for v in sorted(set(np.round(vals[ok], 9))):
            idx = [i for i in range(len(rows)) if ok[i] and abs(vals[i] - v) <= 1e-9]
            if len(idx) >= 2:
                groups.append((v, idx))
        parts = []
        for v, idx in groups:
            members = set(idx)
            pairs = [(x, y) for i, x in enumerate(numeric) for y in numeric[i + 1:]
                     if _unit(study, x) == _unit(study, y)
                     and {j for j in range(len(rows)) if abs(float(rows[j][x]) - float(rows[j][y])) <= 1e-12} == members]
            if pairs:
                x, y = pairs[0]
                parts.append(f"every design with {x} = {y} ({len(idx)} of the {len(rows)} {basis} designs) keeps "
                             f"exactly {_pct_of(v)}")
            else:
                names = [f"trial {int(rows[j]['trial'])}" if int(rows[j]["trial"]) >= 0 else reference_name(study)
                         for j in idx]
                trials = ", ".join(names[:-1]) + " and " + names[-1]
                parts.append(f"{len(idx)} of the {len(rows)} {basis} designs keep exactly {_pct_of(v)} ({trials})")
        grouped = {j for _, idx in groups for j in idx}
        rest = [vals[j] for j in range(len(rows)) if ok[j] and j not in grouped]
        if rest:
            lo, hi = min(rest), max(rest)
            span = _pct_of(lo) if lo == hi else f"{fmt_number(100 * lo, 3)}-{_pct_of(hi)}"
            parts.append(f"{'the other designs' if groups else f'the {len(rows)} {basis} designs'} keep {span}")
        named = []
        if fa is not None and fa.ref is not None and np.isfinite(float(fa.ref[o.label])):
            named.append(f"{reference_name(study)} {_pct_of(fa.ref[o.label])}")
        elif a.ref_row is not None:
            named.append(f"{reference_name(study)} {_pct_of(a.ref_row[o.label])} (single sample)")
        if fa is not None and fa.knee is not None:
            named.append(f"the recommended design (trial {int(fa.knee['trial'])}) {_pct_of(fa.knee[o.label])}")
        elif a.knee_row is not None:
            named.append(f"the recommended design (trial {int(a.knee_row['trial'])}) "
                         f"{_pct_of(a.knee_row[o.label])} (single sample)")
        text = f"**{o.label}**: " + "; ".join(parts)
        if named:
            text += "; " + ", ".join(named)
        texts.append(text + ".")
    return "**Shares** (" + basis + " values): " + " ".join(texts)


def _fmt_design(study, row) -> list[str]:
    parts = [_design_values(study, row)] if study.variables else []
    for o in study.objectives:
        parts.append(f"{o.label} = {fmt_quantity(row[o.label], _unit(study, o.label))}")
    return parts


def _design_values(study, row) -> str:
    parts = []
    for v in study.variables:
        val = row[v.name]
        if val is None or (not isinstance(val, str) and pd.isna(val)):
            continue  # a dimension the design's structure does not use (or an inactive conditional variable)
        parts.append(f"{v.name} = {fmt_quantity(val, _unit(study, v.name))}" if _is_number_col(study, v.name)
                     else f"{v.name} = {val}")
    return ", ".join(parts)


def _pct(diff, se, base) -> str:
    """Relative difference ``+x % ± y %`` (or the absolute one when ``base`` is 0)."""
    if base == 0 or not np.isfinite(base):
        return fmt_mean_se(diff, se)
    return ("+" if diff >= 0 else "") + fmt_mean_se(100 * diff / abs(base), 100 * se / abs(base)) + " %"


def _comparison_text(study, row, cmp, ref) -> str:
    labels = [o.label for o in study.objectives]
    groups = {1: [], -1: [], 0: []}
    for j, lab in enumerate(labels):
        groups[int(cmp.status[j])].append(f"{lab} ({_pct(cmp.diff[j], cmp.se[j], float(ref[lab]))})")
    parts = []
    if groups[1]:
        parts.append("better on " + ", ".join(groups[1]))
    if groups[-1]:
        parts.append("worse on " + ", ".join(groups[-1]))
    if groups[0]:
        parts.append(("equal within noise on " if cmp.noise_known else "equal on ") + ", ".join(groups[0]))
    return f"trial {int(row['trial'])} ({_design_values(study, row)}): " + "; ".join(parts)


def _paper_text(run: Run, a: Analysis) -> str:
    study = run.study
    r = a.ref_row
    txt = (reference_name(study, capital=True, with_source=True) + ": " + ", ".join(_fmt_design(study, r))
           + " (single sample); feasible: "
           + ("yes" if bool(r["feasible"]) else "no") + ".")
    st = a.standing
    fa = a.final
    screened = ""
    if st is not None:
        screened = ((f"{st.n_dominating} evaluated feasible designs dominate it" if st.n_dominating > 1 else
                     "1 evaluated feasible design dominates it") if st.n_dominating
                    else "no evaluated feasible design dominates it")
    if fa is None or fa.ref is None:
        if st is not None:
            if st.n_dominating:
                imp = "; ".join(f"{k} by up to {fmt_number(100 * v, 2)} %" for k, v in st.best_improvements.items())
                txt += (f" On single-sample values {screened}, improving {imp} (additive epsilon "
                        f"{fmt_number(st.epsilon, 3)} in range-normalised objectives).")
            else:
                txt += " On single-sample values no evaluated feasible design dominates it (it is on or beyond the front found)."
            txt += (" These single-sample values were not re-evaluated: differences smaller than the sampling noise "
                    "are not resolved (set evaluation.final_samples to re-evaluate the best designs).")
        return txt
    fin = fa.table
    z = a.noise_z
    txt += (f"\n\nVerdict on the re-evaluated values ({int(fin['repeats'].iloc[0])} seeds x "
            f"{int(fin['samples'].iloc[0])} samples; a difference counts when it exceeds {fmt_number(z)} "
            f"combined standard errors, otherwise it is within noise):")
    vs = fa.vs_ref
    dom = [(row, c) for row, c in vs if c.verdict == "dominates"]
    worse = [(row, c) for row, c in vs if c.verdict == "dominated"]
    same = [(row, c) for row, c in vs if c.verdict == "within noise"]
    ref = fa.ref
    if fa.unverified is not None and len(fa.unverified):
        txt += (f" ({len(fa.unverified)} re-evaluated design{'s' if len(fa.unverified) != 1 else ''} failed "
                "verification and count in no verdict: " + ", ".join(f"trial {int(t)}" for t in fa.unverified["trial"])
                + ".)")
    if dom:
        txt += (f" {len(dom)} of the {len(vs)} {_counted(fa)} designs {'dominates' if len(dom) == 1 else 'dominate'} it (better beyond noise on at least "
                "one objective, worse beyond noise on none): " + " | ".join(_comparison_text(study, row, c, ref)
                                                                          for row, c in dom) + ".")
    else:
        txt += f" none of the {len(vs)} {_counted(fa)} designs dominates it beyond noise."
    if same:
        txt += " Equal to it within noise on every objective: " + ", ".join(f"trial {int(row['trial'])}" for row, _ in same) + "."
    if worse:
        txt += " Dominated by it: " + ", ".join(f"trial {int(row['trial'])}" for row, _ in worse) + "."
    if st is not None:
        txt += f"\n\n(Single-sample screening: {screened}; the re-evaluation above decides.)"
        txt += _screen_text(fa, fa.n_screen)
    return txt


def _counted(fa: FinalAnalysis) -> str:
    """What the verdicts count: verified designs (a final.csv written before verification: the
    re-evaluated ones)."""
    return "verified re-evaluated" if "verified" in fa.table else "re-evaluated"


def _screen_text(fa: FinalAnalysis, n_screen: int) -> str:
    """How the designs that dominate the reference on single-sample values fared once
    re-evaluated (the ones re-evaluated: the largest normalised margins, see
    :func:`parasynth.study.final.screening_dominators`)."""
    if not n_screen:
        return ""
    sel = [(row, c) for row, c in fa.vs_ref if bool(row.get("dominates_reference_screen", False))]
    if not sel:
        return (f" None of the {n_screen} screening dominators is in final.csv (it was written before this "
                "selection); run the study again with --resume to redo the final stage.")

    def trials(group):
        return ", ".join(f"trial {int(row['trial'])}" for row, _ in group)

    dom = [(r, c) for r, c in sel if c.verdict == "dominates"]
    same = [(r, c) for r, c in sel if c.verdict == "within noise"]
    trade = [(r, c) for r, c in sel if c.verdict == "trade-off"]
    worse = [(r, c) for r, c in sel if c.verdict == "dominated"]
    n = len(sel)
    txt = (f" Screening dominators re-evaluated: {n} of the {n_screen} distinct ones"
           + (" (the ones by the largest normalised margin)" if n < n_screen else "") + "; ")
    if dom:
        txt += f"{len(dom)} of them {'dominates' if len(dom) == 1 else 'dominate'} it beyond noise ({trials(dom)})"
    else:
        txt += "none of them dominates it beyond noise"
    if same and len(same) == n:
        txt += ": all of them are equal to it within noise"
    else:
        rest = []
        if same:
            rest.append(f"within noise: {trials(same)}")
        if trade:
            rest.append(f"trade-off (better and worse beyond noise): {trials(trade)}")
        if worse:
            rest.append(f"dominated by it: {trials(worse)}")
        if rest:
            txt += "; " + "; ".join(rest)
    return txt + "."
