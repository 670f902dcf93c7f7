"""The motion profile's options: limits per coordinate, sampled timing (phases rounded up to whole
steps, as the toolbox's traj_trapez2_multipoint / Lambrechts' make3), and path waypoints.

Independent values: finite differences of the sampled coordinates against each coordinate's
limits; one segment's duration and peak speed from the trapezoid formulas worked by hand; the
angular velocity and acceleration of a path whose Euler angles move linearly against finite
differences of its rotation matrices; the samples at rest against the waypoints given.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import parasynth
from parasynth.model.spatial import euler_to_matrix
from parasynth.model.task import Task, TaskError, rotation_log
from parasynth.model.trajectory import MotionLimits, sample_path, segment_timing

NAMES = ("x", "y", "z", "alpha", "beta", "gamma")
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def gs():
    return parasynth.load_mechanism("gough_stewart_6ups")


def test_one_sampled_segment_worked_by_hand():
    # 100 mm at 1 m/s, 3 m/s^2, jerk ramp 0.1 s (jerk 30 m/s^3), phases rounded up to 50 ms.
    # Jerk phase for the distance alone: (p / (2 j))^(1/3) = (0.1 / 60)^(1/3) = 0.1186 s -> 3 steps,
    # 0.15 s, the jerk lowered to p / (2 t1^3) = 14.81 m/s^3; then the peak speed j t1^2 = 1/3 m/s
    # < 1 and the peak acceleration j t1 = 2.22 m/s^2 < 3: neither bound is hit, no constant
    # acceleration and no cruise. Duration 4 t1 = 0.6 s, peak speed p / (2 t1) = 1/3 m/s.
    lim = MotionLimits(speed=1.0, acceleration=3.0, jerk_time=0.1, timing="sampled", step=0.05)
    tm = segment_timing([0.1], [0.0], lim)
    assert tm.duration[0] == pytest.approx(0.6, abs=1e-12)
    assert tm.v[0] * 0.1 == pytest.approx(1.0 / 3.0, rel=1e-12)
    assert tm.a[0] * 0.1 == pytest.approx(0.1 / (2 * 0.15 ** 3) * 0.15, rel=1e-12)
    ps = sample_path([0.1], [0.0], lim, 0.05)
    assert len(ps.t) == 13 and ps.t[-1] == pytest.approx(0.6)
    assert ps.s[0] == 0.0 and ps.s[-1] == pytest.approx(1.0, abs=1e-12)
    # the same segment without rounding: the acceleration bound is hit (j t1 with t1 = 0.1186 would
    # exceed 3), so t1 = a / j = 0.1 s and v (v / a + tj) = p gives the peak speed
    cont = segment_timing([0.1], [0.0], MotionLimits(speed=1.0, acceleration=3.0, jerk_time=0.1))
    v = 0.5 * 3.0 * (-0.1 + math.sqrt(0.01 + 4 * 0.1 / 3.0))
    assert cont.v[0] * 0.1 == pytest.approx(v, rel=1e-12)
    assert cont.v[0] * 0.1 > 1.0 / 3.0  # rounding up slows the short segment down


def test_long_segment_duration_from_the_trapezoid_formula():
    # continuous: T = D / v + v / a + tj for a segment that cruises
    lim = MotionLimits(speed=1.0, acceleration=3.0, jerk_time=0.1)
    assert segment_timing([1.0], [0.0], lim).duration[0] == pytest.approx(1.0 + 1.0 / 3.0 + 0.1, rel=1e-12)
    # per coordinate: a diagonal move (0.6, 0.6, 0) takes as long as 0.6 m along one axis; on the
    # path's norm it is 0.6 sqrt(2) long
    per = MotionLimits(speed=1.0, acceleration=3.0, jerk_time=0.1, limits="per_coordinate")
    P = np.array([[0, 0, 0.6, 0, 0, 0], [0.6, 0.6, 0.6, 0, 0, 0]])
    T_per = Task(poses=P, coordinates=NAMES, frame="platform", trajectory=dict(
        speed=1.0, acceleration=3.0, jerk_time=0.1, limits="per_coordinate", dt=0.001))
    T_path = Task(poses=P, coordinates=NAMES, frame="platform", trajectory=dict(
        speed=1.0, acceleration=3.0, jerk_time=0.1, dt=0.001))
    assert per.limits == "per_coordinate"
    gs = parasynth.load_mechanism("gough_stewart_6ups")
    t_per, t_path = T_per.path(gs).t[-1], T_path.path(gs).t[-1]
    assert t_per == pytest.approx(0.6 + 1.0 / 3.0 + 0.1, abs=1e-3)
    assert t_path == pytest.approx(0.6 * math.sqrt(2) + 1.0 / 3.0 + 0.1, abs=1e-3)


def _fd(X, h):
    v = np.diff(X, axis=0) / h
    a = np.diff(v, axis=0) / h
    j = np.diff(a, axis=0) / h
    return v, a, j


def test_per_coordinate_sampled_path_keeps_every_coordinates_limits(gs):
    P = np.array([[0.0, 0.0, 0.6, 0, 0, 0], [0.15, 0.05, 0.65, 0, 0, 0.3], [0.15, 0.05, 0.65, 0.2, -0.1, 0.35],
                  [0.1, -0.1, 0.6, 0.1, 0, 0], [0.1, -0.1, 0.6, 0.1, 0, 0], [-0.05, -0.1, 0.55, 0.0, 0.05, 0.0]])
    lim = dict(speed=0.25, acceleration=1.5, angular_speed=0.8, angular_acceleration=5.0, jerk_time=0.04)
    h, step = 0.0005, 0.02
    t = Task(poses=P, coordinates=NAMES, frame="platform",
             trajectory={**lim, "dt": h, "limits": "per_coordinate", "timing": "sampled", "step": step})
    path = t.path(gs)
    X = path.X  # gough_stewart_6ups: x, y, z and X-Y'-Z'' angles, the task's own coordinates
    assert np.allclose(np.diff(path.t), h)
    v, a, j = _fd(X, h)
    for cols, vmax, amax in ((slice(0, 3), lim["speed"], lim["acceleration"]),
                             (slice(3, 6), lim["angular_speed"], lim["angular_acceleration"])):
        assert np.abs(v[:, cols]).max() <= vmax * (1 + 1e-6)
        assert np.abs(a[:, cols]).max() <= amax * (1 + 2e-3)
        assert np.abs(j[:, cols]).max() <= amax / lim["jerk_time"] * (1 + 2e-2)
    # the long first move (150 mm along x at 0.25 m/s) comes near its speed limit; the norm of the
    # translation's speed exceeds it where two coordinates move at once (limits per coordinate)
    assert np.abs(v[:, 0]).max() > 0.9 * lim["speed"]
    assert np.linalg.norm(v[:, :3], axis=1).max() > lim["speed"] * 1.0001 or \
        np.linalg.norm(v[:, 3:], axis=1).max() > lim["angular_speed"] * 1.0001
    # every phase a whole number of steps; every pose visited at rest; one step of rest at each
    # corner (the repeated pose makes a segment of one step at rest)
    dur = path.samples.timing.duration
    np.testing.assert_allclose(dur / step, np.round(dur / step), atol=1e-9)
    for k in range(len(P)):
        d = np.linalg.norm(X - P[k], axis=1)
        i = int(np.argmin(d))
        assert d[i] < 1e-12 and np.allclose(path.Xd[i], 0.0, atol=1e-7)
    assert len(path.t) == int(round((dur.sum() + step * (len(dur) - 1)) / h)) + 1


def test_linear_euler_angles_give_the_exact_twist(gs):
    # per coordinate the angles move linearly: omega and its derivative against finite
    # differences of the sampled rotation matrices
    P = np.array([[0.0, 0.0, 0.6, 0.0, 0.0, 0.0], [0.05, 0.0, 0.62, 0.3, -0.25, 0.4]])
    h = 0.0002
    t = Task(poses=P, coordinates=NAMES, frame="platform",
             trajectory=dict(speed=0.5, acceleration=2.0, angular_speed=1.0, angular_acceleration=3.0,
                             jerk_time=0.05, dt=h, limits="per_coordinate"))
    path = t.path(gs)
    R = euler_to_matrix("xyz", path.X[:, 3:])
    w_fd = rotation_log(R[1:] @ np.swapaxes(R[:-1], 1, 2)) / h  # in the base frame, at the midpoints
    w_mid = 0.5 * (path.twist[1:, 3:] + path.twist[:-1, 3:])
    np.testing.assert_allclose(w_fd, w_mid, atol=2e-5)
    al_fd = np.diff(path.twist[:, 3:], axis=0) / h
    al_mid = 0.5 * (path.accel[1:, 3:] + path.accel[:-1, 3:])
    np.testing.assert_allclose(al_fd, al_mid, atol=5e-3)
    # the linear part: the velocity and acceleration of the platform point
    np.testing.assert_allclose(np.diff(path.X[:, :3], axis=0) / h, 0.5 * (path.twist[1:, :3] + path.twist[:-1, :3]),
                               atol=1e-6)
    # the angles do move linearly: every sample lies on the line between the poses
    d = P[1, 3:] - P[0, 3:]
    s = (path.X[:, 3:] - P[0, 3:]) @ d / (d @ d)
    np.testing.assert_allclose(path.X[:, 3:], P[0, 3:] + s[:, None] * d, atol=1e-12)


def test_an_angle_moves_the_short_way_round(gs):
    # 170 deg to -170 deg is a 20 deg move per coordinate (its change wrapped to (-180, 180])
    def tk(a0, a1):
        return Task(poses=np.array([[0, 0, 0.1, a0, 0, 0], [0, 0, 0.1, a1, 0, 0]]), coordinates=NAMES,
                    placement={"hanging": False, "offset": (0, 0, 0.5)},
                    trajectory=dict(speed=1.0, acceleration=3.0, angular_speed=1.0, angular_acceleration=3.0,
                                    jerk_time=0.1, dt=0.01, limits="per_coordinate"))
    short = tk(np.deg2rad(170.0), np.deg2rad(-170.0))
    ref = tk(np.deg2rad(-10.0), np.deg2rad(10.0))
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    # the samples in W (these orientations are not reachable by the mechanism)
    ps_short = short._full_samples(mech)[0]
    ps_ref = ref._full_samples(mech)[0]
    assert ps_short.t[-1] == pytest.approx(ps_ref.t[-1])


def test_waypoints_set_the_path_not_the_poses(gs):
    P = np.array([[0.0, 0.0, 0.6, 0, 0, 0], [0.1, 0.0, 0.6, 0, 0, 0]])
    Wp = np.array([[0.0, 0.0, 0.6, 0, 0, 0], [0.1, 0.0, 0.6, 0, 0, 0], [0.0, 0.0, 0.6, 0, 0, 0],
                   [0.0, 0.05, 0.6, 0, 0, 0.1]])
    lim = dict(speed=0.5, acceleration=2.0, angular_speed=1.0, angular_acceleration=3.0, jerk_time=0.05, dt=0.01)
    t = Task(poses=P, coordinates=NAMES, frame="platform", trajectory={**lim, "waypoints": Wp})
    assert t.n_poses == 2
    path = t.path(gs)
    rest = np.flatnonzero(np.linalg.norm(path.Xd, axis=1) < 1e-9)
    # the samples at rest are the waypoints, in their order
    stops = [path.X[rest[0]]] + [path.X[i] for a, i in zip(rest[:-1], rest[1:]) if i != a + 1]
    np.testing.assert_allclose(np.array(stops), Wp, atol=1e-12)
    # without waypoints the path ends at the last pose
    plain = Task(poses=P, coordinates=NAMES, frame="platform", trajectory=lim).path(gs)
    np.testing.assert_allclose(plain.X[-1], P[-1], atol=1e-12)
    assert plain.t[-1] < path.t[-1]


def test_the_naval_path_runs_through_the_357_rows():
    import yaml

    study = ROOT / "studies" / "naval_testbed.yaml"
    t = Task.from_mapping(yaml.safe_load(study.read_text())["task"], base_dir=study.parent)
    assert t.n_poses == 342
    tr = t.trajectory
    assert tr.waypoints.shape == (357, 6)
    assert tr.limits.limits == "per_coordinate" and tr.limits.timing == "sampled" and tr.limits.step == 0.05
    # the distinct rows of the path, in first order, are the required poses
    seen, uniq = set(), []
    for r in tr.waypoints:
        k = tuple(np.round(r, 9))
        if k not in seen:
            seen.add(k)
            uniq.append(r)
    np.testing.assert_allclose(np.array(uniq), t.poses, atol=1e-12)


@pytest.mark.parametrize("spec,message", [
    ({"limits": "norm"}, "task.trajectory.limits: must be one of path, per_coordinate"),
    ({"timing": "rounded"}, "task.trajectory.timing: must be one of continuous, sampled"),
    ({"timing": "sampled", "jerk_time": "0 s"}, "task.trajectory.jerk_time: sampled timing needs a jerk ramp time"),
    ({"waypoints": {"list": [{"x": "0 mm"}]}}, "task.trajectory.waypoints: give at least 2 poses"),
    ({"waypoints": {"list": [{"x": "0 mm"}, {"x": "1 mm"}], "order": "nearest"}},
     "task.trajectory.waypoints.order"),
])
def test_bad_profile_options_name_the_key(spec, message):
    m = {"poses": {"list": [{"x": "0 mm"}, {"x": "10 mm"}]},
         "trajectory": {"speed": "1 m/s", "acceleration": "3 m/s^2", "jerk_time": "0.1 s", "dt": "50 ms", **spec}}
    with pytest.raises(TaskError) as e:
        Task.from_mapping(m)
    assert str(e.value).startswith(message)


def test_sampled_timing_needs_a_step_the_samples_divide():
    lim = MotionLimits(speed=1.0, acceleration=3.0, jerk_time=0.1, timing="sampled", step=0.05)
    with pytest.raises(ValueError, match="dt: with sampled timing the time step must divide"):
        sample_path([0.1], [0.0], lim, 0.03)
    with pytest.raises(ValueError, match="step: sampled timing rounds phases"):
        MotionLimits(speed=1.0, acceleration=3.0, jerk_time=0.1, timing="sampled")


def test_a_waypoint_outside_the_freedoms_is_named(gs):
    t = Task(poses=np.zeros((2, 6)) + [0, 0, 0.6, 0, 0, 0], coordinates=NAMES, frame="platform",
             trajectory=dict(speed=1.0, acceleration=3.0, dt=0.01))
    bad = t._copy(trajectory=t.trajectory.__class__(t.trajectory.limits, 0.01, waypoints=np.zeros((2, 1)),
                                                    waypoint_coordinates=("q",)))
    with pytest.raises(TaskError, match=r"task.trajectory.waypoints.q: not a pose coordinate"):
        bad.path(gs)


def test_the_dense_recheck_samples_the_same_sampled_profile(gs):
    P = np.array([[0.0, 0.0, 0.6, 0, 0, 0], [0.1, 0.03, 0.62, 0.1, 0, 0.2], [0.0, 0.05, 0.6, 0, 0.05, 0]])
    t = Task(poses=P, coordinates=NAMES, frame="platform",
             trajectory=dict(speed=1.0, acceleration=3.0, angular_speed=1.0, angular_acceleration=3.0,
                             jerk_time=0.1, dt=0.05, limits="per_coordinate", timing="sampled"))
    dense = t.refined()
    assert dense.trajectory.dt == pytest.approx(0.005) and dense.trajectory.limits.step == 0.05
    a, b = t.path(gs), dense.path(gs)
    assert len(b.t) == (len(a.t) - 1) * 10 + 1
    np.testing.assert_allclose(b.X[::10], a.X, atol=1e-12)  # the same profile, ten times as dense
