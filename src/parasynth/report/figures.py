"""The report's figures as PNG bytes (:class:`Figures`): the Pareto front (pair panels), the
convergence, parallel coordinates, a one-variable sweep, and the sketches and workspaces of
the recommended and reference designs. matplotlib (Agg) is imported on the first figure."""

from __future__ import annotations

import io

import numpy as np
import pandas as pd

from ..measures.display import UNITS, Unit, fmt_number, fmt_value, reference_name, reference_short
from ..measures.objectives import USABLE_MEASURES, usable_workspace_of, workspace_of
from ..common.pareto import FAR_FENCE, default_reference_point, hypervolume, to_min, view_range
from ..study.rundir import Run, design_mechanism, measure_settings

#: Lengths in the sketches: the display unit of lengths (the tables' unit).
mm = UNITS["length"]
from .analysis import Analysis
from .tables import is_number_col as _is_number_col
from .tables import unit as _unit
from ..common import columns as derived

__all__ = ["Figures", "make_figures", "plot_pareto", "plot_parallel", "plot_convergence", "plot_sweep", "plot_designs",
           "sketch_boxes"]


def _figure(**kw):
    """A matplotlib figure drawn by Agg, outside pyplot: no global backend switch, no figure
    manager, nothing to close."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # lazy: matplotlib costs ~0.5 s; figures only
    from matplotlib.figure import Figure  # lazy: as above

    fig = Figure(**kw)
    FigureCanvasAgg(fig)
    return fig


def _subplots(*args, figsize, layout="constrained", **kw):
    fig = _figure(figsize=figsize, layout=layout)
    return fig, fig.subplots(*args, **kw)


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
        # Every figure is laid out to fit its canvas (a constrained layout, or fixed margins for
        # the 3D sketches): no "tight" bounding box, which would cost one more layout pass.
        fig.savefig(buf, format="png", dpi=110)
        if self.keep:
            self.figures[name] = fig
        self.items.append((name, caption, buf.getvalue()))


def _label(study, lab) -> tuple[str, Unit]:
    u = _unit(study, lab)
    return u.label(lab), u


def _tidy(ax, x=True, y=True):
    """Few, plainly formatted ticks (no offset text, no scientific multiplier) so that tick
    labels do not run into each other at the figure's size."""
    from matplotlib.ticker import MaxNLocator, ScalarFormatter  # lazy: matplotlib, as in _figure

    for on, axis in ((x, ax.xaxis), (y, ax.yaxis)):
        if not on:
            continue
        axis.set_major_locator(MaxNLocator(nbins=5, min_n_ticks=3))
        fmt = ScalarFormatter(useOffset=False)
        fmt.set_scientific(True)
        fmt.set_powerlimits((-4, 6))
        axis.set_major_formatter(fmt)
    ax.tick_params(labelsize=8)


def _grid(n, width=4.4, height=3.5, max_cols=3):
    """``n`` panels in a grid that wraps after ``max_cols`` columns (unused cells hidden)."""
    cols = max(1, min(max_cols, n))
    rows = int(np.ceil(n / cols))
    fig, axes = _subplots(rows, cols, figsize=(width * cols, height * rows), squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    return fig, axes.ravel()[:n]


def plot_pareto(figs, study, run_df, front, ref_row, knee_row):
    objs = study.objectives
    if len(objs) < 2:
        return
    pairs = [(i, j) for i in range(len(objs)) for j in range(i + 1, len(objs))]
    fig, axes = _grid(len(pairs), width=5.2 if len(pairs) == 1 else 4.6, height=3.8)
    ok = run_df["status"] == "ok"
    outside = 0
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
                       edgecolors="#2ca02c", linewidths=2, label="recommended", zorder=5)
        if ref_row is not None:
            ax.scatter([fa(ref_row[a])], [fb(ref_row[b])], s=220, marker="*", c="#ff7f0e", edgecolors="k",
                       label=reference_short(study), zorder=6)
        ax.set_xlabel(f"{la} ({objs[i].goal})", fontsize=9)
        ax.set_ylabel(f"{lb} ({objs[j].goal})", fontsize=9)
        # The axes span the feasible designs without their far outliers, the front and the marked
        # designs (as the interactive plot's): a few designs near a singularity would squash the rest.
        marked = [r for r in (knee_row, ref_row) if r is not None]
        for col, f, setlim in ((a, fa, ax.set_xlim), (b, fb, ax.set_ylim)):
            keep = np.concatenate([np.asarray(f(fr[col]), float)] + [np.atleast_1d(np.asarray(f(r[col]), float)) for r in marked])
            rng = view_range(np.asarray(f(fea[col]), float), keep)
            if rng is not None:
                setlim(*rng)
        xs, ys = (np.asarray(fa(run_df.loc[ok, a]), float), np.asarray(fb(run_df.loc[ok, b]), float))
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
        outside += int(np.sum(np.isfinite(xs) & np.isfinite(ys) & ((xs < x0) | (xs > x1) | (ys < y0) | (ys > y1))))
        ax.grid(alpha=0.3)
        _tidy(ax)
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", ncols=3 if len(pairs) == 1 else 5, fontsize=8)
    fig.suptitle(f"Pareto front: {study.name}")
    cut = (f" The axes span the feasible designs, the front and the marked designs; {outside} designs lie "
           "beyond them (far outliers, or infeasible)." if outside else "")
    figs.add(fig, "pareto", "Objective space: every evaluated design, the non-dominated feasible set, the "
             f"recommended design and {reference_name(study)}.{cut}")


