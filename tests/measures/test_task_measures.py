"""Task measures against independent values: closed-form inverse kinematics of the
Gough-Stewart platform, least-squares statics and Newton-Euler dynamics written here, finite
differences of the sampled path, the gamma = 90 deg singularity, brute-force distances."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial import cKDTree

import parasynth
from parasynth import objectives
from parasynth.measures.task import path_continuity, task_evaluation
from parasynth.model.spatial import euler_to_matrix
from parasynth.model.task import Task, TaskError

G = 9.80665


@pytest.fixture(scope="module")
def gs():
    return parasynth.load_mechanism("gough_stewart_6ups")


def _anchors(mech):
    B = np.array([leg.base for leg in mech.legs])
    A = np.array([leg.platform for leg in mech.legs])
    return B, A


def _legs_by_hand(mech, X):
    """Leg vectors (N, 6, 3) of the 6-UPS: l_i = p + Rx(a) Ry(b) Rz(c) a_i - b_i."""
    B, A = _anchors(mech)
    out = []
    for x in X:
        ca, sa, cb, sb, cc, sc = np.cos(x[3]), np.sin(x[3]), np.cos(x[4]), np.sin(x[4]), np.cos(x[5]), np.sin(x[5])
        Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
        Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
        Rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
        R = Rx @ Ry @ Rz
        out.append(x[:3] + A @ R.T - B)
    return np.array(out)


def _poses(n, seed=0, spread=1.0):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-0.15, 0.15, (n, 2)) * spread, rng.uniform(0.4, 0.95, n),
                            rng.uniform(-0.3, 0.3, (n, 3)) * spread])


def test_coverage_is_the_share_of_poses_within_the_stroke_by_closed_form_ik(gs):
    X = _poses(400)
    lengths = np.linalg.norm(_legs_by_hand(gs, X), axis=2)
    inside = np.all((lengths >= 0.45) & (lengths <= 0.9), axis=1)
    assert 0.2 < inside.mean() < 0.95  # the case tests both sides
    task = Task(poses=X)
    got = objectives.get("task_coverage")(gs, task=task, constraints=["stroke"])
    assert got == pytest.approx(inside.mean(), abs=1e-12)
    # the leg lengths the measures use are the closed form's
    ev = task_evaluation(gs, task, ["stroke"])
    np.testing.assert_allclose(gs.inverse_kinematics(ev.X).actuators, lengths, atol=1e-12)
    # the total stroke: sum of each leg's range over the feasible poses
    stroke = objectives.get("total_stroke")(gs, task=task, constraints=["stroke"])
    Lf = lengths[inside]
    assert stroke == pytest.approx(np.sum(Lf.max(0) - Lf.min(0)), rel=1e-12)


def test_tool_and_placement_move_the_platform_by_hand(gs):
    """Tool poses given in a placed task frame: the platform's legs by hand."""
    rng = np.random.default_rng(1)
    T = np.column_stack([rng.uniform(-0.05, 0.05, (20, 2)), rng.uniform(0.55, 0.65, 20),
                         rng.uniform(-0.1, 0.1, (20, 3))])
    tool, tool_yaw = np.array([0.01, -0.02, 0.08]), 0.3
    off, yaw = np.array([0.02, 0.01, -0.05]), 0.2
    task = Task(poses=T, coordinates=("x", "y", "z", "alpha", "beta", "gamma"), tool=tool, tool_yaw=tool_yaw,
                placement={"offset": off, "yaw": yaw})
    X = task.platform_poses(gs)
    # by hand: R_BP = Rz(yaw) R_WT Rz(tool_yaw)^T, p_BP = off + Rz(yaw) p_WT - R_BP tool
    cz, sz = np.cos(yaw), np.sin(yaw)
    Rw = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    ct, st = np.cos(tool_yaw), np.sin(tool_yaw)
    Rt = np.array([[ct, -st, 0], [st, ct, 0], [0, 0, 1]])
    RWT = euler_to_matrix("xyz", T[:, 3:])
    RBP = Rw @ RWT @ Rt.T
    pBP = off + T[:, :3] @ Rw.T - RBP @ tool
    p, R = gs.pose(X)
    np.testing.assert_allclose(p, pBP, atol=1e-12)
    np.testing.assert_allclose(R, RBP, atol=1e-12)
    # hanging: W turned 180 deg about x, a tool pose at z = -0.6 is the platform at z = +0.6
    hang = Task(poses=np.array([[0.0, 0.0, -0.6, np.pi, 0.0, 0.0]]), coordinates=("x", "y", "z", "alpha", "beta",
                                                                                  "gamma"),
                placement={"hanging": True})
    np.testing.assert_allclose(hang.platform_poses(gs)[0], [0, 0, 0.6, 0, 0, 0], atol=1e-12)


