"""Tests of parasynth.measures.indices: transmission, conditioning, singularity statistics, statics.

Expected values come from hand analysis of small mechanisms (tests/_toy_mechanisms.py), the
2018 paper's closed-form limb vectors, finite differences of the inverse kinematics, and
virtual-power identities that do not use the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest
from _support import central_difference, load, sample_poses
from _toy_mechanisms import Iso6, Tsai3

import parasynth
from parasynth.measures import indices as I

d2r = np.deg2rad


# --------------------------------------------------------------------------- transmission
def test_lti_is_one_at_the_isotropic_pose_of_six_orthogonal_legs():
    mech = Iso6()
    ti = I.transmission_indices(mech, np.zeros(6))
    np.testing.assert_allclose(ti.input, 1.0, atol=1e-12)
    np.testing.assert_allclose(ti.output, 1.0, atol=1e-12)
    assert ti.lti == pytest.approx(1.0, abs=1e-12)
    assert ti.uncontrolled == 0
    # Leg 1 (along x at +r e_y) alone drives the twist (e_x, -e_z / r): its anchor moves along x.
    t = ti.output_twists[0]
    v_anchor = t[:3] + np.cross(t[3:], [0.0, mech.r, 0.0])
    np.testing.assert_allclose(np.cross(v_anchor, [1.0, 0, 0]), 0.0, atol=1e-12)
    # Away from it the index drops below 1 but stays high.
    lti = I.local_transmission_index(mech, [[0.02, -0.01, 0.03, 0.1, -0.05, 0.08]])
    assert 0.9 < lti[0] < 1.0 - 1e-4


def test_lti_is_one_for_the_translational_3upu_with_orthogonal_legs():
    """Lower mobility: the output twists must respect the UPU legs' constraint couples."""
    mech = Tsai3()
    ti = I.transmission_indices(mech, np.zeros((1, 3)))
    np.testing.assert_allclose(ti.output, 1.0, atol=1e-12)
    assert ti.lti[0] == pytest.approx(1.0, abs=1e-12)
    # The output twists are pure translations along the legs.
    np.testing.assert_allclose(ti.output_twists[0, :, 3:], 0.0, atol=1e-12)
    np.testing.assert_allclose(ti.output_twists[0, :, :3], np.eye(3), atol=1e-12)


def test_transmission_indices_do_not_depend_on_the_length_scale():
    X = [[0.02, -0.01, 0.03, 0.1, -0.05, 0.08]]
    a = I.transmission_indices(Iso6(length_scale=0.2), X)
    b = I.transmission_indices(Iso6(length_scale=3.0), X)
    np.testing.assert_allclose(a.output, b.output, rtol=1e-10)


def _output_ti_by_inversion(mech, X):
    """Independent route for a controlled mechanism: the output twist of leg i solves
    [a_j / s_j; c_k] t = e_i (every other actuator rate and every constraint power zero);
    the index is the cosine between the leg line and its anchor's velocity."""
    W = mech.wrench_matrix(X)
    ik = mech.inverse_kinematics(X)
    p = mech.pose(X)[0]
    na = mech.n_actuators
    out = np.zeros((len(X), na))
    for k in range(len(X)):
        for i in range(na):
            rhs = np.zeros(W.shape[1])
            rhs[i] = 1.0
            t = np.linalg.lstsq(W[k], rhs, rcond=None)[0]
            st = [s for leg, s in zip(mech.legs, ik.legs) if leg.is_actuated][i]
            vA = t[:3] + np.cross(t[3:], st.platform_point[k] - p[k])
            n = st.direction[k]
            out[k, i] = abs(n @ vA) / np.linalg.norm(vA)
    return out


