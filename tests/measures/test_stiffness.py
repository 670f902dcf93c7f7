"""Cartesian stiffness: closed forms, a compliant-model equilibrium, bad input and units."""

import math

import numpy as np
import pytest
import yaml
from scipy.optimize import root
from scipy.spatial.transform import Rotation

import parasynth
from parasynth.measures import objectives
from parasynth.measures.stiffness import (STEEL_E, compliance, deflection, part_stiffness, point_deflection,
                                          stiffness_along, stiffness_matrix)
from parasynth.study.spec import StudyError, load_study


def _gough_rows(mech, p, R):
    """Unit leg-line wrenches (f, m_P) computed from the anchors alone."""
    rows, lengths = [], []
    for leg in mech.legs:
        a = R @ np.asarray(leg.platform)
        d = p + a - np.asarray(leg.base)
        L = np.linalg.norm(d)
        n = d / L
        rows.append(np.concatenate([n, np.cross(a, n)]))
        lengths.append(L)
    return np.array(rows), np.array(lengths)


def test_gough_stewart_home_closed_form():
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    X = mech.home
    p, R = np.array([0.0, 0.0, X[2]]), np.eye(3)
    Wr, L = _gough_rows(mech, p, R)
    k = 2e7
    K_ref = k * sum(np.outer(w, w) for w in Wr)
    K = parasynth.stiffness_matrix(mech, X, axial_stiffness=k)
    assert K.shape == (6, 6)
    np.testing.assert_allclose(K, K_ref, rtol=1e-12, atol=1e-12 * np.abs(K_ref).max())
    # Default: steel rod of the leg diameter, k = E A / L (all legs equally long at home).
    d = mech.params.leg_diameter
    k_def = STEEL_E * math.pi * d ** 2 / 4 / L
    K_def = sum(ki * np.outer(w, w) for ki, w in zip(k_def, Wr))
    np.testing.assert_allclose(stiffness_matrix(mech, X), K_def, rtol=1e-12, atol=1e-12 * np.abs(K_def).max())
    # Batched shape.
    assert stiffness_matrix(mech, np.stack([X, X]), axial_stiffness=k).shape == (2, 6, 6)


def test_gough_stewart_vertical_force_deflection():
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    X = mech.home
    Wr, L = _gough_rows(mech, np.array([0.0, 0.0, X[2]]), np.eye(3))
    k, F = 2e7, -500.0
    # By the threefold and mirror symmetry a vertical force at P moves P straight down:
    # dz = F / (k sum n_z^2) with n_z = h / L for every leg.
    nz = X[2] / L
    dz = F / (k * np.sum(nz ** 2))
    t = deflection(mech, X, [0, 0, F, 0, 0, 0], axial_stiffness=k)
    np.testing.assert_allclose(t, [0, 0, dz, 0, 0, 0], atol=1e-12 * abs(dz) + 1e-18, rtol=1e-10)
    u = point_deflection(mech, X, force=[0, 0, F], axial_stiffness=k)
    np.testing.assert_allclose(u, [0, 0, dz], atol=1e-12 * abs(dz), rtol=1e-10)
    # Vertical stiffness: F / dz, the same through stiffness_along.
    np.testing.assert_allclose(stiffness_along(mech, X, [0, 0, 1], axial_stiffness=k), k * np.sum(nz ** 2), rtol=1e-10)


def _rps_geometry(mech):
    return [(np.asarray(l.base), np.asarray(l.platform), np.asarray(l.r_axis)) for l in mech.legs]


