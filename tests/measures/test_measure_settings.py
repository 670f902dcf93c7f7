"""Declared, typed measure settings: one validator per measure naming the field path, and the
workspace sample passed whole (no setting merged with it by name)."""
from __future__ import annotations

import inspect

import pytest
import yaml

import parasynth
from parasynth.measures import objectives
from parasynth.measures.measure_spec import Setting, SettingError, check_settings
from parasynth.study.design import evaluation_sample, measure_arguments, measure_settings
from parasynth.study.evaluate import Evaluator
from parasynth.study.spec import StudyError, load_study
from parasynth.measures.workspace import WorkspaceSample

TOL = {"link_tolerance": "0.02 mm", "spherical_clearance": "0.01 mm"}


def _study(objs, evaluation=None, constraints=()):
    spec = {"name": "s", "mechanism": "5pus_upu", "variables": [{"name": "link_length", "values": ["205 mm"]}],
            "objectives": objs, "constraints": list(constraints),
            "evaluation": {"samples": 256, "seed": 0,
                           "ranges": {"x": ["-200 mm", "200 mm"], "y": ["-200 mm", "200 mm"],
                                      "z": ["-450 mm", "300 mm"]}, **(evaluation or {})}}
    return load_study(yaml.safe_dump(spec), is_text=True)


def _error(objs, **kw) -> str:
    with pytest.raises(StudyError) as e:
        _study(objs, **kw)
    return str(e.value)


@pytest.mark.parametrize("objs, path, allowed", [
    ([{"name": "workspace_volume"}, {"name": "position_error_max", "settings": {**TOL, "method": "foo"}}],
     "objectives[1].settings.method", "'foo' is not one of first_order, monte_carlo"),
    ([{"name": "workspace_volume"}, {"name": "extent", "settings": {"axis": "w"}}],
     "objectives[1].settings.axis", "'w' is not one of x, y, z"),
    ([{"name": "workspace_volume", "settings": {"method": "halton"}}],
     "objectives[0].settings.method", "is not one of sobol, grid, random"),
    ([{"name": "position_error_max", "settings": {**TOL, "sampling": "halton"}}],
     "objectives[0].settings.sampling", "is not one of sobol, grid, random"),
    ([{"name": "min_lti", "settings": {"quantile": 1.5}}], "objectives[0].settings.quantile", "1"),
    ([{"name": "workspace_volume", "settings": {"engine": "gpu"}}],
     "objectives[0].settings.engine", "is not one of compiled, numpy"),
    ([{"name": "stiffness_along", "settings": {"frame": "world"}}],
     "objectives[0].settings.frame", "is not one of base, platform"),
    ([{"name": "position_error_max", "settings": {"link_tolerance": "-0.01 mm"}}],
     "objectives[0].settings.link_tolerance", "outside the allowed range"),
    ([{"name": "min_lti", "settings": {"max_points": 0}}], "objectives[0].settings.max_points", ">= 1"),
    ([{"name": "min_lti", "settings": {"colour": "red"}}], "objectives[0].settings.colour", "allowed: ranges, n"),
])
def test_a_bad_setting_names_its_field_path_and_what_is_allowed(objs, path, allowed):
    msg = _error(objs)
    assert msg.startswith(path + ":"), msg
    assert allowed in msg, msg


def test_constraint_settings_are_checked_by_the_same_validator():
    msg = _error([{"name": "workspace_volume"}],
                 constraints=[{"name": "singularity_margin_min", "min": 0.1, "settings": {"quantile": -1}}])
    assert msg.startswith("constraints[0].settings.quantile:"), msg


def test_valid_settings_resolve_to_si():
    s = _study([{"name": "max_actuator_force", "settings": {"mass": "2000 g", "max_points": 64}},
                {"name": "position_error_max", "settings": {**TOL, "method": "monte_carlo", "sampling": "grid"}}])
    assert s.objectives[0].settings == {"mass": 2.0, "max_points": 64}
    assert s.objectives[1].settings["link_tolerance"] == pytest.approx(2e-5)
    assert s.objectives[1].settings["sampling"] == "grid"


