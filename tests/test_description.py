"""Mechanisms described in YAML: the seed models' descriptions against the built-in models,
the expression evaluator, loading by file name and path, and use in studies."""

from __future__ import annotations

import copy
import dataclasses
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

import parasynth
from parasynth.mechanisms import mechanism_class, packaged_descriptions, resolve_mechanism_name
from parasynth.mechanisms.description import (DescribedMechanism, DescriptionError, DescriptionWarning, Expression,
                                              from_description)

PKG = Path(parasynth.__file__).parent / "mechanisms"

# (built-in name, description file, changed parameters, half-widths of the pose box around home)
SEEDS = [
    ("2rpu_2sps", "2rpu_2sps.yaml", dict(a1=0.16, b2=0.36, b3=0.5, q_max=0.95, theta_max=np.deg2rad(40.0),
                                         leg_diameter=0.05),
     [0.2, 0.5, 0.6]),
    ("5pus_upu", "5pus_upu.yaml", dict(link_length=0.22, slider_radius=0.14, hinge_scale=1.1, hinge_rotation=0.1,
                                       hinge_shift_y=0.005, upu_base_z=-0.2, sphere_max=0.6,
                                       slider_angles=tuple(np.deg2rad([20.0, 160.0, 230.0, 310.0, 90.0]))),
     [0.06, 0.06, 0.1, 0.45, 0.45]),
    ("4ups_1rps", "4ups_1rps.yaml", dict(base_radius=0.3, platform_radius=0.11, mu1=np.deg2rad(50.0), l_s0=0.06,
                                         u_phase=0.1, base_offset=0.01, l_max=0.6,
                                         platform_angles=tuple(np.deg2rad([-40.0, 45.0, 135.0, 220.0]))),
     [0.15, 0.1, 1.0, 0.6, 1.0]),
]
CASES = [(b, y, {}, s) for b, y, _, s in SEEDS] + [(b, y, p, s) for b, y, p, s in SEEDS]
IDS = [f"{b}-default" for b, *_ in SEEDS] + [f"{b}-changed" for b, *_ in SEEDS]


def _builtin_defaults(builtin, yaml_name) -> dict:
    """The built-in model's current defaults of the parameters both versions have (the
    descriptions carry the same defaults, but the comparison must not depend on it)."""
    cb, cy = mechanism_class(builtin), mechanism_class(yaml_name)
    shared = {f.name for f in dataclasses.fields(cy.Params)} & {f.name for f in dataclasses.fields(cb.Params)}
    P = cb.Params()
    return {k: getattr(P, k) for k in shared}


def _pair(builtin, yaml_name, changes):
    params = {**_builtin_defaults(builtin, yaml_name), **changes}
    return parasynth.load_mechanism(builtin, **changes), parasynth.load_mechanism(yaml_name, **params)


def _poses(mech, half, n=300, seed=0):
    rng = np.random.default_rng(seed)
    X = mech.home + rng.uniform(-1.0, 1.0, size=(n, mech.n_task)) * np.asarray(half)
    X[-1] = np.nan  # a non-finite pose is masked the same way
    return X


def _close(a, b, atol):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    assert np.array_equal(np.isnan(a), np.isnan(b))
    np.testing.assert_allclose(a, b, rtol=0, atol=atol, equal_nan=True)


