"""Mechanisms described in YAML: the paper models defined by their packaged descriptions and
their variants (checked against closed forms and the papers' numbers), the expression
evaluator, loading by file name and path, and use in studies."""

from __future__ import annotations

import copy
import dataclasses
import math
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import parasynth
from parasynth.mechanisms import mechanism_class, packaged_descriptions, resolve_mechanism_name
from parasynth.mechanisms.description import (DescribedMechanism, DescriptionError, DescriptionWarning, Expression,
                                              from_description)

PKG = Path(parasynth.__file__).parent / "mechanisms"
MM = 1e-3
DEG = np.pi / 180


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


# -- the paper models are their packaged descriptions ---------------------------------------------
@pytest.mark.parametrize("name", ["5pus_upu", "2rpu_2sps", "4ups_1rps"])
def test_paper_model_is_the_class_of_its_packaged_description(name):
    cls = mechanism_class(name)
    assert issubclass(cls, DescribedMechanism)
    assert cls is mechanism_class(f"{name}.yaml")  # the bare file name: the same description
    assert cls.name == name and cls.description.source == f"{name}.yaml"
    m = parasynth.load_mechanism(name)
    assert type(m) is cls and m.name == name
    assert name + "_yaml" not in parasynth.list_mechanisms()


# Slider heights at home of the 5-PUS/UPU (platform centre at the origin, level): the sphere
# S_i in the plane z = 0 and the universal joint U_i above it on the slider line through
# R (cos a_i, sin a_i), so s_i = sqrt(L^2 - |U_i - S_i|_xy^2).
def _slider_heights(R, L, angles, spheres_xy):
    U = R * np.c_[np.cos(angles), np.sin(angles)]
    return np.sqrt(L**2 - np.sum((U - np.asarray(spheres_xy)) ** 2, axis=1))


SCHEME1 = np.array([[35, 51], [-35, 51], [-51, -35], [51, -35], [0, 51]]) * MM
SCHEME2 = np.array([[40, 40], [-40, 40], [-40, -40], [40, -40], [0, 40]]) * MM
SLIDERS = np.deg2rad([18.0, 162.0, 234.0, 306.0, 90.0])


def test_5pus_upu_variants_against_closed_forms():
    m = parasynth.load_mechanism("5pus_upu")
    assert (m.params.platform, m.params.hinge_layout) == ("rectangular", "scheme1")
    q = m.inverse_kinematics(m.home).actuators
    # docs/models/5pus_upu.md: 182.2543, 182.2543, 188.9789, 188.9789, 187.0000 mm
    np.testing.assert_allclose(q / MM, [182.2543, 182.2543, 188.9789, 188.9789, 187.0000], atol=5e-5)
    np.testing.assert_allclose(q, _slider_heights(0.135, 0.205, SLIDERS, SCHEME1), atol=1e-14)
    pent = parasynth.load_mechanism("5pus_upu", platform="pentagonal")
    r = pent.params.pentagon_radius
    assert r == pytest.approx(0.062)
    sph = r * np.c_[np.cos(SLIDERS), np.sin(SLIDERS)]
    np.testing.assert_allclose([leg.platform[:2] for leg in pent.legs[:5]], sph, atol=1e-15)
    np.testing.assert_allclose(pent.inverse_kinematics(pent.home).actuators / MM, [191.5620] * 5, atol=5e-5)
    # The pentagon ignores the hinge-layout transforms (they belong to the rectangular platform).
    pent2 = parasynth.load_mechanism("5pus_upu", platform="pentagonal", hinge_layout="scheme2", hinge_scale=1.3)
    np.testing.assert_allclose([leg.platform for leg in pent2.legs], [leg.platform for leg in pent.legs], atol=0)
    # The structural singularity of the first scheme (Section 2.3) at the centred level pose.
    assert pent.singularity_margin(pent.home) < 1e-9 < m.singularity_margin(m.home)
    # scheme2 (assumed coordinates), scaled, rotated and shifted: points by hand.
    k, th, dy = 1.2, 10 * DEG, 4 * MM
    s2 = parasynth.load_mechanism("5pus_upu", hinge_layout="scheme2", hinge_scale=k, hinge_rotation=th,
                                  hinge_shift_y=dy)
    c, s = np.cos(th), np.sin(th)
    pts = k * SCHEME2 @ np.array([[c, s], [-s, c]]) + [0.0, dy]
    np.testing.assert_allclose([leg.platform[:2] for leg in s2.legs[:5]], pts, atol=1e-15)
    np.testing.assert_allclose(s2.inverse_kinematics(s2.home).actuators,
                               _slider_heights(0.135, 0.205, SLIDERS, pts), atol=1e-14)
    # custom: hinge_points
    pts = SCHEME1 * 0.9
    cu = parasynth.load_mechanism("5pus_upu", hinge_layout="custom", hinge_points=tuple(map(tuple, pts)))
    np.testing.assert_allclose(cu.inverse_kinematics(cu.home).actuators,
                               _slider_heights(0.135, 0.205, SLIDERS, pts), atol=1e-14)
    # hinge_points only acts in the custom layout
    s1 = parasynth.load_mechanism("5pus_upu", hinge_points=tuple(map(tuple, pts)))
    np.testing.assert_allclose(s1.inverse_kinematics(s1.home).actuators, q, atol=0)