def test_a_setting_named_like_a_workspace_key_does_not_change_the_sample():
    # evaluation.method grid; the accuracy measure's own method (its error model) is first_order:
    # its workspace is still sampled on the grid, as the volume's is.
    s = _study([{"name": "workspace_volume"},
                {"name": "position_error_max", "settings": {**TOL, "method": "first_order"}}],
               evaluation={"method": "grid"})
    sample = evaluation_sample(s)
    assert sample.method == "grid"
    args = measure_arguments(s, "position_error_max", s.objectives[1].settings, sample)
    assert args["sample"] is sample and args["method"] == "first_order"
    assert measure_arguments(s, "workspace_volume", {}, sample)["sample"] is sample
    rec = Evaluator(s).evaluate({"link_length": 0.205})
    assert rec.status == "ok", rec.error
    mech = parasynth.load_mechanism("5pus_upu", link_length=0.205)
    own = dict(s.objectives[1].settings)
    pe = objectives.get("position_error_max")
    on_grid = pe(mech, sample=WorkspaceSample(**{**sample.kwargs(), "method": "grid"}), **own)
    on_sobol = pe(mech, sample=WorkspaceSample(**{**sample.kwargs(), "method": "sobol"}), **own)
    assert on_grid != on_sobol  # the sampler matters, so the test can tell them apart
    assert rec.objectives["position_error_max"] == on_grid
    # the older flat form says the same: the sampler under the measure's own name for it
    flat = measure_settings(s, "position_error_max", s.objectives[1].settings)
    assert flat["sampling"] == "grid" and flat["method"] == "first_order"
    assert pe(mech, **flat) == on_grid


def test_a_measure_overrides_its_own_sample_only():
    s = _study([{"name": "workspace_volume", "label": "v_all"},
                {"name": "workspace_volume", "label": "v_128", "settings": {"n": 128, "seed": 3}}])
    sample = evaluation_sample(s)
    a = measure_arguments(s, "workspace_volume", s.objectives[1].settings, sample)
    assert a["sample"] == WorkspaceSample(**{**sample.kwargs(), "n": 128, "seed": 3}) and sample.n == 256
    # a re-evaluation's n and seed win over the measure's
    b = measure_arguments(s, "workspace_volume", s.objectives[1].settings, evaluation_sample(s, n=512, seed=7),
                          pinned=("n", "seed"))
    assert (b["sample"].n, b["sample"].seed) == (512, 7)
    rec = Evaluator(s).evaluate({"link_length": 0.205})
    mech = parasynth.load_mechanism("5pus_upu", link_length=0.205)
    ranges = sample.kwargs()["ranges"]
    assert rec.objectives["v_128"] == objectives.get("workspace_volume")(mech, ranges=ranges, n=128, seed=3)
    assert rec.objectives["v_all"] == objectives.get("workspace_volume")(mech, ranges=ranges, n=256, seed=0)


def test_evaluation_keys_reach_the_settings_that_declare_them():
    s = _study([{"name": "workspace_volume"}, {"name": "footprint_radius"}],
               evaluation={"engine": "numpy", "constraints": ["stroke"]})
    sample = evaluation_sample(s)
    a = measure_arguments(s, "workspace_volume", {}, sample)
    assert a["engine"] == "numpy" and a["constraints"] == ["stroke"]
    assert measure_arguments(s, "footprint_radius", {}, sample) == {}
    # the measure's own value wins over the evaluation's
    assert measure_arguments(s, "workspace_volume", {"engine": "compiled"}, sample)["engine"] == "compiled"


def test_python_calls_check_the_same_declarations():
    mech = parasynth.load_mechanism("5pus_upu")
    s = WorkspaceSample(n=64)
    with pytest.raises(ValueError, match=r"min_lti\.quantile"):
        objectives.get("min_lti")(mech, sample=s, quantile=5)
    with pytest.raises(ValueError, match=r"extent\.axis: 'w' is not one of x, y, z"):
        objectives.get("extent")(mech, n=64, axis="w")
    # keyword settings in SI, as before
    v = objectives.get("min_lti")(mech, n=64, seed=0, quantile=0.5, max_points=32)
    assert v == objectives.get("min_lti")(mech, sample=s, quantile=0.5, max_points=32)