def _wrench_rows(mech, X):
    """Unit actuation wrenches (N, 6, 6) of the 6-UPS about the platform point by hand."""
    legs = _legs_by_hand(mech, X)
    n = legs / np.linalg.norm(legs, axis=2, keepdims=True)
    B, _ = _anchors(mech)
    r = B[None] + legs - X[:, None, :3]  # platform joint centres relative to P
    return np.concatenate([n, np.cross(r, n)], axis=2), r


def _rot(X):
    return euler_to_matrix("xyz", X[:, 3:])


def test_static_forces_by_least_squares(gs):
    X = _poses(60, seed=2, spread=0.6)
    tool = np.array([0.02, 0.0, 0.12])
    com = np.array([0.01, -0.02, 0.05])
    wrench = np.array([15.0, -8.0, -60.0, 1.5, -2.0, 0.7])
    task = Task(poses=X, tool=tool, wrench=wrench, payload={"mass": 4.0, "com": com})
    W, _ = _wrench_rows(gs, X)
    R = _rot(X)
    expected = []
    for k in range(len(X)):
        rt, rc = R[k] @ tool, R[k] @ com
        f = wrench[:3] + 4.0 * np.array([0, 0, -G])
        m = wrench[3:] + np.cross(rt, wrench[:3]) + np.cross(rc, 4.0 * np.array([0, 0, -G]))
        F, *_ = np.linalg.lstsq(W[k].T, -np.concatenate([f, m]), rcond=None)
        expected.append(F)
    expected = np.array(expected)
    feas = gs.is_feasible(X)
    assert feas.sum() >= 10
    got = objectives.get("task_actuator_force_max")(gs, task=task)
    assert got == pytest.approx(np.abs(expected[feas]).max(), rel=1e-9)
    # every sign combination of the wrench's components: brute force over the 64 of them
    signed = Task(poses=X, tool=tool, wrench=wrench, wrench_signs=True, payload={"mass": 4.0, "com": com})
    worst = 0.0
    for sg in itertools.product((-1.0, 1.0), repeat=6):
        w = wrench * np.array(sg)
        for k in np.flatnonzero(feas):
            rt, rc = R[k] @ tool, R[k] @ com
            f = w[:3] + 4.0 * np.array([0, 0, -G])
            m = w[3:] + np.cross(rt, w[:3]) + np.cross(rc, 4.0 * np.array([0, 0, -G]))
            F, *_ = np.linalg.lstsq(W[k].T, -np.concatenate([f, m]), rcond=None)
            worst = max(worst, np.abs(F).max())
    assert objectives.get("task_actuator_force_max")(gs, task=signed) == pytest.approx(worst, rel=1e-9)


