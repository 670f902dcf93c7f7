"""The limbs from joint strings added to the vocabulary (RRUR, RUU, URPU, PRRS), the spherical
3-UPU (axes through one centre: 0T3R), the 6-SPU folded into the 6-UPS, joint-angle limits of
chain limbs in the generated descriptions and chain limbs in structures whose motion is solved
on their closure equations. The mobility of every one of them is also recomputed independently
in test_structures_motion.py (its motions include 3T2R, 3T3R, 3T0R and 0T3R)."""

import functools
import warnings

import numpy as np
import pytest

import parasynth
from parasynth.model.chains import ChainLeg
from parasynth.model.legs import UPS
from parasynth.model.mechanism import EngineFallbackWarning
from parasynth.model.spatial import euler_to_matrix


@functools.lru_cache(maxsize=None)
def _found(motion, types, legs=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        return parasynth.structures(motion, leg_types=list(types), legs=legs)


def _named(found, name):
    out = [s for s in found if s.name == name]
    assert out, f"{name} not in {[s.name for s in found]}"
    return out


@pytest.mark.parametrize("motion, types, name", [
    ("3T2R", ("RRUR",), "5-RRUR"),
    ("3T0R", ("RUU",), "3-RUU"),
    ("3T3R", ("URPU",), "6-URPU"),
    ("3T3R", ("PRRS",), "6-PRRS"),
])
def test_each_new_limb_gives_a_verified_structure(motion, types, name):
    found = _found(motion, types)
    kept = _named(found, name)
    assert all(s.motion == motion for s in kept)
    assert any(s.verified for s in kept)
    assert all(isinstance(leg, ChainLeg) for leg in kept[0].mechanism().legs)


def _box(m, n, seed, frac=0.4):
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    return m.home + frac * (hi - lo) * np.random.default_rng(seed).uniform(-1, 1, (n, len(lo)))


def test_3_ruu_translates_on_its_limbs_closure():
    """The 3-RUU's motion is solved on the chain limbs' closure equations (task.solve): its solved
    rotations are zero at random translations of its task box where it is reachable (Kong and
    Gosselin's translational R-U-U), every limb's own inverse kinematics reaches those poses, and
    none reaches them turned by 0.05 rad."""
    s = next(s for s in _named(_found("3T0R", ("RUU",)), "3-RUU") if s.verified)
    assert s.template == "solved" and set(s.description["task"]["solve"]["unknowns"]) == {"alpha", "beta", "gamma"}
    m = s.mechanism()
    X = _box(m, 16, 1, 0.25)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        p, R = m._pose(X)
        ok = m.inverse_kinematics(X).reachable
    assert ok.mean() > 0.7
    assert np.max(np.abs(R[ok] - np.eye(3))) < 1e-9
    Rt = euler_to_matrix("xyz", np.tile([0.05, 0.0, 0.0], (ok.sum(), 1)))
    for leg in m.legs:
        assert leg.solve(p[ok], R[ok]).reachable.all()
        assert not leg.solve(p[ok], Rt).reachable.any()


def test_spherical_3_upu_turns_about_the_platform_centre():
    """structures("0T3R") gives the 3-UPU whose universal-joint axes pass through the platform
    centre at home (Karouia and Herve): each base joint's first axis and each platform joint's
    last axis meet the point (0, 0, height) (distances computed here), and at random rotations
    the platform centre stays there while the legs' closure holds."""
    found = _found("0T3R", ("UPU",))
    s = _named(found, "3-UPU")[0]
    assert dict(s.groups[0].axes) == {"u_axis": "centre", "u_platform_axis": "centre"}
    assert s.verified and s.motion == "0T3R" and s.axes["translations"] == ()
    m = s.mechanism()
    O = np.array([0.0, 0.0, m.params.height])
    for leg in m.legs:
        a = leg.u_axis / np.linalg.norm(leg.u_axis)
        off = (O - leg.base) - ((O - leg.base) @ a) * a
        assert np.linalg.norm(off) < 1e-12
        A = leg.platform + [0.0, 0.0, m.params.height]
        b = leg.u_platform_axis / np.linalg.norm(leg.u_platform_axis)
        off = (O - A) - ((O - A) @ b) * b
        assert np.linalg.norm(off) < 1e-12
    X = _box(m, 20, 2)
    p, R = m._pose(X)
    ok = np.all(np.isfinite(p), axis=1)
    assert ok.mean() > 0.9 and np.max(np.abs(p[ok] - O)) < 1e-9
    # the rotations are the task's: R = Rx Ry Rz of (alpha, beta, gamma)
    assert np.allclose(R[ok], euler_to_matrix("xyz", X[ok]), atol=1e-12)


def test_3t0r_and_0t3r_tell_the_two_3_upu_apart():
    """Tsai's 3-UPU (tangent axes) is the 3T0R one, the one with axes through the centre the 0T3R
    one; neither appears under the other motion."""
    t = {tuple(v for _, v in s.groups[0].axes) for s in _found("3T0R", ("UPU",)) if s.name == "3-UPU"}
    r = {tuple(v for _, v in s.groups[0].axes) for s in _found("0T3R", ("UPU",)) if s.name == "3-UPU"}
    assert t == {("tangent", "tangent")} and r == {("centre", "centre")}


def test_6_spu_is_reported_with_the_6_ups_as_inverted():
    """The 6-SPU is the 6-UPS inverted (the same actuation lines): structures("3T3R") with both
    reports one structure per layout, "6-UPS (also 6-SPU: inverted)"; the SPU limb's actuator is
    the anchor distance, the UPS's closed form, at random poses."""
    found = _found("3T3R", ("UPS", "SPU"), (6,))
    assert not [s for s in found if s.name == "6-SPU"]
    ups = _named(found, "6-UPS")
    assert all(("6-SPU", "inverted") in s.equivalents for s in ups)
    assert all(s.label.startswith("6-UPS (also 6-SPU: inverted") for s in ups)
    assert found.dropped["equivalent"] == found.dropped_names["equivalent"].count("6-SPU") == len(ups)
    base, plat = np.array([0.3, 0.05, 0.0]), np.array([0.12, -0.06, 0.0])
    spu = parasynth.model.chains.SPU("L1", base=base, platform=plat)
    rng = np.random.default_rng(6)
    p = np.array([0.0, 0.0, 0.4]) + rng.uniform(-0.05, 0.05, (10, 3))
    R = euler_to_matrix("xyz", rng.uniform(-0.2, 0.2, (10, 3)))
    a = spu.solve(p, R).actuator
    assert np.allclose(a, UPS("L1", base=base, platform=plat).solve(p, R).actuator, atol=1e-9)


def test_without_ups_the_6_spu_is_reported_with_the_6_sps():
    """Without the UPS among the limb types, the 6-SPS and the 6-SPU (each a UPS up to an idle spin
    or an inversion) are still one structure per layout: the first, the 6-SPS, with the 6-SPU as
    its equivalent, both reasons said."""
    found = _found("3T3R", ("SPS", "SPU"), (6,))
    assert not [s for s in found if s.name == "6-SPU"]
    sps = _named(found, "6-SPS")
    assert sps and all(("6-SPU", "inverted, idle spin") in s.equivalents for s in sps)
    assert found.dropped_names["equivalent"].count("6-SPU") == len(sps)


def _angle(a, b):
    return float(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1.0, 1.0)))


