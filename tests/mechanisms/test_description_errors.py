"""Malformed mechanism descriptions raise a ValueError naming the key path (and the leg), and
mobility() of a described mechanism warns about under-actuation and inconsistencies."""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest
import yaml

import parasynth
import parasynth.measures.objectives
from parasynth.mechanisms import _PACKAGE_DIR
from parasynth.mechanisms.description import (DescriptionError, DescriptionWarning, description_class,
                                              from_description, load_description)


def _data(name):
    return yaml.safe_load((_PACKAGE_DIR / name).read_text())


TRIPOD = _data("3rps.yaml")
SQUARE = _data("2rpu_2sps.yaml")


def _error(data) -> str:
    with pytest.raises(ValueError) as e:
        description_class(data)
    assert isinstance(e.value, DescriptionError)
    return str(e.value)


def _with(base, path, value):
    """A copy of ``base`` with the entry at ``path`` (a list of keys) set, or deleted for
    value ``...``."""
    d = copy.deepcopy(base)
    node = d
    for k in path[:-1]:
        node = node[k]
    if value is ...:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return d


BAD = [
    # (base, path, value, expected fragments of the message)
    (SQUARE, ["legs", 2, "actuated"], "R", ["legs[2] (L3).actuated: joint 'R' does not exist in the SPS leg",
                                            "S, P, S"]),
    (SQUARE, ["legs", 1, "actuated"], "R", ["legs[1] (L2).actuated: joint 'R' of the RPU leg cannot be actuated",
                                            "'P'"]),
    (SQUARE, ["legs", 0, "actuated"], "none", ["legs[0] (L1).actuated: the SPS leg cannot be passive", "RPS, UPU"]),
    (SQUARE, ["legs", 0, "actuated"], 3, ["legs[0] (L1).actuated: expected a joint letter"]),
    (SQUARE, ["legs", 3, "type"], "RPX", ["legs[3] (L4).type: unknown leg type 'RPX'", "PRS", "UPU"]),
    (SQUARE, ["legs", 3, "type"], ..., ["legs[3] (L4).type: required key is missing"]),
    (SQUARE, ["legs", 1, "base"], ..., ["legs[1].base: missing anchor", "B"]),
    (SQUARE, ["legs", 1, "platform"], "C[1]", ["legs[1].platform: unknown platform anchor set 'C'", "platform sets: A"]),
    (SQUARE, ["legs", 1, "platform"], "A[4]", ["legs[1].platform: index 4 is out of range", "4 point(s)"]),
    (_with(SQUARE, ["legs", 1, "base"], "B[1, 3]"), ["legs", 1, "platform"], "A[0, 1, 2]",
     ["legs[1].platform: 3 platform anchor(s) for 2 base anchor(s)"]),
    (SQUARE, ["legs", 1, "r_axes"], "y", ["legs[1] (L2): unknown key 'r_axes' for the RPU leg", "r_axis"]),
    (SQUARE, ["legs", 1, "r_axis"], "sideways", ["legs[1] (L2).r_axis: unknown direction 'sideways'"]),
    (SQUARE, ["legs", 1, "r_axis"], [0, 0, 0], ["legs[1] (L2).r_axis: the direction must not be zero"]),
    (SQUARE, ["legs", 1, "r_axis"], [0, "k", 0], ["legs[1] (L2).r_axis[1]: unknown name 'k'"]),
    (SQUARE, ["legs", 1, "r_axis"], ["1e-200", 0, 0], ["legs[1] (L2).r_axis: the direction must not be zero"]),
    (_with(SQUARE, ["base", "B", 1], ["0 mm", "0 mm", "0 mm"]), ["legs", 1, "r_axis"], "radial",
     ["legs[1] (L2).r_axis: 'radial' is undefined for an anchor on the axis", "point [0.0, 0.0, 0.0]"]),
    (_with(SQUARE, ["base", "B", 1], ["0 mm", "0 mm", "0 mm"]), ["legs", 1, "r_axis"], "-tangent",
     ["legs[1] (L2).r_axis: 'tangent' is undefined for an anchor on the axis"]),
    (SQUARE, ["legs", 0, "name"], "L2", ["legs: leg name(s) ['L2'] used twice"]),
    (SQUARE, ["base", "B", 1, 0], "b22", ["base.B.points[1][0]: unknown name 'b22'", "parameters: a1"]),
    (SQUARE, ["base", "B", 1, 0], "350 kg", ["base.B.points[1][0]", "not a length"]),
    (SQUARE, ["base", "B", 1, 0], 0.35, ["base.B.points[1][0]: a bare number (0.35)", "give a unit"]),
    (SQUARE, ["base", "B", 1], ["350 mm", "0 mm", "0 mm", "1 mm"], ["base.B.points[1]: a point is a list"]),
    (SQUARE, ["parameters", "b2"], "350 mmm", ["parameters.b2: cannot read '350 mmm'"]),
    (SQUARE, ["parameters", "b2"], True, ["parameters.b2: booleans are not parameters"]),
    (SQUARE, ["parameters", "sin"], "1 mm", ["parameters.sin: parameter name 'sin' is reserved"]),
    (SQUARE, ["parameters", "leg_diameter", "kind"], "mass", ["parameters.leg_diameter.kind: 'mass' is not a kind"]),
    (SQUARE, ["parameters", "leg_diameter", "min"], "40 mm", ["parameters.leg_diameter must be >= 0.04"]),
    (SQUARE, ["checks", 0], "q_min > q_max", ["fail the check 'q_min > q_max'"]),
    (SQUARE, ["checks", 0], "q_min + ", ["checks[0]: cannot parse 'q_min + '"]),
    (SQUARE, ["checks", 0], "__import__('os')", ["checks[0]: the call of '__import__' is not allowed"]),
    (SQUARE, ["task", "position", 0], "z*tan(thet)", ["task.position[0]: unknown name 'thet'", "task coordinates: z, psi, theta"]),
    (SQUARE, ["task", "position", 0], "z.real", ["task.position[0]: Attribute", "is not allowed"]),
    (SQUARE, ["task", "position", 1], 0.1, ["task.position[1]: a bare number (0.1)"]),
    (SQUARE, ["task", "orientation", "convention"], "abc", ["task.orientation.convention: 'abc' is not a convention", "zyz"]),
    (SQUARE, ["task", "orientation", "angles"], ["theta", "psi"], ["task.orientation.angles: convention 'yzx' takes 3 angles"]),
    (SQUARE, ["task", "orientation", "angles", 0], "theta + R11", ["task.orientation.angles[0]: unknown name 'R11'"]),
    (SQUARE, ["task", "home", "psi"], ..., ["task.home.psi: required coordinate is missing"]),
    (SQUARE, ["task", "home", "psi"], "5 mm", ["task.home.psi", "not an angle"]),
    (SQUARE, ["task", "home", "phi"], "0 deg", ["task.home.phi: not a task coordinate"]),
    (SQUARE, ["task", "coordinates", "psi"], "angel", ["task.coordinates.psi: kind must be length or angle"]),
    (SQUARE, ["task", "coordinates", "a1"], "length", ["task.coordinates.a1: 'a1' is also a parameter"]),
    (SQUARE, ["task", "ranges", "z"], ["1000 mm"], ["task.ranges.z: give [low, high]"]),
    (SQUARE, ["task", "ranges", "z"], ["1000 mm", "550 mm"], ["task.ranges.z: low (1) must be below high (0.55)"]),
    (SQUARE, ["task", "valid", 0], "cos(theta)", ["task.valid[0]: 'cos(theta)' is not a condition"]),
    (SQUARE, ["task", "speed"], 1, ["task: unknown key 'speed'"]),
    (SQUARE, ["constraints", 0, "type"], "stroke", ["constraints[0] (stroke).type: unknown constraint type 'stroke'"]),
    (SQUARE, ["constraints", 1, "coordinate"], "phi", ["constraints[1] (psi_range).coordinate: 'phi' is not a task coordinate"]),
    (SQUARE, ["constraints", 3, "legs"], ["L1", "L9"], ["constraints[3] (interference).legs: unknown leg 'L9'"]),
    (SQUARE, ["constraints", 0, "min"], "1100 mm", ["constraints[0] (stroke): min (1.1) must be below max (1)"]),
    (SQUARE, ["constraints", 2, "name"], "psi_range", ["constraints: name(s) ['psi_range'] used twice"]),
    (SQUARE, ["colour"], "red", ["(top level): unknown key 'colour'"]),
    (SQUARE, ["name"], "my mech", ["name: required, letters, digits"]),
    (TRIPOD, ["platform", "A", "n"], 4, ["legs[0].platform: 4 platform anchor(s) for 3 base anchor(s)"]),
    (TRIPOD, ["platform", "A", "pattern"], "hexagon", ["platform.A.pattern: unknown pattern 'hexagon'", "polygon"]),
    (TRIPOD, ["platform", "A", "n"], 0, ["platform.A.n: must be an integer from 1 to 1000"]),
    (TRIPOD, ["platform", "A", "radius"], "platform_radiuss", ["platform.A.radius: unknown name 'platform_radiuss'"]),
    (TRIPOD, ["platform", "A", "plane"], "xx", ["platform.A.plane: 'xx' is not a plane"]),
    (TRIPOD, ["legs", 0, "names"], ["a", "b"], ["legs[0].names: this entry makes 3 legs; give 3 names"]),
    (TRIPOD, ["legs", 0, "name"], "leg", ["legs[0].name: this entry makes 3 legs"]),
    (TRIPOD, ["constraints", 2, "key"], "S_cone", ["constraints[2] (sphere_limit)", "no leg has a joint angle 'S_cone'"]),
    (TRIPOD, ["task", "position", 0], "0.01*cos(alpha) + 0 mm",
     ["task.home: the home pose", "not reachable by leg L2 (RPS)", "off the plane"]),
    (TRIPOD, ["length_scale"], "-base_radius", ["length_scale: must be a positive length"]),
]


