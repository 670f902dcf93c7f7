"""Units and names a user can use: numbers in exponent form, a constraint whose unit follows a
setting, result column names with one unit, validate's messages in the study's units, the
design box whose corners partly build, lengths far from the mechanism's scale, and runs that
write their report into their own directory."""

from __future__ import annotations

import contextlib
import io
import json
import os
from pathlib import Path

import numpy as np
import pytest
import yaml

from parasynth.cli import main
from parasynth.common.yamlio import load_yaml
from parasynth.mechanisms import load_mechanism
from parasynth.study import StudyError, load_study
from parasynth.study.columns import csv_column
from parasynth.study.magnitudes import SCALE_FACTOR, scale_warnings
from parasynth.study.spec import check_study

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "studies" / "quickstart.yaml"

BASE = {
    "name": "units",
    "mechanism": "5pus_upu",
    "variables": [{"name": "link_length", "low": "150 mm", "high": "250 mm"},
                  {"name": "slider_radius", "low": "100 mm", "high": "180 mm"}],
    "objectives": [{"name": "footprint_radius"}],
    "optimizer": {"kind": "optuna", "n_trials": 4},
}


def study_of(**changes):
    d = json.loads(json.dumps(BASE))
    d.update(changes)
    return load_study(yaml.safe_dump(d), is_text=True)


