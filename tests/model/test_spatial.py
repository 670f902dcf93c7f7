"""Rotations, Euler conventions, twists and wrenches (parasynth.model.spatial).

Reference values are the rotation matrices printed in the three papers, written out entry by
entry, finite differences, and elementary screw-theory facts (a force whose line meets a
revolute axis does no work on it).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _support import random_rotation, vee
from parasynth.model.spatial import (
                                     EULER_CONVENTIONS,
                                     couple_wrench,
                                     euler_rate_map,
                                     euler_to_matrix,
                                     force_wrench,
                                     prismatic_twist,
                                     reciprocal_basis,
                                     revolute_twist,
                                     rot_axis,
                                     rot_x,
                                     rot_y,
                                     rot_z,
                                     skew,
                                     )

angle = st.floats(-np.pi, np.pi, allow_nan=False, allow_infinity=False)
SETTINGS = settings(max_examples=40, deadline=None)


def _n_angles(conv: str) -> int:
    return len(conv)


# ---------------------------------------------------------------------------------------------
# Rotation matrices are proper rotations
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("conv", sorted(EULER_CONVENTIONS))
@SETTINGS
@given(data=st.data())
def test_euler_matrices_are_proper_rotations(conv, data):
    q = np.array(data.draw(st.lists(angle, min_size=len(conv), max_size=len(conv))))
    R = euler_to_matrix(conv, q)
    assert R.shape == (3, 3)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-13)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-13)


@SETTINGS
@given(a=angle, seed=st.integers(0, 2**32 - 1))
def test_elementary_and_axis_rotations_are_proper(a, seed):
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    for R in (rot_x(a), rot_y(a), rot_z(a), rot_axis(axis, a)):
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-13)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-13)
    # rot_axis keeps its axis fixed and turns a perpendicular vector by the angle.
    u = axis / np.linalg.norm(axis)
    np.testing.assert_allclose(rot_axis(axis, a) @ u, u, atol=1e-13)
    w = np.cross(u, rng.normal(size=3))
    w /= np.linalg.norm(w)
    Rw = rot_axis(axis, a) @ w
    assert np.dot(Rw, w) == pytest.approx(np.cos(a), abs=1e-12)
    assert np.dot(np.cross(w, Rw), u) == pytest.approx(np.sin(a), abs=1e-12)


def test_batched_euler_shapes():
    q = np.zeros((4, 7, 3))
    assert euler_to_matrix("zyz", q).shape == (4, 7, 3, 3)
    assert euler_rate_map("zyz", q).shape == (4, 7, 3, 3)
    assert euler_rate_map("yx", np.zeros((5, 2))).shape == (5, 3, 2)


def test_unknown_convention_and_wrong_angle_count():
    with pytest.raises(ValueError, match="convention"):
        euler_to_matrix("abc", [0.0, 0.0, 0.0])
    with pytest.raises(ValueError):
        euler_to_matrix("zyz", [0.0, 0.0])


# ---------------------------------------------------------------------------------------------
# Matrices written out from the papers
# ---------------------------------------------------------------------------------------------


def eq1_2018(theta, phi, psi):
    """An et al. 2018, eq. (1), entry by entry (the "x-z-y" rotation, angles psi, phi, theta)."""
    s, c = np.sin, np.cos
    return np.array(
        [
            [c(theta) * c(phi), s(psi) * s(theta) - c(psi) * c(theta) * s(phi),
             c(psi) * s(theta) + s(psi) * c(theta) * s(phi)],
            [s(phi), c(psi) * c(phi), -s(psi) * c(phi)],
            [-s(theta) * c(phi), s(psi) * c(theta) + c(psi) * s(theta) * s(phi),
             c(psi) * c(theta) - s(psi) * s(theta) * s(phi)],
        ]
    )


def eq2_2022(alpha, beta, gamma):
    """Wang et al. 2022, eq. (2): the z-y-z Euler matrix, entry by entry.

    The plain-text extraction of eq. (2) loses the column separator between the first two
    entries of rows 1 and 2, drops the term ``+ c(alpha) c(gamma)`` of entry (2,2), and prints
    entry (3,2) as ``s(beta) c(gamma)``. The entries below are the ones that agree with the
    paper's own eq. (1) under its eq. (3) substitution (alpha = -(theta1 + theta3),
    beta = theta4, gamma = theta5): eq. (1) has (3,2) = s(theta4) s(theta5), i.e.
    s(beta) s(gamma)."""
    s, c = np.sin, np.cos
    a, b, g = alpha, beta, gamma
    return np.array(
        [
            [c(a) * c(b) * c(g) - s(a) * s(g), -c(a) * c(b) * s(g) - s(a) * c(g), c(a) * s(b)],
            [s(a) * c(b) * c(g) + c(a) * s(g), -s(a) * c(b) * s(g) + c(a) * c(g), s(a) * s(b)],
            [-s(b) * c(g), s(b) * s(g), c(b)],
        ]
    )


def eq7_2021(alpha, beta):
    """Wang, Lyu & Liu 2021, eq. (7), the rotation block of T, entry by entry."""
    s, c = np.sin, np.cos
    return np.array(
        [
            [c(beta), s(beta) * s(alpha), s(beta) * c(alpha)],
            [0.0, c(alpha), -s(alpha)],
            [-s(beta), c(beta) * s(alpha), c(beta) * c(alpha)],
        ]
    )


@SETTINGS
@given(theta=angle, phi=angle, psi=angle)
def test_yzx_is_2018_eq1(theta, phi, psi):
    np.testing.assert_allclose(euler_to_matrix("yzx", (theta, phi, psi)), eq1_2018(theta, phi, psi), atol=1e-14)


@SETTINGS
@given(alpha=angle, beta=angle, gamma=angle)
def test_zyz_is_2022_eq2(alpha, beta, gamma):
    np.testing.assert_allclose(euler_to_matrix("zyz", (alpha, beta, gamma)), eq2_2022(alpha, beta, gamma), atol=1e-14)


@SETTINGS
@given(alpha=angle, beta=angle)
def test_yx_is_2021_eq7(alpha, beta):
    # parasynth's "yx" takes the angles in the order (beta, alpha).
    np.testing.assert_allclose(euler_to_matrix("yx", (beta, alpha)), eq7_2021(alpha, beta), atol=1e-14)


def test_paper_matrices_at_a_known_angle():
    """One hand-checked value, so a wrong reference formula cannot agree by accident:
    a pure 90 deg turn about y maps x to -z (2018 eq. (1) with theta = 90 deg)."""
    R = euler_to_matrix("yzx", (np.pi / 2, 0.0, 0.0))
    np.testing.assert_allclose(R @ [1.0, 0, 0], [0, 0, -1.0], atol=1e-15)
    R = euler_to_matrix("zyz", (np.pi / 2, 0.0, 0.0))
    np.testing.assert_allclose(R @ [1.0, 0, 0], [0, 1.0, 0], atol=1e-15)
    R = euler_to_matrix("yx", (0.0, np.pi / 2))  # alpha = 90 deg about X
    np.testing.assert_allclose(R @ [0, 1.0, 0], [0, 0, 1.0], atol=1e-15)


# ---------------------------------------------------------------------------------------------
# Euler rate maps against finite differences of R
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("conv", sorted(EULER_CONVENTIONS))
@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_euler_rate_map_matches_finite_differences(conv, seed):
    rng = np.random.default_rng(seed)
    k = _n_angles(conv)
    q = rng.uniform(-np.pi, np.pi, size=k)
    qd = rng.normal(size=k)
    h = 1e-6
    R = euler_to_matrix(conv, q)
    dR = (euler_to_matrix(conv, q + h * qd) - euler_to_matrix(conv, q - h * qd)) / (2 * h)
    omega_fd = vee(dR @ R.T)
    omega = euler_rate_map(conv, q) @ qd
    np.testing.assert_allclose(omega, omega_fd, atol=1e-8)


@SETTINGS
@given(theta=angle, psi=angle, thd=st.floats(-2, 2), psd=st.floats(-2, 2))
def test_yzx_rate_map_is_2018_eq30(theta, psi, thd, psd):
    """2018 paper eq. (30) (phi = 0): omega = (psi' c(theta), theta', -psi' s(theta))."""
    E = euler_rate_map("yzx", (theta, 0.0, psi))
    omega = E @ np.array([thd, 0.0, psd])
    expected = np.array([psd * np.cos(theta), thd, -psd * np.sin(theta)])
    np.testing.assert_allclose(omega, expected, atol=1e-14)


# ---------------------------------------------------------------------------------------------
# Twists, wrenches, reciprocity
# ---------------------------------------------------------------------------------------------


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_skew_is_cross_product(seed):
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=(2, 5, 3))
    np.testing.assert_allclose((skew(a) @ b[..., None])[..., 0], np.cross(a, b), atol=1e-14)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_elementary_screws_reciprocity(seed):
    """Textbook facts: a force whose line meets (or is parallel to) a revolute axis does no
    work on it; a force normal to a slide does no work on it; a couple normal to a revolute
    axis does no work on it; and a twist's velocity field is the one of a rigid motion."""
    rng = np.random.default_rng(seed)
    P = rng.normal(size=3)  # reference point
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    c = rng.normal(size=3)  # point of the axis
    t = revolute_twist(axis, c, P)
    meet = c + rng.normal() * axis
    f = rng.normal(size=3)
    assert force_wrench(f, meet, P) @ t == pytest.approx(0.0, abs=1e-12)
    assert force_wrench(axis, rng.normal(size=3), P) @ t == pytest.approx(0.0, abs=1e-12)
    n = np.cross(axis, rng.normal(size=3))
    assert couple_wrench(n) @ t == pytest.approx(0.0, abs=1e-12)
    assert force_wrench(n, rng.normal(size=3), P) @ prismatic_twist(axis) == pytest.approx(0.0, abs=1e-12)
    # A force not meeting the axis does work equal to (moment of the force about the axis).
    Q = rng.normal(size=3)
    expected = np.dot(np.cross(Q - c, f), axis)
    assert force_wrench(f, Q, P) @ t == pytest.approx(expected, abs=1e-12)
    # Velocity of the point Q under the twist: v_P + omega x (Q - P) = axis x (Q - c).
    vQ = t[:3] + np.cross(t[3:], Q - P)
    np.testing.assert_allclose(vQ, np.cross(axis, Q - c), atol=1e-12)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(0, 6), dup=st.integers(0, 2))
