"""The 6-PUS and 6-RUS hexapods (``hexapod_6pus.yaml``, ``hexapod_6rus.yaml``): inverse
kinematics against closed forms written here from the parameters alone (anchors on the paired
circles, the slider line cut by the sphere of the link length, the crank's a cos t + b sin t = c),
the mirror symmetry of the crank pairs, the Jacobian against finite differences of the inverse
kinematics, a home pose away from singularity, forward kinematics back to the pose, and the
compiled engine against the NumPy reference on random poses."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import parasynth
from parasynth import engine
from test_engine import check_mechanism

# a changed geometry (SI) beside the defaults, inside the naval studies' ranges
PUS_CHANGED = {"base_radius": 0.7, "platform_radius": 0.15, "base_separation": math.radians(40),
               "platform_separation": math.radians(30), "link_length": 0.9, "s_max": 1.0}
RUS_CHANGED = {"base_radius": 0.45, "platform_radius": 0.35, "base_separation": math.radians(30),
               "platform_separation": math.radians(12), "crank_length": 0.25, "link_length": 0.8}


def _load(name, params):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return parasynth.load_mechanism(name, **params)


def _paired(radius, phase_deg, sep):
    """Three pairs centred at phase + 0, 120, 240 deg, the two points of a pair sep apart
    (the first at centre - sep/2)."""
    ang = []
    for k in range(3):
        c = math.radians(phase_deg + 120 * k)
        ang += [c - sep / 2, c + sep / 2]
    ang = np.array(ang)
    return np.stack([radius * np.cos(ang), radius * np.sin(ang), np.zeros(6)], 1), ang


def _platform_points(p, X):
    """Platform spheres in the base frame; leg i goes to platform joint i - 1 (mod 6)."""
    A, _ = _paired(p.platform_radius, 60.0, p.platform_separation)
    A = A[[5, 0, 1, 2, 3, 4]]
    R = Rotation.from_euler("XYZ", X[:, 3:]).as_matrix()  # R = Rx(alpha) Ry(beta) Rz(gamma)
    return X[:, None, :3] + np.einsum("nij,kj->nki", R, A)


def _random_poses(mech, n, seed):
    rng = np.random.default_rng(seed)
    r = mech.default_ranges()
    lo = np.array([r[c][0] for c in mech.task_coordinates])
    hi = np.array([r[c][1] for c in mech.task_coordinates])
    return rng.uniform(lo, hi, size=(n, 6))


@pytest.mark.parametrize("params", [{}, PUS_CHANGED], ids=["default", "changed"])
def test_pus_slider_positions_closed_form(params):
    """Slider i: the vertical line through the base anchor B_i cut by the sphere of radius L
    about the platform joint S_i, the lower intersection (the carriage below the platform):
    s = (S_z - B_z) - sqrt(L^2 - |(S - B)_xy|^2), unreachable when the root is imaginary."""
    mech = _load("hexapod_6pus", params)
    p = mech.params
    X = _random_poses(mech, 400, seed=1)
    B, _ = _paired(p.base_radius, 0.0, p.base_separation)
    S = _platform_points(p, X)
    d = S - B[None]
    disc = p.link_length**2 - d[..., 0] ** 2 - d[..., 1] ** 2
    ik = mech.inverse_kinematics(X)
    reach = np.all(disc >= 0, axis=1)
    assert np.array_equal(ik.reachable, reach)
    assert 50 < reach.sum() <= len(X)  # the comparison covers many poses
    s = d[..., 2] - np.sqrt(np.where(disc >= 0, disc, np.nan))
    np.testing.assert_allclose(ik.actuators[reach], s[reach], rtol=0, atol=1e-12)
    if reach.sum() < len(X):  # an unreachable pose must really be out of the link's reach
        assert np.all(np.min(disc[~reach], axis=1) < 0)


def test_pus_home_by_hand():
    """The default home pose: level, the carriages at mid-stroke (300 mm). Every leg is alike:
    with B = 500 mm (cos -10 deg, sin -10 deg) and S = 300 mm (cos 310 deg, sin 310 deg) the
    horizontal distance is sqrt(500^2 + 300^2 - 2*500*300*cos 40 deg) = 331.94 mm, so the
    700 mm link rises sqrt(700^2 - 331.94^2) = 616.29 mm and the platform is at 916.29 mm. At a
    level pose 900 mm up the carriages are at 900 - 616.29 = 283.71 mm."""
    mech = _load("hexapod_6pus", {})
    dh = math.sqrt(0.5**2 + 0.3**2 - 2 * 0.5 * 0.3 * math.cos(math.radians(40)))
    assert dh == pytest.approx(0.33194, abs=1e-5)
    rise = math.sqrt(0.7**2 - dh**2)
    assert rise == pytest.approx(0.61629, abs=1e-5)
    np.testing.assert_allclose(mech.home, [0, 0, 0.3 + rise, 0, 0, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(mech.inverse_kinematics(mech.home).actuators, np.full(6, 0.3), rtol=0, atol=1e-12)
    X = np.array([0, 0, 0.9, 0, 0, 0])
    np.testing.assert_allclose(mech.inverse_kinematics(X).actuators, np.full(6, 0.9 - rise), rtol=0, atol=1e-12)


def _crank_closed_form(p, X, branch=1):
    """Crank angle of each RUS leg: the crank turns about u = +radial (first of a pair) or
    -radial (second), zero along c0 = u x z, positive towards c1 = u x c0; its tip
    B + h (cos t c0 + sin t c1) lies at L from S when a cos t + b sin t = c with a = d.c0,
    b = d.c1, c = (|d|^2 + h^2 - L^2) / (2h), d = S - B: t = atan2(b, a) + branch acos(c / rho),
    rho = hypot(a, b), wrapped to (-pi, pi]."""
    B, ang = _paired(p.base_radius, 0.0, p.base_separation)
    radial = np.stack([np.cos(ang), np.sin(ang), np.zeros(6)], 1)
    u = radial * np.array([1, -1, 1, -1, 1, -1])[:, None]
    c0 = np.cross(u, [0.0, 0.0, 1.0])
    c1 = np.cross(u, c0)
    S = _platform_points(p, X)
    d = S - B[None]
    h, L = p.crank_length, p.link_length
    a = np.einsum("nki,ki->nk", d, c0)
    b = np.einsum("nki,ki->nk", d, c1)
    c = (np.einsum("nki,nki->nk", d, d) + h * h - L * L) / (2 * h)
    rho = np.hypot(a, b)
    ok = np.abs(c) <= rho
    t = np.arctan2(b, a) + branch * np.arccos(np.clip(c / rho, -1, 1))
    t = np.arctan2(np.sin(t), np.cos(t))
    tip = B[None] + h * (np.cos(t)[..., None] * c0[None] + np.sin(t)[..., None] * c1[None])
    return t, np.all(ok, axis=1), tip, S


@pytest.mark.parametrize("params", [{}, RUS_CHANGED], ids=["default", "changed"])
def test_rus_crank_angles_closed_form(params):
    mech = _load("hexapod_6rus", params)
    p = mech.params
    X = _random_poses(mech, 400, seed=2)
    t, reach, tip, S = _crank_closed_form(p, X)
    ik = mech.inverse_kinematics(X)
    assert np.array_equal(ik.reachable, reach)
    assert 50 < reach.sum()
    np.testing.assert_allclose(ik.actuators[reach], t[reach], rtol=0, atol=1e-10)
    # the closure itself: every crank tip at the link length from its sphere
    dist = np.linalg.norm(S - tip, axis=2)[reach]
    np.testing.assert_allclose(dist, p.link_length, rtol=0, atol=1e-12)


def test_rus_home_and_raised_cranks_by_hand():
    """Leg 1's anchor B = 500 mm at -10 deg, its sphere S = 300 mm at 310 deg. The crank axis
    is radial at -10 deg, the crank's zero c0 = -tangent, its positive turn towards c1 = -z.
    Home is level with the cranks raised 30 deg (t = -30 deg): the tip
    B + 200 mm (cos 30 deg c0 + sin 30 deg z) is 100 mm up, at a horizontal distance from S
    that leaves the 600 mm link a rise of 535.36 mm: home at 635.36 mm. At the level pose
    600 mm up, in the crank's plane the sphere is at a = d.c0, b = d.c1 = -600 mm; both
    assembly modes reach it, the mode taken is the larger angle, about -18.75 deg (raised),
    the other near -125.6 deg."""
    mech = _load("hexapod_6rus", {})
    th_b, th_s = math.radians(-10), math.radians(310)
    B = np.array([0.5 * math.cos(th_b), 0.5 * math.sin(th_b), 0.0])
    S0 = np.array([0.3 * math.cos(th_s), 0.3 * math.sin(th_s), 0.0])
    c0 = -np.array([-math.sin(th_b), math.cos(th_b), 0.0])
    c1 = np.array([0.0, 0.0, -1.0])
    tip = B + 0.2 * (math.cos(math.radians(30)) * c0 + math.sin(math.radians(30)) * np.array([0.0, 0.0, 1.0]))
    assert tip[2] == pytest.approx(0.1, abs=1e-15)
    rise = math.sqrt(0.6**2 - np.sum((S0 - tip)[:2] ** 2))
    assert 0.1 + rise == pytest.approx(0.63536, abs=1e-5)
    np.testing.assert_allclose(mech.home, [0, 0, 0.1 + rise, 0, 0, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(mech.inverse_kinematics(mech.home).actuators, np.full(6, math.radians(-30)), rtol=0,
                               atol=1e-12)
    d = S0 + [0, 0, 0.6] - B
    a, b = d @ c0, d @ c1
    c = (d @ d + 0.2**2 - 0.6**2) / (2 * 0.2)
    t_hi = math.atan2(b, a) + math.acos(c / math.hypot(a, b))
    t_lo = math.atan2(b, a) - math.acos(c / math.hypot(a, b))
    assert math.degrees(t_hi) == pytest.approx(-18.75, abs=0.01)
    assert math.degrees(t_lo) == pytest.approx(-125.6, abs=0.1)
    X = np.array([0, 0, 0.6, 0, 0, 0])
    np.testing.assert_allclose(mech.inverse_kinematics(X).actuators, np.full(6, t_hi), rtol=0, atol=1e-12)


def test_rus_crank_pairs_are_mirror_images():
    """Legs 1 and 2 are mirror images across the base's x-z plane: at the pose mirrored across
    it (y -> -y, R -> M R M with M = diag(1, -1, 1), i.e. alpha -> -alpha, beta -> beta,
    gamma -> -gamma) leg 2's crank angle is leg 1's, and leg 1's is leg 2's."""
    mech = _load("hexapod_6rus", RUS_CHANGED)
    X = _random_poses(mech, 300, seed=3)
    Xm = X * np.array([1, -1, 1, -1, 1, -1])
    M = np.diag([1.0, -1.0, 1.0])
    _, R = mech.pose(X[:5])
    _, Rm = mech.pose(Xm[:5])
    np.testing.assert_allclose(Rm, M @ R @ M, atol=1e-14)  # the mirrored pose is the one claimed
    q, qm = mech.inverse_kinematics(X), mech.inverse_kinematics(Xm)
    ok = q.reachable & qm.reachable
    assert ok.sum() > 50
    np.testing.assert_allclose(qm.actuators[ok][:, 1], q.actuators[ok][:, 0], atol=1e-12)
    np.testing.assert_allclose(qm.actuators[ok][:, 0], q.actuators[ok][:, 1], atol=1e-12)


@pytest.mark.parametrize("name,params", [("hexapod_6pus", {}), ("hexapod_6pus", PUS_CHANGED),
                                         ("hexapod_6rus", {}), ("hexapod_6rus", RUS_CHANGED)])
def test_home_is_assembled_feasible_and_not_singular(name, params):
    """Home (level, carriages at mid-stroke or cranks raised 30 deg) for the defaults and a changed
    geometry: every leg assembled, every constraint met, the normalised singularity margin above
    0.05 (a regular layout would have it at 0), 6 DOF 3T3R."""
    mech = _load(name, params)
    assert mech.inverse_kinematics(mech.home).reachable.all()
    assert mech.is_feasible(mech.home[None])[0]
    assert mech.singularity_margin(mech.home) > 0.05
    mob = mech.mobility(warn=False)
    assert mob.dof == 6 and mob.type == "3T3R"


def test_regular_6pus_is_singular_at_home():
    """Both separations at 60 deg: the joints on regular hexagons, each base joint at the angle
    of its platform joint, so every link lies in its radial plane with the vertical slider.
    At the level home a rotation about z moves each sphere normal to that plane, hence normal
    to its link: no slider moves (the Jacobian's gamma column is zero), the margin is 0. Turning
    the platform pairs off the base's angles removes it."""
    mech = _load("hexapod_6pus", {"base_separation": math.radians(60), "platform_separation": math.radians(60)})
    assert mech.singularity_margin(mech.home) < 1e-9
    J = np.atleast_2d(mech.jacobian(mech.home))
    np.testing.assert_allclose(J[:, 5], 0.0, atol=1e-12)  # gamma moves no actuator
    turned = _load("hexapod_6pus", {"base_separation": math.radians(60), "platform_separation": math.radians(50)})
    assert turned.singularity_margin(turned.home) > 0.01


@pytest.mark.parametrize("name", ["hexapod_6pus", "hexapod_6rus"])
def test_jacobian_against_finite_differences_and_fk_round_trip(name):
    """J maps task rates to actuator rates; the rates are those of the twist map, so the columns
    are checked along the task coordinates: dq/dX_j by central differences of the IK."""
    mech = _load(name, {})
    X = _random_poses(mech, 200, seed=4)
    X = X[mech.is_feasible(X)][:5]
    assert len(X) == 5
    eps = 1e-6
    for x in X:
        J = np.atleast_2d(mech.jacobian(x))
        fd = np.empty((6, 6))
        for j in range(6):
            e = np.zeros(6)
            e[j] = eps
            fd[:, j] = (mech.inverse_kinematics(x + e).actuators.ravel() - mech.inverse_kinematics(x - e).actuators.ravel()) / (2 * eps)
        np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-7)
        back = mech.forward_kinematics(mech.inverse_kinematics(x).actuators.ravel())
        np.testing.assert_allclose(back, x, atol=1e-8)


@pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba not importable: the NumPy path is the engine")
@pytest.mark.parametrize("name,params", [("hexapod_6pus", PUS_CHANGED), ("hexapod_6rus", RUS_CHANGED)])
def test_compiled_engine_agrees_with_numpy(name, params):
    """The shipped defaults are covered by test_engine.py's loop over the registry; here a
    changed geometry, on random poses of a box widened to cut the workspace."""
    mech = _load(name, params)
    ref = check_mechanism(mech, n=4000, seed=5)
    assert 0.0 < ref.mean() < 1.0


@pytest.mark.parametrize("name,params", [("hexapod_6pus", {"link_length": 0.3}), ("hexapod_6rus", {"link_length": 0.2})])
def test_a_link_too_short_for_a_level_home_is_refused(name, params):
    """A link shorter than the horizontal distance it must bridge at home: no level pose is
    assembled, and the parameters are refused naming the check, not built half-way."""
    with pytest.raises(ValueError, match="link_length"):
        _load(name, params)


def test_registry_lists_them():
    names = parasynth.list_mechanisms()
    assert "hexapod_6pus" in names and "hexapod_6rus" in names
    for name, kind in [("hexapod_6pus", "s"), ("hexapod_6rus", "t")]:
        mech = parasynth.load_mechanism(name)
        assert list(mech.actuators) == [f"{kind}{i}" for i in range(1, 7)]
        assert mech.task_coordinates == ("x", "y", "z", "alpha", "beta", "gamma")