def run_cli(args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as e:
            code = e.code
    return code, out.getvalue(), err.getvalue()


# -- numbers in exponent form ---------------------------------------------------------------------
@pytest.mark.parametrize("text,value", [("2e6", 2e6), ("2.0e6", 2e6), ("2E6", 2e6), ("1e-3", 1e-3), ("-3e-2", -0.03),
                                        ("+4e1", 40.0), (".5e3", 500.0), ("1_000e2", 1e5), ("2.0e+6", 2e6)])
def test_exponent_numbers_are_numbers(text, value):
    got = load_yaml(f"x: {text}\n", is_text=True)["x"]
    assert isinstance(got, float) and got == value


@pytest.mark.parametrize("text", ["1e", "e5", "1.2.3e4", "2e6 N/m", "'2e6'", "1e6e6"])
def test_what_is_not_a_number_stays_a_string(text):
    assert isinstance(load_yaml(f"x: {text}\n", is_text=True)["x"], str)


def test_exponent_numbers_reach_a_study_as_numbers():
    text = yaml.safe_dump({**BASE, "constraints": [{"name": "min_lti", "min": "@B@"}]}).replace("'@B@'", "2e-1")
    assert "min: 2e-1" in text  # as a person writes it, not quoted
    s = load_study(text, is_text=True)
    assert s.constraints[0].min == 0.2
    text = yaml.safe_dump({**BASE, "optimizer": {"kind": "nlopt", "maxeval": 5, "xtol_rel": "@B@"},
                           "objectives": [{"name": "footprint_radius"}]}).replace("'@B@'", "1e-6")
    assert load_study(text, is_text=True).optimizer.xtol_rel == 1e-6


# -- a constraint whose unit follows a setting -------------------------------------------------------
def _stiffness(bound, part=None, label="k_min"):
    c = {"name": "stiffness_min", "label": label, "min": bound}
    if part:
        c["settings"] = {"part": part}
    return load_study(yaml.safe_dump({**BASE, "constraints": [c]}), is_text=True)


@pytest.mark.parametrize("part,bound,si", [(None, "2e6 N/m", 2e6), ("translational", "2e6 N/m", 2e6),
                                           ("translational", "2 kN/mm", 2e6), ("translational", "2.0e6 N/m", 2e6),
                                           ("rotational", "3e4 N*m/rad", 3e4), ("rotational", "30 kN*m/rad", 3e4)])
def test_stiffness_min_takes_the_unit_of_its_part(part, bound, si):
    s = _stiffness(bound, part)
    assert s.constraints[0].min == pytest.approx(si, rel=1e-12)


def test_stiffness_min_unquoted_in_yaml():
    c = [{"name": "stiffness_min", "label": "k_min", "min": "@B@"}]
    text = yaml.safe_dump({**BASE, "constraints": c}).replace("'@B@'", "2e6 N/m")
    assert "min: 2e6 N/m" in text
    assert load_study(text, is_text=True).constraints[0].min == 2e6


@pytest.mark.parametrize("part,bound,given,wanted", [("rotational", "2e6 N/m", "N/m", "N*m/rad"),
                                                     ("translational", "3e4 N*m/rad", "N*m/rad", "N/m")])
def test_stiffness_min_refuses_the_other_parts_unit_naming_both(part, bound, given, wanted):
    with pytest.raises(StudyError) as e:
        _stiffness(bound, part)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("constraints[0].min:")
    assert f"settings.part: {part}" in msg and given in msg and wanted in msg


@pytest.mark.parametrize("bound,needle", [(2e6, "bare number"), ("2e6 kg", "not a stiffness")])
def test_stiffness_min_refuses_a_bound_without_the_unit(bound, needle):
    with pytest.raises(StudyError) as e:
        _stiffness(bound, "translational")
    assert str(e.value).startswith("constraints[0].min:") and needle in str(e.value) and "part" in str(e.value)


# -- column names: identifiers with one unit ----------------------------------------------------------
@pytest.mark.parametrize("part,column", [("translational", "k_min_N_per_m"), ("rotational", "k_min_N_m_per_rad")])
def test_result_columns_are_identifiers_with_one_unit(part, column):
    s = _stiffness("1 N/m" if part == "translational" else "1 N*m/rad", part)
    assert csv_column(s, "k_min") == column
    assert csv_column(s, "k_min_margin") == column.replace("k_min", "k_min_margin")
    for name in ("link_length", "slider_radius", "footprint_radius", "k_min", "k_min_margin"):
        assert csv_column(s, name).isidentifier(), csv_column(s, name)


def test_every_registered_measure_gives_an_identifier_column():
    from parasynth.measures.objectives import OBJECTIVES

    names = [n for n, m in OBJECTIVES.items() if m.models is None or "5pus_upu" in m.models]
    # a task (one pose at home) lets the task measures in too
    s = study_of(objectives=[{"name": n, "goal": "maximize"} for n in names], task={"poses": {"list": [{"x": "0 mm"}]}})
    bad = [csv_column(s, n) for n in names if not csv_column(s, n).isidentifier()]
    assert not bad, bad


# -- validate: the design box, in the study's units ------------------------------------------------------
def _checked(**changes):
    warnings, stats = [], {}
    problems = check_study(study_of(**changes), measures=False, warnings=warnings, stats=stats)
    return problems, warnings, stats


def test_a_box_whose_corners_partly_build_is_accepted_with_the_share():
    # slider_min < slider_max is required: of the 4 corners only (250 mm, 200 mm) fails
    vs = [{"name": "slider_min", "low": "100 mm", "high": "250 mm"},
          {"name": "slider_max", "low": "200 mm", "high": "300 mm"}]
    problems, warnings, stats = _checked(variables=vs)
    assert problems == []
    assert stats["corners"] == 4 and stats["corners_built"] == 3
    (w,) = [w for w in warnings if "corners" in w]
    assert w.startswith("variables: 3 of 4 corners") and "(75 %)" in w
    assert "{slider_min=250 mm, slider_max=200 mm}" in w and "\n" not in w


def test_a_box_of_which_nothing_builds_is_refused():
    # every corner and the centre have slider_min >= slider_max; each bound alone (with the
    # model's default 85 mm / 290 mm for the other) builds
    vs = [{"name": "slider_min", "low": "240 mm", "high": "260 mm"},
          {"name": "slider_max", "low": "200 mm", "high": "230 mm"}]
    problems, warnings, stats = _checked(variables=vs)
    assert stats["corners_built"] == 0
    (p,) = [p for p in problems if p.startswith("variables: no corner")]
    assert "{slider_min=240 mm, slider_max=200 mm}" in p and "narrow the bounds" in p


def test_corner_messages_are_in_the_units_the_study_writes():
    vs = [{"name": "slider_min", "low": "0.1 m", "high": "0.25 m"},
          {"name": "slider_max", "low": "20 cm", "high": "30 cm"}]
    _, warnings, _ = _checked(variables=vs)
    (w,) = [w for w in warnings if "corners" in w]
    assert "{slider_min=0.25 m, slider_max=20 cm}" in w


def test_validate_prints_the_box_warning_and_accepts(tmp_path):
    d = yaml.safe_load(QUICK.read_text())
    d["variables"] = [{"name": "slider_min", "low": "100 mm", "high": "250 mm"},
                      {"name": "slider_max", "low": "200 mm", "high": "300 mm"}]
    d.pop("reference", None)
    p = tmp_path / "box.yaml"
    p.write_text(yaml.safe_dump(d))
    code, out, err = run_cli(["validate", p, "--quick"])
    assert code == 0, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("warning:") and "3 of 4 corners" in lines[0]
    assert "3 of them buildable" in out


# -- lengths far from the mechanism's scale --------------------------------------------------------------
def _joint_radius(mech) -> float:
    """The farthest joint from the base origin at the home pose, computed here leg by leg."""
    p, R = mech.pose(np.asarray(mech.home, float))
    d = [np.linalg.norm(leg.base) for leg in mech.legs]
    d += [np.linalg.norm(np.asarray(p) + np.asarray(R) @ np.asarray(leg.platform)) for leg in mech.legs]
    return max(max(d), mech.length_scale)


def test_a_length_in_metres_for_millimetres_is_warned_about():
    L = _joint_radius(load_mechanism("5pus_upu"))
    s = study_of(variables=[{"name": "link_length", "low": "160 m", "high": "240 m"}])
    w = scale_warnings(s)
    assert [x.split(":")[0] for x in w] == ["variables[0].low", "variables[0].high"]
    assert f"{160 / L:.0f} times" in w[0] and "160 m" in w[0]
    problems, warnings, _ = _checked(variables=[{"name": "link_length", "low": "160 m", "high": "240 m"}])
    assert sum("times the mechanism's characteristic length" in x for x in warnings) == 2


def test_the_rule_is_the_factor_times_the_characteristic_length():
    L = _joint_radius(load_mechanism("5pus_upu"))
    above, below = SCALE_FACTOR * L * 1.01, SCALE_FACTOR * L * 0.99
    vs = lambda x: [{"name": "link_length", "values": [f"{x * 1e3:.6f} mm"]}]  # noqa: E731
    sweep = {"kind": "sweep"}
    assert scale_warnings(study_of(variables=vs(above), optimizer=sweep))
    assert not scale_warnings(study_of(variables=vs(below), optimizer=sweep))
    assert scale_warnings(study_of(variables=vs(below), optimizer=sweep), factor=SCALE_FACTOR / 2)


def test_workspace_ranges_of_hundreds_of_metres_are_warned_about():
    ev = {"ranges": {"x": ["-200 m", "200 m"], "y": ["-150 mm", "150 mm"], "z": ["-300 mm", "200 mm"],
                     "alpha": ["-200 deg", "200 deg"]}}
    w = scale_warnings(study_of(evaluation=ev))
    assert [x.split(":")[0] for x in w] == ["evaluation.ranges.x[0]", "evaluation.ranges.x[1]"]


def test_the_shipped_studies_have_no_scale_warnings():
    for f in sorted((ROOT / "studies").glob("*.yaml")):
        assert scale_warnings(load_study(f)) == [], f.name


# -- runs that leave the clone as it was ----------------------------------------------------------------
def _tiny(tmp_path) -> Path:
    d = yaml.safe_load(QUICK.read_text())
    d["evaluation"].update(samples=64)
    d["evaluation"].pop("final_samples", None)
    d["optimizer"].update(n_trials=2, population_size=2)
    p = tmp_path / "tiny.yaml"
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    return p


def test_run_writes_its_report_into_the_run_directory(tmp_path, monkeypatch):
    study = _tiny(tmp_path)
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(["run", study, "--quiet"])
    assert code == 0, err
    run = tmp_path / "runs" / "quickstart"
    assert (run / "results.csv").exists() and (run / "report" / "index.html").exists()
    assert not (tmp_path / "reports").exists()
    # --out moves the report with the run; report RUN writes where run did
    code, out, err = run_cli(["run", study, "--quiet", "--out", tmp_path / "elsewhere"])
    assert code == 0, err
    assert (tmp_path / "elsewhere" / "report" / "index.html").exists()
    os.remove(tmp_path / "elsewhere" / "report" / "index.html")
    code, out, err = run_cli(["report", tmp_path / "elsewhere"])
    assert code == 0, err
    assert (tmp_path / "elsewhere" / "report" / "index.html").exists()
    assert not (tmp_path / "reports").exists()
    # --report-dir says otherwise
    code, out, err = run_cli(["report", tmp_path / "elsewhere", "--out", tmp_path / "rep"])
    assert code == 0 and (tmp_path / "rep" / "index.html").exists()
    assert (tmp_path / "rep" / "pareto.csv").exists() and not (tmp_path / "reports").exists()


@pytest.mark.parametrize("low,high,shown", [("150 mm", "250 mm", "[150 mm, 250 mm]"), ("0.15 m", "0.25 m", "[0.15 m, 0.25 m]")])
def test_a_start_outside_the_bounds_is_named_in_the_study_units(low, high, shown):
    d = {**BASE, "variables": [{"name": "link_length", "low": low, "high": high}],
         "optimizer": {"kind": "nlopt", "maxeval": 5, "start": {"link_length": "300 mm"}}}
    with pytest.raises(StudyError) as e:
        load_study(yaml.safe_dump(d), is_text=True)
    assert str(e.value).startswith("optimizer.start.link_length:") and shown in str(e.value)


@pytest.mark.parametrize("text,n", [("1.6e4", 16000), ("4096", 4096), ("2e3", 2000)])
def test_a_count_in_exponent_form_is_the_integer_it_writes(text, n):
    t = yaml.safe_dump({**BASE, "evaluation": {"samples": "@N@"}}).replace("'@N@'", text)
    s = load_study(t, is_text=True)
    assert s.evaluation["n"] == n and isinstance(s.evaluation["n"], int)


@pytest.mark.parametrize("text", ["4096.5", "true", "'4096'", "1e30"])
def test_what_is_not_a_count_is_still_refused(text):
    t = yaml.safe_dump({**BASE, "evaluation": {"samples": "@N@"}}).replace("'@N@'", text)
    with pytest.raises(StudyError) as e:
        load_study(t, is_text=True)
    assert str(e.value).startswith("evaluation.samples:")


def test_a_crank_whose_home_height_must_match_its_link_is_accepted_with_the_share():
    # 6-RUS: the home pose is reachable only where the height and the link length roughly match
    # (a band of the plane): of the corners of this box three build, the low platform on the long
    # link does not; each bound alone, with the other's default (height 400 mm, link 350 mm), builds
    rus = str(ROOT / "tests" / "data" / "export_6rus.yaml")
    for h, link, ok in [(0.25, 0.35, True), (0.4, 0.55, True), (0.4, 0.35, True), (0.25, 0.55, False)]:
        try:
            load_mechanism(rus, height=h, link_length=link)
            built = True
        except ValueError:
            built = False
        assert built == ok, (h, link)
    d = {**BASE, "mechanism": rus, "variables": [{"name": "height", "low": "250 mm", "high": "400 mm"},
                                                 {"name": "link_length", "low": "350 mm", "high": "550 mm"}]}
    warnings = []
    problems = check_study(load_study(yaml.safe_dump(d), is_text=True), measures=False, warnings=warnings)
    assert problems == []
    (w,) = [w for w in warnings if "corners" in w]
    assert w.startswith("variables: 3 of 4 corners") and "(75 %)" in w
    assert "{height=250 mm, link_length=550 mm}" in w and "not reachable" in w
