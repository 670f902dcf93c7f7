"""Study reports: ``index.html`` (self-contained, images inline), ``report.md`` (images in
``img/``) and ``pareto.csv`` (the non-dominated feasible designs, columns as results.csv).

``write_report(run_dir, out=None)`` reads a run directory (``study.yaml``, ``results.csv`` or
the journal, ``final.csv``) and writes the report to ``out`` (default ``reports/<study>/``).
A missing or empty run directory raises :class:`ReportError` with a clear message; an
interrupted run gives a report marked *partial*.
"""

from __future__ import annotations

import base64
import html
import importlib.metadata as md
import io
import platform
import re
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..display import (UNITS, Unit, fmt_mean_se, fmt_number, fmt_quantity, fmt_value, quantity_unit, reference_name,
                       reference_short)
from ..mechanisms import load_mechanism
from ..objectives import workspace_of
from ..pareto import compare_with_noise, default_reference_point, hypervolume, reference_standing, to_min
from ..study.rundir import (Run, RunDirError, design_key, design_params, knee_of, pareto_front, read_run,
                            screening_dominators, to_csv_columns)
from .checks import design_roles, design_warnings

__all__ = ["write_report", "ReportError", "load_run"]


class ReportError(ValueError):
    """The run directory cannot be reported (missing, empty, unreadable)."""


def load_run(run_dir) -> Run:
    """The run directory read (:func:`parasynth.study.rundir.read_run`); :class:`ReportError`
    when there is no run to report."""
    try:
        return read_run(run_dir)
    except RunDirError as e:
        raise ReportError(str(e)) from None


# -- formatting ----------------------------------------------------------------------------------
#: A difference between re-evaluated designs counts when it exceeds this many combined standard
#: errors (``write_report(..., noise_z=...)``).
NOISE_Z = 2.0


def _unit(study, name) -> Unit:
    return quantity_unit(study, name)


def _is_number_col(study, name) -> bool:
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
        u = _unit(study, c)
        if _is_number_col(study, c):
            out[u.label(c)] = [fmt_value(x, u) for x in df[c]]
        else:
            out[c] = [str(x) for x in df[c]]
    if "feasible" in df:
        out["feasible"] = ["yes" if bool(x) else "no" for x in df["feasible"]]
    return out


# -- plots -------------------------------------------------------------------------------------------
def _plt():
    import matplotlib  # lazy: matplotlib takes about a second to import; only figures need it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # lazy: as above

    return plt


class Figures:
    """Collects figures as PNG bytes: inlined in HTML, written to img/ for Markdown.

    ``keep=True`` keeps the matplotlib figures open in ``figures`` (name -> figure) so that
    their layout can be inspected (tests of tick-label overlap)."""

    def __init__(self, keep: bool = False):
        self.items: list[tuple[str, str, bytes]] = []  # (name, caption, png)
        self.keep = keep
        self.figures: dict = {}

    def add(self, fig, name, caption):
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        if self.keep:
            self.figures[name] = fig
        else:
            _plt().close(fig)
        self.items.append((name, caption, buf.getvalue()))


def _label(study, lab) -> tuple[str, Unit]:
    u = _unit(study, lab)
    return u.label(lab), u


def _tidy(ax, x=True, y=True):
    """Few, plainly formatted ticks (no offset text, no scientific multiplier) so that tick
    labels do not run into each other at the figure's size."""
    from matplotlib.ticker import MaxNLocator, ScalarFormatter  # lazy: matplotlib, as in _plt

    for on, axis in ((x, ax.xaxis), (y, ax.yaxis)):
        if not on:
            continue
        axis.set_major_locator(MaxNLocator(nbins=5, min_n_ticks=3))
        fmt = ScalarFormatter(useOffset=False)
        fmt.set_scientific(True)
        fmt.set_powerlimits((-4, 6))
        axis.set_major_formatter(fmt)
    ax.tick_params(labelsize=8)


def _grid(plt, n, width=4.4, height=3.5, max_cols=3):
    """``n`` panels in a grid that wraps after ``max_cols`` columns (unused cells hidden)."""
    cols = max(1, min(max_cols, n))
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(width * cols, height * rows), squeeze=False,
                             layout="constrained")
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    return fig, axes.ravel()[:n]


