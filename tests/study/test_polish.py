"""``optimizer.polish``: a local NLopt search after a global optimiser, on analytic measures
with known optima: the polished design is better than the start and nearer the closed-form
optimum, every polish evaluation is a trial inside the study's budget, polish.json says what
moved; with several objectives no objective gets worse; bad combinations are refused by name;
an interrupted polish resumes to the uninterrupted result."""

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

from parasynth.cli.plugins import load_plugins
from parasynth.report import write_report
from parasynth.study import StudyError, load_study, run_study
from parasynth.study.polish import read_polish
from parasynth.study.rundir import read_run

PLUGIN = str(Path(__file__).resolve().parents[1] / "data" / "analytic_plugin.py")
load_plugins(PLUGIN)


def study_dict(optimizer, objectives=None, constraints=None):
    return {"name": "polish", "mechanism": "5pus_upu",
            "variables": [{"name": "link_length", "low": "150 mm", "high": "250 mm"},
                          {"name": "slider_radius", "low": "100 mm", "high": "180 mm"}],
            # test_quadratic: maximum 0 at L = 200 mm, R = 140 mm
            "objectives": objectives or [{"name": "test_quadratic", "goal": "maximize"}],
            "constraints": constraints or [],
            "evaluation": {"samples": 64}, "optimizer": optimizer}


def run(tmp_path, d, **kw):
    return run_study(load_study(yaml.safe_dump(d), is_text=True), out_dir=tmp_path / "r", progress=False, **kw)


@pytest.mark.parametrize("method", ["cobyla", "bobyqa"])
def test_polish_refines_the_best_design_within_the_budget(tmp_path, method):
    d = study_dict({"kind": "optuna", "algorithm": "random", "n_trials": 30, "seed": 1,
                    "polish": {"method": method, "budget": 12}})
    res = run(tmp_path, d)
    t = res.table[res.table["source"] == "run"].sort_values("trial")
    assert len(t) <= 30 and t["trial"].tolist() == list(range(len(t)))
    info = read_polish(tmp_path / "r")
    assert info["status"] == "done" and info["first_trial"] == 18 and 0 < info["evaluations"] <= 12
    assert len(t[t["trial"] >= 18]) == info["evaluations"]
    start = t[t["trial"] < 18].loc[t[t["trial"] < 18]["test_quadratic"].idxmax()]
    assert info["start"]["trial"] == int(start["trial"])
    pol = info["polished"]
    assert pol is not None and pol["objectives"]["test_quadratic"] > start["test_quadratic"]
    # nearer the closed-form optimum (0.2 m, 0.14 m) than the start
    dist = lambda v: np.hypot(v["link_length"] - 0.2, v["slider_radius"] - 0.14)
    assert dist(pol["values"]) < dist(start)
    moved = info["moved"]["link_length"]
    assert moved["share_of_range"] == pytest.approx(abs(moved["to"] - moved["from"]) / 0.1)
    assert info["change"]["test_quadratic"] == pytest.approx(pol["objectives"]["test_quadratic"]
                                                           - start["test_quadratic"])
    # a finished polish is a complete run, even when the local search converged before its budget
    run_ = read_run(tmp_path / "r")
    assert not run_.partial and run_.partial_reason == ""
    if info["evaluations"] < 12:
        assert run_.n_run < 30  # the case the budget rule alone would call partial


