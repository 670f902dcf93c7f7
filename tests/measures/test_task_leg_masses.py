"""Leg masses in the task's inverse dynamics (``task.loads.leg_density``, default 0: massless legs).

Independent values: the actuators' power along a smooth path equals the rate of change of the
legs' kinetic and potential energy, both worked out here from the geometry alone (the leg
lengths from the anchors, each leg's two half rods with their centres of mass, masses and
inertia tensors written by hand, the legs' angular velocity from the universal joint's two
axes); the task measure on its path against the same inverse dynamics on the same samples; the
leg masses against the rod formula of ``moving_mass``; and the bad inputs.
"""

from __future__ import annotations

import numpy as np
import pytest

import parasynth
from parasynth import objectives
from parasynth.measures.dynamics import inverse_dynamics
from parasynth.measures.task import leg_inertia, task_evaluation
from parasynth.model.spatial import euler_to_matrix
from parasynth.model.task import Task, TaskError

NAMES = ("x", "y", "z", "alpha", "beta", "gamma")
G = 9.80665
RHO, DIA, LMAX = 7850.0, 0.04, 0.85


@pytest.fixture(scope="module")
def gs():
    return parasynth.load_mechanism("gough_stewart_6ups")


def _path(mech, t):
    w = 2 * np.pi
    amp = np.array([0.03, 0.02, 0.04, 0.05, 0.04, 0.06])
    ph = np.array([0.0, 1.0, 2.0, 0.0, 0.5, 1.5])
    X = mech.home + amp * np.sin(w * t[:, None] + ph)
    Xd = amp * w * np.cos(w * t[:, None] + ph)
    Xdd = -amp * w * w * np.sin(w * t[:, None] + ph)
    return X, Xd, Xdd


def test_actuator_power_equals_the_legs_energy_rate(gs):
    # massless payload: the actuators' power feeds the legs' kinetic and potential energy alone
    task = Task(poses=gs.home[None, :], coordinates=NAMES, frame="platform", leg_density=RHO, leg_diameter=DIA)
    inertia = leg_inertia(gs, task, {leg.name: LMAX for leg in gs.legs})
    t = np.linspace(0.0, 1.0, 4001)
    h = t[1] - t[0]
    X, Xd, Xdd = _path(gs, t)
    F = inverse_dynamics(gs, X, Xd, Xdd, inertia, gravity=[0.0, 0.0, -G]).actuator

    # the geometry by hand: platform pose from the coordinates (x, y, z, X-Y'-Z'' angles)
    p, R = X[:, :3], euler_to_matrix("xyz", X[:, 3:])
    pm, Rm = gs.pose(X)
    np.testing.assert_allclose(pm, p, atol=1e-12)
    np.testing.assert_allclose(Rm, R, atol=1e-12)
    m = RHO * np.pi * DIA ** 2 / 4 * (LMAX / 2)  # each half rod
    It = m * (3 * (DIA / 2) ** 2 + (LMAX / 2) ** 2) / 12  # about its centre, across the rod
    Ia = m * (DIA / 2) ** 2 / 2  # along the rod
    E = np.zeros(len(t))
    q = np.zeros((len(t), 6))
    for i, leg in enumerate(gs.legs):
        B = np.asarray(leg.base, float)
        A = p + R @ np.asarray(leg.platform, float)
        u = A - B
        L = np.linalg.norm(u, axis=1)
        n = u / L[:, None]
        q[:, i] = L
        c1 = B + (LMAX / 4) * n  # the cylinder's centre, a quarter of the longest length from the base joint
        c2 = A - (LMAX / 4) * n  # the rod's, from the platform joint
        nd = np.gradient(n, h, axis=0)
        # the leg turns about the universal joint's fixed axis a1 and its cross axis e2 (both
        # across the leg): omega = alpha a1 + beta e2 with omega x n = n'
        a1 = np.broadcast_to(np.asarray(leg.u_axis, float), n.shape)
        e2 = np.cross(a1, n)
        e2 /= np.linalg.norm(e2, axis=1, keepdims=True)
        Mx = np.stack([np.cross(a1, n), np.cross(e2, n)], axis=2)  # (N, 3, 2)
        ab = np.einsum("nij,nj->ni", np.linalg.pinv(Mx), nd)
        omega = ab[:, :1] * a1 + ab[:, 1:] * e2
        Iw = It * (omega - np.sum(omega * n, axis=1, keepdims=True) * n) + Ia * np.sum(omega * n, axis=1,
                                                                                     keepdims=True) * n
        for c in (c1, c2):
            v = np.gradient(c, h, axis=0)
            E += 0.5 * m * np.sum(v * v, axis=1) + 0.5 * np.sum(omega * Iw, axis=1) + m * G * c[:, 2]
    qd = np.gradient(q, h, axis=0)
    power = np.sum(F * qd, axis=1)
    dE = np.gradient(E, h)
    k = slice(5, -5)
    scale = np.max(np.abs(dE[k]))
    assert scale > 1.0  # the legs do move and rise: a test that can fail
    # the actuator force is positive pushing; the power it delivers is what the legs gain
    # (finite differences of 2.5e-4 s leave about 1e-7 of the scale; a centre of mass 10 % off,
    # or twice the rods' transverse inertia, leave 3e-4 and more; the axial moment of
    # the 40 mm rods is too small to show)
    np.testing.assert_allclose(power[k], dE[k], atol=1e-5 * scale)


