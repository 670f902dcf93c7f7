"""Limbs from joint strings (model/chains.py): bad input refused in one line naming what is
wrong and what is allowed; the numerical inverse kinematics against closed forms and round
trips; joint twists against finite differences of the forward kinematics; constraint and
actuation wrenches against their closed forms and reciprocity."""

import numpy as np
import pytest

from parasynth.model.chains import ChainError, ChainLeg, parse_chain
from parasynth.model.legs import UPS, supports, require, LegCapabilityError
from parasynth.model.spatial import euler_to_matrix, rot_x, rot_y

# the 3T2R limb of the 5-RPUR: R about x at the base, P along the limb, U (x, then normal to x and
# the limb), R parallel to the U's second axis
RPUR_AXES = ("x", "limb", "parallel:prev", "normal:prev&normal:limb", "parallel:prev")


@pytest.mark.parametrize("spec, kw, words", [
    ("RPQR", {}, ["unknown joint letter 'Q'", "R (revolute)", "S (spherical)"]),
    ("RPUR", {}, ["no actuated joint", "'*'"]),
    ("R*P*UR", {}, ["2 actuated joints", "exactly one"]),
    ("RP*UR", {"actuated": 0}, ["2 actuated joints"]),
    ("RPU*R", {}, ["universal joint", "only a revolute (R) or prismatic (P)"]),
    ("*RPUR", {}, ["'*' must follow"]),
    ("", {}, ["non-empty string"]),
    ("RP*UR", {"axes": ["x", "limb", "parallel:prev"]}, ["has 5 axes", "3 relations"]),
    ("RP*UR", {"axes": ["x", "limb", "parallel:radial&normal:radial", "normal:prev", "prev"]},
     ["axes[2]", "parallel and normal to 'radial'", "contradict"]),
    ("RP*UR", {"axes": ["radial&tangent", "limb", "prev", "normal:prev", "prev"]},
     ["axes[0]", "'radial' and to 'tangent' contradict"]),
    ("RP*UR", {"axes": ["x", "limb", "prev", "parallel:prev", "prev"]}, ["axes[3]", "second axis is normal"]),
    ("RP*UR", {"axes": ["x", "limb", "prev", "normal:prev&parallel:limb", "prev"]},
     ["axes[3]", "contradict each other here"]),
    ("RP*UR", {"axes": ["x", "limb", "prev", "normal:prev", "parallel:x&parallel:limb"]},
     ["axes[4]", "contradict each other here", "parallel to 'limb'"]),
    ("RP*UR", {"axes": ["sideways", "limb", "prev", "normal:prev", "prev"]}, ["unknown reference 'sideways'", "allowed"]),
    ("RP*UR", {"axes": ["along:x", "limb", "prev", "normal:prev", "prev"]}, ["unknown relation 'along'", "parallel, normal"]),
    ("RP*UR", {"axes": ["prev", "limb", "prev", "normal:prev", "prev"]}, ["axes[0]", "no rotational axis comes before"]),
    ("RP*UR", {"axes": ["x", "limb", "axis3", "normal:prev", "prev"]}, ["axes[2]", "not an earlier axis"]),
    ("RP*UR", {"passive": True}, ["passive=True but joint 1"]),
    ("UPU", {"stations": [0.5], "passive": True}, ["stations must be 2 numbers"]),
])
def test_bad_input_one_line_naming_the_fault_and_what_is_allowed(spec, kw, words):
    with pytest.raises(ChainError) as e:
        parse_chain(spec, **kw)
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


def test_marker_and_index_give_the_same_limb():
    a = parse_chain("RP*UR")
    b = parse_chain("rpur", actuated=1)
    assert a == b and a.name == "RP*UR" and a.n_dof == 5 and a.n_axes == 5
    assert parse_chain("UPU", passive=True).actuated is None


def test_a_chain_limb_is_refused_by_name_by_the_parts_it_does_not_support():
    leg = ChainLeg("L1", base=[0.3, 0, 0], platform=[0.15, 0, 0], chain="RP*UR", axes=RPUR_AXES)
    assert supports(leg, "compiled") and supports(leg, "stiffness") and not supports(leg, "closure")
    with pytest.raises(LegCapabilityError, match=r"leg L1: leg type chain does not support 'export'"):
        require(leg, "export")


