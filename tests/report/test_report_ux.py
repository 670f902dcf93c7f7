"""What a designer reads after a run: the reference design named as the study names it, the
budget actually run, one count of saved designs, warnings on bounds and on a workspace cut by
the sampled box, and a terminal summary that recommends what the report recommends."""

import json
import re
import types
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from parasynth.cli import load_plugins
from parasynth.report import write_report
from parasynth.report.checks import bound_warnings, face_warnings
from parasynth.report.summary import design_roles, terminal_summary
from parasynth.study import StudyError, load_study, run_study
from parasynth.study.evaluate import Record

PLUGIN = str(Path(__file__).resolve().parents[1] / "data" / "analytic_plugin.py")
load_plugins(PLUGIN)
STUDIES = Path(__file__).resolve().parents[2] / "studies"


def _study(**changes):
    spec = {
        "name": "ux", "mechanism": "5pus_upu",
        "variables": [{"name": "link_length", "low": "150 mm", "high": "250 mm"},
                      {"name": "slider_radius", "low": "100 mm", "high": "180 mm"}],
        "objectives": [{"name": "test_quadratic"}, {"name": "test_two"}],
        "reference": {"link_length": "205 mm", "slider_radius": "135 mm"},
        "evaluation": {"samples": 256},
        "optimizer": {"kind": "optuna", "algorithm": "nsga2", "n_trials": 6, "seed": 2},
    }
    spec.update(changes)
    return load_study(yaml.safe_dump(spec), is_text=True)


def _rec(trial, L, R, q, two, source="run"):
    return Record(values={"link_length": L, "slider_radius": R}, objectives={"test_quadratic": q, "test_two": two},
                  trial=trial, source=source, samples=256)


def _write_run(d: Path, study, records, final_rows=None) -> Path:
    d.mkdir(parents=True)
    (d / "study.yaml").write_text(study.to_yaml())
    (d / "journal.jsonl").write_text("".join(json.dumps(r.to_dict()) + "\n" for r in records))
    if final_rows is not None:
        pd.DataFrame(final_rows).to_csv(d / "final.csv", index=False)
    return d


def _final_row(source, trial, L, R, q, q_se, two, two_se, knee=False, verified=None):
    """A final.csv row; ``verified`` (True/False) adds the columns of verification, with the
    knee recommended when it passed."""
    row = {"source": source, "trial": trial, "link_length": L, "slider_radius": R, "test_quadratic": q,
           "test_quadratic_stderr": q_se, "test_two": two, "test_two_stderr": two_se, "feasible": True,
           "samples": 4096, "repeats": 4, "knee": knee, "count": 1}
    if verified is not None:
        row.update(verified=verified, verification="verified" if verified else "failed: drop = -1",
                   recommended=bool(knee and verified))
    return row


RECS = [_rec(-1, 0.205, 0.135, -0.0030, 0.4750, source="reference"),
        _rec(0, 0.200, 0.132, -0.00100, 0.5000),
        _rec(1, 0.201, 0.133, -0.00050, 0.5100),
        _rec(2, 0.190, 0.120, -0.01000, 0.4300)]


# -- the reference design's name ---------------------------------------------------------------
def test_reference_label_and_source_name_the_design_everywhere(tmp_path):
    study = _study(reference={"label": "the 2019 prototype", "source": "drawing P-12",
                              "link_length": "205 mm", "slider_radius": "135 mm"})
    assert study.reference == {"link_length": pytest.approx(0.205), "slider_radius": pytest.approx(0.135)}
    assert (study.reference_label, study.reference_source) == ("the 2019 prototype", "drawing P-12")
    run = _write_run(tmp_path / "run", study, RECS)
    md = (write_report(run, out=tmp_path / "rep") / "report.md").read_text()
    assert "## The 2019 prototype" in md
    assert "The 2019 prototype (drawing P-12): link_length = 205 mm" in md
    assert "paper" not in md.lower()
    lines = "\n".join(terminal_summary(study, load_run_table(run, study), None, run))
    assert "The 2019 prototype (drawing P-12):" in lines and "paper" not in lines.lower()


def load_run_table(run, study):
    from parasynth.report.render import load_run

    return load_run(run).table


