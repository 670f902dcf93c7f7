"""The sweep runner: every design of the grid (or of ``optimizer.designs``), in order.

Trial = index of the design in the list; a resumed run skips the designs already evaluated."""

from __future__ import annotations

from .problem import Problem, RunContext
from .progress import Progress

__all__ = ["run_sweep"]


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
            bar.update(rec, problem.best_str(records))
    finally:
        bar.close()