def _poses(rng, n, tilt=0.2, reach=0.05):
    p = np.array([0.0, 0.0, 0.4]) + rng.uniform(-reach, reach, (n, 3))
    return p, rng.uniform(-tilt, tilt, (n, 3))


def test_chain_ups_actuator_is_the_closed_form_leg_length():
    """'UP*S' solved numerically against the hand-written UPS (a closed form: the anchor distance)."""
    rng = np.random.default_rng(1)
    base, plat = np.array([0.3, 0.05, 0.0]), np.array([0.12, -0.06, 0.0])
    chain = ChainLeg("L1", base=base, platform=plat, chain="UP*S", axes=("tangent", "normal:prev", "limb"))
    ref = UPS("L1", base=base, platform=plat)
    p, ang = _poses(rng, 12)
    R = euler_to_matrix("xyz", ang)
    st = chain.solve(p, R)
    assert st.reachable.all()
    assert np.allclose(st.actuator, ref.solve(p, R).actuator, atol=1e-10)
    # a six-freedom limb: no constraint wrench
    assert chain.constraint_wrenches(st, p).shape == (12, 0, 6)


def _rpur(base, plat, home, chain="RP*UR", axes=RPUR_AXES):
    return ChainLeg("L", base=base, platform=plat, chain=chain, axes=axes, home_point=home)


def test_round_trip_forward_then_inverse():
    leg = _rpur([0.3, 0.0, 0.0], [0.15, 0.0, 0.0], [0.15, 0.0, 0.4])
    rng = np.random.default_rng(2)
    q = rng.uniform(-0.15, 0.15, (8, 5))
    q[:, 1] *= 0.3  # metres on the slider
    pos, R, _, _ = leg.forward(q)
    p = pos - np.einsum("nij,j->ni", R, leg.platform)
    st = leg.solve(p, R)
    assert st.reachable.all()
    pos2, R2, _, _ = leg.forward(st.extra["q"])
    assert np.allclose(pos2, pos, atol=1e-10) and np.allclose(R2, R, atol=1e-10)


def test_joint_twists_are_the_derivatives_of_the_forward_kinematics():
    leg = _rpur([0.3, 0.1, 0.0], [0.15, 0.02, 0.0], [0.12, 0.05, 0.42])
    q = np.array([[0.1, 0.03, -0.2, 0.15, 0.05]])
    pos, R, axes, points = leg.forward(q)
    T = leg._twists_at(axes, points, pos)[0]
    h = 1e-6
    for m in range(5):
        dq = np.zeros_like(q)
        dq[0, m] = h
        pp, Rp, _, _ = leg.forward(q + dq)
        pm, Rm, _, _ = leg.forward(q - dq)
        v = (pp - pm)[0] / (2 * h)
        W = ((Rp - Rm)[0] / (2 * h)) @ R[0].T
        w = np.array([W[2, 1], W[0, 2], W[1, 0]])
        assert np.allclose(T[m], np.concatenate([v, w]), atol=1e-6), m


def test_rpur_constraint_is_the_couple_normal_to_its_two_axis_directions():
    """RPUR: the R and first U axes along x, the second U axis and last R along the platform's
    y: the one constraint wrench is a couple about x x (R y) (closed form)."""
    leg = _rpur([0.3, 0.0, 0.0], [0.15, 0.0, 0.0], [0.15, 0.0, 0.4])
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-0.2, 0.2, (2, 6))
    R = rot_x(a) @ rot_y(b)
    p = np.array([0.0, 0.0, 0.4]) + rng.uniform(-0.04, 0.04, (6, 3))
    st = leg.solve(p, R)
    assert st.reachable.all()
    W = leg.constraint_wrenches(st, p)
    assert W.shape == (6, 1, 6)
    c = np.cross([1.0, 0.0, 0.0], R[:, :, 1])
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    assert np.allclose(W[:, 0, :3], 0.0, atol=1e-9)
    assert np.allclose(np.abs(np.einsum("ij,ij->i", W[:, 0, 3:], c)), 1.0, atol=1e-9)
    # a rotation about that couple is not a motion of the limb: unreachable
    st2 = leg.solve(p[:1], (R[0] @ euler_to_matrix("xyz", np.array([[0.0, 0.0, 0.1]]))[0])[None])
    assert not st2.reachable[0] and np.isnan(st2.actuator[0])


