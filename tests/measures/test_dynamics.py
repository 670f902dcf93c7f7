"""Tests of parasynth.measures.dynamics.

The central check is the power balance along smooth trajectories,

    sum_i F_i q_i' + P_gravity + P_external - residual . t = dT/dt,

where the kinetic energy ``T``, the powers and the actuator rates are all computed here from
the geometry alone (inverse-kinematics leg states, platform poses) by finite differences in
time -- body velocities from positions, angular velocities from body frames -- never from
the module's own velocity formulas.
"""

from __future__ import annotations

import numpy as np
import pytest
from _support import load, vee
from _toy_mechanisms import Iso6

import parasynth
from parasynth.measures import dynamics as D
from parasynth.measures import indices as I
from parasynth.model.legs import PUS, RPS, RPU, SPS, UPS, UPU


# --------------------------------------------------------------------------- independent energy
def _frames(leg, st):
    """Body frames (N, 3, 3) of a leg's bodies from the geometry: e3 along the leg, e2 the
    revolute axis or the universal joint's cross axis; None for an SPS leg."""
    n = st.direction
    if isinstance(leg, (RPS, RPU)):
        e2 = np.broadcast_to(leg.r_axis, n.shape)
    elif isinstance(leg, (UPS, UPU, PUS)):
        e2 = np.cross(leg.u_axis, n)
        e2 = e2 / np.linalg.norm(e2, axis=1, keepdims=True)
    else:
        return None
    return np.stack([np.cross(e2, n), e2, n], axis=-1)


def _geometry(mech, inertia, X):
    """[(mass, com (N,3), frame (N,3,3) or None, inertia (3,), kind)] for every body."""
    ik = mech.inverse_kinematics(X)
    p, R = mech.pose(X)
    pl = inertia.platform
    out = [(pl.mass, p + R @ np.asarray(pl.com), R, pl.tensor, "platform")]
    for leg, st in zip(mech.legs, ik.legs):
        li = inertia.legs.get(leg.name)
        if li is None:
            continue
        E = _frames(leg, st)
        if isinstance(leg, PUS):
            out.append((li.cylinder.mass, st.base_point, None, None, "carriage"))
        else:
            out.append((li.cylinder.mass, st.base_point + li.cylinder.offset * st.direction, E,
                        np.diag(li.cylinder.inertia), "S" if E is None else "leg"))
        out.append((li.rod.mass, st.platform_point - li.rod.offset * st.direction, E,
                    np.diag(li.rod.inertia), "S" if E is None else "leg"))
    return out, ik, p, R


def _kinetic_energy_fd(mech, inertia, traj, t, h=1e-6):
    """Kinetic energy at times t from central differences of body positions and frames."""
    Xm, Xp, X0 = traj(t - h)[0], traj(t + h)[0], traj(t)[0]
    bm = _geometry(mech, inertia, Xm)[0]
    bp = _geometry(mech, inertia, Xp)[0]
    b0 = _geometry(mech, inertia, X0)[0]
    T = np.zeros(len(t))
    for (m, cm, Em, Ib, kind), (_, cp, Ep, _, _), (_, _, E0, _, _) in zip(bm, bp, b0):
        v = (cp - cm) / (2 * h)
        T += 0.5 * m * np.sum(v * v, axis=1)
        if kind in ("platform", "leg"):
            w = vee((Ep - Em) / (2 * h) @ np.swapaxes(E0, 1, 2))
            Iw = E0 @ Ib @ np.swapaxes(E0, 1, 2)
            T += 0.5 * np.einsum("ni,nij,nj->n", w, Iw, w)
    # SPS legs: axisymmetric with the mean transverse inertia, angular velocity n x n'.
    ikm, ikp, ik0 = (mech.inverse_kinematics(Z) for Z in (Xm, Xp, X0))
    for leg, stm, stp, st0 in zip(mech.legs, ikm.legs, ikp.legs, ik0.legs):
        li = inertia.legs.get(leg.name)
        if li is None or not isinstance(leg, SPS):
            continue
        w = np.cross(st0.direction, (stp.direction - stm.direction) / (2 * h))
        for body in (li.cylinder, li.rod):
            T += 0.25 * (body.inertia[0] + body.inertia[1]) * np.sum(w * w, axis=1)
    return T