def test_5pus_upu_orientation_is_the_limb_consistent_one():
    """R = Ry(q1) Rx(alpha) Ry(beta - q1), q1 = atan2(x, z - upu_base_z) (scipy rotations)."""
    m = parasynth.load_mechanism("5pus_upu")
    X = _poses(m, [0.05, 0.05, 0.08, 0.3, 0.3])[:-1]
    q1 = np.arctan2(X[:, 0], X[:, 2] + 0.15)
    R = Rotation.from_euler("YXY", np.c_[q1, X[:, 3], X[:, 4] - q1]).as_matrix()
    p, Rm = m.pose(X)
    np.testing.assert_allclose(Rm, R, atol=1e-14)
    np.testing.assert_allclose(p, X[:, :3], atol=0)


def _2rpu_lengths(P, x, z, psi, theta):
    """|p + R a_i - b_i| with R = Ry(theta) Rx(psi) (eq. (1) with phi = 0), p = (x, 0, z)."""
    a1, a2, a3, a4, b1, b2, b3, b4 = P
    A = np.array([[0, -a1, 0], [a2, 0, 0], [0, a3, 0], [-a4, 0, 0]])
    B = np.array([[0, -b1, 0], [b2, 0, 0], [0, b3, 0], [-b4, 0, 0]])
    R = Rotation.from_euler("YX", np.c_[theta, psi]).as_matrix()
    p = np.c_[x, np.zeros_like(x), z]
    return np.linalg.norm(p[:, None, :] + np.einsum("nij,kj->nki", R, A) - B[None], axis=-1)


def test_2rpu_2sps_coupled_switch_against_closed_forms():
    """coupled=True: x = z tan(theta) (eq. (10)); coupled=False: x a fourth coordinate. Leg
    lengths against eq. (11) written out; both variants agree where x = z tan(theta)."""
    P = (0.16, 0.08, 0.15, 0.075, 0.55, 0.36, 0.5, 0.35)
    kw = dict(zip(("a1", "a2", "a3", "a4", "b1", "b2", "b3", "b4"), P))
    c = parasynth.load_mechanism("2rpu_2sps", **kw)
    f = parasynth.load_mechanism("2rpu_2sps", coupled=False, **kw)
    assert c.task_coordinates == ("z", "psi", "theta") and f.task_coordinates == ("x", "z", "psi", "theta")
    assert c.params.coupled is True and f.params.coupled is False
    np.testing.assert_allclose(f.home, [0.75 * np.tan(15 * DEG), 0.75, 0.0, 15 * DEG], atol=1e-15)
    assert list(f.default_ranges()) == ["x", "z", "psi", "theta"]
    assert f.default_ranges()["x"] == pytest.approx((-0.6, 0.6))
    assert list(c.default_ranges()) == ["z", "psi", "theta"]
    rng = np.random.default_rng(1)
    Xf = f.home + rng.uniform(-1, 1, (200, 4)) * [0.2, 0.2, 0.5, 0.6]
    qf = f.inverse_kinematics(Xf)
    np.testing.assert_allclose(qf.actuators[qf.reachable], _2rpu_lengths(P, *Xf.T)[qf.reachable], atol=1e-14)
    assert 0.3 < qf.reachable.mean() <= 1.0
    Xc = Xf[:, 1:]
    x = Xc[:, 0] * np.tan(Xc[:, 2])
    np.testing.assert_allclose(c.x_of(Xc), x, atol=1e-15)
    np.testing.assert_allclose(f.x_of(Xf), Xf[:, 0], atol=0)
    qc = c.inverse_kinematics(Xc)
    np.testing.assert_allclose(qc.actuators[qc.reachable], _2rpu_lengths(P, x, *Xc.T)[qc.reachable], atol=1e-14)
    # The uncoupled model has the four true freedoms, consistently described; FK inverts IK.
    with warnings.catch_warnings():
        warnings.simplefilter("error", DescriptionWarning)
        mob = f.mobility()
    assert (mob.dof, mob.type, mob.controlled, mob.issues) == (4, "2T2R", True, ())
    Xr = Xf[:20][qf.reachable[:20]]
    np.testing.assert_allclose(f.forward_kinematics(f.inverse_kinematics(Xr).actuators, guess=Xr + 1e-3), Xr,
                               atol=1e-9)
    # Constraints by coordinate name follow the variant's columns.
    assert f.constraints["theta_range"].index == 3 and c.constraints["theta_range"].index == 2