def plot_parallel(figs, study, run_df, front):
    cols = [v.name for v in study.variables if v.type != "categorical"] + [o.label for o in study.objectives]
    if len(cols) < 2:
        return
    from matplotlib.collections import LineCollection  # lazy: matplotlib, as in _figure

    d = run_df[run_df["status"] == "ok"][cols + ["feasible"]].copy()
    d[cols] = d[cols].astype(float)
    on_front = set(front["trial"]) if "trial" in front else set()
    trials = run_df.loc[d.index, "trial"] if "trial" in run_df else pd.Series(-1, index=d.index)
    on = trials.isin(on_front).to_numpy()
    # A design variable's axis spans its designs (bounded by the design space); an objective's
    # spans the designs without their far outliers and every front design (a design near a
    # singularity would flatten it), lines beyond drawn at its ends.
    objective = {o.label for o in study.objectives}
    spans = {c: view_range(d[c].to_numpy(float), d[c].to_numpy(float)[on], pad=0.0,
                           fence=FAR_FENCE if c in objective else None) or [0.0, 1.0] for c in cols}
    lo, hi = pd.Series({c: spans[c][0] for c in cols}), pd.Series({c: spans[c][1] for c in cols})
    Z = ((d[cols] - lo) / (hi - lo).replace(0, 1)).clip(-0.04, 1.04)
    fig, ax = _subplots(figsize=(max(6.0, 2.2 * len(cols)), 4.4))
    x = np.arange(len(cols))
    feas = d["feasible"].astype(bool).to_numpy()
    Y = Z.to_numpy(float)
    # One collection of polylines per kind of design (vectorised: one artist, not one per design).
    for mask, color, alpha, lw, z in ((~on & ~feas, "#f4b6b6", 0.35, 0.7, 1), (~on & feas, "#bbbbbb", 0.35, 0.7, 1),
                                      (on, "#1f77b4", 0.9, 1.6, 3)):
        if mask.any():
            segs = np.stack([np.broadcast_to(x, Y[mask].shape), Y[mask]], axis=-1)
            ax.add_collection(LineCollection(segs, colors=color, alpha=alpha, linewidths=lw, zorder=z))
    ax.set_ylim(-0.05, 1.05)
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
    figs.add(fig, "parallel", "Design variables and objectives of every design, scaled to their ranges (an "
             "objective's far outliers, beyond 3 interquartile ranges outside the quartiles, drawn at its axis's ends).")


