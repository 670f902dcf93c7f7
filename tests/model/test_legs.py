"""Leg types (parasynth.model.legs): reciprocity of the analytic actuation and constraint wrenches
to the legs' joint twists, and the PUS slider inverse kinematics.

Legs are built with random anchors and axes, at random poses that satisfy each leg's
geometric conditions (planar legs in their plane, PUS spheres within reach of the slider).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _support import random_rotation
from parasynth.model.legs import PRS, PUS, RPS, RPU, RUS, SPS, UPS, UPU, _axis

#: Freedoms per joint letter (independent of parasynth.model.legs.JOINT_DOF).
DOF = {"R": 1, "P": 1, "U": 2, "S": 3}
#: Joint sequence, index of the actuated (or, for passive legs, the prismatic) joint, and the
#: number of constraint wrenches each leg type imposes (6 minus the rank of its twists).
SPEC = {
    "SPS": ("SPS", 1, 0),
    "UPS": ("UPS", 1, 0),
    "PUS": ("PUS", 0, 0),
    "RPS": ("RPS", 1, 1),
    "RPU": ("RPU", 1, 2),
    "UPU": ("UPU", 1, 1),
}
KINDS = sorted(SPEC)
N = 8
SETTINGS = settings(max_examples=25, deadline=None)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _rotation_taking(a, b):
    """Rotation matrix taking unit vector a onto unit vector b (Rodrigues, written here)."""
    v = np.cross(a, b)
    s, c = np.linalg.norm(v), np.dot(a, b)
    if s < 1e-15:
        return np.eye(3)
    k = v / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * K @ K


def make_leg_and_poses(kind: str, rng: np.random.Generator, n: int = N, branch: int = 1):
    """A random leg of type ``kind`` and n poses (p, R) it can reach."""
    base = rng.uniform(-0.5, 0.5, 3)
    plat = rng.uniform(-0.2, 0.2, 3)
    R = np.stack([random_rotation(rng) for _ in range(n)])
    p = rng.uniform(-0.3, 0.3, (n, 3)) + np.array([0.0, 0.0, 0.6])
    if kind == "SPS":
        leg = SPS("leg", base=base, platform=plat)
    elif kind == "UPS":
        leg = UPS("leg", base=base, platform=plat, u_axis=_unit(rng.normal(size=3)))
    elif kind == "UPU":
        leg = UPU("leg", base=base, platform=plat, u_axis=_unit(rng.normal(size=3)),
                  u_platform_axis=_unit(rng.normal(size=3)), passive=bool(rng.integers(2)))
    elif kind == "PUS":
        e = _unit(rng.normal(size=3))
        L = 0.3
        leg = PUS("leg", base=base, platform=plat, slider_axis=e, link_length=L, branch=branch,
                  u_axis=_unit(np.cross(e, rng.normal(size=3))))
        # Put the universal joint somewhere on the slider and the sphere at distance L from
        # it, on the side required by the branch, with the link well away from normal to e.
        for i in range(n):
            while True:
                d = _unit(rng.normal(size=3))
                if -branch * np.dot(d, e) > 0.3:
                    break
            U = base + rng.uniform(-0.2, 0.2) * e
            S = U + L * d
            p[i] = S - R[i] @ plat
    elif kind in ("RPS", "RPU"):
        r = _unit(rng.normal(size=3))
        if kind == "RPS":
            leg = RPS("leg", base=base, platform=plat, r_axis=r, passive=bool(rng.integers(2)))
        else:
            u = _unit(rng.normal(size=3))
            leg = RPU("leg", base=base, platform=plat, r_axis=r, u_platform_axis=u)
            for i in range(n):  # turn R so that R u is normal to r
                v = R[i] @ u
                w = _unit(v - np.dot(v, r) * r)
                R[i] = _rotation_taking(v, w) @ R[i]
        A = p + np.einsum("nij,j->ni", R, plat)
        p = p - np.outer((A - base) @ r, r)  # platform anchor into the leg's plane
    else:  # pragma: no cover
        raise AssertionError(kind)
    return leg, p, R


def _actuated_twist_index(kind: str) -> int:
    joints, act, _ = SPEC[kind]
    return sum(DOF[j] for j in joints[:act])


def _twist_scale(P, st):
    """Typical size of the twist moments (lever arms), for absolute tolerances."""
    return 1.0 + np.max(np.linalg.norm(st.platform_point - P, axis=-1)) + np.max(
        np.linalg.norm(st.base_point - P, axis=-1))


@pytest.mark.parametrize("kind", KINDS)
@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_leg_geometry_and_twist_count(kind, seed):
    rng = np.random.default_rng(seed)
    leg, p, R = make_leg_and_poses(kind, rng)
    state = leg.solve(p, R)
    assert np.all(state.reachable)
    A = p + np.einsum("nij,j->ni", R, leg.platform)
    np.testing.assert_allclose(state.platform_point, A, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(state.direction, axis=1), 1.0, atol=1e-12)
    d = state.platform_point - state.base_point
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), state.length, rtol=1e-12)
    np.testing.assert_allclose(d, state.direction * state.length[:, None], atol=1e-12)
    if kind != "PUS":
        # telescopic legs: the actuator (or free slide) is the anchor distance
        np.testing.assert_allclose(state.actuator, np.linalg.norm(A - leg.base, axis=1), rtol=1e-12)
    T = leg.joint_twists(state, p)
    joints = SPEC[kind][0]
    assert T.shape == (N, sum(DOF[j] for j in joints), 6)


@pytest.mark.parametrize("kind", KINDS)
@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_actuation_wrench_reciprocal_to_passive_joints_only(kind, seed):
    rng = np.random.default_rng(seed)
    leg, p, R = make_leg_and_poses(kind, rng)
    state = leg.solve(p, R)
    P = p + rng.normal(scale=0.1, size=p.shape)  # any reference point works
    T = leg.joint_twists(state, P)
    w, rate_scale = leg.actuation_wrench(state, P)
    assert w.shape == (N, 6)
    power = np.einsum("nj,nkj->nk", w, T)
    k_act = _actuated_twist_index(kind)
    passive = np.delete(power, k_act, axis=1)
    np.testing.assert_allclose(passive, 0.0, atol=1e-12 * _twist_scale(P, state))
    # The actuated freedom is not annihilated; its power is the leg's transmission scale
    # (1 for a telescopic leg, n . e for a slider).
    assert np.all(np.abs(power[:, k_act]) > 0.1)
    np.testing.assert_allclose(power[:, k_act], rate_scale, atol=1e-12)
    if kind == "PUS":
        np.testing.assert_allclose(rate_scale, state.direction @ leg.slider_axis, atol=1e-14)
    else:
        np.testing.assert_allclose(rate_scale, 1.0, atol=1e-14)


@pytest.mark.parametrize("kind", KINDS)
@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_constraint_wrenches_reciprocal_to_all_joints_and_complete(kind, seed):
    rng = np.random.default_rng(seed)
    leg, p, R = make_leg_and_poses(kind, rng)
    state = leg.solve(p, R)
    P = p + rng.normal(scale=0.1, size=p.shape)
    T = leg.joint_twists(state, P)
    C = leg.constraint_wrenches(state, P)
    n_c = SPEC[kind][2]
    assert C.shape == (N, n_c, 6)
    np.testing.assert_allclose(np.einsum("ncj,nkj->nck", C, T), 0.0, atol=1e-11 * _twist_scale(P, state))
    L = 0.5  # any length to make twists homogeneous for the rank count
    for i in range(N):
        Ts = T[i] * np.r_[np.ones(3), L * np.ones(3)]
        rank_T = np.linalg.matrix_rank(Ts, tol=1e-9)
        assert rank_T + n_c == 6  # the analytic wrenches span the whole reciprocal space
        if n_c:
            Cs = C[i] * np.r_[np.ones(3), np.ones(3) / L]
            assert np.linalg.matrix_rank(Cs, tol=1e-9) == n_c
            # unit forces or unit couples
            f = np.linalg.norm(C[i, :, :3], axis=1)
            m = np.linalg.norm(C[i, :, 3:], axis=1)
            assert np.all(np.isclose(f, 1.0, atol=1e-9) | (np.isclose(f, 0.0, atol=1e-9) & np.isclose(m, 1.0)))


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_rps_and_rpu_constraints_are_the_documented_screws(seed):
    """RPS: a force parallel to the revolute axis through the sphere; RPU: that force through
    the universal joint and a couple about r x (R u)."""
    rng = np.random.default_rng(seed)
    for kind in ("RPS", "RPU"):
        leg, p, R = make_leg_and_poses(kind, rng)
        st_ = leg.solve(p, R)
        C = leg.constraint_wrenches(st_, p)
        A = st_.platform_point
        f = C[:, 0, :3]
        np.testing.assert_allclose(np.abs(f @ leg.r_axis), 1.0, atol=1e-12)
        np.testing.assert_allclose(C[:, 0, 3:], np.cross(A - p, f), atol=1e-12)
        if kind == "RPU":
            a4 = np.einsum("nij,j->ni", R, leg.u_platform_axis)
            expected = _unit(np.cross(leg.r_axis, a4))
            np.testing.assert_allclose(C[:, 1, :3], 0.0, atol=1e-14)
            np.testing.assert_allclose(np.abs(np.einsum("nj,nj->n", C[:, 1, 3:], expected)), 1.0, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# PUS slider inverse kinematics
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("branch", [1, -1])
@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_pus_slider_ik_solves_link_length_exactly(branch, seed):
    rng = np.random.default_rng(seed)
    leg, p, R = make_leg_and_poses("PUS", rng, branch=branch)
    st_ = leg.solve(p, R)
    assert np.all(st_.reachable)
    U = leg.base + st_.actuator[:, None] * leg.slider_axis
    S = p + np.einsum("nij,j->ni", R, leg.platform)
    np.testing.assert_allclose(st_.base_point, U, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(S - U, axis=1), leg.link_length, rtol=1e-12)
    # The branch picks the side: branch +1 puts U further along the slider axis than S.
    assert np.all(branch * ((U - S) @ leg.slider_axis) > 0)


def eq11_2021(U_xy, S):
    """Wang, Lyu & Liu 2021, eq. (11) with the positive sign:
    Z_U = Z_S + sqrt(L^2 - (X_U - X_S)^2 - (Y_U - Y_S)^2)."""
    L = 0.205
    return S[:, 2] + np.sqrt(L**2 - (U_xy[0] - S[:, 0]) ** 2 - (U_xy[1] - S[:, 1]) ** 2)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_vertical_pus_matches_2021_eq11(seed):
    rng = np.random.default_rng(seed)
    a = rng.uniform(0, 2 * np.pi)
    U_xy = 0.135 * np.array([np.cos(a), np.sin(a)])
    b = a + rng.uniform(-0.5, 0.5)
    sphere = np.array([0.06 * np.cos(b), 0.06 * np.sin(b), 0.0])
    leg = PUS("L", base=np.r_[U_xy, 0.0], platform=sphere, slider_axis=[0, 0, 1], link_length=0.205, branch=1)
    n = 10
    p = np.c_[rng.uniform(-0.02, 0.02, (n, 2)), rng.uniform(-0.05, 0.05, n)]
    R = np.stack([np.eye(3)] * n)
    st_ = leg.solve(p, R)
    S = p + sphere
    assert np.all(st_.reachable)
    np.testing.assert_allclose(st_.actuator, eq11_2021(U_xy, S), atol=1e-13, equal_nan=False)


def test_unreachable_pus_pose_is_masked_not_raised():
    leg = PUS("L", base=[0.135, 0.0, 0.0], platform=[0.05, 0.0, 0.0], slider_axis=[0, 0, 1], link_length=0.2)
    p = np.array([[0.0, 0.0, 0.0],      # reachable
                  [-0.5, 0.0, 0.0],     # sphere 0.585 m from the slider line > 0.2 m
                  [0.0, 0.0, 0.1]])     # reachable
    R = np.stack([np.eye(3)] * 3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning from sqrt of a negative either
        st_ = leg.solve(p, R)
    assert st_.reachable.tolist() == [True, False, True]
    assert np.all(np.isfinite(st_.actuator[[0, 2]]))
    assert not np.isfinite(st_.actuator[1])


@pytest.mark.parametrize("kind", ["RPS", "RPU"])
def test_planar_legs_mask_out_of_plane_poses(kind):
    rng = np.random.default_rng(7)
    leg, p, R = make_leg_and_poses(kind, rng)
    p_off = p + 1e-3 * leg.r_axis  # 1 mm out of the leg's plane
    assert np.all(leg.solve(p, R).reachable)
    assert not np.any(leg.solve(p_off, R).reachable)


def test_pus_state_length_one_link_length_or_one_per_pose():
    """The state's link lengths: the leg's one link length at every pose (a writable array of
    its own), or with one link length per pose (a stacked geometry) each pose's, its state
    equal to that of a leg with that link length alone."""
    import copy

    leg = PUS("L", base=[0.1, 0.0, 0.0], platform=[0.05, 0.01, 0.0], link_length=0.3)
    p = np.array([[0.0, 0.0, 0.25], [0.01, 0.02, 0.26], [0.02, -0.01, 0.24]])
    R = np.stack([random_rotation(np.random.default_rng(k)) for k in range(3)])
    st = leg.solve(p, R, joint_angles=False)
    assert st.length.tolist() == [0.3, 0.3, 0.3] and st.length.flags.writeable
    st.length[0] = 1.0  # its own array: the leg is unchanged
    assert leg.link_length == 0.3
    lengths = np.array([0.3, 0.31, 0.29])
    stacked = copy.copy(leg)
    object.__setattr__(stacked, "link_length", lengths)
    sk = stacked.solve(p, R, joint_angles=False)
    assert np.array_equal(sk.length, lengths)
    for i, L in enumerate(lengths):
        one = PUS("L", base=leg.base, platform=leg.platform, link_length=float(L))
        s1 = one.solve(p[i:i + 1], R[i:i + 1], joint_angles=False)
        assert np.array_equal(sk.actuator[i:i + 1], s1.actuator)
        assert np.array_equal(sk.direction[i:i + 1], s1.direction)


def test_axes_are_numpys_unit_vectors_and_a_neutral_copy_changes_only_its_references():
    """A leg's axes normalised in Python floats equal NumPy's ``v / norm`` to the bit; the
    copy ``with_neutral`` gives is a new leg of the same type with every other field the
    same object, the original untouched; bad axes are refused by name."""
    rng = np.random.default_rng(3)
    for _ in range(2000):
        v = rng.normal(size=3) * 10.0 ** rng.uniform(-8, 8)
        x, y, z = v.tolist()
        assert np.array_equal(_axis("v", v), v / math.sqrt(x * x + y * y + z * z))
    leg = PUS("L1", base=np.array([0.1, 0.0, 0.0]), platform=np.array([0.05, 0.0, 0.0]), link_length=0.2,
              slider_axis=np.array([0.0, 0.0, 2.0]))
    new = leg.with_neutral([0.0, 3.0, 4.0], [1.0, 0.0, 0.0])
    assert type(new) is PUS and new is not leg
    assert np.array_equal(new.base_ref, [0.0, 0.6, 0.8]) and np.array_equal(new.platform_ref, [1.0, 0.0, 0.0])
    assert np.array_equal(leg.base_ref, [0.0, 0.0, 1.0])  # the original keeps its own
    for f in ("name", "base", "platform", "slider_axis", "link_length", "branch", "u_axis"):
        assert getattr(new, f) is getattr(leg, f)
    for bad, why in (([0.0, 0.0], "3-vector"), ([np.inf, 0.0, 0.0], "finite"), ([0.0, 0.0, 0.0], "non-zero")):
        with pytest.raises(ValueError, match=f"leg L1: base_ref must be .*{why}"):
            leg.with_neutral(bad, [1.0, 0.0, 0.0])


def test_default_neutral_directions_are_checked_unit_vectors_that_cannot_be_written():
    """A leg built without neutral directions takes the defaults (+z at the base, -z at the
    platform) as the unit vectors ``_axis`` makes of them, shared by every such leg and
    read-only (writing into one would change every leg's); directions given are checked
    and normalised as before, even when equal to the defaults."""
    a = SPS("A", base=[0.1, 0.0, 0.0], platform=[0.05, 0.0, 0.0])
    b = PUS("B", base=[0.1, 0.0, 0.0], platform=[0.05, 0.0, 0.0], link_length=0.2)
    for leg in (a, b):
        assert np.array_equal(leg.base_ref, _axis("r", [0.0, 0.0, 1.0]))
        assert np.array_equal(leg.platform_ref, _axis("r", [0.0, 0.0, -1.0]))
        with pytest.raises(ValueError, match="read-only"):
            leg.base_ref[0] = 1.0
        with pytest.raises(ValueError, match="read-only"):
            leg.platform_ref[2] = 1.0
    assert np.array_equal(a.base_ref, [0.0, 0.0, 1.0])  # nothing written
    given = SPS("C", base=[0.1, 0.0, 0.0], platform=[0.05, 0.0, 0.0], base_ref=[0.0, 0.0, 2.0],
                platform_ref=np.array([0.0, 0.0, -1.0]))
    assert np.array_equal(given.base_ref, [0.0, 0.0, 1.0]) and given.base_ref.flags.writeable
    assert given.platform_ref.flags.writeable  # a copy of its own, not the shared default
    for bad, why in (([0.0, 0.0, 0.0], "non-zero"), ([np.nan, 0.0, 1.0], "finite")):
        with pytest.raises(ValueError, match=f"leg D: platform_ref must be .*{why}"):
            SPS("D", base=[0.1, 0.0, 0.0], platform=[0.05, 0.0, 0.0], platform_ref=bad)


def _random_leg(kind: str, rng, reach: float):
    """A leg of type ``kind`` with random geometry (anchors within 0.3 m, random axes) whose link
    or crank lengths make poses near (0, 0, 0.6) mostly reachable when ``reach`` is about 1."""
    b = rng.uniform(-0.3, 0.3, 3)
    a = rng.uniform(-0.15, 0.15, 3)
    ax = rng.normal(size=3)
    if kind in ("SPS",):
        return SPS("L", base=b, platform=a)
    if kind == "UPS":
        return UPS("L", base=b, platform=a, u_axis=ax)
    if kind == "UPU":
        return UPU("L", base=b, platform=a, u_axis=ax, u_platform_axis=rng.normal(size=3))
    if kind == "RPS":
        return RPS("L", base=b, platform=a, r_axis=ax)
    if kind == "RPU":
        return RPU("L", base=b, platform=a, r_axis=ax, u_platform_axis=rng.normal(size=3))
    if kind == "PUS":
        return PUS("L", base=b, platform=a, slider_axis=ax, link_length=reach * 0.5, branch=int(rng.choice([-1, 1])))
    if kind == "PRS":
        e = ax / np.linalg.norm(ax)
        r = np.cross(e, rng.normal(size=3))
        return PRS("L", base=b, platform=a, slider_axis=e, r_axis=r, link_length=reach * 0.5,
                   branch=int(rng.choice([-1, 1])))
    return RUS("L", base=b, platform=a, r_axis=ax, crank_length=0.2, link_length=reach * 0.6,
               branch=int(rng.choice([-1, 1])))


@pytest.mark.parametrize("kind", ["SPS", "UPS", "UPU", "RPS", "RPU", "PUS", "PRS", "RUS"])
def test_home_direction_in_floats_is_the_solves_direction(kind):
    """``Leg.home_direction`` (Python floats, for the neutral directions at home) against the
    leg's NumPy ``solve`` at random poses of random legs: the same reachability and the same
    direction to a few units in the last place (NumPy's small matrix products may round
    otherwise), and out of reach (None) where the solve says so -- also for the planar legs
    (RPS, RPU, PRS), posed in their plane (reachable) and off it (not)."""
    from parasynth.model.legs import GEOM_TOL

    rng = np.random.default_rng(sum(map(ord, kind)))
    seen = {True: 0, False: 0}
    for trial in range(400):
        leg = _random_leg(kind, rng, reach=rng.uniform(0.6, 1.6))
        R = random_rotation(rng)
        p = rng.uniform(-0.1, 0.1, 3) + [0.0, 0.0, 0.6]
        if kind in ("RPS", "RPU", "PRS") and trial % 2 == 0:
            # move the pose into the leg's plane (through its base, normal to r_axis) for half the
            # trials: a random pose is out of it (and out of reach)
            A = p + R @ leg.platform
            p = p - ((A - leg.base) @ leg.r_axis) * leg.r_axis
            if kind == "RPU":  # and turn the platform's U axis normal to r_axis
                a4 = R @ leg.u_platform_axis
                axis = np.cross(a4, leg.r_axis)
                ang = np.arcsin(np.clip(a4 @ leg.r_axis, -1, 1))
                R = _rot(axis / np.linalg.norm(axis), -ang) @ R
                A = p + R @ leg.platform
                p = p - ((A - leg.base) @ leg.r_axis) * leg.r_axis
        st = leg.solve(p[None, :], R[None, :, :], joint_angles=False)
        hd = leg.home_direction(p.tolist(), R.ravel().tolist())
        ok = bool(st.reachable[0])
        seen[ok] += 1
        if not ok:
            assert hd is None, (trial, hd)
            continue
        assert hd is not None
        n = st.direction[0]
        # a slider's or crank's link direction comes from a difference of nearby points: a few
        # units in the last place of the anchors' coordinates
        assert np.max(np.abs(np.array(hd) - n)) <= (4e-16 if kind in FIXED_BASE else 1e-14), (trial, hd, n)
    assert seen[True] >= 60  # both branches exercised where the leg can miss a pose
    assert seen[False] >= 20 or kind in FIXED_BASE
    assert GEOM_TOL > 0


FIXED_BASE = ("SPS", "UPS", "UPU")


def _rot(u, ang):
    """The rotation by ``ang`` about the unit axis ``u`` (Rodrigues)."""
    K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return np.eye(3) + np.sin(ang) * K + (1.0 - np.cos(ang)) * K @ K


def test_a_described_mechanisms_neutral_directions_are_its_legs_directions_at_home():
    """Every shipped description, at its defaults and at random designs of the quick start: each
    leg's neutral directions are its NumPy solve's direction at home (base frame) and the
    opposite of it in the platform frame, unit vectors to a few units in the last place."""
    import parasynth
    from parasynth.mechanisms import list_mechanisms

    mechs = [parasynth.load_mechanism(n) for n in list_mechanisms()]
    rng = np.random.default_rng(5)
    for _ in range(20):
        mechs.append(parasynth.load_mechanism("5pus_upu", link_length=rng.uniform(0.16, 0.24),
                                              slider_radius=rng.uniform(0.11, 0.17)))
    for m in mechs:
        p, R = m._pose(m.home[None, :])
        for leg in m.legs:
            n = solve_geometry_dir(leg, p, R)
            assert np.max(np.abs(leg.base_ref - n / np.linalg.norm(n))) <= 1e-14, (m.name, leg.name)
            pr = R[0].T @ (-n)
            assert np.max(np.abs(leg.platform_ref - pr / np.linalg.norm(pr))) <= 1e-14, (m.name, leg.name)
            for ref in (leg.base_ref, leg.platform_ref):
                assert abs(np.linalg.norm(ref) - 1.0) <= 4e-16
            # made as with_unit_neutral makes them from the leg's direction in floats, bit for bit
            hd = leg.home_direction(p[0].tolist(), R[0].ravel().tolist())
            if hd is not None and hd is not NotImplemented:
                Rf = R[0].ravel().tolist()
                want = leg.with_unit_neutral(hd, tuple(sum(Rf[3 * i + j] * -hd[i] for i in range(3)) for j in range(3)))
                assert leg.base_ref.tobytes() == want.base_ref.tobytes(), (m.name, leg.name)
                assert np.max(np.abs(leg.platform_ref - want.platform_ref)) <= 1e-15, (m.name, leg.name)
            leg.base_ref[0] += 1.0  # each leg's own rows: the others' unchanged
            assert all(abs(np.linalg.norm(o.base_ref) - 1.0) <= 4e-16 for o in m.legs if o is not leg)
            leg.base_ref[0] -= 1.0


def solve_geometry_dir(leg, p, R):
    from parasynth.model.legs import solve_geometry

    return solve_geometry(leg, p, R).direction[0]