def test_a_reference_without_label_is_the_reference_design(tmp_path):
    study = _study()
    assert study.reference_label is None
    run = _write_run(tmp_path / "run", study, RECS)
    md = (write_report(run, out=tmp_path / "rep") / "report.md").read_text()
    assert "## The reference design" in md and "paper" not in md.lower()
    lines = "\n".join(terminal_summary(study, load_run_table(run, study), None, run))
    assert "The reference design:" in lines and "paper" not in lines.lower()


def test_shipped_paper_studies_say_they_reference_the_paper():
    for f in sorted(STUDIES.glob("*.yaml")):
        s = load_study(f)
        if s.reference is not None:
            assert "paper" in (s.reference_label or ""), f.name
            assert s.reference_source, f.name


@pytest.mark.parametrize("bad", [5, "", ["a"], "two\nlines"])
def test_reference_label_must_be_one_line_of_text(bad):
    with pytest.raises(StudyError, match=r"reference\.label"):
        _study(reference={"label": bad, "link_length": "205 mm"})


# -- budget and counts ---------------------------------------------------------------------------
NLOPT = {"kind": "nlopt", "algorithm": "LN_COBYLA", "maxeval": 80, "xtol_rel": 1e-9}


def test_n_trials_is_the_budget_recorded_and_resumed(tmp_path):
    study = _study(objectives=[{"name": "test_quadratic"}], optimizer=NLOPT, reference=None)
    out = tmp_path / "r"
    run_study(study, out_dir=out, progress=False, n_trials=7)
    assert yaml.safe_load((out / "study.yaml").read_text())["optimizer"]["maxeval"] == 7
    md = (write_report(out, out=tmp_path / "rep") / "report.md").read_text()
    assert "budget 7;" in md and "budget 80" not in md
    # --resume without --n-trials continues to the recorded budget (7), not the file's 80.
    res = run_study(study, out_dir=out, resume=True, progress=False)
    assert res.n_new == 0 and len(res.table) == 7
    # --resume --n-trials 12 extends it, and records it.
    res = run_study(study, out_dir=out, resume=True, progress=False, n_trials=12)
    assert len(res.table) == 12
    assert yaml.safe_load((out / "study.yaml").read_text())["optimizer"]["maxeval"] == 12


def test_optuna_budget_in_report_and_storage(tmp_path):
    study = _study()
    out = tmp_path / "r"
    run_study(study, out_dir=out, progress=False, n_trials=3)
    md = (write_report(out, out=tmp_path / "rep") / "report.md").read_text()
    assert "budget 3;" in md and "PARTIAL" not in md
    assert yaml.safe_load((out / "study.yaml").read_text())["optimizer"]["n_trials"] == 3
    res = run_study(study, out_dir=out, resume=True, progress=False)  # the storage holds the same study
    assert res.n_new == 0


def test_n_trials_refused_for_a_sweep(tmp_path):
    study = _study(objectives=[{"name": "test_quadratic"}],
                   variables=[{"name": "link_length", "values": ["190 mm", "200 mm"]}],
                   optimizer={"kind": "sweep"})
    with pytest.raises(StudyError, match="sweep"):
        run_study(study, out_dir=tmp_path / "r", progress=False, n_trials=5)


def test_resume_of_a_missing_directory_is_refused(tmp_path):
    study = _study(objectives=[{"name": "test_quadratic"}], optimizer=NLOPT, reference=None)
    with pytest.raises(StudyError, match="does not exist"):
        run_study(study, out_dir=tmp_path / "nowhere", resume=True, progress=False)
    assert not (tmp_path / "nowhere").exists()


def test_one_count_of_saved_designs(tmp_path, capsys):
    from parasynth.study.runner import RunResult, results_table
    from parasynth.cli.study_cmd import interrupted_run

    study = _study()
    table = results_table(study, RECS)
    res = RunResult(tmp_path, table, None, 4, 4, 1.0, interrupted=True, new_records=RECS)
    assert res.saved_counts() == (3, True)
    first = res.summary(study).splitlines()[0]
    assert "3 designs evaluated and the reference design" in first
    args = types.SimpleNamespace(study="s.yaml", out=None, no_report=True, storage=None, workers=None, n_trials=None)
    assert interrupted_run(args, res) == 130
    assert "interrupted: 3 designs and the reference design are saved" in capsys.readouterr().err