def test_actuation_wrench_gives_the_actuator_rate_along_a_motion():
    """w . t / rate_scale is the rate of the solved actuator along a finite motion of the limb
    (finite differences of the inverse kinematics)."""
    leg = _rpur([0.3, 0.0, 0.0], [0.15, 0.0, 0.0], [0.15, 0.0, 0.4])
    def pose(s):
        return np.array([[0.01 + 0.02 * s, -0.01 + 0.01 * s, 0.4 - 0.03 * s]]), (rot_x(0.1 * s) @ rot_y(0.05 + 0.1 * s))[None]
    p, R = pose(0.0)
    st = leg.solve(p, R)
    w, rate = leg.actuation_wrench(st, p)
    T = leg.joint_twists(st, p)[0]
    passive = np.delete(T, 1, axis=0)
    assert np.allclose(passive @ w[0], 0.0, atol=1e-9)
    h = 1e-5
    (pp, Rp), (pm, Rm) = pose(h), pose(-h)
    v = (pp - pm)[0] / (2 * h)
    Wd = ((Rp - Rm)[0] / (2 * h)) @ R[0].T
    t = np.concatenate([v, [Wd[2, 1], Wd[0, 2], Wd[1, 0]]])
    rate_fd = (leg.solve(pp, Rp).actuator - leg.solve(pm, Rm).actuator)[0] / (2 * h)
    assert np.isclose(w[0] @ t / rate[0], rate_fd, rtol=1e-5, atol=1e-8)


# -- closed forms ---------------------------------------------------------------------------------
def _random_limb(cls, rng):
    """A limb of type ``cls`` at a random anchor, platform point and height."""
    a, b = rng.uniform(-np.pi, np.pi, 2)
    rb, rp = rng.uniform(0.2, 0.5), rng.uniform(0.05, 0.3)
    return cls("L", base=[rb * np.cos(a), rb * np.sin(a), 0.0], platform=[rp * np.cos(b), rp * np.sin(b), 0.0],
               home_height=float(rng.uniform(0.3, 0.9)))


def _random_rrps(rng):
    """An RRPS limb (model.chains.RRPS: revolute along the anchor's tangent, revolute normal to it
    and the limb a tenth up, slider along the limb, spherical at the platform anchor) at a random
    anchor, platform point and height."""
    from parasynth.model.chains import RRPS

    return _random_limb(RRPS, rng)


def _poses_around(leg, rng, n, reach=0.15, turn=0.6, motion="3T3R"):
    """Platform poses within ``reach`` of the limb's home, turned by up to ``turn`` rad about
    random axes (3T3R) or about x and then the moving y (3T2R: the motion of the RRUR and PRUR)."""
    from parasynth.model.spatial import rot_axis

    home = leg._home - leg.platform
    p = home + rng.uniform(-reach, reach, (n, 3))
    if motion == "3T2R":
        return p, rot_x(rng.uniform(-turn, turn, n)) @ rot_y(rng.uniform(-turn, turn, n))
    ax = rng.normal(size=(n, 3))
    R = rot_axis(ax / np.linalg.norm(ax, axis=1, keepdims=True), rng.uniform(-turn, turn, n))
    return p, R


@pytest.mark.parametrize("name, form, motion", [("RRPS", "RRP-S", "3T3R"), ("RRUR", "RR-UR", "3T2R"),
                                                ("PRUR", "PR-UR", "3T2R"), ("SPU", "SP-U", "3T3R")])
