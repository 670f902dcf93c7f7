"""The evaluation budget a run was given, recorded in its ``study.yaml``.

``parasynth run --n-trials N`` runs N designs: the study saved in the run directory says so
(``optimizer.n_trials`` for Optuna, ``optimizer.maxeval`` for NLopt), so that the report, a
worker and ``--resume`` see the budget actually run. ``--resume`` without ``--n-trials``
continues to the recorded budget; with it, the new budget is recorded.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import yaml

from .optimizers.base import kinds, optimizer_class
from .spec import OptimizerSpec, ResolvedStudy, StudyError
from .structure_space import STRUCTURE, check_halving

__all__ = ["budget_key", "budget_of", "with_budget", "recorded_budget", "budget_for_run", "same_study"]


def budget_key(study: ResolvedStudy) -> str | None:
    """``n_trials`` (Optuna), ``maxeval`` (NLopt) or None (a sweep: its designs are listed)."""
    return optimizer_class(study.optimizer.kind).budget_key


def budget_of(study: ResolvedStudy) -> int | None:
    key = budget_key(study)
    return getattr(study.optimizer, key) if key else None


def with_budget(study: ResolvedStudy, n: int) -> ResolvedStudy:
    """The study with its budget set to ``n`` (its saved ``study.yaml`` says ``n``)."""
    key = budget_key(study)
    if key is None:
        raise StudyError("--n-trials applies to Optuna and NLopt studies; a sweep evaluates the designs it lists")
    if getattr(study.optimizer, key) == n:
        return study
    opt = study.optimizer.model_copy(update={key: int(n)})
    spec = study.spec.model_copy(update={"optimizer": opt})
    if study.structures is not None:  # the halving settings must still act within the new budget
        try:
            check_halving(spec.structure, opt, study.space.by_name[STRUCTURE].choices, int(n))
        except StudyError as e:
            raise StudyError(f"--n-trials {n}: {e}") from None
    return dataclasses.replace(study, spec=spec, optimizer=opt)


def recorded_budget(out_dir, study: ResolvedStudy) -> int | None:
    """The budget recorded in ``out_dir/study.yaml`` (None: no such file or no budget)."""
    key = budget_key(study)
    p = Path(out_dir) / "study.yaml"
    if key is None or not p.is_file():
        return None
    try:
        data = yaml.safe_load(p.read_text())
    except (yaml.YAMLError, OSError, UnicodeError):
        return None
    opt = data.get("optimizer") if isinstance(data, dict) else None
    n = opt.get(key) if isinstance(opt, dict) else None
    return n if isinstance(n, int) and not isinstance(n, bool) and n >= 1 else None


def budget_for_run(study: ResolvedStudy, out_dir, resume: bool, n_trials: int | None,
                   note=print) -> ResolvedStudy:
    """The study to run: with ``n_trials`` when given; on resume without it, with the budget
    recorded in the run directory (``note`` says so when it differs from the study file's)."""
    if n_trials is not None:
        return with_budget(study, n_trials)
    if resume:
        rec = recorded_budget(out_dir, study)
        if rec is not None and rec != budget_of(study):
            note(f"resume: continuing to the recorded budget of {rec} designs (the study file says "
                 f"{budget_of(study) or 'the default'}; pass --n-trials to change it)")
            return with_budget(study, rec)
    return study


def same_study(saved_text: str, text: str) -> bool:
    """Whether two saved studies (``study.yaml`` texts) are the same study, whatever budget
    each records (``--n-trials`` changes the budget of a run, not its study)."""
    if saved_text == text:
        return True
    try:
        a, b = yaml.safe_load(saved_text), yaml.safe_load(text)
    except yaml.YAMLError:
        return False
    if not isinstance(a, dict) or not isinstance(b, dict):
        return False
    for d in (a, b):
        opt = d.get("optimizer")
        if isinstance(opt, dict):
            kind = opt.get("kind", OptimizerSpec.model_fields["kind"].default)
            if kind in kinds():
                opt.pop(optimizer_class(kind).budget_key or "", None)
    return a == b
