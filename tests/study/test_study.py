"""The study machinery: YAML validation, runners on an analytic problem, determinism, resume."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from parasynth.cli import load_plugins
from parasynth.study import StudyError, load_study, run_study

PLUGIN = str(Path(__file__).resolve().parents[1] / "data" / "analytic_plugin.py")
load_plugins(PLUGIN)

BASE = {
    "name": "analytic",
    "mechanism": "5pus_upu",
    "variables": [
        {"name": "link_length", "low": "150 mm", "high": "250 mm"},
        {"name": "slider_radius", "low": "100 mm", "high": "180 mm"},
    ],
    "objectives": [{"name": "test_quadratic", "goal": "maximize"}],
    "optimizer": {"kind": "nlopt", "algorithm": "LN_COBYLA", "maxeval": 80, "xtol_rel": 1e-6},
}


def study_of(**changes):
    d = json.loads(json.dumps(BASE))
    for k, v in changes.items():
        d[k] = v
    return load_study(yaml.safe_dump(d), is_text=True)


# -- validation -------------------------------------------------------------------------------------
def error_of(data) -> str:
    with pytest.raises(StudyError) as e:
        load_study(yaml.safe_dump(data), is_text=True)
    return str(e.value)


def test_round_trip_resolved_yaml():
    s1 = study_of()
    s2 = load_study(s1.to_yaml(), is_text=True)
    assert s1.variables == s2.variables
    assert s1.objectives == s2.objectives
    assert s2.variables[0].low == pytest.approx(0.150)
    assert s2.variables[1].high == pytest.approx(0.180)


def test_units_are_converted():
    s = study_of(fixed={"sphere_max": "30 deg", "link_diameter": "8 mm"})
    assert s.fixed["sphere_max"] == pytest.approx(np.deg2rad(30))
    assert s.fixed["link_diameter"] == pytest.approx(0.008)


def test_unknown_objective_lists_valid_names():
    msg = error_of({**BASE, "objectives": [{"name": "volumee"}]})
    assert "objectives[0].name" in msg and "workspace_volume" in msg and "test_quadratic" in msg


def test_bare_number_where_unit_required():
    d = json.loads(json.dumps(BASE))
    d["variables"][0]["low"] = 150
    msg = error_of(d)
    assert "variables[0].low" in msg and "unit" in msg


def test_empty_bounds():
    d = json.loads(json.dumps(BASE))
    d["variables"][0]["low"] = "250 mm"
    msg = error_of(d)
    assert "variables[0]" in msg and "low" in msg and "high" in msg


def test_unknown_key_names_path_and_allowed():
    d = json.loads(json.dumps(BASE))
    d["variables"][1]["lo"] = "1 mm"
    msg = error_of(d)
    assert "variables[1].lo" in msg and "low" in msg


def test_unknown_parameter_lists_valid():
    d = json.loads(json.dumps(BASE))
    d["variables"][0]["name"] = "link_lenght"
    msg = error_of(d)
    assert "variables[0].name" in msg and "link_length" in msg


def test_wrong_dimension():
    d = json.loads(json.dumps(BASE))
    d["variables"][0]["high"] = "3 kg"
    assert "not a length" in error_of(d)


def test_unknown_mechanism_and_setting():
    assert "available" in error_of({**BASE, "mechanism": "nope"})
    d = json.loads(json.dumps(BASE))
    d["objectives"][0]["settings"] = {"colour": 1}
    msg = error_of(d)
    assert "objectives[0].settings.colour" in msg and "delay" in msg


def test_nlopt_refuses_two_objectives():
    d = json.loads(json.dumps(BASE))
    d["objectives"].append({"name": "test_two"})
    assert "optuna" in error_of(d)


def test_missing_file():
    with pytest.raises(StudyError, match="does not exist"):
        load_study("/nonexistent/study.yaml")


# -- runners on the analytic problem ------------------------------------------------------------------
def test_nlopt_finds_known_optimum(tmp_path):
    res = run_study(study_of(), out_dir=tmp_path / "r", progress=False)
    t = res.table[res.table.source == "run"]
    best = t.loc[t["test_quadratic"].idxmax()]
    assert best["link_length"] == pytest.approx(0.2, abs=1e-3)
    assert best["slider_radius"] == pytest.approx(0.14, abs=1e-3)
    assert (tmp_path / "r" / "results.csv").exists() and (tmp_path / "r" / "study.yaml").exists()


def test_nlopt_with_constraint_moves_to_bound(tmp_path):
    s = study_of(constraints=[{"name": "test_link_length", "max": "190 mm"}])
    res = run_study(s, out_dir=tmp_path / "r", progress=False)
    t = res.table[(res.table.source == "run") & res.table.feasible]
    best = t.loc[t["test_quadratic"].idxmax()]
    assert best["link_length"] == pytest.approx(0.19, abs=2e-3)
    assert best["slider_radius"] == pytest.approx(0.14, abs=2e-3)
    assert (t["test_link_length_margin"] >= 0).all()


def test_optuna_finds_known_optimum(tmp_path):
    s = study_of(optimizer={"kind": "optuna", "algorithm": "tpe", "n_trials": 60, "seed": 1})
    res = run_study(s, out_dir=tmp_path / "r", progress=False)
    t = res.table[res.table.source == "run"]
    assert len(t) == 60
    best = t.loc[t["test_quadratic"].idxmax()]
    # TPE is a sampler, not a local solver: it gets close, not exact.
    assert abs(best["link_length"] - 0.2) < 0.01 and abs(best["slider_radius"] - 0.14) < 0.01
    # The embedded storage holds every design's record: the table can be rebuilt from it alone.
    from parasynth.study.storage import open_storage, records_from_trials
    import optuna

    st = optuna.load_study(study_name="analytic", storage=open_storage(f"journal:{tmp_path / 'r' / 'optuna.journal'}"))
    recs = records_from_trials(st.trials)
    assert [r.trial for r in recs] == list(t["trial"])
    assert np.allclose([r.objectives["test_quadratic"] for r in recs], t["test_quadratic"])


def test_optuna_multiobjective_and_failures_recorded(tmp_path):
    s = study_of(
        objectives=[{"name": "test_quadratic"}, {"name": "test_two"}],
        constraints=[{"name": "test_fail_above", "max": "1 m"}],
        optimizer={"kind": "optuna", "algorithm": "nsga2", "n_trials": 30, "seed": 0},
    )
    res = run_study(s, out_dir=tmp_path / "r", progress=False)
    t = res.table[res.table.source == "run"]
    assert len(t) == 30
    failed = t[t.status == "failed"]
    assert len(failed) > 0 and (failed["link_length"] > 0.21).all()
    assert failed["error"].str.contains("deliberate failure").all()
    assert not failed["feasible"].any()


def test_sweep_and_reference(tmp_path):
    s = study_of(
        variables=[{"name": "link_length", "values": ["165 mm", "185 mm", "205 mm", "225 mm"]}],
        optimizer={"kind": "sweep"},
        reference={"link_length": "205 mm"},
    )
    res = run_study(s, out_dir=tmp_path / "r", progress=False)
    t = res.table
    run = t[t.source == "run"]
    assert sorted(run["link_length"].round(6)) == [0.165, 0.185, 0.205, 0.225]
    expected = -((run["link_length"] - 0.2) ** 2) - (0.135 - 0.14) ** 2
    assert np.allclose(run["test_quadratic"], expected)
    assert (t.source == "reference").sum() == 1


def test_determinism_same_table(tmp_path):
    s = study_of(optimizer={"kind": "optuna", "algorithm": "tpe", "n_trials": 15, "seed": 3})
    a = run_study(s, out_dir=tmp_path / "a", progress=False).table.drop(columns="time_s")
    b = run_study(s, out_dir=tmp_path / "b", progress=False).table.drop(columns="time_s")
    pd.testing.assert_frame_equal(a, b)


def test_existing_dir_needs_resume(tmp_path):
    s = study_of()
    run_study(s, out_dir=tmp_path / "r", progress=False)
    with pytest.raises(StudyError, match="--resume"):
        run_study(s, out_dir=tmp_path / "r", progress=False)


def test_resume_refuses_changed_study(tmp_path):
    run_study(study_of(), out_dir=tmp_path / "r", progress=False)
    other = study_of(optimizer={"kind": "nlopt", "algorithm": "LN_COBYLA", "maxeval": 10})
    with pytest.raises(StudyError, match="differs"):
        run_study(other, out_dir=tmp_path / "r", resume=True, progress=False)


def test_nlopt_resume_replays_without_repeating(tmp_path):
    s = study_of()
    run_study(s, out_dir=tmp_path / "r", progress=False, n_trials=20)
    first = (tmp_path / "r" / "journal.jsonl").read_text().splitlines()
    res = run_study(s, out_dir=tmp_path / "r", resume=True, progress=False, n_trials=60)
    lines = (tmp_path / "r" / "journal.jsonl").read_text().splitlines()
    values = [json.dumps(json.loads(l)["values"], sort_keys=True) for l in lines]
    assert len(values) == len(set(values)), "a design was evaluated twice"
    assert len(first) == 20 and lines[:20] == first and res.n_new == len(lines) - 20 > 0
    # The resumed run follows exactly the path of an uninterrupted one.
    fresh = run_study(s, out_dir=tmp_path / "f", progress=False, n_trials=60)
    fresh_values = [json.dumps(json.loads(l)["values"], sort_keys=True)
                    for l in (tmp_path / "f" / "journal.jsonl").read_text().splitlines()]
    assert fresh_values == values


@pytest.mark.parametrize("kind", ["optuna", "sweep"])
def test_resume_after_killed_subprocess(tmp_path, kind):
    d = json.loads(json.dumps(BASE))
    d["objectives"] = [{"name": "test_quadratic", "settings": {"delay": 0.15}}]
    if kind == "optuna":
        d["optimizer"] = {"kind": "optuna", "algorithm": "tpe", "n_trials": 24, "seed": 0}
        total = 24
    else:
        d["variables"] = [{"name": "link_length", "low": "150 mm", "high": "250 mm", "num": 24}]
        d["optimizer"] = {"kind": "sweep"}
        total = 24
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(d))
    out = tmp_path / "run"
    env = {**os.environ, "PARASYNTH_PLUGINS": PLUGIN}
    cmd = [sys.executable, "-m", "parasynth.cli", "run", str(path), "--out", str(out), "--quiet", "--no-report"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    journal = out / "journal.jsonl"
    deadline = time.time() + 60
    while time.time() < deadline:
        if journal.exists() and len(journal.read_text().splitlines()) >= 6:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done_before = [json.loads(l) for l in journal.read_text().splitlines() if l.strip()]
    assert 6 <= len(done_before) < total, "the run was not interrupted mid-way"
    r = subprocess.run(cmd + ["--resume"], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    recs = [json.loads(l) for l in journal.read_text().splitlines() if l.strip()]
    keys = [json.dumps(x["values"], sort_keys=True) for x in recs]
    assert len(recs) == total
    assert len(set(keys)) == total, "a completed design was repeated"
    assert keys[: len(done_before)] == [json.dumps(x["values"], sort_keys=True) for x in done_before]
    table = pd.read_csv(out / "results.csv")
    assert len(table[table.source == "run"]) == total


def test_tied_parameters_follow_their_variable(tmp_path):
    s = load_study(yaml.safe_dump({
        "name": "tied", "mechanism": "5pus_upu",
        "variables": [{"name": "sphere_max", "values": ["30 deg", "40 deg"]}],
        "tied": {"ujoint_max": "sphere_max"},
        "objectives": [{"name": "home_feasibility"}],
        "optimizer": {"kind": "sweep"}}), is_text=True)
    from parasynth.study import Evaluator

    mech = Evaluator(s).build({"sphere_max": np.deg2rad(33)})
    assert mech.params.ujoint_max == pytest.approx(np.deg2rad(33))
    bad = {"name": "tied", "mechanism": "5pus_upu", "variables": [{"name": "sphere_max", "values": ["30 deg"]}],
           "tied": {"link_length": "sphere_max"}, "objectives": [{"name": "home_feasibility"}],
           "optimizer": {"kind": "sweep"}}
    with pytest.raises(StudyError, match="different units"):
        load_study(yaml.safe_dump(bad), is_text=True)


def test_optuna_parallel_processes(tmp_path, monkeypatch):
    """n_jobs > 1 runs worker processes sharing the run's journal storage: every trial
    evaluated once (identical designs included), the table complete."""
    monkeypatch.setenv("PARASYNTH_PLUGINS", PLUGIN)
    s = study_of(optimizer={"kind": "optuna", "algorithm": "random", "n_trials": 12, "seed": 0, "n_jobs": 2})
    res = run_study(s, out_dir=tmp_path / "r", progress=False)
    t = res.table[res.table.source == "run"]
    assert len(t) == 12
    assert sorted(t["trial"]) == list(range(12))
    import optuna

    from parasynth.study.storage import open_storage

    st = optuna.load_study(study_name="analytic", storage=open_storage(f"journal:{tmp_path / 'r' / 'optuna.journal'}"))
    assert len([x for x in st.trials if x.state == optuna.trial.TrialState.COMPLETE]) == 12


@pytest.mark.parametrize("algorithm, maxeval, tol", [("GN_ISRES", 600, 0.01), ("GN_DIRECT_L", 300, 0.005)])
def test_nlopt_global_algorithms_find_known_optimum(tmp_path, algorithm, maxeval, tol):
    """Global algorithms through the same machinery; DIRECT_L has no nonlinear constraints in
    NLopt, so a constraint would be handled by the documented penalty (none here)."""
    s = study_of(optimizer={"kind": "nlopt", "algorithm": algorithm, "maxeval": maxeval, "seed": 1})
    res = run_study(s, out_dir=tmp_path / "r", progress=False)
    t = res.table[res.table.source == "run"]
    best = t.loc[t["test_quadratic"].idxmax()]
    assert abs(best["link_length"] - 0.2) < tol and abs(best["slider_radius"] - 0.14) < tol


def test_nlopt_penalty_keeps_unconstrained_algorithm_feasible(tmp_path):
    s = study_of(constraints=[{"name": "test_link_length", "max": "190 mm"}],
                 optimizer={"kind": "nlopt", "algorithm": "LN_BOBYQA", "maxeval": 150})
    res = run_study(s, out_dir=tmp_path / "r", progress=False)
    t = res.table[(res.table.source == "run") & res.table.feasible]
    best = t.loc[t["test_quadratic"].idxmax()]
    assert best["link_length"] <= 0.19 + 1e-9 and best["link_length"] > 0.185


# -- validation that catches what the run would reject -------------------------------------------
from parasynth.study.spec import check_study  # noqa: E402


def _problems(**changes):
    return check_study(study_of(**changes))


def test_check_study_accepts_the_base_study():
    assert _problems() == []


def test_check_study_names_the_bound_that_cannot_be_built():
    vs = [{"name": "link_length", "low": "0 mm", "high": "250 mm"}, BASE["variables"][1]]
    p = _problems(variables=vs)
    assert len(p) == 1 and p[0].startswith("variables[0].low:") and "link_length" in p[0]
    p = _problems(fixed={"link_diameter": "-8 mm"})
    assert p and p[0].startswith("fixed.link_diameter:")
    p = _problems(reference={"link_length": "-1 mm", "slider_radius": "135 mm"})
    assert p and p[0].startswith("reference.link_length:")


def test_check_study_finds_a_corner_that_no_single_bound_shows():
    # each bound alone is buildable with the default of the other (slider_min < slider_max),
    # but the corner slider_min = 250 mm, slider_max = 200 mm is not: 3 of the 4 corners build,
    # so the box is accepted with a warning naming that corner in the study's units
    vs = [{"name": "slider_min", "low": "100 mm", "high": "250 mm"},
          {"name": "slider_max", "low": "200 mm", "high": "300 mm"}]
    warnings = []
    p = check_study(study_of(variables=vs), warnings=warnings)
    assert p == [] and len(warnings) == 1, (p, warnings)
    assert warnings[0].startswith("variables: 3 of 4 corners") and "slider_min=250 mm, slider_max=200 mm" in warnings[0]


def test_check_study_probes_every_measure_with_its_settings():
    from parasynth.measures import objectives

    @objectives.register("test_refuses_flag", unit="1", sense="maximize", settings={"flag": "bool"}, cost="cheap")
    def _refuses(mech, flag=False):
        if flag:
            raise ValueError("flag is not supported by this model")
        return 1.0

    try:
        ok = _problems(objectives=[{"name": "test_refuses_flag", "settings": {"flag": False}}])
        assert ok == []
        p = _problems(objectives=[{"name": "test_quadratic"},
                                  {"name": "test_refuses_flag", "settings": {"flag": True}}],
                      optimizer={"kind": "optuna", "n_trials": 2})
        assert len(p) == 1 and p[0].startswith("objectives[1].settings.flag") and "not supported" in p[0]
    finally:
        objectives.OBJECTIVES.pop("test_refuses_flag", None)


@pytest.mark.parametrize("label", ["trial", "feasible", "status", "time_s", "link_length", "role",
                                   "dominates_reference_screen", "count"])
def test_labels_may_not_clash_with_result_columns(label):
    msg = error_of({**BASE, "objectives": [{"name": "test_quadratic", "label": label}]})
    assert "objectives[0].label" in msg and repr(label) in msg


def test_constraint_margin_column_clash():
    msg = error_of({**BASE, "objectives": [{"name": "test_quadratic", "label": "fp_margin"}],
                    "constraints": [{"name": "footprint_radius", "label": "fp", "max": "150 mm"}]})
    assert "constraints[0].label" in msg and "fp_margin" in msg


def test_nan_bound_would_make_every_design_feasible_and_is_refused():
    msg = error_of({**BASE, "constraints": [{"name": "footprint_radius", "max": "nan mm"}]})
    assert "constraints[0].max" in msg and "finite" in msg


def test_duplicate_keys_are_refused():
    text = yaml.safe_dump(BASE) + "name: other\n"
    with pytest.raises(StudyError) as e:
        load_study(text, is_text=True)
    assert "duplicate key 'name'" in str(e.value)


@pytest.mark.parametrize("ev,path", [({"seed": -1}, "evaluation.seed"), ({"samples": 0}, "evaluation.samples"),
                                     ({"samples": 10**20}, "evaluation.samples"), ({"ranges": {}}, "evaluation.ranges"),
                                     ({"ranges": {"w": ["0 mm", "1 mm"]}}, "evaluation.ranges.w"),
                                     ({"constraints": ["nope"]}, "evaluation.constraints[0]")])
def test_evaluation_values_are_checked(ev, path):
    assert path in error_of({**BASE, "evaluation": ev})


def test_optimisers_need_variables():
    for opt in ({"kind": "optuna", "n_trials": 5}, {"kind": "nlopt", "maxeval": 5}):
        msg = error_of({**BASE, "variables": [], "optimizer": opt})
        assert msg.startswith("variables:") and opt["kind"] in msg