def test_4ups_1rps_geometry_and_grinding_point_against_closed_forms():
    from parasynth.mechanisms.extras import grinding_u_angles

    m = parasynth.load_mechanism("4ups_1rps", u_phase=0.1, base_offset=-0.1)
    P = m.params
    ua = P.u_phase - P.mu1 / 2 + np.array([0.0, P.mu1, P.mu1 + P.mu2, 2 * P.mu1 + P.mu2])
    np.testing.assert_allclose(grinding_u_angles(P), ua, atol=1e-15)
    U = np.c_[P.base_radius * np.cos(ua), np.full(4, P.base_offset), P.base_radius * np.sin(ua)]
    np.testing.assert_allclose([leg.base for leg in m.legs[:4]], U, atol=1e-15)
    sa = np.deg2rad([-45.0, 45.0, 135.0, 225.0])
    S = P.platform_radius * np.c_[np.cos(sa), np.zeros(4), np.sin(sa)]
    np.testing.assert_allclose([leg.platform for leg in m.legs[:4]], S, atol=1e-15)
    np.testing.assert_allclose(m.legs[4].base, [0.0, -0.05, 0.0], atol=0)
    X = _poses(m, [0.1, 0.1, 1.0, 0.3, 1.0])[:-1]
    R = Rotation.from_euler("ZYZ", X[:, 2:]).as_matrix()
    p = np.c_[X[:, :2], np.zeros(len(X))]
    G = p + R @ np.array([0.0, P.y_t, 0.0])
    np.testing.assert_allclose(m.grinding_point(X), G, atol=1e-15)
    np.testing.assert_allclose(m.grinding_point(np.array([0.0, 0.42, 0, 0, 0])), [0.0, 0.495, 0.0], atol=1e-15)
    q = m.inverse_kinematics(X)
    L = np.linalg.norm(p[:, None, :] + np.einsum("nij,kj->nki", R, S) - U[None], axis=-1)
    np.testing.assert_allclose(q.actuators[q.reachable], L[q.reachable], atol=1e-14)
    # phi_o of eq. (9): the platform y axis against the centre's position vector.
    phi_o = np.arccos(np.clip(np.sum(R[:, :, 1] * p, -1) / np.linalg.norm(p, axis=1), -1, 1))
    mg = m.constraint_margins(X, "sphere_constraint")["sphere_constraint"]
    ok = q.reachable
    np.testing.assert_allclose(mg[ok], (P.sphere_max - phi_o)[ok], atol=1e-12)


@pytest.mark.parametrize("name, expected", [
    ("5pus_upu", {"slider_radius": "length", "link_length": "length", "platform": None, "hinge_layout": None,
                  "hinge_points": "length", "hinge_scale": "dimensionless", "hinge_rotation": "angle",
                  "hinge_shift_y": "length", "pentagon_radius": "length", "slider_angles": "angle",
                  "upu_base_z": "length", "slider_min": "length", "slider_max": "length", "sphere_max": "angle",
                  "ujoint_max": "angle", "link_diameter": "length", "link_modulus": "pressure"}),
    ("2rpu_2sps", {**{k: "length" for k in ("a1", "a2", "a3", "a4", "b1", "b2", "b3", "b4", "q_min", "q_max",
                                           "leg_diameter")}, "psi_max": "angle", "theta_max": "angle",
                   "leg_modulus": "pressure", "coupled": None}),
    ("4ups_1rps", {**{k: "length" for k in ("platform_radius", "base_radius", "l_s0", "y_t", "base_offset", "l_min",
                                           "l_max", "d2_min", "d2_max", "leg_diameter")},
                   **{k: "angle" for k in ("mu1", "mu2", "u_phase", "platform_angles", "theta1_max", "sphere_max",
                                           "ujoint_max")}, "leg_modulus": "pressure"}),
])
def test_paper_model_parameters_and_units(name, expected):
    """Every parameter of the paper models keeps its name and quantity kind (studies, CLI
    ``--param`` and YAML files use them); variants are fields with kind None."""
    cls = mechanism_class(name)
    assert dict(cls.Params.UNITS) == expected
    assert {f.name for f in dataclasses.fields(cls.Params)} == set(expected)


def test_paper_model_defaults_are_the_papers():
    p = mechanism_class("5pus_upu").Params()
    assert (p.slider_radius, p.link_length, p.link_diameter, p.slider_max - p.slider_min) == \
        pytest.approx((0.135, 0.205, 0.008, 0.205))
    np.testing.assert_allclose(p.hinge_points, SCHEME1, atol=1e-15)
    np.testing.assert_allclose(p.slider_angles, SLIDERS, atol=1e-15)
    q = mechanism_class("2rpu_2sps").Params()
    assert (q.a1, q.a2, q.b1, q.b2, q.q_min, q.q_max, q.psi_max, q.theta_max) == \
        pytest.approx((0.15, 0.075, 0.55, 0.35, 0.7, 1.0, 30 * DEG, 45 * DEG))
    g = mechanism_class("4ups_1rps").Params()
    assert (g.base_radius, g.platform_radius, g.mu1, g.mu2, g.l_min, g.l_max, g.d2_min, g.d2_max, g.y_t) == \
        pytest.approx((0.335, 0.1, 53 * DEG, 127 * DEG, 0.43, 0.68, 0.32, 0.55, 0.075))