def test_the_task_measure_carries_the_legs_masses(gs):
    P = np.array([gs.home, gs.home + [0.05, 0.0, 0.04, 0.0, 0.1, 0.2]])
    lim = dict(speed=0.5, acceleration=2.0, angular_speed=1.0, angular_acceleration=3.0, jerk_time=0.05, dt=0.005)
    kw = dict(coordinates=NAMES, frame="platform", payload=dict(mass=5.0, com=[0, 0, 0.02]), leg_diameter=DIA)
    heavy = Task(poses=P, trajectory=lim, leg_density=RHO, **kw)
    light = Task(poses=P, trajectory=lim, **kw)
    force = objectives.get("task_actuator_force_max")
    f_heavy, f_light = force(gs, task=heavy), force(gs, task=light)
    assert f_heavy > f_light
    # the same inverse dynamics on the same samples (the path's coordinates and rates)
    ev = task_evaluation(gs, heavy)
    inertia = ev.inertia
    lengths = {leg.name: float(np.max(np.linalg.norm(
        gs.pose(P)[0] + gs.pose(P)[1] @ np.asarray(leg.platform, float) - np.asarray(leg.base, float), axis=1)))
        for leg in gs.legs}
    m_half = RHO * np.pi * DIA ** 2 / 4 * lengths[gs.legs[0].name] / 2
    assert inertia.legs[gs.legs[0].name].cylinder.mass == pytest.approx(m_half, rel=1e-12)
    # the rods weigh what moving_mass counts for the legs
    total = sum(li.cylinder.mass + li.rod.mass for li in inertia.legs.values())
    rods = objectives.get("moving_mass")(gs, task=heavy, density=RHO, platform_thickness=0.0)
    assert total == pytest.approx(rods, rel=1e-12)
    pa = ev.path
    sf = inverse_dynamics(gs, pa.X, pa.Xd, pa.Xdd, inertia, gravity=heavy.gravity_vector())
    assert f_heavy == pytest.approx(float(np.max(np.abs(sf.actuator))), rel=2e-4)
    # at rest (no trajectory) the legs' weight alone is added to the payload's
    still = Task(poses=P, leg_density=RHO, **kw)
    sf0 = inverse_dynamics(gs, P, np.zeros_like(P), np.zeros_like(P), inertia, gravity=still.gravity_vector())
    assert force(gs, task=still) == pytest.approx(float(np.max(np.abs(sf0.actuator))), rel=1e-9)


def test_massless_legs_are_the_default(gs):
    t = Task(poses=gs.home[None, :])
    assert t.leg_density == 0.0 and not leg_inertia(gs, t).legs


def test_bad_leg_density_inputs(gs):
    with pytest.raises(TaskError, match=r"task.loads.leg_density: must be >= 0"):
        Task.from_mapping({"poses": {"list": [{"x": "0 mm"}]}, "loads": {"leg_density": "-1 kg/m^3"}})
    with pytest.raises(TaskError, match=r"task.loads.leg_density: a bare number"):
        Task.from_mapping({"poses": {"list": [{"x": "0 mm"}]}, "loads": {"leg_density": 7850}})
    ok = Task.from_mapping({"poses": {"list": [{"x": "0 mm"}]}, "loads": {"leg_density": "7.85 g/cm^3"}})
    assert ok.leg_density == pytest.approx(7850.0)
    rus = parasynth.load_mechanism("hexapod_6rus")
    t = Task(poses=rus.home[None, :], leg_density=RHO, leg_diameter=DIA)
    with pytest.raises(TaskError, match=r"task.loads.leg_density: leg masses are modelled for SPS, UPS and PUS legs"):
        leg_inertia(rus, t)
    nodia = Task(poses=gs.home[None, :], leg_density=RHO, leg_diameter=0.0)
    with pytest.raises(TaskError, match=r"the legs need a diameter"):
        leg_inertia(gs, nodia, {leg.name: 1.0 for leg in gs.legs})