def plot_pareto(figs, study, run_df, front, ref_row, knee_row):
    objs = study.objectives
    if len(objs) < 2:
        return
    plt = _plt()
    pairs = [(i, j) for i in range(len(objs)) for j in range(i + 1, len(objs))]
    fig, axes = _grid(plt, len(pairs), width=5.2 if len(pairs) == 1 else 4.6, height=3.8)
    ok = run_df["status"] == "ok"
    for ax, (i, j) in zip(axes, pairs):
        a, b = objs[i].label, objs[j].label
        la, fa = _label(study, a)
        lb, fb = _label(study, b)
        inf = run_df[ok & ~run_df["feasible"].astype(bool)]
        fea = run_df[ok & run_df["feasible"].astype(bool)]
        ax.scatter(fa(inf[a]), fb(inf[b]), s=10, c="#d62728", alpha=0.35, label="infeasible")
        ax.scatter(fa(fea[a]), fb(fea[b]), s=12, c="#7f7f7f", alpha=0.6, label="feasible")
        fr = front.sort_values(a)
        if len(objs) == 2 and len(fr) > 1:
            # Two objectives: the front is a staircase; joining its points in order of one
            # objective is meaningful. With more, a pair panel is a projection: points only.
            # (the boundary of the region the front dominates, sorted by the x objective)
            step = "pre" if objs[i].goal == "maximize" else "post"
            ax.step(fa(fr[a]), fb(fr[b]), where=step, c="#1f77b4", lw=1.0, alpha=0.7)
        ax.scatter(fa(fr[a]), fb(fr[b]), s=28, c="#1f77b4", zorder=4,
                   label="non-dominated" if len(objs) == 2 else "non-dominated (in all objectives)")
        if knee_row is not None:
            ax.scatter([fa(knee_row[a])], [fb(knee_row[b])], s=140, marker="D", facecolors="none",
                       edgecolors="#2ca02c", linewidths=2, label="recommended (knee)", zorder=5)
        if ref_row is not None:
            ax.scatter([fa(ref_row[a])], [fb(ref_row[b])], s=220, marker="*", c="#ff7f0e", edgecolors="k",
                       label=reference_short(study), zorder=6)
        ax.set_xlabel(f"{la} ({objs[i].goal})", fontsize=9)
        ax.set_ylabel(f"{lb} ({objs[j].goal})", fontsize=9)
        ax.grid(alpha=0.3)
        _tidy(ax)
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", ncols=3 if len(pairs) == 1 else 5, fontsize=8)
    fig.suptitle(f"Pareto front: {study.name}")
    figs.add(fig, "pareto", "Objective space: every evaluated design, the non-dominated feasible set, the "
             f"recommended design and {reference_name(study)}.")


def plot_parallel(figs, study, run_df, front):
    cols = [v.name for v in study.variables if v.type != "categorical"] + [o.label for o in study.objectives]
    if len(cols) < 2:
        return
    plt = _plt()
    d = run_df[run_df["status"] == "ok"][cols + ["feasible"]].copy()
    d[cols] = d[cols].astype(float)
    lo, hi = d[cols].min(), d[cols].max()
    Z = (d[cols] - lo) / (hi - lo).replace(0, 1)
    fig, ax = plt.subplots(figsize=(max(6.0, 2.2 * len(cols)), 4.4), layout="constrained")
    x = np.arange(len(cols))
    on_front = set(front["trial"]) if "trial" in front else set()
    trials = run_df.loc[d.index, "trial"] if "trial" in run_df else pd.Series(-1, index=d.index)
    for idx, row in Z.iterrows():
        on = trials[idx] in on_front
        feas = bool(d.loc[idx, "feasible"])
        ax.plot(x, row.values, c="#1f77b4" if on else ("#bbbbbb" if feas else "#f4b6b6"),
                alpha=0.9 if on else 0.35, lw=1.6 if on else 0.7, zorder=3 if on else 1)
    ax.set_xticks(x)
    labels = []
    for c in cols:
        u = _unit(study, c)
        name = c if len(c) <= 14 else c.replace("_", "_\n", 1)  # long names on two lines
        labels.append(f"{name}\n{fmt_value(lo[c], u, 3)} to {fmt_value(hi[c], u, 3)}" + (f" {u.symbol}" if u.symbol else ""))
    ax.set_xticklabels(labels, fontsize=9)
    ax.set_xlim(-0.3, len(cols) - 0.7)
    ax.set_yticks([])
    ax.set_title("Parallel coordinates (blue: non-dominated feasible; grey: feasible; red: infeasible)", fontsize=10)
    figs.add(fig, "parallel", "Design variables and objectives of every design, scaled to their ranges.")


