"""The terminal summary of a run: what the report recommends, in a few lines.

The recommendation is the report's (:func:`parasynth.report.analysis.analyse`): the knee of the
non-dominated feasible front (the best design for one objective), with its re-evaluated
values when ``final.csv`` holds them, then a few designs spread along the front -- leaving
out those the re-evaluation shows dominated beyond noise -- each row saying why it is listed
(``knee``, ``best <objective>``, ``on the front``), then the reference design under the
name the study gives it, and the warnings of :mod:`parasynth.report.checks`.
"""

from __future__ import annotations

import functools
from pathlib import Path

import pandas as pd

from ..mechanisms import load_mechanism
from ..measures.task import ASSEMBLY_MODE_SKIPPED, assembly_mode_checked
from ..measures.display import fmt_mean_se, fmt_number, fmt_quantity, quantity_unit, reference_name, text_table
from ..study.rundir import SINGULARITY_FLOOR, Run, best_designs, design_key, estimate_of, read_final
from .checks import design_roles
from .analysis import analyse
from ..common import columns as derived

__all__ = ["terminal_summary", "run_summary", "recommendation_lines", "verification_text", "reevaluated_text"]


def terminal_summary(study, table: pd.DataFrame, final: pd.DataFrame | None, out_dir, k: int = 3) -> list[str]:
    """Lines of the terminal summary after the counts line (see the module docstring)."""
    out_dir = Path(out_dir)
    if final is None and (out_dir / "final.csv").exists():
        try:
            final = read_final(study, out_dir / "final.csv")
        except (ValueError, OSError):
            final = None
    lines: list[str] = []
    runs = table[table["source"] == "run"] if len(table) else table
    if not len(runs):
        return lines
    a = analyse(Run(study, table, final, out_dir, None))
    knee = a.knee_row
    fa = a.final
    several = len(study.objectives) > 1
    if knee is None:
        lines.append("no feasible design found")
        return lines
    lines += recommendation_lines(study, a)
    # Designs along the front, without those dominated beyond noise once re-evaluated.
    dominated = {}
    if fa is not None:
        for i, r in fa.best.iterrows():
            if fa.dominated_by.get(i):
                dominated[design_key(study, r)] = fa.dominated_by[i]
    pool = best_designs(study, runs, k=0)
    kk = design_key(study, knee)
    dominated.pop(kk, None)  # the recommendation is listed, never left out
    kept = pool[[design_key(study, r) not in dominated for _, r in pool.iterrows()]]
    dropped = [(int(r["trial"]), dominated[design_key(study, r)]) for _, r in pool.iterrows()
               if design_key(study, r) in dominated]
    show = best_designs(study, kept, k=k) if len(kept) else kept
    if several and len(show) and not any(design_key(study, r) == kk for _, r in show.iterrows()):
        o = study.objectives[0]  # the recommended design is always listed
        mine = pool[[design_key(study, r) == kk for _, r in pool.iterrows()]]
        if not len(mine):  # recommended from beyond the front (every front design failed verification)
            mine = knee.to_frame().T
        show = pd.concat([show, mine])
        show = show.sort_values(o.label, ascending=(o.goal == "minimize"), kind="stable")
    if len(show):
        show = show.copy()
        roles = design_roles(study, show, kk if a.recommendation is None or a.recommendation.verified else None,
                             front=pool)
        show.insert(0, "listed as", _with_verification(study, show, roles, a))
        n_front = len(pool)
        head = (f"non-dominated feasible designs: {n_front} distinct" + (f", {len(show)} listed (spread along the "
                f"front)" if n_front > len(show) else "") if several else f"best feasible designs ({len(show)})")
        cols = ["trial"] + [v.name for v in study.variables] + [o.label for o in study.objectives]
        if "count" in show and (show["count"] > 1).any():
            show = show.rename(columns={"count": "evaluations"})
            cols.append("evaluations")
            head += "; evaluations: how many times the run evaluated the design"
        lines.append(head + ":")
        text = text_table(study, show, cols)
        roles = ["listed as"] + list(show["listed as"])
        width = max(len(x) for x in roles)
        lines += [f"{role:<{width}}  {row}" for role, row in zip(roles, text.splitlines())]
    if dropped:
        lines.append("left out, dominated beyond noise once re-evaluated: " + "; ".join(
            f"trial {t} (by " + ", ".join(f"trial {x}" for x in by) + ")" for t, by in dropped))
    ref = table[table["source"] == "reference"]
    if len(ref):
        lines.append(reference_name(study, capital=True, with_source=True) + ":")
        ref = ref.assign(feasible=["yes" if bool(x) else "no" for x in ref["feasible"]])
        lines.append(text_table(study, ref, [o.label for o in study.objectives] + ["feasible"]))
    lines += [f"warning: {w}" for w in a.warnings]
    return lines


def _with_verification(study, rows: pd.DataFrame, roles: list[str], a) -> list[str]:
    """``roles`` with the outcome of verification: the recommended design says so (for one
    objective too), a design that failed verification says that."""
    rec = a.recommendation
    fa = a.final
    if rec is None or fa is None or "verified" not in fa.table:
        return roles
    verdict = {design_key(study, r): bool(r["verified"]) for _, r in fa.best.iterrows()}
    rk = design_key(study, rec.row) if rec.verified and rec.row is not None else None
    out = []
    for role, (_, r) in zip(roles, rows.iterrows()):
        k = design_key(study, r)
        if k == rk and "recommended" not in role:
            role = "recommended, " + role
        if verdict.get(k) is False:
            role += ", failed verification"
        out.append(role)
    return out