def _compliant_equilibrium(mech, X, wrench, eps):
    """Solve the equilibrium of the 3-RPS platform held by springs (legs along their lines with
    k = E A / L, lateral constraint springs 3 E I / L^3) under ``eps * wrench``; returns the
    pose change (dp, rotation vector)."""
    p0, R0 = mech.pose(X)
    geo = _rps_geometry(mech)
    d = mech.params.leg_diameter
    A, I = math.pi * d ** 2 / 4, math.pi * d ** 4 / 64
    L0 = np.array([np.linalg.norm(p0 + R0 @ a - b) for b, a, _ in geo])
    k_ax = STEEL_E * A / L0
    k_lat = 3 * STEEL_E * I / L0 ** 3
    scale = np.array([1, 1, 1, mech.length_scale, mech.length_scale, mech.length_scale])

    def balance(x):
        t = x * eps / scale
        p = p0 + t[:3]
        R = Rotation.from_rotvec(t[3:]).as_matrix() @ R0
        total = np.zeros(6)
        for (b, a, r), L, ka, kl in zip(geo, L0, k_ax, k_lat):
            A_ = p + R @ a
            dvec = A_ - b
            Lc = np.linalg.norm(dvec)
            n = dvec / Lc
            fa = -ka * (Lc - L)  # the leg spring pushes back along its line
            g = (A_ - b) @ r  # the sphere leaving the leg's plane
            fl = -kl * g
            arm = A_ - p
            total[:3] += fa * n + fl * r
            total[3:] += np.cross(arm, fa * n + fl * r)
        total += eps * np.asarray(wrench)
        return total / eps * np.array([1, 1, 1, 1 / mech.length_scale, 1 / mech.length_scale, 1 / mech.length_scale])

    sol = root(balance, np.zeros(6), method="hybr", options={"xtol": 1e-14})
    assert np.max(np.abs(balance(sol.x))) < 1e-6 * np.max(np.abs(wrench))  # round-off floor of k (L - L0)
    return sol.x * eps / scale


def test_3rps_deflection_matches_compliant_model():
    mech = parasynth.load_mechanism("3rps")
    X = np.array([0.52, 0.08, -0.11])
    wrench = np.array([30.0, -45.0, 80.0, 4.0, -6.0, 2.5])
    eps = 1e-3
    # Central difference of the nonlinear equilibrium response removes the second-order terms.
    resp = (_compliant_equilibrium(mech, X, wrench, eps) - _compliant_equilibrium(mech, X, wrench, -eps)) / (2 * eps)
    t = deflection(mech, X, wrench)
    np.testing.assert_allclose(t, resp, rtol=1e-6, atol=1e-6 * np.abs(resp).max())
    # And the 6x6 matrix is full rank although the mechanism has 3 freedoms.
    assert np.linalg.matrix_rank(stiffness_matrix(mech, X)) == 6


