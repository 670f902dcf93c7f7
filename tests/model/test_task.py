"""The task model: Task, Task.from_mapping (grid, lists, CSV files, placement, tool, loads, space,
floors, units), the motion profile's limits on a sampled path, and bad input."""

from __future__ import annotations

import numpy as np
import pytest

import parasynth
from parasynth.model.spatial import euler_to_matrix
from parasynth.model.task import Task, TaskError, matrix_to_euler, rotation_exp, rotation_log
from parasynth.model.trajectory import MotionLimits, sample_path, segment_timing

G = 9.80665
NAMES = ("x", "y", "z", "alpha", "beta", "gamma")


@pytest.fixture(scope="module")
def gs():
    return parasynth.load_mechanism("gough_stewart_6ups")


@pytest.fixture(scope="module")
def rpu():
    return parasynth.load_mechanism("2rpu_2sps")


def test_task_is_exported_and_takes_the_mechanisms_own_coordinates(gs):
    X = np.array([[0.01, -0.02, 0.6, 0.1, -0.05, 0.2], [0.0, 0.0, 0.7, 0.0, 0.0, 0.0]])
    t = parasynth.Task(poses=X)
    assert t.frame == "platform" and t.coordinates is None
    np.testing.assert_array_equal(t.platform_poses(gs), X)
    with pytest.raises(TaskError, match=r"task\.poses: 3 columns"):
        Task(poses=X[:, :3]).platform_poses(gs)


@pytest.mark.parametrize("conv", ["xyz", "zyx", "zyz", "zxz", "yzx", "yxy"])
def test_euler_angles_round_trip(conv):
    rng = np.random.default_rng(0)
    a = rng.uniform(-2.5, 2.5, (200, 3))
    a[:, 1] = rng.uniform(-1.4, 1.4, 200) if conv[0] != conv[2] else rng.uniform(0.1, 3.0, 200)
    R = euler_to_matrix(conv, a)
    np.testing.assert_allclose(matrix_to_euler(conv, R), a, atol=1e-10)


def test_rotation_log_and_exp_are_inverse():
    rng = np.random.default_rng(1)
    v = rng.normal(size=(100, 3))
    v *= (rng.uniform(0, 3.1, 100) / np.linalg.norm(v, axis=1))[:, None]
    np.testing.assert_allclose(rotation_log(rotation_exp(v)), v, atol=1e-10)
    # a half turn
    R = euler_to_matrix("xyz", np.array([[np.pi, 0.0, 0.0]]))
    np.testing.assert_allclose(np.abs(rotation_log(R)[0]), [np.pi, 0, 0], atol=1e-9)


