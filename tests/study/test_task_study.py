"""A study's task: section (docs/tasks.md): read into a parasynth.Task, its placement and tool as
design variables, the task measures fed the design's task, and the dense re-check of the
verification rule (docs/verification.md).

Independent values: the measures through the study against the same measures called on a Task
built in the test; the refined grid's size counted by hand; the path's first broken sample
against the sample where gamma crosses 90 deg (the Gough-Stewart's known singularity) read from
the path itself; the naval testbed's pose file against rows of lufi_synth_traj.m written here.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import yaml

import parasynth
from parasynth import objectives
from parasynth.study import StudyError, load_study
from parasynth.study.design import design_mechanism, design_task
from parasynth.study.evaluate import Evaluator
from parasynth.study.verify import verify

ROOT = Path(__file__).resolve().parents[2]

STUDY = {
    "name": "gs_task", "mechanism": "gough_stewart_6ups",
    "fixed": {"ujoint_max": "89 deg", "sphere_max": "89 deg", "l_min": "100 mm", "l_max": "2000 mm"},
    "variables": [{"name": "platform_radius", "values": ["250 mm", "280 mm"]},
                  {"name": "task.placement.z", "values": ["0 mm", "20 mm"]}],
    "task": {"poses": {"list": [{"x": "0 mm", "y": "0 mm", "z": "600 mm", "gamma": "0 deg"},
                                {"x": "0 mm", "y": "0 mm", "z": "600 mm", "gamma": "100 deg"}]},
             "frame": "platform",
             "trajectory": {"speed": "0.5 m/s", "acceleration": "2 m/s^2", "angular_speed": "1 rad/s",
                            "angular_acceleration": "4 rad/s^2", "jerk_time": "0.05 s", "dt": "50 ms"},
             "loads": {"payload": {"mass": "20 kg", "com": ["0 mm", "0 mm", "0 mm"],
                                   "inertia": ["0.1 kg*m^2", "0.1 kg*m^2", "0.2 kg*m^2"]}}},
    "objectives": [{"name": "task_actuator_force_max", "label": "force"}],
    "constraints": [{"name": "task_coverage", "label": "coverage", "min": 1}],
    "optimizer": {"kind": "sweep"},
}


def _load(**changes):
    d = {**STUDY, **changes}
    return load_study(yaml.safe_dump(d), is_text=True)


def test_the_task_and_its_variables_reach_the_measures():
    s = _load()
    values = {"platform_radius": 0.25, "task.placement.z": 0.02}
    t = design_task(s, values)
    assert t.placement.offset == (0.0, 0.0, 0.02) and s.task.placement.offset == (0.0, 0.0, 0.0)
    rec = Evaluator(s).evaluate(values)
    assert rec.status == "ok", rec.error
    # the same measures on a Task built here: poses of the platform, 20 mm lower in the base frame
    mech = parasynth.load_mechanism("gough_stewart_6ups", platform_radius=0.25, ujoint_max=np.deg2rad(89),
                                    sphere_max=np.deg2rad(89), l_min=0.1, l_max=2.0)
    X = np.array([[0, 0, 0.62, 0, 0, 0], [0, 0, 0.62, 0, 0, np.deg2rad(100)]])
    np.testing.assert_allclose(t.platform_poses(design_mechanism(s, values)), X, atol=1e-12)
    own = parasynth.Task(poses=X, payload=dict(mass=20.0, com=[0, 0, 0], inertia=[0.1, 0.1, 0.2]),
                         trajectory=dict(speed=0.5, acceleration=2.0, angular_speed=1.0, angular_acceleration=4.0,
                                         jerk_time=0.05, dt=0.05))
    assert rec.objectives["force"] == pytest.approx(objectives.get("task_actuator_force_max")(mech, task=own), rel=1e-9)
    assert rec.constraint_values["coverage"] == objectives.get("task_coverage")(mech, task=own) == 1.0


def test_a_task_measure_needs_the_task_section():
    d = {k: v for k, v in STUDY.items() if k != "task"}
    d["variables"] = [STUDY["variables"][0]]
    with pytest.raises(StudyError, match=r"^objectives\[0\]\.name: 'task_actuator_force_max' is a task measure"):
        load_study(yaml.safe_dump(d), is_text=True)


def test_a_task_variable_needs_the_task_section():
    d = {k: v for k, v in STUDY.items() if k != "task"}
    d["objectives"] = [{"name": "footprint_radius"}]
    d["constraints"] = []
    with pytest.raises(StudyError, match=r"^variables\[1\]\.name: 'task.placement.z' is a variable of the study's task"):
        load_study(yaml.safe_dump(d), is_text=True)


def test_the_task_setting_is_the_studys():
    bad = dict(STUDY, objectives=[{"name": "task_actuator_force_max", "settings": {"task": "x"}}])
    with pytest.raises(StudyError, match=r"objectives\[0\]\.settings\.task: the task of a study is its task: section"):
        load_study(yaml.safe_dump(bad), is_text=True)


def test_a_pose_file_is_found_from_the_run_copy(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "p.csv").write_text("x [mm],y [mm],z [mm]\n0,0,600\n10,0,610\n")
    d = dict(STUDY, task={"poses": {"file": "sub/p.csv"}, "frame": "platform"})
    f = tmp_path / "study.yaml"
    f.write_text(yaml.safe_dump(d))
    s = load_study(f)
    again = load_study(s.to_yaml(), is_text=True)  # the run's copy, read from nowhere in particular
    np.testing.assert_allclose(again.task.poses, s.task.poses)
    assert len(s.task.poses) == 2


def test_the_refined_task():
    grid = parasynth.Task(poses=np.array([[x, 0, z, 0, 0, g] for x in (-0.1, 0, 0.1) for z in (0.5, 0.6)
                                          for g in (0, 0.2)]))
    assert len(grid.refined().poses) == 7 * 4 * 4  # (3-1)*3+1, (2-1)*3+1, (2-1)*3+1
    lst = parasynth.Task(poses=np.array([[0, 0, 0.6, 0, 0, 0], [0.1, 0, 0.6, 0, 0, 0], [0, 0.1, 0.6, 0, 0, 0]]))
    assert len(lst.refined().poses) == 3  # not a grid: kept
    assert grid.refinement() == "grid poses 3x per axis (12 -> 112)"
    assert lst.refinement() == "its 3 poses kept (not a full grid)"
    s = _load()
    assert s.task.refined().trajectory.dt == pytest.approx(0.005)
    # with a path the poses are kept (the path through them is the task) and only the path is denser
    limits = dict(speed=0.5, acceleration=2.0, angular_speed=1.0, angular_acceleration=4.0, jerk_time=0.05, dt=0.05)
    pathed = parasynth.Task(poses=grid.poses, trajectory=limits)
    dense = pathed.refined()
    assert dense.poses is pathed.poses and dense.trajectory.dt == pytest.approx(0.005)
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    t0, t1 = pathed.path(mech).t, dense.path(mech).t
    assert t1[-1] == pytest.approx(t0[-1]) and len(t1) - 1 == pytest.approx(10 * (len(t0) - 1), abs=11)
    assert pathed.refinement() == "the path at 10x the sample rate, its 12 poses kept"


def test_the_dense_recheck_flags_the_path_through_the_singularity():
    s = _load()
    values = {"platform_radius": 0.25, "task.placement.z": 0.0}
    rec = Evaluator(s).evaluate(values)
    v = verify(s, values, [], screened=rec.constraint_values)
    assert not v.passed
    cont = next(c for c in v.checks if c.requirement == "path continuity")
    assert not cont.passed and "singularity" in cont.where
    k = int(cont.where.split("breaks at sample ")[1].split(" ")[0])
    mech = design_mechanism(s, values)
    X = design_task(s, values).refined().path(mech).X
    gamma = X[:, 5]
    assert gamma[k - 1] < np.pi / 2 <= gamma[k] + 1e-9  # the first sample at or past 90 deg
    # the same design on a path that stops short of 90 deg passes
    short = dict(STUDY["task"], poses={"list": [{"x": "0 mm", "y": "0 mm", "z": "600 mm", "gamma": "0 deg"},
                                                {"x": "0 mm", "y": "0 mm", "z": "600 mm", "gamma": "60 deg"}]})
    s2 = _load(task=short)
    rec2 = Evaluator(s2).evaluate(values)
    assert verify(s2, values, [], screened=rec2.constraint_values).passed


def test_the_naval_testbed_poses_as_transcribed():
    spec = importlib.util.spec_from_file_location("naval", ROOT / "studies" / "tasks" / "naval_testbed_poses.py")
    naval = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(naval)
    rows = naval.rows()
    assert len(rows) == 357 and len(naval.unique_stable(rows)) == 342
    # rows of lufi_synth_traj.m by hand (world frame, z of the cube centre 1.0 m; angles in rad)
    phi = np.deg2rad(15)
    np.testing.assert_allclose(rows[0], [0, 0, 1.0, 0, 0, 0])          # SR(1) = X1
    np.testing.assert_allclose(rows[1], [0.1, 0, 1.1, 0, 0, 0])        # surge, z = +h/2
    np.testing.assert_allclose(rows[3], [0, 0, 1.1, phi, 0, 0])        # roll
    np.testing.assert_allclose(rows[14], [0, 0, 1.1, 0, 0, 0])         # SP(1) = X0
    np.testing.assert_allclose(rows[16], [0, -0.1, 1.1, 0, phi, 0])    # sway with pitch
    np.testing.assert_allclose(rows[42], [0.1, 0.1, 1.1, phi, 0, 0])   # IL(1)
    np.testing.assert_allclose(rows[42 + 104], [0.1, 0.1, 1.1, phi, phi, phi])  # IL after the corners of i = 1
    # the shipped file is what the script writes, in W (z - 1 m, alpha + 180 deg)
    import csv
    with open(ROOT / "studies" / "tasks" / "naval_testbed_poses.csv") as f:
        data = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    assert data[0] == ["x [mm]", "y [mm]", "z [mm]", "alpha [deg]", "beta [deg]", "gamma [deg]"]
    vals = np.array(data[1:], float)
    want = naval.poses_in_W()
    assert len(vals) == 342
    np.testing.assert_allclose(vals[:, :3], 1000 * want[:, :3], atol=1e-6)
    ang = np.rad2deg(want[:, 3:]) + [180, 0, 0]
    ang[:, 0] = np.where(ang[:, 0] > 180, ang[:, 0] - 360, ang[:, 0])
    np.testing.assert_allclose(vals[:, 3:], ang, atol=1e-6)


def test_a_design_that_reaches_no_pose_is_recorded_as_failed():
    """Lifted 3 m, the platform poses need legs of about 3.6 m against l_max = 2 m (closed form
    below): no pose is reachable, so the design fails instead of holding vacuous values."""
    d = {**STUDY, "objectives": [{"name": "task_margin_min", "label": "margin"}], "constraints": [],
         "variables": [STUDY["variables"][0], {"name": "task.placement.z", "values": ["0 mm", "3000 mm"]}]}
    s = load_study(yaml.safe_dump(d), is_text=True)
    far = {"platform_radius": 0.25, "task.placement.z": 3.0}
    mech = design_mechanism(s, far)
    X = design_task(s, far).platform_poses(mech)
    assert np.allclose(X[:, 2], 3.6)
    B = np.array([leg.base for leg in mech.legs], float)
    A = np.array([leg.platform for leg in mech.legs], float)
    lengths = np.linalg.norm(X[0, :3] + A - B, axis=1)  # the first pose is level
    assert lengths.min() > 3.5 > mech.params.l_max
    rec = Evaluator(s).evaluate(far)
    assert rec.status == "failed" and not rec.feasible
    assert rec.error == ("RequirementError: reaches none of the task's 2 required poses (none reachable with every "
                         "pose constraint met); its task measures would have no pose to hold on")
    # the check off: the vacuous worst value, 0 for a margin to maximise
    loose = Evaluator(s, require_reachable=False).evaluate(far)
    assert loose.status == "ok" and loose.objectives["margin"] == 0.0
    near = Evaluator(s).evaluate({"platform_radius": 0.25, "task.placement.z": 0.0})
    assert near.status == "ok" and near.objectives["margin"] > 0


def test_the_naval_testbed_729_variant_is_the_full_grid_holding_the_342_poses():
    s = load_study(str(ROOT / "studies" / "naval_testbed_729.yaml"))
    base = load_study(str(ROOT / "studies" / "naval_testbed.yaml"))
    P, P342 = s.task.poses, base.task.poses
    assert P.shape == (729, 6)
    # every combination, by hand: x, y, z in {-100, 0, 100} mm; the listed tilts in {-15, 0, 15} deg
    # (alpha stored as the listed one plus the hanging rest's 180 deg)
    ang = np.deg2rad([-15.0, 0.0, 15.0])
    alpha = np.angle(np.exp(1j * (ang + np.pi)))
    expected = {(x, y, z, a, b, g) for x in (-100, 0, 100) for y in (-100, 0, 100) for z in (-100, 0, 100)
                for a in np.round(np.rad2deg(alpha), 6) for b in (-15.0, 0.0, 15.0) for g in (-15.0, 0.0, 15.0)}
    got = {tuple(np.round(np.r_[1000 * r[:3], np.rad2deg(r[3:])], 6)) for r in P}
    assert got == {tuple(float(v) for v in e) for e in expected}
    assert {tuple(np.round(r, 9)) for r in P342} <= {tuple(np.round(r, 9)) for r in P}
    # a serpentine: consecutive poses differ in one coordinate
    assert np.all(np.sum(~np.isclose(P[1:], P[:-1], atol=1e-12), axis=1) == 1)
    # the rest of the study is the 342-pose one's
    assert s.objectives == base.objectives and s.constraints == base.constraints
    # the same profile; the 342-pose study's path runs through the 357 rows of lufi_synth_traj.m,
    # the grid's through its own poses
    assert s.task.trajectory.limits == base.task.trajectory.limits and s.task.trajectory.dt == base.task.trajectory.dt
    assert s.task.trajectory.waypoints is None and base.task.trajectory.waypoints.shape == (357, 6)
    assert s.task.payload == base.task.payload
