"""SciPy's differential evolution (``optimizer: {kind: scipy, algorithm: differential_evolution,
n_trials: N, seed: S}``): one objective over the study's variables.

* Coordinates: a continuous variable on [0, 1] of its range (log-aware, as NLopt), an integer
  variable on [low, high] and a categorical one on the index of its choice, both with
  ``integrality`` (SciPy rounds them). Inactive conditional variables are left out of the
  design.
* Constraints: every design constraint is a component of one ``NonlinearConstraint`` (margin
  >= 0); the objective and the constraints of a design read the same cached evaluation (one
  :meth:`~parasynth.study.problem.Problem.evaluate` per design). A failed design is infeasible.
* ``polish=False`` (the polish of a run is ``optimizer.polish``), ``updating="deferred"`` (the
  whole generation proposed before any is evaluated), seeded with ``optimizer.seed`` (else the
  evaluation seed).
* Budget: ``n_trials`` (``--n-trials``; default :data:`SCIPY_TRIALS`) designs; the generations
  are chosen so that the population fits, and the run stops at the budget. The population is
  ``optimizer.population_size`` designs (default 15 per variable, at most a quarter of the
  budget, at least 5), rounded up to a multiple of the number of variables (SciPy's
  ``popsize`` is per variable).
* Resume: the path is deterministic, so a resumed run replays it, answering the designs
  already evaluated from the records (trial numbers: the order of first evaluation), and gives
  the same results as an uninterrupted run.
* Several objectives are refused (name one objective, or use optuna), so is a study over
  structures (by the base class: no ``structure:``).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import StudyError
from ..problem import Problem, RunContext
from ..progress import Progress
from .base import BaseOptimizer, register

__all__ = ["Scipy", "SCIPY_TRIALS"]

#: Designs of a SciPy run without ``optimizer.n_trials`` (and no ``--n-trials``).
SCIPY_TRIALS = 100
#: The value of a non-finite margin (NaN, -inf) as SciPy sees it: far infeasible.
_FAR = 1e12


class _Stop(Exception):
    """The budget is spent or an interrupt was asked for."""


@register("scipy")
class Scipy(BaseOptimizer):
    title = "SciPy run"
    algorithms = ("differential_evolution",)
    budget_key = "n_trials"
    default_budget = SCIPY_TRIALS
    description = ("SciPy's differential evolution, one objective; constraints as a NonlinearConstraint, "
                   "integrality for integer and categorical variables; recorded evaluations replayed on resume")

    @classmethod
    def check(cls, opt, variables, objectives, space) -> None:
        if not variables:
            raise StudyError("variables: scipy needs at least one design variable (with low and high, or choices); "
                             "to evaluate fixed designs use optimizer.kind: sweep")
        if len(objectives) != 1:
            raise StudyError(f"objectives: scipy optimises one objective, {len(objectives)} given "
                             f"({', '.join(o.label for o in objectives)}); keep one, or use optimizer.kind: optuna "
                             f"for several")
        for v in variables:
            if v.type == "categorical" and not v.choices:
                raise StudyError(f"variables: scipy needs choices for the categorical variable {v.name!r}")
            if v.type != "categorical" and (v.low is None or v.high is None):
                raise StudyError(f"variables: scipy needs low/high for {v.name!r} (or type: categorical with choices)")

    @classmethod
    def planned_designs(cls, study) -> None:
        return None  # it may converge before the budget

    def run(self, problem: Problem, ctx: RunContext) -> None:
        run_scipy(problem, ctx)


def _coordinates(space):
    """(variables, bounds, integrality, to_values) of the search: see the module docstring."""
    vars_ = list(space.variables)
    bounds, integral = [], []
    for v in vars_:
        if v.type == "categorical":
            bounds.append((0, len(v.choices) - 1))
            integral.append(True)
        elif v.type == "integer":
            bounds.append((int(v.low), int(v.high)))
            integral.append(True)
        else:
            bounds.append((0.0, 1.0))
            integral.append(False)

    def to_values(x) -> dict:
        out = {}
        for v, xi in zip(vars_, x):
            if v.type == "categorical":
                out[v.name] = v.choices[int(np.clip(round(float(xi)), 0, len(v.choices) - 1))]
            elif v.type == "integer":
                out[v.name] = int(np.clip(round(float(xi)), int(v.low), int(v.high)))
            else:
                out[v.name] = v.denormalize(float(np.clip(xi, 0.0, 1.0)))
        return space.restrict(out)

    return vars_, bounds, np.array(integral, dtype=bool), to_values


def population(n_vars: int, budget: int, given: int | None) -> int:
    """SciPy's ``popsize`` (designs per variable) for ``given`` designs (else the default)."""
    total = given or max(5, min(15 * n_vars, budget // 4))
    return max(1, math.ceil(total / n_vars))


def run_scipy(problem: Problem, ctx: RunContext) -> None:
    # lazy: scipy.optimize takes ~0.3 s to import, and every study's parse imports this module
    # (the optimiser registry) whatever its optimiser
    from scipy.optimize import NonlinearConstraint, differential_evolution

    study, space, guard = problem.study, problem.space, ctx.guard
    o = problem.objectives[0]
    sign = -1.0 if o.goal == "maximize" else 1.0  # SciPy minimises sign * f
    budget = problem.budget(ctx.n_trials)
    vars_, bounds, integrality, to_values = _coordinates(space)
    popsize = population(len(vars_), budget, study.optimizer.population_size)
    n_pop = popsize * len(vars_)
    maxiter = max(0, budget // n_pop - 1) + 1  # the last generation may be cut by the budget
    cache = {space.key(r.values): r for r in ctx.records if r.source == "run"}
    n_run = len(cache)
    state = {"n": n_run}
    bar = Progress(budget, ctx.progress, f"scipy differential_evolution {study.name}", initial=min(n_run, budget))

    def get(x):
        values = to_values(x)
        k = space.key(values)
        rec = cache.get(k)
        if rec is None:
            if guard.requested or state["n"] >= budget:
                raise _Stop
            with guard.evaluating():
                rec = problem.evaluate(values, trial=state["n"])
            state["n"] += 1
            cache[k] = rec
            ctx.record(rec)
            bar.update(rec, lambda: problem.best_str(list(cache.values())))
        return rec

    def f(x):
        rec = get(x)
        if rec.status != "ok":
            return _FAR
        val = rec.objectives[o.label]
        return sign * val if math.isfinite(val) else _FAR

    labels = [c.label for c in problem.constraints]

    def g(x):
        rec = get(x)
        if rec.status != "ok":
            return np.full(len(labels), -_FAR)
        return np.array([m if math.isfinite(m) else -_FAR for m in (rec.margins[lab] for lab in labels)])

    constraints = (NonlinearConstraint(g, 0.0, np.inf),) if labels else ()
    try:
        differential_evolution(f, bounds, maxiter=maxiter, popsize=popsize, rng=int(problem.seed) % 2**32,
                               polish=False, updating="deferred", constraints=constraints,
                               integrality=integrality if integrality.any() else None, tol=0.0, atol=0.0)
    except _Stop:
        pass
    except KeyboardInterrupt:
        guard.requested = True
    finally:
        bar.close()
