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
import io
import json
import platform
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .pareto import default_reference_point, hypervolume, knee_index, pareto_mask, reference_standing, to_min

__all__ = ["write_report", "ReportError", "load_run"]


class ReportError(ValueError):
    """The run directory cannot be reported (missing, empty, unreadable)."""


@dataclass
class Run:
    study: object  # ResolvedStudy
    table: pd.DataFrame
    final: pd.DataFrame | None
    run_dir: Path
    partial: bool
    partial_reason: str
    expected: int | None


def _expected(study) -> int | None:
    opt = study.optimizer
    if opt.kind == "sweep":
        if opt.designs:
            return len(opt.designs)
        n = 1
        for v in study.variables:
            n *= len(v.values if v.values is not None else v.choices)
        return n
    if opt.kind == "optuna":
        return opt.n_trials or 50
    return None  # NLopt may stop early on its tolerances


def load_run(run_dir) -> Run:
    from ..study import load_study
    from ..study.runner import read_journal, results_table
    from ..study.spec import StudyError

    run_dir = Path(run_dir)
    if not run_dir.exists():
        raise ReportError(f"run directory {str(run_dir)!r} does not exist; run the study first (parasynth run STUDY.yaml)")
    sy = run_dir / "study.yaml"
    if not sy.exists():
        raise ReportError(f"{str(run_dir)!r} is not a run directory (no study.yaml); run the study first")
    try:
        study = load_study(sy)
    except StudyError as e:
        raise ReportError(f"{sy}: {e}") from None
    records = read_journal(run_dir)
    if not records:
        raise ReportError(f"{str(run_dir)!r} holds no evaluated designs yet; run (or resume) the study")
    table = results_table(study, records)
    final = None
    if (run_dir / "final.csv").exists():
        try:
            final = pd.read_csv(run_dir / "final.csv")
        except (pd.errors.EmptyDataError, pd.errors.ParserError):
            final = None
    n_run = int((table["source"] == "run").sum())
    expected = _expected(study)
    partial, reason = False, ""
    if expected is not None and n_run < expected:
        partial, reason = True, f"{n_run} of {expected} planned designs evaluated (interrupted run?)"
    return Run(study, table, final, run_dir, partial, reason, expected)


# -- formatting ----------------------------------------------------------------------------------
def _measure(name):
    from ..objectives import OBJECTIVES

    return OBJECTIVES.get(name)


_DISPLAY = {"length": (1e3, "mm"), "angle": (180 / np.pi, "deg")}


def _var_display(v):
    return _DISPLAY.get(v.kind, (1.0, ""))


def _obj_display(study, label):
    for o in list(study.objectives) + list(study.constraints):
        if o.label == label:
            m = _measure(o.name)
            if m is not None and m.kind in _DISPLAY:
                return _DISPLAY[m.kind]
            if m is not None and m.unit == "sampled units":
                return 1.0, _sampled_units(study, o)
            return 1.0, (m.unit if m is not None and m.unit not in ("1", "mixed") else "")
    return 1.0, ""


def _sampled_units(study, o) -> str:
    ranges = o.settings.get("ranges") or study.evaluation.get("ranges")
    if not ranges:
        return "(task-space units)"
    ang = {"alpha", "beta", "gamma", "psi", "theta", "phi"}
    nl = sum(1 for k in ranges if k not in ang)
    na = len(ranges) - nl
    parts = ([f"m^{nl}" if nl > 1 else "m"] if nl else []) + ([f"rad^{na}" if na > 1 else "rad"] if na else [])
    return " ".join(parts)


def display_table(study, df: pd.DataFrame) -> pd.DataFrame:
    """Columns of a results table in engineering units (mm, deg), renamed with the unit."""
    out = pd.DataFrame(index=df.index)
    for c in ["trial"]:
        if c in df:
            out[c] = df[c]
    for v in study.variables:
        f, u = _var_display(v)
        col = df[v.name]
        out[f"{v.name} [{u}]" if u else v.name] = col * f if v.type != "categorical" and v.kind else col
    for o in study.objectives:
        f, u = _obj_display(study, o.label)
        out[f"{o.label} [{u}]" if u else o.label] = df[o.label] * f
    for c in study.constraints:
        f, u = _obj_display(study, c.label)
        out[f"{c.label} [{u}]" if u else c.label] = df[c.label] * f
    if "feasible" in df:
        out["feasible"] = df["feasible"]
    return out