# -- the seed models: a description reproduces the built-in model ---------------------------------
@pytest.mark.parametrize("builtin, yaml_name, params, half", CASES, ids=IDS)
def test_seed_description_reproduces_builtin(builtin, yaml_name, params, half):
    b, y = _pair(builtin, yaml_name, params)
    assert isinstance(y, DescribedMechanism)
    assert y.task_coordinates == b.task_coordinates
    assert y.angular_coordinates == b.angular_coordinates
    assert y.actuators == b.actuators
    assert [leg.name for leg in y.legs] == [leg.name for leg in b.legs]
    assert [type(leg) for leg in y.legs] == [type(leg) for leg in b.legs]
    np.testing.assert_allclose(y.home, b.home, atol=1e-15)
    assert y.length_scale == pytest.approx(b.length_scale, abs=1e-15)
    for lb, ly in zip(b.legs, y.legs):  # the geometry itself
        np.testing.assert_allclose(ly.base, lb.base, atol=1e-15)
        np.testing.assert_allclose(ly.platform, lb.platform, atol=1e-15)
        assert ly.is_actuated == lb.is_actuated
    X = _poses(b, half)
    pb, Rb = b.pose(X[:-1])
    py, Ry = y.pose(X[:-1])
    _close(py, pb, 1e-14)
    _close(Ry, Rb, 1e-14)
    _close(y.twist_map(X[:-1]), b.twist_map(X[:-1]), 1e-12)
    ib, iy = b.inverse_kinematics(X), y.inverse_kinematics(X)
    assert np.array_equal(iy.reachable, ib.reachable)
    _close(iy.actuators, ib.actuators, 1e-12)
    assert list(iy.passive_angles) == list(ib.passive_angles)
    for k in ib.passive_angles:
        _close(iy.passive_angles[k], ib.passive_angles[k], 1e-10)
    _close(y.jacobian(X), b.jacobian(X), 1e-10)
    _close(y.wrench_matrix(X), b.wrench_matrix(X), 1e-10)
    _close(y.singularity_margin(X), b.singularity_margin(X), 1e-10)
    mb, my = b.constraint_margins(X), y.constraint_margins(X)
    assert list(my) == list(mb)
    assert {c.unit for c in y.constraints.values()} <= {"m", "rad"}
    for k in mb:
        assert y.constraints[k].unit == b.constraints[k].unit
        assert np.array_equal(np.isfinite(my[k]), np.isfinite(mb[k]))
        np.testing.assert_allclose(my[k], mb[k], rtol=0, atol=1e-9)
    fb, fy = b.is_feasible(X), y.is_feasible(X)
    assert np.array_equal(fy, fb)
    assert 0 < fb.mean() < 1  # the box holds feasible and infeasible poses
    rb, ry = b.default_ranges(), y.default_ranges()
    assert list(ry) == list(rb)
    for k in rb:
        np.testing.assert_allclose(ry[k], rb[k], atol=1e-15)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DescriptionWarning)
        mob_y = y.mobility()
    mob_b = b.mobility()
    assert (mob_y.dof, mob_y.type, mob_y.controlled, mob_y.constraint_rank) == \
        (mob_b.dof, mob_b.type, mob_b.controlled, mob_b.constraint_rank)
    assert mob_y.consistent


@pytest.mark.parametrize("builtin, yaml_name", [(b, y) for b, y, *_ in SEEDS])
def test_seed_parameters_have_the_builtin_units(builtin, yaml_name):
    cb, cy = mechanism_class(builtin), mechanism_class(yaml_name)
    shared = {f.name for f in dataclasses.fields(cy.Params)} & {f.name for f in dataclasses.fields(cb.Params)}
    assert len(shared) >= 9
    for k in shared:
        assert cy.Params.UNITS[k] == cb.Params.UNITS[k], k
        assert np.shape(getattr(cy.Params(), k)) == np.shape(getattr(cb.Params(), k)), k