def test_inverse_dynamics_of_a_payload_against_newton_euler(gs):
    """A straight move with a turn about z: Newton-Euler of the payload by hand, legs massless."""
    P = np.array([[-0.05, 0.02, 0.58, 0.0, 0.0, -0.3], [0.08, -0.03, 0.66, 0.0, 0.0, 0.4]])
    m, com = 6.0, np.array([0.02, -0.01, 0.07])
    I = np.array([[0.05, 0.004, 0.0], [0.004, 0.07, 0.002], [0.0, 0.002, 0.09]])
    task = Task(poses=P, payload={"mass": m, "com": com, "inertia": I},
                trajectory={"speed": 0.4, "acceleration": 3.0, "angular_speed": 2.0, "angular_acceleration": 30.0,
                            "jerk_time": 0.02, "dt": 0.002})
    ev = task_evaluation(gs, task)
    path = ev.path
    X, Xd, Xdd, t = path.X, path.Xd, path.Xdd, path.t
    # the path's rates are the derivatives of its samples (central differences)
    np.testing.assert_allclose((X[2:] - X[:-2]) / (t[2:] - t[:-2])[:, None], Xd[1:-1], atol=2e-3)
    # (a central difference is off by up to jerk * dt / 2 next to a jump of the jerk: 1500 rad/s^3 here)
    np.testing.assert_allclose((Xd[2:] - Xd[:-2]) / (t[2:] - t[:-2])[:, None], Xdd[1:-1], atol=1.6)
    assert np.allclose(X[:, 3:5], 0.0, atol=1e-12)  # a turn about z only: omega = gamma' e_z
    W, _ = _wrench_rows(gs, X)
    R = _rot(X)
    g = np.array([0, 0, -G])
    expected = []
    for k in range(len(X)):
        w = np.array([0, 0, Xd[k, 5]])
        al = np.array([0, 0, Xdd[k, 5]])
        r = R[k] @ com
        ac = Xdd[k, :3] + np.cross(al, r) + np.cross(w, np.cross(w, r))
        F = m * (g - ac)
        Iw = R[k] @ I @ R[k].T
        Mp = np.cross(r, F) - (Iw @ al + np.cross(w, Iw @ w))
        f, *_ = np.linalg.lstsq(W[k].T, -np.concatenate([F, Mp]), rcond=None)
        expected.append(np.abs(f))
    expected = np.array(expected)
    got = ev.dynamic_forces
    ok = ev.path_feasible
    assert ok.all()
    np.testing.assert_allclose(got, expected, rtol=1e-7, atol=1e-7)
    ref = parasynth.inverse_dynamics(gs, X, Xd, Xdd, parasynth.InertiaModel(
        parasynth.measures.dynamics.PlatformInertia(m, com, I))).actuator
    np.testing.assert_allclose(got, np.abs(ref), rtol=1e-9, atol=1e-9)
    assert objectives.get("task_actuator_force_max")(gs, task=task) == pytest.approx(expected.max(), rel=1e-9)
    # actuator speeds: the rates of the closed-form leg lengths by central differences
    L = np.linalg.norm(_legs_by_hand(gs, X), axis=2)
    rates = np.abs((L[2:] - L[:-2]) / (t[2:] - t[:-2])[:, None])
    speed = objectives.get("task_actuator_speed_max")(gs, task=task)
    assert speed == pytest.approx(rates.max(), rel=1e-3)
    power = objectives.get("task_actuator_power_max")(gs, task=task)
    assert power == pytest.approx(expected.max() * speed, rel=1e-12)


def test_a_path_through_the_gamma_90_singularity_breaks_at_the_first_sample_past_it(gs):
    P = np.array([[0.0, 0.0, 0.6, 0.0, 0.0, np.deg2rad(60)], [0.0, 0.0, 0.6, 0.0, 0.0, np.deg2rad(120)]])
    task = Task(poses=P, trajectory={"speed": 0.5, "acceleration": 2.0, "angular_speed": 1.0,
                                     "angular_acceleration": 4.0, "jerk_time": 0.05, "dt": 0.01})
    path = task.path(gs)
    gam = path.X[:, 5]
    past = int(np.argmax(gam > np.pi / 2 + 1e-12))
    assert 0 < past < len(gam) - 1 and gam[past - 1] < np.pi / 2
    c = path_continuity(gs, path.X)
    assert c.rule == "sign" and c.reason == "singularity" and c.first_break == past
    got = objectives.get("task_path_followed")(gs, task=task, constraints=[])
    assert got == pytest.approx(past / len(gam))
    # the same path stopping short of 90 deg is followed
    short = Task(poses=np.array([P[0], [0.0, 0.0, 0.6, 0.0, 0.0, np.deg2rad(85)]]),
                 trajectory={"speed": 0.5, "acceleration": 2.0, "angular_speed": 1.0,
                             "angular_acceleration": 4.0, "dt": 0.01})
    assert path_continuity(gs, short.path(gs).X).ok
    assert objectives.get("task_path_followed")(gs, task=short, constraints=[]) == 1.0


