"""The HTML report's interactive view: a 3D viewer of the recommended design, the reference
design and a bounded number of front designs, each with its feasible workspace samples and the
legs drawn at a few dozen poses (a slider moves the platform through them), and a Pareto plot
whose points show their design values on hover and switch the viewer to their design.

The geometry at a pose is the mechanism's own inverse kinematics (``Mechanism.leg_states``): a
leg is drawn from its fixed base anchor to the first joint that moves with it (a slider or a
crank, when the anchor and that joint differ), then to its platform anchor, as in the static
sketches of :func:`parasynth.report.figures.plot_designs`. The poses are the study's trajectory
when a measure of the study follows one (:data:`parasynth.objectives.TRAJECTORIES`), otherwise
feasible samples of the design's workspace, visited in a nearest-neighbour order from the home
pose. Lengths are in the display unit of lengths (mm), rounded to 0.1 mm.

The drawings are the run's own: its final stage stores them in ``view.json``
(:mod:`parasynth.study.view`) and the view reads them. A run without that file (an older
version) or a design it did not draw is drawn here as before, and the view says so in a note.

:func:`viewer_data` gives the page's data as plain JSON-ready values; :func:`plotly_script`
puts one copy of plotly.js in a shared assets folder and returns its path relative to the
report (reports share the script, several MB, rather than inlining it each).
"""

from __future__ import annotations

import html
import json
import os
import shutil
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
from markupsafe import Markup
from plotly.offline import get_plotlyjs_version

from ..common.pareto import view_range
from ..measures.display import UNITS, fmt_quantity, reference_name, reference_short
from ..study.rundir import (MAX_FRONT_DESIGNS, N_CLOUD, N_POSES, Run, design_key, design_mechanism, design_values,
                            design_view, front_choice, read_view, rounded, trajectory_of, view_key)
from .analysis import Analysis
from .tables import is_number_col, unit

__all__ = ["viewer_data", "viewer_json", "viewer_script", "plotly_script", "default_assets_dir", "MAX_FRONT_DESIGNS",
           "N_POSES", "N_CLOUD", "N_BACKGROUND"]

#: Evaluated designs drawn behind the front in the Pareto plot (an even subsample beyond that).
N_BACKGROUND = 2000

mm = UNITS["length"]


def _fmt(study, name: str, x) -> str:
    """A value of a variable or objective in its display unit ("n/a" when missing)."""
    if x is None or (not isinstance(x, str) and pd.isna(x)):
        return "n/a"
    if is_number_col(study, name):
        return fmt_quantity(float(x), unit(study, name))
    return str(x)


def _hover(study, values: dict, objectives: dict, head: str) -> str:
    lines = [f"<b>{html.escape(head)}</b>"]
    lines += [f"{html.escape(k)} = {html.escape(_fmt(study, k, x))}" for k, x in values.items()]
    lines += [f"{html.escape(k)}: {html.escape(_fmt(study, k, x))}" for k, x in objectives.items()]
    return "<br>".join(lines)