def test_compliance_inverse_and_symmetry():
    mech = parasynth.load_mechanism("5pus_upu")
    X = np.array([[0.01, -0.02, 0.03, 0.05, -0.04], [0.0, 0.0, 0.0, 0.0, 0.0]])
    K = stiffness_matrix(mech, X)
    np.testing.assert_allclose(K, np.swapaxes(K, 1, 2), rtol=0, atol=1e-9 * np.abs(K).max())
    C, Z = compliance(K, mech.length_scale)
    np.testing.assert_allclose(np.einsum("nij,njk->nik", K, C), np.broadcast_to(np.eye(6), K.shape), atol=1e-8)
    assert np.all(np.abs(Z) < 1e-12)
    # Translational stiffness: the smallest force-to-displacement ratio over directions.
    kt = part_stiffness(mech, X)
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(500, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    ratios = 1.0 / np.einsum("di,ij,dj->d", dirs, C[0, :3, :3], dirs)
    assert kt[0] <= ratios.min() * (1 + 1e-12)
    assert kt[0] >= 0.98 * ratios.min()


def test_series_actuator_stiffness():
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    K1 = stiffness_matrix(mech, mech.home, axial_stiffness=3e7, actuator_stiffness=6e7)
    K2 = stiffness_matrix(mech, mech.home, axial_stiffness=2e7)
    np.testing.assert_allclose(K1, K2, rtol=1e-12, atol=1e-6)


def test_under_actuated_policy():
    mech = parasynth.load_mechanism("4ups_1rps")
    X = mech.home
    yt = mech.params.y_t
    # The grinding force (along Z at the grinding point) is carried: finite stiffness.
    k = stiffness_along(mech, X, [0, 0, 1], point=[0, yt, 0])
    assert np.isfinite(k) and k > 0
    # A force along the uncontrolled freedom (X translation coupled with a turn about Z) is not.
    assert stiffness_along(mech, X, [1, 0, 0]) == 0.0
    assert np.all(np.isinf(point_deflection(mech, X, force=[10.0, 0, 0])))
    assert part_stiffness(mech, X) == 0.0


@pytest.mark.parametrize("kw, match", [
    ({"axial_stiffness": 0.0}, "axial_stiffness"),
    ({"axial_stiffness": -1e7}, "axial_stiffness"),
    ({"axial_stiffness": [1e7] * 5}, "axial_stiffness"),
    ({"constraint_force_stiffness": float("nan")}, "constraint_force_stiffness"),
    ({"youngs_modulus": 0}, "youngs_modulus"),
    ({"bogus": 1.0}, "bogus"),
])
def test_bad_stiffness_values(kw, match):
    mech = parasynth.load_mechanism("3rps")
    with pytest.raises(ValueError, match=match):
        stiffness_matrix(mech, mech.home, **kw)


def test_bad_direction_and_point():
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    with pytest.raises(ValueError, match="direction"):
        stiffness_along(mech, mech.home, [0, 0, 0])
    with pytest.raises(ValueError, match="reach"):
        stiffness_along(mech, mech.home, [0, 0, 1], point=[0, 75.0, 0])  # 75 m: mm given as m
    with pytest.raises(ValueError, match="force"):
        objectives.get("deflection")(mech, n=64)


def test_singular_pose_gives_inf_deflection():
    # Fichter's singularity of the Gough-Stewart platform: gamma = 90 deg at the symmetric pose.
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    X = np.array([0, 0, 0.6, 0, 0, math.pi / 2])
    K = stiffness_matrix(mech, X, axial_stiffness=1e7)
    L = mech.length_scale
    S = np.array([1, 1, 1, 1 / L, 1 / L, 1 / L])
    lam, V = np.linalg.eigh(S[:, None] * K * S[None, :])
    assert lam[0] < 1e-9 * lam[-1]  # singular
    w = V[:, 0] / S  # a wrench doing work on the leg lines' common freedom
    assert np.all(np.isinf(deflection(mech, X, w, axial_stiffness=1e7)))
    assert stiffness_along(mech, X, w[:3] if np.linalg.norm(w[:3]) > 1e-6 else [1, 0, 0], axial_stiffness=1e7) >= 0
    # The regular neighbour gives finite numbers.
    assert np.all(np.isfinite(deflection(mech, mech.home, [0, 0, 0, 0, 0, 1.0], axial_stiffness=1e7)))


def test_unreachable_is_nan():
    mech = parasynth.load_mechanism("3rps")
    K = stiffness_matrix(mech, np.array([[0.5, 0, 0], [np.nan, 0, 0]]))
    assert np.all(np.isfinite(K[0])) and np.all(np.isnan(K[1]))


def _study(settings, measure="stiffness_along"):
    spec = {"name": "s", "mechanism": "3rps", "variables": [{"name": "base_radius", "values": ["300 mm"]}],
            "objectives": [{"name": measure, "settings": settings}], "evaluation": {"samples": 64}}
    return yaml.safe_dump(spec)


def test_study_stiffness_units():
    s = load_study(_study({"axial_stiffness": "2e7 N/m", "constraint_couple_stiffness": "300 N*m/rad",
                           "point": ["0 mm", "0 mm", "10 mm"]}), is_text=True)
    st = s.objectives[0].settings
    assert st["axial_stiffness"] == pytest.approx(2e7)
    assert st["constraint_couple_stiffness"] == pytest.approx(300.0)
    assert st["point"] == pytest.approx((0, 0, 0.01))
    assert load_study(_study({"axial_stiffness": "20 N/mm"}), is_text=True).objectives[0].settings[
        "axial_stiffness"] == pytest.approx(2e4)
    with pytest.raises(StudyError, match=r"objectives\[0\]\.settings\.axial_stiffness"):
        load_study(_study({"axial_stiffness": 2e7}), is_text=True)
    with pytest.raises(StudyError, match=r"objectives\[0\]\.settings\.constraint_force_stiffness"):
        load_study(_study({"constraint_force_stiffness": "2e7 N"}), is_text=True)
    with pytest.raises(StudyError, match=r"objectives\[0\]\.settings\.youngs_modulus"):
        load_study(_study({"youngs_modulus": 210e9}), is_text=True)


def test_api_values_with_units():
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    np.testing.assert_allclose(stiffness_matrix(mech, mech.home, axial_stiffness="20 N/mm"),
                               stiffness_matrix(mech, mech.home, axial_stiffness=2e4), rtol=1e-12)
    with pytest.raises(ValueError, match="axial_stiffness"):
        stiffness_matrix(mech, mech.home, axial_stiffness="2e7 N")


# -- stiffness values declared in the mechanism description -----------------------------------------
from pathlib import Path  # noqa: E402

from parasynth.mechanisms.description import DescriptionError, description_class  # noqa: E402
from parasynth.study.evaluate import Evaluator  # noqa: E402

_GS_FILE = Path(parasynth.__file__).parent / "mechanisms" / "gough_stewart_6ups.yaml"


def _gs_description(leg_stiffness="2e7 N/m", section=None):
    d = yaml.safe_load(_GS_FILE.read_text())
    d["name"] = "gs_declared"
    d["parameters"]["leg_stiffness"] = leg_stiffness
    d["stiffness"] = {"axial": "leg_stiffness"} if section is None else section
    return d


def test_declared_leg_stiffness_closed_form():
    cls = description_class(_gs_description())
    assert cls.Params.UNITS["leg_stiffness"] == "stiffness"
    mech = cls()
    assert mech.params.leg_stiffness == pytest.approx(2e7)
    X = mech.home
    Wr, _ = _gough_rows(mech, np.array([0.0, 0.0, X[2]]), np.eye(3))
    K_ref = 2e7 * sum(np.outer(w, w) for w in Wr)
    K = stiffness_matrix(mech, X)
    np.testing.assert_allclose(K, K_ref, rtol=1e-12, atol=1e-12 * np.abs(K_ref).max())
    # Not the geometric estimate (40 mm steel rod over ~0.6 m is ~4.4e8 N/m).
    assert not np.allclose(K, stiffness_matrix(parasynth.load_mechanism("gough_stewart_6ups"), X), rtol=0.5)
    # K is linear in the parameter, at any pose.
    Xs = np.array([X, X + np.array([0.05, -0.03, 0.1, 0.1, -0.05, 0.2])])
    mech3 = cls(cls.Params(leg_stiffness=6e7))
    np.testing.assert_allclose(stiffness_matrix(mech3, Xs), 3 * stiffness_matrix(mech, Xs), rtol=1e-12, atol=1e-6)
    # The vertical deflection under 500 N follows the declared k.
    nz = Wr[:, 2]
    dz = -500.0 / (2e7 * np.sum(nz ** 2))
    np.testing.assert_allclose(point_deflection(mech, X, force=[0, 0, -500.0]), [0, 0, dz], rtol=1e-9,
                               atol=1e-12 * abs(dz))


def test_declared_stiffness_expression_and_groups():
    # Per-leg groups: legs L1..L3 at k, L4..L6 at 2k through an expression of the parameter.
    section = [{"legs": ["L1", "L2", "L3"], "axial": "leg_stiffness"},
               {"legs": ["L4", "L5", "L6"], "axial": "2*leg_stiffness", "doc": "stiffer half"}]
    mech = description_class(_gs_description(section=section))()
    X = mech.home
    Wr, _ = _gough_rows(mech, np.array([0.0, 0.0, X[2]]), np.eye(3))
    k = np.array([2e7] * 3 + [4e7] * 3)
    K_ref = sum(ki * np.outer(w, w) for ki, w in zip(k, Wr))
    np.testing.assert_allclose(stiffness_matrix(mech, X), K_ref, rtol=1e-12, atol=1e-12 * np.abs(K_ref).max())
    # The series drive of the description: 3e7 and 6e7 in series give 2e7.
    sec2 = {"axial": "3e7 N/m", "actuator": "6e7 N/m"}
    m2 = description_class(_gs_description(section=sec2))()
    np.testing.assert_allclose(stiffness_matrix(m2, X), 2e7 * sum(np.outer(w, w) for w in Wr), rtol=1e-12, atol=1e-3)


def test_stiffness_precedence():
    mech = description_class(_gs_description())()
    X = mech.home
    Wr, L = _gough_rows(mech, np.array([0.0, 0.0, X[2]]), np.eye(3))
    G = sum(np.outer(w, w) for w in Wr)
    # 1. An explicit setting beats the description's value.
    np.testing.assert_allclose(stiffness_matrix(mech, X, axial_stiffness=5e7), 5e7 * G, rtol=1e-12, atol=1e-3)
    np.testing.assert_allclose(stiffness_along(mech, X, [0, 0, 1], axial_stiffness="50 N/mm"),
                               5e4 * np.sum(Wr[:, 2] ** 2), rtol=1e-10)
    # 2. The description's value beats the estimate (whose diameter setting then does nothing).
    np.testing.assert_allclose(stiffness_matrix(mech, X, diameter=0.08), 2e7 * G, rtol=1e-12, atol=1e-3)
    # 3. Without a declaration: the steel-rod estimate E A / L of the leg diameter.
    plain = parasynth.load_mechanism("gough_stewart_6ups")
    d = plain.params.leg_diameter
    K_est = sum(ki * np.outer(w, w) for ki, w in zip(STEEL_E * math.pi * d * d / 4 / L, Wr))
    np.testing.assert_allclose(stiffness_matrix(plain, X), K_est, rtol=1e-12, atol=1e-12 * np.abs(K_est).max())
    # A declared diameter feeds the estimate for legs without a declared value; the keyword beats it.
    m_d = description_class(_gs_description(section={"diameter": "20 mm"}))()
    np.testing.assert_allclose(stiffness_matrix(m_d, X), K_est / 4, rtol=1e-12, atol=1e-12 * np.abs(K_est).max())
    np.testing.assert_allclose(stiffness_matrix(m_d, X, diameter=0.04), K_est, rtol=1e-12,
                               atol=1e-12 * np.abs(K_est).max())
    # Through a measure: the study setting beats the description, as in stiffness_matrix.
    kz = objectives.get("stiffness_along")
    a = kz(mech, direction=[0, 0, 1], n=64, seed=1)
    b = kz(mech, direction=[0, 0, 1], n=64, seed=1, axial_stiffness=4e7)
    assert b == pytest.approx(2 * a, rel=1e-9)


def test_constraint_limb_declared_stiffness():
    # 3-RPS: the constraint force rows of each leg at a declared value give K = sum k_j w_j w_j^T.
    d = yaml.safe_load((_GS_FILE.parent / "3rps.yaml").read_text())
    d["name"] = "rps_declared"
    d["parameters"]["limb_force_stiffness"] = {"value": "3e6 N/m", "above": "0 N/m"}
    d["parameters"]["leg_stiffness"] = "4e7 N/m"
    d["stiffness"] = {"axial": "leg_stiffness", "constraint_force": "limb_force_stiffness"}
    mech = description_class(d)()
    X = np.array([0.52, 0.08, -0.11])
    W = mech.wrench_matrix(X)
    na = mech.n_actuators
    k = np.array([4e7] * na + [3e6] * (W.shape[0] - na))
    K_ref = W.T @ np.diag(k) @ W
    np.testing.assert_allclose(stiffness_matrix(mech, X), K_ref, rtol=1e-10, atol=1e-10 * np.abs(K_ref).max())
    # Keyword beats description for the constraint rows too.
    np.testing.assert_allclose(stiffness_matrix(mech, X, constraint_force_stiffness=6e6, axial_stiffness=4e7),
                               W.T @ np.diag(np.where(np.arange(len(k)) < na, 4e7, 6e6)) @ W, rtol=1e-10,
                               atol=1e-10 * np.abs(K_ref).max())


@pytest.mark.parametrize("value, section, match", [
    (2e7, None, r"stiffness\.axial: 'leg_stiffness' is a plain number \(parameters\.leg_stiffness"),
    ({"value": 2e7, "kind": "stiffness"}, None, r"parameters\.leg_stiffness: a bare number"),
    ("-2e7 N/m", None, r"parameters\.leg_stiffness must be > 0"),
    ("0 N/m", None, r"parameters\.leg_stiffness must be > 0"),
    ({"value": "2e7 N/m", "min": "3e7 N/m"}, None, r"parameters\.leg_stiffness must be >= 3"),
    ("2e7 N", None, r"parameters\.leg_stiffness: cannot read '2e7 N'"),
    ("2e7 N/m", {"axial": "3e7"}, r"stiffness\.axial: '3e7' has no unit"),
    ("2e7 N/m", {"axial": "-3e7 N/m"}, r"stiffness\.axial: must be positive"),
    ("2e7 N/m", {"axial": "leg_diameter"}, r"stiffness\.axial: parameters\.leg_diameter is a length"),
    ("2e7 N/m", {"axial": "-leg_stiffness"}, r"stiffness\.axial: must be a finite positive value"),
    ("2e7 N/m", {"constraint_couple": "leg_stiffness"}, r"stiffness\.constraint_couple: parameters\.leg_stiffness is a stiffness"),
    ("2e7 N/m", {"constraint_force": "3e6 N/m"}, r"stiffness\.constraint_force: no leg of this entry"),
    ("2e7 N/m", [{"legs": ["L9"], "axial": "leg_stiffness"}], r"stiffness\[0\]\.legs: unknown leg 'L9'"),
    ("2e7 N/m", [{"axial": "leg_stiffness"}, {"legs": ["L2"], "axial": "leg_stiffness"}],
     r"stiffness\[1\]\.axial: leg L2's axial is already given by stiffness\[0\]\.axial"),
    ("2e7 N/m", {"axial_stiffness": "leg_stiffness"}, r"stiffness: unknown key 'axial_stiffness'"),
])
def test_declared_stiffness_bad_input(value, section, match):
    with pytest.raises(DescriptionError, match=match):
        description_class(_gs_description(value, section))


def test_declared_stiffness_bad_value_at_build():
    cls = description_class(_gs_description())
    with pytest.raises(ValueError, match=r"leg_stiffness must be > 0"):
        cls.Params(leg_stiffness=-1.0)


def test_study_with_stiffness_variable(tmp_path):
    desc = tmp_path / "gs_declared.yaml"
    desc.write_text(yaml.safe_dump(_gs_description()))
    spec = {"name": "k", "mechanism": "gs_declared.yaml",
            "variables": [{"name": "leg_stiffness", "low": "1e7 N/m", "high": "5e7 N/m", "num": 3}],
            "objectives": [{"name": "stiffness_along", "settings": {"direction": [0, 0, 1]}}],
            "evaluation": {"samples": 64}}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(spec))
    s = load_study(path)
    v = s.variables[0]
    assert v.kind == "stiffness" and v.low == pytest.approx(1e7) and v.high == pytest.approx(5e7)
    assert v.values == pytest.approx((1e7, 3e7, 5e7))
    from parasynth.measures.display import quantity_unit

    assert quantity_unit(s, "leg_stiffness").symbol == "N/m"  # reports show the variable's unit
    from parasynth.study.spec import check_study

    assert check_study(s) == []  # what `parasynth validate` runs: designs built, measure evaluated
    ev = Evaluator(s)
    r1 = ev.evaluate({"leg_stiffness": 1e7})
    r3 = ev.evaluate({"leg_stiffness": 3e7})
    assert r1.status == "ok" and r3.status == "ok", (r1.error, r3.error)
    assert r1.objectives["stiffness_along"] > 0
    assert r3.objectives["stiffness_along"] == pytest.approx(3 * r1.objectives["stiffness_along"], rel=1e-9)
    # Bounds without a unit, or in the wrong unit, are refused naming the key path.
    for low, match in ((1e7, r"variables\[0\]\.low: a bare number"), ("1e7 N", r"variables\[0\]\.low")):
        spec["variables"][0]["low"] = low
        path.write_text(yaml.safe_dump(spec))
        with pytest.raises(StudyError, match=match):
            load_study(path)


