"""Chain limbs (model/chains.py) beyond their inverse kinematics: the closure equations that
model/parasitic.py solves (against the hand-written legs' closed forms), the elbow offsets of
joint centres (against the stated geometry), the universal and spherical joints' cone angles
(against angles computed here) and the bad input of the new arguments."""

import math

import numpy as np
import pytest

from parasynth.model.chains import RRUR, RUU, ChainError, ChainLeg, parse_chain
from parasynth.model.legs import RPS, RPU, UPS
from parasynth.model.parasitic import closure_count, closure_residuals, gauss_newton
from parasynth.model.spatial import euler_to_matrix, rot_axis, rot_x, rot_y

RB, RP, H = 0.3, 0.15, 0.4
ANGLES = np.deg2rad([90.0, 210.0, 330.0])


def _ring(kind):
    """A 3-RPS ring (revolute axes tangential, no platform twist) of hand-written legs or of chain
    limbs ``RP*S`` with the same anchors and axes."""
    out = []
    for i, t in enumerate(ANGLES):
        b = RB * np.array([math.cos(t), math.sin(t), 0.0])
        a = RP * np.array([math.cos(t), math.sin(t), 0.0])
        tan = np.array([-math.sin(t), math.cos(t), 0.0])
        if kind == "hand":
            out.append(RPS(f"L{i}", base=b, platform=a, r_axis=tan))
        else:
            out.append(ChainLeg(f"L{i}", base=b, platform=a, chain="RP*S", axes=("tangent", "limb"), home_height=H))
    return out


def _solve_parasitic(legs, X):
    """x, y, gamma of the platform at (z, alpha, beta) rows X, on the legs' closure equations."""
    def fun(X, U):
        p = np.stack([U[:, 0], U[:, 1], X[:, 0]], -1)
        R = euler_to_matrix("xyz", np.stack([X[:, 1], X[:, 2], U[:, 2]], -1))
        return closure_residuals(legs, p, R, RB)
    return gauss_newton(fun, X, np.zeros(3), np.array([RB, RB, 1.0]), iterations=60)


def test_chain_3rps_parasitic_motion_equals_the_hand_written_3rps():
    """The dependent x, y, gamma of a 3-RPS of chain limbs (closure: the chains' least-squares
    reach) equal those of the hand-written 3-RPS (closure: the sphere in the revolute's plane)
    to 1e-9 at random heights and tilts, and at the solution every chain limb reaches the pose."""
    hand, chain = _ring("hand"), _ring("chain")
    assert [closure_count(leg) for leg in chain] == [1, 1, 1] == [closure_count(leg) for leg in hand]
    rng = np.random.default_rng(3)
    X = np.column_stack([H + rng.uniform(-0.06, 0.06, 30), rng.uniform(-0.3, 0.3, (30, 2))])
    U0, ok0 = _solve_parasitic(hand, X)
    U1, ok1 = _solve_parasitic(chain, X)
    assert ok0.all() and ok1.all()
    assert np.max(np.abs(U1 - U0)) < 1e-9
    assert np.max(np.abs(U0[:, :2])) > 1e-3  # the parasitic motion is not trivially zero
    p = np.stack([U1[:, 0], U1[:, 1], X[:, 0]], -1)
    R = euler_to_matrix("xyz", np.stack([X[:, 1], X[:, 2], U1[:, 2]], -1))
    for leg in chain:
        assert leg.solve(p, R).reachable.all()


def test_closure_vanishes_on_the_limbs_motion_and_measures_the_forbidden_rotation():
    """An RPUR: on poses its forward kinematics reaches the closure residual is at rounding; a
    pose turned by a small angle d about the limb's constraint couple c (x cross the platform's
    y) gives a residual d (c . z) to first order: the forbidden rotation on the constraint's
    direction at home (z = x cross y)."""
    leg = ChainLeg("L", base=[RB, 0.0, 0.0], platform=[RP, 0.0, 0.0], chain="RP*UR",
                   axes=("x", "limb", "parallel:prev", "normal:prev&normal:limb", "parallel:prev"),
                   home_point=[RP, 0.0, H])
    assert leg.n_closure == 1
    rng = np.random.default_rng(8)
    q = rng.uniform(-0.15, 0.15, (6, 5))
    q[:, 1] *= 0.3
    pos, R, _, _ = leg.forward(q)
    p = pos - np.einsum("nij,j->ni", R, leg.platform)
    r = np.stack(leg.closure_residuals(p, R), -1)
    assert np.max(np.abs(r)) < 1e-12
    c = np.cross([1.0, 0.0, 0.0], R[:, :, 1])
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    for d in (1e-4, 1e-5):
        Rd = rot_axis(c, np.full(len(c), d)) @ R
        rd = np.abs(np.stack(leg.closure_residuals(p, Rd), -1)[:, 0])
        assert np.allclose(rd / d, np.abs(c[:, 2]), atol=1e-3), (rd / d, c[:, 2])
    assert np.min(np.abs(c[:, 2])) < 0.999  # the constraint has turned away from its home direction