@pytest.mark.parametrize("study,name", [("naval_testbed_6pus", "hexapod_6pus"), ("naval_testbed_6rus", "hexapod_6rus")])
def test_naval_studies_assemble_every_corner_of_their_geometry(study, name):
    """Every corner of the studies' geometric variables (radii, separations, link and crank
    lengths; the placement and tool are the task's) with the studies' fixed values builds a
    mechanism whose home is assembled and within the actuator and joint ranges: the
    link-length bounds clear the horizontal span at home (computed here from the corner's
    values). Not asked for: the links' interference (two spheres of a pair 5 deg apart on a
    100 mm circle are closer than the 40 mm links) and the singularity margin (both separations
    at 60 deg is the regular, singular 6-PUS): designs the study rejects or verification catches."""
    import itertools
    from pathlib import Path

    from parasynth.study import load_study

    here = Path(__file__).resolve()
    # the 6-RUS study is kept with the tests until its crank torques are displayed in N m
    path = here.parents[2] / "studies" / f"{study}.yaml"
    s = load_study(path if path.exists() else here.parents[1] / "data" / f"{study}.yaml")
    assert s.mechanism == name
    geo = [v for v in s.variables if not v.name.startswith("task.")]
    assert {v.name for v in geo} >= {"base_radius", "platform_radius", "base_separation", "platform_separation",
                                     "link_length"}
    fixed = dict(s.fixed)
    for corner in itertools.product(*[(v.low, v.high) for v in geo]):
        p = dict(fixed, **{v.name: x for v, x in zip(geo, corner)})
        rb, rp, sb, sp = p["base_radius"], p["platform_radius"], p["base_separation"], p["platform_separation"]
        if name == "hexapod_6pus":
            span = math.sqrt(rb**2 + rp**2 - 2 * rb * rp * math.cos(math.pi / 3 - sb / 2 - sp / 2))
        else:
            hc = p["crank_length"] * math.cos(math.radians(30))
            span = math.hypot(rb * math.cos(sb / 2) - hc * math.sin(sb / 2) - rp * math.cos(math.pi / 3 - sp / 2),
                              rb * math.sin(sb / 2) + hc * math.cos(sb / 2) - rp * math.sin(math.pi / 3 - sp / 2))
        assert p["link_length"] > span
        mech = _load(name, p)
        assert mech.inverse_kinematics(mech.home).reachable.all(), p
        margins = mech.constraint_margins(mech.home[None], engine="numpy")
        for c in ("stroke", "crank_range", "ujoint_limit", "sphere_limit"):
            if c in margins:
                assert margins[c][0] >= 0, (c, p)