def test_variant_instances_share_one_parsed_description_per_choice():
    cls = mechanism_class("5pus_upu")
    a = cls(cls.Params(link_length=0.21))
    b = cls(cls.Params(link_length=0.22))
    c = cls(cls.Params(platform="pentagonal"))
    assert a.description is b.description is cls.description
    assert c.description is not a.description
    assert c.description is cls(cls.Params(platform="pentagonal", slider_radius=0.14)).description
    assert c.description.selection == {"hinge_layout": "scheme1", "platform": "pentagonal"}
    assert a.with_params(platform="pentagonal").description is c.description


def test_extras_trajectory_eq13_closed_form():
    from parasynth.mechanisms.extras import trajectory_eq13

    t = np.linspace(0.0, 10.0, 11)
    X, Xd, Xdd = trajectory_eq13(t)
    u = np.pi / 3 + np.pi * t / 30
    np.testing.assert_allclose(X[:, 1:3], 0.05 * np.c_[np.cos(u), -np.sin(u)], atol=1e-16)
    h = 1e-6
    Xp, Xm = trajectory_eq13(t + h)[0], trajectory_eq13(t - h)[0]
    np.testing.assert_allclose(Xd, (Xp - Xm) / (2 * h), atol=1e-9)
    np.testing.assert_allclose(Xdd, (trajectory_eq13(t + h)[1] - trajectory_eq13(t - h)[1]) / (2 * h), atol=1e-9)
    assert np.all(X[:, [0, 3, 4]] == 0)
    assert trajectory_eq13(t, attitude_follows_curve=True)[0][:, 3] == pytest.approx(u)


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
    from parasynth.measures import objectives

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


def test_home_pose_shared_only_by_designs_with_the_same_task_inputs():
    """Designs that change only leg geometry reuse the checked home pose; one that changes a
    parameter the task expressions name (upu_base_z) gets its own. Either way the legs' neutral
    directions and the home pose are bit for bit those of a fresh build (memo emptied)."""
    cls = mechanism_class("5pus_upu")
    designs = [{}, {"link_length": 0.19}, {"slider_radius": 0.12}, {"upu_base_z": -0.17},
               {"upu_base_z": -0.17, "link_length": 0.21}]

    def state(m):
        p, R = m._pose(m.home[None, :])
        return [p, R] + [np.r_[leg.base_ref, leg.platform_ref] for leg in m.legs]

    cached = []
    cls._HOME_POSES = {}
    for d in designs:
        cached.append(state(cls(cls.Params(**d))))
    hits = len(cls._HOME_POSES)
    assert hits == 2  # the default task inputs and upu_base_z = -0.17 m
    for d, want in zip(designs, cached):
        cls._HOME_POSES = {}
        got = state(cls(cls.Params(**d)))
        assert all(np.array_equal(a, b) for a, b in zip(got, want))
    # the key holds the task's inputs exactly: -0.0 and 0.0 differ, as atan2 tells them apart
    m = cls(cls.Params())
    assert m._home_pose_key(m.home) != m._home_pose_key(-0.0 * m.home + np.where(m.home == 0, -0.0, 0.0))


def test_parameter_values_kept_per_exact_inputs():
    """A geometry value computed before for the same float64 inputs is given again; a zero input
    is kept with its sign (0.0 == -0.0, but atan2 tells them apart), a list parameter by its
    values, and other types are always computed."""
    from parasynth.mechanisms.description.expressions import _Scope
    from parasynth.mechanisms.description.parameters import _Scalar

    s = _Scalar("atan2(a, b) * 1 rad", "angle", "t", _Scope(("parameters", ("a", "b")), kinds={"a": "length", "b": "length"}))
    f64 = np.float64
    assert s({"a": f64(1.0), "b": f64(2.0)}) == np.arctan2(1.0, 2.0)
    assert len(s._memo) == 1 and s({"a": f64(1.0), "b": f64(2.0)}) == np.arctan2(1.0, 2.0)
    for _ in range(2):  # computed, then given again: each zero with its sign
        assert s({"a": f64(0.0), "b": f64(-1.0)}) == np.pi and s({"a": f64(-0.0), "b": f64(-1.0)}) == -np.pi
    assert len(s._memo) == 3
    assert s({"a": 1.0, "b": f64(3.0)}) == np.arctan2(1.0, 3.0)
    assert len(s._memo) == 3  # the Python float was not kept
    with pytest.raises(DescriptionError, match="t"):
        s({"a": f64(1.0)})
    from parasynth.mechanisms.description.parameters import values_key

    assert values_key({"a": f64(0.0)}, ("a",)) != values_key({"a": f64(-0.0)}, ("a",))
    v = np.array([0.1, -0.0])
    assert values_key({"v": v}, ("v",)) == values_key({"v": v.copy()}, ("v",)) != values_key({"v": np.abs(v)}, ("v",))
    assert values_key({"v": v}, ("v",)) != values_key({"v": v.reshape(2, 1)}, ("v",))
    assert values_key({"a": f64(1.0)}, ("a", "b")) is None and values_key({"a": 1}, ("a",)) is None


