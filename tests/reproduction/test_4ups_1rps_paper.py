"""Reproduction of Wang, Liang, Zhou, Yang & Wang (2022), "Analysis of position, pose and force
decoupling characteristics of a 4-UPS/1-RPS parallel grinding robot" (model ``4ups_1rps``).

Paper facts: Table 2 dimensions; the constraining R-P-S branch (Table 1 DH chain, eq. (1))
gives the platform pose of eq. (3)/(7): centre (-d2 s(theta1), d2 c(theta1) - l_s0, 0) and
z-y-z angles alpha = -(theta1 + theta3), beta = theta4, gamma = theta5; the branch constrains
the motion along Z (Section 3.1), a force along Z through the platform centre; driving-leg
lengths from eq. (8), l_i = |C + R A_i - B_i|. Mobility: Grübler-Kutzbach
6(12 - 15 - 1) + 29 = 5 and screw theory 5 freedoms (2T3R) for four actuators, so one freedom
is not controlled by the legs (the paper's constant-force actuator closes it).
"""

from __future__ import annotations

import numpy as np
import pytest

import parasynth
from parasynth.model.spatial import reciprocal_basis

DEG = np.pi / 180


@pytest.fixture(scope="module")
def m():
    return parasynth.load_mechanism("4ups_1rps")


def eq2(alpha, beta, gamma):
    """Eq. (2), z-y-z Euler matrix (see tests/model/test_spatial.py for the resolved entries)."""
    s, c = np.sin, np.cos
    a, b, g = alpha, beta, gamma
    return np.array([
        [c(a) * c(b) * c(g) - s(a) * s(g), -c(a) * c(b) * s(g) - s(a) * c(g), c(a) * s(b)],
        [s(a) * c(b) * c(g) + c(a) * s(g), -s(a) * c(b) * s(g) + c(a) * c(g), s(a) * s(b)],
        [-s(b) * c(g), s(b) * s(g), c(b)],
    ])


