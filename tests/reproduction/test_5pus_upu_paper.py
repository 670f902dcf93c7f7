"""Reproduction of Wang, Lyu & Liu (2021), "Kinematic analysis and verification of a new
5-DOF parallel mechanism" (model ``5pus_upu``).

Paper facts: eq. (2) mobility count M = 6(14 - 18 - 1) + 35 = 5; Section 2.2.2 screw analysis
(3T2R; the U-P-U limb's reciprocal screw is the couple (0 0 0; 0 0 1) of eq. (6)); Section 2.3
structural singularity of the first (pentagonal) scheme with the platform parallel to the
base above the origin: the five link force lines meet in one point, the five forces have
rank 3 and the whole system rank 4; Section 2.4 the improved scheme is not singular there;
eq. (11) inverse kinematics with the positive sign (sliders above the platform) and the
prototype dimensions of Section 3.2 (R = 135 mm, L = 205 mm, sphere centres).
"""

from __future__ import annotations

import numpy as np
import pytest

import parasynth
from _support import closest_point_to_lines

MM = 1e-3
DEG = np.pi / 180
SPHERES_MM = [(35, 51), (-35, 51), (-51, -35), (51, -35), (0, 51)]  # Section 3.2


@pytest.fixture(scope="module")
def improved():
    return parasynth.load_mechanism("5pus_upu")


@pytest.fixture(scope="module")
def first():
    return parasynth.load_mechanism("5pus_upu", platform="pentagonal")


def test_prototype_dimensions(improved):
    p = improved.params
    assert p.slider_radius == pytest.approx(0.135)
    assert p.link_length == pytest.approx(0.205)
    np.testing.assert_allclose(np.array(p.hinge_points) / MM, SPHERES_MM, atol=1e-9)
    # sliders on a regular pentagon of radius R (Section 2.1)
    ang = np.sort(np.mod(p.slider_angles, 2 * np.pi))
    np.testing.assert_allclose(np.diff(np.r_[ang, ang[0] + 2 * np.pi]), 72 * DEG, atol=1e-12)
    assert improved.task_coordinates == ("x", "y", "z", "alpha", "beta")
    assert len(improved.actuators) == 5


@pytest.mark.parametrize("platform", ["rectangular", "pentagonal"])
def test_mobility_eq2_and_screw_analysis(platform):
    m = parasynth.load_mechanism("5pus_upu", platform=platform)
    mob = m.mobility()
    assert (mob.n_links, mob.n_joints, mob.sum_joint_dof) == (14, 18, 35)
    assert mob.gruebler == 6 * (14 - 18 - 1) + 35 == 5
    assert mob.dof == 5
    assert mob.type == "3T2R"
    assert mob.constraint_rank == 1
    # the platform cannot spin about Z: no freedom has an omega_z component
    np.testing.assert_allclose(mob.twist_basis[:, 5], 0.0, atol=1e-12)


def test_upu_constraint_is_a_couple_about_z_eq6(improved, first):
    for m in (improved, first):
        C = m.wrench_matrix(m.home)[5:]
        assert C.shape == (1, 6)
        np.testing.assert_allclose(np.abs(C[0]), [0, 0, 0, 0, 0, 1], atol=1e-12)
    # the same from the U-P-U limb's own twists (eq. (6)), independently of the analytic row
    from parasynth.model.spatial import reciprocal_basis

    ik = improved.inverse_kinematics(improved.home)
    leg, st_ = improved.legs[5], ik.legs[5]
    T = leg.joint_twists(st_, np.zeros((1, 3)))
    W = reciprocal_basis(T, 0.1)[0]
    assert W.shape == (1, 6)
    np.testing.assert_allclose(np.abs(W[0]), [0, 0, 0, 0, 0, 1], atol=1e-12)


def _link_lines(m, X):
    ik = m.inverse_kinematics(X)
    assert bool(ik.reachable)
    pts = np.array([st.base_point[0] for st in ik.legs[:5]])
    dirs = np.array([st.platform_point[0] - st.base_point[0] for st in ik.legs[:5]])
    return pts, dirs


def test_first_scheme_structural_singularity_at_home(first):
    X = first.home
    np.testing.assert_allclose(X, 0.0)  # platform parallel to the base, above the origin
    assert first.singularity_margin(X) < 1e-9
    pts, dirs = _link_lines(first, X)
    centre, worst = closest_point_to_lines(pts, dirs)
    assert worst < 1e-12  # the five link lines meet in one point ...
    assert abs(centre[0]) < 1e-12 and abs(centre[1]) < 1e-12  # ... on the Z axis
    # rank of the five force lines is 3, of the whole system (plus the couple) 4
    W = first.wrench_matrix(X)
    L = first.length_scale
    Ws = W * np.r_[np.ones(3), np.ones(3) / L]
    assert np.linalg.matrix_rank(Ws[:5], tol=1e-9) == 3
    assert np.linalg.matrix_rank(Ws, tol=1e-9) == 4
    mob = first.mobility()
    assert mob.singular_at_pose and mob.controlled
    assert len(mob.uncontrolled_twists) == 2  # the rotations about X and Y
    np.testing.assert_allclose(mob.uncontrolled_twists[:, 5], 0.0, atol=1e-9)