@pytest.mark.parametrize("chain, axes, hand", [
    ("RP*U", ("tangent", "limb", "tangent", "normal:prev&normal:limb"), 2),
    ("UP*S", ("tangent", "normal:prev", "limb"), 0),
])
def test_closure_count_is_the_number_of_constraint_wrenches(chain, axes, hand):
    leg = ChainLeg("L", base=[RB, 0.0, 0.0], platform=[RP, 0.0, 0.0], chain=chain, axes=axes, home_height=H)
    assert closure_count(leg) == hand
    ref = RPU("L", base=[RB, 0.0, 0.0], platform=[RP, 0.0, 0.0], r_axis=[0.0, 1.0, 0.0],
              u_platform_axis=[1.0, 0.0, 0.0]) if hand == 2 else UPS("L", base=[RB, 0.0, 0.0], platform=[RP, 0, 0])
    assert closure_count(ref) == hand


def test_elbow_offset_puts_the_joint_centre_off_the_limb_line():
    """RRUR: its second revolute's centre at home is at station 0.4 of the anchor line plus 0.3 of
    the limb's length along x cross the limb (its axis is x); RUU: the crank end at station 0.3
    plus 0.25 along tangent cross limb."""
    base, plat = np.array([RB, 0.0, 0.0]), np.array([RP * math.cos(0.5), RP * math.sin(0.5), 0.0])
    for cls, m, station, off, axis in ((RRUR, 1, 0.4, 0.3, np.array([1.0, 0.0, 0.0])),
                                       (RUU, 1, 0.3, 0.25, np.array([0.0, 1.0, 0.0]))):
        leg = cls("L", base=base, platform=plat, home_height=H)
        d = plat + [0.0, 0.0, H] - base
        L = np.linalg.norm(d)
        e = np.cross(axis, d / L)
        want = base + station * d + off * L * e / np.linalg.norm(e)
        _, _, _, points = leg.forward(np.zeros((1, leg.n_joint_dof)))
        assert np.allclose(points[m][0], want, atol=1e-12), cls.joints
        # off the line by the stated fraction of its length
        rel = points[m][0] - base
        assert np.isclose(np.linalg.norm(rel - (rel @ d / L) * d / L), off * L, rtol=1e-12)


def test_cone_angles_are_the_angles_of_the_links_from_their_home_directions():
    """UP*S (a chain UPS): after a translation (dx, 0, dz) and a turn about z, U_base_cone is the
    angle between the limb's direction and its home direction, and S_platform_cone the angle
    between the limb's direction and its home direction carried by the platform (computed here
    from the anchors); the hand-written UPS gives the same."""
    base, plat = np.array([RB, 0.0, 0.0]), np.array([RP, 0.05, 0.0])
    leg = ChainLeg("L", base=base, platform=plat, chain="UP*S", axes=("tangent", "normal:prev", "limb"),
                   home_height=H)
    n0 = plat + [0.0, 0.0, H] - base
    n0 /= np.linalg.norm(n0)
    p = np.array([[0.04, 0.0, H - 0.03], [-0.02, 0.03, H + 0.02]])
    R = np.stack([rot_axis(np.array([0.0, 0.0, 1.0]), np.array([0.2]))[0], rot_x(np.array([0.1]))[0]])
    st = leg.solve(p, R)
    assert st.reachable.all()
    A = p + np.einsum("nij,j->ni", R, plat)
    n = (A - base) / np.linalg.norm(A - base, axis=1, keepdims=True)
    base_cone = np.arccos(np.clip(n @ n0, -1, 1))
    plat_cone = np.arccos(np.clip(np.einsum("ni,ni->n", n, np.einsum("nij,j->ni", R, n0)), -1, 1))
    assert np.allclose(st.angles["U_base_cone"], base_cone, atol=1e-9)
    assert np.allclose(st.angles["S_platform_cone"], plat_cone, atol=1e-9)
    assert np.allclose(st.angles["U0_cone"], base_cone, atol=1e-9)
    ref = UPS("L", base=base, platform=plat, base_ref=n0, platform_ref=-n0)
    rs = ref.solve(p, R)
    assert np.allclose(rs.angles["U_base_cone"], base_cone, atol=1e-9)
    assert np.allclose(rs.angles["S_platform_cone"], plat_cone, atol=1e-9)
    assert base_cone.min() > 0.01 and plat_cone.min() > 0.01  # not trivially zero