def _check_power_balance(mech, inertia, traj, t, external=None, g=None, rtol=2e-6):
    g = I.default_gravity(mech) if g is None else np.asarray(g)
    X, Xd, Xdd = traj(t)
    sf = D.inverse_dynamics(mech, X, Xd, Xdd, inertia, gravity=g, external=external)
    H = 1e-4
    Tp = _kinetic_energy_fd(mech, inertia, traj, t + H)
    Tm = _kinetic_energy_fd(mech, inertia, traj, t - H)
    dTdt = (Tp - Tm) / (2 * H)
    # Gravity power and actuator rates by finite differences of the geometry at t.
    h = 1e-6
    bm = _geometry(mech, inertia, traj(t - h)[0])[0]
    bp = _geometry(mech, inertia, traj(t + h)[0])[0]
    Pg = sum(m * ((cp - cm) / (2 * h)) @ g for (m, cm, *_), (_, cp, *_) in zip(bm, bp))
    qp, qm = (mech.inverse_kinematics(traj(t + s)[0]).actuators for s in (h, -h))
    qd = (qp - qm) / (2 * h)
    pm, Rm = mech.pose(traj(t - h)[0])
    pp, Rp = mech.pose(traj(t + h)[0])
    _, R0 = mech.pose(X)
    tw = np.concatenate([(pp - pm) / (2 * h), vee((Rp - Rm) / (2 * h) @ np.swapaxes(R0, 1, 2))], axis=1)
    Pext = 0.0 if external is None else np.einsum("ni,ni->n", np.broadcast_to(external, tw.shape), tw)
    lhs = np.sum(sf.actuator * qd, axis=1) + Pg + Pext - np.einsum("ni,ni->n", sf.residual, tw)
    scale = np.max(np.abs(np.sum(sf.actuator * qd, axis=1))) + np.max(np.abs(Pg)) + 1e-3
    np.testing.assert_allclose(lhs, dTdt, atol=rtol * scale)
    return sf, dTdt


def _sine_traj(X0, amp, omega):
    X0, amp, omega = map(np.asarray, (X0, amp, omega))

    def traj(t):
        t = np.atleast_1d(t)[:, None]
        return (X0 + amp * np.sin(omega * t), amp * omega * np.cos(omega * t), -amp * omega**2 * np.sin(omega * t))

    return traj


_LEG_U = D.LegInertia(D.RigidBody(1.2, (0.020, 0.012, 0.002), 0.09), D.RigidBody(0.4, (0.006, 0.003, 0.0005), 0.12))
_LEG_SPS = D.LegInertia(D.RigidBody(0.9, (0.010, 0.014, 0.001), 0.1), D.RigidBody(0.3, (0.004, 0.002, 0.0002), 0.15))

CASES = {
    "5pus_upu": (("5pus_upu", {}), _sine_traj([0.01, -0.01, 0.02, 0.05, -0.04], [0.01, 0.015, 0.02, 0.1, 0.08],
                                              [1.3, 0.9, 1.7, 1.1, 0.7]),
                 D.InertiaModel(D.PlatformInertia(2.0, (0.01, -0.02, 0.015),
                                                  ((0.01, 0.001, 0), (0.001, 0.02, 0.002), (0, 0.002, 0.015))),
                                {**{f"L{i}": D.LegInertia(D.RigidBody(0.5),
                                                          D.RigidBody(0.3, (0.002, 0.001, 0.0001), 0.08))
                                    for i in range(1, 6)}, "L6": _LEG_U})),
    "2rpu_2sps": (("2rpu_2sps", {}), _sine_traj([0.75, 0.1, 0.35], [0.05, 0.2, 0.1], [1.1, 0.8, 1.5]),
                  D.InertiaModel(D.PlatformInertia(5.0, (0.0, 0.02, 0.03), (0.05, 0.03, 0.07)),
                                 {"L1": _LEG_SPS, "L2": _LEG_U, "L3": _LEG_SPS, "L4": _LEG_U})),
    "2rpu_2sps-free": (("2rpu_2sps", {"coupled": False}), _sine_traj([0.15, 0.75, 0.1, 0.35], [0.04, 0.05, 0.2, 0.1],
                                                                      [0.6, 1.1, 0.8, 1.5]),
                       D.InertiaModel(D.PlatformInertia(5.0, (0.0, 0.02, 0.03), (0.05, 0.03, 0.07)),
                                      {"L1": _LEG_SPS, "L2": _LEG_U, "L3": _LEG_SPS, "L4": _LEG_U})),
    "4ups_1rps": (("4ups_1rps", {}), _sine_traj([0.02, 0.45, 0.1, -0.3, 0.1], [0.03, 0.02, 0.2, 0.1, 0.15],
                                                [0.7, 1.1, 0.9, 1.3, 0.5]), D.GRINDING_INERTIA),
}