@pytest.mark.parametrize("base, path, value, fragments", BAD, ids=[".".join(map(str, b[1])) for b in BAD])
def test_malformed_description_names_the_key(base, path, value, fragments):
    msg = _error(_with(base, path, value))
    for f in fragments:
        assert f in msg, (f, msg)


def test_home_out_of_reach_of_a_slider_leg():
    data = _with(_data("3prs.yaml"), ["task", "home", "z"], "300 mm")
    msg = _error(_with(data, ["parameters", "link_length", "value"], "100 mm"))
    assert "task.home: the home pose" in msg and "L1 (PRS)" in msg and "link_length" in msg


def test_bad_yaml_file_and_nothing_half_built(tmp_path):
    p = tmp_path / "m.yaml"
    p.write_text("name: m\nlegs: [\n")
    with pytest.raises(DescriptionError, match="m.yaml: not valid YAML"):
        load_description(p)
    p.write_text(yaml.safe_dump(_with(SQUARE, ["legs", 2, "actuated"], "R")))
    with pytest.raises(ValueError, match=r"m\.yaml: legs\[2\] \(L3\)\.actuated"):
        parasynth.load_mechanism(str(p))
    p.write_text(yaml.safe_dump(SQUARE) + "\n# fixed\n")  # fixed: loads now (the failure was not cached)
    assert parasynth.load_mechanism(str(p)).name == "2rpu_2sps"
    p.write_text("- just a list\n")
    with pytest.raises(DescriptionError, match="must be a mapping"):
        load_description(p)