def test_continuity_flags_a_change_of_assembly_mode(gs):
    """Two samples in different poses with the same leg lengths (mirror image through the base
    plane): forward kinematics continued from the first does not reach the second."""
    a = np.array([0.0, 0.0, 0.6, 0.0, 0.0, 0.0])
    b = np.array([0.0, 0.0, -0.6, 0.0, 0.0, 0.0])  # the base plane's mirror, equal leg lengths
    Lb = np.linalg.norm(_legs_by_hand(gs, b[None]), axis=2)
    La = np.linalg.norm(_legs_by_hand(gs, a[None]), axis=2)
    np.testing.assert_allclose(La, Lb, atol=1e-12)
    c = path_continuity(gs, np.array([a, a, b]), floor=0.0)
    assert c.first_break == 2 and c.reason in ("assembly mode", "singularity")


def test_envelope_clearance_against_brute_force_distances(gs):
    X = _poses(15, seed=4, spread=0.5)
    X[:, 2] = np.clip(X[:, 2], 0.55, 0.75)
    box_lo, box_hi = np.array([-0.62, -0.6, -0.05]), np.array([0.6, 0.63, 0.95])
    task = Task(poses=X, space={"shape": "box", "low": box_lo, "high": box_hi}, leg_diameter=0.04)
    got = objectives.get("envelope_clearance")(gs, task=task)
    # brute force: points along every leg and on the platform disc against a dense sampling of
    # the box's surface
    B, A = _anchors(gs)
    legs = _legs_by_hand(gs, X)
    s = np.linspace(0, 1, 41)
    rad = np.max(np.linalg.norm(A[:, :2], axis=1))
    th = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    disc = np.stack([rad * np.cos(th), rad * np.sin(th), 0 * th], 1)
    R = _rot(X)
    u = np.linspace(0, 1, 121)
    faces = []
    for ax in range(3):
        o = [a for a in range(3) if a != ax]
        for side in (box_lo[ax], box_hi[ax]):
            g1, g2 = np.meshgrid(box_lo[o[0]] + u * (box_hi[o[0]] - box_lo[o[0]]),
                                 box_lo[o[1]] + u * (box_hi[o[1]] - box_lo[o[1]]), indexing="ij")
            F = np.zeros((g1.size, 3))
            F[:, ax], F[:, o[0]], F[:, o[1]] = side, g1.ravel(), g2.ravel()
            faces.append(F)
    surf = cKDTree(np.concatenate(faces))  # the nearest sampled surface point of each point
    worst = np.inf
    for k in range(len(X)):
        pts_leg = B[:, None, :] + s[None, :, None] * legs[k][:, None, :]
        d_leg = surf.query(pts_leg.reshape(-1, 3))[0] - 0.02
        pts_disc = X[k, :3] + disc @ R[k].T
        d_disc = surf.query(pts_disc)[0]
        worst = min(worst, d_leg.min(), d_disc.min())
    assert np.all((pts_leg >= box_lo) & (pts_leg <= box_hi))
    step = (box_hi - box_lo).max() / 120
    assert got == pytest.approx(worst, abs=step)
    assert got > 0
    # outside: a box that cuts the base anchors gives a negative clearance of the right size
    cut = Task(poses=X, space={"shape": "box", "low": [-0.62, -0.6, -0.05], "high": [0.45, 0.63, 0.95]},
               leg_diameter=0.0)
    out = objectives.get("envelope_clearance")(gs, task=cut)
    assert out == pytest.approx(-(0.5 * np.cos(np.deg2rad(10)) - 0.45), abs=1e-9)


@pytest.mark.parametrize("space", [
    {"shape": "box", "low": [-0.62, -0.6, -0.05], "high": [0.6, 0.63, 0.95], "base_plane": True},
    {"shape": "box", "low": [-0.55, -0.5, 0.2], "high": [0.45, 0.63, 0.62], "base_plane": False},  # points outside
    {"shape": "cylinder", "radius": 0.58, "z": [-0.05, 0.7], "center": [0.02, 0.0], "base_plane": False},
])
def test_line_legs_clearance_equals_the_legs_states(gs, space):
    """The SPS/UPS fast path (platform poses only) against the general one (the legs solved),
    placed and hanging, inside and outside the space."""
    X = _poses(40, seed=7, spread=0.8)
    for placement in ({}, {"offset": (0.0, 0.0, -0.1), "yaw": 0.4}):
        task = Task(poses=X, space=dict(space), leg_diameter=0.03, placement=placement)
        p, R = gs.pose(X)
        fast = task.line_clearance(gs, p, R)
        slow = task.space_clearance(gs, X)
        assert np.isfinite(slow).all()
        np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-12)
    assert (slow < 0).any() or space["shape"] != "box" or space["base_plane"]