def test_the_closed_form_reaches_the_pose_and_finds_the_numerical_solution(name, form, motion):
    """The closed form against two independent checks: its coordinates carried through the
    forward kinematics give the pose (a round trip), and the Levenberg-Marquardt solve from home
    (``closed=False``) reaches every pose it solves, at the same coordinates; a pose without a
    solution in the home pose's working mode is out of reach (the numerical solve may reach it in
    another). 20 random
    limbs, 500 poses each within 150 mm and 0.6 rad of home (the limb's motion: any rotation for
    the RRPS and SPU, x then the moving y for the RRUR and PRUR, which reach a part of them)."""
    from parasynth.model.chains import closed_form_solve
    from parasynth.model.legs import LEG_TYPES

    rng = np.random.default_rng(11)
    reached = []
    for _ in range(20):
        leg = _random_limb(LEG_TYPES[name], rng)
        assert leg.closed_form == form
        p, R = _poses_around(leg, rng, 500, motion=motion)
        target = p + np.einsum("nij,j->ni", R, leg.platform)
        q = closed_form_solve(leg._closed, target, R)
        pos, Rc, _, _ = leg.forward(q)
        err = np.maximum(np.abs(pos - target).max(axis=1) / leg._L, np.abs(Rc - R).max(axis=(1, 2)))
        solved = err < 1e-12  # the others have no solution in the home pose's working mode: NaN
        assert np.isnan(q[~solved]).any(axis=1).all()
        qn, res = leg.inverse(p, R, closed=False)
        ok = res < 1e-6
        assert not (solved & ~ok).any()  # every pose it solves the numerical solve reaches,
        np.testing.assert_allclose(q[solved], qn[solved], rtol=0, atol=1e-6)  # at the same coordinates
        # a pose it has no solution for is out of reach (the numerical solve from home may reach one in
        # another working mode: a PRUR with its platform-side universal joint turned over)
        qc, resc = leg.inverse(p, R)
        assert np.array_equal(resc < 1e-6, solved) and np.isinf(resc[~solved]).all()
        assert solved.sum() >= 0.9 * ok.sum()
        reached.append(ok.mean())
        # the home pose is the home configuration (the branch of every solve from home)
        q0 = closed_form_solve(leg._closed, leg._home[None], np.eye(3)[None])
        np.testing.assert_allclose(q0, 0.0, rtol=0, atol=1e-12)
    assert np.mean(reached) > (0.99 if motion == "3T3R" else 0.3)


def test_the_closed_form_is_what_the_solve_gives_and_is_taken_only_where_the_geometry_allows():
    from parasynth.model.chains import PRRS, RPUR, RRPS, SPU, URPU, chain_class

    rng = np.random.default_rng(5)
    leg = _random_rrps(rng)
    p, R = _poses_around(leg, rng, 300)
    st = leg.solve(p, R)
    target = p + np.einsum("nij,j->ni", R, leg.platform)
    from parasynth.model.chains import closed_form_solve

    np.testing.assert_array_equal(st.extra["q"], closed_form_solve(leg._closed, target, R))
    assert st.reachable.all() and st.extra["residual"].max() < 1e-13
    # an elbow (the second revolute's centre off the slider's line) has no closed form of this kind:
    # the numerical solve alone, which still reaches
    bent = chain_class("RRP*S", axes=("tangent", "normal:prev&normal:limb", "limb"), stations=(0.0, 0.1, 1.0),
                       offsets=(0.0, 0.05, 0.0))("L", base=leg.base, platform=leg.platform)
    assert bent.closed_form is None and bent.chain_arrays()["closed"].size == 0
    pb, Rb = _poses_around(bent, rng, 100, reach=0.05, turn=0.2)
    assert bent.solve(pb, Rb).reachable.all()
    # the same axes written again (a limb type of the user's) have it; the other limbs have none
    same = chain_class("RRP*S", axes=("tangent", "normal:prev&normal:limb", "limb"), stations=(0.0, 0.1, 1.0))
    assert same("L", base=leg.base, platform=leg.platform).closed_form == "RRP-S"
    for cls in (RPUR, URPU, PRRS):
        assert cls("L", base=leg.base, platform=leg.platform).closed_form is None
    assert SPU("L", base=leg.base, platform=leg.platform).closed_form == "SP-U"
    assert RRPS("L", base=leg.base, platform=leg.platform).closed_form == "RRP-S"
