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