def test_reciprocal_basis_is_reciprocal_and_complete(seed, k, dup):
    rng = np.random.default_rng(seed)
    N = 3
    L = 0.3
    T = rng.normal(size=(N, k, 6))
    if dup and k >= 2:
        # Make the system rank deficient: the last twist(s) are combinations of the first.
        T[:, k - 1] = rng.normal() * T[:, 0] + (rng.normal() * T[:, 1] if k >= 3 else 0.0)
        if dup == 2 and k >= 4:
            T[:, k - 2] = rng.normal() * T[:, 0]
    ranks = [np.linalg.matrix_rank(T[i] * np.r_[np.ones(3), L * np.ones(3)], tol=1e-9) if k else 0
             for i in range(N)]
    out = reciprocal_basis(T, L)
    assert len(out) == N
    for i in range(N):
        W = out[i]
        assert W.shape == (6 - ranks[i], 6)
        if W.shape[0]:
            # reciprocal: no work on any input twist
            np.testing.assert_allclose(W @ T[i].T, 0.0, atol=1e-9)
            # independent rows (rank equals dimension)
            Ws = W.copy()
            Ws[:, 3:] /= L
            assert np.linalg.matrix_rank(Ws, tol=1e-9) == W.shape[0]


def test_reciprocal_basis_of_a_universal_prismatic_universal_chain_is_a_couple():
    """Two parallel-axis U joints joined by a slide (axes x, y at both ends): the only wrench
    reciprocal to all five freedoms is the couple about z (the 2021 paper's eq. (6))."""
    P = np.zeros(3)
    top = np.array([0.0, 0.0, 0.2])
    base = np.array([0.0, 0.0, -0.1])
    ex, ey, ez = np.eye(3)
    T = np.stack([
        revolute_twist(ex, base, P), revolute_twist(ey, base, P), prismatic_twist(ez),
        revolute_twist(ex, top, P), revolute_twist(ey, top, P),
    ])[None]
    W = reciprocal_basis(T, 0.1)[0]
    assert W.shape == (1, 6)
    np.testing.assert_allclose(np.abs(W[0]), [0, 0, 0, 0, 0, 1], atol=1e-12)