@pytest.mark.parametrize("name,params", [("5pus_upu", {}), ("2rpu_2sps", {"coupled": False}), ("2rpu_2sps", {})])
def test_output_index_matches_an_independent_inversion(name, params):
    mech = load(name, params)
    X = sample_poses(mech, np.random.default_rng(3), 6)
    if name == "2rpu_2sps":
        X = X + np.where(np.array([c == "theta" for c in mech.task_coordinates]), 0.3, 0.0)
    ti = I.transmission_indices(mech, X)
    assert np.all(ti.uncontrolled == 0)
    np.testing.assert_allclose(ti.output, _output_ti_by_inversion(mech, X), rtol=1e-7, atol=1e-10)
    # PUS legs: the input index is the cosine between link and slider.
    if name == "5pus_upu":
        ik = mech.inverse_kinematics(X)
        cosines = np.stack([abs(st.direction[:, 2]) for st in ik.legs[:5]], axis=1)
        np.testing.assert_allclose(ti.input, cosines, rtol=1e-12)
    else:
        np.testing.assert_allclose(ti.input, 1.0)


def test_lti_vanishes_at_the_theta_zero_singularity_of_the_2t2r_mechanism():
    mech = load("2rpu_2sps", {})
    lti = I.local_transmission_index(mech, [[0.75, 0.0, 0.0], [0.75, 0.0, d2r(1.0)], [0.75, 0.0, d2r(20.0)]])
    assert lti[0] < 1e-10
    assert 0 < lti[1] < lti[2]


def test_underactuated_output_index_is_the_best_over_the_uncontrolled_freedom():
    """4-UPS/1-RPS: locking three actuators leaves a 2-D set of twists; the index is the
    largest pressure-angle cosine over that set (checked by a brute-force scan)."""
    mech = load("4ups_1rps", {})
    X = np.array([[0.03, 0.45, d2r(10), d2r(-15), d2r(5)]])
    ti = I.transmission_indices(mech, X)
    assert ti.uncontrolled[0] == 1
    W = mech.wrench_matrix(X)[0].copy()
    L = mech.length_scale
    Ws = W.copy()
    Ws[:, 3:] /= L
    ik = mech.inverse_kinematics(X)
    p = mech.pose(X)[0][0]
    for i in range(4):
        rows = np.delete(Ws, i, axis=0)
        _, s, Vt = np.linalg.svd(np.vstack([rows, np.zeros((2, 6))]))
        B = Vt[4:].copy()  # two scaled twists
        B[:, 3:] /= L
        st = ik.legs[i]
        r = st.platform_point[0] - p
        n = st.direction[0]
        ang = np.linspace(0, np.pi, 200001)[:, None]
        t = np.cos(ang) * B[0] + np.sin(ang) * B[1]
        vA = t[:, :3] + np.cross(t[:, 3:], r)
        best = np.max(np.abs(vA @ n) / np.linalg.norm(vA, axis=1))
        assert ti.output[0, i] == pytest.approx(best, abs=1e-8)


def test_unreachable_poses_give_nan_and_are_counted():
    mech = load("5pus_upu", {})
    X = np.array([mech.home, [1.0, 0, 0, 0, 0]])
    lti = I.local_transmission_index(mech, X)
    assert np.isfinite(lti[0]) and np.isnan(lti[1])
    fr = I.good_transmission_fraction(mech, X, threshold=0.0)
    assert (fr.n, fr.n_excluded, fr.value) == (1, 1, 1.0)


def test_good_transmission_fraction_and_volume():
    mech = Iso6()
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(40, 6)) * np.array([0.02, 0.02, 0.02, 0.1, 0.1, 0.1])
    lti = I.local_transmission_index(mech, X)
    thr = float(np.median(lti))
    fr = I.good_transmission_fraction(mech, X, threshold=thr)
    assert fr.value == pytest.approx(np.mean(lti >= thr))
    assert fr.stderr == pytest.approx(np.sqrt(fr.value * (1 - fr.value) / 40))
    vol, err = I.good_transmission_volume(mech, X, workspace_volume=2.0, threshold=thr)
    assert vol == pytest.approx(2.0 * fr.value) and err == pytest.approx(2.0 * fr.stderr)
    assert I.good_transmission_fraction(mech, X).value == 1.0  # all above the default 0.7
    with pytest.raises(ValueError):
        I.good_transmission_fraction(mech, X, threshold=float("nan"))