# -- warnings ------------------------------------------------------------------------------------
def _front(rows):
    return pd.DataFrame([{"trial": t, "link_length": L, "slider_radius": R, "test_quadratic": q, "test_two": w}
                         for t, L, R, q, w in rows])


def test_bound_warning_within_one_percent_of_the_range():
    study = _study()
    # link_length range 100 mm: 0.5 mm from the low bound is on it, 2 mm is not.
    on = _front([(4, 0.1505, 0.140, -0.1, 0.5)])
    near = _front([(4, 0.152, 0.140, -0.1, 0.5)])
    w = bound_warnings(study, on.iloc[0], on)
    assert len(w) == 1 and "trial 4" in w[0] and "link_length = 150.5 mm at its lower bound 150 mm" in w[0]
    assert "variables[0].low" in w[0]
    assert bound_warnings(study, near.iloc[0], near) == []
    # the best design of an objective at the upper bound of slider_radius (80 mm range: 0.6 mm)
    fr = _front([(4, 0.2, 0.14, -0.1, 0.5), (5, 0.2, 0.1794, -0.2, 0.4), (6, 0.2, 0.12, -0.05, 0.6)])
    w = bound_warnings(study, fr.iloc[0], fr)
    assert len(w) == 1 and "the best test_two design (trial 5)" in w[0] and "upper bound 180 mm" in w[0]


def test_report_and_summary_warn_of_a_best_design_on_a_bound(tmp_path):
    study = _study(objectives=[{"name": "test_two"}], reference=None, optimizer=NLOPT)
    recs = [_rec(0, 0.15, 0.10, 0, 0.35), _rec(1, 0.2, 0.14, 0, 0.48)]
    for r in recs:
        r.objectives = {"test_two": r.objectives["test_two"]}
    run = _write_run(tmp_path / "run", study, recs)
    md = (write_report(run, out=tmp_path / "rep") / "report.md").read_text()
    sec = md.split("## Warnings")[1].split("## ")[0]
    assert "link_length = 150 mm at its lower bound" in sec and "slider_radius = 100 mm at its lower bound" in sec
    lines = terminal_summary(study, load_run_table(run, study), None, run)
    assert any(x.startswith("warning: the recommended design (trial 0) lies on a bound") for x in lines)


def test_face_fraction_of_a_box_inside_the_workspace():
    """A box well inside the workspace is feasible everywhere: the share of samples within 1 %
    of a face is 1 - 0.98^d for d sampled coordinates."""
    from parasynth import load_mechanism, workspace

    mech = load_mechanism("5pus_upu")
    h = mech.home
    t = mech.task_coordinates
    ranges = {c: (h[t.index(c)] - 0.005, h[t.index(c)] + 0.005) for c in ("x", "y", "z")}
    ws = workspace(mech, ranges, n=8192, seed=1)
    assert ws.fraction == 1.0
    assert ws.face_fraction() == pytest.approx(1 - 0.98 ** 3, abs=0.004)
    ff = ws.face_fractions()
    assert set(ff) == {"x low", "x high", "y low", "y high", "z low", "z high"}
    assert all(x == pytest.approx(0.01, abs=0.003) for x in ff.values())
    from parasynth.measures.objectives import get

    assert get("workspace_face_fraction")(mech, ranges=ranges, n=8192, seed=1) == ws.face_fraction()
    # the quickstart box holds the paper's design's workspace: nothing on its faces
    qs = load_study(STUDIES / "quickstart.yaml")
    big = workspace(mech, qs.evaluation["ranges"], n=8192, seed=0)
    assert big.n_feasible > 100 and big.face_fraction() == 0.0


def test_face_warning_names_the_share_and_the_advice():
    study = _study(objectives=[{"name": "workspace_volume"}],
                   evaluation={"samples": 512, "ranges": {"x": ["-20 mm", "20 mm"], "y": ["-20 mm", "20 mm"],
                                                          "z": ["-10 mm", "10 mm"]}})
    w = face_warnings(study, None)
    assert len(w) == 1 and w[0].startswith("the workspace of the reference design reaches the faces")
    assert "widen evaluation.ranges" in w[0] and "% of its feasible samples" in w[0]
    wide = _study(objectives=[{"name": "workspace_volume"}], evaluation={
        "samples": 512, "ranges": {"x": ["-200 mm", "200 mm"], "y": ["-200 mm", "200 mm"], "z": ["-450 mm", "300 mm"]}})
    assert face_warnings(wide, None) == []


