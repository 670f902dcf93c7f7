"""A SciPy differential-evolution runner written against the problem object."""

from scipy.optimize import differential_evolution


class BudgetSpent(Exception):
    pass


def run_de(problem, ctx, popsize=8):
    """Optimise the first objective over the unit cube of the numeric variables."""
    space, o = problem.space, problem.objectives[0]
    sign = -1.0 if o.goal == "maximize" else 1.0  # SciPy minimises
    budget = problem.budget(ctx.n_trials)
    seen = {space.key(r.values): r for r in ctx.records if r.source == "run"}

    def f(u):
        values = space.from_unit(u)
        rec = seen.get(space.key(values))
        if rec is None:
            if ctx.guard.requested or len(seen) >= budget:
                raise BudgetSpent
            with ctx.guard.evaluating():
                rec = problem.evaluate(values, trial=len(seen))
            seen[space.key(values)] = rec
            ctx.record(rec)
        return sign * rec.objectives[o.label] if rec.feasible else 1e30

    n = len(space.numeric)
    try:
        differential_evolution(f, [(0.0, 1.0)] * n, seed=problem.seed, popsize=popsize, polish=False,
                               maxiter=max(1, budget // (popsize * n)), tol=0.0)
    except BudgetSpent:
        pass