def test_mid_chain_universal_joint_cone_follows_its_outgoing_link():
    """RPUR's universal joint (station 0.8): its cone is the angle its outgoing link (to the last
    revolute at the anchor) turns across it. With the platform turned by b about y around its
    centre, the limb stays in the x-z plane: the slider runs along the home line d0 and the link
    of length 0.2 L turns by u about y, A - B = (0.8 L + s) d0 + 0.2 L Ry(u) d0; u is solved here
    (a root in the plane) and the cone is |u|."""
    from scipy.optimize import brentq

    B, A0 = np.array([RB, 0.0, 0.0]), np.array([RP, 0.0, H])
    leg = ChainLeg("L", base=B, platform=[RP, 0.0, 0.0], chain="RP*UR",
                   axes=("x", "limb", "parallel:prev", "normal:prev&normal:limb", "parallel:prev"),
                   home_point=A0, stations=(0.0, 0.8, 1.0))
    p = np.array([[0.0, 0.0, H]])
    st = leg.solve(p, np.eye(3)[None])
    assert np.allclose(st.angles["U2_cone"], 0.0, atol=1e-9)
    L = np.linalg.norm(A0 - B)
    d0 = (A0 - B) / L
    for b in (0.15, -0.1):
        R = rot_y(np.array([b]))
        v = p[0] + R[0] @ [RP, 0.0, 0.0] - B
        u = brentq(lambda u: np.cross(v - 0.2 * L * rot_y(np.array([u]))[0] @ d0, d0)[1], -1.0, 1.0, xtol=1e-14)
        st = leg.solve(p, R)
        assert st.reachable[0] and np.isclose(st.angles["U2_cone"][0], abs(u), atol=1e-9), (st.angles["U2_cone"], u)
        assert abs(u) > 0.05


@pytest.mark.parametrize("kw, words", [
    ({"offsets": [0.0, 0.3]}, ["offsets must be 4 numbers in [-1, 1]"]),
    ({"offsets": [0.0, 1.5, 0.0, 0.0]}, ["offsets must be 4 numbers", "fractions of the limb's length"]),
    ({"offsets": "0.3"}, ["offsets must be 4 numbers"]),
    ({"offsets": [0.0, float("nan"), 0.0, 0.0]}, ["offsets must be 4 numbers"]),
])
def test_bad_offsets_refused_in_one_line(kw, words):
    with pytest.raises(ChainError) as e:
        parse_chain("R*RUR", **kw)
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


def test_offsets_are_kept_in_the_spec():
    s = parse_chain("R*RUR", offsets=[0.0, 0.3, 0.0, 0.0])
    assert s.offsets == (0.0, 0.3, 0.0, 0.0) and s.name == "R*RUR"
    assert parse_chain("R*RUR", offsets=[0, 0, 0, 0]).offsets is None


@pytest.mark.parametrize("spec", ["RP*S", "P*RS", "UP*U", "RP*UR", "R*RUR", "RP*U", "UP*S"])
def test_closure_directions_are_the_left_null_space_of_the_home_twists(spec):
    """A chain limb's closure directions (onto which its closure residual is projected) span the
    wrenches reciprocal to its joint twists at home, taken about the home anchor with their
    linear parts over the limb's length -- the twists computed here from the forward kinematics
    at q = 0 -- and there are 6 minus their rank of them (a constraint force, RP*S, P*RS, UP*U:
    its direction depends on the reference point; a couple, RP*UR, R*RUR; two, RP*U; none,
    UP*S)."""
    from parasynth.model.chains import chain_class

    leg = chain_class(spec)("L", base=[0.3 * math.cos(0.4), 0.3 * math.sin(0.4), 0.02],
                            platform=[0.15 * math.cos(0.5), 0.15 * math.sin(0.5), 0.0], home_height=0.37)
    n = len(leg.chain_arrays()["kinds"])
    pos, _, axes, points = leg.forward(np.zeros((1, n)))
    T = np.zeros((6, n))
    for m, (a, c) in enumerate(zip(axes, points)):
        if c is None:
            T[:3, m] = a[0]
        else:
            T[:3, m] = np.cross(a[0], pos[0] - c[0])
            T[3:, m] = a[0]
    T[:3] /= np.linalg.norm(pos[0] - leg.base)  # lengths over the limb's home length
    U = leg._closure_dirs
    assert U.shape == (6, 6 - np.linalg.matrix_rank(T, tol=1e-9))
    np.testing.assert_allclose(U.T @ T, 0.0, atol=1e-12)
    np.testing.assert_allclose(U.T @ U, np.eye(U.shape[1]), atol=1e-12)