def _scaled(v, rng, lists: bool):
    """A single value changed by up to 2 % (``lists`` False) or each entry of a list parameter (True)."""
    if isinstance(v, float) and not lists:
        return v * (1.0 + 0.02 * rng.uniform(-1, 1))
    if lists and isinstance(v, tuple) and all(isinstance(x, float) for x in np.ravel(v)):
        return tuple(np.asarray(v) * (1.0 + 0.02 * rng.uniform(-1, 1, np.shape(v))))
    return v


def _shipped_anchor_sets(rng, designs: int):
    """(description name, parameter environment, its anchor sets) of ``designs`` random designs
    of every shipped description: every parameter scaled a little (the defaults' checks hold
    for small changes), the single values changed in one design, the lists in the next."""
    import parasynth
    from parasynth.mechanisms import list_mechanisms
    from parasynth.mechanisms.description.parameters import _param_env

    for name in list_mechanisms():
        cls = type(parasynth.load_mechanism(name))
        d = getattr(cls, "description", None)
        if d is None:
            continue
        sets = list(d.base_sets.values()) + list(d.plat_sets.values())
        defaults = cls.Params()
        for k in range(designs):
            kw = {f.name: _scaled(getattr(defaults, f.name), rng, lists=k % 2 == 1) for f in dataclasses.fields(defaults)}
            try:
                env = _param_env(cls.Params(**kw), d.params)
            except ValueError:
                continue
            yield name, env, sets


def test_anchor_sets_kept_per_their_inputs_give_each_call_its_own_arrays():
    """A base or platform set built before for the same values of the parameters it reads (its
    expressions' names, its list parameter) is given again as arrays of its own; for random
    designs of every shipped description each set equals a fresh build, before and after the
    others (a parameter the key left out would give a stale set)."""
    rng = np.random.default_rng(11)
    for name, env, sets in _shipped_anchor_sets(rng, 6):
        for s in sets:
            for _ in range(2):
                got, want = s.build(env), s._build(env)
                for a, b in zip((got.points, got.radial, got.tangent, got.normal),
                                (want.points, want.radial, want.tangent, want.normal)):
                    assert np.array_equal(a, b), (name, s.name)
            got.points[:] = np.nan  # the caller's own arrays
            assert np.array_equal(s.build(env).points, want.points)


def _array_form_anchors(s, env):
    """An anchor set's points and directions as arrays (the pattern's points, scaled, turned,
    shifted; the norms, unit vectors and directions of the whole set at once), written apart
    from the set's own build."""
    i1, i2, i3 = s.axes
    off = s.offset(env)
    if s.pattern == "points":
        rows = np.asarray(env[s.points_param.name], float) if s.points_param is not None else \
            [[v(env) for v in row] for row in s.point_rows]
        P = []
        for row in rows:
            v = np.zeros(3)
            if len(row) == 3:
                v[:] = row
            else:
                v[i1], v[i2], v[i3] = row[0], row[1], off
            P.append(v)
        P = np.array(P)
    else:
        if s.pattern == "rectangle":
            a, b = 0.5 * s.length(env), 0.5 * s.width(env)
            ab = np.array([[a, b], [-a, b], [-a, -b], [a, -b]])
        else:
            if s.pattern == "circle":
                ang = (np.asarray(env[s.angles_param.name], float) if s.angles_param is not None
                       else np.array([a(env) for a in s.angles]))
                r = s.radius(env)
            else:
                r, ph = s.radius(env), s.phase(env)
                centres = ph + 2 * np.pi * np.arange(s.n) / s.n
                ang = (np.column_stack([centres - 0.5 * s.separation(env), centres + 0.5 * s.separation(env)]).ravel()
                       if s.pattern == "paired" else centres)
            ab = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
        P = np.zeros((len(ab), 3))
        P[:, i1], P[:, i2], P[:, i3] = ab[:, 0], ab[:, 1], off
    sc, rot = s.scale(env), s.rotation(env)
    if sc != 1.0 or rot != 0.0:
        a, b = sc * P[:, i1], sc * P[:, i2]
        P[:, i1], P[:, i2] = np.cos(rot) * a - np.sin(rot) * b, np.sin(rot) * a + np.cos(rot) * b
    P = P + np.array([v(env) for v in s.shift])
    e = np.eye(3)
    ab = P[:, [i1, i2]]
    n = np.linalg.norm(ab, axis=1, keepdims=True)
    u = np.divide(ab, n, out=np.zeros_like(ab), where=n > 1e-15)
    return P, u[:, :1] * e[i1] + u[:, 1:] * e[i2], -u[:, 1:] * e[i1] + u[:, :1] * e[i2], e[i3]


_PATTERN_SETS = """
name: pattern_sets
parameters:
  r: {value: 200 mm}
  sep: {value: 20 deg}
  turn: {value: 7 deg}
  grow: {value: 1.2}
  dz: {value: 5 mm}
  pts: {value: [[10 mm, 0 mm], [0 mm, 0 mm], [-40 mm, 30 mm], [5 mm, -7 mm], [0 mm, 9 mm], [-3 mm, -3 mm]]}
base:
  A: {pattern: paired, n: 3, radius: r, separation: sep, phase: turn, rotation: turn, scale: grow}
  B: {pattern: polygon, n: 6, radius: 0.5 * r, plane: yz, offset: dz, shift: [dz, 0 mm, -dz]}
  C: {pattern: rectangle, length: r, width: 0.4 * r, plane: zx, rotation: -turn}
  D: {pattern: points, points: pts, scale: grow, shift: [0 mm, dz, 0 mm]}
  E: {pattern: circle, radius: r, angles: [0 deg, 90 deg, 200 deg, 300 deg, 45 deg, 123 deg], offset: -dz}
platform:
  a: {pattern: points, points: [[0 mm, 0 mm, 1 mm], [30 mm, 0 mm], [0 mm, 30 mm], [-30 mm, 0 mm], [0 mm, -30 mm], [9 mm, 9 mm]]}
"""