@pytest.mark.parametrize("case", list(CASES))
def test_inverse_dynamics_power_balance(case):
    (name, params), traj, inertia = CASES[case]
    mech = load(name, params)
    t = np.linspace(0.1, 4.0, 9)
    ext = np.array([3.0, -2.0, 5.0, 0.2, -0.1, 0.3])
    sf, dTdt = _check_power_balance(mech, inertia, traj, t, external=ext)
    assert np.max(np.abs(dTdt)) > 1e-4  # the trajectory is dynamic enough to matter
    if name == "4ups_1rps":
        assert not np.all(sf.balanced)  # under-actuated: a residual is part of the balance
    else:
        assert np.all(sf.balanced)


def _potential(mech, inertia, X, g):
    return -sum(m * (c @ g) for m, c, *_ in _geometry(mech, inertia, X)[0])


@pytest.mark.parametrize("case", list(CASES))
def test_inverse_dynamics_satisfies_lagrange_equations(case):
    """Per task coordinate j: F . J_j + Q_gravity_j + Q_ext_j - residual . T_j
    = d/dt dT/dX'_j - dT/dX_j. The power balance sees only the combination along the motion;
    this sees every term (e.g. gyroscopic moments). T is the module's kinetic energy, which
    test_kinetic_energy_matches_finite_differences checks against the geometry; the potential
    comes from the geometry."""
    (name, params), traj, inertia = CASES[case]
    mech = load(name, params)
    g = I.default_gravity(mech)
    ext = np.array([3.0, -2.0, 5.0, 0.2, -0.1, 0.3])
    t = np.linspace(0.1, 4.0, 5)
    X, Xd, Xdd = traj(t)
    sf = D.inverse_dynamics(mech, X, Xd, Xdd, inertia, external=ext)
    n = mech.n_task
    E = np.eye(n)

    def KE(Z, Zd):
        return D.kinetic_energy(mech, Z, Zd, inertia)

    def momenta(tt):  # T is quadratic in X': a unit central difference is exact
        Z, Zd, _ = traj(tt)
        return np.stack([(KE(Z, Zd + E[j]) - KE(Z, Zd - E[j])) / 2 for j in range(n)], axis=1)

    h, dx = 1e-4, 1e-6
    dpdt = (momenta(t + h) - momenta(t - h)) / (2 * h)
    dTdX = np.stack([(KE(X + dx * E[j], Xd) - KE(X - dx * E[j], Xd)) / (2 * dx) for j in range(n)], axis=1)
    Qg = -np.stack([(_potential(mech, inertia, X + dx * E[j], g) - _potential(mech, inertia, X - dx * E[j], g))
                    / (2 * dx) for j in range(n)], axis=1)
    Tm = mech.twist_map(X)
    lhs = (np.einsum("nk,nkj->nj", sf.actuator, mech.jacobian(X)) + Qg + ext @ Tm
           - np.einsum("ni,nij->nj", sf.residual, Tm))
    rhs = dpdt - dTdX
    assert np.max(np.abs(rhs)) > 1e-3
    np.testing.assert_allclose(lhs, rhs, atol=1e-6 * (np.max(np.abs(lhs)) + 1.0))


def test_power_balance_on_the_isotropic_sps_mechanism_without_gravity():
    mech = Iso6()
    inertia = D.InertiaModel(D.PlatformInertia(1.5, (0.01, 0.0, -0.02), (0.02, 0.03, 0.04)),
                             {f"L{i}": _LEG_SPS for i in range(1, 7)})
    traj = _sine_traj([0.0] * 6, [0.02, 0.01, 0.015, 0.1, 0.12, 0.08], [2.0, 1.5, 1.2, 1.8, 0.9, 1.4])
    _check_power_balance(mech, inertia, traj, np.linspace(0, 3, 7), g=np.zeros(3))


def test_kinetic_energy_matches_finite_differences():
    (name, params), traj, inertia = CASES["5pus_upu"]
    mech = load(name, params)
    t = np.linspace(0, 2, 5)
    X, Xd, _ = traj(t)
    T = D.kinetic_energy(mech, X, Xd, inertia)
    np.testing.assert_allclose(T, _kinetic_energy_fd(mech, inertia, traj, t), rtol=1e-7)