def test_settings_checked_once_are_still_checked_for_other_values():
    # Settings that passed the checks with a sample are not checked again; any other value is,
    # also one equal as a number but of another type, every time.
    mech = parasynth.load_mechanism("5pus_upu")
    s = WorkspaceSample(n=64)
    m = objectives.get("min_lti")
    good = m(mech, sample=s, quantile=0.5)
    assert m(mech, sample=s, quantile=0.5) == good
    for _ in range(2):
        with pytest.raises(ValueError, match=r"min_lti\.quantile"):
            m(mech, sample=s, quantile=5)
        with pytest.raises(ValueError, match=r"min_lti\.quantile"):
            m(mech, sample=s, quantile=True)  # not the number 1
        with pytest.raises(ValueError, match=r"unknown setting"):
            m(mech, sample=s, quantile=0.5, bogus=1)
    with pytest.raises(ValueError, match=r"min_lti\.quantile"):
        m(mech, sample=s, quantile=[0.5])  # not hashable: checked as always


def test_settings_checked_without_a_sample_are_kept_apart_from_those_with_one():
    # Without a sample (the older flat form) settings that passed are not checked again either;
    # other values are, every time; and settings allowed only without a sample (a sample field
    # given beside the measure's own) are still refused with one after passing without it.
    mech = parasynth.load_mechanism("5pus_upu")
    m = objectives.get("min_lti")
    good = m(mech, n=64, quantile=0.5)
    assert m(mech, n=64, quantile=0.5) == good
    for _ in range(2):
        with pytest.raises(ValueError, match=r"min_lti\.quantile"):
            m(mech, n=64, quantile=5)
        with pytest.raises(ValueError, match=r"unknown setting"):
            m(mech, n=64, quantile=0.5, bogus=1)
        with pytest.raises(ValueError, match="belong to the workspace sample"):
            m(mech, sample=WorkspaceSample(n=64), n=64, quantile=0.5)
    assert objectives.get("footprint_radius")(mech) == objectives.get("footprint_radius")(mech) > 0
    with pytest.raises(ValueError, match="unknown setting"):
        objectives.get("footprint_radius")(mech, quantile=0.5)


def test_declared_defaults_match_the_functions():
    checked = 0
    for name, m in objectives.OBJECTIVES.items():
        sig = inspect.signature(m.func).parameters
        for k, p in m.params.items():
            if k in sig and sig[k].default is not inspect.Parameter.empty and p.default is not None:
                assert p.default == sig[k].default, (name, k)
                checked += 1
    assert checked >= 15


def test_every_setting_is_typed_and_sample_fields_are_declared():
    for name, m in objectives.OBJECTIVES.items():
        assert set(m.settings) == set(m.params), name
        assert all(isinstance(p, Setting) for p in m.params.values()), name
        fields = {p.sample_field for p in m.params.values() if p.sample_field}
        assert (fields == set(WorkspaceSample.FIELDS)) == m.sample, name
    assert objectives.get("position_error_max").params["sampling"].sample_field == "method"
    assert objectives.get("position_error_max").params["method"].sample_field is None


def test_the_validator_itself():
    specs = {"q": Setting("float", low=0.0, high=1.0), "k": Setting("str", choices=("a", "b"), doc="a letter"),
             "m": Setting("mass")}
    assert check_settings("t", specs, {"q": 0.5, "k": "a", "m": "3 kg"}, "x", resolve={}) == {"q": 0.5, "k": "a",
                                                                                             "m": 3.0}
    for bad, where in [({"q": 2}, "x.q"), ({"k": "c"}, "x.k"), ({"m": 3}, "x.m"), ({"z": 1}, "x.z")]:
        with pytest.raises(SettingError, match=rf"^{where}:"):
            check_settings("t", specs, bad, "x", resolve={})
    with pytest.raises(SettingError, match=r"\(a letter\)"):
        check_settings("t", specs, {"k": "c"}, "x")
    with pytest.raises(ValueError, match="kind"):
        Setting("colour")