def plot_convergence(figs, study, run_df):
    plt = _plt()
    d = run_df[run_df["source"] == "run"].sort_values("trial").reset_index(drop=True)
    if not len(d):
        return
    objs = study.objectives
    fig, ax = plt.subplots(figsize=(6, 3.6), layout="constrained")
    ok = (d["status"] == "ok") & d["feasible"].astype(bool)
    if len(objs) == 1:
        o = objs[0]
        lab, u = _label(study, o.label)
        vals = u(np.where(ok, d[o.label].astype(float), np.nan))
        best = pd.Series(vals).cummax() if o.goal == "maximize" else pd.Series(vals).cummin()
        ax.plot(np.arange(1, len(d) + 1), vals, ".", c="#999999", label="feasible designs")
        ax.plot(np.arange(1, len(d) + 1), best, "-", c="#1f77b4", label="best so far")
        ax.set_ylabel(lab)
    else:
        Fm = to_min(d[[o.label for o in objs]].to_numpy(float), [o.goal for o in objs])
        feas = ok.to_numpy()
        if not feas.any():
            plt.close(fig)
            return
        ref = default_reference_point(Fm[feas])
        hv = []
        for k in range(1, len(d) + 1):
            m = feas[:k]
            hv.append(hypervolume(Fm[:k][m], ref) if m.any() else 0.0)
        hv = np.asarray(hv)
        ax.plot(np.arange(1, len(d) + 1), hv / hv[-1] if hv[-1] > 0 else hv, "-", c="#1f77b4")
        ax.set_ylabel("hypervolume / final hypervolume")
    ax.set_xlabel("evaluations")
    ax.grid(alpha=0.3)
    _tidy(ax)
    ax.legend(fontsize=8) if len(objs) == 1 else None
    figs.add(fig, "convergence", "Convergence: best feasible value (one objective) or hypervolume of the feasible "
             "non-dominated set relative to its final value (several objectives, reference point as in the "
             "summary) against evaluations.")


def plot_sweep(figs, study, run_df, final):
    if study.optimizer.kind != "sweep" or len(study.variables) != 1:
        return
    plt = _plt()
    v = study.variables[0]
    xl, xu = _label(study, v.name)
    d = run_df[(run_df["source"] == "run") & (run_df["status"] == "ok")].sort_values(v.name)
    objs = list(study.objectives)
    fig, axes = _grid(plt, len(objs), width=4.2, height=3.3)
    numeric = _is_number_col(study, v.name)
    for k, (ax, o) in enumerate(zip(axes, objs)):
        lab, u = _label(study, o.label)
        x = xu(d[v.name].astype(float)) if numeric else d[v.name].astype(str)
        ax.plot(x, u(d[o.label].astype(float)), "o-", c="#1f77b4",
                label=f"{int(d['samples'].iloc[0]) if len(d) else ''} samples, one seed")
        if final is not None and f"{o.label}_stderr" in final and v.name in final:
            fb = final[final["source"] == "best"].sort_values(v.name)
            if len(fb):
                xf = xu(fb[v.name].astype(float)) if numeric else fb[v.name].astype(str)
                ax.errorbar(xf, u(fb[o.label].astype(float)), yerr=u(2 * fb[f"{o.label}_stderr"].astype(float)),
                            fmt="s", c="#d62728", capsize=4, ms=4,
                            label=f"re-evaluated, +-2 s.e. ({int(fb['samples'].iloc[0])} x {int(fb['repeats'].iloc[0])})")
        if study.reference and v.name in study.reference and numeric:
            ax.axvline(xu(study.reference[v.name]), c="#ff7f0e", ls="--", label=reference_short(study))
        ax.set_xlabel(xl, fontsize=9)
        ax.set_ylabel(lab, fontsize=9)
        ax.set_title(o.label, fontsize=9)
        ax.grid(alpha=0.3)
        _tidy(ax, x=numeric)
        if numeric and 1 < d[v.name].nunique() <= 6:  # a short sweep: ticks at the swept values
            ax.set_xticks(sorted(set(xu(d[v.name].astype(float)))))
        if k == 0:
            ax.legend(fontsize=7)
    figs.add(fig, "sweep", f"Sweep of {v.name}: each objective against the design variable (one panel per "
             "objective; red: re-evaluated mean with +-2 standard errors).")


