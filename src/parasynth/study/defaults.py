"""Defaults of the optimisers, in one place: the budget when a study gives none, the default
algorithm of each kind and the seed of the optimiser."""

from __future__ import annotations

from .optimizers import optimizer_class

__all__ = ["OPTUNA_TRIALS", "NLOPT_MAXEVAL", "NLOPT_ALGORITHM", "optuna_algorithm", "nlopt_algorithm",
           "optuna_budget", "nlopt_budget", "optimizer_seed", "planned_designs"]

#: Optuna trials of a study without ``optimizer.n_trials`` (and no ``--n-trials``).
OPTUNA_TRIALS = 50
#: NLopt evaluations of a study without ``optimizer.maxeval`` (and no ``--n-trials``).
NLOPT_MAXEVAL = 100
#: NLopt algorithm of a study without ``optimizer.algorithm``.
NLOPT_ALGORITHM = "LN_COBYLA"


def optuna_algorithm(study) -> str:
    """``optimizer.algorithm``, else NSGA-II for several objectives and TPE for one; TPE for a
    study over structures (each structure's sampler sees only its trials)."""
    if getattr(study, "structures", None) is not None:
        return study.optimizer.algorithm or "tpe"
    return study.optimizer.algorithm or ("nsga2" if len(study.objectives) > 1 else "tpe")


def nlopt_algorithm(study) -> str:
    return study.optimizer.algorithm or NLOPT_ALGORITHM


def optuna_budget(study, n_trials: int | None = None, stored: int | None = None) -> int:
    """Trials of an Optuna study: ``n_trials`` (``--n-trials``), else the budget ``stored`` with
    the study in its storage (a worker joining a run), else ``optimizer.n_trials``, else
    :data:`OPTUNA_TRIALS`."""
    return int(n_trials or stored or study.optimizer.n_trials or OPTUNA_TRIALS)


def nlopt_budget(study, n_trials: int | None = None) -> int:
    """Evaluations of an NLopt run: ``n_trials``, else ``optimizer.maxeval``, else
    :data:`NLOPT_MAXEVAL`."""
    return int(n_trials or study.optimizer.maxeval or NLOPT_MAXEVAL)


def optimizer_seed(study) -> int:
    """``optimizer.seed``, else the evaluation seed."""
    return study.optimizer.seed if study.optimizer.seed is not None else study.evaluation["seed"]


def planned_designs(study) -> int | None:
    """Designs a finished run of ``study`` holds with its own budget: every design of a sweep,
    the trials of an Optuna study; ``None`` for NLopt (it may stop early on its tolerances)
    (each optimiser's :meth:`~parasynth.study.optimizers.BaseOptimizer.planned_designs`);
    ``None`` with ``optimizer.polish`` (the local search may stop before its budget)."""
    if getattr(study.optimizer, "polish", None) is not None:
        return None
    return optimizer_class(study.optimizer.kind).planned_designs(study)
