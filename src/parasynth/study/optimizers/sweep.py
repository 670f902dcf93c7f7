"""The sweep: every design of the grid (or of ``optimizer.designs``), in order.

Trial = index of the design in the list; a resumed run skips the designs already evaluated."""

from __future__ import annotations

from ...common.validation import MAX_TRIALS
from ..errors import StudyError
from ..problem import Problem, RunContext
from ..progress import Progress
from ..space import DesignSpace
from .base import BaseOptimizer, register

__all__ = ["Sweep"]

#: Most designs a sweep may list (the product of the variables' value counts).
MAX_DESIGNS = MAX_TRIALS


@register("sweep")
class Sweep(BaseOptimizer):
    title = "sweep"
    algorithms = ("grid", "list")
    budget_key = None
    lists_designs = True
    runs_structures = True
    description = "every design of the grid of the variables' values, or of optimizer.designs, in order"

    @classmethod
    def check(cls, opt, variables, objectives, space) -> None:
        if opt.designs:
            return
        for v in variables:
            if v.values is None and v.choices is None:
                raise StudyError(f"variables: a sweep needs values (or num with low/high, or choices) for {v.name!r}")
        n_designs = space.grid_size()
        if n_designs > MAX_DESIGNS:
            raise StudyError(f"variables: the sweep grid has {n_designs} designs; the maximum is {MAX_DESIGNS}")

    @classmethod
    def check_structures(cls, opt) -> None:
        """A sweep lists its designs: a study over structures may be swept."""

    @classmethod
    def budget(cls, study, n_trials: int | None = None) -> int:
        return int(n_trials or cls.planned_designs(study))

    @classmethod
    def planned_designs(cls, study) -> int:
        opt = study.optimizer
        if opt.designs:
            return len(opt.designs)
        return DesignSpace(study.variables).grid_size()

    @classmethod
    def searches_globally(cls, opt) -> bool:
        return False  # it evaluates listed designs

    def run(self, problem: Problem, ctx: RunContext) -> None:
        run_sweep(problem, ctx)


def run_sweep(problem: Problem, ctx: RunContext) -> None:
    designs = problem.designs()
    records, guard = ctx.records, ctx.guard
    done = {r.trial for r in records if r.source == "run"}
    todo = [(i, d) for i, d in enumerate(designs) if i not in done]
    bar = Progress(len(designs), ctx.progress, f"sweep {problem.name}", initial=len(designs) - len(todo))
    try:
        for i, d in todo:
            if guard.requested:
                break
            with guard.evaluating():
                rec = problem.evaluate(d, trial=i)
            ctx.record(rec)
            bar.update(rec, lambda: problem.best_str(records))
    finally:
        bar.close()
