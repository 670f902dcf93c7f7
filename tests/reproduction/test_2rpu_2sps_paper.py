"""Reproduction of An, Li, Wang & Ge (2018), "Kinematics and transmission performance
analyses of a 2T2R type 4-DOF spatial parallel manipulator" (model ``2rpu_2sps``).

Paper values: Table 1 (inverse position), Table 2 (forward position), the mobility count of
eq. (2), the 2T2R screw analysis of Section 3, and the actuation singularity of Section 5.2
(theta = 0 and theta = 77.63 deg).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import parasynth

MM = 1e-3
DEG = np.pi / 180

# Table 1: inputs (psi deg, theta deg, z mm, x mm) -> outputs q1..q4 (mm).
# Case (b) prints x = -74.1670; with x = z tan(theta) (eq. (10)) it is -174.1670 (typo).
TABLE1 = {
    "a": ((25.0, 15.0, 650.0, 174.1670), (736.8688, 639.0079, 844.7550, 807.5673)),
    "b": ((25.0, -15.0, 650.0, -174.1670), (736.8688, 807.5673, 844.7550, 639.0079)),
}
PRINTED_X_CASE_B = -74.1670
# Table 2: inputs q1..q4 (mm) -> outputs (psi deg, theta deg, z mm, x mm).
TABLE2 = {
    "a": ((736.8688, 639.0079, 844.7550, 807.5673), (25.0, 15.0, 650.0, 174.1670)),
    "b": ((736.8688, 807.5673, 844.7550, 639.0079), (25.0, -15.0, 650.0, -174.1670)),
}
A = (0.150, 0.075, 0.150, 0.075)  # a1..a4 (m), Section 4.3
B = (0.550, 0.350, 0.550, 0.350)  # b1..b4


def eq1(theta, phi, psi):
    s, c = np.sin, np.cos
    return np.array([
        [c(theta) * c(phi), s(psi) * s(theta) - c(psi) * c(theta) * s(phi), c(psi) * s(theta) + s(psi) * c(theta) * s(phi)],
        [s(phi), c(psi) * c(phi), -s(psi) * c(phi)],
        [-s(theta) * c(phi), s(psi) * c(theta) + c(psi) * s(theta) * s(phi), c(psi) * c(theta) - s(psi) * s(theta) * s(phi)],
    ])


def eq11_lengths(x, z, psi, theta):
    """Leg lengths from the paper's eq. (11), q_i = |r - b_i + a_i| with a_i = R a_i0 and the
    anchors of eq. (6); r = (x, 0, z), phi = 0 (eq. (10))."""
    R = eq1(theta, 0.0, psi)
    dirs = [np.array([0, -1.0, 0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([-1.0, 0, 0])]
    r = np.array([x, 0.0, z])
    return np.array([np.linalg.norm(r - b * d + R @ (a * d)) for a, b, d in zip(A, B, dirs)])


@pytest.fixture(scope="module")
def coupled():
    return parasynth.load_mechanism("2rpu_2sps")


@pytest.fixture(scope="module")
def free():
    return parasynth.load_mechanism("2rpu_2sps", coupled=False)


def test_default_parameters_are_section_4_3(coupled):
    p = coupled.params
    assert (p.a1, p.a2, p.a3, p.a4) == A
    assert (p.b1, p.b2, p.b3, p.b4) == B
    assert coupled.task_coordinates == ("z", "psi", "theta")
    assert coupled.actuators == ("q1", "q2", "q3", "q4")


@pytest.mark.parametrize("case", ["a", "b"])
def test_table1_inverse_kinematics(coupled, free, case):
    (psi, theta, z, x), q_paper = TABLE1[case]
    X = np.array([z * MM, psi * DEG, theta * DEG])
    ik = coupled.inverse_kinematics(X)
    assert bool(ik.reachable)
    np.testing.assert_allclose(ik.actuators / MM, q_paper, atol=1e-3)
    # the dependent coordinate x = z tan(theta) of eq. (10) is the table's x
    assert coupled.x_of(X) / MM == pytest.approx(x, abs=1e-3)
    # the uncoupled model at the same (x, z, psi, theta) gives the same lengths
    ik_free = free.inverse_kinematics(np.array([x * MM, z * MM, psi * DEG, theta * DEG]))
    np.testing.assert_allclose(ik_free.actuators / MM, q_paper, atol=1e-3)
    # and so does eq. (11) written out independently
    np.testing.assert_allclose(eq11_lengths(x * MM, z * MM, psi * DEG, theta * DEG) / MM, q_paper, atol=1e-3)


def test_table1_case_b_x_is_a_typo():
    """Case (b): x = z tan(theta) = 650 tan(-15 deg) = -174.1670 mm; the printed -74.1670 does
    not satisfy eq. (10) and does not give the table's leg lengths."""
    x = 650.0 * np.tan(-15.0 * DEG)
    assert x == pytest.approx(-174.1670, abs=1e-4)
    assert abs(x - PRINTED_X_CASE_B) == pytest.approx(100.0, abs=1e-3)
    q_printed_x = eq11_lengths(PRINTED_X_CASE_B * MM, 0.650, 25 * DEG, -15 * DEG) / MM
    assert np.max(np.abs(q_printed_x - np.array(TABLE1["b"][1]))) > 10.0