def test_chain_limbs_get_the_joint_angle_limits_of_their_end_joints():
    """A generated 6-PRRS limits its spherical platform joint (platform_joint_max) and a 6-URPU its
    two universal joints. The URPU's limited angles, computed here from its joint centres: at the
    base, the angle of the link from the base anchor to the revolute's centre against its home
    direction; at the platform, the angle of the link arriving from the revolute's centre against
    its home direction carried by the platform."""
    prrs = next(s for s in _named(_found("3T3R", ("PRRS",)), "6-PRRS") if s.verified)
    keys = {c["key"] for c in prrs.description["constraints"] if c["type"] == "joint_angle"}
    assert keys == {"S_platform_cone"}
    urpu = next(s for s in _named(_found("3T3R", ("URPU",)), "6-URPU") if s.verified)
    keys = {c["key"] for c in urpu.description["constraints"] if c["type"] == "joint_angle"}
    assert keys == {"U_base_cone", "U_platform_cone"}
    m = urpu.mechanism()
    leg = m.legs[0]
    _, _, _, home_points = leg.forward(np.zeros((1, leg.n_joint_dof)))
    C0, A0 = home_points[2][0], leg._home
    X = m.home + np.array([0.03, -0.02, 0.01, 0.08, -0.05, 0.04])
    p, R = m._pose(X[None])
    st = leg.solve(p, R)
    assert st.reachable[0]
    C, A = st.extra["points"][2][0], st.extra["points"][-1][0]
    base_cone = _angle(C - leg.base, C0 - leg.base)
    plat_cone = _angle(A - C, R[0] @ (A0 - C0))
    assert min(base_cone, plat_cone) > 0.005
    assert np.isclose(st.angles["U_base_cone"][0], base_cone, atol=1e-9)
    assert np.isclose(st.angles["U_platform_cone"][0], plat_cone, atol=1e-9)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        assert m.is_feasible(np.atleast_2d(m.home))[0]