def test_task_measures_support_rus_legs():
    from test_engine_rus import _rus  # the 6-RUS of the engine tests

    mech = _rus(False)
    X = np.tile(mech.home, (30, 1))
    rng = np.random.default_rng(5)
    X[:, :3] += rng.uniform(-0.005, 0.005, (30, 3))
    X[:, 3:] += rng.uniform(-0.02, 0.02, (30, 3))
    task = Task(poses=X, tool=[0, 0, 0.05], wrench=[5, 0, -20, 0, 0, 0.5], payload={"mass": 1.0},
                trajectory={"speed": 0.1, "acceleration": 1.0, "angular_speed": 1.0, "angular_acceleration": 10.0,
                            "dt": 0.01})
    vals = {n: objectives.get(n)(mech, task=task, constraints=[]) for n in
            ("task_coverage", "task_margin_min", "task_condition_max", "task_lti_min",
             "task_actuator_force_max", "task_actuator_speed_max", "task_actuator_power_max", "installed_height",
             "total_stroke")}
    vals["task_stiffness_min"] = objectives.get("task_stiffness_min")(mech, task=task, constraints=[], diameter=0.01)
    vals["moving_mass"] = objectives.get("moving_mass")(mech, task=task, constraints=[], leg_diameter=0.01)
    vals["task_position_error_max"] = objectives.get("task_position_error_max")(mech, task=task, constraints=[],
                                                                                 actuator_tolerance=1e-4)
    assert vals["task_coverage"] == 1.0
    for k, v in vals.items():
        assert np.isfinite(v) and v > 0, (k, v)
    # crank torques: virtual work against the platform's weight, J^T F = -w (least squares here)
    ev = task_evaluation(mech, task, [])
    J = mech.jacobian(ev.X)
    R = mech.pose(ev.X)[1]
    rt = R @ np.array([0, 0, 0.05])
    w = np.array([5, 0, -20.0 - G, 0, 0, 0.5])
    Tm = mech.twist_map(ev.X)
    F_hand = []
    for k in range(len(X)):
        wk = w.copy()
        wk[3:] += np.cross(rt[k], w[:3] - np.array([0, 0, -G]))  # the weight acts at P (com 0)
        # power balance: F . (J xd) + w . (T xd) = 0 for every xd
        F, *_ = np.linalg.lstsq(J[k].T, -(Tm[k].T @ wk), rcond=None)
        F_hand.append(np.abs(F).max())
    assert vals["task_actuator_force_max"] >= max(F_hand) * (1 - 1e-9)
    np.testing.assert_allclose(ev.static_forces.max(axis=1), F_hand, rtol=1e-8)
    # a one-pose error bound: actuator tolerance only, the tool point's error by finite differences
    one = Task(poses=X[:1], tool=[0, 0, 0.05])
    b = objectives.get("task_position_error_max")(mech, task=one, constraints=[], actuator_tolerance=1e-4)
    Jt = Tm[0] @ np.linalg.inv(J[0])  # actuator rates -> platform twist (v_P, omega)
    Mt = Jt[:3] + np.array([np.cross(Jt[3:, j], rt[0]) for j in range(6)]).T  # tool point: v_P + omega x r
    assert b == pytest.approx(np.linalg.norm(np.abs(Mt).sum(axis=1) * 1e-4), rel=1e-4)


def test_one_evaluation_per_design_and_task(gs, monkeypatch):
    X = _poses(50, seed=6, spread=0.5)
    task = Task(poses=X, wrench=[0, 0, -10, 0, 0, 0])
    calls = []
    orig = Task.platform_poses

    def counting(self, mech):
        calls.append(1)
        return orig(self, mech)

    monkeypatch.setattr(Task, "platform_poses", counting)
    for n in ("task_coverage", "task_margin_min", "task_condition_max", "task_lti_min", "task_actuator_force_max"):
        objectives.get(n)(gs, task=task)
    assert len(calls) == 1


