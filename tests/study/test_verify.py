"""Verification of a recommended design (parasynth.study.verify, docs/verification.md).

Independent values: the tolerance rules are checked on re-evaluation values written in the
test (their mean and standard error computed here by hand); the singularity floor against the
margin recomputed with the NumPy reference of the built design; the walk down the ranking on a
constraint made to fail on the re-evaluation seeds for a known set of designs; the verdicts on a
final.csv written in the test.
"""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from parasynth.cli import load_plugins
from parasynth.measures import objectives
from parasynth.measures.objectives import OBJECTIVES, SAMPLE_SETTINGS, register
from parasynth.report.analysis import analyse
from parasynth.report.checks import design_roles
from parasynth.report.summary import terminal_summary
from parasynth.study import load_study
from parasynth.study.design import design_mechanism
from parasynth.study.evaluate import Evaluator, Record
from parasynth.study.final import knee_of, pareto_front, recommendation_order, reevaluate_best
from parasynth.study.rundir import Run, design_key, read_final
from parasynth.study.tables import results_table
from parasynth.study.verify import (EXTREME_RTOL, NOISE_Z, SINGULARITY_FLOOR, STATISTIC_RTOL, estimate_of,
                                    home_margin_check, verify)

load_plugins(str(Path(__file__).resolve().parents[1] / "data" / "analytic_plugin.py"))

def _drops(L) -> bool:
    return 0.185 < L < 0.2


def _seed(seed, kw) -> int:
    return kw["sample"].seed if kw.get("sample") is not None else seed


def verify_test_drop(mech, n: int = 4096, seed: int = 0, **kw):
    """+1 on the study's own seed; on other seeds -1 for a link length in (185 mm, 200 mm), else
    +1 (a constraint that holds on the screening sample and fails once re-evaluated)."""
    if _seed(seed, kw) < 1000:
        return 1.0
    return -1.0 if _drops(mech.params.link_length) else 1.0


def verify_test_noisy(mech, n: int = 4096, seed: int = 0, **kw):
    """The seed's last digit / 10 (a statistic whose spread over seeds is known)."""
    return (_seed(seed, kw) % 10) / 10.0


@pytest.fixture(autouse=True, scope="module")
def _test_measures():
    """The two test measures, registered for this module only (the registry is global)."""
    for f in (verify_test_drop, verify_test_noisy):
        register(f.__name__, unit="1", sense="maximize", settings=dict(SAMPLE_SETTINGS))(f)
    yield
    for f in (verify_test_drop, verify_test_noisy):
        OBJECTIVES.pop(f.__name__, None)


def _study(**changes):
    spec = {
        "name": "verify", "mechanism": "5pus_upu",
        "variables": [{"name": "link_length", "low": "150 mm", "high": "250 mm"},
                      {"name": "slider_radius", "low": "100 mm", "high": "180 mm"}],
        "objectives": [{"name": "test_quadratic"}, {"name": "test_two"}],
        "evaluation": {"samples": 64, "final_samples": 64, "final_repeats": 3, "final_top": 1},
        "optimizer": {"kind": "optuna", "algorithm": "nsga2", "n_trials": 6, "seed": 2},
    }
    spec.update(changes)
    return load_study(yaml.safe_dump(spec), is_text=True)


def _rec(study, trial, L, R, seed=0):
    ev = Evaluator(study)
    r = ev.evaluate({"link_length": L, "slider_radius": R}, trial=trial)
    return r


# -- the kinds of measure -----------------------------------------------------------------------
def test_each_measure_declares_how_it_depends_on_its_points():
    get = objectives.get
    assert get("workspace_volume").estimate_of({}) == "statistic"
    assert get("singularity_margin_min").estimate_of({}) == "extreme"  # quantile 0: the least
    assert get("singularity_margin_min").estimate_of({"quantile": 0.05}) == "statistic"
    assert get("position_error_max").estimate_of({}) == "extreme"  # quantile 1
    assert get("usable_workspace_volume").estimate_of({}) == "grid"
    assert get("singularity_free_radius").estimate_of({}) == "grid"
    assert get("inscribed_box_volume").estimate_of({"region": "usable"}) == "grid"
    assert get("inscribed_box_volume").estimate_of({}) == "statistic"  # the raster of a seeded sample
    assert get("footprint_radius").estimate_of({}) == "exact"
    assert get("max_actuator_force").estimate_of({}) == "extreme"


