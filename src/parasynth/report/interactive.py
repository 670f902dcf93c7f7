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

from ..measures.display import UNITS, fmt_number, fmt_quantity, reference_name, reference_short
from ..measures.objectives import TRAJECTORIES, get as get_measure, workspace_of
from ..study.rundir import Run, design_key, design_mechanism
from .analysis import Analysis
from .tables import is_number_col, unit

__all__ = ["viewer_data", "viewer_json", "viewer_script", "plotly_script", "default_assets_dir", "MAX_FRONT_DESIGNS",
           "N_POSES", "N_CLOUD", "N_BACKGROUND"]

#: Front designs the viewer can switch to, besides the recommended and the reference design
#: (spread evenly along the front, in the order of its first objective).
MAX_FRONT_DESIGNS = 12
#: Poses per design (the slider's positions).
N_POSES = 30
#: Workspace samples drawn per design, and the sample the viewer takes them from.
N_CLOUD = 250
N_WORKSPACE = 16384
#: Evaluated designs drawn behind the front in the Pareto plot (an even subsample beyond that).
N_BACKGROUND = 2000

mm = UNITS["length"]
deg = UNITS["angle"]


def _r(a, digits: int = 1):
    """Display values rounded to ``digits`` decimals as nested lists, NaN and infinities as None."""
    a = np.round(np.asarray(a, dtype=float), digits)
    if a.ndim == 0:
        return float(a) if np.isfinite(a) else None
    return [_r(x, digits) for x in a]


def _fmt(study, name: str, x) -> str:
    """A value of a variable or objective in its display unit ("n/a" when missing)."""
    if x is None or (not isinstance(x, str) and pd.isna(x)):
        return "n/a"
    if is_number_col(study, name):
        return fmt_quantity(float(x), unit(study, name))
    return str(x)


def _values(study, row) -> dict:
    """The design values of a row of the results (inactive conditional variables left out)."""
    out = {}
    for v in study.variables:
        x = row[v.name] if v.name in row else None
        if x is None or (not isinstance(x, str) and pd.isna(x)):
            continue
        out[v.name] = x.item() if hasattr(x, "item") else x
    return out


def _pose_text(mech, x) -> str:
    parts = []
    for c, v in zip(mech.task_coordinates, x):
        u = deg if c in mech.angular_coordinates else mm
        parts.append(f"{c} = {fmt_quantity(float(v), u)}")
    return ", ".join(parts)


def _trajectory(study):
    """The trajectory the study's measures follow, or None: (f(n) -> (t, X), measure name). The
    built-in paths of :data:`TRAJECTORIES` only where the measure follows one: a study without a
    task on a model the measure runs on without one (with a task it follows the task's path)."""
    if getattr(study, "task", None) is not None:
        return None
    for m in list(study.objectives) + list(study.constraints):
        if m.name in TRAJECTORIES and study.mechanism in get_measure(m.name).without_task:
            return TRAJECTORIES[m.name], m.name
    return None


def _tour(X: np.ndarray, start: int) -> list[int]:
    """A nearest-neighbour order of the rows of ``X`` (coordinates scaled by their spread) from
    row ``start``: the slider moves the platform between neighbouring poses."""
    s = X.std(axis=0)
    Z = X / np.where(s > 0, s, 1.0)
    left = set(range(len(X))) - {start}
    order = [start]
    while left:
        idx = np.fromiter(left, int)
        k = int(idx[np.argmin(np.linalg.norm(Z[idx] - Z[order[-1]], axis=1))])
        order.append(k)
        left.remove(k)
    return order