@pytest.mark.parametrize("case", ["a", "b"])
def test_table2_forward_kinematics_exact_inputs(coupled, free, case):
    """The unrounded leg lengths of the table's pose (eq. (11), computed independently, with
    x = z tan(theta) unrounded) give back the table's outputs to 1e-6 deg and 1e-3 mm, in
    both parametrisations."""
    _, (psi, theta, z, x) = TABLE2[case]
    q = eq11_lengths(z * MM * np.tan(theta * DEG), z * MM, psi * DEG, theta * DEG)
    np.testing.assert_allclose(q / MM, TABLE2[case][0], atol=1e-3)  # the table's inputs
    guess = np.array([0.70, 0.3, np.sign(theta) * 0.2])
    zf, psif, thf = coupled.forward_kinematics(q, guess=guess)
    assert psif / DEG == pytest.approx(psi, abs=1e-6)
    assert thf / DEG == pytest.approx(theta, abs=1e-6)
    assert zf / MM == pytest.approx(z, abs=1e-3)
    assert coupled.x_of(np.array([zf, psif, thf])) / MM == pytest.approx(x, abs=1e-3)
    xf, zf, psif, thf = free.forward_kinematics(q, guess=np.r_[x * MM + 0.01, guess])
    assert (psif / DEG, thf / DEG) == pytest.approx((psi, theta), abs=1e-6)
    assert (xf / MM, zf / MM) == pytest.approx((x, z), abs=1e-3)


@pytest.mark.parametrize("case", ["a", "b"])
def test_table2_forward_kinematics_printed_inputs(coupled, case):
    """The printed inputs are rounded to 1e-4 mm, so four lengths over-determine the three
    coordinates only to ~1e-8 m: the solve needs a tolerance matching that rounding
    (``tol``), and the outputs can match the table only within the propagated rounding
    error (|J^+| * 5e-5 mm: 3e-5 deg in psi, 1e-5 deg in theta, 6e-5 mm in z)."""
    q_paper, (psi, theta, z, x) = TABLE2[case]
    q = np.array(q_paper) * MM
    guess = np.array([0.70, 0.3, np.sign(theta) * 0.2])
    zf, psif, thf = coupled.forward_kinematics(q, guess=guess, tol=1e-10)
    assert psif / DEG == pytest.approx(psi, abs=1e-4)
    assert thf / DEG == pytest.approx(theta, abs=1e-4)
    assert zf / MM == pytest.approx(z, abs=1e-3)
    assert coupled.x_of(np.array([zf, psif, thf])) / MM == pytest.approx(x, abs=1e-3)


