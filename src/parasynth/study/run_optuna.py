"""The Optuna runner: the trial loop of one process, or local worker processes, on the study
opened by :func:`parasynth.study.runner._optuna_setup` (``ctx.backend``: the Optuna study,
its budget, its storage URL and whether the storage is shared)."""

from __future__ import annotations

import sys
from pathlib import Path

from . import storage as st
from .defaults import optuna_algorithm
from .journal import rewrite_journal
from .problem import Problem, RunContext
from .progress import Progress
from .workers import optimize_budget, optuna_objective, run_local_workers

__all__ = ["run_optuna"]


def run_optuna(problem: Problem, ctx: RunContext) -> None:
    study, records, record, guard = problem.study, ctx.records, ctx.record, ctx.guard
    backend = ctx.backend
    ostudy, total = backend["ostudy"], backend["total"]
    counted = sum(1 for r in records if r.source == "run")
    if counted >= total and not backend["shared"]:
        return
    alg = optuna_algorithm(study)
    bar = Progress(total, ctx.progress, f"optuna {alg} {study.name}", initial=min(counted, total))
    try:
        if ctx.workers > 1:
            def on_new(recs):
                for r in recs:
                    record(r)
                bar.update(None, problem.best_str(records), n=len(recs))

            codes = run_local_workers(Path(ctx.out_dir) / "study.yaml", backend["url"], ctx.workers, total, ostudy,
                                      guard, on_new=on_new, fork=(study, problem.evaluator, backend["seed"]))
            bad = [c for c in codes if c not in (0, 130, -2)]
            if bad and not guard.requested:
                print(f"warning: {len(bad)} worker(s) stopped with an error (exit codes {bad}); the study keeps "
                      f"their stored trials", file=sys.stderr)
        else:
            def on_record(rec):
                record(rec)
                bar.update(rec, problem.best_str(records))

            objective = optuna_objective(study, problem.evaluator, on_record, guard=guard, mark_owner=backend["shared"])
            optimize_budget(ostudy, objective, study, total, guard, shared=backend["shared"], counted=counted,
                          on_count=bar.set_count)
    finally:
        bar.close()
    if backend["shared"] or ctx.workers > 1:
        # Designs of every worker (other machines included), each trial once, in trial order.
        ref = [r for r in records if r.source == "reference"]
        recs = st.records_from_trials(ostudy.get_trials(deepcopy=False))
        records[:] = ref + recs
        ctx.journal.close()
        rewrite_journal(Path(ctx.out_dir) / "journal.jsonl", records)