def test_list_shows_stiffness_unit(tmp_path, capsys, monkeypatch):
    from parasynth import cli

    desc = tmp_path / "gs_declared.yaml"
    d = _gs_description("25 N/mm")
    d["parameters"]["limb_couple"] = {"value": "3e5 N*m/rad", "above": "0 N*m/rad"}
    desc.write_text(yaml.safe_dump(d))
    monkeypatch.setattr(cli, "mechanism_summaries", lambda: {str(desc): "declared stiffness"})
    assert cli.cmd_list(None) == 0
    out = capsys.readouterr().out
    assert "leg_stiffness (stiffness, N/m) = 25000 N/m" in out
    assert "limb_couple (rotational stiffness, N*m/rad, > 0 N*m/rad) = 300000 N*m/rad" in out


@pytest.mark.parametrize("name, modulus", [("4ups_1rps", "leg_modulus"), ("5pus_upu", "link_modulus"),
                                           ("2rpu_2sps", "leg_modulus")])
def test_paper_models_declare_the_documented_estimate(name, modulus):
    """The paper models' stiffness sections name the estimate's inputs (rod diameter, steel
    moduli) as parameters: the same matrix as the undeclared estimate, linear in the modulus."""
    mech = parasynth.load_mechanism(name)
    assert getattr(mech.params, modulus) == pytest.approx(STEEL_E)
    d = yaml.safe_load((_GS_FILE.parent / f"{name}.yaml").read_text())
    del d["stiffness"]
    d["name"] = f"{name}_undeclared"
    bare = description_class(d)()
    assert bare.declared_stiffness == {}
    rng = np.random.default_rng(7)
    X = mech.home + 1e-3 * rng.uniform(-1, 1, (3, mech.n_task)) * np.where(
        [c in mech.angular_coordinates for c in mech.task_coordinates], 10.0, mech.length_scale)
    K = stiffness_matrix(mech, X)
    assert np.all(np.isfinite(K))
    np.testing.assert_allclose(K, stiffness_matrix(bare, X), rtol=1e-12, atol=1e-12 * np.abs(K).max())
    stiffer = mech.with_params(**{modulus: 2 * STEEL_E})
    np.testing.assert_allclose(stiffness_matrix(stiffer, X), 2 * K, rtol=1e-12, atol=1e-12 * np.abs(K).max())
    # The study setting beats the declared modulus.
    np.testing.assert_allclose(stiffness_matrix(stiffer, X, youngs_modulus=STEEL_E, shear_modulus=STEEL_E / 2.6), K,
                               rtol=1e-12, atol=1e-12 * np.abs(K).max())


def test_declared_stiffness_follows_the_parameters_and_is_not_shared():
    # The values are kept per parameter values: another value gives its own, and each
    # mechanism gets dicts of its own (writing one leaves the next build's unchanged).
    section = [{"legs": ["L1", "L2", "L3"], "axial": "leg_stiffness"},
               {"legs": ["L4", "L5", "L6"], "axial": "2*leg_stiffness"}]
    cls = description_class(_gs_description(section=section))
    a = cls(cls.Params(leg_stiffness=3e7))
    a.declared_stiffness["L1"]["axial"] = -1.0
    b = cls(cls.Params(leg_stiffness=3e7))
    c = cls(cls.Params(leg_stiffness=5e7))
    assert b.declared_stiffness["L1"]["axial"] == 3e7 and b.declared_stiffness["L4"]["axial"] == 6e7
    assert c.declared_stiffness["L1"]["axial"] == 5e7 and c.declared_stiffness["L4"]["axial"] == 1e8
    assert b.declared_stiffness is not cls(cls.Params(leg_stiffness=3e7)).declared_stiffness