def test_reciprocal_basis_of_a_revolute_is_five_wrenches():
    T = revolute_twist(np.array([0.0, 0.0, 1.0]), np.array([1.0, 2.0, 0.0]), np.zeros(3))[None, None]
    W = reciprocal_basis(T, 1.0)[0]
    assert W.shape == (5, 6)
    np.testing.assert_allclose(W @ T[0, 0], 0.0, atol=1e-12)


def test_euler_matrix_and_rate_is_both_functions_exactly():
    """One pass over the per-axis rotations gives the matrices and rate maps of
    euler_to_matrix and euler_rate_map bit for bit (and the rate map agrees with a finite
    difference of the matrix: omega from dR R^T)."""
    from parasynth.model.spatial import EULER_CONVENTIONS, euler_matrix_and_rate, euler_rate_map, euler_to_matrix

    rng = np.random.default_rng(5)
    for conv, seq in EULER_CONVENTIONS.items():
        a = rng.uniform(-3, 3, size=(7, len(seq)))
        R, E = euler_matrix_and_rate(conv, a)
        assert np.array_equal(R, euler_to_matrix(conv, a)) and np.array_equal(E, euler_rate_map(conv, a))
        R1, none = euler_matrix_and_rate(conv, a[0], rate=False)
        assert none is None and np.array_equal(R1, euler_to_matrix(conv, a[0]))
        rates, h = rng.normal(size=len(seq)), 1e-6
        dR = (euler_to_matrix(conv, a[0] + h * rates) - euler_to_matrix(conv, a[0] - h * rates)) / (2 * h)
        W = dR @ R[0].T
        omega = np.array([W[2, 1], W[0, 2], W[1, 0]])
        assert np.allclose(omega, E[0] @ rates, atol=1e-7)
    with pytest.raises(ValueError, match="convention"):
        euler_matrix_and_rate("abc", a)