def test_mobility_eq2_and_screw_analysis(coupled, free):
    """Eq. (2): F = 6(10 - 12 - 1) + 22 + 2 - 2 = 4; Section 3: 2T2R, the RPU limbs
    constrain a translation along y and a rotation about z."""
    for m in (coupled, free):
        mob = m.mobility()
        assert mob.dof == 4
        assert mob.type == "2T2R"
        assert (mob.n_links, mob.n_joints, mob.sum_joint_dof) == (10, 12, 22)
        assert mob.gruebler == 6 * (10 - 12 - 1) + 22 == 4
        assert (mob.redundant_constraints, mob.local_dof) == (2, 2)
        assert mob.gruebler_corrected == 6 * (10 - 12 - 1) + 22 + 2 - 2 == 4
        assert mob.n_actuators == 4 and mob.controlled
        # the freedoms: no translation along y, no rotation about the constrained couple
        Tb = mob.twist_basis
        np.testing.assert_allclose(Tb[:, 1], 0.0, atol=1e-12)


def test_rpu_constraints_eq4_at_zero_tilt(free):
    """Eq. (4) (limb frame with the revolute axis along y): a force along y and a couple
    about z. At theta = 0 the limb frame is the base frame."""
    X = np.array([0.0, 0.75, 0.3, 0.0])
    C = free.wrench_matrix(X)[4:]
    forces = C[np.linalg.norm(C[:, :3], axis=1) > 0.5]
    couples = C[np.linalg.norm(C[:, :3], axis=1) < 1e-12]
    assert len(forces) == 2 and len(couples) == 2
    np.testing.assert_allclose(np.abs(forces[:, :3]), [[0, 1, 0]] * 2, atol=1e-12)
    np.testing.assert_allclose(np.abs(couples[:, 3:]), [[0, 0, 1]] * 2, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# Section 5.2: actuation singularity at theta = 0 and theta = 77.63 deg
# ---------------------------------------------------------------------------------------------


def _det_library(free, z, psi, theta):
    return np.linalg.det(free.jacobian(np.array([z * np.tan(theta), z, psi, theta])))


def _det_eq11(z, psi, theta, h=1e-6):
    """det of d(q)/d(x, z, psi, theta) by central differences of eq. (11), independently of
    parasynth."""
    X = np.array([z * np.tan(theta), z, psi, theta])
    J = np.zeros((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = h
        J[:, j] = (eq11_lengths(*(X + e)) - eq11_lengths(*(X - e))) / (2 * h)
    return np.linalg.det(J)


@pytest.mark.parametrize("z,psi_deg", [(0.65, 25.0), (0.75, 0.0), (0.85, -30.0)])
def test_singularity_at_77_63_deg(coupled, free, z, psi_deg):
    psi = psi_deg * DEG
    root = brentq(lambda t: _det_library(free, z, psi, t), 60 * DEG, 85 * DEG, xtol=1e-13)
    assert root / DEG == pytest.approx(77.63, abs=0.01)
    root_ref = brentq(lambda t: _det_eq11(z, psi, t), 60 * DEG, 85 * DEG, xtol=1e-13)
    assert root / DEG == pytest.approx(root_ref / DEG, abs=1e-5)
    # the margin vanishes there on the coupled manifold, and not away from it
    assert coupled.singularity_margin(np.array([z, psi, root])) < 1e-9
    assert free.singularity_margin(np.array([z * np.tan(root), z, psi, root])) < 1e-9
    assert coupled.singularity_margin(np.array([z, psi, 40 * DEG])) > 1e-3
    assert coupled.singularity_margin(np.array([z, psi, 70 * DEG])) > 1e-4


@pytest.mark.parametrize("z,psi_deg", [(0.65, 25.0), (0.80, -10.0)])
def test_singularity_at_zero_tilt(coupled, free, z, psi_deg):
    psi = psi_deg * DEG
    assert abs(_det_library(free, z, psi, 0.0)) < 1e-12
    assert abs(_det_eq11(z, psi, 0.0)) < 1e-8
    assert coupled.singularity_margin(np.array([z, psi, 0.0])) < 1e-9
    # and the determinant changes sign through theta = 0 (a genuine crossing)
    assert _det_library(free, z, psi, -5 * DEG) * _det_library(free, z, psi, 5 * DEG) < 0
    assert coupled.singularity_margin(np.array([z, psi, 10 * DEG])) > 1e-3
