"""Pose accuracy: actuator errors against J^-1 dq, first-order bound against Monte Carlo, Monte
Carlo covariance against the first-order covariance, independent checks of the closure
sensitivities, bad input and units."""

import math

import numpy as np
import pytest
import yaml

import parasynth
from parasynth.measures import accuracy as acc
from parasynth.measures import objectives
from parasynth.study.spec import StudyError, load_study

TOL = dict(actuator_tolerance=1e-5, anchor_tolerance=2e-5, link_tolerance=2e-5,
           axis_tolerance=math.radians(0.05), spherical_clearance=1e-5, universal_clearance=1.5e-5)


def _poses(mech, n=4, seed=1):
    ws = objectives.workspace_of(mech, n=512, seed=seed)
    pts = ws.points
    return pts[np.linspace(0, len(pts) - 1, n).astype(int)]


@pytest.mark.parametrize("name", ["gough_stewart_6ups", "5pus_upu", "3rps"])
def test_actuator_only_error_is_inverse_jacobian(name):
    mech = parasynth.load_mechanism(name)
    X = _poses(mech)
    rng = np.random.default_rng(0)
    dq = rng.uniform(-1e-5, 1e-5, size=(len(X), mech.n_actuators))
    t = acc.actuator_pose_error(mech, X, dq)
    dX = np.linalg.solve(mech.jacobian(X), dq[..., None])[..., 0]
    ref = np.einsum("nij,nj->ni", mech.twist_map(X), dX)
    np.testing.assert_allclose(t, ref, rtol=1e-6, atol=1e-6 * np.abs(ref).max())


@pytest.mark.parametrize("name", ["gough_stewart_6ups", "5pus_upu", "3rps", "3prs"])
def test_first_order_bound_contains_monte_carlo(name):
    mech = parasynth.load_mechanism(name)
    X = _poses(mech, n=3)
    b = acc.pose_error_bound(mech, X, **TOL)
    t, _ = acc.pose_error_monte_carlo(mech, X, samples=300, seed=2, **TOL)
    assert np.all(np.isfinite(t))
    # Every sample inside the first-order box (the linearisation error is far below the 1 % slack).
    assert np.all(np.abs(t) <= b[None] * 1.01)
    # ... and the bound is not vacuous: the samples reach a good part of it.
    assert np.max(np.abs(t) / b[None]) > 0.3
    # The measures agree with the functions they wrap.
    pe = np.linalg.norm(b[:, :3], axis=-1)
    assert pe.max() > 0


@pytest.mark.parametrize("which", ["all", "clearances"])
def test_monte_carlo_converges_to_first_order_covariance(which):
    mech = parasynth.load_mechanism("5pus_upu")
    X = np.array([[0.02, -0.01, 0.01, 0.05, -0.08]])
    small = {k: v * 0.1 for k, v in TOL.items() if which == "all" or k.endswith("clearance")}
    cov = acc.pose_error_covariance(mech, X, **small)[0]
    t, E = acc.pose_error_monte_carlo(mech, X, samples=3000, seed=5, **small)
    mc = np.cov(t[:, 0].T)
    sd, sd_mc = np.sqrt(np.diag(cov)), np.sqrt(np.diag(mc))
    np.testing.assert_allclose(sd_mc, sd, rtol=0.06)
    # Correlations too (the full matrix, scaled by the standard deviations).
    corr = cov / np.outer(sd, sd)
    corr_mc = mc / np.outer(sd_mc, sd_mc)
    np.testing.assert_allclose(corr_mc, corr, atol=0.06)
    # Sample by sample, the exact solution is the linear one up to second-order terms.
    S, _ = acc.sensitivity(mech, X)
    lin = np.einsum("ij,sj->si", S[0], E)
    assert np.max(np.abs(t[:, 0] - lin)) < 1e-3 * np.max(np.abs(lin))


