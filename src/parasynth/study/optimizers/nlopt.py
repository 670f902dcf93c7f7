"""The NLopt runner: one objective, on the unit cube of the design space.

Trial numbers are the order of first evaluation along the (deterministic) path: a resumed run
replays the path, answering already-evaluated points from the records."""

from __future__ import annotations

import math
import sys

import numpy as np

from ..defaults import NLOPT_MAXEVAL
from ..design import BOX_CENTRE_U
from ..errors import StudyError
from ..evaluate import Record
from ..problem import Problem, RunContext
from ..progress import Progress
from .base import BaseOptimizer, register

__all__ = ["NLopt", "NLOPT_WITH_CONSTRAINTS"]

#: The NLopt algorithms that take the design constraints as constraints (the others: a penalty).
NLOPT_WITH_CONSTRAINTS = ("LN_COBYLA", "GN_ISRES")


@register("nlopt")
class NLopt(BaseOptimizer):
    title = "NLopt run"
    algorithms = ("LN_COBYLA", "LN_BOBYQA", "LN_NELDERMEAD", "LN_SBPLX", "GN_ISRES", "GN_DIRECT_L", "GN_CRS2_LM",
                  "GN_ESCH")
    budget_key = "maxeval"
    default_budget = NLOPT_MAXEVAL
    description = "one objective on the unit cube of the continuous variables; the path replayed on resume"

    @classmethod
    def check(cls, opt, variables, objectives, space) -> None:
        if not variables:
            raise StudyError("variables: nlopt needs at least one design variable (with low and high); "
                             "to evaluate fixed designs use optimizer.kind: sweep")
        if len(objectives) != 1:
            raise StudyError(f"objectives: nlopt optimises one objective, {len(objectives)} given; use "
                             f"optimizer.kind: optuna for several")
        for v in variables:
            if v.type != "continuous" or v.low is None:
                raise StudyError(f"variables: nlopt needs continuous variables with low/high; {v.name!r} is {v.type}")

    @classmethod
    def check_structures(cls, opt) -> None:
        raise StudyError("optimizer.kind: a study over structures has a categorical design variable (the structure); "
                         "use optimizer.kind: optuna (or sweep)")

    @classmethod
    def planned_designs(cls, study) -> None:
        return None  # it may stop early on its tolerances

    @classmethod
    def searches_globally(cls, opt) -> bool:
        return (opt.algorithm or cls.algorithms[0]).startswith("GN_")

    def run(self, problem: Problem, ctx: RunContext) -> None:
        run_nlopt(problem, ctx)


def run_nlopt(problem: Problem, ctx: RunContext) -> None:
    import nlopt  # lazy: only NLopt runs need it

    study, space, guard, record = problem.study, problem.space, ctx.guard, ctx.record
    opt_spec = study.optimizer
    alg = NLopt.algorithm(study)
    vars_ = space.numeric
    nv = len(vars_)
    o = problem.objectives[0]
    sign = -1.0 if o.goal == "maximize" else 1.0  # NLopt minimises sign * f
    maxeval = problem.budget(ctx.n_trials)
    seed = problem.seed
    nlopt.srand(int(seed))
    opt = nlopt.opt(getattr(nlopt, alg), nv)
    opt.set_lower_bounds([0.0] * nv)
    opt.set_upper_bounds([1.0] * nv)
    opt.set_maxeval(int(maxeval))
    if opt_spec.xtol_rel:
        opt.set_xtol_rel(opt_spec.xtol_rel)
    if opt_spec.ftol_rel:
        opt.set_ftol_rel(opt_spec.ftol_rel)
    if alg.startswith("LN_"):
        opt.set_initial_step([0.1] * nv)
    if opt_spec.population_size:
        opt.set_population(int(opt_spec.population_size))
    # Trial numbers are the order of first evaluation along the (deterministic) path, the same
    # in an uninterrupted and a resumed run.
    cache = {space.key(r.values): r for r in ctx.records if r.source == "run"}
    state = {"worst": None, "stop": None}
    bar = Progress(int(maxeval), ctx.progress, f"nlopt {alg} {study.name}", initial=min(len(cache), int(maxeval)))

    def values_of(u):
        return {v.name: v.denormalize(float(np.clip(x, 0, 1))) for v, x in zip(vars_, u)}

    def get(u) -> Record:
        vals = values_of(u)
        k = space.key(vals)
        rec = cache.get(k)
        if rec is None:
            if guard.requested:
                raise KeyboardInterrupt
            with guard.evaluating():
                rec = problem.evaluate(vals, trial=len(cache))
            cache[k] = rec
            record(rec)
            bar.update(rec, lambda: problem.best_str(list(cache.values())))
        return rec

    use_constraints = alg in NLOPT_WITH_CONSTRAINTS
    penalty_weight = 10.0

    def penalty_value(rec):
        # NLopt has no "infeasible" return: a failed design gets a value worse than any seen.
        w = state["worst"]
        return (abs(w) * 2 + 1.0) if w is not None else 1e6

    def get_or_stop(u) -> Record:
        # NLopt swallows Python exceptions: turn an interrupt into its forced stop.
        try:
            return get(u)
        except KeyboardInterrupt:
            state["stop"] = "interrupt"
            raise nlopt.ForcedStop

    def f(u, grad):
        rec = get_or_stop(u)
        if rec.status != "ok":
            return penalty_value(rec)
        val = sign * rec.objectives[o.label]
        state["worst"] = val if state["worst"] is None else max(state["worst"], val)
        if not use_constraints and rec.margins:
            viol = sum(max(0.0, -m) for m in rec.margins.values() if math.isfinite(m))
            if any(not math.isfinite(m) for m in rec.margins.values()):
                return penalty_value(rec)
            val += penalty_weight * viol * (1 + abs(val))
        return val

    if use_constraints:
        for c in problem.constraints:
            def g(u, grad, label=c.label):
                rec = get_or_stop(u)
                if rec.status != "ok":
                    return 1.0
                m = rec.margins[label]
                return -m if math.isfinite(m) else 1e6
            opt.add_inequality_constraint(g, 0.0)
    opt.set_min_objective(f)
    start = problem.start()
    if start:
        x0 = [v.normalize(start[v.name]) if v.name in start else BOX_CENTRE_U for v in vars_]
    elif study.reference and all(v.name in study.reference for v in vars_):
        x0 = [v.normalize(study.reference[v.name]) for v in vars_]
    else:
        x0 = [BOX_CENTRE_U] * nv  # the centre of the box
    x0 = list(np.clip(x0, 0, 1))
    try:
        opt.optimize(x0)
    except nlopt.ForcedStop:
        if state["stop"] == "interrupt":
            guard.requested = True
    except (nlopt.RoundoffLimited, ValueError, RuntimeError) as e:
        print(f"nlopt stopped: {type(e).__name__}: {e}", file=sys.stderr)
    finally:
        bar.close()