def test_cobyla_polish_keeps_the_constraints_and_resume_equals_uninterrupted(tmp_path):
    d = study_dict({"kind": "scipy", "n_trials": 40, "seed": 2, "polish": {"method": "cobyla", "budget": 15}},
                   constraints=[{"name": "test_link_length", "max": "190 mm"}])
    res = run(tmp_path, d)
    info = read_polish(tmp_path / "r")
    pol = info["polished"]
    assert pol is not None and pol["values"]["link_length"] <= 0.19 + 1e-9
    lines = [json.loads(x) for x in (tmp_path / "r" / "journal.jsonl").read_text().splitlines()]
    # interrupted in the polish: the journal cut after 30 designs, polish.json as at its start
    cut = tmp_path / "cut"
    cut.mkdir()
    (cut / "journal.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines[:30]))
    (cut / "study.yaml").write_text((tmp_path / "r" / "study.yaml").read_text())
    (cut / "polish.json").write_text(json.dumps({**info, "status": "running", "polished": None}))
    run_study(load_study(yaml.safe_dump(d), is_text=True), out_dir=cut, resume=True, progress=False)
    again = [json.loads(x) for x in (cut / "journal.jsonl").read_text().splitlines()]
    key = lambda x: (x["trial"], json.dumps(x["values"], sort_keys=True), json.dumps(x["objectives"]))
    assert [key(x) for x in again] == [key(x) for x in lines]
    assert read_polish(cut)["polished"] == pol
    assert len(res.table[res.table["source"] == "run"]) <= 40  # COBYLA may converge before its budget


def test_several_objectives_polish_the_recommended_design_none_worse(tmp_path):
    d = study_dict({"kind": "optuna", "algorithm": "random", "n_trials": 40, "seed": 0,
                    "polish": {"method": "cobyla", "budget": 15}},
                   objectives=[{"name": "test_quadratic", "goal": "maximize"}, {"name": "test_two", "goal": "minimize"}])
    run(tmp_path, d)
    info = read_polish(tmp_path / "r")
    assert info["status"] == "done" and info["start"] is not None
    if info["polished"] is not None:
        s, p = info["start"]["objectives"], info["polished"]["objectives"]
        assert p["test_quadratic"] >= s["test_quadratic"] and p["test_two"] <= s["test_two"]
        assert p["test_quadratic"] > s["test_quadratic"] or p["test_two"] < s["test_two"]


@pytest.mark.parametrize("optimizer,constraints,needle", [
    ({"kind": "sweep", "polish": {"budget": 3}}, None, "optimizer.polish: refines the result of a global optimiser"),
    ({"kind": "nlopt", "maxeval": 20, "polish": {"budget": 3}}, None, "nlopt LN_COBYLA is not one"),
    ({"kind": "scipy", "n_trials": 20, "polish": {"method": "bobyqa", "budget": 3}},
     [{"name": "test_link_length", "max": "190 mm"}], "optimizer.polish.method: bobyqa takes no constraints"),
    ({"kind": "scipy", "n_trials": 20, "polish": {"budget": 20}}, None, "optimizer.polish.budget: 20 designs"),
    ({"kind": "optuna", "polish": {"method": "lbfgs", "budget": 3}}, None, "optimizer.polish.method"),
])
def test_bad_polish_is_refused_by_name(optimizer, constraints, needle):
    d = study_dict(optimizer, constraints=constraints)
    if optimizer["kind"] == "sweep":
        d["variables"] = [{"name": "link_length", "values": ["180 mm", "200 mm"]}]
    with pytest.raises(StudyError, match=needle):
        load_study(yaml.safe_dump(d), is_text=True)


def test_nlopt_global_algorithm_may_be_polished():
    d = study_dict({"kind": "nlopt", "algorithm": "GN_ISRES", "maxeval": 20, "polish": {"budget": 5}})
    assert load_study(yaml.safe_dump(d), is_text=True).optimizer.polish.budget == 5


def test_the_report_says_which_design_was_polished_and_how_far_it_moved(tmp_path):
    d = study_dict({"kind": "scipy", "n_trials": 30, "seed": 2, "polish": {"method": "cobyla", "budget": 10}})
    run(tmp_path, d)
    info = read_polish(tmp_path / "r")
    assert info["polished"] is not None
    md = (write_report(tmp_path / "r", tmp_path / "rep") / "report.md").read_text()
    # a finished polish is a complete run (a local polish may stop before its budget is spent)
    assert "PARTIAL REPORT" not in md
    sec = md[md.index("Polish"):]
    assert f"(trial {info['start']['trial']}) was polished by a local COBYLA search" in sec
    assert f"Polished design: trial {info['polished']['trial']}" in sec
    moved_mm = (info["moved"]["link_length"]["to"] - info["moved"]["link_length"]["from"]) * 1e3
    assert "link_length" in sec and f"{100 * info['moved']['link_length']['share_of_range']:.2g} %" in sec
    assert abs(moved_mm) > 0 or info["moved"]["slider_radius"]["share_of_range"] > 0


def test_optuna_polish_interrupted_by_ctrl_c_resumes_to_the_uninterrupted_run(tmp_path):
    """Ctrl-C in the polish of an Optuna run: the polish designs are trials of its storage, and
    ``--resume`` continues the same path to the same journal and polish.json."""
    d = study_dict({"kind": "optuna", "algorithm": "random", "n_trials": 14, "seed": 3,
                    "polish": {"method": "bobyqa", "budget": 8}},
                   objectives=[{"name": "test_quadratic", "goal": "maximize", "settings": {"delay": 0.2}}])
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(d))
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "parasynth.cli", "run", str(path), "--out", str(out), "--quiet", "--no-report"]
    proc = subprocess.Popen(cmd, env={**os.environ, "PARASYNTH_PLUGINS": PLUGIN}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 90
    while time.time() < deadline:  # the 6 trials of the global search, then 2 of the polish
        p = out / "journal.jsonl"
        if p.exists() and len([x for x in p.read_text().splitlines() if x.endswith("}")]) >= 8:
            break
        if proc.poll() is not None:
            raise AssertionError(f"the run ended early: {proc.communicate()}")
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert read_polish(out)["status"] == "running"
    cut = [json.loads(x) for x in (out / "journal.jsonl").read_text().splitlines()]
    assert 8 <= len(cut) < 14
    run_study(load_study(yaml.safe_dump(d), is_text=True), out_dir=out, resume=True, progress=False)
    fresh = tmp_path / "fresh"
    run_study(load_study(yaml.safe_dump(d), is_text=True), out_dir=fresh, progress=False)
    key = lambda x: (x["trial"], json.dumps(x["values"], sort_keys=True), json.dumps(x["objectives"]))
    lines = lambda o: [key(json.loads(x)) for x in (o / "journal.jsonl").read_text().splitlines()]
    assert lines(out) == lines(fresh)
    assert lines(out)[:len(cut)] == [key(x) for x in cut]
    a, b = read_polish(out), read_polish(fresh)
    assert a["status"] == b["status"] == "done" and a["polished"] == b["polished"] and a["first_trial"] == 6