def _design_view(study, mech, k: int, path) -> dict | None:
    """One design's drawing: anchors, the legs at each pose, the platform centres, the feasible
    workspace samples and the text of each pose."""
    ev = study.evaluation
    try:
        ws = workspace_of(mech, ranges=ev.get("ranges"), n=N_WORKSPACE, method=ev["method"], seed=ev["seed"] + 7 * (k + 1),
                          fixed=ev.get("fixed"), constraints=ev.get("constraints"))
        pts = np.asarray(ws.points, float) if ws.n_feasible else np.zeros((0, mech.n_task))
    except ValueError:
        pts = np.zeros((0, mech.n_task))
    rng = np.random.default_rng(1000 + k)
    cloud = pts[rng.choice(len(pts), N_CLOUD, replace=False)] if len(pts) > N_CLOUD else pts
    home = np.asarray(mech.home, float)[None, :]
    if path is not None:
        t, X = path[0](N_POSES)
        texts = [f"t = {fmt_number(float(ti), 3)} s" for ti in t]
        source = f"the trajectory of {path[1]}"
    else:
        cand = pts[rng.choice(len(pts), N_POSES - 1, replace=False)] if len(pts) > N_POSES - 1 else pts
        X = np.vstack([home, cand])
        X = X[_tour(X, 0)] if len(X) > 2 else X
        texts = None
        source = "feasible workspace samples, from the home pose"
    _, states, p = mech.leg_states(X)
    reach = np.logical_and.reduce([st.reachable for st in states])
    if not reach.any():
        return None
    feasible = np.asarray(mech.is_feasible(X), bool) & reach
    keep = np.flatnonzero(reach)
    if texts is None:
        texts = [_pose_text(mech, X[i]) for i in range(len(X))]
    B = np.stack([st.base_point for st in states], axis=1)[keep]  # (P, legs, 3)
    A = np.stack([st.platform_point for st in states], axis=1)[keep]
    anchors = np.array([np.asarray(leg.base, float) for leg in mech.legs])
    first = [bool(np.max(np.linalg.norm(B[:, i] - anchors[i], axis=1)) > 1e-9) for i in range(len(mech.legs))]
    centres = p[keep]
    cloud_p = mech.pose(cloud)[0] if len(cloud) else np.zeros((0, 3))
    return {
        "anchors": _r(mm(anchors)),
        "actuated": [bool(leg.is_actuated) for leg in mech.legs],
        "first_joint": first,
        "B": _r(mm(B)), "A": _r(mm(A)), "C": _r(mm(centres)),
        "pose_text": [texts[i] + ("" if feasible[i] else " (outside the limits)") for i in keep],
        "cloud": _r(mm(cloud_p).T) if len(cloud_p) else [[], [], []],
        "n_feasible_samples": int(len(pts)), "n_samples": N_WORKSPACE,
        "pose_source": source, "trajectory": path is not None,
    }


def _front_choice(front: pd.DataFrame, n: int) -> list[int]:
    """Positions of at most ``n`` front designs spread evenly along the front (its order)."""
    if len(front) <= n:
        return list(range(len(front)))
    return sorted({int(round(x)) for x in np.linspace(0, len(front) - 1, n)})


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
                        _values(study, a.knee_row)))
    if study.reference:
        entries.append((reference_short(study), "reference", a.ref_row, dict(study.reference)))
    front = a.front.reset_index(drop=True)
    front_design = {}  # front position -> design index
    for i in _front_choice(front, MAX_FRONT_DESIGNS):
        row = front.iloc[i]
        if knee_key is not None and design_key(study, row) == knee_key:
            front_design[i] = 0
            continue
        front_design[i] = len(entries)
        entries.append((f"trial {int(row['trial'])}", "front", row, _values(study, row)))
    path = _trajectory(study)
    designs, index = [], {}
    for k, (name, role, row, values) in enumerate(entries):
        try:
            mech = design_mechanism(study, values)
            view = _design_view(study, mech, k, path)
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
    return {"length_unit": mm.symbol, "designs": designs,
            "box": _r(np.stack([lo - pad, hi + pad], axis=1)),
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
            out.append(_r(v if c == "trial" else unit(study, c)(v), 6))
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
        fr["hover"].append(_hover(study, _values(study, row), {lab: row[lab] for lab in labels}, head))
    marks = []
    for role, row, k in (("recommended", a.knee_row, 0), ("reference", a.ref_row, None)):
        if row is None:
            continue
        if role == "reference":
            k = 1 if a.knee_row is not None else 0
        d = index.get(k, -1)
        name = "recommended (knee)" if role == "recommended" else reference_short(study)
        marks.append({"role": role, "name": name, "coords": coords(pd.DataFrame([row])), "design": d,
                      "hover": _hover(study, _values(study, row) if role == "recommended" else dict(study.reference),
                                      {lab: row[lab] for lab in labels}, name)})
    return {"axes": axes, "background": groups, "front": fr, "marks": marks,
            "staircase": len(labels) == 2, "goals": [o.goal for o in study.objectives]}


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