# -- plots -------------------------------------------------------------------------------------------
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


class Figures:
    """Collects figures as PNG bytes: inlined in HTML, written to img/ for Markdown."""

    def __init__(self):
        self.items: list[tuple[str, str, bytes]] = []  # (name, caption, png)

    def add(self, fig, name, caption):
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        _plt().close(fig)
        self.items.append((name, caption, buf.getvalue()))


def _label(study, lab):
    f, u = _obj_display(study, lab)
    return (f"{lab} [{u}]" if u else lab), f


def plot_pareto(figs, study, run_df, front, ref_row, knee_row):
    objs = study.objectives
    if len(objs) < 2:
        return
    plt = _plt()
    pairs = [(i, j) for i in range(len(objs)) for j in range(i + 1, len(objs))]
    n = len(pairs)
    cols = min(3, n)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 4.2 * rows), squeeze=False)
    ok = run_df["status"] == "ok"
    for ax, (i, j) in zip(axes.ravel(), pairs):
        a, b = objs[i].label, objs[j].label
        la, fa = _label(study, a)
        lb, fb = _label(study, b)
        inf = run_df[ok & ~run_df["feasible"]]
        fea = run_df[ok & run_df["feasible"]]
        ax.scatter(inf[a] * fa, inf[b] * fb, s=10, c="#d62728", alpha=0.35, label="infeasible")
        ax.scatter(fea[a] * fa, fea[b] * fb, s=12, c="#7f7f7f", alpha=0.6, label="feasible")
        fr = front.sort_values(a)
        ax.plot(fr[a] * fa, fr[b] * fb, "o-", c="#1f77b4", ms=5, lw=1.2, label="non-dominated")
        if knee_row is not None:
            ax.scatter([knee_row[a] * fa], [knee_row[b] * fb], s=140, marker="D", facecolors="none",
                       edgecolors="#2ca02c", linewidths=2, label="recommended (knee)", zorder=5)
        if ref_row is not None:
            ax.scatter([ref_row[a] * fa], [ref_row[b] * fb], s=220, marker="*", c="#ff7f0e", edgecolors="k",
                       label="paper design", zorder=6)
        ax.set_xlabel(f"{la} ({objs[i].goal})")
        ax.set_ylabel(f"{lb} ({objs[j].goal})")
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    axes.ravel()[0].legend(fontsize=8, loc="best")
    fig.suptitle(f"Pareto front: {study.name}")
    figs.add(fig, "pareto", "Objective space: every evaluated design, the non-dominated feasible set, the "
             "recommended design and the paper's design.")


def plot_parallel(figs, study, run_df, front):
    cols = [v.name for v in study.variables if v.type != "categorical"] + [o.label for o in study.objectives]
    if len(cols) < 2:
        return
    plt = _plt()
    d = run_df[run_df["status"] == "ok"][cols + ["feasible"]].copy()
    lo, hi = d[cols].min(), d[cols].max()
    Z = (d[cols] - lo) / (hi - lo).replace(0, 1)
    fig, ax = plt.subplots(figsize=(max(6, 1.6 * len(cols)), 4))
    x = np.arange(len(cols))
    for idx, row in Z.iterrows():
        on = idx in front.index
        feas = bool(d.loc[idx, "feasible"])
        ax.plot(x, row.values, c="#1f77b4" if on else ("#bbbbbb" if feas else "#f4b6b6"),
                alpha=0.9 if on else 0.35, lw=1.6 if on else 0.7, zorder=3 if on else 1)
    ax.set_xticks(x)
    labels = []
    for c in cols:
        v = next((v for v in study.variables if v.name == c), None)
        f, u = _var_display(v) if v else _obj_display(study, c)
        labels.append(f"{c}\n[{lo[c] * f:.3g}, {hi[c] * f:.3g}] {u}")
    ax.set_xticklabels(labels, fontsize=8)
    ax.set_yticks([])
    ax.set_title("Parallel coordinates (blue: non-dominated feasible; grey: feasible; red: infeasible)")
    figs.add(fig, "parallel", "Design variables and objectives of every design, scaled to their ranges.")