def test_anchor_sets_built_in_floats_are_the_array_forms():
    """Every anchor set (each pattern, plane, scale, rotation, shift; points on the plane's
    axis) built in Python floats equals, bit for bit, the same operations on whole arrays:
    every shipped description's sets at random designs and a description with one set of each
    pattern."""
    from parasynth.mechanisms.description.parameters import _param_env

    rng = np.random.default_rng(5)
    spec = yaml.safe_load(_PATTERN_SETS)
    spec["legs"] = [{"type": "SPS", "name": f"s{i}", "base": f"{k}[{j}]", "platform": f"a[{i}]"}
                    for i, (k, j) in enumerate([("A", 0), ("B", 1), ("C", 2), ("D", 3), ("E", 4), ("A", 5)])]
    spec["task"] = yaml.safe_load("""
      coordinates: {x: length, y: length, z: length, alpha: angle, beta: angle, gamma: angle}
      position: [x, y, z]
      orientation: {convention: xyz, angles: [alpha, beta, gamma]}
      home: {x: 0 mm, y: 0 mm, z: 300 mm, alpha: 0 deg, beta: 0 deg, gamma: 0 deg}
    """)
    checked, patterns = 0, set()
    for name, env, sets in _shipped_anchor_sets(rng, 4):
        for s in sets:
            got = s._build(env)
            for a, b in zip((got.points, got.radial, got.tangent, got.normal), _array_form_anchors(s, env)):
                assert a.tobytes() == np.asarray(b, float).tobytes(), (name, s.name)
            checked += 1
            patterns.add(s.pattern)
    assert checked > 40 and {"circle", "paired", "polygon", "points"} <= patterns
    from parasynth.mechanisms.description import description_class
    cls = description_class(spec)
    d = cls.description
    on_axis = 0
    for k in range(10):
        env = dict(_param_env(cls.Params(), d.params))
        if k:
            env.update(r=rng.uniform(0.05, 0.5), sep=rng.uniform(-1, 1), turn=rng.uniform(-4, 4),
                       grow=rng.uniform(0.5, 2), dz=rng.uniform(-0.1, 0.1))
        for s in list(d.base_sets.values()) + list(d.plat_sets.values()):
            got = s._build(env)
            want = _array_form_anchors(s, env)
            for a, b in zip((got.points, got.radial, got.tangent, got.normal), want):
                assert a.tobytes() == np.asarray(b, float).tobytes(), s.name
            on_axis += int(not got.radial.any(axis=1).all())
    assert on_axis == 10  # the platform's first point lies on its plane's axis: no direction there


def test_anchor_directions_are_the_in_plane_units_in_arrays_of_each_calls_own():
    """The radial and tangent directions of anchor points in their set's plane (the unit
    in-plane vector, turned a quarter about the plane's normal; zero on the axis): a second
    call gives the same values in arrays of its own."""
    from parasynth.mechanisms.description.anchors import _PLANES, _float_directions

    rng = np.random.default_rng(4)
    for plane, (i1, i2, i3) in _PLANES.items():
        P = rng.uniform(-1, 1, (5, 3))
        P[4, [i1, i2]] = 0.0  # on the plane's axis
        for _ in range(2):
            a = _float_directions(P.tolist(), (i1, i2, i3))
            assert np.array_equal(a.points, P)
            for k in range(4):
                u = P[k, [i1, i2]] / math.hypot(P[k, i1], P[k, i2])
                assert np.allclose(a.radial[k, [i1, i2]], u, rtol=0, atol=1e-15) and a.radial[k, i3] == 0
                assert np.allclose(a.tangent[k, [i1, i2]], [-u[1], u[0]], rtol=0, atol=1e-15)
            assert not a.radial[4].any() and not a.tangent[4].any()
            assert a.normal.tolist() == np.eye(3)[i3].tolist()
            a.points[:] = 7.0  # the caller's arrays: the next call is not changed
            a.radial[:] = 7.0
            a.normal[:] = 7.0