def test_condition_number_is_in_si_units(gs):
    X = _poses(20, seed=7, spread=0.4)
    task = Task(poses=X)
    ev = task_evaluation(gs, task, [])
    J = gs.jacobian(X)
    s = np.linalg.svd(J, compute_uv=False)
    feas = gs.is_feasible(X)
    assert objectives.get("task_condition_max")(gs, task=task) == pytest.approx(
        (s[:, 0] / s[:, -1])[feas].max(), rel=1e-8)
    assert ev.X.shape == X.shape


def test_measures_refuse_a_missing_task_and_a_missing_trajectory(gs):
    with pytest.raises(TaskError, match="task"):
        objectives.get("task_coverage")(gs)
    with pytest.raises(ValueError, match="parasynth.Task"):
        objectives.get("task_coverage")(gs, task={"poses": [[0, 0, 0.6, 0, 0, 0]]})
    with pytest.raises(TaskError, match=r"task\.trajectory"):
        objectives.get("task_actuator_speed_max")(gs, task=Task(poses=gs.home[None]))


def test_continuity_applies_the_floors_to_every_path_sample(gs):
    P = np.array([[0.0, 0.0, 0.6, 0.0, 0.0, np.deg2rad(60)], [0.0, 0.0, 0.6, 0.0, 0.0, np.deg2rad(85)]])
    floor = float(gs.singularity_margin(np.array([0.0, 0.0, 0.6, 0.0, 0.0, np.deg2rad(80)])))
    task = Task(poses=P, floors={"singularity_margin": {"min": floor}},
                trajectory={"speed": 0.5, "acceleration": 2.0, "angular_speed": 1.0, "angular_acceleration": 4.0,
                            "dt": 0.01})
    ev = task_evaluation(gs, task, [])
    X = ev.path.X
    # the margin falls as gamma nears 90 deg: the first sample past 80 deg breaks the floor
    expected = int(np.argmax(X[:, 5] > np.deg2rad(80) + 1e-12))
    c = ev.continuity()
    assert c.reason == "floor" and c.first_break == expected
    assert task_evaluation(gs, Task(poses=P, trajectory=task.trajectory), []).continuity().ok


def test_per_pose_wrenches_follow_their_poses(gs):
    """One wrench per pose, some poses infeasible, the poses reordered: each pose keeps its wrench."""
    X = _poses(40, seed=8)
    rng = np.random.default_rng(9)
    Wr = rng.uniform(-50, 50, (40, 6)) * np.array([1, 1, 1, 0.05, 0.05, 0.05])
    feas = gs.is_feasible(X, names=["stroke"])
    assert 0 < feas.sum() < 40
    W, _ = _wrench_rows(gs, X)
    expected = 0.0
    for k in np.flatnonzero(feas):
        F, *_ = np.linalg.lstsq(W[k].T, -Wr[k], rcond=None)
        expected = max(expected, np.abs(F).max())
    for order in ("given", "nearest"):
        task = Task(poses=X, wrench=Wr, order=order)
        got = objectives.get("task_actuator_force_max")(gs, task=task, constraints=["stroke"])
        assert got == pytest.approx(expected, rel=1e-9), order


