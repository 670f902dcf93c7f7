"""The report of a study over structures (``structure:`` in the study): what each structure
got and gave, the combined front labelled by structure, and the verdict on the reference
structure.

* :func:`structure_table` -- one row per structure: limbs and arrangement, designs evaluated,
  feasible and failed, the best single-sample value of each objective among its feasible
  designs, its designs on the combined front, where the schedule stopped it and why, and why
  its designs failed (violated design constraints, evaluation errors);
* :func:`structure_verdict` -- whether the reference structure is on the combined front, on
  the re-evaluated designs of ``final.csv`` (each structure's best design, the reference
  structure's front, the combined front's spread) beyond noise
  (:func:`parasynth.common.pareto.compare_with_noise`), else on single samples (said so);
* :func:`structure_sections` -- the sections for :mod:`parasynth.report.render`;
* :func:`plot_structures` -- the combined front, every point labelled (coloured) by its
  structure, the reference structure's best design (the knee of its own front) marked.

Reads the run only as :class:`parasynth.study.rundir.Run` (its ``plan`` is the schedule's, as
the run decided it from the same stored designs).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..measures.display import fmt_mean_se, fmt_number, fmt_quantity, fmt_value
from ..common.pareto import compare_with_noise
from ..study.rundir import Run, knee_of, pareto_front
from .analysis import Analysis, passed_mask
from .figures import _grid, _label, _tidy
from .tables import unit
from ..common import columns as derived

__all__ = ["structure_table", "structure_verdict", "structure_sections", "plot_structures", "Verdict"]

STRUCTURE = "structure"


def _setup(run: Run):
    return getattr(run.study, "structures", None)


def _why_failed(study, rows: pd.DataFrame) -> str:
    """Why designs are not feasible: the design constraints violated (count of designs) and the
    evaluation errors (their exception types)."""
    parts = []
    for c in study.constraints:
        n = int((rows[derived.margin(c.label)] < 0).sum()) if derived.margin(c.label) in rows else 0
        if n:
            parts.append(f"{c.label} violated {n}x")
    failed = rows[rows["status"] != "ok"]
    if len(failed):
        kinds = failed["error"].fillna("").map(lambda e: str(e).split(":", 1)[0] or "error").value_counts()
        parts.append("failed: " + ", ".join(f"{k} {n}x" for k, n in kinds.items()))
    return "; ".join(parts) or "-"


def structure_table(run: Run, a: Analysis) -> pd.DataFrame:
    """One row per structure (see the module docstring), display strings."""
    study, setup = run.study, _setup(run)
    runs, front = a.runs, a.front
    stopped = run.plan.stopped_at() if run.plan is not None else {}
    last = run.plan.current.target if run.plan is not None else None
    rows = []
    for label in study.space.by_name[STRUCTURE].choices:
        s = setup.structures[label]
        mine = runs[runs[STRUCTURE] == label]
        ok = mine[(mine["status"] == "ok") & mine["feasible"].astype(bool)]
        row = {"structure": label + (" (reference)" if label == setup.reference else ""), "limbs": s.limbs,
               "arrangement": "; ".join(g.arrangement for g in s.groups), "designs": fmt_number(len(mine)),
               "feasible": fmt_number(len(ok)), "failed": fmt_number(int((mine["status"] != "ok").sum()))}
        for o in study.objectives:
            u = unit(study, o.label)
            v = ok[o.label].astype(float)
            best = (v.max() if o.goal == "maximize" else v.min()) if len(v) else np.nan
            row[f"best {u.label(o.label)}"] = fmt_value(best, u) if np.isfinite(best) else "-"
        row["on the combined front"] = fmt_number(int((front[STRUCTURE] == label).sum())) if len(front) else "0"
        if label in stopped:
            k, target, why = stopped[label]
            row["schedule"] = f"stopped after rung {k + 1} ({target} designs): {why}"
        else:
            row["schedule"] = f"full budget ({last} designs)" if last is not None else "-"
        row["why designs failed"] = _why_failed(study, mine)
        rows.append(row)
    return pd.DataFrame(rows)


class Verdict:
    """Whether the reference structure is on the combined front: ``on_front`` (bool or None
    without a reference structure), ``re_evaluated`` (decided on final.csv beyond noise, else
    on single samples), ``text``."""

    def __init__(self, on_front, re_evaluated: bool, text: str):
        self.on_front = on_front
        self.re_evaluated = re_evaluated
        self.text = text


def _ref_best(study, runs, ref):
    mine = runs[runs[STRUCTURE] == ref]
    return knee_of(study, pareto_front(study, mine))


def structure_verdict(run: Run, a: Analysis) -> Verdict:
    """The verdict on the reference structure (module docstring)."""
    study, setup = run.study, _setup(run)
    ref = setup.reference
    if ref is None:
        return Verdict(None, False, "The study names no reference structure (structure.reference).")
    labels = [o.label for o in study.objectives]
    senses = [o.goal for o in study.objectives]
    fin = a.final.table if a.final is not None else None
    if fin is not None and STRUCTURE in fin:
        best = fin[(fin["source"] == "best") & passed_mask(fin)]  # only designs that passed verification count
        mine = best[best[STRUCTURE] == ref]
        others = best[best[STRUCTURE] != ref]
        if len(mine):
            def mse(r):
                return r[labels].to_numpy(float), r[[derived.stderr(x) for x in labels]].to_numpy(float)

            free, beaten = [], {}
            for _, r in mine.iterrows():
                doms = [o for _, o in others.iterrows()
                        if compare_with_noise(*mse(o), *mse(r), senses, a.noise_z).verdict == "dominates"]
                if doms:
                    beaten[int(r["trial"])] = sorted({f"{o[STRUCTURE]} (trial {int(o['trial'])})" for o in doms})
                else:
                    free.append(int(r["trial"]))
            n = len(mine)
            if free:
                txt = (f"**{ref} is on the combined front** (re-evaluated, beyond {fmt_number(a.noise_z)} combined "
                       f"standard errors): of its {n} re-evaluated designs, trial(s) "
                       f"{', '.join(map(str, free))} are dominated by no re-evaluated design of another structure.")
                if beaten:
                    txt += " Dominated: " + "; ".join(f"trial {t} by {', '.join(v)}" for t, v in beaten.items()) + "."
                return Verdict(True, True, txt)
            txt = (f"**{ref} is not on the combined front** (re-evaluated, beyond {fmt_number(a.noise_z)} combined "
                   f"standard errors): each of its {n} re-evaluated designs is dominated by a design of another "
                   "structure: " + "; ".join(f"trial {t} by {', '.join(v)}" for t, v in beaten.items()) + ".")
            return Verdict(False, True, txt)
    front = a.front
    n = int((front[STRUCTURE] == ref).sum()) if len(front) else 0
    if fin is not None and STRUCTURE in fin and "verified" in fin:
        tried = fin[(fin["source"] == "best") & (fin[STRUCTURE] == ref)]
        if len(tried):
            return Verdict(None, True, f"**No verdict on {ref}**: none of its {len(tried)} re-evaluated designs passed "
                           "verification (docs/verification.md), and a design that fails counts in no verdict. "
                           f"On single samples it has {n} design(s) on the combined front of {len(front)}.")
    txt = (f"On single samples (no re-evaluation of its designs in final.csv), {ref} has {n} design(s) on the "
           f"combined front of {len(front)}: {'on' if n else 'not on'} the combined front; set "
           "evaluation.final_samples to decide beyond noise.")
    return Verdict(bool(n), False, txt)


def structure_sections(run: Run, a: Analysis) -> list:
    """(title, text, table) of a study over structures; [] for other studies."""
    setup = _setup(run)
    if setup is None or STRUCTURE not in a.runs:
        return []
    study, plan = run.study, run.plan
    choices = study.space.by_name[STRUCTURE].choices
    dropped = ", ".join(f"{k} {v}" for k, v in setup.dropped.items()) or "none"
    txt = (f"Structures of **{setup.motion}** (parasynth.structures): {setup.enumerated} candidates enumerated "
           f"(dropped: {dropped}), **{len(choices)} screened**: {', '.join(choices)}.")
    same = [f"{lab} also stands for {', '.join(f'{n} ({why})' for n, why in setup.structures[lab].equivalents)}"
            for lab in choices if setup.structures[lab].equivalents]
    if same:
        txt += " Equivalent structures are reported as one: " + "; ".join(same) + "."
    floor = next((c.min for c in study.constraints if c.name == "home_singularity_margin"), None)
    if floor is not None:
        txt += (f" Every structure is compared on designs controlled at their home pose with a singularity margin of "
                f"at least {fmt_number(floor)} (the study's floor; docs/structures.md).")
    if plan is not None:
        targets = "; ".join(f"rung {r.index + 1}: {r.target} designs each for {len(r.alive)}" for r in plan.rungs)
        full = plan.full() if plan.done else ()
        txt += (f" Successive halving (eta {study.spec.structure.eta}): {targets}"
                + (f"; **{len(full)} got the full budget** ({', '.join(full)})" if plan.done else
                   " (the schedule is not finished)") + ".")
        why = plan.stopped_at()
        if why:
            txt += " Stopped: " + "; ".join(f"{s} after {t} designs ({w})" for s, (k, t, w) in why.items()) + "."
    v = structure_verdict(run, a)
    out = [("Structures", txt, structure_table(run, a))]
    if setup.reference is not None:
        rb = _ref_best(study, a.runs, setup.reference)
        txt = v.text
        if rb is not None:
            parts = []
            for o in study.objectives:
                u = unit(study, o.label)
                parts.append(f"{o.label} = {fmt_quantity(rb[o.label], u)}")
            txt += (f" Its best design (the knee of its own front, marked in the figure): trial {int(rb['trial'])}, "
                    + ", ".join(parts) + " (single sample).")
            fin = a.final.table if a.final is not None else None
            if fin is not None and STRUCTURE in fin:
                hit = fin[(fin["source"] == "best") & (fin["trial"] == rb["trial"])]
                if len(hit):
                    r = hit.iloc[0]
                    txt += " Re-evaluated: " + ", ".join(
                        f"{o.label} = {fmt_mean_se(r[o.label], r[o.label + '_stderr'], unit(study, o.label), True)}"
                        for o in study.objectives) + "."
        out.append((f"Reference structure {setup.reference}", txt, None))
    return out


_MARKERS = "osD^v<>PX*"


def plot_structures(figs, run: Run, a: Analysis) -> None:
    """The combined front labelled by structure (module docstring)."""
    setup = _setup(run)
    if setup is None or STRUCTURE not in a.runs or len(run.study.objectives) < 2:
        return
    import matplotlib  # lazy: matplotlib, imported with the report's first figure

    study, runs, front = run.study, a.runs, a.front
    objs = study.objectives
    pairs = [(i, j) for i in range(len(objs)) for j in range(i + 1, len(objs))]
    fig, axes = _grid(len(pairs), width=5.6 if len(pairs) == 1 else 4.6, height=4.0)
    cmap = matplotlib.colormaps["tab10"]
    choices = list(study.space.by_name[STRUCTURE].choices)
    feas = runs[(runs["status"] == "ok") & runs["feasible"].astype(bool)]
    rb = _ref_best(study, runs, setup.reference) if setup.reference else None
    for ax, (i, j) in zip(axes, pairs):
        x, y = objs[i].label, objs[j].label
        lx, fx = _label(study, x)
        ly, fy = _label(study, y)
        for k, lab in enumerate(choices):
            c, m = cmap(k % 10), _MARKERS[k % len(_MARKERS)]
            mine = feas[feas[STRUCTURE] == lab]
            ax.scatter(fx(mine[x]), fy(mine[y]), s=9, color=c, marker=m, alpha=0.25)
            on = front[front[STRUCTURE] == lab] if len(front) else front
            ax.scatter(fx(on[x]), fy(on[y]), s=36, color=c, marker=m, edgecolors="k", linewidths=0.6, zorder=4,
                       label=f"{lab} ({len(on)} on the front)")
        if rb is not None:
            ax.scatter([fx(rb[x])], [fy(rb[y])], s=260, marker="*", c="#ff7f0e", edgecolors="k", zorder=6,
                       label=f"best {setup.reference} design (knee of its front)")
        ax.set_xlabel(f"{lx} ({objs[i].goal})", fontsize=9)
        ax.set_ylabel(f"{ly} ({objs[j].goal})", fontsize=9)
        ax.grid(alpha=0.3)
        _tidy(ax)
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", ncols=2, fontsize=8)
    fig.suptitle(f"Combined front by structure: {study.name}")
    figs.add(fig, "structures", "Feasible designs of every structure (small, pale) and the combined non-dominated "
             "front (large, outlined), coloured by structure; the star is the reference structure's best design.")