def recommendation_lines(study, a) -> list[str]:
    """The first lines of a summary: the recommended design and whether it passed verification
    (:mod:`parasynth.study.verify`), or that none did, with what failed."""
    rec = a.recommendation
    knee = a.knee_row
    several = len(study.objectives) > 1
    what = "knee of the non-dominated front" if several else "best feasible design"
    vals = ", ".join(f"{x} = {fmt_quantity(knee[x], quantity_unit(study, x))}"
                     for x in [v.name for v in study.variables] + [o.label for o in study.objectives]
                     if fmt_quantity(knee[x], quantity_unit(study, x)) != "")  # a dimension its structure does not use
    lines = []
    fa = a.final
    if rec is None or rec.status == "not verified":
        lines.append(f"recommended ({what}), NOT VERIFIED: trial {int(knee['trial'])}: {vals} (single sample)")
        lines.append("  the run has not re-checked it (interrupted before its final stage, or written by an older "
                     "version): run it again with --resume to verify it")
    elif rec.status == "verified":
        first = rec.first is not None and design_key(study, rec.first) == design_key(study, knee)
        if first:
            why = what
        elif rec.failed:
            why = "the first design of the ranking that passed verification"
        else:  # the first-ranked design passed, and this one dominates it beyond noise once re-evaluated
            why = (f"it dominates the {'knee' if several else 'best design on single samples'}, trial "
                   f"{int(rec.first['trial'])}, beyond noise once re-evaluated")
        lines.append(f"recommended ({why}), verified: trial {int(knee['trial'])}: {vals} (single sample)")
        lines.append("  " + verification_text(study, rec.final_row))
    else:
        lines.append(f"NO DESIGN PASSED VERIFICATION: none of the {rec.checked} re-checked designs holds every "
                     "requirement; none is recommended (docs/verification.md)")
        lines.append(f"  best design on single samples ({what}), not to be built as it is: trial {int(knee['trial'])}: {vals}")
    if fa is not None and fa.knee is not None:
        kr = fa.knee
        lines.append("  re-evaluated: " + ", ".join(
            f"{o.label} = {reevaluated_text(study, o, kr)}" for o in study.objectives))
    for trial, reason in rec.failed if rec is not None else []:
        lines.append(f"  trial {trial} {'(ranked before it) ' if rec.status == 'verified' else ''}{reason}")
    return lines


def reevaluated_text(study, o, row) -> str:
    """A re-evaluated objective: mean ± standard error, or the value alone for a measure exact on
    its grid (or without a sample), which is not resampled."""
    u = quantity_unit(study, o.label)
    kind = estimate_of(o)
    if kind in ("grid", "exact"):
        return fmt_quantity(row[o.label], u) + (" (exact on its grid)" if kind == "grid" else " (exact)")
    return fmt_mean_se(row[o.label], row[derived.stderr(o.label)], u, True)


def verification_text(study, fr) -> str:
    """One line on how a verified design was checked (its final.csv row ``fr``)."""
    if fr is None:
        return "verified"
    ev = study.evaluation
    parts = []
    n_rep = int(fr.get("repeats", 0) or 0)
    if n_rep:
        parts.append(f"{n_rep} new seed{'s' if n_rep != 1 else ''} x {int(fr['samples'])} samples")
    if study.constraints:
        parts.append(f"{len(study.constraints)} constraint{'s' if len(study.constraints) != 1 else ''} "
                     "within tolerance")
    hm = fr.get("home_margin")
    if hm is not None and pd.notna(hm):
        parts.append(f"singularity margin at home {fmt_number(float(hm), 3)} >= "
                     f"{fmt_number(ev.get('singularity_floor', SINGULARITY_FLOOR))}")
    if getattr(study, "task", None) is not None:
        mode = "no change of assembly mode" if _assembly_mode_checked(study) else ASSEMBLY_MODE_SKIPPED
        parts.append(f"the task re-checked densely ({study.task.refinement()}: "
                     f"margin above the floor, no singularity crossed, {mode})")
    return "verified: " + ", ".join(parts)


def _assembly_mode_checked(study) -> bool:
    """Whether the dense re-check checks the assembly mode on the study's mechanism
    (:func:`parasynth.measures.task.assembly_mode_checked`: the counts of actuators and
    freedoms, the same for every design of the mechanism)."""
    try:
        return assembly_mode_checked(_counts_mechanism(study.mechanism))
    except Exception:  # a structure study or a description that needs its design's values
        return True


@functools.lru_cache(maxsize=16)
def _counts_mechanism(name):
    return load_mechanism(name)


def run_summary(study, res) -> str:
    """The terminal summary of a finished (or interrupted) run ``res``
    (:class:`~parasynth.study.runner.RunResult`): its counts, what the report recommends, and
    where the results are."""
    return res.summary(study, terminal_summary(study, res.table, res.final, res.out_dir))