# -- the terminal summary recommends what the report recommends ---------------------------------
def test_summary_names_the_knee_and_leaves_out_designs_dominated_beyond_noise(tmp_path):
    study = _study()
    # Trial 1 looks best on test_quadratic on its single sample; re-evaluated it is worse than
    # trial 0 beyond noise on test_quadratic and equal on test_two: dominated by trial 0.
    fin = [_final_row("best", 0, 0.200, 0.132, -0.00100, 0.00001, 0.5000, 0.0001, knee=True, verified=True),
           _final_row("best", 1, 0.201, 0.133, -0.00130, 0.00001, 0.5000, 0.0001, verified=True),
           _final_row("best", 2, 0.190, 0.120, -0.01000, 0.00001, 0.4300, 0.0001, verified=True),
           _final_row("reference", -1, 0.205, 0.135, -0.0030, 0.00001, 0.4750, 0.0001, verified=True)]
    run = _write_run(tmp_path / "run", study, RECS, fin)
    from parasynth.report.render import analyse, load_run

    r = load_run(run)
    a = analyse(r)
    knee = int(a.knee_row["trial"])
    lines = terminal_summary(study, r.table, None, run)
    text = "\n".join(lines)
    assert knee == 0
    assert lines[0].startswith(f"recommended (knee of the non-dominated front), verified: trial {knee}:")
    assert "left out, dominated beyond noise once re-evaluated: trial 1 (by trial 0)" in text
    table = text.split("non-dominated feasible designs")[1].split("left out")[0]
    assert "200" in table and "190" in table  # trials 0 and 2 (link_length 200 and 190 mm)
    assert "201" not in table  # trial 1 (link_length 201 mm) is not recommended
    assert any(ln.startswith("recommended") for ln in table.splitlines())
    # the report says the same of trial 1
    md = (write_report(run, out=tmp_path / "rep") / "report.md").read_text()
    assert "trial 1 (by trial 0)" in md


def test_design_roles_name_the_objective():
    study = _study()
    fr = _front([(4, 0.2, 0.14, -0.1, 0.5), (5, 0.2, 0.12, -0.2, 0.4), (6, 0.2, 0.13, -0.05, 0.6)])
    from parasynth.study.final import design_key

    roles = design_roles(study, fr, design_key(study, fr.iloc[0]))
    assert roles == ["recommended", "best test_two", "best test_quadratic"]
    one = _study(objectives=[{"name": "test_two"}])
    assert design_roles(one, fr) == ["rank 1", "best test_two", "rank 3"]


# -- figures and the hypervolume ------------------------------------------------------------------
def _figures(study, recs, tmp_path):
    from parasynth.report.render import analyse, load_run, make_figures

    run = load_run(_write_run(tmp_path / "run", study, recs))
    a = analyse(run)
    return make_figures(run, a, keep=True), a


def test_three_objective_pareto_panels_are_not_joined_by_lines(tmp_path):
    study = _study(objectives=[{"name": "test_quadratic"}, {"name": "test_two"}, {"name": "test_link_length"}])
    rng = np.random.default_rng(3)
    recs = []
    for t in range(25):
        L, R = 0.15 + 0.1 * rng.random(), 0.10 + 0.08 * rng.random()
        r = _rec(t, L, R, -((L - 0.2) ** 2) - (R - 0.14) ** 2, L + 2 * R)
        r.objectives["test_link_length"] = L
        recs.append(r)
    figs, a = _figures(study, recs, tmp_path)
    assert len(a.front) >= 3
    fig = figs.figures["pareto"]
    panels = [ax for ax in fig.axes if ax.collections]
    assert len(panels) == 3
    for ax in panels:
        assert all(len(line.get_xdata()) <= 1 for line in ax.get_lines()), "front points joined by a line"
    import matplotlib.pyplot as plt

    plt.close("all")