def test_uncoupled_2rpu_2sps_as_a_python_dict():
    """The 2-RPU&2-SPS with its four true freedoms (coupled=False), by editing the dict."""
    data = yaml.safe_load((PKG / "2rpu_2sps.yaml").read_text())
    d = copy.deepcopy(data)
    d["name"] = "2rpu_2sps_uncoupled"
    d["task"].update({
        "coordinates": {"x": "length", "z": "length", "psi": "angle", "theta": "angle"},
        "restricted": False,
        "position": ["x", "0 mm", "z"],
        "home": {"x": "750 mm * tan(15 deg)", "z": "750 mm", "psi": "0 deg", "theta": "15 deg"},
        "ranges": {"x": ["-600 mm", "600 mm"], **data["task"]["ranges"]},
    })
    del d["task"]["valid"]
    y = from_description(d, **{**_builtin_defaults("2rpu_2sps", "2rpu_2sps.yaml"), "a2": 0.08})
    b = parasynth.load_mechanism("2rpu_2sps", coupled=False, a2=0.08)
    X = _poses(b, [0.2, 0.2, 0.5, 0.6])
    _close(y.jacobian(X), b.jacobian(X), 1e-10)
    _close(y.singularity_margin(X), b.singularity_margin(X), 1e-10)
    assert np.array_equal(y.is_feasible(X), b.is_feasible(X))
    assert y.default_ranges().keys() == b.default_ranges().keys()
    with warnings.catch_warnings():
        warnings.simplefilter("error", DescriptionWarning)
        m = y.mobility()
    assert (m.dof, m.type, m.controlled, m.issues) == (4, "2T2R", True, ())
    # Forward kinematics of the square model inverts the inverse kinematics.
    Xr = X[:20][b.inverse_kinematics(X[:20]).reachable]
    q = y.inverse_kinematics(Xr).actuators
    np.testing.assert_allclose(y.forward_kinematics(q, guess=Xr + 1e-3), Xr, atol=1e-9)


def test_orientation_as_a_product_of_rotations():
    """rotations: [...] (any axes) gives the same pose and twist map as the named convention."""
    data = yaml.safe_load((PKG / "5pus_upu.yaml").read_text())
    d = copy.deepcopy(data)
    d["task"]["orientation"] = {"rotations": [{"axis": "y", "angle": "q1"}, {"axis": [2, 0, 0], "angle": "alpha"},
                                              {"axis": [0, 1, 0], "angle": "beta - q1"}]}
    a, b = from_description(data), from_description(d)
    X = _poses(a, [0.05, 0.05, 0.08, 0.4, 0.4])[:-1]
    _close(b.pose(X)[1], a.pose(X)[1], 1e-14)
    _close(b.twist_map(X), a.twist_map(X), 1e-14)


# -- expressions ------------------------------------------------------------------------------------
@pytest.mark.parametrize("text", [
    "__import__('os').system('true')",
    "x.real",
    "(lambda: 1)()",
    "[1, 2]",
    "'abc'",
    "x if x else 1",
    "open('f')",
    "globals()",
    "x[1:2]",
    "sin(x, y)",
    "sin",
    "x == 1",
    "True",
    "f'{x}'",
    "x @ x",
    "-" * 1900 + "1",
    "(" * 300 + "1" + ")" * 300,
])
def test_expression_rejects_anything_but_arithmetic(text):
    with pytest.raises(DescriptionError) as e:
        Expression(text, "where")
    assert str(e.value).startswith("where:")


def test_expression_units_and_names():
    e = Expression("2*r + 5 mm - 1.5 cm", "p")
    assert e.names == {"r"} and e.has_units
    assert float(e({"r": np.float64(0.1)})) == pytest.approx(0.19)
    assert float(Expression("90 deg", "p")({})) == pytest.approx(np.pi / 2)
    assert float(Expression("angles[-1] + angles[0]", "p")({"angles": np.array([1.0, 2.0, 3.0])})) == 4.0
    c = Expression("q_min < q_max <= 2", "p", allow_compare=True)
    assert bool(c({"q_min": 1.0, "q_max": 2.0})) and not bool(c({"q_min": 3.0, "q_max": 2.0}))
    with pytest.raises(DescriptionError, match="not a condition"):
        Expression("q_min", "p", allow_compare=True)


