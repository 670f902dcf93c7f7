"""The polish (``optimizer.polish: {method: cobyla | bobyqa, budget: N}``): after a global
optimiser, one design is refined by a local NLopt search within the bounds.

* Which design: the best feasible design of a single objective; with several objectives the
  recommended design before the final re-evaluation (the knee of the front of the feasible
  designs), refined by an achievement scalarisation ``max_i (g_i - g0_i) / s_i + rho sum_i
  (g_i - g0_i) / s_i`` (``g`` the objectives as minimised, ``g0`` those of the start, ``s_i``
  the objective's spread over the front, else ``|g0_i|``, else 1; ``rho`` = :data:`RHO`): it
  improves every objective together, and a polished design is kept only when no objective is
  worse than at the start.
* The search: the continuous variables on the unit cube of their bounds (integer and
  categorical ones held at the start's values), a first step of :data:`POLISH_STEP` of each
  range. COBYLA takes the design constraints (margin >= 0) and, with several objectives, "no
  objective worse" as constraints; BOBYQA takes no constraints, so a study with design
  constraints is refused with it (``optimizer.polish.method``).
* Budget: the polish's ``budget`` designs are part of the study's budget (``n_trials`` /
  ``maxeval`` / ``--n-trials``): the global optimiser gets the rest. Every polish evaluation is
  recorded as a trial of the run (``source`` run, trial numbers after the optimiser's), so the
  final re-evaluation and the report see the polished designs as any other.
* ``polish.json`` in the run directory: the method, the budget, the first polish trial (a
  resumed run replays the deterministic path from the same start, answering the designs
  already evaluated from the records), the start and the polished design, how far each
  variable moved (SI and share of its range) and each objective's change.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from .final import knee_of, pareto_front
from .journal import jsonable
from .tables import results_table

__all__ = ["POLISH_METHODS", "POLISH_STEP", "RHO", "polish_budget", "polish_run", "read_polish",
           "start_design"]

#: ``optimizer.polish.method`` -> the NLopt algorithm.
POLISH_METHODS = {"cobyla": "LN_COBYLA", "bobyqa": "LN_BOBYQA"}
#: The first step of the local search, as a share of each continuous variable's range.
POLISH_STEP = 0.05
#: The weight of the sum in the achievement scalarisation (several objectives).
RHO = 1e-3
POLISH_FILE = "polish.json"


def polish_budget(study) -> int:
    """Designs of the study's budget the polish takes (0 without ``optimizer.polish``)."""
    pol = getattr(study.optimizer, "polish", None)
    return int(pol.budget) if pol is not None else 0


def read_polish(out_dir) -> dict | None:
    """The run's ``polish.json``, or None."""
    p = Path(out_dir) / POLISH_FILE
    if not p.exists():
        return None
    try:
        return json.loads(p.read_text())
    except (OSError, ValueError):
        return None


def _write(out_dir, d: dict) -> None:
    p = Path(out_dir) / POLISH_FILE
    tmp = p.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(jsonable(d), indent=1))
    os.replace(tmp, p)


def _minimised(problem, rec) -> np.ndarray:
    return np.array([(-1.0 if o.goal == "maximize" else 1.0) * rec.objectives[o.label] for o in problem.objectives])


def start_design(problem, records, first_trial: int):
    """The design the polish starts from (see the module docstring) and the objectives' scales;
    (None, None) when no feasible design was found."""
    runs = [r for r in records if r.source == "run" and r.trial < first_trial and r.status == "ok" and r.feasible
            and all(math.isfinite(r.objectives.get(o.label, math.nan)) for o in problem.objectives)]
    if not runs:
        return None, None
    if len(problem.objectives) == 1:
        return min(runs, key=lambda r: (float(_minimised(problem, r)[0]), r.trial)), np.ones(1)
    table = results_table(problem.study, runs)
    front = pareto_front(problem.study, table[table["source"] == "run"])
    knee = knee_of(problem.study, front)
    if knee is None:
        return None, None
    rec = next(r for r in runs if r.trial == int(knee["trial"]))
    g = np.array([[(-1.0 if o.goal == "maximize" else 1.0) * float(v) for o, v in zip(problem.objectives, row)]
                  for row in front[[o.label for o in problem.objectives]].to_numpy(float)])
    spread = g.max(axis=0) - g.min(axis=0) if len(g) > 1 else np.zeros(len(problem.objectives))
    g0 = np.abs(_minimised(problem, rec))
    scale = np.where(spread > 0, spread, np.where(g0 > 0, g0, 1.0))
    return rec, scale