# --------------------------------------------------------------------------- pressure angles
def _paper_limb_vectors(z, psi, th, a=(0.15, 0.075, 0.15, 0.075), b=(0.55, 0.35, 0.55, 0.35)):
    """Limb vectors B_i -> A_i of the 2018 paper written out from eqs. (1), (5), (6), (10):
    x = z tan(theta), phi = 0, v = (s psi s theta, c psi, s psi c theta), u = (c theta, 0, -s theta)."""
    x = z * np.tan(th)
    s, c = np.sin, np.cos
    q1 = np.array([x - a[0] * s(psi) * s(th), b[0] - a[0] * c(psi), z - a[0] * s(psi) * c(th)])
    q2 = np.array([x - b[1] + a[1] * c(th), 0.0, z - a[1] * s(th)])
    q3 = np.array([x + a[2] * s(psi) * s(th), a[2] * c(psi) - b[2], z + a[2] * s(psi) * c(th)])
    q4 = np.array([x + b[3] - a[3] * c(th), 0.0, z + a[3] * s(th)])
    return [q / np.linalg.norm(q) for q in (q1, q2, q3, q4)]


@pytest.mark.parametrize("pose", [(0.7, 0.0, 0.0), (0.8, d2r(25), d2r(15)), (0.65, d2r(-30), d2r(40))])
def test_pressure_angle_indices_against_hand_computation(pose):
    mech = load("2rpu_2sps", {})
    w1, w2, w3, w4 = _paper_limb_vectors(*pose)
    pa = I.pressure_angle_indices(mech, np.array(pose))
    assert pa.lambda1 == pytest.approx(abs(w2 @ w4), abs=1e-12)
    assert pa.lambda2 == pytest.approx(abs(w1 @ w3), abs=1e-12)
    assert pa.alpha == pytest.approx(np.arccos(abs(w2 @ w4)), abs=1e-9)
    pr = I.pressure_angle_indices(mech, np.array(pose), definition="pressure")
    assert pr.lambda1 == pytest.approx(np.linalg.norm(np.cross(w2, w4)), abs=1e-12)
    assert pr.lambda2 == pytest.approx(np.linalg.norm(np.cross(w1, w3)), abs=1e-12)
    assert pr.alpha + pa.alpha == pytest.approx(np.pi / 2, abs=1e-12)


def test_pressure_angle_indices_at_a_symmetric_pose_by_hand():
    # theta = psi = 0, z = 0.7 m: w2 ~ (-0.275, 0, 0.7), w4 ~ (0.275, 0, 0.7),
    # w1 ~ (0, 0.4, 0.7), w3 ~ (0, -0.4, 0.7).
    mech = load("2rpu_2sps", {})
    pa = I.pressure_angle_indices(mech, [0.7, 0.0, 0.0])
    assert pa.lambda1 == pytest.approx((0.7**2 - 0.275**2) / (0.7**2 + 0.275**2), abs=1e-12)
    assert pa.lambda2 == pytest.approx((0.7**2 - 0.4**2) / (0.7**2 + 0.4**2), abs=1e-12)


def test_pressure_angle_trends_of_figures_13_and_14():
    """Section 7: both indices grow with z and with theta (10-50 deg); lambda1 does not depend
    on psi; lambda2 is largest at psi = 0."""
    mech = load("2rpu_2sps", {})
    z, psi, th = np.meshgrid(np.linspace(0.7, 0.9, 5), d2r(np.linspace(-40, 40, 9)), d2r(np.linspace(10, 50, 5)),
                             indexing="ij")
    pa = I.pressure_angle_indices(mech, np.stack([z.ravel(), psi.ravel(), th.ravel()], -1))
    l1, l2 = pa.lambda1.reshape(z.shape), pa.lambda2.reshape(z.shape)
    assert np.all(np.diff(l1, axis=0) > 0) and np.all(np.diff(l2, axis=0) > 0)
    assert np.all(np.diff(l1, axis=2) > 0) and np.all(np.diff(l2, axis=2) > 0)
    np.testing.assert_allclose(l1, l1[:, :1, :].repeat(9, axis=1), atol=1e-12)
    assert np.all(np.argmax(l2, axis=1) == 4)


def test_pressure_angle_indices_reject_other_models():
    with pytest.raises(ValueError, match="2rpu_2sps"):
        I.pressure_angle_indices(load("4ups_1rps", {}), load("4ups_1rps", {}).home)
    with pytest.raises(ValueError, match="definition"):
        I.pressure_angle_indices(load("2rpu_2sps", {}), [0.7, 0, 0.2], definition="other")