def test_link_length_sensitivity_against_inverse_kinematics():
    """A link-length error of one PUS leg acts like an actuator error of that leg: at a fixed
    pose, the slider must move by ds = dL / (d s / d L) to keep the sphere, so the pose error of
    a link error dL equals the actuator-error response to dq = -dIK/dL dL, with dIK/dL from the
    closed form s = de + sqrt(L^2 - perp^2) (d s / d L = L / sqrt(L^2 - perp^2))."""
    mech = parasynth.load_mechanism("5pus_upu")
    X = _poses(mech, n=3)
    S, src = acc.sensitivity(mech, X)
    p, R = mech.pose(X)
    for li, leg in enumerate(mech.legs[:5]):
        j = src.names.index(f"{leg.name}.link_length")
        Sp = leg.platform_points(p, R)
        d = Sp - leg.base
        e = np.asarray(leg.slider_axis)
        perp2 = np.sum(d * d, -1) - (d @ e) ** 2
        dsdL = leg.link_length / np.sqrt(leg.link_length ** 2 - perp2)
        dq = np.zeros((len(X), mech.n_actuators))
        dq[:, li] = -dsdL
        ref = acc.actuator_pose_error(mech, X, dq)
        np.testing.assert_allclose(S[..., j], ref, rtol=1e-5, atol=1e-6 * np.abs(ref).max())


def test_clearance_bound_is_a_ball():
    """A clearance of radius c contributes c * ||S_k,g|| to component k, and an anchor tolerance
    of the same size in the box norm contributes c * sum |S_k,g|: the ball bound is smaller."""
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    X = _poses(mech, n=2)
    b_ball = acc.pose_error_bound(mech, X, spherical_clearance=1e-5)
    S, src = acc.sensitivity(mech, X)
    cols = [j for j, k in enumerate(src.kind) if k == "spherical_clearance"]
    ref = sum(1e-5 * np.linalg.norm(S[..., cols[i:i + 3]], axis=-1) for i in range(0, len(cols), 3))
    np.testing.assert_allclose(b_ball, ref, rtol=1e-12)
    # The platform S joints of a UPS leg are its platform anchors.
    anch = [src.names.index(f"{leg.name}.platform.{a}") for leg in mech.legs for a in "xyz"]
    np.testing.assert_allclose(S[..., anch], S[..., cols], rtol=1e-12, atol=1e-15)


def test_parameter_sensitivity_against_refit():
    """Changing a design parameter by a small amount and solving the forward kinematics of the
    changed mechanism for the nominal actuator values moves the platform as predicted."""
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    X = np.array([0.02, -0.03, 0.62, 0.05, -0.04, 0.1])
    S, names = acc.parameter_sensitivity(mech, X[None])
    j = names.index("base_radius")
    h = 1e-6
    q = mech.inverse_kinematics(X).actuators
    m2 = mech.with_params(base_radius=mech.params.base_radius + h)
    X2 = m2.forward_kinematics(q, guess=X, tol=1e-15, residual_tol=1e-9)
    p0, R0 = mech.pose(X)
    p2, R2 = m2.pose(X2)
    dR = R2 @ R0.T
    ref = np.concatenate([p2 - p0, 0.5 * np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])]) / h
    np.testing.assert_allclose(S[0, :, j], ref, rtol=1e-3, atol=1e-4 * np.abs(ref).max())
    # Limits do not move the platform.
    assert np.all(S[0, :, names.index("l_max")] == 0)


def test_ranking_orders_the_groups():
    mech = parasynth.load_mechanism("5pus_upu")
    X = _poses(mech, n=3)
    rows = acc.sensitivity_ranking(mech, X, link_tolerance=2e-5, spherical_clearance=1e-5)
    names = [r["name"] for r in rows]
    assert {"link lengths", "spherical_clearance"} <= set(names)
    pos = [r["position"] for r in rows]
    assert pos == sorted(pos, reverse=True)
    # Groups without a tolerance contribute nothing.
    assert all(r["position"] == 0 for r in rows if r["name"] not in ("link lengths", "spherical_clearance"))
    rows_p = acc.sensitivity_ranking(mech, X, level="parameters", anchor_tolerance=2e-5,
                                     axis_tolerance=math.radians(0.05))
    assert rows_p[0]["position"] >= rows_p[-1]["position"]
    assert "link_length" in [r["name"] for r in rows_p]