_GROUP_LEGS = """
name: group_legs
parameters:
  r: {value: 200 mm}
  rp: {value: 60 mm}
  L: {value: 400 mm}
  tilt: {value: 0.1}
base:
  B: {pattern: paired, n: 3, radius: r, separation: 20 deg}
  C: {pattern: points, points: [[40 mm, 10 mm], [100 mm, 0 mm], [0 mm, 120 mm]]}
platform:
  P: {pattern: paired, n: 3, radius: rp, separation: 70 deg, phase: 60 deg}
  P2: {pattern: paired, n: 3, radius: rp, separation: 20 deg}
  Q: {pattern: polygon, n: 3, radius: rp, plane: xz}
legs:
  - {type: PUS, base: B, platform: P, link_length: L, slider_axis: [tilt, 0, 1], u_axis: -tangent, names: [a1, a2, a3, a4, a5, a6]}
  - {type: UPS, base: C, platform: Q, u_axis: radial, names: [u1, u2, u3]}
  - {type: RPS, base: "B[0, 2, 4]", platform: "P2[0, 2, 4]", r_axis: tangent, names: [r1, r2, r3]}
  - {type: RPU, base: "C[1]", platform: [10 mm, 0 mm, 0 mm], r_axis: y, u_platform_axis: -x, name: q1}
  - {type: UPU, base: C, platform: "Q[2, 1, 0]", u_axis: normal, names: [w1, w2, w3]}
  - {type: UPU, base: "C[1]", platform: "Q[1]", name: w4}
  - {type: SPS, base: B, platform: P, names: [s1, s2, s3, s4, s5, s6]}
task:
  coordinates: {x: length, y: length, z: length, alpha: angle, beta: angle, gamma: angle}
  position: [x, y, z]
  orientation: {convention: xyz, angles: [alpha, beta, gamma]}
  home: {x: 0 mm, y: 0 mm, z: 300 mm, alpha: 0 deg, beta: 0 deg, gamma: 0 deg}
"""


def _leg_fields_equal(got, want) -> bool:
    """Two legs of the same type with the same fields, arrays to the bit."""
    if type(got) is not type(want) or vars(got).keys() != vars(want).keys():
        return False
    for k, v in vars(want).items():
        g = vars(got)[k]
        if isinstance(v, np.ndarray):
            if not (isinstance(g, np.ndarray) and g.dtype == v.dtype and g.shape == v.shape and g.tobytes() == v.tobytes()):
                return False
        elif type(g) is not type(v) or g != v:
            return False
    return True


def _group_build_off(monkeypatch):
    from parasynth.model.legs import LEG_TYPES
    for cls in LEG_TYPES.values():
        if cls.__dict__.get("group_built"):
            monkeypatch.setattr(cls, "group_built", False)


def test_leg_groups_built_in_floats_are_the_legs_their_types_build(monkeypatch):
    """A described group of legs of a type built in floats (``Leg.group_built``: SPS, UPS, PUS,
    RPS, RPU, UPU) gives the legs its type's constructor gives (every field, arrays to the bit;
    the constructor applied to each leg is the reference): every shipped description at random
    designs (lengths, lists changed), and a description with every such type and every kind of
    axis option (a vector of expressions, named, radial, tangent, normal, signs, defaults) over
    whole sets, subsets and inline points. Each leg owns its arrays: a write to one leaves the
    others, and the next build, unchanged."""
    from parasynth.mechanisms.description import description_class
    from parasynth.mechanisms.description.parameters import _param_env

    rng = np.random.default_rng(23)
    cases = []
    for name, env, _ in _shipped_anchor_sets(rng, 6):
        cases.append((type(parasynth.load_mechanism(name)).description, env))
    cls = description_class(yaml.safe_load(_GROUP_LEGS))
    for k in range(8):
        env = dict(_param_env(cls.Params(), cls.description.params))
        if k:
            env.update(r=rng.uniform(0.1, 0.4), rp=rng.uniform(0.02, 0.09), L=rng.uniform(0.2, 0.6),
                       tilt=rng.uniform(-2, 2))
        cases.append((cls.description, env))
    fast = [d.build_geometry(env)[0] for d, env in cases]
    fast_again = [d.build_geometry(env)[0] for d, env in cases]  # the templates kept
    kinds = set()
    with monkeypatch.context() as m:
        _group_build_off(m)
        slow = [d.build_geometry(env)[0] for d, env in cases]
    for (d, _), a, b, c in zip(cases, fast, fast_again, slow):
        assert len(a) == len(c)
        for x, y, z in zip(a, b, c):
            assert _leg_fields_equal(x, z) and _leg_fields_equal(y, z), (d.name, z.name)
            kinds.add(type(z).__name__)
    assert {"SPS", "UPS", "PUS", "RPS", "RPU", "UPU"} <= kinds
    legs = fast[-1]
    arrays = [v for leg in legs for v in vars(leg).values() if isinstance(v, np.ndarray) and v.flags.writeable]
    assert len(arrays) >= 2 * len(legs)
    for i, u in enumerate(arrays):
        for v in arrays[i + 1:]:
            assert not np.shares_memory(u, v)
    before = [dict(vars(leg)) for leg in cases[-1][0].build_geometry(cases[-1][1])[0]]
    for a in arrays:
        a[:] = np.nan
    after = cases[-1][0].build_geometry(cases[-1][1])[0]
    assert all(_leg_fields_equal(type(x)(**{k: v for k, v in b.items() if k in {f.name for f in dataclasses.fields(x)}}), x)
               for x, b in zip(after, before))


