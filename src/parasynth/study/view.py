"""The interactive view's drawings of a run's designs, computed once at the run's final stage and
stored in ``view.json`` beside ``final.csv``: for each design the report may show (the final
candidates, the recommended and the reference design, and up to :data:`MAX_FRONT_DESIGNS` designs
spread along the Pareto front), its anchors, the legs at a few dozen poses, the platform centres
and a cloud of feasible workspace samples. The report reads them (:func:`read_view`) instead
of recomputing the workspaces; a run without ``view.json`` (written by an older version) is
drawn as before, by :func:`design_view`, and the report says so.

The geometry at a pose is the mechanism's own inverse kinematics (``Mechanism.leg_states``).
The poses are the study's trajectory when a measure of the study follows one
(:data:`parasynth.measures.objectives.TRAJECTORIES`), otherwise feasible samples of the design's
workspace (drawn with the seed ``evaluation.seed + 7 (k + 1)``, ``k`` the design's place in
``view.json``), visited in a nearest-neighbour order from the home pose. Lengths are in mm,
rounded to 0.1 mm.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from ..common.units import UNITS
from ..measures.display import fmt_number, fmt_quantity
from ..measures.objectives import TRAJECTORIES, get as get_measure, solve_compiled, workspace_of
from ..model.legs import require
from .design import design_key, design_mechanism

__all__ = ["design_view", "design_values", "rounded", "front_choice", "sorted_front", "view_key", "write_view",
           "read_view", "trajectory_of", "VIEW_FILE", "MAX_FRONT_DESIGNS", "N_POSES", "N_CLOUD", "N_WORKSPACE"]

#: The file of a run's stored drawings.
VIEW_FILE = "view.json"
#: Front designs the viewer can switch to, besides the recommended and the reference design
#: (spread evenly along the front, in the order of its first objective).
MAX_FRONT_DESIGNS = 12
#: Poses per design (the slider's positions).
N_POSES = 30
#: Workspace samples drawn per design, and the sample the viewer takes them from.
N_CLOUD = 250
N_WORKSPACE = 16384

mm = UNITS["length"]
deg = UNITS["angle"]


def rounded(a, digits: int = 1):
    """Display values rounded to ``digits`` decimals as nested lists, NaN and infinities as None."""
    a = np.round(np.asarray(a, dtype=float), digits)
    if a.ndim == 0:
        return float(a) if np.isfinite(a) else None
    out = a.tolist()  # one pass (element by element cost ~9 ms a drawing)
    return out if np.isfinite(a).all() else _finite_or_none(out)


def _finite_or_none(x):
    if isinstance(x, list):
        return [_finite_or_none(v) for v in x]
    return x if np.isfinite(x) else None


def design_values(study, row) -> dict:
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


def trajectory_of(study):
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


def design_view(study, mech, seed: int, path, k: int = 0) -> dict | None:
    """One design's drawing: anchors, the legs at each pose, the platform centres, the feasible
    workspace samples (drawn with ``seed``; ``k`` picks the cloud's subsample) and the text of
    each pose. A leg type without the ``view`` capability is
    refused by name (``LegCapabilityError``, a ``ValueError``: the design is not drawn)."""
    for leg in mech.legs:
        require(leg, "view")
    ev = study.evaluation
    try:
        ws = workspace_of(mech, ranges=ev.get("ranges"), n=N_WORKSPACE, method=ev["method"], seed=seed,
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
    engine = ev.get("engine", "compiled")
    solve_compiled(mech, X, engine)  # the parasitic coordinates of a task.solve by the compiled solve (as the measures)
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
    if len(cloud):
        solve_compiled(mech, cloud, engine)
    cloud_p = mech.pose(cloud)[0] if len(cloud) else np.zeros((0, 3))
    return {
        "anchors": rounded(mm(anchors)),
        "actuated": [bool(leg.is_actuated) for leg in mech.legs],
        "first_joint": first,
        "B": rounded(mm(B)), "A": rounded(mm(A)), "C": rounded(mm(centres)),
        "pose_text": [texts[i] + ("" if feasible[i] else " (outside the limits)") for i in keep],
        "cloud": rounded(mm(cloud_p).T) if len(cloud_p) else [[], [], []],
        "n_feasible_samples": int(len(pts)), "n_samples": N_WORKSPACE,
        "pose_source": source, "trajectory": path is not None,
    }


def front_choice(n_front: int, n: int = MAX_FRONT_DESIGNS) -> list[int]:
    """Positions of at most ``n`` of ``n_front`` front designs spread evenly along the front."""
    if n_front <= n:
        return list(range(n_front))
    return sorted({int(round(x)) for x in np.linspace(0, n_front - 1, n)})


def sorted_front(study, front: pd.DataFrame) -> pd.DataFrame:
    """The front best first in the study's first objective (stable): the order in which the
    report lists it and :func:`front_choice` spreads the viewer's designs along it."""
    if not len(front):
        return front
    o = study.objectives[0]
    return front.sort_values(o.label, ascending=o.goal == "minimize", kind="stable")


def view_key(study, row=None) -> str:
    """The key of a design in ``view.json``: ``"reference"`` for the reference design (``row``
    None), else its design key (:func:`parasynth.study.design.design_key`) written out."""
    return "reference" if row is None else repr(tuple(design_key(study, row)))


def write_view(study, final: pd.DataFrame, front: pd.DataFrame, out_dir) -> dict:
    """Draw the designs the report may show and write them to ``out_dir/view.json``: the rows
    of ``final`` (the reference as ``"reference"``) and up to :data:`MAX_FRONT_DESIGNS` rows of
    ``front`` spread along it. Designs that cannot be drawn are left out (the report then
    draws them itself). Returns {key: drawing}."""
    path = trajectory_of(study)
    entries = []
    for _, row in final.iterrows():
        ref = str(row.get("source", "")) == "reference"
        values = dict(study.reference or {}) if ref else design_values(study, row)
        entries.append((view_key(study, None if ref else row), values))
    front = sorted_front(study, front).reset_index(drop=True)
    for i in front_choice(len(front)):
        entries.append((view_key(study, front.iloc[i]), design_values(study, front.iloc[i])))
    views, seed = {}, int(study.evaluation["seed"])
    for k, (key, values) in enumerate(entries):
        if key in views or (key == "reference" and not study.reference):
            continue
        try:
            view = design_view(study, design_mechanism(study, values), seed + 7 * (k + 1), path, k)
        except (ValueError, ArithmeticError):
            view = None
        if view is not None:
            views[key] = view
    Path(out_dir, VIEW_FILE).write_text(json.dumps({"version": 1, "designs": views}))
    return views


def read_view(run_dir) -> dict | None:
    """The stored drawings of a run {key: drawing}, or None for a run without ``view.json``."""
    p = Path(run_dir) / VIEW_FILE
    if not p.exists():
        return None
    try:
        data = json.loads(p.read_text())
    except (OSError, ValueError):
        return None
    return data.get("designs") if isinstance(data, dict) else None