def test_two_objective_front_is_a_staircase(tmp_path):
    study = _study()
    recs = [_rec(t, 0.15 + 0.01 * t, 0.10 + 0.005 * t, -1 + 0.1 * t, 0.3 + 0.05 * t) for t in range(6)]
    figs, a = _figures(study, recs, tmp_path)
    ax = [ax for ax in figs.figures["pareto"].axes if ax.collections][0]
    lines = [line for line in ax.get_lines() if len(line.get_xdata()) > 1]
    assert len(lines) == 1
    from matplotlib.cbook import STEP_LOOKUP_MAP

    line = lines[0]
    assert line.get_drawstyle().startswith("steps")
    x, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
    vx, vy = STEP_LOOKUP_MAP[line.get_drawstyle()](x, y)
    # a staircase (segments horizontal or vertical) along the boundary of the region the front
    # dominates: every corner is weakly dominated by a front point (test_quadratic maximised on
    # x, test_two minimised on y)
    assert np.all((np.abs(np.diff(vx)) < 1e-12) | (np.abs(np.diff(vy)) < 1e-12))
    for cx, cy in zip(vx, vy):
        assert np.any((x >= cx - 1e-9) & (y <= cy + 1e-9)), (cx, cy)


def test_hypervolume_only_for_a_front_of_several_designs_and_in_display_units(tmp_path):
    study = _study()
    one = [_rec(0, 0.2, 0.14, 0.0, 0.3), _rec(1, 0.21, 0.15, -0.1, 0.4)]  # trial 0 dominates trial 1
    md = (write_report(_write_run(tmp_path / "one", study, one), out=tmp_path / "r1") / "report.md").read_text()
    assert "## Hypervolume" not in md
    many = [_rec(t, 0.15 + 0.01 * t, 0.10 + 0.005 * t, -1e-4 + 1e-5 * t, 0.3 + 0.05 * t) for t in range(6)]
    md = (write_report(_write_run(tmp_path / "many", study, many), out=tmp_path / "r2") / "report.md").read_text()
    sec = md.split("## Hypervolume")[1].split("## ")[0]
    assert "SI" not in sec and not re.search(r"\de-\d", sec), sec
    assert "normalised" in sec and "cm^2 x mm in display units" in sec


def test_reevaluation_rows_say_for_which_objective_they_are_best(tmp_path):
    study = _study()
    fin = [_final_row("best", 0, 0.200, 0.132, -0.00100, 0.00001, 0.5000, 0.0001),
           _final_row("best", 2, 0.190, 0.120, -0.01000, 0.00001, 0.4300, 0.0001),
           _final_row("best", 3, 0.195, 0.125, -0.00500, 0.00001, 0.4600, 0.0001),
           _final_row("reference", -1, 0.205, 0.135, -0.0030, 0.00001, 0.4750, 0.0001)]
    recs = RECS[:2] + RECS[3:] + [_rec(3, 0.195, 0.125, -0.005, 0.46)]
    md = (write_report(_write_run(tmp_path / "run", study, recs, fin), out=tmp_path / "rep") / "report.md").read_text()
    sec = md.split("## Re-evaluation of the best designs")[1].split("## ")[0]
    rows = {ln.split("|")[2].strip(): ln.split("|")[1].strip() for ln in sec.splitlines() if ln.startswith("| ")
            and ln.split("|")[2].strip().lstrip("-").isdigit()}
    assert rows["2"] == "best test_two"
    assert "best test_quadratic" in rows["0"] or rows["0"].startswith("recommended")
    assert rows["-1"] == "reference design"
    assert all(r != "best" for r in rows.values())