def polish_run(problem, optimizer, ctx) -> dict | None:
    """Polish the run's result (see the module docstring); returns what ``polish.json`` holds,
    or None when the study asks for no polish."""
    study = problem.study
    pol = getattr(study.optimizer, "polish", None)
    if pol is None:
        return None
    import nlopt  # lazy: only a polished run needs NLopt

    out_dir = ctx.out_dir
    state = read_polish(out_dir) if out_dir is not None else None
    if state and state.get("status") == "done":
        return state
    runs = [r for r in ctx.records if r.source == "run"]
    first = int(state["first_trial"]) if state else optimizer.polish_trial(ctx.records)
    start, scale = start_design(problem, ctx.records, first)
    info = {"method": pol.method, "budget": int(pol.budget), "first_trial": first, "status": "running",
            "start": None, "polished": None, "evaluations": 0}
    if start is None:
        info.update(status="done", note="no feasible design to polish")
        if out_dir is not None:
            _write(out_dir, info)
        return info
    info["start"] = {"trial": start.trial, "values": start.values, "objectives": start.objectives}
    if out_dir is not None:
        _write(out_dir, info)
    space, guard = problem.space, ctx.guard
    cont = [v for v in space.variables if v.type == "continuous" and v.low is not None and v.name in start.values]
    fixed = {k: x for k, x in start.values.items() if k not in {v.name for v in cont}}
    several = len(problem.objectives) > 1
    g0 = _minimised(problem, start)
    cache = {space.key(r.values): r for r in runs}
    mine: list = [r for r in runs if r.trial >= first]
    n_done = [len(mine)]

    def values_of(u):
        vals = dict(fixed)
        vals.update({v.name: v.denormalize(float(np.clip(x, 0.0, 1.0))) for v, x in zip(cont, u)})
        return space.restrict({k: vals[k] for k in space.names if k in vals})

    class _Spent(Exception):
        pass

    def get(u):
        vals = values_of(u)
        k = space.key(vals)
        rec = cache.get(k)
        if rec is None:
            if guard.requested:
                raise KeyboardInterrupt
            if n_done[0] >= pol.budget:
                raise _Spent
            with guard.evaluating():
                rec = problem.evaluate(vals, trial=optimizer.polish_trial(ctx.records))
            n_done[0] += 1
            cache[k] = rec
            mine.append(rec)
            ctx.record(rec)
            optimizer.stored_polished(rec)
        return rec

    def asf(rec):
        d = (_minimised(problem, rec) - g0) / scale
        return float(d.max() + RHO * d.sum()) if several else float(d[0])

    worst = [0.0]
    stop = {}

    def wrapped(fn):
        def call(u, grad):
            try:
                return fn(get(u))
            except (KeyboardInterrupt, _Spent) as e:
                stop["why"] = e
                raise nlopt.ForcedStop
        return call

    def f(rec):
        if rec.status != "ok" or not all(math.isfinite(x) for x in _minimised(problem, rec)):
            return abs(worst[0]) * 2 + 1.0
        val = asf(rec)
        worst[0] = max(worst[0], val)
        return val

    opt = nlopt.opt(getattr(nlopt, POLISH_METHODS[pol.method]), len(cont))
    opt.set_lower_bounds([0.0] * len(cont))
    opt.set_upper_bounds([1.0] * len(cont))
    opt.set_maxeval(int(pol.budget) + 1)  # the start is answered from the records
    opt.set_initial_step([POLISH_STEP] * len(cont))
    opt.set_min_objective(wrapped(f))
    if pol.method == "cobyla":
        for c in problem.constraints:
            opt.add_inequality_constraint(wrapped(
                lambda rec, lab=c.label: 1.0 if rec.status != "ok" or not math.isfinite(rec.margins[lab])
                else -rec.margins[lab]), 0.0)
        if several:
            for i in range(len(problem.objectives)):
                opt.add_inequality_constraint(wrapped(
                    lambda rec, i=i: 1.0 if rec.status != "ok" else float((_minimised(problem, rec)[i] - g0[i])
                                                                          / scale[i])), 0.0)
    x0 = [float(np.clip(v.normalize(start.values[v.name]), 0.0, 1.0)) for v in cont]
    try:
        opt.optimize(x0)
    except nlopt.ForcedStop:
        if isinstance(stop.get("why"), KeyboardInterrupt):
            guard.requested = True
    except (nlopt.RoundoffLimited, ValueError, RuntimeError):
        pass
    if guard.requested:
        return info  # polish.json says running: a resumed run continues it
    ok = [r for r in mine if r.status == "ok" and r.feasible
          and all(math.isfinite(x) for x in _minimised(problem, r))
          and (not several or np.all(_minimised(problem, r) <= g0))]
    best = min(ok, key=lambda r: (asf(r), r.trial), default=None)
    info["evaluations"] = len(mine)
    info["status"] = "done"
    if best is None or asf(best) >= 0:
        info["note"] = "no design better than the start was found"
    else:
        info["polished"] = {"trial": best.trial, "values": best.values, "objectives": best.objectives}
        info["moved"] = {v.name: {"from": start.values[v.name], "to": best.values[v.name],
                                  "share_of_range": abs(best.values[v.name] - start.values[v.name]) / (v.high - v.low)}
                         for v in cont}
        info["change"] = {o.label: best.objectives[o.label] - start.objectives[o.label] for o in problem.objectives}
    if out_dir is not None:
        _write(out_dir, info)
    return info