# --------------------------------------------------------------------------- conditioning
def test_condition_number_is_one_at_isotropic_poses():
    assert I.local_condition_number(Iso6(), np.zeros(6)) == pytest.approx(1.0, abs=1e-12)
    assert I.local_condition_number(Iso6(), np.zeros(6), space="twist") == pytest.approx(1.0, abs=1e-12)
    assert I.local_condition_number(Tsai3(), np.zeros(3)) == pytest.approx(1.0, abs=1e-12)
    # The homogenising length matters: with L = 2 r the angular columns halve, kappa = 2.
    assert I.local_condition_number(Iso6(), np.zeros(6), length=0.4) == pytest.approx(2.0, rel=1e-12)


@pytest.mark.parametrize("name,params", [("5pus_upu", {}), ("4ups_1rps", {}), ("2rpu_2sps", {"coupled": False})])
def test_condition_number_against_finite_difference_jacobian(name, params):
    mech = load(name, params)
    X = sample_poses(mech, np.random.default_rng(5), 5)
    if name == "4ups_1rps":
        X[:, 3] = d2r(20)  # away from the z-y-z representation singularity at beta = 0
    if name == "2rpu_2sps":
        X[:, 3] += 0.3
    J = central_difference(lambda Z: mech.inverse_kinematics(Z).actuators, X, np.full(mech.n_task, 1e-6))
    L = mech.length_scale
    ang = np.array([c in mech.angular_coordinates for c in mech.task_coordinates])
    J[:, :, ang] /= L
    s = np.linalg.svd(J, compute_uv=False)
    k = min(J.shape[1:])
    np.testing.assert_allclose(I.local_condition_number(mech, X), s[:, 0] / s[:, k - 1], rtol=1e-6)


def test_global_conditioning_index_is_the_mean_inverse_condition_number():
    mech = load("5pus_upu", {})
    X = np.vstack([sample_poses(mech, np.random.default_rng(1), 30), [[1.0, 0, 0, 0, 0]]])
    k = I.local_condition_number(mech, X)
    g = I.global_conditioning_index(mech, X)
    inv = 1 / k[:-1]
    assert (g.n, g.n_excluded) == (30, 1)
    assert g.value == pytest.approx(inv.mean(), rel=1e-12)
    assert g.stderr == pytest.approx(inv.std(ddof=1) / np.sqrt(30), rel=1e-12)
    assert 0 < g.value <= 1
    assert I.global_conditioning_index(Iso6(), np.zeros((3, 6))).value == pytest.approx(1.0)


def test_singularity_margin_stats_ignore_and_count_unreachable_poses():
    mech = load("5pus_upu", {})
    X = np.vstack([sample_poses(mech, np.random.default_rng(2), 20), [[1.0, 0, 0, 0, 0]]])
    m = mech.singularity_margin(X)
    st = I.singularity_margin_stats(mech, X, percentiles=(50,))
    assert (st.n, st.n_unreachable) == (20, 1)
    assert st.min == pytest.approx(np.nanmin(m)) and st.mean == pytest.approx(np.nanmean(m))
    assert st.percentiles[50] == pytest.approx(np.nanmedian(m))
    assert st.argmin == int(np.nanargmin(m))


# --------------------------------------------------------------------------- statics
CONTROLLED = [("5pus_upu", {}), ("2rpu_2sps", {}), ("2rpu_2sps", {"coupled": False})]


