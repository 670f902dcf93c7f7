"""The pose constraint on the singularity margin (``SingularityMarginFloor``): in descriptions
(``type: singularity_margin``), added to a mechanism (``with_constraints``) and by a study
(``evaluation.constraints``); the compiled engine against the NumPy reference.

Exact: the NumPy margin is ``singularity_margin(X, engine="numpy") - floor`` (an independent
evaluation of the margin from fresh leg states). Agreement of the engines: margins within
1e-9 (the compiled singularity margin's contract), booleans equal except where the margin is
within 1e-9 of the floor or the pose is within 1e-12 of another constraint's boundary.
"""

from __future__ import annotations

import copy
import warnings
from pathlib import Path

import numpy as np
import pytest

import parasynth
from parasynth import engine
from parasynth.measures import objectives
from parasynth.model.constraints import SingularityMarginFloor
from parasynth.mechanisms.description import DescriptionError, description_class
from parasynth.study.design import design_mechanism
from parasynth.study.evaluate import Evaluator
from parasynth.study.spec import StudyError, check_study, resolve_study
from parasynth.measures.workspace import WorkspaceSample
from parasynth.common.yamlio import load_yaml
from test_kernels import numpy_margin

ROOT = Path(__file__).resolve().parents[2]
MECHS = ["5pus_upu", "gough_stewart_6ups", "3rps", "3prs", "2rpu_2sps", "4ups_1rps"]


def _poses(mech, n=4000, seed=0):
    r = mech.default_ranges()
    lo = np.array([r.get(c, (v - 0.1, v + 0.1))[0] for c, v in zip(mech.task_coordinates, mech.home)])
    hi = np.array([r.get(c, (v - 0.1, v + 0.1))[1] for c, v in zip(mech.task_coordinates, mech.home)])
    X = np.random.default_rng(seed).uniform(lo, hi, (n, mech.n_task))
    return np.vstack([X, mech.home, np.full(mech.n_task, np.nan)])


@pytest.mark.parametrize("name", MECHS)
def test_engines_agree_on_the_floor(name):
    base = parasynth.load_mechanism(name)
    X = _poses(base)
    plain = base.is_feasible(X)
    floor = float(np.median(base.singularity_margin(X[plain], engine="numpy")))  # cuts the feasible set
    mech = base.with_constraints(SingularityMarginFloor("conditioned", floor=floor))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no fallback: the compiled path covers the floor
        fast = mech.is_feasible(X)
        M1 = mech.constraint_margins(X)
    ref = mech.is_feasible(X, engine="numpy")
    M0 = mech.constraint_margins(X, engine="numpy")
    # the NumPy margin against an independent evaluation of the singularity margin
    sm = base.singularity_margin(X, engine="numpy")
    want = np.where(np.isnan(sm), -np.inf, sm - floor)
    np.testing.assert_allclose(M0["conditioned"], want, rtol=0, atol=1e-15)
    a, b = M0["conditioned"], M1["conditioned"]
    assert np.array_equal(np.isneginf(a), np.isneginf(b))
    fin = np.isfinite(a)
    assert np.abs(a[fin] - b[fin]).max() < 1e-9
    diff = np.flatnonzero(fast != ref)
    near = (np.abs(a[diff]) < 1e-9) | (np.abs(numpy_margin(base, X[diff])) <= 1e-12)
    assert near.all(), X[diff[~near][:3]].tolist()
    # the floor cuts: both outcomes among the poses feasible without it
    assert 0 < np.count_nonzero(ref & plain) < np.count_nonzero(plain)
    assert not np.any(ref & ~plain)


def test_floor_is_compiled_without_a_fallback_and_the_kernel_is_asked_for():
    mech = parasynth.load_mechanism("5pus_upu").with_constraints(SingularityMarginFloor("c", floor=0.1))
    if engine.HAVE_NUMBA:
        assert engine.available(mech), engine.reason(mech)
    asked = engine.needs(lambda: mech.is_feasible(mech.home[None, :]))
    assert {"feasible", "singularity_margin"} <= asked


def _described(extra):
    data = load_yaml(ROOT / "src/parasynth/mechanisms/gough_stewart_6ups.yaml")
    data = copy.deepcopy(data)
    data["constraints"].append(extra)
    return description_class(data)


def test_description_constraint_type():
    cls = _described({"name": "conditioned", "type": "singularity_margin", "min": 0.45,
                      "doc": "well-conditioned poses"})
    mech = cls()
    c = mech.constraints["conditioned"]
    assert isinstance(c, SingularityMarginFloor) and c.floor == 0.45 and c.unit == "1"
    X = _poses(mech, 3000, seed=2)
    ref = mech.is_feasible(X, engine="numpy")
    fast = mech.is_feasible(X)
    plain = parasynth.load_mechanism("gough_stewart_6ups")
    want = plain.is_feasible(X, engine="numpy") & (plain.singularity_margin(X, engine="numpy") >= 0.45)
    assert np.array_equal(ref, want)
    sm = plain.singularity_margin(X, engine="numpy")
    odd = np.flatnonzero(fast != ref)
    assert np.all(np.abs(sm[odd] - 0.45) < 1e-9)
    # a workspace measure over well-conditioned poses only
    s = WorkspaceSample(n=2048, seed=1)
    v_all = objectives.get("workspace_volume")(plain, sample=s)
    v_ok = objectives.get("workspace_volume")(mech, sample=s)
    assert 0 < v_ok < v_all