def test_grid_measures_do_not_depend_on_the_seed():
    """What 'exact on its grid' promises: another seed gives the same value."""
    import parasynth
    m = parasynth.load_mechanism("2rpu_2sps")
    for name in ("usable_workspace_volume", "singularity_free_radius"):
        assert objectives.get(name).estimate_of({}) == "grid"
        a = objectives.get(name)(m, n=4096, seed=0)
        b = objectives.get(name)(m, n=4096, seed=7)
        assert a == b


# -- the tolerance rules on values written here ---------------------------------------------------
def _recs(label, values, seeds=None, robust_se=None):
    seeds = seeds or list(range(1000, 1000 + len(values)))
    out = []
    for i, (v, s) in enumerate(zip(values, seeds)):
        r = Record(values={}, constraint_values={label: v}, margins={}, seed=s, samples=64)
        if robust_se is not None:
            r.robust = {label: {"stderr": robust_se[i]}}
        out.append(r)
    return out


def _one_constraint(name, **bounds):
    return _study(constraints=[{"name": name, "label": "c", **bounds}])


def test_a_statistic_passes_within_two_standard_errors_and_fails_beyond():
    study = _one_constraint("verify_test_noisy", min=0.5)
    vals = [0.46, 0.49, 0.475]  # mean 0.475, SE of the mean computed by hand
    mean = sum(vals) / 3
    se = math.sqrt(sum((v - mean) ** 2 for v in vals) / 2) / math.sqrt(3)
    chk = verify(study, {"link_length": 0.2, "slider_radius": 0.14}, _recs("c", vals)).checks[0]
    assert chk.kind == "statistic"
    assert chk.value == pytest.approx(mean) and chk.stderr == pytest.approx(se)
    assert chk.tolerance == pytest.approx(min(NOISE_Z * se, STATISTIC_RTOL * 0.5))
    assert (0.5 - mean) > chk.tolerance and not chk.passed  # 0.025 short, tolerance 2 x 0.00866
    wide = [0.46, 0.50, 0.49]  # a like shortfall inside a wider spread passes
    m2 = sum(wide) / 3
    se2 = math.sqrt(sum((v - m2) ** 2 for v in wide) / 2) / math.sqrt(3)
    chk2 = verify(study, {"link_length": 0.2, "slider_radius": 0.14}, _recs("c", wide)).checks[0]
    assert 0.5 - m2 < NOISE_Z * se2 <= STATISTIC_RTOL * 0.5 and chk2.passed


def test_a_noisy_statistic_buys_no_more_than_its_relative_tolerance():
    """Two seeds far apart (P = 0.59 and 0.94 against 0.9, as a chance constraint of a robust
    study gave): 2 standard errors would pass the mean 0.765; the tolerance is capped at 5 %."""
    study = _one_constraint("verify_test_noisy", min=0.9)
    chk = verify(study, {"link_length": 0.2, "slider_radius": 0.14}, _recs("c", [0.59, 0.94])).checks[0]
    assert NOISE_Z * chk.stderr > 0.9 - chk.value  # the noise alone would have passed it
    assert chk.tolerance == pytest.approx(STATISTIC_RTOL * 0.9) and not chk.passed


def test_a_robust_statistic_adds_the_standard_error_of_its_draws():
    study = _one_constraint("verify_test_noisy", min=0.5)
    vals = [0.45, 0.45]
    chk = verify(study, {"link_length": 0.2, "slider_radius": 0.14}, _recs("c", vals, robust_se=[0.04, 0.04])).checks[0]
    want = math.sqrt(0.0 ** 2 + 0.04 ** 2 / 2)  # seeds agree; each robust value has SE 0.04
    assert chk.stderr == pytest.approx(want)
    assert chk.tolerance == pytest.approx(min(NOISE_Z * want, STATISTIC_RTOL * 0.5))
    assert chk.passed == (0.05 <= chk.tolerance)