def eq1(theta1, d2, theta3, theta4, theta5, l_s0):
    """Eq. (1), the DH transform of the R-P-S branch, entry by entry. Entry (1,2) is printed
    with c(theta3) where every other entry has c(theta13); c(theta13) is the value that
    keeps the matrix orthonormal and equal to eq. (2) under eq. (3)."""
    s, c = np.sin, np.cos
    s13, c13 = s(theta1 + theta3), c(theta1 + theta3)
    t4, t5 = theta4, theta5
    return np.array([
        [c13 * c(t4) * c(t5) + s13 * s(t5), -c13 * c(t4) * s(t5) + s13 * c(t5), c13 * s(t4), -d2 * s(theta1)],
        [-s13 * c(t4) * c(t5) + c13 * s(t5), s13 * c(t4) * s(t5) + c13 * c(t5), -s13 * s(t4), d2 * c(theta1) - l_s0],
        [-s(t4) * c(t5), s(t4) * s(t5), c(t4), 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ])


def eq3(theta1, d2, theta3, theta4, theta5, l_s0):
    """Eq. (3): task coordinates (x, y, alpha, beta, gamma) from the branch's joint values."""
    return np.array([-d2 * np.sin(theta1), d2 * np.cos(theta1) - l_s0, -(theta1 + theta3), theta4, theta5])


def branch_samples(m, n=12, seed=2022):
    """Joint values of the constraining branch within Table 2's limits, with moderate
    sphere angles."""
    rng = np.random.default_rng(seed)
    P = m.params
    th1 = rng.uniform(-P.theta1_max, P.theta1_max, n) * 0.5
    d2 = rng.uniform(P.d2_min, P.d2_max, n)
    th3 = rng.uniform(-0.3, 0.3, n)
    th4 = rng.uniform(-0.3, 0.3, n)
    th5 = rng.uniform(-0.3, 0.3, n)
    return np.c_[th1, d2, th3, th4, th5]


def test_table2_parameters(m):
    P = m.params
    assert P.platform_radius == pytest.approx(0.1)
    assert P.base_radius == pytest.approx(0.335)
    assert P.mu1 == pytest.approx(53 * DEG)
    assert P.mu2 == pytest.approx(127 * DEG)
    assert P.l_s0 == pytest.approx(0.05)
    assert P.y_t == pytest.approx(0.075)
    assert (P.l_min, P.l_max) == pytest.approx((0.43, 0.68))
    assert (P.d2_min, P.d2_max) == pytest.approx((0.32, 0.55))
    assert P.theta1_max == pytest.approx(np.pi / 3)
    assert m.task_coordinates == ("x", "y", "alpha", "beta", "gamma")
    assert len(m.actuators) == 4


def test_anchor_geometry_follows_table2(m):
    """Universal joints at the corners of a rectangle inscribed in the circle of radius
    Rs = 0.335 m, 53 deg (U1-U2) and 127 deg (U2-U3) apart seen from its centre; spheres
    evenly spaced on the platform circle of radius R = 0.1 m; the constraining revolute axis
    at l_s0 = 0.05 m from the fixed-platform centre."""
    ups = [leg for leg in m.legs if type(leg).joints == "UPS"]
    assert len(ups) == 4
    U = np.array([leg.base for leg in ups])
    S = np.array([leg.platform for leg in ups])
    c = U.mean(axis=0)
    n = np.cross(U[1] - U[0], U[2] - U[0])
    np.testing.assert_allclose((U - c) @ n, 0.0, atol=1e-12)  # coplanar
    np.testing.assert_allclose(np.linalg.norm(U - c, axis=1), 0.335, atol=1e-12)

    def ang(a, b):
        return np.arccos(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b))

    assert ang(U[0] - c, U[1] - c) == pytest.approx(53 * DEG, abs=1e-12)
    assert ang(U[1] - c, U[2] - c) == pytest.approx(127 * DEG, abs=1e-12)
    assert ang(U[2] - c, U[3] - c) == pytest.approx(53 * DEG, abs=1e-12)
    np.testing.assert_allclose(np.linalg.norm(S, axis=1), 0.1, atol=1e-12)
    for i in range(4):
        assert ang(S[i], S[(i + 1) % 4]) == pytest.approx(90 * DEG, abs=1e-12)
    rps = [leg for leg in m.legs if type(leg).joints == "RPS"]
    assert len(rps) == 1
    r, b = rps[0].r_axis, rps[0].base
    # the fixed-platform centre: the rectangle's centre in the plane Y = 0 (the universal-joint
    # centres lie base_offset from that plane)
    centre = c - np.array([0.0, m.params.base_offset, 0.0])
    np.testing.assert_allclose(centre, 0.0, atol=1e-12)
    dist = np.linalg.norm(np.cross(centre - b, r))
    assert dist == pytest.approx(0.05, abs=1e-12)
    np.testing.assert_allclose(np.abs(r), [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(rps[0].platform, 0.0, atol=1e-15)  # sphere at the platform centre


def test_platform_pose_is_eq1_eq3(m):
    l_s0 = m.params.l_s0
    for th1, d2, th3, th4, th5 in branch_samples(m):
        X = eq3(th1, d2, th3, th4, th5, l_s0)
        p, R = m.pose(X[None])
        T = eq1(th1, d2, th3, th4, th5, l_s0)
        np.testing.assert_allclose(R[0], T[:3, :3], atol=1e-14)
        np.testing.assert_allclose(p[0], T[:3, 3], atol=1e-14)  # eq. (7): z = 0
        np.testing.assert_allclose(R[0], eq2(*X[2:]), atol=1e-14)


def test_constraining_branch_joint_values_from_ik(m):
    """The model's R-P-S branch at the pose of eq. (3) has prismatic length d2 and revolute
    angle theta1 (measured from its direction at the home pose)."""
    l_s0 = m.params.l_s0
    xh, yh = m.home[0], m.home[1]
    theta1_home = np.arctan2(-xh, yh + l_s0)
    samples = branch_samples(m)
    X = np.array([eq3(*s, l_s0) for s in samples])
    ik = m.inverse_kinematics(X)
    assert np.all(ik.reachable)
    rps_index = [i for i, leg in enumerate(m.legs) if type(leg).joints == "RPS"][0]
    name = m.legs[rps_index].name
    np.testing.assert_allclose(ik.legs[rps_index].length, samples[:, 1], atol=1e-14)
    np.testing.assert_allclose(ik.passive_angles[f"{name}.R_base"], samples[:, 0] - theta1_home, atol=1e-12)


def test_leg_lengths_eq8(m):
    """l_i = |C + R A_i - B_i| with C from eq. (7) and R from eq. (2), computed here."""
    l_s0 = m.params.l_s0
    ups = [leg for leg in m.legs if type(leg).joints == "UPS"]
    X = np.array([eq3(*s, l_s0) for s in branch_samples(m)])
    ik = m.inverse_kinematics(X)
    assert np.all(ik.reachable)
    for k, Xk in enumerate(X):
        C = np.array([Xk[0], Xk[1], 0.0])
        R = eq2(*Xk[2:])
        lengths = [np.linalg.norm(C + R @ leg.platform - leg.base) for leg in ups]
        np.testing.assert_allclose(ik.actuators[k], lengths, atol=1e-14)


def test_mobility(m):
    mob = m.mobility()
    assert (mob.n_links, mob.n_joints, mob.sum_joint_dof) == (12, 15, 29)
    assert mob.gruebler == 6 * (12 - 15 - 1) + 29 == 5
    assert mob.dof == 5
    assert mob.type == "2T3R"
    assert mob.constraint_rank == 1
    assert mob.n_actuators == 4
    assert mob.controlled is False
    assert mob.uncontrolled_twists.shape == (1, 6)
    t = mob.uncontrolled_twists[0]
    assert np.linalg.norm(t) > 0.5
    # the uncontrolled twist is a freedom (no work against the constraint) that no actuated
    # leg sees
    W = m.wrench_matrix(m.home)
    np.testing.assert_allclose(W @ t, 0.0, atol=1e-9)
    # and it is structural: one freedom stays uncontrolled at other poses too
    X = m.home + np.array([0.02, -0.03, 0.2, 0.15, -0.1])
    mob2 = m.mobility(X)
    assert mob2.controlled is False and mob2.uncontrolled_twists.shape == (1, 6)


def test_rps_constraint_is_force_along_z_through_platform_centre(m):
    X = np.array([eq3(*s, m.params.l_s0) for s in branch_samples(m, n=6, seed=5)])
    W = m.wrench_matrix(X)
    C = W[:, len(m.actuators):]
    assert C.shape[1] == 1
    # about the platform centre (the reference point): force along Z, zero moment
    np.testing.assert_allclose(np.abs(C[:, 0]), np.tile([0, 0, 1.0, 0, 0, 0], (len(X), 1)), atol=1e-14)
    # independently: the complement of the R-P-S branch's joint twists
    ik = m.inverse_kinematics(X)
    k = [i for i, leg in enumerate(m.legs) if type(leg).joints == "RPS"][0]
    p, _ = m.pose(X)
    T = m.legs[k].joint_twists(ik.legs[k], p)
    for Wi in reciprocal_basis(T, m.length_scale):
        assert Wi.shape == (1, 6)
        np.testing.assert_allclose(np.abs(Wi[0]), [0, 0, 1.0, 0, 0, 0], atol=1e-12)


def test_fk_with_fixed_gamma_recovers_branch_pose(m):
    """Forward kinematics with gamma held (the under-actuated freedom) recovers the pose of
    eq. (3) from the four leg lengths."""
    l_s0 = m.params.l_s0
    s = np.array([0.1, 0.45, 0.1, 0.2, -0.15])
    X = eq3(*s, l_s0)
    q = m.inverse_kinematics(X).actuators
    Xf = m.forward_kinematics(q, guess=X + np.array([0.005, -0.005, 0.02, 0.02, 0.0]), fixed={"gamma": X[4]})
    np.testing.assert_allclose(Xf, X, atol=1e-9)
    d2 = np.hypot(Xf[0], Xf[1] + l_s0)
    th1 = np.arctan2(-Xf[0], Xf[1] + l_s0)
    assert (th1, d2) == pytest.approx((s[0], s[1]), abs=1e-9)