def test_first_scheme_not_singular_away_from_home(first):
    X = np.array([0.01, -0.01, 0.0, 0.2, -0.2])
    assert first.singularity_margin(X) > 1e-3


def test_improved_scheme_not_singular_at_home(improved):
    assert improved.singularity_margin(improved.home) > 0.05
    pts, dirs = _link_lines(improved, improved.home)
    _, worst = closest_point_to_lines(pts, dirs)
    assert worst > 1e-3  # the lines do not meet
    W = improved.wrench_matrix(improved.home)
    Ws = W * np.r_[np.ones(3), np.ones(3) / improved.length_scale]
    assert np.linalg.matrix_rank(Ws, tol=1e-9) == 6
    mob = improved.mobility()
    assert mob.controlled and not mob.singular_at_pose and len(mob.uncontrolled_twists) == 0


def eq7(alpha, beta):
    s, c = np.sin, np.cos
    return np.array([[c(beta), s(beta) * s(alpha), s(beta) * c(alpha)],
                     [0.0, c(alpha), -s(alpha)],
                     [-s(beta), c(beta) * s(alpha), c(beta) * c(alpha)]])


def limb_consistent(X, upu_base_z=-0.15):
    """The model's orientation R = Ry(q1) Rx(alpha) Ry(beta - q1), q1 = atan2(x, z - z_B),
    written out with explicit matrices; it equals eq. (7) when alpha = 0 or beta = q1."""
    x, y, z, alpha, beta = X
    q1 = np.arctan2(x, z - upu_base_z)

    def Ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def Rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    return Ry(q1) @ Rx(alpha) @ Ry(beta - q1)


def eq11_sliders(X, slider_angles, spheres, R_=0.135, L=0.205, Rm=None):
    """Eq. (8) then eq. (11) with the positive sign: Z_i^U = Z_i^S + sqrt(L^2 - dX^2 - dY^2),
    with U_i' = R (cos a_i, sin a_i) the slider positions on the pentagon."""
    x, y, z, alpha, beta = X
    Rm = eq7(alpha, beta) if Rm is None else Rm
    out = []
    for a, (sx, sy) in zip(slider_angles, spheres):
        S = np.array([x, y, z]) + Rm @ np.array([sx, sy, 0.0])
        Ux, Uy = R_ * np.cos(a), R_ * np.sin(a)
        out.append(S[2] + np.sqrt(L**2 - (Ux - S[0]) ** 2 - (Uy - S[1]) ** 2))
    return np.array(out)


def test_slider_ik_matches_eq11(improved):
    rng = np.random.default_rng(2021)
    spheres = np.array(SPHERES_MM) * MM
    ang = improved.params.slider_angles
    # Where the model's orientation is eq. (7) exactly: alpha = 0, or beta = q1 (the limb's
    # base-joint rotation, atan2(x, z - z_B)).
    A = np.c_[rng.uniform(-0.02, 0.02, (20, 3)), np.zeros(20), rng.uniform(-10, 10, 20) * DEG]
    B = np.c_[rng.uniform(-0.02, 0.02, (20, 3)), rng.uniform(-10, 10, 20) * DEG, np.zeros(20)]
    B[:, 4] = np.arctan2(B[:, 0], B[:, 2] + 0.15)
    # and points of the eq. (13) test trajectory (x = 0, beta = 0, alpha = 0 platform attitude)
    t = np.linspace(0.0, 10.0, 6)
    u = np.pi / 3 + np.pi * t / 30
    C = np.c_[np.zeros_like(u), 0.050 * np.cos(u), -0.050 * np.sin(u), 0 * u, 0 * u]
    X = np.r_[A, B, C]
    ik = improved.inverse_kinematics(X)
    assert np.all(ik.reachable)
    expected = np.array([eq11_sliders(Xi, ang, spheres) for Xi in X])
    np.testing.assert_allclose(ik.actuators, expected, atol=1e-12)
    # the sliders are above the platform (the sign choice of eq. (11))
    assert np.all(ik.actuators > X[:, [2]])
    # General poses: eq. (11) with the limb-consistent orientation (documented departure).
    G = np.c_[rng.uniform(-0.02, 0.02, (20, 3)), rng.uniform(-10, 10, (20, 2)) * DEG]
    expected = np.array([eq11_sliders(Xi, ang, spheres, Rm=limb_consistent(Xi)) for Xi in G])
    np.testing.assert_allclose(improved.inverse_kinematics(G).actuators, expected, atol=1e-12)


def test_slider_ik_first_scheme_matches_eq11(first):
    p = first.params
    spheres = [(p.pentagon_radius * np.cos(a), p.pentagon_radius * np.sin(a)) for a in p.slider_angles]
    X = np.array([0.0, 0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(first.inverse_kinematics(X).actuators,
                               eq11_sliders(X, p.slider_angles, spheres), atol=1e-12)
    # at home all five sliders are at the same height (symmetry of the first scheme)
    q = first.inverse_kinematics(X).actuators
    expected = np.sqrt(0.205**2 - (0.135 - p.pentagon_radius) ** 2)
    np.testing.assert_allclose(q, expected, atol=1e-12)