def test_expression_derivatives_are_exact():
    """Dual-number derivatives against central differences."""
    from parasynth.mechanisms.description import _Dual

    text = ("atan2(x, z - 0.1) * sqrt(x**2 + 1) / cos(z) + hypot(x, z) + clip(2*x, -1, 1) + min(x, z)"
            " + max(x**3, z) + exp(-z) * log(2 + x) + abs(x - z) + tan(x) - asin(x/2) + acos(z/3)"
            " + atan(x*z) + 2**z + z**x + tanh(x) + sinh(z) + cosh(x) + 1/(1 + z)")
    e = Expression(text, "p")
    rng = np.random.default_rng(3)
    X = rng.uniform(0.15, 0.6, size=(50, 2))
    eye = np.eye(2)
    env = {"x": _Dual(X[:, 0], np.broadcast_to(eye[0], (50, 2))), "z": _Dual(X[:, 1], np.broadcast_to(eye[1], (50, 2)))}
    d = e(env, dual=True)
    v0 = e({"x": X[:, 0], "z": X[:, 1]})
    np.testing.assert_allclose(d.v, v0, rtol=1e-15)
    h = 1e-6
    for j, name in enumerate("xz"):
        up = {"x": X[:, 0] + h * eye[j, 0], "z": X[:, 1] + h * eye[j, 1]}
        dn = {"x": X[:, 0] - h * eye[j, 0], "z": X[:, 1] - h * eye[j, 1]}
        np.testing.assert_allclose(d.g[:, j], (e(up) - e(dn)) / (2 * h), rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("name", ["2rpu_2sps.yaml", "5pus_upu.yaml", "4ups_1rps.yaml", "gough_stewart_6ups", "3rps",
                                  "3prs"])
def test_twist_map_matches_finite_differences_of_the_pose(name):
    from _support import central_difference, vee

    m = parasynth.load_mechanism(name)
    rng = np.random.default_rng(5)
    step = np.where([c in m.angular_coordinates for c in m.task_coordinates], 0.2, 0.03)
    X = m.home + step * rng.uniform(-1, 1, size=(20, m.n_task))
    if name == "4ups_1rps.yaml":
        X[:, 3] = np.abs(X[:, 3]) + 0.1  # away from the z-y-z angles' beta = 0
    T = m.twist_map(X)
    h = np.full(m.n_task, 1e-6)
    dp = central_difference(lambda Y: m.pose(Y)[0], X, h)
    dR = central_difference(lambda Y: m.pose(Y)[1], X, h)  # (N, 3, 3, n)
    R = m.pose(X)[1]
    w = vee(np.einsum("nijk,nlj->nkil", dR, R))  # dR R^T per coordinate
    np.testing.assert_allclose(T[:, :3], dp, atol=1e-8)
    np.testing.assert_allclose(T[:, 3:], np.moveaxis(w, 1, 2), atol=1e-8)


# -- loading --------------------------------------------------------------------------------------
def test_registry_lists_the_classics_and_packaged_files():
    names = parasynth.list_mechanisms()
    assert {"gough_stewart_6ups", "3rps", "3prs", "2rpu_2sps", "5pus_upu", "4ups_1rps"} <= set(names)
    assert names == sorted(names)
    assert {"2rpu_2sps.yaml", "5pus_upu.yaml", "4ups_1rps.yaml", "gough_stewart_6ups.yaml"} <= set(packaged_descriptions())
    assert mechanism_class("3rps") is mechanism_class("3rps.yaml")  # cached while unchanged
    assert parasynth.load_mechanism("3rps").name == "3rps"


def test_load_by_path_with_parameters(tmp_path):
    p = tmp_path / "sub" / "my_mech.yaml"
    p.parent.mkdir()
    shutil.copy(PKG / "3rps.yaml", p)
    m = parasynth.load_mechanism(str(p), platform_radius=0.12)
    assert m.params.platform_radius == 0.12
    assert m.with_params(platform_radius=0.13).params.platform_radius == 0.13
    assert type(m.with_params(q_max=0.8)) is type(m)
    assert parasynth.load_mechanism(p).name == "3rps"  # a Path works too
    assert resolve_mechanism_name("sub/my_mech.yaml", base_dir=tmp_path) == str(p.resolve())
    assert resolve_mechanism_name("5pus_upu.yaml") == "5pus_upu.yaml"
    assert resolve_mechanism_name("5pus_upu") == "5pus_upu"
    with pytest.raises(ValueError) as e:
        parasynth.load_mechanism(str(p), radius=0.1)
    assert "radius" in str(e.value) and "platform_radius" in str(e.value)
    with pytest.raises(ValueError, match="not found"):
        parasynth.load_mechanism(str(tmp_path / "missing.yaml"))
    with pytest.raises(ValueError) as e:
        parasynth.load_mechanism("nope")
    assert "3rps" in str(e.value) and ".yaml" in str(e.value)


def test_params_dataclass_is_frozen_with_units():
    cls = mechanism_class("gough_stewart_6ups")
    P = cls.Params()
    assert dataclasses.is_dataclass(P)
    with pytest.raises(dataclasses.FrozenInstanceError):
        P.base_radius = 1.0
    assert cls.Params.UNITS["base_radius"] == "length"
    assert cls.Params.UNITS["base_separation"] == "angle"
    assert P.base_separation == pytest.approx(np.deg2rad(20.0))
    with pytest.raises(ValueError, match="l_min < l_max"):
        cls.Params(l_min=1.0)
    with pytest.raises(ValueError, match="base_radius"):
        cls.Params(base_radius=-0.1)  # min: 0 mm
    with pytest.raises(ValueError, match="shape"):
        mechanism_class("5pus_upu.yaml").Params(slider_angles=(0.1, 0.2))


def test_objective_on_a_described_mechanism():
    from parasynth import objectives

    m = parasynth.load_mechanism("3rps")
    v = objectives.get("workspace_volume")(m, n=1024, seed=0)
    assert v > 0
    v2 = objectives.get("workspace_volume")(m.with_params(q_max=0.6), n=1024, seed=0)
    assert v2 < v


def test_study_with_a_user_description(tmp_path):
    from parasynth.study import load_study, run_study

    (tmp_path / "mechs").mkdir()
    shutil.copy(PKG / "3rps.yaml", tmp_path / "mechs" / "tripod.yaml")
    study = {
        "name": "tripod",
        "mechanism": "mechs/tripod.yaml",
        "fixed": {"base_radius": "320 mm"},
        "variables": [{"name": "platform_radius", "values": ["120 mm", "160 mm"]}],
        "objectives": [{"name": "workspace_volume", "goal": "maximize"}],
        "evaluation": {"method": "sobol", "samples": 512, "seed": 0,
                       "ranges": {"z": ["250 mm", "750 mm"], "alpha": ["-40 deg", "40 deg"],
                                  "beta": ["-40 deg", "40 deg"]},
                       "fixed_pose": {}},
        "optimizer": {"kind": "sweep"},
    }
    path = tmp_path / "tripod_study.yaml"
    path.write_text(yaml.safe_dump(study))
    s = load_study(path)
    assert s.mechanism == str((tmp_path / "mechs" / "tripod.yaml").resolve())
    assert s.fixed == {"base_radius": pytest.approx(0.32)}
    assert s.evaluation["ranges"]["alpha"] == pytest.approx((-np.deg2rad(40), np.deg2rad(40)))
    assert s.variables[0].values == pytest.approx((0.12, 0.16))
    again = load_study(s.to_yaml(), is_text=True)  # the run copy finds the description
    assert again.mechanism == s.mechanism
    res = run_study(s, out_dir=tmp_path / "run", progress=False)
    assert res.n_total == 2
    assert [r.status for r in res.new_records] == ["ok", "ok"], [r.error for r in res.new_records]
    assert all(r.objectives["workspace_volume"] > 0 for r in res.new_records)
    # Bad references in a study name the mechanism key.
    bad = dict(study, mechanism="mechs/missing.yaml")
    path.write_text(yaml.safe_dump(bad))
    with pytest.raises(ValueError, match=r"^mechanism: .*not found"):
        load_study(path)
    bad = dict(study, fixed={"base_radius": "320"})
    path.write_text(yaml.safe_dump(bad))
    with pytest.raises(ValueError, match=r"fixed\.base_radius"):
        load_study(path)
