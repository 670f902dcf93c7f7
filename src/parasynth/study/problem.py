"""The problem a runner solves: one object with the design space, the objectives, the
constraints, the budget, the seed and the evaluation of a design.

Every optimiser (:mod:`parasynth.study.optimizers`) runs ``run(problem, ctx)`` against a
:class:`Problem` and a :class:`RunContext` (the records so far, the callback that
records a new one, the progress flag and the interrupt guard); the run directory, the
journal, resuming and the tables are the caller's (:mod:`parasynth.study.runner`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from ..measures.display import fmt_column_value
from .defaults import optimizer_seed
from .evaluate import Evaluator, Record
from .signals import Interrupt
from .optimizers import optimizer_class
from .polish import polish_budget
from .spec import ResolvedStudy
from .space import DesignSpace

__all__ = ["Problem", "RunContext"]


class Problem:
    """A resolved study as an optimisation problem.

    * ``space``: the :class:`~parasynth.study.space.DesignSpace`;
    * ``objectives`` / ``names`` / ``senses``: the objectives, their column labels and goals
      (``"maximize"`` / ``"minimize"``);
    * ``constraints``: the design constraints (a design is feasible when every margin >= 0);
    * ``seed``: the optimiser's seed; :meth:`budget`: the designs a run may evaluate;
    * :meth:`evaluate`: one design -> :class:`~parasynth.study.evaluate.Record`.
    """

    def __init__(self, study: ResolvedStudy, evaluator: Evaluator | None = None):
        self.study = study
        self.space: DesignSpace = study.space
        self.objectives = study.objectives
        self.names = [o.label for o in study.objectives]
        self.senses = [o.goal for o in study.objectives]
        self.constraints = study.constraints
        self.seed = optimizer_seed(study)
        self.evaluator = evaluator or Evaluator(study)
        self.optimizer = optimizer_class(study.optimizer.kind)

    @property
    def name(self) -> str:
        return self.study.name

    def budget(self, n_trials: int | None = None) -> int:
        """Designs the optimiser may evaluate: ``n_trials`` when given, else the study's own
        budget (the sweep's designs, ``optimizer.maxeval`` of NLopt, ``optimizer.n_trials`` of
        Optuna, each with its default from :mod:`parasynth.study.defaults`), less the designs
        of ``optimizer.polish`` (:mod:`parasynth.study.polish`)."""
        return self.optimizer.budget(self.study, n_trials) - polish_budget(self.study)

    def designs(self) -> list[dict]:
        """The designs of a sweep: ``optimizer.designs`` (SI), else the grid."""
        opt = self.study.optimizer
        if opt.designs:
            return [self.space.parse(d, f"optimizer.designs[{j}]") for j, d in enumerate(opt.designs)]
        return self.space.grid()

    def start(self) -> dict | None:
        """The start design given in the study (``optimizer.start``, SI), else None."""
        start = self.study.optimizer.start
        return self.space.parse(start, "optimizer.start") if start else None

    @property
    def reference(self) -> dict | None:
        return self.study.reference

    def evaluate(self, values: dict, trial: int = -1, source: str = "run", n: int | None = None,
                 seed: int | None = None) -> Record:
        """Evaluate design ``values`` (SI; inactive conditional variables left out)."""
        return self.evaluator.evaluate(values, n=n, seed=seed, trial=trial, source=source)

    def best_str(self, records) -> str:
        """The progress bar's note: the best value of one objective, else the feasible count."""
        ok = [r for r in records if r.feasible and r.source == "run"]
        if not ok or len(self.objectives) != 1:
            return f"{len(ok)} feasible"
        o = self.objectives[0]
        vals = [r.objectives[o.label] for r in ok]
        b = max(vals) if o.goal == "maximize" else min(vals)
        return f"best {o.label} = {fmt_column_value(self.study, o.label, b)}"


@dataclass
class RunContext:
    """What a runner gets besides the problem.

    ``records``: every record so far (a resumed run's included; a runner skips or replays
    them); ``record(rec)``: journal, keep and count a new record; ``progress``: show a
    progress bar; ``guard``: the interrupt guard (evaluate inside ``guard.evaluating()``, stop
    when ``guard.requested``); ``n_trials``: the budget given on the command line.
    The remaining fields serve the optimisers with a storage and workers (Optuna)."""

    records: list
    record: Callable[[Record], None]
    progress: bool = False
    guard: Interrupt = field(default_factory=Interrupt)
    n_trials: int | None = None
    out_dir: Path | None = None
    workers: int = 1
    journal: object = None
    backend: dict = field(default_factory=dict)