def test_bad_parameter_values_at_load():
    with pytest.raises(ValueError, match=r"5pus_upu\.slider_angles must have shape \(5,\)"):
        parasynth.load_mechanism("5pus_upu.yaml", slider_angles=(0.1, 0.2, 0.3))
    with pytest.raises(ValueError, match=r"3rps\.q_min must be a number"):
        parasynth.load_mechanism("3rps", q_min="300 mm")
    with pytest.raises(ValueError, match="fail the check 'q_min < q_max'"):
        parasynth.load_mechanism("3rps", q_min=0.8)
    with pytest.raises(ValueError, match="task.home: the home pose .* not reachable by leg L1"):
        parasynth.load_mechanism("3prs", link_length=0.1)


def test_parameter_checks_kept_per_values_refuse_every_failing_set():
    """A check's passing values are kept per the values it reads: values that fail it are
    refused each time, also between and after passing ones."""
    Params = type(parasynth.load_mechanism("3rps")).Params
    q_max = Params().q_max
    for _ in range(3):
        for q_min, ok in ((0.5 * q_max, True), (q_max, False), (1.2 * q_max, False), (0.0, True), (-0.0, True),
                          (0.5 * q_max, True), (q_max, False)):
            if ok:
                assert Params(q_min=q_min).q_min == q_min
            else:
                with pytest.raises(ValueError, match="fail the check 'q_min < q_max'"):
                    Params(q_min=q_min)