def viewer_data(run: Run, a: Analysis) -> dict | None:
    """The interactive view's data (JSON-ready), or None when no design can be drawn."""
    study = run.study
    labels = a.labels
    entries = []  # (name, role, row or None, values)
    knee_key = design_key(study, a.knee_row) if a.knee_row is not None else None
    if a.knee_row is not None:
        rec = a.recommendation
        state = "verified" if rec is not None and rec.verified else (
            "none passed verification" if rec is not None and rec.status == "none passed" else "not verified")
        entries.append((f"recommended ({state}, trial {int(a.knee_row['trial'])})", "recommended", a.knee_row,
                        design_values(study, a.knee_row)))
    if study.reference:
        entries.append((reference_short(study), "reference", a.ref_row, dict(study.reference)))
    front = a.front.reset_index(drop=True)
    front_design = {}  # front position -> design index
    for i in front_choice(len(front), MAX_FRONT_DESIGNS):
        row = front.iloc[i]
        if knee_key is not None and design_key(study, row) == knee_key:
            front_design[i] = 0
            continue
        front_design[i] = len(entries)
        entries.append((f"trial {int(row['trial'])}", "front", row, design_values(study, row)))
    stored = read_view(run.run_dir)  # the drawings the run stored at its final stage
    path = None if stored is not None else trajectory_of(study)
    designs, index, recomputed = [], {}, 0
    for k, (name, role, row, values) in enumerate(entries):
        key = view_key(study, None if role == "reference" else row)
        view = dict(stored[key]) if stored is not None and key in stored else None
        if view is None and (stored is None or key not in stored):
            try:  # a run without view.json (an older version), or a design it did not draw
                path = path if path is not None else trajectory_of(study)
                view = design_view(study, design_mechanism(study, values), study.evaluation["seed"] + 7 * (k + 1),
                                   path, k)
                recomputed += 1
            except (ValueError, ArithmeticError):
                view = None
        if view is None:
            continue
        index[k] = len(designs)
        objs = {lab: row[lab] for lab in labels} if row is not None and all(lab in row for lab in labels) else {}
        view.update(name=name, role=role, trial=None if row is None or pd.isna(row.get("trial", np.nan)) else int(row["trial"]),
                    values=[[k2, _fmt(study, k2, x)] for k2, x in values.items()],
                    objectives=[[lab, _fmt(study, lab, x)] for lab, x in objs.items()])
        designs.append(view)
    if not designs:
        return None
    allpts = [np.asarray(d[key], float).reshape(-1, 3) for d in designs for key in ("anchors", "B", "A")]
    allpts += [np.asarray(d["cloud"], float).T for d in designs if len(d["cloud"][0])]
    P = np.vstack(allpts)
    lo, hi = np.nanmin(P, axis=0), np.nanmax(P, axis=0)
    pad = 0.05 * max(float(np.max(hi - lo)), 1.0)
    note = ("this run stored no drawings (view.json, written by newer versions at the run's final stage): "
            "the workspaces were sampled again for this report") if stored is None else (
        f"{recomputed} design(s) not stored in view.json were drawn for this report" if recomputed else "")
    return {"length_unit": mm.symbol, "designs": designs, "note": note,
            "box": rounded(np.stack([lo - pad, hi + pad], axis=1)),
            "pareto": _pareto(study, a, front, front_design, index),
            "reference_name": reference_name(study)}


def _pareto(study, a: Analysis, front: pd.DataFrame, front_design: dict, index: dict) -> dict:
    """Axes (the objectives in display units; the trial number too for one objective), the
    evaluated designs behind, the front (with hover text and the design each one switches to),
    the recommended and the reference design."""
    labels = a.labels
    axes = [{"name": lab, "title": unit(study, lab).label(lab) + f" ({o.goal})"} for lab, o in zip(labels, study.objectives)]
    cols = list(labels)
    if len(labels) == 1:
        axes.insert(0, {"name": "trial", "title": "trial"})
        cols.insert(0, "trial")

    def coords(df):
        out = []
        for c in cols:
            v = df[c].to_numpy(float)
            out.append(rounded(v if c == "trial" else unit(study, c)(v), 6))
        return out

    runs = a.runs[a.runs["status"] == "ok"]
    feas = runs["feasible"].astype(bool)
    groups = {}
    for name, df in (("feasible", runs[feas]), ("infeasible", runs[~feas])):
        if len(df) > N_BACKGROUND:
            df = df.iloc[np.linspace(0, len(df) - 1, N_BACKGROUND).round().astype(int)]
        groups[name] = coords(df)
    fr = {"coords": coords(front) if len(front) else [[] for _ in cols], "design": [], "hover": []}
    for i in range(len(front)):
        row = front.iloc[i]
        d = index.get(front_design.get(i, -1), -1)
        head = f"trial {int(row['trial'])}" + ("" if d >= 0 else " (not in the viewer)")
        fr["design"].append(d)
        fr["hover"].append(_hover(study, design_values(study, row), {lab: row[lab] for lab in labels}, head))
    marks = []
    for role, row, k in (("recommended", a.knee_row, 0), ("reference", a.ref_row, None)):
        if row is None:
            continue
        if role == "reference":
            k = 1 if a.knee_row is not None else 0
        d = index.get(k, -1)
        name = "recommended (knee)" if role == "recommended" else reference_short(study)
        marks.append({"role": role, "name": name, "coords": coords(pd.DataFrame([row])), "design": d,
                      "hover": _hover(study, design_values(study, row) if role == "recommended" else dict(study.reference),
                                      {lab: row[lab] for lab in labels}, name)})
    return {"axes": axes, "background": groups, "front": fr, "marks": marks,
            "ranges": _ranges(len(cols), groups["feasible"], [fr["coords"]] + [m["coords"] for m in marks]),
            "staircase": len(labels) == 2, "goals": [o.goal for o in study.objectives]}