def plot_designs(figs, study, designs: dict):
    """Mechanism sketches at home and workspace projections of named designs."""
    plt = _plt()
    mm = UNITS["length"]
    mechs = {}
    for name, values in designs.items():
        try:
            mechs[name] = load_mechanism(study.mechanism, **design_params(study, values))
        except ValueError:
            continue
    if not mechs:
        return
    fig = plt.figure(figsize=(5.2 * len(mechs), 4.6))
    for k, (name, mech) in enumerate(mechs.items()):
        ax = fig.add_subplot(1, len(mechs), k + 1, projection="3d")
        _, states, p = mech.leg_states(mech.home[None, :])
        for leg, st in zip(mech.legs, states):
            b, a = mm(st.base_point[0]), mm(st.platform_point[0])
            ax.plot([b[0], a[0]], [b[1], a[1]], [b[2], a[2]], "-", lw=2.5,
                    c="#1f77b4" if leg.is_actuated else "#2ca02c")
            anchor = mm(np.asarray(leg.base, float))
            ax.scatter(*anchor, c="k", s=12)  # the fixed end of the leg (caption)
            if np.linalg.norm(anchor - b) > 1e-6:  # a prismatic joint first: its anchor to the slider
                ax.plot(*np.vstack([anchor, b]).T, ls=":", c="#555555", lw=1.2)
        plat = mm(np.array([st.platform_point[0] for st in states]))
        if len(plat) >= 3:
            ax.plot(*np.vstack([plat, plat[:1]]).T, c="#ff7f0e", lw=1.5)
        ax.set_title(f"{name} at home ({mm.symbol})", fontsize=9)
        ax.set_xlabel("X")
        ax.set_ylabel("Y")
        ax.set_zlabel("Z")
    figs.add(fig, "designs", "Mechanism sketches at the home pose (blue: actuated legs, green: passive legs, "
             "black dots: the legs' fixed base anchors, dotted: a leg's first prismatic joint from its anchor to "
             "the slider, orange outline: the platform anchors).")
    ev = study.evaluation
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), layout="constrained")
    colors = ["#1f77b4", "#ff7f0e", "#2ca02c"]
    for k, ((name, mech), c) in enumerate(zip(mechs.items(), colors)):
        try:
            # Different sample points per design, so that the two clouds do not hide each other.
            ws = workspace_of(mech, ranges=ev.get("ranges"), n=32768, method=ev["method"], seed=ev["seed"] + 101 * (k + 1),
                              fixed=ev.get("fixed"), constraints=ev.get("constraints"))
        except ValueError:
            continue
        if ws.n_feasible == 0:
            continue
        P = mm(mech.pose(ws.points)[0])
        axes[0].scatter(P[:, 0], P[:, 1], s=2, alpha=0.25, c=c, label=name)
        axes[1].scatter(P[:, 0], P[:, 2], s=2, alpha=0.25, c=c, label=name)
    for ax, (a, b) in zip(axes, (("X", "Y"), ("X", "Z"))):
        ax.set_xlabel(mm.label(a))
        ax.set_ylabel(mm.label(b))
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        _tidy(ax)
        ax.legend(fontsize=8, markerscale=4)
    figs.add(fig, "workspace", "Feasible platform positions (projections on XY and XZ) of the recommended design and "
             f"{reference_name(study)}, from the study's evaluation samples.")