def plot_convergence(figs, study, run_df):
    plt = _plt()
    d = run_df[run_df["source"] == "run"].sort_values("trial").reset_index(drop=True)
    if not len(d):
        return
    objs = study.objectives
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ok = (d["status"] == "ok") & d["feasible"]
    if len(objs) == 1:
        o = objs[0]
        lab, f = _label(study, o.label)
        vals = np.where(ok, d[o.label], np.nan) * f
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
        ax.plot(np.arange(1, len(d) + 1), hv, "-", c="#1f77b4")
        ax.set_ylabel("hypervolume of feasible front")
    ax.set_xlabel("evaluations")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8) if len(objs) == 1 else None
    figs.add(fig, "convergence", "Convergence: best feasible value (one objective) or hypervolume of the feasible "
             "non-dominated set (several objectives, reference point as in the summary) against evaluations.")


def plot_sweep(figs, study, run_df, final):
    if study.optimizer.kind != "sweep" or len(study.variables) != 1:
        return
    plt = _plt()
    v = study.variables[0]
    fv, uv = _var_display(v)
    d = run_df[(run_df["source"] == "run") & (run_df["status"] == "ok")].sort_values(v.name)
    objs = list(study.objectives)
    fig, axes = plt.subplots(1, len(objs), figsize=(4.6 * len(objs), 3.6), squeeze=False)
    for ax, o in zip(axes[0], objs):
        lab, f = _label(study, o.label)
        x = d[v.name] * fv if v.kind else d[v.name]
        ax.plot(x, d[o.label] * f, "o-", c="#1f77b4", label=f"{int(d['samples'].iloc[0]) if len(d) else ''} samples")
        if final is not None and f"{o.label}_stderr" in final and v.name in final:
            fb = final[final["source"] == "best"].sort_values(v.name)
            if len(fb):
                xf = fb[v.name] * fv if v.kind else fb[v.name]
                ax.errorbar(xf, fb[o.label] * f, yerr=2 * fb[f"{o.label}_stderr"] * f, fmt="s", c="#d62728", capsize=4,
                            label=f"re-evaluated, +-2 s.e. ({int(fb['samples'].iloc[0])} x {int(fb['repeats'].iloc[0])})")
        if study.reference and v.name in study.reference:
            ax.axvline(study.reference[v.name] * (fv if v.kind else 1), c="#ff7f0e", ls="--", label="paper's choice")
        ax.set_xlabel(f"{v.name} [{uv}]" if uv else v.name)
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    figs.add(fig, "sweep", f"Sweep of {v.name}: each objective against the design variable.")