def test_grid_lists_and_file_with_units(tmp_path, gs):
    (tmp_path / "poses.csv").write_text("x [mm],z [mm],gamma [deg]\n10,620,5\n-10,580,-5\n")
    spec = {"poses": {"grid": {"x": ["-100 mm", "100 mm", "50 mm"], "z": ["550 mm", "650 mm", "50 mm"],
                               "gamma": {"values": ["-10 deg", "0 deg", "10 deg"]}},
                      "list": [{"y": "20 mm", "z": "600 mm"}],
                      "file": "poses.csv"}}
    t = Task.from_mapping(spec, base_dir=tmp_path)
    assert t.coordinates == ("x", "z", "gamma", "y")
    assert t.n_poses == 5 * 3 * 3 + 1 + 2
    # the grid is the product of the axes, the first varying slowest
    np.testing.assert_allclose(t.poses[:3, 0], -0.1)
    np.testing.assert_allclose(t.poses[:3, 2], np.deg2rad([-10, 0, 10]))
    np.testing.assert_allclose(t.poses[44], [0.1, 0.65, np.deg2rad(10), np.nan])
    np.testing.assert_allclose(t.poses[45], [np.nan, 0.6, np.nan, 0.02])
    np.testing.assert_allclose(t.poses[46], [0.01, 0.62, np.deg2rad(5), np.nan])
    # coordinates not named stay at home: the tool is the platform here
    X = t.platform_poses(gs)
    np.testing.assert_allclose(X[45], [0.0, 0.02, 0.6, 0.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(X[0], [-0.1, 0.0, 0.55, 0.0, 0.0, np.deg2rad(-10)], atol=1e-12)
    # units for bare numbers
    t2 = Task.from_mapping({"poses": {"grid": {"x": [-100, 100, 50]}}}, units={"length": "mm"})
    np.testing.assert_allclose(t2.poses[:, 0], [-0.1, -0.05, 0.0, 0.05, 0.1])
    # nearest-neighbour order keeps the poses
    t3 = Task.from_mapping({"poses": {"list": [{"x": "0 mm"}, {"x": "30 mm"}, {"x": "10 mm"}], "order": "nearest"}})
    np.testing.assert_allclose(t3.poses[:, 0], [0.0, 0.01, 0.03])


def test_placement_tool_and_with_settings(gs):
    spec = {"poses": {"list": [{"x": "10 mm", "y": "-5 mm", "z": "700 mm", "gamma": "20 deg"}]},
            "placement": {"z": "50 mm", "yaw": "30 deg"}, "tool": {"x": "5 mm", "z": "100 mm", "yaw": "15 deg"}}
    t = Task.from_mapping(spec)
    X = t.platform_poses(gs)
    p, R = gs.pose(X)
    # back to the tool frame in W by hand
    Rw = euler_to_matrix("xyz", np.array([0, 0, np.deg2rad(30)]))
    Rt = euler_to_matrix("xyz", np.array([0, 0, np.deg2rad(15)]))
    RWT = Rw.T @ R[0] @ Rt
    pWT = Rw.T @ (p[0] + R[0] @ np.array([0.005, 0, 0.1]) - np.array([0, 0, 0.05]))
    np.testing.assert_allclose(pWT, [0.01, -0.005, 0.7], atol=1e-12)
    np.testing.assert_allclose(RWT, euler_to_matrix("xyz", np.array([0, 0, np.deg2rad(20)])), atol=1e-12)
    # design variables of a study: a new task, the old one unchanged
    t2 = t.with_settings({"placement.z": 0.08, "placement.yaw": 0.0, "tool.yaw": 0.0})
    assert t.placement.offset[2] == 0.05 and t2.placement.offset[2] == 0.08
    X2 = t2.platform_poses(gs)
    p2, R2 = gs.pose(X2)
    np.testing.assert_allclose(p2[0] + R2[0] @ np.array([0.005, 0, 0.1]), [0.01, -0.005, 0.78], atol=1e-12)
    with pytest.raises(TaskError, match=r"task\.placement\.w: not a task setting"):
        t.with_settings({"placement.w": 1.0})


def test_a_mechanism_with_fewer_freedoms_takes_its_own_coordinates(rpu):
    t = Task.from_mapping({"poses": {"list": [{"z": "650 mm", "psi": "25 deg", "theta": "15 deg"}]}})
    np.testing.assert_allclose(t.platform_poses(rpu)[0], [0.65, np.deg2rad(25), np.deg2rad(15)])
    with pytest.raises(TaskError, match=r"task\.poses\.gamma: 2rpu_2sps has no freedom 'gamma'"):
        Task.from_mapping({"poses": [{"z": "650 mm", "gamma": "5 deg"}]}).platform_poses(rpu)
    with pytest.raises(TaskError, match=r"^study\.task\.poses\.gamma: 2rpu_2sps has no freedom"):
        Task.from_mapping({"poses": [{"z": "650 mm", "gamma": "5 deg"}]}, where="study.task").platform_poses(rpu)
    with pytest.raises(TaskError, match=r"^study\.task\.poses\.grid\.z\[2\]: the step must be positive"):
        Task.from_mapping({"poses": {"grid": {"z": ["1 mm", "2 mm", "0 mm"]}}}, where="study.task")
    with pytest.raises(TaskError, match=r"task\.poses\.psi: 'psi' is an angle coordinate"):
        Task.from_mapping({"poses": [{"z": "650 mm", "psi": "5 mm"}]}).platform_poses(rpu)
    # a tool offset that needs a motion the mechanism lacks
    with pytest.raises(TaskError, match="outside the freedoms of 2rpu_2sps"):
        Task.from_mapping({"poses": [{"z": "650 mm", "psi": "25 deg", "theta": "15 deg"}],
                           "placement": {"y": "50 mm"}}).platform_poses(rpu)


def test_loads_and_gravity_in_the_task_frame(gs):
    spec = {"poses": [{"z": "600 mm"}],
            "placement": {"hanging": True, "z": "1 m"},
            "loads": {"payload": {"mass": "2 kg", "com": ["0 mm", "0 mm", "10 mm"],
                                  "inertia": ["0.01 kg*m^2", "200 kg*cm^2", "0.03 kg*m^2"]},
                      "wrench": {"force": ["0 N", "0 N", "-10 N"]}, "signs": True, "frame": "base"}}
    t = Task.from_mapping(spec)
    np.testing.assert_allclose(t.gravity_vector(), [0, 0, G], atol=1e-12)  # W upside down: -z_W is +z_B
    assert t.payload.mass == 2.0
    np.testing.assert_allclose(np.diag(t.payload.tensor), [0.01, 0.02, 0.03])
    np.testing.assert_allclose(t.wrench, [0, 0, -10, 0, 0, 0])
    assert t.wrench_signs and t.wrench_frame == "base"
    # a gravity vector in W (a model whose vertical is y)
    t = Task.from_mapping({"poses": [{"z": "600 mm"}], "placement": {"yaw": "90 deg"},
                           "loads": {"gravity": ["0 m/s^2", "-9.81 m/s^2", "0 m/s^2"]}})
    np.testing.assert_allclose(t.gravity_vector(), [9.81, 0, 0], atol=1e-12)  # W's -y is B's +x


def test_profile_limits_on_a_sampled_path(gs):
    P = np.array([[0.0, 0.0, 0.6, 0, 0, 0], [0.15, 0.05, 0.65, 0, 0, 0.3], [0.15, 0.05, 0.65, 0, 0, 0.35],
                  [0.1, -0.1, 0.6, 0.1, 0, 0]])
    lim = dict(speed=0.25, acceleration=1.5, angular_speed=0.8, angular_acceleration=5.0, jerk_time=0.04)
    t = Task(poses=P, coordinates=NAMES, trajectory={**lim, "dt": 0.0005})
    path = t.path(gs)
    ts, X = path.t, path.X
    dt = np.diff(ts)
    assert np.allclose(dt, 0.0005) or np.allclose(dt[:-1], 0.0005)
    p = X[:, :3]
    R = euler_to_matrix("xyz", X[:, 3:])
    # finite differences of the samples, independent of the profile's formulas
    v = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    w = np.linalg.norm(rotation_log(np.swapaxes(R[:-1], 1, 2) @ R[1:]), axis=1) / dt
    u = slice(None) if np.isclose(dt[-1], 0.0005) else slice(None, -1)  # the end may come before a full step
    vel = (np.diff(p, axis=0) / dt[:, None])[u]
    h = 0.0005
    a = np.linalg.norm(np.diff(vel, axis=0), axis=1) / h
    jerk = np.linalg.norm(np.diff(np.diff(vel, axis=0), axis=0), axis=1) / h ** 2
    assert v.max() <= lim["speed"] * (1 + 1e-6) and v.max() > 0.99 * lim["speed"]  # reached on the long move
    assert w.max() <= lim["angular_speed"] * (1 + 1e-3)
    assert a.max() <= lim["acceleration"] * (1 + 1e-3) + 1e-9
    assert a.max() > 0.98 * lim["acceleration"]
    j_lim = lim["acceleration"] / lim["jerk_time"]  # the ramp's jerk
    assert jerk.max() <= j_lim * (1 + 1e-2)
    # every required pose is visited, at rest
    for k in range(len(P)):
        d = np.linalg.norm(X - P[k], axis=1)
        i = int(np.argmin(d))
        assert d[i] < 1e-9
        assert np.allclose(path.Xd[i], 0.0, atol=1e-7)
    # the rates are the derivatives of the positions
    np.testing.assert_allclose(np.diff(X, axis=0) / dt[:, None], 0.5 * (path.Xd[1:] + path.Xd[:-1]), atol=1e-5)


def test_profile_timing_closed_forms():
    lim = MotionLimits(speed=0.5, acceleration=2.0, jerk_time=0.05)
    # long move: v / a + tj to accelerate, the cruise makes up the rest
    tm = segment_timing([1.0], [0.0], lim)
    ta = 0.5 / 2.0 + 0.05
    assert tm.ta[0] == pytest.approx(ta)
    assert tm.duration[0] == pytest.approx(2 * ta + (1.0 - 0.5 * ta) / 0.5)
    # short move: v (v / a + tj) = D
    tm = segment_timing([0.01], [0.0], lim)
    assert tm.v[0] * 0.01 == pytest.approx(0.1)
    # very short: the peak acceleration is not reached, jerk a / tj throughout: 2 v^1.5 sqrt(tj / a) = D
    tm = segment_timing([1e-5], [0.0], lim)
    v = tm.v[0] * 1e-5
    assert 2 * v ** 1.5 * np.sqrt(0.05 / 2.0) == pytest.approx(1e-5)
    ps = sample_path([1e-5], [0.0], lim, 1e-5)
    assert ps.s[-1] == pytest.approx(1.0)
    assert np.max(np.abs(ps.sddd)) * 1e-5 == pytest.approx(2.0 / 0.05)


def test_timed_poses_from_a_file(tmp_path, gs):
    (tmp_path / "path.csv").write_text("t [s],x [mm],z [mm]\n" + "\n".join(
        f"{t:.3f},{100 * t * t:.9f},600" for t in np.arange(0, 0.5, 0.05)))
    t = Task.from_mapping({"poses": [{"z": "600 mm"}], "trajectory": {"file": "path.csv"}}, base_dir=tmp_path)
    path = t.path(gs)
    np.testing.assert_allclose(path.X[:, 0], 0.1 * path.t ** 2, atol=1e-12)
    np.testing.assert_allclose(path.Xd[:, 0], 0.2 * path.t, atol=1e-9)
    np.testing.assert_allclose(path.Xdd[:, 0], 0.2, atol=1e-9)


def test_floors_and_coverage(gs):
    from parasynth import objectives
    X = np.array([[0, 0, 0.6, 0, 0, 0], [0, 0, 0.6, 0, 0, np.deg2rad(88)]])
    t = Task.from_mapping({"poses": {"list": [{"z": "600 mm"}, {"z": "600 mm", "gamma": "88 deg"}]},
                           "floors": {"singularity_margin": {"min": 0.05}}})
    m = gs.singularity_margin(X)
    assert m[0] > 0.05 > m[1]
    assert objectives.get("task_coverage")(gs, task=t, constraints=[]) == pytest.approx(0.5)


def test_installation_space_must_contain_the_home_pose(gs):
    t = Task.from_mapping({"poses": [{"z": "600 mm"}], "space": {"cylinder": {"radius": "300 mm",
                                                                               "z": ["0 mm", "1 m"]}}})
    with pytest.raises(TaskError, match=r"task\.space: the mechanism's bodies at its home pose"):
        t.check(gs)
    ok = Task.from_mapping({"poses": [{"z": "600 mm"}], "space": {"cylinder": {"radius": "700 mm",
                                                                                "z": ["-50 mm", "1 m"]}}})
    ok.check(gs)


@pytest.mark.parametrize("spec, message", [
    ({"poses": {"grid": {"x": ["0 mm", "1 mm", "0 mm"]}}}, r"^task\.poses\.grid\.x\[2\]: the step must be positive"),
    ({"poses": {"grid": {"x": [0, 10, 1]}}}, r"^task\.poses\.grid\.x\[0\]: a bare number"),
    ({"poses": {"grid": {"x": ["10 mm", "0 mm", "1 mm"]}}}, r"^task\.poses\.grid\.x: high"),
    ({"poses": {"grid": {"x": ["0 mm", "1 mm"]}}}, r"^task\.poses\.grid\.x: give \[low, high, step\]"),
    ({"poses": [{"x": "1 mm"}], "convention": "xyx"}, r"^task\.convention: unknown orientation convention 'xyx'"),
    ({"poses": [{"x": "1 mm"}], "trajectory": {"speed": "0 m/s", "acceleration": "1 m/s^2"}},
     r"^task\.trajectory\.speed: must be positive"),
    ({"poses": [{"x": "1 mm"}], "trajectory": {"speed": "1 m/s", "acceleration": "-2 m/s^2"}},
     r"^task\.trajectory\.acceleration: must be positive"),
    ({"poses": [{"x": "1 mm"}], "trajectory": {"speed": "1 m/s"}}, r"^task\.trajectory\.acceleration: required"),
    ({"poses": [{"x": "1 mm"}], "trajectory": {"speed": "1 m", "acceleration": "1 m/s^2"}},
     r"^task\.trajectory\.speed: '1 m' is not a speed"),
    ({"poses": [{"x": "1 mm"}], "loads": {"payload": {"mass": 5}}}, r"^task\.loads\.payload\.mass: a bare number"),
    ({"poses": [{"x": "1 mm"}], "loads": {"wrench": [1, 0, 0, 0, 0, 0]}}, r"^task\.loads\.wrench\[0\]: a bare number"),
    ({"poses": [{"x": "1 mm"}], "loads": {"payload": {"mass": "1 kg", "inertia": [1, 1, 1]}}},
     r"^task\.loads\.payload\.inertia\[0\]: a bare number"),
    ({"poses": [{"x": "1 mm"}], "space": {"box": {"low": ["0 mm"] * 3, "high": ["0 mm"] * 3}}},
     r"^task\.space\.box: low must be below high"),
    ({"poses": [{"x": "1 mm"}], "space": {"cylinder": {"radius": "0 mm", "z": ["0 mm", "1 m"]}}},
     r"^task\.space\.cylinder\.radius: must be > 0"),
    ({"poses": [{"x": "1 mm"}], "floors": {"stiffness": {"min": 1}}}, r"^task\.floors\.stiffness: unknown floor"),
    ({"poses": [{"x": "1 mm"}], "speed": 1}, r"^task\.speed: unknown key"),
    ({"poses": {"file": "missing.csv"}}, r"^task\.poses\.file: cannot read 'missing.csv'"),
    ({"poses": [{"x": "1 kg"}]}, r"^task\.poses\.list\[0\]\.x: '1 kg' is not a length"),
    ({}, r"^task\.poses: required"),
    ({"poses": [{"x": "1 mm"}], "loads": {"wrench": [["1 N"] * 3 + ["0 N*m"] * 3] * 2}},
     r"^task\.loads\.wrench: 2 wrenches for 1 poses"),
])
def test_bad_task_sections_name_the_key(spec, message):
    with pytest.raises(TaskError, match=message) as e:
        Task.from_mapping(spec)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("content, message", [
    ("x [mm],z [mm]\n1,2\n3,abc\n", r"row 3 column 'z': 'abc' is not a number"),
    ("x [mm],z\n1,2\n", r"column 'z' has no unit"),
    ("x [mm],z [mm]\n1,2\n3\n", r"row 3 has 1 values for 2 columns"),
    ("x [mm],,z [mm]\n1,2,3\n", r"column 2 has no name"),
    ("x [mm]\n", r"needs a header of named columns and at least one row"),
])
def test_bad_csv_files(tmp_path, content, message):
    (tmp_path / "p.csv").write_text(content)
    with pytest.raises(TaskError, match=r"^task\.poses\.file: 'p.csv' " + message.split(":")[0][:20]):
        Task.from_mapping({"poses": {"file": "p.csv"}}, base_dir=tmp_path)
    with pytest.raises(TaskError, match=message):
        Task.from_mapping({"poses": {"file": "p.csv"}}, base_dir=tmp_path)


def test_per_pose_wrenches_inline_and_the_units_argument():
    t = Task.from_mapping({"poses": [{"x": "1 mm"}, {"x": "2 mm"}],
                           "loads": {"wrench": [["1 N", "0 N", "0 N", "0 N*m", "0 N*m", "3 N*m"],
                                                {"force": ["0 N", "2 N", "0 N"]}]}})
    np.testing.assert_allclose(t.wrench, [[1, 0, 0, 0, 0, 3], [0, 2, 0, 0, 0, 0]])
    with pytest.raises(TaskError, match=r"^units\.lenght: unknown kind"):
        Task.from_mapping({"poses": [{"x": 1}]}, units={"lenght": "mm"})
    t = Task.from_mapping({"poses": [{"x": 1, "gamma": 90}]}, units={"length": "mm", "angle": "deg"})
    np.testing.assert_allclose(t.poses, [[0.001, np.pi / 2]])


def test_timed_file_needs_a_time_column(tmp_path):
    (tmp_path / "p.csv").write_text("x [mm]\n1\n2\n3\n")
    with pytest.raises(TaskError, match=r"^task\.trajectory\.file: 'p.csv' has no time column"):
        Task.from_mapping({"poses": [{"x": "1 mm"}], "trajectory": {"file": "p.csv"}}, base_dir=tmp_path)


@pytest.mark.parametrize("kwargs, message", [
    ({"poses": "abc"}, r"task\.poses: give an \(N, k\) array"),
    ({"poses": [[0.0] * 6], "wrench": [1, 2]}, r"task\.wrench: give \[fx, fy, fz, mx, my, mz\]"),
    ({"poses": [[0.0] * 6], "payload": {"mass": -1}}, r"payload\.mass: must be >= 0"),
    ({"poses": [[0.0] * 6], "payload": {"mass": 1, "inertia": [[1, 2, 0], [0, 1, 0], [0, 0, 1]]}},
     r"payload\.inertia: give 3 principal moments or a symmetric"),
    ({"poses": [[0.0] * 6], "tool": [1, 2]}, r"tool: give 3 finite numbers"),
    ({"poses": [[0.0] * 6], "convention": "abc"}, r"task\.convention: unknown Euler convention"),
    ({"poses": [[0.0] * 6], "trajectory": {"speed": 0, "acceleration": 1}}, r"task\.trajectory\.speed: must be"),
    ({"poses": [[0.0] * 6], "space": {"shape": "sphere"}}, r"space: shape must be box or cylinder"),
    ({"poses": [[0.0] * 6], "frame": "world"}, r"task\.frame: must be tool or platform"),
])
def test_bad_python_arguments(kwargs, message):
    with pytest.raises(TaskError, match=message):
        Task(**kwargs)


def test_a_coupled_mechanism_reaches_a_placed_pose_within_the_pose_tolerance():
    """The 5-PUS/UPU's orientation is coupled to its position: a placement offset is reached in
    the least-squares sense, within pose_tolerance, or refused."""
    mech = parasynth.load_mechanism("5pus_upu")
    X = np.tile(mech.home, (2, 1))
    X[1, 0], X[1, 3] = 0.02, 0.05  # off-centre and tilted: the limb's angle q1 = atan2(x, z - z_B) moves with z
    strict = Task(poses=X, coordinates=mech.task_coordinates, placement={"offset": (0, 0, 0.01)}, pose_tolerance=1e-9)
    with pytest.raises(TaskError, match=r"task\.poses\[1\]: the platform pose asked for is outside the freedoms"):
        strict.platform_poses(mech)
    loose = Task(poses=X, coordinates=mech.task_coordinates, placement={"offset": (0, 0, 0.01)}, pose_tolerance=1e-3)
    Y = loose.platform_poses(mech)
    p, R = mech.pose(Y)
    p0, R0 = mech.pose(X)
    np.testing.assert_allclose(p[0], p0[0] + [0, 0, 0.01], atol=1e-12)  # at home the shift is exact
    assert np.linalg.norm(p[1] - p0[1] - [0, 0, 0.01]) < 1e-3 * mech.length_scale
    assert np.linalg.norm(rotation_log(R[1] @ R0[1].T)) < 1e-3
