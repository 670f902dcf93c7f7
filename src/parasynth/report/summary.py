"""The terminal summary of a run: what the report recommends, in a few lines.

The recommendation is the report's (:func:`parasynth.report.analysis.analyse`): the knee of the
non-dominated feasible front (the best design for one objective), with its re-evaluated
values when ``final.csv`` holds them, then a few designs spread along the front -- leaving
out those the re-evaluation shows dominated beyond noise -- each row saying why it is listed
(``knee``, ``best <objective>``, ``on the front``), then the reference design under the
name the study gives it, and the warnings of :mod:`parasynth.report.checks`.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..measures.display import fmt_mean_se, fmt_quantity, quantity_unit, reference_name, text_table
from ..study.rundir import Run, best_designs, design_key, read_final
from .checks import design_roles
from .analysis import analyse

__all__ = ["terminal_summary", "run_summary"]


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
    if knee is not None:
        what = "knee of the non-dominated front" if several else "best feasible design"
        vals = ", ".join(f"{x} = {fmt_quantity(knee[x], quantity_unit(study, x))}"
                         for x in [v.name for v in study.variables] + [o.label for o in study.objectives])
        lines.append(f"recommended ({what}): trial {int(knee['trial'])}: {vals} (single sample)")
        if fa is not None and fa.knee is not None:
            kr = fa.knee
            lines.append("  re-evaluated: " + ", ".join(
                f"{o.label} = {fmt_mean_se(kr[o.label], kr[o.label + '_stderr'], quantity_unit(study, o.label), True)}"
                for o in study.objectives))
    else:
        lines.append("no feasible design found")
        return lines
    # Designs along the front, without those dominated beyond noise once re-evaluated.
    dominated = {}
    if fa is not None:
        for i, r in fa.best.iterrows():
            if fa.dominated_by.get(i):
                dominated[design_key(study, r)] = fa.dominated_by[i]
    pool = best_designs(study, runs, k=0)
    kept = pool[[design_key(study, r) not in dominated for _, r in pool.iterrows()]]
    dropped = [(int(r["trial"]), dominated[design_key(study, r)]) for _, r in pool.iterrows()
               if design_key(study, r) in dominated]
    show = best_designs(study, kept, k=k) if len(kept) else kept
    kk = design_key(study, knee)
    if several and len(show) and not any(design_key(study, r) == kk for _, r in show.iterrows()):
        o = study.objectives[0]  # the recommended design is always listed
        show = pd.concat([show, pool[[design_key(study, r) == kk for _, r in pool.iterrows()]]])
        show = show.sort_values(o.label, ascending=(o.goal == "minimize"), kind="stable")
    if len(show):
        show = show.copy()
        show.insert(0, "listed as", design_roles(study, show, kk))
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


def run_summary(study, res) -> str:
    """The terminal summary of a finished (or interrupted) run ``res``
    (:class:`~parasynth.study.runner.RunResult`): its counts, what the report recommends, and
    where the results are."""
    return res.summary(study, terminal_summary(study, res.table, res.final, res.out_dir))