# -- variants -----------------------------------------------------------------------------------------
FIVE = _data("5pus_upu.yaml")


@pytest.mark.parametrize("name, kw, pattern", [
    ("5pus_upu", {"platform": "hexagonal"}, r"5pus_upu\.platform must be one of 'rectangular', 'pentagonal', "
                                            r"got 'hexagonal'"),
    ("5pus_upu", {"hinge_layout": "scheme3"}, r"5pus_upu\.hinge_layout must be one of 'scheme1', 'scheme2', "
                                              r"'custom', got 'scheme3'"),
    ("5pus_upu", {"platform": True}, r"5pus_upu\.platform must be one of"),
    ("2rpu_2sps", {"coupled": "yes"}, r"2rpu_2sps\.coupled must be true or false, got 'yes'"),
    ("2rpu_2sps", {"coupled": 1}, r"2rpu_2sps\.coupled must be true or false"),
    ("2rpu_2sps", {"b2": 0.0}, r"2rpu_2sps\.b2 must be > 0"),
    ("4ups_1rps", {"mu2": np.pi}, r"4ups_1rps\.mu2 must be < 3\.14"),
])
def test_variant_and_bound_errors_name_the_field_and_the_choices(name, kw, pattern):
    with pytest.raises(ValueError, match=pattern):
        parasynth.load_mechanism(name, **kw)


def test_variants_section_errors_name_the_key_path():
    v = FIVE["variants"]
    cases = [
        (["variants", "platform", "default"], "round", r"variants\.platform\.default must be one of 'rectangular', "
                                                       r"'pentagonal', got 'round'"),
        (["variants", "platform", "default"], ..., r"variants\.platform\.default: required key is missing"),
        (["variants", "platform", "choices"], {"only": {}}, r"variants\.platform\.choices: give at least two"),
        (["variants", "platform", "choices", "pentagonal", "parameters"], {"pentagon_radius": "70 mm"},
         r"variants\.platform\.choices\.pentagonal: 'parameters' cannot be overlaid by a variant \(every choice "
         r"shares"),
        (["variants", "platform", "choices", "pentagonal", "platform"], ["S"],
         r"variants\.platform\.choices\.pentagonal\.platform: give a mapping"),
        (["variants", "platform", "colour"], "red", r"variants\.platform: unknown key 'colour'"),
        (["variants", "link_length"], v["platform"], r"variants\.link_length: 'link_length' is also a parameter"),
        (["variants", "platform", "choices"], {True: {}, "no": {}}, r"variants\.platform\.choices: choice names"),
    ]
    for path, value, pattern in cases:
        msg = _error(_with(FIVE, path, value))
        assert msg.startswith("5pus_upu:"), msg
        assert __import__("re").search(pattern, msg), (pattern, msg)
    sw = _with(SQUARE, ["variants", "coupled", "choices"], {True: {}, "maybe": {}})
    assert "choice names are all strings, or the two booleans" in _error(sw)


def test_a_broken_non_default_variant_fails_at_load_naming_the_choice():
    # The pentagonal platform names a parameter that does not exist: found when the
    # description is loaded, not when someone first selects it.
    d = _with(FIVE, ["variants", "platform", "choices", "pentagonal", "platform", "S", "radius"], "pentagon_r")
    msg = _error(d)
    assert "variants (hinge_layout=" in msg and "platform='pentagonal')" in msg
    assert "unknown name 'pentagon_r'" in msg and "platform.S.radius" in msg
    # ... and a choice whose geometry fails at its defaults too.
    d = _with(FIVE, ["variants", "platform", "choices", "pentagonal", "platform", "S", "radius"], "400 mm")
    msg = _error(d)
    assert "platform='pentagonal'" in msg and "not reachable by leg L1" in msg