def plot_designs(figs, study, designs: dict):
    """Mechanism sketches at home and workspace projections of named designs."""
    from ..mechanisms import load_mechanism
    from ..objectives import workspace_of

    plt = _plt()
    mechs = {}
    for name, values in designs.items():
        try:
            tied = {k: values[v] for k, v in study.tied.items() if v in values}
            mechs[name] = load_mechanism(study.mechanism, **{**study.fixed, **values, **tied})
        except ValueError:
            continue
    if not mechs:
        return
    fig = plt.figure(figsize=(5.2 * len(mechs), 4.6))
    for k, (name, mech) in enumerate(mechs.items()):
        ax = fig.add_subplot(1, len(mechs), k + 1, projection="3d")
        _, states, p = mech.leg_states(mech.home[None, :])
        for leg, st in zip(mech.legs, states):
            b, a = st.base_point[0] * 1e3, st.platform_point[0] * 1e3
            ax.plot([b[0], a[0]], [b[1], a[1]], [b[2], a[2]], "-", lw=2.5,
                    c="#1f77b4" if leg.is_actuated else "#2ca02c")
            ax.scatter(*leg.base * 1e3, c="k", s=12)
        plat = np.array([st.platform_point[0] for st in states]) * 1e3
        if len(plat) >= 3:
            ax.plot(*np.vstack([plat, plat[:1]]).T, c="#ff7f0e", lw=1.5)
        ax.set_title(f"{name} at home (mm)", fontsize=9)
        ax.set_xlabel("X")
        ax.set_ylabel("Y")
        ax.set_zlabel("Z")
    figs.add(fig, "designs", "Mechanism sketches at the home pose (blue: actuated legs, green: passive legs, "
             "orange: platform anchors).")
    ev = study.evaluation
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
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
        P = mech.pose(ws.points)[0] * 1e3
        axes[0].scatter(P[:, 0], P[:, 1], s=2, alpha=0.25, c=c, label=name)
        axes[1].scatter(P[:, 0], P[:, 2], s=2, alpha=0.25, c=c, label=name)
    for ax, (a, b) in zip(axes, (("X", "Y"), ("X", "Z"))):
        ax.set_xlabel(f"{a} [mm]")
        ax.set_ylabel(f"{b} [mm]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, markerscale=4)
    figs.add(fig, "workspace", "Feasible platform positions (projections on XY and XZ) of the recommended and the "
             "paper's design, from the study's evaluation samples.")


# -- report ---------------------------------------------------------------------------------------------
def _versions() -> dict:
    import importlib.metadata as md

    out = {"python": platform.python_version()}
    for pkg in ("parasynth", "numpy", "scipy", "pandas", "optuna", "nlopt", "cvxpy", "matplotlib"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    return out


def analyse(run: Run) -> dict:
    study, t = run.study, run.table
    runs = t[t["source"] == "run"].copy()
    objs = study.objectives
    labels = [o.label for o in objs]
    senses = [o.goal for o in objs]
    ok = (runs["status"] == "ok").to_numpy()
    feas = (runs["feasible"].astype(bool)).to_numpy() & ok
    F = runs[labels].to_numpy(float)
    mask = pareto_mask(np.where(ok[:, None], F, np.nan), senses, feas) if len(runs) else np.zeros(0, bool)
    front = runs[mask]
    out = {"runs": runs, "front": front, "mask": mask, "labels": labels, "senses": senses}
    ref = t[t["source"] == "reference"]
    out["ref_row"] = ref.iloc[0] if len(ref) and ref.iloc[0]["status"] == "ok" else None
    knee_row = None
    if len(front):
        Fm = to_min(front[labels].to_numpy(float), senses)
        knee_row = front.iloc[knee_index(Fm)]
        if len(objs) > 1:
            refpt = default_reference_point(to_min(F[feas], senses))
            out["hv_ref"] = refpt
            out["hv"] = hypervolume(Fm, refpt)
    out["knee_row"] = knee_row
    if out["ref_row"] is not None and feas.any():
        out["standing"] = reference_standing(F[feas], senses, np.ones(feas.sum(), bool),
                                             out["ref_row"][labels].to_numpy(float), labels)
    return out


def write_report(run_dir, out=None) -> Path:
    """Write index.html, report.md and pareto.csv for a run directory; returns the report dir."""
    run = load_run(run_dir)
    study = run.study
    out = Path(out) if out else Path("reports") / study.name
    out.mkdir(parents=True, exist_ok=True)
    a = analyse(run)
    runs, front = a["runs"], a["front"]
    front.to_csv(out / "pareto.csv", index=False)
    figs = Figures()
    plot_sweep(figs, study, run.table, run.final)
    plot_pareto(figs, study, runs, front, a["ref_row"], a["knee_row"])
    plot_convergence(figs, study, runs)
    plot_parallel(figs, study, runs, front)
    designs = {}
    if a["knee_row"] is not None:
        designs["recommended"] = {v.name: a["knee_row"][v.name] for v in study.variables}
    if study.reference:
        designs["paper"] = dict(study.reference)
    try:
        plot_designs(figs, study, designs)
    except Exception as e:  # a picture must not cost the report
        figs.items.append(("designs_error", f"design pictures unavailable: {e}", b""))
    sections = _sections(run, a)
    (out / "img").mkdir(exist_ok=True)
    for name, _, png in figs.items:
        if png:
            (out / "img" / f"{name}.png").write_bytes(png)
    (out / "report.md").write_text(_markdown(run, sections, figs))
    (out / "index.html").write_text(_html(run, sections, figs))
    return out


def _sections(run: Run, a: dict) -> list[tuple[str, str, pd.DataFrame | None]]:
    """(title, text, table) triples shared by the HTML and Markdown renderers."""
    study, t = run.study, run.table
    runs, front = a["runs"], a["front"]
    sec = []
    n_ok = int((runs["status"] == "ok").sum())
    n_feas = int((runs["feasible"] & (runs["status"] == "ok")).sum())
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
    if len(study.objectives) > 1 and "hv" in a:
        ref = ", ".join(f"{l}: {v:.4g}" for l, v in zip(a["labels"], a["hv_ref"]))
        sec.append(("Hypervolume", f"Hypervolume of the feasible non-dominated set: {a['hv']:.6g} "
                    f"(objectives in minimisation form, maximised ones negated; reference point: nadir of the "
                    f"feasible designs plus 10 % of their range: {ref}).", None))
    if len(front):
        k = a["knee_row"]
        txt = (f"{len(front)} non-dominated feasible designs. Recommended (knee of the front): trial "
               f"{int(k['trial'])}: " + ", ".join(_fmt_design(study, k)) + ".")
        sec.append(("Non-dominated designs", txt, display_table(study, front)))
    else:
        sec.append(("Non-dominated designs", "No feasible design was found.", None))
    if a["ref_row"] is not None:
        r = a["ref_row"]
        st = a.get("standing")
        txt = "Paper's design: " + ", ".join(_fmt_design(study, r)) + f"; feasible: {bool(r['feasible'])}."
        if st is not None:
            if st.n_dominating:
                imp = "; ".join(f"{k} by up to {100 * v:.1f} %" for k, v in st.best_improvements.items())
                txt += (f" It is dominated by {st.n_dominating} feasible designs, which improve {imp} "
                        f"(additive epsilon {st.epsilon:.3g} in range-normalised objectives).")
            else:
                txt += " No evaluated feasible design dominates it (it is on or beyond the front found)."
        sec.append(("Paper design", txt, display_table(study, t[t["source"] == "reference"])))
    if run.final is not None and len(run.final):
        sec.append(("Re-evaluation of the best designs",
                    f"Mean and standard error over {int(run.final['repeats'].iloc[0])} seeds with "
                    f"{int(run.final['samples'].iloc[0])} samples each.", run.final))
    if study.constraints or (runs["status"] != "ok").any():
        rows = []
        for c in study.constraints:
            m = runs[f"{c.label}_margin"]
            rows.append({"constraint": c.label, "measure": c.name, "bounds": f"min={c.min} max={c.max} (SI)",
                         "violated": int((m < 0).sum()), "smallest margin": float(m.min()) if len(m) else np.nan})
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
    parts = []
    for v in study.variables:
        f, u = _var_display(v)
        val = row[v.name]
        parts.append(f"{v.name} = {val * f:.4g} {u}".rstrip() if v.kind and v.type != "categorical" else f"{v.name} = {val}")
    for o in study.objectives:
        f, u = _obj_display(study, o.label)
        parts.append(f"{o.label} = {row[o.label] * f:.4g} {u}".rstrip())
    return parts


def _md_table(df: pd.DataFrame) -> str:
    cols = list(df.columns)
    lines = ["| " + " | ".join(str(c) for c in cols) + " |", "|" + "---|" * len(cols)]
    for _, r in df.iterrows():
        lines.append("| " + " | ".join(_cell(r[c]) for c in cols) + " |")
    return "\n".join(lines)


def _cell(x) -> str:
    if isinstance(x, (float, np.floating)):
        return "" if np.isnan(x) else f"{x:.5g}"
    return str(x)


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
        "text-align:right}th{background:#f3f3f3}figure{margin:1.5em 0}img{max-width:100%}"
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
            parts.append(table.to_html(index=False, float_format=lambda x: f"{x:.5g}", na_rep="", border=0,
                                       classes="designs"))
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
    import re

    return re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", s).replace("\n\n", "</p><p>")