def plot_convergence(figs, study, run_df):
    d = run_df[run_df["source"] == "run"].sort_values("trial").reset_index(drop=True)
    if not len(d):
        return
    objs = study.objectives
    fig, ax = _subplots(figsize=(6, 3.6))
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
            return
        ref = default_reference_point(Fm[feas], fence=FAR_FENCE)
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
    if not study.optimizer.plugin.lists_designs or len(study.variables) != 1:
        return
    v = study.variables[0]
    xl, xu = _label(study, v.name)
    d = run_df[(run_df["source"] == "run") & (run_df["status"] == "ok")].sort_values(v.name)
    objs = list(study.objectives)
    fig, axes = _grid(len(objs), width=4.2, height=3.3)
    numeric = _is_number_col(study, v.name)
    for k, (ax, o) in enumerate(zip(axes, objs)):
        lab, u = _label(study, o.label)
        x = xu(d[v.name].astype(float)) if numeric else d[v.name].astype(str)
        ax.plot(x, u(d[o.label].astype(float)), "o-", c="#1f77b4",
                label=f"{int(d['samples'].iloc[0]) if len(d) else ''} samples, one seed")
        if final is not None and derived.stderr(o.label) in final and v.name in final:
            fb = final[final["source"] == "best"].sort_values(v.name)
            if len(fb):
                xf = xu(fb[v.name].astype(float)) if numeric else fb[v.name].astype(str)
                ax.errorbar(xf, u(fb[o.label].astype(float)), yerr=u(2 * fb[derived.stderr(o.label)].astype(float)),
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
    mechs = {}
    for name, values in designs.items():
        try:
            mechs[name] = design_mechanism(study, values)
        except ValueError:
            continue
    if not mechs:
        return
    from matplotlib.ticker import MaxNLocator  # lazy: matplotlib, as in _figure

    homes = {name: mech.leg_states(mech.home[None, :])[1] for name, mech in mechs.items()}
    boxes = sketch_boxes({name: _sketch_points(mech, homes[name]) for name, mech in mechs.items()})
    # 3D panels: fixed margins (a layout engine would draw the figure twice when saving)
    fig = _figure(figsize=(5.2 * len(mechs), 4.6))
    fig.subplots_adjust(left=0.0, right=0.96, bottom=0.03, top=0.95, wspace=0.08)
    for k, (name, mech) in enumerate(mechs.items()):
        ax = fig.add_subplot(1, len(mechs), k + 1, projection="3d")
        # One scale for every sketch: the same cube's side, drawn the same size in an orthographic
        # view, so that a length covers the same pixels in each (the designs compare by eye).
        ax.set_proj_type("ortho")
        ax.set_box_aspect((1.0, 1.0, 1.0))
        lo, hi = boxes[name]
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
        states = homes[name]
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
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):  # few ticks: legible, and fewer labels to lay out
            axis.set_major_locator(MaxNLocator(nbins=4))
        ax.tick_params(labelsize=8)
    side = next(iter(boxes.values()))
    figs.add(fig, "designs", "Mechanism sketches at the home pose, all at one scale (orthographic views of cubes "
             f"of the same side, {fmt_number(float(side[1][0] - side[0][0]), 3)} {mm.symbol}, each centred on its "
             "design: a length covers the same pixels in every sketch) (blue: actuated legs, green: passive legs, "
             "black dots: the legs' fixed base anchors, dotted: a leg's first prismatic joint from its anchor to "
             "the slider, orange outline: the platform anchors).")
    ev = study.evaluation
    usable = _usable_measure(study)
    rows = len(mechs) if usable is not None else 1  # the usable component: one row per design
    fig, grid = _subplots(rows, 2, figsize=(10, 4.2 if rows == 1 else 3.8 * rows), squeeze=False)
    colors = ["#1f77b4", "#ff7f0e", "#2ca02c"]
    for k, ((name, mech), c) in enumerate(zip(mechs.items(), colors)):
        axes = grid[k if usable is not None else 0]
        if usable is not None and _plot_usable(axes, study, usable, name, mech, c):
            continue
        try:
            # Different sample points per design, so that the two clouds do not hide each other.
            ws = workspace_of(mech, ranges=ev.get("ranges"), n=32768, method=ev["method"], seed=ev["seed"] + 101 * (k + 1),
                              fixed=ev.get("fixed"), constraints=ev.get("constraints"))
        except ValueError:
            continue
        if ws.n_feasible == 0:
            continue
        P = mm(mech.pose(ws.points)[0])
        # markers of one line, not a scatter collection: the same dots, drawn several times faster
        axes[0].plot(P[:, 0], P[:, 1], "o", ms=2.4, mew=0, alpha=0.3, c=c, label=name)
        axes[1].plot(P[:, 0], P[:, 2], "o", ms=2.4, mew=0, alpha=0.3, c=c, label=name)
    for ax, (a, b) in zip(grid.ravel(), (("X", "Y"), ("X", "Z")) * rows):
        ax.set_xlabel(mm.label(a))
        ax.set_ylabel(mm.label(b))
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        _tidy(ax)
        if ax.lines:
            ax.legend(fontsize=8, markerscale=3)
    what = ("Feasible platform positions (projections on XY and XZ) of the recommended design and "
            f"{reference_name(study)}, from the study's evaluation samples.")
    if usable is not None:
        what = ("Platform positions (projections on XY and XZ; one row per design) of the recommended design and "
                f"{reference_name(study)} at the centres of the usable-workspace grid ({usable.label}): dots, the "
                "usable component connected to the home pose; grey crosses, the rest of the feasible set (beyond a "
                "singularity or below the singularity-margin floor), which the platform cannot reach from home.")
    figs.add(fig, "workspace", what)


