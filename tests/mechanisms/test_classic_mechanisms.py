"""Classic mechanisms shipped as descriptions: the 6-UPS Gough-Stewart platform (round trips,
Fichter's singularity), the 3-RPS and the 3-PRS (three freedoms, 1T2R, parasitic motion),
and the PRS leg. Expected values come from independent computations written out here."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import parasynth
from parasynth.model.legs import PRS
from parasynth.mechanisms.description import DescriptionWarning

DEG = np.pi / 180


def _rz(g):
    c, s = np.cos(g), np.sin(g)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _mobility_without_warnings(m):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DescriptionWarning)
        return m.mobility()


def _random_poses(m, n, seed, shrink=1.0):
    rng = np.random.default_rng(seed)
    r = m.default_ranges()
    lo = np.array([r[c][0] for c in m.task_coordinates])
    hi = np.array([r[c][1] for c in m.task_coordinates])
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo) * shrink
    return mid + half * rng.uniform(-1, 1, size=(n, m.n_task))


# -- Gough-Stewart ----------------------------------------------------------------------------------
def _gs_lines(P, X):
    """Plücker lines (n_i, a_i x n_i) of the legs about the platform centre, from the parameters
    alone: base joints in pairs at 0/120/240 deg +- base_separation/2, platform joints at
    60/180/300 deg +- platform_separation/2, leg i to the neighbouring platform pair."""
    sb, sp = P.base_separation / 2, P.platform_separation / 2
    base_ang = np.array([c + s for c in (0.0, 120 * DEG, 240 * DEG) for s in (-sb, sb)])
    plat_ang = np.array([c + s for c in (60 * DEG, 180 * DEG, 300 * DEG) for s in (-sp, sp)])[[5, 0, 1, 2, 3, 4]]
    B = P.base_radius * np.column_stack([np.cos(base_ang), np.sin(base_ang), np.zeros(6)])
    A0 = P.platform_radius * np.column_stack([np.cos(plat_ang), np.sin(plat_ang), np.zeros(6)])
    x, y, z, a, b, g = X
    ca, sa, cb, sb_, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    Ry = np.array([[cb, 0, sb_], [0, 1, 0], [-sb_, 0, cb]])
    R = Rx @ Ry @ _rz(g)
    a_rel = A0 @ R.T
    A = np.array([x, y, z]) + a_rel
    d = A - B
    lengths = np.linalg.norm(d, axis=1)
    n = d / lengths[:, None]
    return np.hstack([n, np.cross(a_rel, n)]), lengths


def test_gough_stewart_geometry_and_mobility():
    m = parasynth.load_mechanism("gough_stewart_6ups")
    X = _random_poses(m, 50, 0)
    q = m.inverse_kinematics(X).actuators
    for k in range(5):
        _, lengths = _gs_lines(m.params, X[k])
        np.testing.assert_allclose(q[k], lengths, atol=1e-12)
    mob = _mobility_without_warnings(m)
    assert (mob.dof, mob.type, mob.controlled, mob.constraint_rank, mob.gruebler) == (6, "3T3R", True, 0, 6)
    assert m.actuators == ("q1", "q2", "q3", "q4", "q5", "q6")


@pytest.mark.parametrize("params", [{}, {"base_separation": 30 * DEG, "platform_separation": 12 * DEG,
                                         "platform_radius": 0.25}])
def test_gough_stewart_ik_fk_round_trip(params):
    m = parasynth.load_mechanism("gough_stewart_6ups", **params)
    X = _random_poses(m, 40, 1, shrink=0.5)
    ik = m.inverse_kinematics(X)
    assert ik.reachable.all()
    Xf = m.forward_kinematics(ik.actuators, guess=X + 0.01)
    np.testing.assert_allclose(Xf, X, atol=1e-9)
    np.testing.assert_allclose(m.inverse_kinematics(Xf).actuators, ik.actuators, atol=1e-12)


@pytest.mark.parametrize("params", [{}, {"base_separation": 30 * DEG, "platform_separation": 12 * DEG,
                                         "platform_radius": 0.25}])
def test_gough_stewart_fichter_singularity(params):
    """Fichter (1986): platform turned by +-90 deg about the vertical at the symmetric pose is
    singular at every height; checked with the singularity margin and, independently, with the
    determinant of the six leg lines built from the parameters alone."""
    m = parasynth.load_mechanism("gough_stewart_6ups", **params)
    for z in (0.45, 0.6, 0.8):
        home = np.array([0.0, 0.0, z, 0.0, 0.0, 0.0])
        regular = m.singularity_margin(home)
        assert regular > 0.05
        lines0, _ = _gs_lines(m.params, home)
        det0 = abs(np.linalg.det(lines0))
        assert det0 > 1e-3
        for g in (90 * DEG, -90 * DEG):
            Xs = home + np.array([0, 0, 0, 0, 0, g])
            assert m.inverse_kinematics(Xs).reachable
            assert m.singularity_margin(Xs) < 1e-9 * regular
            lines, _ = _gs_lines(m.params, Xs)
            assert abs(np.linalg.det(lines)) < 1e-12 * det0
            J = m.jacobian(Xs)
            s = np.linalg.svd(J, compute_uv=False)
            assert s[-1] < 1e-9 * s[0]
        # Turned 60 deg, the platform is regular, and the margin grows as it leaves 90 deg.
        margins = [m.singularity_margin(home + np.array([0, 0, 0, 0, 0, g * DEG])) for g in (60, 75, 85, 89)]
        assert margins[0] > 1e-3 and all(a > b for a, b in zip(margins, margins[1:]))
    with pytest.raises(parasynth.ForwardKinematicsError, match="do not determine the pose"):
        m.forward_kinematics(m.inverse_kinematics(np.array([0, 0, 0.6, 0, 0, 90 * DEG])).actuators,
                             guess=np.array([0, 0, 0.6, 0, 0, 90 * DEG]))


# -- 3-RPS and 3-PRS ------------------------------------------------------------------------------
def _tilt_torsion_check(P_radius, p, R):
    """Independent closed form of the parasitic motion of a symmetric 3-RPS/3-PRS with its first
    leg on +x: the platform turns about a horizontal axis (tilt theta about azimuth phi + 90
    deg) with zero torsion, and its centre moves by a/2 (1 - cos theta) (-cos 2phi, sin 2phi)."""
    k = R[:, :, 2]  # platform normal = (cos phi sin theta, sin phi sin theta, cos theta)
    theta = np.arccos(np.clip(k[:, 2], -1, 1))
    phi = np.arctan2(k[:, 1], k[:, 0])
    for i in range(len(p)):
        c, s = np.cos(theta[i]), np.sin(theta[i])
        Ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        R_expected = _rz(phi[i]) @ Ry @ _rz(-phi[i])
        np.testing.assert_allclose(R[i], R_expected, atol=1e-12)
    xy = 0.5 * P_radius * (1 - np.cos(theta))[:, None] * np.column_stack([-np.cos(2 * phi), np.sin(2 * phi)])
    np.testing.assert_allclose(p[:, :2], xy, atol=1e-12)


def _plane_residuals(m, X):
    """t_i . (A_i - B_i) for each leg: each sphere must stay in the vertical plane through its
    base joint (or slider line) and the base centre; t_i is the tangent of the base circle."""
    P = m.params
    ang = np.array([0.0, 120 * DEG, 240 * DEG])
    t = np.column_stack([-np.sin(ang), np.cos(ang), np.zeros(3)])
    B = P.base_radius * np.column_stack([np.cos(ang), np.sin(ang), np.zeros(3)])
    A0 = P.platform_radius * np.column_stack([np.cos(ang), np.sin(ang), np.zeros(3)])
    p, R = m.pose(X)
    A = p[:, None, :] + np.einsum("nij,kj->nki", R, A0)
    return np.einsum("nki,ki->nk", A - B, t)


@pytest.mark.parametrize("name, params", [("3rps", {}), ("3rps", {"platform_radius": 0.12, "base_radius": 0.35}),
                                          ("3prs", {}), ("3prs", {"platform_radius": 0.08, "link_length": 0.35})])
def test_tripods_parasitic_motion_and_mobility(name, params):
    m = parasynth.load_mechanism(name, **params)
    mob = _mobility_without_warnings(m)
    assert (mob.dof, mob.type, mob.controlled, mob.constraint_rank, mob.gruebler) == (3, "1T2R", True, 3, 3)
    assert mob.consistent and not mob.issues
    X = _random_poses(m, 200, 2)
    ik = m.inverse_kinematics(X)
    assert ik.reachable.all()  # the legs' plane conditions hold (to GEOM_TOL) on every pose
    np.testing.assert_allclose(_plane_residuals(m, X), 0.0, atol=1e-12)
    p, R = m.pose(X)
    _tilt_torsion_check(m.params.platform_radius, p, R)
    np.testing.assert_allclose(p[:, 2], X[:, 0], atol=0)
    # The platform's instantaneous freedoms at a tilted pose are the twists the model moves along.
    Xt = X[3]
    T = m.twist_map(Xt)
    C = m.wrench_matrix(Xt)[m.n_actuators:]
    assert C.shape == (3, 6)
    np.testing.assert_allclose(C @ T, 0.0, atol=1e-12)


@pytest.mark.parametrize("name", ["3rps", "3prs"])
def test_tripods_round_trip_and_jacobian(name):
    from _support import central_difference

    m = parasynth.load_mechanism(name)
    X = _random_poses(m, 30, 3, shrink=0.6)
    q = m.inverse_kinematics(X).actuators
    np.testing.assert_allclose(m.forward_kinematics(q, guess=X + 0.005), X, atol=1e-9)
    J = m.jacobian(X)
    Jfd = central_difference(lambda Y: m.inverse_kinematics(Y).actuators, X, np.full(3, 1e-6))
    np.testing.assert_allclose(J, Jfd, atol=1e-7)
    f = m.is_feasible(_random_poses(m, 400, 4))
    assert 0 < f.mean() < 1


def test_tripod_without_parasitic_motion_is_reported_inconsistent():
    """Dropping the parasitic motion (x = y = 0, no rotation about z) contradicts the legs: the
    home pose is still reachable, but mobility() says why nothing else is."""
    import yaml

    from parasynth.mechanisms.description import from_description

    data = yaml.safe_load((parasynth.mechanisms._PACKAGE_DIR / "3rps.yaml").read_text())
    data["name"] = "3rps_naive"
    del data["task"]["define"]
    data["task"]["position"] = ["0 mm", "0 mm", "z"]
    data["task"]["orientation"] = {"convention": "xyz", "angles": ["alpha", "beta", 0]}
    m = from_description(data)
    with pytest.warns(DescriptionWarning, match=r"inconsistent parametrisation: a small step of alpha, beta"):
        mob = m.mobility()
    assert not mob.consistent and mob.dof == 3
    assert not m.inverse_kinematics(np.array([0.5, 0.1, 0.1])).reachable


# -- the PRS leg ------------------------------------------------------------------------------------
def test_prs_leg_wrenches_are_reciprocal():
    rng = np.random.default_rng(6)
    leg = PRS("L", base=[0.25, 0.0, 0.0], platform=[0.1, 0.0, 0.0], slider_axis=[0, 0, 1], r_axis=[0, 1, 0],
              link_length=0.3)
    N = 20
    p = np.column_stack([rng.uniform(-0.02, 0.02, N), np.zeros(N), rng.uniform(-0.1, 0.1, N)])
    ang = rng.uniform(-0.3, 0.3, N)
    c, s = np.cos(ang), np.sin(ang)
    R = np.zeros((N, 3, 3))
    R[:, 0, 0], R[:, 0, 2], R[:, 1, 1], R[:, 2, 0], R[:, 2, 2] = c, s, 1, -s, c  # about y: stays in the plane
    st = leg.solve(p, R)
    assert st.reachable.all()
    np.testing.assert_allclose(np.linalg.norm(st.platform_point - st.base_point, axis=1), 0.3, atol=1e-12)
    np.testing.assert_allclose(st.base_point[:, :2], [[0.25, 0.0]] * N, atol=1e-15)  # on the slider line
    P = p + 0.01
    T = leg.joint_twists(st, P)
    C = leg.constraint_wrenches(st, P)
    np.testing.assert_allclose(np.einsum("nki,nji->nkj", C, T), 0.0, atol=1e-12)
    w, scale = leg.actuation_wrench(st, P)
    np.testing.assert_allclose(np.einsum("ni,nji->nj", w, T[:, 1:]), 0.0, atol=1e-12)  # passive joints
    np.testing.assert_allclose(np.einsum("ni,ni->n", w, T[:, 0]), scale, atol=1e-12)  # unit slider rate
    off = leg.solve(p + np.array([0.0, 1e-3, 0.0]), R)
    assert not off.reachable.any()
    with pytest.raises(ValueError, match="perpendicular"):
        PRS("L", base=[0, 0, 0], platform=[0, 0, 0], slider_axis=[0, 0, 1], r_axis=[0, 1, 1])