def test_measures_first_order_and_monte_carlo():
    mech = parasynth.load_mechanism("5pus_upu")
    kw = dict(n=512, max_points=8, link_tolerance=2e-5, spherical_clearance=1e-5)
    fo = objectives.get("position_error_max")(mech, **kw)
    mc = objectives.get("position_error_max")(mech, method="monte_carlo", samples=60, **kw)
    assert 0 < mc <= fo
    ofo = objectives.get("orientation_error_max")(mech, **kw)
    assert ofo > 0
    # A study's sampling method in place of the error method keeps the first-order model.
    assert objectives.get("position_error_max")(mech, method="sobol", **kw) == pytest.approx(fo)
    with pytest.raises(ValueError, match="method"):
        objectives.get("position_error_max")(mech, method="exact", **kw)


@pytest.mark.parametrize("tol, match", [
    ({"link_tolerance": -1e-5}, "link_tolerance"),
    ({"spherical_clearance": float("nan")}, "spherical_clearance"),
    ({}, "at least one positive tolerance"),
    ({"link_tolerance": 0.0}, "at least one positive tolerance"),
    ({"gap": 1e-5}, "gap"),
])
def test_bad_tolerances(tol, match):
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    with pytest.raises(ValueError, match=match):
        acc.pose_error_bound(mech, mech.home[None], **tol)


def test_under_actuated_has_no_pose_error():
    mech = parasynth.load_mechanism("4ups_1rps")
    with pytest.raises(ValueError, match="under-actuated"):
        acc.pose_error_bound(mech, mech.home[None], actuator_tolerance=1e-5)


def test_singular_pose_gives_inf():
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    X = np.array([[0, 0, 0.6, 0, 0, math.pi / 2], list(mech.home)])
    b = acc.pose_error_bound(mech, X, actuator_tolerance=1e-5)
    assert np.all(np.isinf(b[0])) and np.all(np.isfinite(b[1]))


def _study(settings, measure="position_error_max"):
    spec = {"name": "s", "mechanism": "5pus_upu", "variables": [{"name": "link_length", "values": ["205 mm"]}],
            "objectives": [{"name": measure, "settings": settings}], "evaluation": {"samples": 64}}
    return yaml.safe_dump(spec)


def test_study_tolerance_units():
    s = load_study(_study({"link_tolerance": "0.02 mm", "axis_tolerance": "0.05 deg", "method": "monte_carlo"}),
                   is_text=True)
    st = s.objectives[0].settings
    assert st["link_tolerance"] == pytest.approx(2e-5)
    assert st["axis_tolerance"] == pytest.approx(math.radians(0.05))
    assert st["method"] == "monte_carlo"
    with pytest.raises(StudyError, match=r"objectives\[0\]\.settings\.link_tolerance"):
        load_study(_study({"link_tolerance": 0.02}), is_text=True)
    with pytest.raises(StudyError, match=r"objectives\[0\]\.settings\.axis_tolerance"):
        load_study(_study({"axis_tolerance": 0.05}, measure="orientation_error_max"), is_text=True)
    with pytest.raises(StudyError, match=r"objectives\[0\]\.settings\.spherical_clearance"):
        load_study(_study({"spherical_clearance": "0.01 deg"}), is_text=True)


def test_api_tolerances_with_units():
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    X = mech.home[None]
    np.testing.assert_allclose(acc.pose_error_bound(mech, X, anchor_tolerance="0.02 mm", axis_tolerance="0.05 deg"),
                               acc.pose_error_bound(mech, X, anchor_tolerance=2e-5, axis_tolerance=math.radians(0.05)),
                               rtol=1e-12)
    with pytest.raises(ValueError, match="anchor_tolerance"):
        acc.pose_error_bound(mech, X, anchor_tolerance="0.02 deg")