# -- units in the CSV column names ---------------------------------------------------------------
def test_csv_files_name_their_units_and_hold_si_values(tmp_path):
    from parasynth.study.columns import read_run_csv

    study = _study(objectives=[{"name": "test_quadratic"}, {"name": "test_two"}],
                   constraints=[{"name": "test_link_length", "label": "link", "max": "240 mm"}],
                   evaluation={"samples": 64, "final_samples": 64, "final_repeats": 2, "final_top": 2},
                   optimizer={"kind": "optuna", "algorithm": "nsga2", "n_trials": 6, "population_size": 4, "seed": 1})
    res = run_study(study, out_dir=tmp_path / "r", progress=False)
    raw = pd.read_csv(tmp_path / "r" / "results.csv")
    assert {"link_length_m", "slider_radius_m", "test_quadratic_m2", "test_two_m", "link_m", "link_margin_m",
            "trial", "time_s", "feasible"} <= set(raw.columns)
    assert "link_length" not in raw.columns and "test_two" not in raw.columns
    t = res.table.sort_values(["source", "trial"]).reset_index(drop=True)
    r = raw.sort_values(["source", "trial"]).reset_index(drop=True)
    # SI values: link_length in m (0.15 to 0.25), test_two = L + 2 R in m
    assert r["link_length_m"].between(0.15, 0.25).all()
    np.testing.assert_allclose(r["test_two_m"], r["link_length_m"] + 2 * r["slider_radius_m"])
    back = read_run_csv(study, tmp_path / "r" / "results.csv").sort_values(["source", "trial"]).reset_index(drop=True)
    assert list(back.columns) == list(res.table.columns)
    np.testing.assert_allclose(back["test_quadratic"], t["test_quadratic"])
    fin = pd.read_csv(tmp_path / "r" / "final.csv")
    assert {"test_quadratic_m2", "test_quadratic_stderr_m2", "test_two_m", "test_two_stderr_m", "count"} <= set(fin.columns)
    rep = write_report(tmp_path / "r", out=tmp_path / "rep")
    par = pd.read_csv(rep / "pareto.csv")
    assert "link_length_m" in par.columns and "test_two_m" in par.columns
    md = (rep / "report.md").read_text()
    assert "## Re-evaluation of the best designs" in md  # final.csv with unit names is read back


def test_progress_best_value_names_its_unit():
    from parasynth.study.problem import Problem

    study = _study(objectives=[{"name": "test_two"}])
    recs = [_rec(0, 0.2, 0.14, 0, 0.48), _rec(1, 0.2, 0.12, 0, 0.44)]
    for r in recs:
        r.objectives = {"test_two": r.objectives["test_two"]}
    assert Problem(study).best_str(recs) == "best test_two = 440 mm"


def test_objective_plot_spans_the_feasible_designs_and_the_front_not_far_infeasible_ones():
    """The interactive objective plot's initial ranges: every feasible design, front point and
    marked design inside, padded 8 %; an infeasible design a million times off does not set the
    scale (it stays reachable through the plot's autoscale); nothing finite -> None."""
    from parasynth.report.interactive import _ranges

    feasible = [[1.0, 2.0, 3.0], [10.0, 20.0, float("nan")]]
    front = [[1.5], [40.0]]
    marks = [[[0.5], [15.0]]]
    r = _ranges(2, feasible, [front] + marks)
    assert r[0] == pytest.approx([0.5 - 0.08 * 2.5, 3.0 + 0.08 * 2.5])
    assert r[1] == pytest.approx([10.0 - 0.08 * 30, 40.0 + 0.08 * 30])
    assert _ranges(1, [[]], [[[float("inf")]]]) == [None]


def test_objective_plot_leaves_far_feasible_outliers_out_of_its_initial_range():
    """Feasible designs far beyond Tukey's far fences (3 interquartile ranges outside the
    quartiles; here quartiles 3.5 and 8.5 kN, fences -11.5 and 23.5 kN) do not set the
    scale, a front point beyond them does."""
    from parasynth.report.interactive import _ranges

    forces = [1e3 * k for k in range(1, 11)] + [3.8e8]  # 1..10 kN and one design near a singularity
    q1, q3 = 3.5e3, 8.5e3  # numpy's linear percentiles of the eleven values
    assert _ranges(1, [forces], [[[2.9e3]]])[0] == pytest.approx([1e3 - 0.08 * 9e3, 1e4 + 0.08 * 9e3])
    assert q3 + 3 * (q3 - q1) < 3.8e8
    r = _ranges(1, [forces], [[[5e4]]])  # a front point outside the fences stays in view
    assert r[0] == pytest.approx([1e3 - 0.08 * 4.9e4, 5e4 + 0.08 * 4.9e4])


def test_design_values_leave_out_the_dimensions_a_structure_does_not_use():
    """In a study over structures a row holds no value (NaN) for a dimension its structure does
    not use: the report's design text leaves it out instead of printing 'link_length = ,'."""
    import pandas as pd

    from parasynth.report.sections import _design_values
    from parasynth.study import load_study

    study = load_study(str(STUDIES / "structures_3t2r.yaml"))
    values = {v.name: float("nan") for v in study.variables}
    values.update(structure="5-UPS/UPU (irregular)", base_radius=0.08682)
    row = pd.Series(values, dtype=object)
    text = _design_values(study, row)
    assert text == "structure = 5-UPS/UPU (irregular), base_radius = 86.82 mm", text