@pytest.mark.parametrize("edit, where", [
    ({"slider_axis": [0, 0, 0]}, "the direction must not be zero"),
    ({"slider_axis": "radial"}, "undefined for an anchor on the axis"),
    ({"slider_axis": ["1e400", 0, 1]}, None),
    ({"link_length": "0 mm"}, None),
    ({"link_length": "-5 mm"}, None),
])
def test_leg_groups_built_in_floats_refuse_what_their_types_refuse(monkeypatch, edit, where):
    """A wrong leg option of a group built in floats gives the error its type's constructor
    gives (the same text): a zero or undefined direction, a non-finite axis, a link length that
    is not positive."""
    from parasynth.mechanisms.description import description_class

    spec = yaml.safe_load(_GROUP_LEGS)
    spec["base"]["B"] = {"pattern": "points", "points": [[0, 0], ["100 mm", 0], [0, "100 mm"],
                                                         ["-100 mm", 0], [0, "-100 mm"], ["70 mm", "70 mm"]]}
    spec["legs"][0].update(edit)
    errors = []
    for off in (False, True):
        with monkeypatch.context() as m:
            if off:
                _group_build_off(m)
            try:
                cls = description_class(copy.deepcopy(spec))
                cls()
            except (DescriptionError, ValueError) as e:
                errors.append(str(e))
            else:
                errors.append(None)
    assert errors[0] is not None and errors[0] == errors[1]
    if where is not None:
        assert where in errors[0]


@pytest.mark.parametrize("L, text", [(0.0, "link_length must be a positive length"),
                                     (-0.1, "link_length must be a positive length"),
                                     (float("nan"), "evaluates to nan (not finite)")])
def test_leg_groups_built_in_floats_check_the_shared_options_of_each_design(monkeypatch, L, text):
    """After a design built in floats (its group's template kept), a design whose shared
    option is wrong (a link length that is zero, negative, not a number) is refused with the
    error its type's constructor gives."""
    from parasynth.mechanisms.description import description_class
    from parasynth.mechanisms.description.parameters import _param_env

    errors = []
    for off in (False, True):
        with monkeypatch.context() as m:
            if off:
                _group_build_off(m)
            cls = description_class(yaml.safe_load(_GROUP_LEGS))
            cls()
            d = cls.description
            env = dict(_param_env(cls.Params(), d.params), L=np.float64(L))
            try:
                d.build_geometry(env)
            except DescriptionError as e:
                errors.append(str(e))
            else:
                errors.append(None)
    assert errors[0] is not None and errors[0] == errors[1] and text in errors[0]


def test_constraints_kept_per_the_values_they_read_are_each_designs_own():
    """A described mechanism's constraints are kept per the values of the parameters their
    bounds read: for random designs of every shipped description (single values changed in one
    design, lists in the next) the constraints equal those built one by one, and a design with a
    bound parameter changed gets the changed bound (a name the key left out would give a stale
    constraint)."""
    import parasynth
    from parasynth.mechanisms import list_mechanisms

    rng = np.random.default_rng(17)
    seen = 0
    for name in list_mechanisms():
        cls = type(parasynth.load_mechanism(name))
        defaults = cls.Params()
        for k in range(4):
            kw = {f.name: _scaled(getattr(defaults, f.name), rng, lists=k % 2 == 1) for f in dataclasses.fields(defaults)}
            try:
                mech = cls(cls.Params(**kw))
            except ValueError:
                continue
            d = getattr(mech, "description", None)
            if d is None:
                continue
            want = [c.build(mech) for c in d.constraints]
            got = mech.build_constraints()
            assert [type(c) for c in got] == [type(c) for c in want] and [repr(c) for c in got] == [repr(c) for c in want]
            seen += 1
    assert seen > 20
    m = parasynth.load_mechanism("5pus_upu")
    for hi in (0.29, 0.31, 0.29):
        got = parasynth.load_mechanism("5pus_upu", slider_max=hi).constraints
        assert [c for c in got.values() if getattr(c, "hi", None) == hi], (hi, got)
    assert m.constraints.keys() == got.keys()


def test_pose_expression_columns_are_the_stacked_broadcast_values():
    """The pose's columns (mechanism._columns): each expression's value -- a scalar, an integer,
    an (N,) array or a dual number's value -- broadcast to (N,) as a float column, bit for bit
    what np.stack of the broadcast values gives, and a fresh array."""
    from parasynth.mechanisms.description.expressions import _Dual
    from parasynth.mechanisms.description.mechanism import _columns

    rng = np.random.default_rng(5)
    col = rng.normal(size=7)
    dual = _Dual(rng.normal(size=7), rng.normal(size=(7, 3)))
    vals = [0.25, col, 3, dual, np.float64(-1.5)]
    want = np.stack([np.broadcast_to(v.v if isinstance(v, _Dual) else v, (7,)) for v in vals], -1).astype(float)
    got = _columns(vals, 7)
    assert got.dtype == np.float64 and got.shape == (7, 5)
    assert got.tobytes() == want.tobytes()
    assert not np.shares_memory(got, col)
    assert _columns([], 4).shape == (4, 0)