# -- report ---------------------------------------------------------------------------------------------
def _versions() -> dict:
    out = {"python": platform.python_version()}
    for pkg in ("parasynth", "numpy", "scipy", "pandas", "optuna", "nlopt", "cvxpy", "matplotlib"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    return out


def analyse(run: Run, noise_z: float = NOISE_Z) -> dict:
    """Front, knee, hypervolume and the paper design's standing (single-sample screening and,
    when ``final.csv`` holds it, the re-evaluated verdict) of a loaded run."""
    study, t = run.study, run.table
    runs = t[t["source"] == "run"].copy()
    objs = study.objectives
    labels = [o.label for o in objs]
    senses = [o.goal for o in objs]
    ok = (runs["status"] == "ok").to_numpy()
    feas = (runs["feasible"].astype(bool)).to_numpy() & ok
    F = runs[labels].to_numpy(float)
    front = pareto_front(study, runs)
    if len(front):  # best first in the first objective
        front = front.sort_values(labels[0], ascending=senses[0] == "minimize", kind="stable")
    out = {"runs": runs, "front": front, "labels": labels, "senses": senses, "noise_z": float(noise_z)}
    ref = t[t["source"] == "reference"]
    out["ref_row"] = ref.iloc[0] if len(ref) and ref.iloc[0]["status"] == "ok" else None
    knee_row = knee_of(study, front)
    if len(front) and len(objs) > 1:
        Fm = to_min(front[labels].to_numpy(float), senses)
        Ffeas = to_min(F[feas], senses)
        refpt = default_reference_point(Ffeas)
        out["hv_ref"] = refpt
        out["hv"] = hypervolume(Fm, refpt)
        ideal = Ffeas.min(axis=0)
        box = float(np.prod(refpt - ideal))
        out["hv_fraction"] = out["hv"] / box if box > 0 else float("nan")
    out["knee_row"] = knee_row
    if out["ref_row"] is not None and feas.any():
        out["standing"] = reference_standing(F[feas], senses, np.ones(feas.sum(), bool),
                                             out["ref_row"][labels].to_numpy(float), labels)
    out["final"] = _final_analysis(run, knee_row, noise_z)
    out["warnings"] = design_warnings(study, out)
    return out


def make_figures(run: Run, a: dict, keep: bool = False) -> Figures:
    """Every figure of the report for a loaded and analysed run."""
    study, runs, front = run.study, a["runs"], a["front"]
    figs = Figures(keep=keep)
    plot_sweep(figs, study, run.table, run.final)
    plot_pareto(figs, study, runs, front, a["ref_row"], a["knee_row"])
    plot_convergence(figs, study, runs)
    plot_parallel(figs, study, runs, front)
    designs = {}
    if a["knee_row"] is not None:
        designs["recommended"] = {v.name: a["knee_row"][v.name] for v in study.variables}
    if study.reference:
        designs[reference_short(study)] = dict(study.reference)
    try:
        plot_designs(figs, study, designs)
    except Exception as e:  # a picture must not cost the report
        figs.items.append(("designs_error", f"design pictures unavailable: {e}", b""))
    return figs


def write_report(run_dir, out=None, noise_z: float = NOISE_Z) -> Path:
    """Write index.html, report.md and pareto.csv for a run directory; returns the report dir.

    ``pareto.csv``: the distinct non-dominated feasible designs, columns as results.csv plus
    ``count`` (how many times the design was evaluated). ``noise_z``: a difference between
    re-evaluated designs counts when it exceeds this many combined standard errors."""
    run = load_run(run_dir)
    study = run.study
    out = Path(out) if out else Path("reports") / study.name
    out.mkdir(parents=True, exist_ok=True)
    a = analyse(run, noise_z=noise_z)
    to_csv_columns(study, a["front"]).to_csv(out / "pareto.csv", index=False)  # unit suffixes, SI values
    figs = make_figures(run, a)
    sections = _sections(run, a)
    (out / "img").mkdir(exist_ok=True)
    for name, _, png in figs.items:
        if png:
            (out / "img" / f"{name}.png").write_bytes(png)
    (out / "report.md").write_text(_markdown(run, sections, figs))
    (out / "index.html").write_text(_html(run, sections, figs))
    return out


def _final_analysis(run: Run, knee_row, noise_z: float) -> dict | None:
    """Re-evaluated designs compared with each other and with the reference, beyond noise."""
    study, fin = run.study, run.final
    labels = [o.label for o in study.objectives]
    senses = [o.goal for o in study.objectives]
    need = labels + [f"{lab}_stderr" for lab in labels] + ["source"]
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
        return row[labels].to_numpy(float), row[[f"{lab}_stderr" for lab in labels]].to_numpy(float)

    dominated_by = {}
    for i, ri in best.iterrows():
        mi, si = mse(ri)
        dominated_by[i] = [int(rj["trial"]) for j, rj in best.iterrows()
                           if j != i and compare_with_noise(*mse(rj), mi, si, senses, noise_z).verdict == "dominates"]
    # Which re-evaluated designs dominate the reference on the single-sample values: decided
    # from the run's table (the screening the report states), by design values.
    screen_keys = {design_key(study, r) for _, r in screening_dominators(study, run.table).iterrows()}
    fin["dominates_reference_screen"] = [r["source"] == "best" and design_key(study, r) in screen_keys
                                         for _, r in fin.iterrows()]
    best = fin[fin["source"] == "best"]
    out = {"table": fin, "best": best, "dominated_by": dominated_by, "ref": None, "vs_ref": [],
           "n_screen": len(screen_keys)}
    if len(ref):
        r = ref.iloc[0]
        out["ref"] = r
        rk = design_key(study, r) if all(v.name in r and pd.notna(r[v.name]) for v in study.variables) else None
        mr, sr = mse(r)
        for i, row in best.iterrows():
            if rk is not None and design_key(study, row) == rk:
                continue  # the paper's design itself among the re-evaluated ones
            out["vs_ref"].append((row, compare_with_noise(*mse(row), mr, sr, senses, noise_z)))
    # The knee as the report computes it must be the one re-evaluated (final.csv may be older
    # than a resumed run's table).
    out["knee"], out["knee_missing"] = None, knee_row is not None
    if knee_row is not None:
        kk = design_key(study, knee_row)
        hit = [i for i, r in best.iterrows() if design_key(study, r) == kk]
        fin["knee"] = False
        if hit:
            out["knee"], out["knee_missing"] = best.loc[hit[0]], False
            fin.loc[hit[0], "knee"] = True
    return out


def _design_values(study, row) -> str:
    parts = []
    for v in study.variables:
        val = row[v.name]
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


def _paper_text(run: Run, a: dict) -> str:
    study = run.study
    r = a["ref_row"]
    txt = (reference_name(study, capital=True, with_source=True) + ": " + ", ".join(_fmt_design(study, r))
           + " (single sample); feasible: "
           + ("yes" if bool(r["feasible"]) else "no") + ".")
    st = a.get("standing")
    fa = a.get("final")
    screened = ""
    if st is not None:
        screened = ((f"{st.n_dominating} evaluated feasible designs dominate it" if st.n_dominating > 1 else
                     "1 evaluated feasible design dominates it") if st.n_dominating
                    else "no evaluated feasible design dominates it")
    if fa is None or fa["ref"] is None:
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
    fin = fa["table"]
    z = a["noise_z"]
    txt += (f"\n\nVerdict on the re-evaluated values ({int(fin['repeats'].iloc[0])} seeds x "
            f"{int(fin['samples'].iloc[0])} samples; a difference counts when it exceeds {fmt_number(z)} "
            f"combined standard errors, otherwise it is within noise):")
    vs = fa["vs_ref"]
    dom = [(row, c) for row, c in vs if c.verdict == "dominates"]
    worse = [(row, c) for row, c in vs if c.verdict == "dominated"]
    same = [(row, c) for row, c in vs if c.verdict == "within noise"]
    ref = fa["ref"]
    if dom:
        txt += (f" {len(dom)} of the {len(vs)} re-evaluated designs {'dominates' if len(dom) == 1 else 'dominate'} it (better beyond noise on at least "
                "one objective, worse beyond noise on none): " + " | ".join(_comparison_text(study, row, c, ref)
                                                                          for row, c in dom) + ".")
    else:
        txt += f" none of the {len(vs)} re-evaluated designs dominates it beyond noise."
    if same:
        txt += " Equal to it within noise on every objective: " + ", ".join(f"trial {int(row['trial'])}" for row, _ in same) + "."
    if worse:
        txt += " Dominated by it: " + ", ".join(f"trial {int(row['trial'])}" for row, _ in worse) + "."
    if st is not None:
        txt += f"\n\n(Single-sample screening: {screened}; the re-evaluation above decides.)"
        txt += _screen_text(fa, fa.get("n_screen", 0))
    return txt


def _screen_text(fa: dict, n_screen: int) -> str:
    """How the designs that dominate the reference on single-sample values fared once
    re-evaluated (the ones re-evaluated: the largest normalised margins, see
    :func:`parasynth.study.final.screening_dominators`)."""
    if not n_screen:
        return ""
    sel = [(row, c) for row, c in fa["vs_ref"] if bool(row.get("dominates_reference_screen", False))]
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


def final_display_table(study, fa: dict) -> pd.DataFrame:
    """The re-evaluation table for people: role, trial, evaluations, design variables and each
    objective as ``mean ± standard error`` in display units, and the re-evaluated designs that
    dominate each one beyond noise."""
    fin = fa["table"]
    rows = []
    best_rows = fin[fin["source"] == "best"]
    why = dict(zip(best_rows.index, design_roles(study, best_rows))) if len(best_rows) else {}
    for i, r in fin.iterrows():
        other = "sweep point" if study.optimizer.kind == "sweep" else why.get(i, "best")
        rec = "recommended (knee)" if len(study.objectives) > 1 else "recommended (best)"
        role = other
        if r["source"] == "best" and bool(r.get("dominates_reference_screen", False)):
            role = f"dominates {reference_short(study)} (screening)"
        row = {"design": (reference_short(study) if r["source"] == "reference" else (rec if r["knee"] else role)),
               "trial": fmt_number(int(r["trial"]))}
        if "count" in fin:
            row["evaluations"] = fmt_number(int(r["count"])) if r["source"] == "best" else ""
        for v in study.variables:
            u = _unit(study, v.name)
            row[u.label(v.name)] = fmt_value(r[v.name], u) if _is_number_col(study, v.name) else str(r[v.name])
        for o in study.objectives:
            u = _unit(study, o.label)
            row[u.label(o.label)] = fmt_mean_se(r[o.label], r[f"{o.label}_stderr"], u)
        row["feasible"] = "yes" if bool(r.get("feasible", True)) else "no"
        if r["source"] == "best":
            d = fa["dominated_by"].get(i, [])
            row["dominated by (beyond noise)"] = ", ".join(f"trial {t}" for t in d) if d else "none"
        else:
            row["dominated by (beyond noise)"] = ", ".join(f"trial {int(x['trial'])}" for x, c in fa["vs_ref"]
                                                           if c.verdict == "dominates") or "none"
        rows.append(row)
    return pd.DataFrame(rows)


def _sections(run: Run, a: dict) -> list[tuple[str, str, pd.DataFrame | None]]:
    """(title, text, table) triples shared by the HTML and Markdown renderers."""
    study, t = run.study, run.table
    runs, front = a["runs"], a["front"]
    sec = []
    n_ok = int((runs["status"] == "ok").sum())
    n_feas = int((runs["feasible"].astype(bool) & (runs["status"] == "ok")).sum())
    ev = study.evaluation
    opt = study.optimizer
    elapsed = float(runs["time_s"].sum()) if len(runs) else 0.0
    text = (f"Mechanism **{study.mechanism}**; optimiser **{opt.kind}** "
            f"({opt.algorithm or 'default'}); budget {run.expected or opt.maxeval or opt.n_trials or '-'}; "
            f"evaluation: {ev['method']} sampling, {ev['n']} samples, seed {ev['seed']}. "
            f"{len(runs)} designs evaluated ({n_ok} completed, {n_feas} feasible, "
            f"{len(runs) - n_ok} failed); evaluation time {elapsed:.1f} s.")
    if run.partial:
        text = f"**PARTIAL REPORT: {run.partial_reason}.** " + text
    if study.spec.description:
        text = study.spec.description.strip() + "\n\n" + text
    sec.append(("Summary", text, None))
    if a.get("warnings"):
        sec.append(("Warnings", "\n\n".join("**Warning:** " + w[:1].upper() + w[1:] for w in a["warnings"]), None))
    if len(study.objectives) > 1 and "hv" in a and len(front) >= 2:
        refs = []
        for o, x in zip(study.objectives, a["hv_ref"]):
            val = x if o.goal == "minimize" else -x
            refs.append(f"{o.label} {fmt_quantity(val, _unit(study, o.label))}")
        units = [_unit(study, o.label) for o in study.objectives]
        sym = " x ".join(u.symbol for u in units if u.symbol)
        hv_disp = a["hv"] * float(np.prod([u.factor for u in units]))
        sec.append(("Hypervolume", f"Hypervolume of the feasible non-dominated set: {fmt_number(a['hv_fraction'], 3)} "
                    f"of the box between the ideal point and the reference point (normalised: 1 would be a front "
                    f"at the ideal point; {fmt_number(hv_disp)}{' ' + sym if sym else ''} in display units). "
                    f"Reference point: the worst feasible value of each objective plus 10 % of its range: "
                    + ", ".join(refs) + ". It measures how much of the objective space the front covers; "
                    "compare it between runs of this study only.", None))
    if len(front):
        k = a["knee_row"]
        n_dup = int((front["count"] > 1).sum()) if "count" in front else 0
        txt = (f"{len(front)} distinct non-dominated feasible designs"
               + (f" ({n_dup} of them evaluated more than once: column evaluations)" if n_dup else "")
               + (". Recommended (knee of the front)" if len(study.objectives) > 1 else ". Recommended (the best)")
               + f": trial {int(k['trial'])}: " + ", ".join(_fmt_design(study, k))
               + " (single sample)")
        fa = a.get("final")
        if fa is not None and fa.get("knee") is not None:
            kr = fa["knee"]
            txt += ("; re-evaluated: " + ", ".join(
                f"{o.label} = {fmt_mean_se(kr[o.label], kr[o.label + '_stderr'], _unit(study, o.label), True)}"
                for o in study.objectives))
        txt += "."
        if fa is not None:
            keys = {design_key(study, r): i for i, r in fa["best"].iterrows()}
            notes = []
            for _, r in front.iterrows():
                i = keys.get(design_key(study, r))
                if i is not None and fa["dominated_by"].get(i):
                    notes.append(f"trial {int(r['trial'])} (by " + ", ".join(f"trial {t}" for t in fa["dominated_by"][i]) + ")")
            if notes:
                txt += (" On the re-evaluated values some of these designs are dominated beyond noise: "
                        + "; ".join(notes) + ".")
        if fa is not None and fa.get("knee_missing"):
            txt += (" final.csv does not hold this design (it was written before the run's last designs): its "
                    "re-evaluated values are not known; run the study again with --resume to redo the final stage.")
        sec.append(("Non-dominated designs", txt, display_table(study, front)))
    else:
        sec.append(("Non-dominated designs", "No feasible design was found.", None))
    if a["ref_row"] is not None:
        sec.append((reference_name(study, capital=True), _paper_text(run, a),
                    display_table(study, t[t["source"] == "reference"])))
    fa = a.get("final")
    if fa is not None:
        fin = fa["table"]
        sec.append(("Re-evaluation of the best designs",
                    f"Mean ± standard error over {int(fin['repeats'].iloc[0])} seeds with "
                    f"{int(fin['samples'].iloc[0])} samples each, for the best designs, the recommended (knee) "
                    f"design, the designs that dominate {reference_name(study)} on single samples by the largest "
                    f"normalised margin and {reference_name(study)}. A design is dominated beyond noise when another is better by "
                    f"more than {fmt_number(a['noise_z'])} combined standard errors on some objective and worse by "
                    f"as much on none.", final_display_table(study, fa)))
    elif run.final is not None and len(run.final):
        sec.append(("Re-evaluation of the best designs", "final.csv (columns as written by the run):", run.final))
    if study.constraints or (runs["status"] != "ok").any():
        rows = []
        for c in study.constraints:
            m = runs[f"{c.label}_margin"]
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


def _fmt_design(study, row) -> list[str]:
    parts = [_design_values(study, row)] if study.variables else []
    for o in study.objectives:
        parts.append(f"{o.label} = {fmt_quantity(row[o.label], _unit(study, o.label))}")
    return parts


def _md_table(df: pd.DataFrame) -> str:
    cols = list(df.columns)
    lines = ["| " + " | ".join(str(c) for c in cols) + " |", "|" + "---|" * len(cols)]
    for _, r in df.iterrows():
        lines.append("| " + " | ".join(_cell(r[c]) for c in cols) + " |")
    return "\n".join(lines)


def _cell(x) -> str:
    return fmt_number(x) if isinstance(x, (float, np.floating)) else str(x)


def _markdown(run, sections, figs) -> str:
    out = [f"# Study report: {run.study.name}", ""]

    def section(title, text, table):
        nonlocal out
        out += [f"## {title}", "", text, ""]
        if table is not None and len(table):
            out += [_md_table(table), ""]
        if title == "Study and software":
            out += ["```yaml", run.study.to_yaml().rstrip(), "```", ""]

    for sec in sections[:-1]:
        section(*sec)
    out += ["## Figures", ""]
    for name, caption, png in figs.items:
        if png:
            out += [f"![{name}](img/{name}.png)", "", f"*{caption}*", ""]
        else:
            out += [f"*{caption}*", ""]
    section(*sections[-1])  # study file and software versions last
    return "\n".join(out)


def _html(run, sections, figs) -> str:
    esc = html.escape
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>parasynth report: {esc(run.study.name)}</title>",
        "<style>body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}"
        "table{border-collapse:collapse;font-size:13px;margin:.5em 0}td,th{border:1px solid #ccc;padding:3px 6px;"
        "text-align:right;white-space:nowrap}th{background:#f3f3f3}.table-wrap{overflow-x:auto;max-width:100%}figure{margin:1.5em 0}img{max-width:100%}"
        ".partial{background:#fff3cd;border:1px solid #e0c36a;padding:.6em}pre{background:#f6f6f6;padding:.8em;"
        "overflow:auto;font-size:12px}</style></head><body>",
        f"<h1>Study report: {esc(run.study.name)}</h1>",
    ]
    if run.partial:
        parts.append(f"<p class='partial'><b>Partial report:</b> {esc(run.partial_reason)}.</p>")
    def section(title, text, table):
        parts.append(f"<h2>{esc(title)}</h2>")
        parts.append("<p>" + _md_inline(esc(text)) + "</p>")
        if table is not None and len(table):
            parts.append("<div class='table-wrap'>" + table.to_html(index=False, float_format=fmt_number, na_rep="",
                                                                    border=0, classes="designs") + "</div>")
        if title == "Study and software":
            parts.append(f"<pre>{esc(run.study.to_yaml())}</pre>")

    for sec in sections[:-1]:
        section(*sec)
    parts.append("<h2>Figures</h2>")
    for name, caption, png in figs.items:
        if png:
            b64 = base64.b64encode(png).decode()
            parts.append(f"<figure id='fig-{name}'><img alt='{esc(name)}' src='data:image/png;base64,{b64}'>"
                         f"<figcaption>{esc(caption)}</figcaption></figure>")
        else:
            parts.append(f"<p><i>{esc(caption)}</i></p>")
    section(*sections[-1])  # study file and software versions last
    parts.append("</body></html>")
    return "\n".join(parts)


def _md_inline(s: str) -> str:
    return re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", s).replace("\n\n", "</p><p>")