def test_variant_overlays_replace_entries_and_null_removes():
    """Mapping sections are overlaid entry by entry (an anchor set, a task key), lists and the
    other sections replaced whole; null removes an entry."""
    d = copy.deepcopy(SQUARE)
    d["name"] = "square_variants"
    d["variants"]["wide"] = {"default": "no", "choices": {
        "no": {},
        "yes": {"base": {"B": [["0 mm", "-b1 - 50 mm", "0 mm"], ["b2 + 50 mm", "0 mm", "0 mm"],
                               ["0 mm", "b3 + 50 mm", "0 mm"], ["-b4 - 50 mm", "0 mm", "0 mm"]]},
                "constraints": [{"name": "stroke", "type": "actuator_range", "min": "q_min", "max": "q_max"}]},
    }}
    cls = description_class(d)
    a, b = cls(), cls(cls.Params(wide="yes"))
    np.testing.assert_allclose(b.legs[1].base - a.legs[1].base, [0.05, 0, 0], atol=1e-15)
    assert list(a.constraints) == ["stroke", "psi_range", "theta_range", "interference"]
    assert list(b.constraints) == ["stroke"]
    assert b.task_coordinates == a.task_coordinates  # task untouched
    c = cls(cls.Params(wide="yes", coupled=False))  # two variants combine
    assert c.task_coordinates == ("x", "z", "psi", "theta") and list(c.constraints) == ["stroke"]
    assert "define" not in c.description.selection and c.description.task.defines == []  # define: null
    assert cls.Params.UNITS["wide"] is None and cls.Params().wide == "no"


def test_categorical_study_variable_over_a_variant(tmp_path):
    from parasynth.study import StudyError, load_study, run_study

    study = {
        "name": "schemes",
        "mechanism": "5pus_upu",
        "variables": [{"name": "platform", "type": "categorical", "choices": ["rectangular", "pentagonal"]}],
        "objectives": [{"name": "workspace_volume", "goal": "maximize"}],
        "evaluation": {"method": "sobol", "samples": 256, "seed": 0},
        "optimizer": {"kind": "sweep"},
    }
    s = load_study(yaml.safe_dump(study), is_text=True)
    assert s.variables[0].choices == ("rectangular", "pentagonal")
    res = run_study(s, out_dir=tmp_path / "run", progress=False)
    assert [r.status for r in res.new_records] == ["ok", "ok"], [r.error for r in res.new_records]
    vol = {r.values["platform"]: r.objectives["workspace_volume"] for r in res.new_records}
    assert set(vol) == {"pentagonal", "rectangular"}
    direct = {k: parasynth.objectives.get("workspace_volume")(parasynth.load_mechanism("5pus_upu", platform=k),
                                                               n=256, seed=0) for k in vol}
    assert vol == pytest.approx(direct) and vol["pentagonal"] != vol["rectangular"]
    bad = copy.deepcopy(study)
    bad["variables"][0]["choices"] = ["rectangular", "hexagonal"]
    with pytest.raises(StudyError, match=r"variables\[0\]\.choices\[1\] must be one of 'rectangular', 'pentagonal', "
                                         r"got 'hexagonal'"):
        load_study(yaml.safe_dump(bad), is_text=True)
    bad = dict(study, variables=[{"name": "link_length", "low": "200 mm", "high": "210 mm", "num": 2}],
               fixed={"coupled": True})
    with pytest.raises(StudyError, match=r"fixed\.coupled: 'coupled' is not a parameter"):
        load_study(yaml.safe_dump(bad), is_text=True)
    sw = dict(study, mechanism="2rpu_2sps", variables=[{"name": "coupled", "type": "categorical",
                                                          "choices": [True, "no"]}])
    with pytest.raises(StudyError, match=r"variables\[0\]\.choices\[1\] must be true or false"):
        load_study(yaml.safe_dump(sw), is_text=True)