def test_cross_and_axis_rotations_are_bit_for_bit_numpys():
    """spatial.cross against np.cross and rot_x/y/z against the matrices written out with
    np.stack (their earlier form): the same bits, broadcast shapes and signed zeros included."""
    from parasynth.model.spatial import cross, rot_x, rot_y, rot_z

    rng = np.random.default_rng(8)
    for sa, sb in [((3,), (3,)), ((5, 3), (3,)), ((3,), (4, 3)), ((2, 5, 3), (5, 3)), ((1, 3), (7, 3))]:
        a = rng.normal(size=sa) * 10.0 ** rng.integers(-8, 8, size=sa)
        b = rng.normal(size=sb)
        assert np.array_equal(cross(a, b), np.cross(a, b))
        assert cross(a, b).tobytes() == np.cross(a, b).tobytes()
    z = np.array([0.0, -0.0, 1.0])
    assert cross(z, [1.0, 0.0, 0.0]).tobytes() == np.cross(z, [1.0, 0.0, 0.0]).tobytes()  # signed zeros
    a = np.concatenate([rng.uniform(-7, 7, 40), [0.0, -0.0, np.pi, -np.pi / 2]])
    c, s = np.cos(a), np.sin(a)
    o, n = np.ones_like(a), np.zeros_like(a)
    old = {
        rot_x: np.stack([np.stack([o, n, n], -1), np.stack([n, c, -s], -1), np.stack([n, s, c], -1)], -2),
        rot_y: np.stack([np.stack([c, n, s], -1), np.stack([n, o, n], -1), np.stack([-s, n, c], -1)], -2),
        rot_z: np.stack([np.stack([c, -s, n], -1), np.stack([s, c, n], -1), np.stack([n, n, o], -1)], -2),
    }
    for f, M in old.items():
        assert f(a).tobytes() == M.tobytes()
        assert f(a[3]).shape == (3, 3) and f(a[3]).tobytes() == M[3].tobytes()
        assert f(a.reshape(4, 11)).shape == (4, 11, 3, 3)