@pytest.mark.parametrize("name,params", CONTROLLED)
def test_static_forces_satisfy_equilibrium_and_virtual_power(name, params):
    mech = load(name, params)
    rng = np.random.default_rng(11)
    X = sample_poses(mech, rng, 8)
    if name == "2rpu_2sps":
        X[:, -1] += 0.3  # theta away from 0
    w = rng.normal(size=(8, 6)) * np.array([50, 50, 50, 5, 5, 5])
    sf = I.static_forces(mech, X, w)
    assert np.all(sf.balanced)
    W = mech.wrench_matrix(X)
    net = np.einsum("nki,nk->ni", W, np.concatenate([sf.line, sf.constraint], axis=1)) + w
    scale = np.abs(w).max()
    assert np.abs(net).max() <= 1e-9 * scale
    np.testing.assert_allclose(sf.residual, net, atol=1e-9 * scale)
    # Virtual power with the independently built Jacobian: F . J X' = -w . T X' for all X'.
    lhs = np.einsum("nk,nkj->nj", sf.actuator, mech.jacobian(X))
    rhs = -np.einsum("ni,nij->nj", w, mech.twist_map(X))
    np.testing.assert_allclose(lhs, rhs, atol=1e-9 * scale)


def test_static_forces_of_the_underactuated_grinding_robot():
    mech = load("4ups_1rps", {})
    home = mech.home
    # Weight through the centre at home (no work on the uncontrolled swing) plus a force
    # along Z (taken by the RPS branch): balanced exactly.
    w_ok = I.gravity_wrench(mech, home, 5.0) + np.array([0, 0, 40.0, 0, 0, 0])
    sf = I.static_forces(mech, home, w_ok)
    assert sf.balanced
    assert np.abs(sf.residual).max() < 1e-9
    assert sf.constraint[0] == pytest.approx(-40.0, abs=1e-9)
    np.testing.assert_allclose(sf.actuator, sf.actuator[0], rtol=1e-9)  # symmetric
    # A force along X at home makes the platform swing: not balanceable.
    w_bad = np.array([10.0, 0, 0, 0, 0, 0])
    sf = I.static_forces(mech, home, w_bad)
    assert not sf.balanced
    assert np.linalg.norm(sf.residual) > 0.1
    # What is left unbalanced is exactly the load's work on the uncontrolled twist.
    t_u = mech.mobility().uncontrolled_twists[0]
    assert sf.residual @ t_u == pytest.approx(w_bad @ t_u, rel=1e-9)
    W = mech.wrench_matrix(home)
    assert np.allclose(W @ t_u, 0, atol=1e-12)


def test_static_forces_input_errors():
    mech = load("5pus_upu", {})
    with pytest.raises(ValueError, match="wrench"):
        I.static_forces(mech, mech.home, [1.0, 2.0])
    with pytest.raises(ValueError, match="finite"):
        I.static_forces(mech, mech.home, [np.nan] * 6)


def test_gravity_wrench_moment_about_P():
    mech = load("4ups_1rps", {})
    X = np.array([0.0, 0.45, 0.0, 0.0, 0.0])
    w = I.gravity_wrench(mech, X, 2.0, com=(0.1, 0.0, 0.0))
    g = I.default_gravity(mech)
    np.testing.assert_allclose(g, [0, -9.80665, 0])
    np.testing.assert_allclose(w, np.r_[2 * g, np.cross([0.1, 0, 0], 2 * g)])
    np.testing.assert_allclose(I.default_gravity(load("5pus_upu", {})), [0, 0, -9.80665])


def test_a_load_of_weight_and_force_poses_the_platform_once(monkeypatch):
    """max_actuator_force's load (weight and an external force at the same point): the platform
    posed once for both wrenches, the wrench bit for bit the sum of gravity_wrench and
    point_force_wrench each posing it itself; a given pose is the one used."""
    from parasynth.measures import objectives

    mech = load("5pus_upu", {})
    X = sample_poses(mech, np.random.default_rng(3), 40, scale=0.3)
    com, F = (0.0, 0.01, -0.15), np.array([300.0, 300.0, -500.0])
    want = I.gravity_wrench(mech, X, 20.0, com=com) + I.point_force_wrench(mech, X, F, com)
    calls = []
    real = type(mech).pose
    monkeypatch.setattr(type(mech), "pose", lambda self, Xa: (calls.append(1), real(self, Xa))[1])
    got = objectives._load(mech, X, 20.0, F, com)
    assert len(calls) == 1 and got.tobytes() == want.tobytes()
    p, R = real(mech, X)
    turned = (p, np.broadcast_to(np.eye(3), R.shape))  # a level platform: the moment of r = com
    w = I.point_force_wrench(mech, X, F, com, pose=turned)
    np.testing.assert_allclose(w[:, 3:], np.cross(np.broadcast_to(com, (40, 3)), np.broadcast_to(F, (40, 3))))


