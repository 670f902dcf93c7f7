"""``optimizer: {kind: scipy, algorithm: differential_evolution}``: a run on analytic measures
finds the closed-form constrained optimum, is cut at its budget and records every evaluation as a
trial; Ctrl-C then ``--resume`` gives the journal of an uninterrupted run; the settings SciPy
gets (constraints, integrality, polish, updating) are checked; several objectives and a study
over structures are refused by name."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import parasynth.study.optimizers.scipy as de
from parasynth.cli.plugins import load_plugins
from parasynth.study import StudyError, load_study, run_study
from parasynth.study.problem import Problem, RunContext
from parasynth.study.space import DesignSpace, Variable

PLUGIN = str(Path(__file__).resolve().parents[1] / "data" / "analytic_plugin.py")
load_plugins(PLUGIN)


def study_dict(n=40, delay=0.0, **over):
    d = {"name": "scipy_de", "mechanism": "5pus_upu",
         "variables": [{"name": "link_length", "low": "150 mm", "high": "250 mm"},
                       {"name": "slider_radius", "low": "100 mm", "high": "180 mm"}],
         # test_quadratic: maximum at L = 200 mm, R = 140 mm; the constraint L <= 190 mm moves it
         # to L = 190 mm (closed form)
         "objectives": [{"name": "test_quadratic", "goal": "maximize", "settings": {"delay": delay}}],
         "constraints": [{"name": "test_link_length", "max": "190 mm"}],
         "evaluation": {"samples": 64},
         "optimizer": {"kind": "scipy", "algorithm": "differential_evolution", "n_trials": n, "seed": 4}}
    d.update(over)
    return d


def journal(out):
    return [json.loads(x) for x in (Path(out) / "journal.jsonl").read_text().splitlines() if x.strip()]


def test_finds_the_constrained_optimum_within_the_budget(tmp_path):
    res = run_study(load_study(yaml.safe_dump(study_dict(n=160)), is_text=True), out_dir=tmp_path / "r",
                    progress=False)
    lines = [x for x in journal(tmp_path / "r") if x["source"] == "run"]
    assert len(lines) == 160 and [x["trial"] for x in lines] == list(range(160))
    t = res.table[res.table["source"] == "run"]
    assert len(t) == 160
    feas = t[t["feasible"]]
    assert (feas["test_link_length"] <= 0.19 + 1e-12).all() and not feas.empty
    best = feas.loc[feas["test_quadratic"].idxmax()]
    assert best["link_length"] == pytest.approx(0.19, abs=4e-3)
    assert best["slider_radius"] == pytest.approx(0.14, abs=6e-3)
    # the optimum value is -(0.19 - 0.2)^2 = -1e-4
    assert best["test_quadratic"] == pytest.approx(-1e-4, abs=6e-5)
    assert res.final is not None and len(res.final)


def test_interrupted_and_resumed_run_equals_the_uninterrupted_one(tmp_path):
    d = study_dict(n=30, delay=0.1)
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(d))
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "parasynth.cli", "run", str(path), "--out", str(out), "--quiet", "--no-report"]
    env = {**os.environ, "PARASYNTH_PLUGINS": PLUGIN}
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 90
    while time.time() < deadline:
        p = out / "journal.jsonl"
        if p.exists() and len([x for x in p.read_text().splitlines() if x.endswith("}")]) >= 8:
            break
        if proc.poll() is not None:
            raise AssertionError(f"the run ended early: {proc.communicate()}")
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    before = journal(out)
    assert 8 <= len(before) < 30, "the run was not interrupted mid-way"
    run_study(load_study(yaml.safe_dump(d), is_text=True), out_dir=out, resume=True, progress=False)
    after = journal(out)
    fresh = run_study(load_study(yaml.safe_dump(d), is_text=True), out_dir=tmp_path / "fresh", progress=False)
    keys = [(x["trial"], json.dumps(x["values"], sort_keys=True)) for x in after]
    assert keys[:len(before)] == [(x["trial"], json.dumps(x["values"], sort_keys=True)) for x in before]
    assert keys == [(x["trial"], json.dumps(x["values"], sort_keys=True)) for x in journal(tmp_path / "fresh")]
    assert len(set(k[1] for k in keys)) == len(keys) == 30  # nothing evaluated twice
    assert [x["objectives"] for x in after] == [x["objectives"] for x in journal(tmp_path / "fresh")]
    assert fresh.n_total == 30


def test_scipy_gets_one_constraint_integrality_no_polish_and_deferred_updating(monkeypatch):
    seen = {}

    def fake(func, bounds, **kw):
        seen.update(kw, bounds=bounds)
        x = np.array([0.5] * len(bounds))
        # objective and constraints of one design: one evaluation
        func(x)
        kw["constraints"][0].fun(x)

    import scipy.optimize

    monkeypatch.setattr(scipy.optimize, "differential_evolution", fake)  # the optimiser imports it when it runs
    s = load_study(yaml.safe_dump(study_dict(n=10)), is_text=True)
    calls = []

    class Counted(Problem):
        def evaluate(self, values, **kw):
            calls.append(values)
            return super().evaluate(values, **kw)

    recs = []
    de.run_scipy(Counted(s), RunContext(recs, recs.append, n_trials=10))
    assert seen["polish"] is False and seen["updating"] == "deferred"
    assert len(seen["constraints"]) == 1 and seen["constraints"][0].lb == 0.0
    assert seen["integrality"] is None and seen["bounds"] == [(0.0, 1.0), (0.0, 1.0)]
    assert len(calls) == 1 and len(recs) == 1 and recs[0].trial == 0


def test_integer_and_categorical_variables_are_integral_coordinates():
    space = DesignSpace([Variable("n", "integer", None, 2, 7), Variable("c", "categorical", None, choices=("a", "b", "c")),
                         Variable("x", "continuous", "length", 0.1, 0.3)])
    vars_, bounds, integral, to_values = de._coordinates(space)
    assert bounds == [(2, 7), (0, 2), (0.0, 1.0)] and integral.tolist() == [True, True, False]
    assert to_values([4.4, 1.6, 0.25]) == {"n": 4, "c": "c", "x": pytest.approx(0.15)}


def test_several_objectives_are_refused_by_name():
    d = study_dict(objectives=[{"name": "test_quadratic"}, {"name": "test_two"}])
    with pytest.raises(StudyError, match=r"objectives: scipy optimises one objective, 2 given \(test_quadratic, "
                                         r"test_two\)"):
        load_study(yaml.safe_dump(d), is_text=True)


def test_a_study_over_structures_is_refused_by_name():
    d = {"name": "s", "structure": {"motion": "3T2R", "leg_types": ["SPS", "UPS", "PUS", "UPU"]},
         "variables": [{"name": "base_radius", "low": "100 mm", "high": "140 mm"}],
         "objectives": [{"name": "workspace_volume"}], "evaluation": {"samples": 64},
         "optimizer": {"kind": "scipy", "n_trials": 10}}
    with pytest.raises(StudyError, match="optimizer.kind: scipy cannot run a study over structures"):
        load_study(yaml.safe_dump(d), is_text=True)