@pytest.mark.parametrize("extra,match", [
    ({"name": "c", "type": "singularity_margin"}, r"constraints\[4\] \(c\)\.min: required key"),
    ({"name": "c", "type": "singularity_margin", "min": 0.1, "max": 0.5}, r"constraints\[4\] \(c\): unknown key"),
    ({"name": "c", "type": "singularity_margin", "min": 1.5}, r"constraints\[4\] \(c\)\.min: .*number in \[0, 1\)"),
    ({"name": "c", "type": "singularity_margin", "min": "5 mm"}, r"constraints\[4\] \(c\)\.min"),
])
def test_description_constraint_errors(extra, match):
    with pytest.raises(DescriptionError, match=match):
        _described(extra)()


def test_with_constraints_copies_and_checks_names():
    mech = parasynth.load_mechanism("3rps")
    m2 = mech.with_constraints(SingularityMarginFloor("c", floor=0.3))
    assert "c" not in mech.constraints and list(m2.constraints)[-1] == "c"
    assert m2.with_params(q_max=0.8).constraints["c"].floor == 0.3  # kept by with_params
    with pytest.raises(ValueError, match="duplicate constraint names \\['stroke'\\]"):
        mech.with_constraints(SingularityMarginFloor("stroke", floor=0.3))
    with pytest.raises(ValueError, match="floor must be a number in \\[0, 1\\)"):
        SingularityMarginFloor("c", floor=-0.1)
    with pytest.raises(ValueError, match="takes Constraint objects"):
        mech.with_constraints("c")
    # the workspace cache tells the two apart
    s = WorkspaceSample(n=1024)
    assert objectives.get("workspace_volume")(m2, sample=s) < objectives.get("workspace_volume")(mech, sample=s)


STUDY = {
    "name": "floor_test", "mechanism": "3rps",
    "objectives": [{"name": "workspace_volume"}, {"name": "usable_workspace_fraction"}],
    "evaluation": {"samples": 1000, "method": "grid"},
    "optimizer": {"kind": "sweep", "designs": [{}]},
}


def _study(pose_constraints, **objective_settings):
    data = copy.deepcopy(STUDY)
    data["evaluation"]["constraints"] = pose_constraints
    if objective_settings:
        data["objectives"][0]["settings"] = objective_settings
    return resolve_study(data)


def test_study_adds_the_floor_to_every_design():
    plain = _study(None)
    added = _study([{"type": "singularity_margin", "min": 0.3, "name": "conditioned"}])
    assert added.evaluation["constraints"] is None  # only added ones: all of the model's are kept
    assert added.evaluation["added_constraints"] == ({"type": "singularity_margin", "name": "conditioned",
                                                      "min": 0.3},)
    mech = design_mechanism(added, {})
    assert list(mech.constraints)[-1] == "conditioned" and len(mech.constraints) == 5
    named = _study(["stroke", {"type": "singularity_margin", "min": 0.3}])
    assert named.evaluation["constraints"] == ["stroke", "singularity_margin"]
    r0, r1 = Evaluator(plain).evaluate({}), Evaluator(added).evaluate({})
    assert r0.status == r1.status == "ok", (r0.error, r1.error)
    assert 0 < r1.objectives["workspace_volume"] < r0.objectives["workspace_volume"]
    # a measure's own selection may name the added constraint
    s = _study([{"type": "singularity_margin", "min": 0.3}], constraints=["singularity_margin"])
    assert Evaluator(s).evaluate({}).status == "ok"
    assert check_study(added) == []


@pytest.mark.parametrize("entry,match", [
    ({"type": "singularity_margin"}, r"evaluation\.constraints\[0\]\.min: required"),
    ({"type": "margin", "min": 0.1}, r"evaluation\.constraints\[0\]\.type: an added pose constraint needs type: "
                                     r"singularity_margin"),
    ({"type": "singularity_margin", "min": 2}, r"evaluation\.constraints\[0\]\.min: .*plain number in \[0, 1\)"),
    ({"type": "singularity_margin", "min": "0.1 mm"}, r"evaluation\.constraints\[0\]\.min"),
    ({"type": "singularity_margin", "min": 0.1, "max": 0.2}, r"evaluation\.constraints\[0\]: unknown key 'max'"),
    ({"type": "singularity_margin", "min": 0.1, "name": "stroke"}, r"evaluation\.constraints\[0\]\.name: 'stroke' "
                                                                  r"is already a pose constraint"),
])
def test_study_bad_added_constraint(entry, match):
    with pytest.raises(StudyError, match=match):
        _study([entry])
