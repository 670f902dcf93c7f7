"""The per-trial samplers keep the multivariate TPE's search space across trials
(``PerTrialSeeded._keep_space``): the proposals are exactly those of a new space each trial."""

from __future__ import annotations

import pytest

optuna = pytest.importorskip("optuna")

from parasynth.study.schedule import ATTR_STRUCTURE  # noqa: E402
from parasynth.study.workers import PerTrialSeeded  # noqa: E402


def _tpe(seed):
    return optuna.samplers.TPESampler(seed=seed, multivariate=True, n_startup_trials=5)


def _run(keep: bool, structures: bool, monkeypatch, n=36):
    """The params of ``n`` trials of a two-objective study with a conditional parameter (``z``
    only where ``x > 0.5``, so the intersection of the search spaces changes as trials come),
    a failed trial now and then, and, with ``structures``, two structures taking turns
    (each proposed from its own trials, as in a study over structures)."""
    cls = type(PerTrialSeeded(_tpe, 0))
    if not keep:
        monkeypatch.setattr(cls, "_keep_space", lambda self, sampler, number: sampler)
    else:
        monkeypatch.undo()
    assign = (lambda study, trial: "AB"[trial.number % 2]) if structures else None
    sampler = PerTrialSeeded(_tpe, 7, assign=assign)
    study = optuna.create_study(directions=["minimize", "minimize"], sampler=sampler)
    out = []
    for k in range(n):
        trial = study.ask()
        x = trial.suggest_float("x", 0.0, 1.0)
        y = trial.suggest_float("y", -1.0, 1.0)
        params = {"x": x, "y": y}
        if x > 0.5:
            params["z"] = trial.suggest_float("z", 0.0, 2.0)
        s = study._storage.get_trial(trial._trial_id).system_attrs.get(ATTR_STRUCTURE)
        if k % 7 == 3:
            study.tell(trial, state=optuna.trial.TrialState.FAIL)
        else:
            study.tell(trial, [(x - 0.3) ** 2 + params.get("z", 0.0), (y + 0.2) ** 2 + (1.0 if s == "B" else 0.0)])
        out.append((s, params))
    return out, sampler


@pytest.mark.parametrize("structures", [False, True])
def test_a_kept_search_space_proposes_exactly_what_a_new_one_each_trial_does(structures, monkeypatch):
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    fresh, _ = _run(False, structures, monkeypatch)
    kept, sampler = _run(True, structures, monkeypatch)
    assert kept == fresh
    # the proposals after the random start-up used the relative (multivariate) space, with z in
    # and out of it as the trials came
    assert any("z" in p for _, p in kept) and any("z" not in p for _, p in kept)
    # one space a structure (or one for the study), the one the last trial's sampler used
    keys = {"A", "B"} if structures else {None}
    assert set(sampler._spaces) == keys
    last = sampler._cur[1]
    assert last._search_space is sampler._spaces[kept[-1][0] if structures else None]
    # it read on from where it stopped: its cursor is past the start-up trials
    assert last._search_space._cached_trial_number > 5


def test_a_sampler_without_that_space_is_left_as_it_is(monkeypatch):
    sampler = PerTrialSeeded(lambda seed: optuna.samplers.RandomSampler(seed=seed), 3)
    study = optuna.create_study(sampler=sampler)
    for _ in range(4):
        t = study.ask()
        study.tell(t, t.suggest_float("x", 0.0, 1.0))
    assert sampler._spaces == {}