def test_an_extreme_takes_the_worst_seed_with_a_relative_tolerance():
    study = _one_constraint("singularity_margin_min", min=0.2)  # quantile 0: the least margin
    assert estimate_of(study.constraints[0]) == "extreme"
    vals = [0.25, 0.1925, 0.30]  # worst 0.1925: 3.75 % below 0.2
    chk = verify(study, {"link_length": 0.2, "slider_radius": 0.14}, _recs("c", vals, seeds=[1000, 1001, 1002])).checks[0]
    assert chk.value == 0.1925 and "seed 1001" in chk.where
    assert chk.tolerance == pytest.approx(EXTREME_RTOL * 0.2) and chk.passed
    vals = [0.25, 0.185, 0.30]  # 7.5 % below
    assert not verify(study, {"link_length": 0.2, "slider_radius": 0.14}, _recs("c", vals)).checks[0].passed


def test_an_exact_measure_is_checked_on_the_runs_own_value_without_tolerance():
    study = _one_constraint("test_link_length", max="200 mm")
    assert estimate_of(study.constraints[0]) == "exact"
    ok = verify(study, {"link_length": 0.2, "slider_radius": 0.14}, [], screened={"c": 0.2})
    bad = verify(study, {"link_length": 0.2001, "slider_radius": 0.14}, [], screened={"c": 0.2001})
    assert ok.checks[0].passed and not bad.checks[0].passed
    assert "c = " in bad.reason(study) and "200 mm" in bad.reason(study)  # in the study's units


def test_a_failed_reevaluation_fails_the_design():
    study = _one_constraint("verify_test_noisy", min=0.5)
    r = Record(values={}, status="failed", error="RuntimeError: boom", seed=1001)
    v = verify(study, {"link_length": 0.2, "slider_radius": 0.14}, [r])
    assert not v.passed and "seed 1001" in v.reason() and "boom" in v.reason()


# -- the singularity floor ------------------------------------------------------------------------
def test_the_home_margin_is_the_mechanisms_least_singular_value_at_home():
    study = _study()
    mech = design_mechanism(study, {"link_length": 0.205, "slider_radius": 0.135})
    want = float(mech.singularity_margin(np.atleast_2d(mech.home), engine="numpy")[0])
    chk = home_margin_check(mech)
    assert chk.value == pytest.approx(want, abs=1e-9) and chk.passed and chk.kind == "floor"
    assert not home_margin_check(mech, floor=want + 1e-3).passed
    assert SINGULARITY_FLOOR < 0.0155  # the shipped 2-RPU&2-SPS paper design (home margin 0.0156) passes


def test_a_design_singular_at_home_fails():
    """The 2021 paper's first scheme of the 5-PUS/UPU (five limbs on a regular pentagon, its
    pentagonal platform) is singular at the symmetric home pose: margin ~1e-16 by the NumPy
    reference."""
    import parasynth
    mech = parasynth.load_mechanism("5pus_upu", platform="pentagonal")
    m = float(mech.singularity_margin(np.atleast_2d(mech.home), engine="numpy")[0])
    chk = home_margin_check(mech)
    assert m < 1e-8 and not chk.passed and chk.value == pytest.approx(m, abs=1e-12)


# -- the walk down the ranking --------------------------------------------------------------------
DESIGNS = [(0, 0.205, 0.140), (1, 0.201, 0.138), (2, 0.195, 0.130), (3, 0.190, 0.125), (4, 0.170, 0.110),
           (5, 0.210, 0.150)]


def _run_with_drop(tmp_path, **ev):
    evaluation = {"samples": 64, "final_samples": 64, "final_repeats": 2, "final_top": 1, **ev}
    study = _study(constraints=[{"name": "verify_test_drop", "label": "drop", "min": 0}], evaluation=evaluation)
    recs = [_rec(study, t, L, R) for t, L, R in DESIGNS]
    table = results_table(study, recs)
    out = tmp_path / "run"
    out.mkdir()
    (out / "study.yaml").write_text(study.to_yaml())
    (out / "journal.jsonl").write_text("".join(json.dumps(r.to_dict()) + "\n" for r in recs))
    final = reevaluate_best(study, Evaluator(study), table, out)
    return study, table, final, out