def test_min_max_forces_with_redundant_actuation():
    """Seven legs, three along x: a force along x through P is shared by legs 1, 2 (at +-r e_y)
    and 7 (through P). Moment balance forces F1 = F2; minimising max |F_i| / weight_i with
    weight_7 = 2 gives F1 = F2 = c/4, F7 = c/2 for 2 F1 + F7 = c."""
    mech = Iso6(extra_leg=True)
    w = np.array([12.0, 0, 0, 0, 0, 0])
    mm = I.min_max_forces(mech, np.zeros(6), w, weights=[1, 1, 1, 1, 1, 1, 2])
    c = -12.0
    np.testing.assert_allclose(mm.actuator[[0, 1, 6]], [c / 4, c / 4, c / 2], atol=1e-7)
    np.testing.assert_allclose(mm.actuator[2:6], 0.0, atol=1e-7)
    assert mm.balanced
    W = mech.wrench_matrix(np.zeros(6))
    np.testing.assert_allclose(W.T @ np.r_[mm.line, mm.constraint] + w, 0.0, atol=1e-7)
    # Unweighted: equal thirds, and never worse than the least-squares distribution.
    mm1 = I.min_max_forces(mech, np.zeros(6), w)
    np.testing.assert_allclose(mm1.actuator[[0, 1, 6]], [c / 3] * 3, atol=1e-7)
    ls = I.static_forces(mech, np.zeros(6), w)
    assert np.abs(mm1.actuator).max() <= np.abs(ls.actuator).max() + 1e-9


def test_wrench_capability_hand_cases():
    mech = Iso6()
    r = mech.r
    lim = np.array([10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
    dirs = np.array([
        [1.0, 0, 0, 0, 0, -r],  # force along leg 1's line (through r e_y): leg 1 alone holds it
        [-1.0, 0, 0, 0, 0, r],  # the same line, the other way
        [1.0, 0, 0, 0, 0, 0],  # along x through P: legs 1 and 2 share it equally
        [0, 0, 1.0, 0, 0, 0],  # along z through P, against gravity below
    ])
    m = 3.0
    wg = I.gravity_wrench(mech, np.zeros(6), m)  # (0, 0, -m g) through P
    cap = I.wrench_capability(mech, np.zeros(6), dirs, lim, gravity_wrench=wg)
    np.testing.assert_allclose(cap[:2], [10.0, 10.0], rtol=1e-7)
    assert cap[2] == pytest.approx(2 * 10.0, rel=1e-7)  # the weaker of legs 1, 2 limits it
    assert cap[3] == pytest.approx(m * 9.80665 + 2 * 50.0, rel=1e-7)  # legs 5, 6 share, 50 N each


def test_wrench_capability_constraints_and_underactuation():
    mech = load("4ups_1rps", {})
    cap = I.wrench_capability(mech, mech.home, np.eye(3), 100.0)
    assert cap[2] == np.inf  # along Z through the centre: the RPS branch takes any amount
    assert abs(cap[0]) < 1e-5  # along X: the uncontrolled swing, nothing can be held
    assert 100 < cap[1] < 1000
    # Gravity far beyond what four legs at 1 N can hold: only a load along Y that relieves it
    # can be balanced, at most the weight plus all four legs pushing (symmetric at home).
    wg = I.gravity_wrench(mech, mech.home, 10.0)
    cap = I.wrench_capability(mech, mech.home, np.eye(3), 1.0, gravity_wrench=wg)
    assert np.isnan(cap[0]) and np.isnan(cap[2])
    n_y = [st.direction[0, 1] for st in mech.inverse_kinematics(mech.home[None]).legs[:4]]
    assert cap[1] == pytest.approx(10.0 * 9.80665 + np.sum(n_y), rel=1e-7)


def test_indices_are_exported():
    for name in ("local_transmission_index", "static_forces", "wrench_capability", "global_conditioning_index",
                 "pressure_angle_indices", "inverse_dynamics", "GRINDING_INERTIA", "force_decoupling"):
        assert hasattr(parasynth, name)
