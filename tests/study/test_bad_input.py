"""Bad input: unknown names and parameters, invalid parameter values, wrong pose shapes and
non-finite poses."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import parasynth
from _support import MODEL_CONFIGS, MODEL_IDS, load, sample_poses

configs = pytest.mark.parametrize("config", MODEL_CONFIGS, ids=MODEL_IDS)
NAMES = ["4ups_1rps", "2rpu_2sps", "5pus_upu"]


def test_list_mechanisms():
    names = parasynth.list_mechanisms()
    assert set(NAMES) <= set(names)
    assert names == sorted(names)


@pytest.mark.parametrize("bad", ["nope", "2rpu-2sps", "", "4UPS_1RPS"])
def test_unknown_mechanism_lists_valid_names(bad):
    with pytest.raises(ValueError) as exc:
        parasynth.load_mechanism(bad)
    msg = str(exc.value)
    for name in NAMES:
        assert name in msg


@pytest.mark.parametrize("name", NAMES)
def test_unknown_parameter_lists_valid_parameters(name):
    import dataclasses

    valid = [f.name for f in dataclasses.fields(load(name, {}).params)]
    with pytest.raises(ValueError) as exc:
        parasynth.load_mechanism(name, not_a_parameter=1.0)
    msg = str(exc.value)
    assert "not_a_parameter" in msg
    for field in valid:
        assert field in msg


BAD_PARAMS = [
    # (mechanism, field, bad value)
    ("2rpu_2sps", "a1", -0.15),
    ("2rpu_2sps", "b2", 0.0),
    ("2rpu_2sps", "b3", float("nan")),
    ("2rpu_2sps", "a4", float("inf")),
    ("2rpu_2sps", "a2", "abc"),
    ("2rpu_2sps", "a3", [0.1, 0.2]),
    ("2rpu_2sps", "coupled", "yes"),
    ("5pus_upu", "link_length", -0.205),
    ("5pus_upu", "slider_radius", float("nan")),
    ("5pus_upu", "pentagon_radius", -1.0),
    ("5pus_upu", "upu_base_z", float("nan")),
    ("5pus_upu", "hinge_points", ((0.035, 0.051), (-0.035, 0.051))),
    ("5pus_upu", "hinge_points", ((0.035, 0.051, 0.0),) * 5),
    ("5pus_upu", "hinge_points", ((0.035, float("nan")),) * 5),
    ("5pus_upu", "hinge_points", ((0.035, 0.051), (0.0,), (1, 2), (1, 2), (1, 2))),
    ("5pus_upu", "slider_angles", (0.1, 0.2, 0.3)),
    ("5pus_upu", "platform", "hexagonal"),
    ("4ups_1rps", "platform_radius", -0.1),
    ("4ups_1rps", "base_radius", float("nan")),
    ("4ups_1rps", "l_s0", -0.05),
    ("4ups_1rps", "mu1", float("nan")),
    ("4ups_1rps", "mu2", -1.0),
    ("4ups_1rps", "platform_angles", (0.0, 1.0, 2.0)),
    ("4ups_1rps", "platform_angles", (0.0, 1.0, 2.0, float("nan"))),
]


@pytest.mark.parametrize("name,field,value", BAD_PARAMS, ids=[f"{n}.{f}-{i}" for i, (n, f, _) in enumerate(BAD_PARAMS)])
def test_invalid_parameter_value_names_the_field(name, field, value):
    with pytest.raises(ValueError) as exc:
        parasynth.load_mechanism(name, **{field: value})
    assert field in str(exc.value)


@configs
@pytest.mark.parametrize("shape_delta", ["short", "long", "3d", "row-short", "empty-cols"])
def test_wrong_pose_shape_raises_value_error(config, shape_delta):
    m = load(*config)
    n = m.n_task
    X = {
        "short": np.zeros(n - 1),
        "long": np.zeros((2, n + 1)),
        "3d": np.zeros((2, 3, n)),
        "row-short": np.zeros((4, n - 1)),
        "empty-cols": np.zeros((3, 0)),
    }[shape_delta]
    for method in (m.inverse_kinematics, m.jacobian, m.wrench_matrix, m.singularity_margin):
        with pytest.raises(ValueError):
            method(X)
    q = m.inverse_kinematics(m.home).actuators
    with pytest.raises(ValueError):
        m.forward_kinematics(q, guess=X, fixed={"gamma": 0.0} if m.name == "4ups_1rps" else None)


@configs
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_pose_is_unreachable_without_leaking(config, bad):
    m = load(*config)
    X = sample_poses(m, np.random.default_rng(0), 4, scale=0.3)
    X[0] = m.home if m.name != "5pus_upu" else X[0]
    ok_before = m.inverse_kinematics(X).reachable
    assert np.all(ok_before)
    X[1, 0] = bad
    X[2, -1] = bad
    with warnings.catch_warnings():
        if np.isnan(bad):
            # NaN poses pass silently (no RuntimeWarning). For +-inf some models evaluate
            # cos(inf) in their validity check, which numpy reports as a RuntimeWarning;
            # the masking is what matters there.
            warnings.simplefilter("error")
        ik = m.inverse_kinematics(X)
        J = m.jacobian(X)
        W = m.wrench_matrix(X)
        s = m.singularity_margin(X)
        ik1 = m.inverse_kinematics(X[1])
    assert ik.reachable.tolist() == [True, False, False, True]
    assert not bool(ik1.reachable) and np.all(np.isnan(ik1.actuators))
    good = ik.reachable
    # reachable rows are untouched and finite ...
    assert np.all(np.isfinite(ik.actuators[good]))
    assert np.all(np.isfinite(J[good])) and np.all(np.isfinite(W[good])) and np.all(np.isfinite(s[good]))
    for k, v in ik.passive_angles.items():
        assert np.all(np.isfinite(v[good])), k
    clean = m.inverse_kinematics(X[good])
    np.testing.assert_array_equal(ik.actuators[good], clean.actuators)
    np.testing.assert_allclose(s[good], m.singularity_margin(X[good]), rtol=1e-12)
    # ... and unreachable rows are NaN, not stale numbers
    assert np.all(np.isnan(ik.actuators[~good]))
    assert np.all(np.isnan(J[~good])) and np.all(np.isnan(s[~good]))


def test_2rpu_theta_90_deg_is_unreachable_not_an_error():
    m = load("2rpu_2sps", {})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ik = m.inverse_kinematics(np.array([[0.75, 0.0, np.pi / 2], [0.75, 0.0, 0.2]]))
    assert ik.reachable.tolist() == [False, True]
    assert np.all(np.isnan(ik.actuators[0])) and np.all(np.isfinite(ik.actuators[1]))


def test_out_of_reach_5pus_pose_is_masked():
    m = load("5pus_upu", {})
    X = np.array([m.home, [0.5, 0.0, 0.0, 0.0, 0.0], m.home + 0.01])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ik = m.inverse_kinematics(X)
    assert ik.reachable.tolist() == [True, False, True]
    assert np.all(np.isnan(ik.actuators[1]))


@configs
def test_non_finite_actuators_rejected_by_fk(config):
    m = load(*config)
    q = m.inverse_kinematics(m.home).actuators.copy()
    q[0] = np.nan
    with pytest.raises(ValueError):
        m.forward_kinematics(q, fixed={"gamma": 0.0} if m.name == "4ups_1rps" else None)


# -- parasynth.common.validation: number, count and pose checks ----------------------------------------
from parasynth.common.validation import (MAX_SAMPLES, InputError, check_count, check_number,  # noqa: E402
                                         check_pose_array, is_real_number)


@pytest.mark.parametrize("value", [True, False, np.bool_(True), "0.2", b"0.2", 0.2 + 0j, np.complex128(1), None,
                                   [0.2], (0.2,), {"v": 0.2}, np.array([0.2])])
def test_check_number_rejects_non_numbers_naming_the_field(value):
    with pytest.raises(InputError) as e:
        check_number("link_length", value, "length", 0.0, lo_open=True)
    msg = str(e.value)
    assert msg.startswith("link_length must be a length in m > 0"), msg


@pytest.mark.parametrize("value,ok", [(0.2, True), (1, True), (np.float32(0.5), True), (np.int64(2), True),
                                      (np.array(0.3), True), (0.0, False), (-0.1, False), (float("nan"), False),
                                      (float("inf"), False), (1e308 * 10, False)])
def test_check_number_range_and_finiteness(value, ok):
    if ok:
        assert check_number("x", value, "length", 0.0, lo_open=True) == float(value)
    else:
        with pytest.raises(InputError, match=r"^x must be"):
            check_number("x", value, "length", 0.0, lo_open=True)


def test_check_number_closed_and_open_bounds():
    assert check_number("q", 0.0, None, 0.0, 1.0) == 0.0
    assert check_number("q", 1.0, None, 0.0, 1.0) == 1.0
    with pytest.raises(InputError, match=r"q must be a number in \(0.0, 1.0\)"):
        check_number("q", 1.0, None, 0.0, 1.0, lo_open=True, hi_open=True)
    with pytest.raises(InputError, match=r"in \[0, 3.14\] rad"):
        check_number("a", 4.0, "angle", 0, 3.14)


@pytest.mark.parametrize("value,expected", [(1, 1), (4096.0, 4096), (np.int32(7), 7), (MAX_SAMPLES, MAX_SAMPLES)])
def test_check_count_accepts_integral_values(value, expected):
    v = check_count("n", value, 1, MAX_SAMPLES)
    assert v == expected and type(v) is int


@pytest.mark.parametrize("value,needle", [(0, ">= 1"), (-3, ">= 1"), (2.5, ">= 1"), (True, "boolean"), ("10", "string"),
                                          (float("nan"), ">= 1"), (1e20, "documented maximum"),
                                          (MAX_SAMPLES + 1, "documented maximum"), (10**20, "documented maximum")])
def test_check_count_refuses(value, needle):
    with pytest.raises(InputError) as e:
        check_count("n", value, 1, MAX_SAMPLES)
    assert str(e.value).startswith("n must") and needle in str(e.value)


def test_is_real_number():
    assert all(is_real_number(v) for v in (1, 1.5, np.float64(2), np.int8(1), np.array(3.0)))
    assert not any(is_real_number(v) for v in (True, np.bool_(False), "1", 1j, None, [1], np.array([1.0])))


@pytest.mark.parametrize("X,needle", [("0.1, 0.2", "string"), (np.array(["0.1", "0.2"]), "strings"),
                                      (np.array([1 + 0j, 2]), "complex"), (np.array([True, False]), "booleans"),
                                      ([0.1, "0.2"], "string"), ([0.1, None], "None"), (None, "None")])
def test_check_pose_array_refuses_non_numbers(X, needle):
    with pytest.raises(InputError) as e:
        check_pose_array("poses X", X)
    assert str(e.value).startswith("poses X must") and needle in str(e.value)


def test_check_pose_array_keeps_non_finite_values_for_masking():
    X = check_pose_array("X", [[0.0, np.nan], [np.inf, 1e308], [1, 2]])
    assert X.dtype == float and X.shape == (3, 2)
    assert np.isnan(X[0, 1]) and np.isinf(X[1, 0]) and X[2, 1] == 2.0


# -- parasynth.common.yamlio: the one safe YAML reader ------------------------------------------------
from parasynth.common.yamlio import MAX_ALIASES, MAX_DEPTH, MAX_NODES, YamlError, load_yaml  # noqa: E402


def test_yaml_plain_document_round_trips():
    import yaml as pyyaml

    data = {"a": [1, 2.5, "x", None, True], "b": {"c": {"d": "205 mm"}}, "e": []}
    assert load_yaml(pyyaml.safe_dump(data), is_text=True) == data


@pytest.mark.parametrize("text,line", [("a: 1\nb: 2\na: 3\n", 3), ("x:\n  k: 1\n  k: 2\n", 3),
                                       ("{a: 1, b: 2, a: 1}", 1), ("- {n: 1}\n- {n: 1, n: 2}\n", 2)])
def test_yaml_duplicate_keys_are_refused_with_their_line(text, line):
    with pytest.raises(YamlError) as e:
        load_yaml(text, is_text=True, name="s.yaml")
    assert str(e.value).startswith("s.yaml: duplicate key") and f"line {line}" in str(e.value)


def test_yaml_merge_keys_and_a_few_aliases_are_fine():
    d = load_yaml("base: &b {x: 1, y: 2}\nthis: {<<: *b, y: 3}\nl: [*b, *b]\n", is_text=True)
    assert d["this"] == {"x": 1, "y": 3} and d["l"] == [{"x": 1, "y": 2}] * 2


def test_yaml_alias_limits():
    many = "v: &v 1\nl: [" + ", ".join(["*v"] * (MAX_ALIASES + 1)) + "]\n"
    with pytest.raises(YamlError, match="aliases"):
        load_yaml(many, is_text=True)
    # a "billion laughs" with few aliases: the expansion is counted
    bomb = "a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"a{j}: &a{j} [" + ", ".join([f"*a{j - 1}"] * 10) + "]\n" for j in range(1, 7))
    assert 6 * 10 <= MAX_ALIASES
    with pytest.raises(YamlError, match=f"the maximum is {MAX_NODES}"):
        load_yaml(bomb, is_text=True)
    with pytest.raises(YamlError, match="contains it"):
        load_yaml("a: &a [1, *a]\n", is_text=True)


def test_yaml_depth_limit():
    ok = "[" * (MAX_DEPTH - 1) + "]" * (MAX_DEPTH - 1)
    load_yaml(ok, is_text=True)
    with pytest.raises(YamlError, match="nested deeper"):
        load_yaml("[" * 100_000 + "]" * 100_000, is_text=True)
    with pytest.raises(YamlError, match="nested deeper"):
        load_yaml("".join(f"{' ' * j}k{j}:\n" for j in range(MAX_DEPTH + 5)) + " " * (MAX_DEPTH + 5) + "v: 1\n",
                  is_text=True)


def test_yaml_files(tmp_path):
    (tmp_path / "bom.yaml").write_bytes("\ufeffa: 1\n".encode("utf-8"))
    assert load_yaml(tmp_path / "bom.yaml") == {"a": 1}
    (tmp_path / "latin1.yaml").write_bytes("a: caf\xe9\n".encode("latin-1"))
    with pytest.raises(YamlError, match="not UTF-8"):
        load_yaml(tmp_path / "latin1.yaml")
    (tmp_path / "bin.yaml").write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00")
    with pytest.raises(YamlError, match="binary"):
        load_yaml(tmp_path / "bin.yaml")
    with pytest.raises(YamlError, match="directory"):
        load_yaml(tmp_path)
    with pytest.raises(YamlError, match="does not exist"):
        load_yaml(tmp_path / "nope.yaml")


def test_leg_limit_matches_the_description_reader():
    from parasynth.mechanisms.description.anchors import MAX_PATTERN_POINTS
    from parasynth.common.validation import MAX_LEGS

    assert MAX_LEGS == MAX_PATTERN_POINTS