def test_the_walk_recommends_the_first_design_of_the_ranking_that_passes(tmp_path):
    study, table, final, out = _run_with_drop(tmp_path)
    runs = table[table["source"] == "run"]
    knee = knee_of(study, pareto_front(study, runs))
    assert _drops(knee["link_length"])  # the knee is among the designs that fail once re-evaluated
    rec = final[final["recommended"].astype(bool)]
    assert len(rec) == 1
    r = rec.iloc[0]
    assert not _drops(r["link_length"]) and bool(r["verified"])
    # every design the ranking puts before it fails, by the constraint, and says so
    order = recommendation_order(study, runs)
    keys = [design_key(study, x) for _, x in order.iterrows()]
    pos = keys.index(design_key(study, r))
    before = order.iloc[:pos]
    assert len(before) >= 1 and all(_drops(x) for x in before["link_length"])
    for _, b in before.iterrows():
        row = final[(final["trial"] == b["trial"]) & (final["source"] == "best")].iloc[0]
        assert not bool(row["verified"]) and "drop" in row["verification"]
    # the summary's first lines say it
    lines = terminal_summary(study, table, read_final(study, out / "final.csv"), out)
    assert lines[0].startswith("recommended (the first design of the ranking that passed verification), verified: "
                               f"trial {int(r['trial'])}:")
    assert any(f"trial {int(knee['trial'])} (ranked before it) failed: drop" in ln for ln in lines)


def test_none_passing_is_said_at_the_top(tmp_path):
    study, table, final, out = _run_with_drop(tmp_path, singularity_floor=0.99)
    assert not final["recommended"].astype(bool).any() and not final["verified"].astype(bool).any()
    lines = terminal_summary(study, table, read_final(study, out / "final.csv"), out)
    assert lines[0].startswith("NO DESIGN PASSED VERIFICATION")
    assert "singularity margin at home" in "\n".join(lines)


def test_the_walk_is_bounded(tmp_path):
    study, table, final, out = _run_with_drop(tmp_path, singularity_floor=0.99, verify_designs=2, final_top=1)
    walked = final[final["role"] == "verify"]
    assert len(walked) <= 2


def test_an_interrupted_run_says_its_design_is_not_verified(tmp_path):
    study, table, final, out = _run_with_drop(tmp_path)
    (out / "final.csv").unlink()
    lines = terminal_summary(study, table, None, out)
    assert "NOT VERIFIED" in lines[0] and "--resume" in lines[1]


# -- verdicts count only verified designs -----------------------------------------------------------
def test_a_design_that_failed_verification_dominates_nothing(tmp_path):
    study, table, final, out = _run_with_drop(tmp_path)
    fin = read_final(study, out / "final.csv")
    a = analyse(Run(study, table, fin, out, None))
    failed = {int(t) for t in fin[(fin["source"] == "best") & ~fin["verified"].astype(bool)]["trial"]}
    assert failed
    for by in a.final.dominated_by.values():
        assert not (set(by) & failed)
    assert all(int(row["trial"]) not in failed for row, _ in a.final.vs_ref)


def test_best_means_best_over_the_whole_run():
    study = _study()
    cols = ["trial", "link_length", "slider_radius", "test_quadratic", "test_two"]
    front = pd.DataFrame([(4, 0.2, 0.14, -0.1, 0.5), (5, 0.2, 0.12, -0.2, 0.4), (6, 0.2, 0.13, -0.05, 0.6),
                          (7, 0.2, 0.11, -0.3, 0.3)], columns=cols)
    listed = front.iloc[:3]
    roles = design_roles(study, listed, None, front=front)
    # trial 5 has the least test_two of those listed, but trial 7 of the run
    assert roles == ["on the front", "best test_two of those listed", "best test_quadratic"]