def test_stiffness_height_and_mass_by_hand(gs):
    X = _poses(30, seed=10, spread=0.5)
    tool = np.array([0.03, -0.01, 0.15])
    task = Task(poses=X, tool=tool)
    feas = gs.is_feasible(X)
    W, r = _wrench_rows(gs, X)
    R = _rot(X)
    k = 2.0e7
    best = np.inf
    for i in np.flatnonzero(feas):
        C = np.linalg.inv(k * W[i].T @ W[i])  # twist (dp, dtheta) per wrench (f, m_P)
        rt = R[i] @ tool
        S = np.array([[0, -rt[2], rt[1]], [rt[2], 0, -rt[0]], [-rt[1], rt[0], 0]])
        A = np.hstack([np.eye(3), -S])  # tool displacement dp + dtheta x r_t; a force at the tool: A^T f
        best = min(best, 1.0 / np.linalg.eigvalsh(A @ C @ A.T)[-1])
    got = objectives.get("task_stiffness_min")(gs, task=task, axial_stiffness=k)
    assert got == pytest.approx(best, rel=1e-8)
    # the tool offset matters: the platform point's stiffness differs
    assert got != pytest.approx(objectives.get("task_stiffness_min")(gs, task=Task(poses=X), axial_stiffness=k),
                                rel=1e-3)
    # installed height: base joints at z = 0, platform joints at p_z + (R a)_z
    B, A = _anchors(gs)
    zt = (X[:, None, 2] + np.einsum("nij,kj->nki", R, A)[..., 2])[feas]
    h = max(zt.max(), B[:, 2].max()) - min(zt.min(), B[:, 2].min())
    assert objectives.get("installed_height")(gs, task=task) == pytest.approx(h, rel=1e-12)
    # moving mass: six rods at their longest length over the task and the platform disc
    L = np.linalg.norm(_legs_by_hand(gs, X[feas]), axis=2).max(axis=0)
    rad = np.max(np.linalg.norm(A[:, :2], axis=1))
    mass = 7850 * (np.pi * 0.04 ** 2 / 4 * L.sum() + np.pi * rad ** 2 * 0.02)
    assert objectives.get("moving_mass")(gs, task=task) == pytest.approx(mass, rel=1e-12)


def test_a_path_in_a_lower_mobility_mechanisms_own_coordinates():
    mech = parasynth.load_mechanism("2rpu_2sps")
    P = np.array([[0.65, np.deg2rad(20), np.deg2rad(10)], [0.70, np.deg2rad(28), np.deg2rad(16)]])
    task = Task(poses=P, coordinates=mech.task_coordinates, payload={"mass": 3.0},
                trajectory={"speed": 0.05, "acceleration": 0.5, "angular_speed": 0.3, "angular_acceleration": 3.0,
                            "jerk_time": 0.02, "dt": 0.002})
    ev = task_evaluation(mech, task, [])
    path = ev.path
    assert np.all(ev.path_feasible)
    # a straight line in (z, psi, theta), at rest at both ends
    d = (path.X - P[0]) / (P[1] - P[0])
    np.testing.assert_allclose(d, d[:, :1] * np.ones((1, 3)), atol=1e-12)
    np.testing.assert_allclose(path.Xd[[0, -1]], 0.0, atol=1e-12)
    # actuator speeds: central differences of the inverse kinematics along the path
    q = mech.inverse_kinematics(path.X).actuators
    t = path.t
    rates = np.abs((q[2:] - q[:-2]) / (t[2:] - t[:-2])[:, None])
    assert objectives.get("task_actuator_speed_max")(mech, task=task, constraints=[]) == pytest.approx(
        rates.max(), rel=1e-3)
    # at rest (the path's ends) the forces are the static ones of the payload's weight
    F = ev.dynamic_forces
    sf = parasynth.static_forces(mech, path.X[[0, -1]], parasynth.measures.indices.gravity_wrench(
        mech, path.X[[0, -1]], 3.0))
    np.testing.assert_allclose(F[[0, -1]], np.abs(sf.actuator), rtol=1e-9)


@pytest.mark.parametrize("rb, rp, sb, sp", [(0.5, 0.3, 20.0, 20.0), (0.4175, 0.1819, 6.746, 14.51), (0.6, 0.2, 40.0, 100.0)])
def test_joint_spacing_min_is_the_closest_pair_of_joints_by_hand(rb, rp, sb, sp):
    """joint_spacing_min on the paired 6-UPS: joints in pairs ``s`` apart on a circle of radius
    ``r``, the pairs 120 deg apart, so the closest two joints of a body are the nearer of a pair's
    chord 2 r sin(s/2) and the chord between neighbouring pairs 2 r sin((120 - s)/2); the smaller
    over base and platform (the second case is the naval design whose joints sit 46-49 mm apart)."""
    from parasynth import load_mechanism, objectives

    m = load_mechanism("gough_stewart_6ups", base_radius=rb, platform_radius=rp, base_separation=np.radians(sb),
                       platform_separation=np.radians(sp))
    chord = lambda r, a: 2 * r * np.sin(np.radians(a) / 2)  # noqa: E731
    want = min(chord(rb, sb), chord(rb, 120 - sb), chord(rp, sp), chord(rp, 120 - sp))
    assert objectives.get("joint_spacing_min")(m) == pytest.approx(want, rel=1e-12)