def _ranges(n_axes: int, background: list, keep: list, pad: float = 0.08) -> list:
    """Each axis's initial range (:func:`parasynth.common.pareto.view_range`): the span of the
    ``background`` designs (the feasible ones) without their far outliers, and of every design
    of ``keep`` (the front and the marked designs), padded by ``pad`` of it; None where there is
    nothing finite to span (the plot scales itself). Designs near a singularity reach forces of
    giganewtons, infeasible ones and, where no constraint bounds the force along a path, feasible
    ones too: an axis spanning them would squash the front into one corner. They stay reachable
    through the plot's autoscale."""
    def axis(sets, i):
        vals = [np.asarray(c[i], float) for c in sets if len(c) > i and len(c[i])]
        return np.concatenate(vals) if vals else np.zeros(0)

    return [view_range(axis([background], i), axis(keep, i), pad) for i in range(n_axes)]


def viewer_json(data: dict) -> Markup:
    """The data for a ``<script type="application/json">`` element: no ``<``, ``>`` or ``&``
    characters (escaped as JSON unicode escapes), so nothing in it can end the element."""
    text = json.dumps(data, separators=(",", ":"), allow_nan=False)
    return Markup(text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026"))


def viewer_script() -> Markup:
    """The viewer's own script (``templates/viewer.js``), inlined in the page."""
    return Markup((Path(__file__).parent / "templates" / "viewer.js").read_text())


def default_assets_dir(out: Path) -> Path:
    """Where a report's shared scripts go: ``<reports>/assets`` for a report directory inside a
    folder named ``reports`` (``reports/<study name>/``, as run-all writes them), else ``<out>/assets``."""
    out = Path(out)
    return out.parent / "assets" if out.resolve().parent.name == "reports" else out / "assets"


def plotly_script(out: Path, assets: Path | None = None) -> str:
    """Copy plotly.js (``plotly-<version>.min.js``, from the plotly package) into ``assets``
    (default :func:`default_assets_dir`) unless it is there already; its path relative to the
    report directory ``out``, with forward slashes."""
    out = Path(out)
    assets = Path(assets) if assets is not None else default_assets_dir(out)
    name = f"plotly-{get_plotlyjs_version()}.min.js"
    dst = assets / name
    src = resources.files("plotly").joinpath("package_data", "plotly.min.js")
    with resources.as_file(src) as path:
        if not dst.exists() or dst.stat().st_size != Path(path).stat().st_size:
            assets.mkdir(parents=True, exist_ok=True)
            tmp = dst.with_name(dst.name + f".{os.getpid()}.tmp")
            shutil.copyfile(path, tmp)
            os.replace(tmp, dst)
    return Path(os.path.relpath(dst.resolve(), out.resolve())).as_posix()