def test_outputs_and_exclusive_bounds_errors():
    assert "outputs.jacobian: 'jacobian' is already an attribute" in _error(
        _with(TRIPOD, ["outputs"], {"jacobian": "px"}))
    assert "outputs.tip.value: a vector output has three components" in _error(
        _with(TRIPOD, ["outputs"], {"tip": {"value": ["px", "py"]}}))
    assert "outputs.tip: unknown name 'nope'" in _error(_with(TRIPOD, ["outputs"], {"tip": "px + nope"}))
    assert "parameters.q_min.above: '1 kg'" in _error(_with(TRIPOD, ["parameters", "q_min"],
                                                            {"value": "300 mm", "above": "1 kg"}))
    # An output evaluated on poses: the platform point (0, 0, h) of the 3-RPS, by hand.
    m = from_description(_with(TRIPOD, ["outputs"], {"tip": ["px + 0.1*R13", "py + 0.1*R23", "pz + 0.1*R33"],
                                                      "height": "pz"}))
    X = np.array([[0.5, 0.1, -0.2], [0.45, 0.0, 0.3]])
    p, R = m.pose(X)
    np.testing.assert_allclose(m.tip(X), p + 0.1 * R[:, :, 2], atol=1e-15)
    np.testing.assert_allclose(m.height(X), X[:, 0], atol=1e-15)
    assert m.tip(X[0]).shape == (3,) and np.ndim(m.height(X[0])) == 0
    # Exclusive bounds name the field and the bound.
    cls = description_class(_with(TRIPOD, ["parameters", "q_min"], {"value": "300 mm", "above": "100 mm",
                                                                   "below": "500 mm"}))
    with pytest.raises(ValueError, match=r"3rps\.q_min must be > 0\.1 \(m\), got 0\.1"):
        cls.Params(q_min=0.1)
    with pytest.raises(ValueError, match=r"3rps\.q_min must be < 0\.5 \(m\), got 0\.5"):
        cls.Params(q_min=0.5)
    assert cls.Params(q_min=0.1000001).q_min == pytest.approx(0.1000001)


# -- mobility warnings ------------------------------------------------------------------------------
def test_under_actuation_warns():
    m = parasynth.load_mechanism("4ups_1rps.yaml")
    with pytest.warns(DescriptionWarning, match=r"under-actuated: the 4 actuator\(s\) q1, q2, q3, q4 do not control all 5"):
        mob = m.mobility()
    assert mob.under_actuated and not mob.controlled and mob.consistent
    assert len(mob.issues) == 1 and "issues:" in mob.summary()
    with warnings.catch_warnings():  # the analyses that use the constraint rank stay quiet
        warnings.simplefilter("error", DescriptionWarning)
        assert np.isfinite(m.singularity_margin(np.array([0.0, 0.42, 0.1, 0.2, 0.3])))
        assert m.mobility(warn=False).under_actuated


def test_restriction_without_the_flag_warns():
    m = from_description(_with(SQUARE, ["task", "restricted"], False))
    with pytest.warns(DescriptionWarning, match=r"cover fewer than the 4 freedoms \(2T2R\).*task.restricted: true"):
        mob = m.mobility()
    assert mob.consistent and mob.controlled


def test_more_coordinates_than_freedoms_warns():
    d = _with(TRIPOD, ["task", "coordinates", "gamma"], "angle")
    del d["task"]["define"]
    d["task"]["home"]["gamma"] = "0 deg"
    m = from_description(d)
    with pytest.warns(DescriptionWarning) as rec:
        mob = m.mobility()
    text = " | ".join(str(w.message) for w in rec)
    assert "inconsistent description: 4 task coordinates" in text
    assert "a small step of gamma from" in text
    assert not mob.consistent


def test_coordinate_that_moves_nothing_warns():
    d = _with(TRIPOD, ["task", "coordinates", "spare"], "length")
    d["task"]["home"]["spare"] = "0 mm"
    m = from_description(d)
    with pytest.warns(DescriptionWarning) as rec:
        m.mobility()
    text = " | ".join(str(w.message) for w in rec)
    assert "are not independent" in text and "spare do not move the platform" in text


def test_consistent_models_do_not_warn():
    for name in ("gough_stewart_6ups", "3rps", "3prs", "2rpu_2sps.yaml", "5pus_upu.yaml"):
        with warnings.catch_warnings():
            warnings.simplefilter("error", DescriptionWarning)
            mob = parasynth.load_mechanism(name).mobility()
        assert mob.issues == () and mob.consistent and not mob.under_actuated