def _sketch_points(mech, states) -> np.ndarray:
    """Every point a sketch draws (display units): base anchors, leg ends, platform anchors."""
    pts = [np.asarray(leg.base, float) for leg in mech.legs]
    for st in states:
        pts += [st.base_point[0], st.platform_point[0]]
    return mm(np.array(pts))


def sketch_boxes(points: dict, pad: float = 0.05) -> dict:
    """{name: (lo, hi)} axis limits of the design sketches: cubes of one side for all designs
    (the largest extent of any design along any axis, plus ``pad`` of it), each centred on its
    design's points, so that every sketch has the same scale."""
    centre = {n: (P.min(axis=0) + P.max(axis=0)) / 2 for n, P in points.items()}
    half = max(float(np.max(P.max(axis=0) - P.min(axis=0))) for P in points.values()) / 2 * (1 + pad)
    half = half if half > 0 else 1.0
    return {n: (c - half, c + half) for n, c in centre.items()}


def _usable_measure(study):
    """The study's first objective or constraint over the usable component, or None."""
    for m in list(study.objectives) + list(study.constraints):
        if m.name in USABLE_MEASURES or (m.name.startswith("inscribed_box") and m.settings.get("region") == "usable"):
            return m
    return None


def _plot_usable(axes, study, item, name, mech, color) -> bool:
    """Draw the usable component of ``mech`` apart from the rest of its feasible set (the grid
    of the measure ``item``); False when it cannot be computed (the caller draws the samples)."""
    kw = {k: v for k, v in measure_settings(study, item.name, item.settings).items()
          if k not in ("coords", "region", "axis")}
    try:
        u = usable_workspace_of(mech, **kw)
    except (ValueError, ArithmeticError):
        return False
    for mask, style in ((u.feasible & ~u.usable, dict(marker="x", ms=2.6, c="#9a9a9a", alpha=0.5,
                                                      label=f"{name}: feasible, not usable")),
                        (u.usable, dict(marker="o", ms=2.4, mew=0, c=color, alpha=0.35,
                                        label=f"{name}: usable ({u.fraction:.0%} of the feasible)"))):
        if not mask.any():
            continue
        P = mm(mech.pose(u.centres(mask))[0])
        axes[0].plot(P[:, 0], P[:, 1], ls="none", **style)
        axes[1].plot(P[:, 0], P[:, 2], ls="none", **style)
    return True


def make_figures(run: Run, a: Analysis, keep: bool = False) -> Figures:
    """Every figure of the report for a loaded and analysed run."""
    study, runs, front = run.study, a.runs, a.front
    figs = Figures(keep=keep)
    plot_sweep(figs, study, run.table, run.final)
    plot_pareto(figs, study, runs, front, a.ref_row, a.knee_row)
    plot_convergence(figs, study, runs)
    plot_parallel(figs, study, runs, front)
    designs = {}
    if a.knee_row is not None:
        designs["recommended"] = {v.name: a.knee_row[v.name] for v in study.variables}
    if study.reference:
        designs[reference_short(study)] = dict(study.reference)
    try:
        plot_designs(figs, study, designs)
    except Exception as e:  # a picture must not cost the report
        figs.items.append(("designs_error", f"design pictures unavailable: {e}", b""))
    return figs