def test_static_limit_equals_statics_with_the_weights():
    """At rest with massless legs, inverse dynamics is the static problem with the platform's
    weight at its centre of mass."""
    mech = load("5pus_upu", {})
    X = np.array([[0.01, 0.0, 0.01, 0.05, 0.02], [-0.02, 0.01, -0.01, 0.0, 0.1]])
    inertia = D.InertiaModel(D.PlatformInertia(4.0, (0.01, 0.02, -0.01), (0.01, 0.01, 0.02)))
    dyn = D.inverse_dynamics(mech, X, np.zeros_like(X), np.zeros_like(X), inertia)
    st = I.static_forces(mech, X, I.gravity_wrench(mech, X, 4.0, (0.01, 0.02, -0.01)))
    np.testing.assert_allclose(dyn.actuator, st.actuator, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(dyn.constraint, st.constraint, rtol=1e-10, atol=1e-10)


def test_weight_of_a_leg_transferred_by_lever_arms():
    """A tilted SPS leg at rest: the platform anchor carries the cylinder's transverse weight
    times d_c / l and the rod's weight minus its transverse part times d_r / l."""
    mech = Iso6()
    X = np.array([[0.05, 0.03, -0.04, 0.0, 0.0, 0.0]])
    mc, dc, mr, dr = 1.3, 0.2, 0.7, 0.1
    inertia = D.InertiaModel(legs={"L5": D.LegInertia(D.RigidBody(mc, (0.1, 0.1, 0.01), dc),
                                                      D.RigidBody(mr, (0.1, 0.1, 0.01), dr))})
    g = np.array([0.0, 0.0, -9.81])
    w = D.equivalent_load(mech, X, np.zeros_like(X), np.zeros_like(X), inertia, gravity=g)[0]
    st = mech.inverse_kinematics(X).legs[4]
    n, l, A = st.direction[0], st.length[0], st.platform_point[0]
    gt = g - (g @ n) * n
    fA = mc * gt * dc / l + mr * g - mr * gt * dr / l
    np.testing.assert_allclose(w[:3], fA, atol=1e-12)
    np.testing.assert_allclose(w[3:], np.cross(A - mech.pose(X)[0][0], fA), atol=1e-12)
    # A vertical leg's rod weight is carried by its own actuator alone.
    inertia = D.InertiaModel(legs={"L5": D.LegInertia(D.RigidBody(mc, (0.1, 0.1, 0.01), dc),
                                                      D.RigidBody(mr, (0.1, 0.1, 0.01), dr))})
    sf = D.inverse_dynamics(mech, np.zeros(6), np.zeros(6), np.zeros(6), inertia, gravity=g)
    np.testing.assert_allclose(sf.actuator, [0, 0, 0, 0, mr * 9.81, 0], atol=1e-12)


def test_own_weight_along_a_revolute_axis_stays_in_the_leg():
    """Documented choice: a load a revolute-jointed leg (RPS, RPU) carries along its revolute
    axis is reacted by its base joint, not passed to the platform. The grinding robot with
    only its RPS branch massive and gravity along the branch's revolute axis (Z): nothing
    reaches the platform, every force is zero."""
    mech = load("4ups_1rps", {})
    inertia = D.InertiaModel(legs={"L5": D.GRINDING_INERTIA.legs["L5"]})
    X = np.array([[0.05, 0.45, 0.1, -0.2, 0.1]])
    sf = D.inverse_dynamics(mech, X, np.zeros_like(X), np.zeros_like(X), inertia, gravity=[0, 0, -9.81])
    np.testing.assert_allclose(sf.actuator, 0.0, atol=1e-12)
    np.testing.assert_allclose(sf.constraint, 0.0, atol=1e-12)


def test_inertia_model_validation():
    with pytest.raises(ValueError, match="mass"):
        D.RigidBody(-1.0)
    with pytest.raises(ValueError, match="inertia"):
        D.RigidBody(1.0, (1.0, 2.0))
    with pytest.raises(ValueError, match="unknown leg"):
        D.inverse_dynamics(load("5pus_upu", {}), np.zeros(5), np.zeros(5), np.zeros(5),
                           D.InertiaModel(legs={"L9": D.LegInertia()}))
    with pytest.raises(ValueError, match="Xd"):
        D.inverse_dynamics(load("5pus_upu", {}), np.zeros((2, 5)), np.zeros((3, 5)), np.zeros((2, 5)), D.InertiaModel())


# --------------------------------------------------------------------------- grinding robot
def test_grinding_inertia_is_table_3():
    gi = D.GRINDING_INERTIA
    assert gi.platform.mass == 3.593
    np.testing.assert_allclose(np.diag(gi.platform.tensor), [3.30e-3, 17.79e-3, 16.28e-3])
    assert gi.legs["L1"].cylinder == D.RigidBody(1.458, (15.34e-3, 14.92e-3, 0.72e-3), 0.063)
    assert gi.legs["L4"].rod == D.RigidBody(0.255, (1.95e-3, 1.95e-3, 0.013e-3), 0.155)
    assert gi.legs["L5"].cylinder.mass == 1.311 and gi.legs["L5"].cylinder.offset == 0.133
    assert D.grinding_inertia(rps_rod_mass=0.1).legs["L5"].rod.mass == 0.1


def test_grinding_trajectory_eqs_66_to_68():
    t = np.array([0.0, 2.0, 5.0, 7.0, 10.0, 20.0, 30.0, 50.0])
    X, Xd, Xdd = D.grinding_trajectory(t)
    np.testing.assert_allclose(X[:, 0], [0, 0.008, 0.05, 0.1 - 0.002 * 9, 0.1, 0.0, -0.1, 0.1], atol=1e-15)
    np.testing.assert_allclose(X[:, 1], [0.45, 0.45, 0.45, 0.45, 0.45, 0.55, 0.45, 0.45], atol=1e-15)
    np.testing.assert_allclose(X[:, 3], -np.pi / 12)
    np.testing.assert_allclose(X[:, [2, 4]], 0.0)
    # Derivatives by central differences inside each branch.
    for tt in (1.0, 7.5, 23.0):
        h = 1e-5
        dX = (D.grinding_trajectory(tt + h)[0] - D.grinding_trajectory(tt - h)[0]) / (2 * h)
        ddX = (D.grinding_trajectory(tt + h)[1] - D.grinding_trajectory(tt - h)[1]) / (2 * h)
        np.testing.assert_allclose(D.grinding_trajectory(tt)[1], dX, atol=1e-8)
        np.testing.assert_allclose(D.grinding_trajectory(tt)[2], ddX, atol=1e-8)
    # The printed equations jump in velocity at t = 10 s (documented).
    assert D.grinding_trajectory(10.0 + 1e-9)[1][0, 1] == pytest.approx(0.1 * np.pi / 20, rel=1e-6)
    assert D.grinding_trajectory(10.0)[1][0, 1] == 0.0
    X, Xd, Xdd = D.grinding_lift_trajectory(np.array([0.0, 5.0, 10.0]))
    np.testing.assert_allclose(X[:, 1], [0.45, 0.475, 0.5])
    np.testing.assert_allclose(Xd[:, 1], [0.0, 0.01, 0.0], atol=1e-15)
    with pytest.raises(ValueError):
        D.grinding_trajectory(60.0)


def test_force_decoupling_numbers():
    res = D.force_decoupling(dt=1.0)
    s = res.summary()
    # A grinding force along Z with no moment about the centre is exactly what the RPS
    # branch's constraint wrench can take: all of it goes there and none to the legs.
    for key in ("constraint_share_path", "constraint_share_lift"):
        for share in s[key].values():
            assert share == pytest.approx(1.0, abs=1e-9)
    for key in ("drive_change_path", "drive_change_lift"):
        for change in s[key].values():
            assert change < 1e-9
    # Gravity only: the legs carry the weight (positive forces on the L1/L3 pair) and the
    # driving forces are symmetric at the two x = 0 points of the circle, where the weight
    # does no work on the uncontrolled swing and is balanced exactly.
    h1 = res.gravity_only
    for tt in (20.0, 40.0):
        k = int(np.argmin(np.abs(h1.t - tt)))
        a = h1.actuator[k]
        assert a[0] == pytest.approx(a[2], rel=1e-9) and a[1] == pytest.approx(a[3], rel=1e-9)
        assert h1.balanced[k]
    assert s["h1_max"] > 10.0
    # At the grinding point, (0, y_T, 0), the force's moment about the centre reaches the legs.
    s2 = D.force_decoupling(dt=2.0, load_point=(0.0, 0.075, 0.0)).summary()
    assert s2["drive_change_lift_30_50"] > 1.0
    assert 0.5 < s2["constraint_share_lift"][50.0] < 1.0


def test_dynamics_exports():
    assert parasynth.inverse_dynamics is D.inverse_dynamics
    assert parasynth.GRINDING_INERTIA is D.GRINDING_INERTIA
