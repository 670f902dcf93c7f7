"""max_force_trajectory and force_decoupling_ratio as task measures of any mechanism, and the
2022 paper's grinding path as a shipped task file (docs/tasks.md, "The grinding path").

Independent values: the task file's rows against eqs. (66)-(68) evaluated here; the ratio on the
grinding task against the paper's path computed with its analytic derivatives and the Table 3 leg
masses (the ratio does not depend on them: the forces are linear in the load); the largest force
on the grinding task against ``inverse_dynamics`` of the analytic path with the platform's
inertia alone; the 6-UPS ratio against a least-squares solve of the wrench system written here.
"""

from pathlib import Path

import numpy as np
import pytest
import yaml

import parasynth
from parasynth import objectives
from parasynth.measures.dynamics import InertiaModel, PlatformInertia, grinding_trajectory, inverse_dynamics
from parasynth.measures.indices import point_force_wrench
from parasynth.model.spatial import euler_to_matrix
from parasynth.model.task import Task, TaskError
from parasynth.study import StudyError, load_study

ROOT = Path(__file__).resolve().parents[2]
GRINDING = ROOT / "studies" / "tasks" / "grinding_path.yaml"


@pytest.fixture(scope="module")
def grinder():
    return parasynth.load_mechanism("4ups_1rps")


@pytest.fixture(scope="module")
def grinding_task():
    return Task.from_file(GRINDING)


def test_the_grinding_task_file_holds_eqs_66_to_68(grinding_task):
    t = grinding_task.trajectory.times
    assert len(t) == 201 and t[0] == 0.0 and t[-1] == 50.0
    P = grinding_task.poses  # SI: x, y (m), alpha, beta, gamma (rad)
    by_hand = {7.5: (0.1 - 0.002 * 2.5**2, 0.45), 20.0: (0.0, 0.55), 30.0: (-0.1, 0.45), 45.0: (0.1 * np.cos(1.75 * np.pi), 0.1 * np.sin(1.75 * np.pi) + 0.45)}
    for tk, (x, y) in by_hand.items():
        k = int(np.flatnonzero(np.isclose(t, tk))[0])
        np.testing.assert_allclose(P[k, :2], [x, y], atol=1e-12)
        np.testing.assert_allclose(P[k, 2:], [0.0, np.deg2rad(-15.0), 0.0], atol=1e-15)
    assert grinding_task.payload.mass == 3.593 and grinding_task.tool.offset == pytest.approx((0.0, 0.075, 0.0))
    np.testing.assert_allclose(grinding_task.gravity_vector(), [0.0, -9.80665, 0.0])


def test_decoupling_ratio_on_the_grinding_task_equals_the_papers_path(grinder, grinding_task):
    ratio = objectives.get("force_decoupling_ratio")
    built_in = ratio(grinder)  # the analytic path, Table 3 legs, its own solve
    assert ratio(grinder, task=grinding_task) == pytest.approx(built_in, rel=1e-9)
    # a stronger force, the same ratio (linearity), and a force twice as large at the same point
    doubled = Task.from_mapping({**yaml.safe_load(GRINDING.read_text())["task"],
                                 "loads": {"wrench": {"force": ["0 N", "0 N", "100 N"]}, "frame": "base"}},
                                base_dir=GRINDING.parent)
    assert ratio(grinder, task=doubled) == pytest.approx(built_in, rel=1e-9)


def test_max_force_on_the_grinding_task_against_the_analytic_path(grinder, grinding_task):
    got = objectives.get("max_force_trajectory")(grinder, task=grinding_task)
    t = np.round(np.arange(0.0, 50.0 + 1e-9, 0.25), 12)
    X, Xd, Xdd = grinding_trajectory(t)
    inertia = InertiaModel(PlatformInertia(3.593, (0, 0, 0), (3.30e-3, 17.79e-3, 16.28e-3)))
    ext = point_force_wrench(grinder, X, np.array([0.0, 0.0, 50.0]), (0.0, 0.075, 0.0))
    F = inverse_dynamics(grinder, X, Xd, Xdd, inertia, external=ext).actuator
    feas = grinder.is_feasible(X)
    assert 0.5 < feas.mean() < 1.0
    # the file's rates are finite differences (the path's accelerations are 4 mm/s^2 and 25 mm/s^2)
    assert got == pytest.approx(np.nanmax(np.abs(F[feas])), rel=1e-4)
    # the built-in path adds the legs' Table 3 masses: a larger force
    assert objectives.get("max_force_trajectory")(grinder) > got * 1.1


def _gs_task(**kw):
    P = np.array([[-0.05, 0.02, 0.58, 0.05, 0.0, -0.3], [0.08, -0.03, 0.66, 0.0, -0.1, 0.4],
                  [0.0, 0.06, 0.62, 0.0, 0.0, 0.0]])
    return Task(poses=P, tool=[0.01, 0.0, 0.1], payload={"mass": 8.0, "com": [0.0, 0.0, 0.05]},
                trajectory={"speed": 0.4, "acceleration": 3.0, "angular_speed": 2.0, "angular_acceleration": 30.0,
                            "jerk_time": 0.02, "dt": 0.01}, **kw)


def test_trajectory_measures_of_a_gough_stewart_by_hand():
    gs = parasynth.load_mechanism("gough_stewart_6ups")
    wrench = np.array([30.0, -40.0, -120.0, 2.0, -3.0, 1.0])
    task = _gs_task(wrench=wrench)
    path = task.path(gs)
    X = path.X
    feas = gs.is_feasible(X)
    assert feas.all()
    # the unit actuation wrenches about the platform point, from the closed-form leg vectors
    B = np.array([np.asarray(leg.base, float) for leg in gs.legs])
    A = np.array([np.asarray(leg.platform, float) for leg in gs.legs])
    R = euler_to_matrix("xyz", X[:, 3:])
    pts = X[:, None, :3] + np.einsum("nij,kj->nki", R, A)
    n = pts - B[None]
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    r = pts - X[:, None, :3]
    W = np.concatenate([n, np.cross(r, n)], axis=2)
    worst = 0.0
    for k in range(len(X)):
        rt = R[k] @ np.array([0.01, 0.0, 0.1])
        w = np.concatenate([wrench[:3], wrench[3:] + np.cross(rt, wrench[:3])])
        F, *_ = np.linalg.lstsq(W[k].T, -w, rcond=None)
        worst = max(worst, np.abs(F).max())
    ratio = objectives.get("force_decoupling_ratio")(gs, task=task)
    assert ratio == pytest.approx(worst / np.linalg.norm(wrench[:3]), rel=1e-9)
    # the largest force along the path is the path part of task_actuator_force_max
    ev = parasynth.measures.task.task_evaluation(gs, task)
    assert objectives.get("max_force_trajectory")(gs, task=task) == pytest.approx(np.nanmax(ev.dynamic_forces), rel=0)
    assert objectives.get("max_force_trajectory")(gs, task=task) <= objectives.get("task_actuator_force_max")(gs, task=task)


def test_trajectory_measures_refuse_what_they_cannot_do(grinder, grinding_task):
    gs = parasynth.load_mechanism("gough_stewart_6ups")
    with pytest.raises(TaskError, match=r"^task: max_force_trajectory needs a task .* on 4ups_1rps only"):
        objectives.get("max_force_trajectory")(gs)
    with pytest.raises(TaskError, match=r"^force_decoupling_ratio: dt, grinding_force set\(s\) the built-in"):
        objectives.get("force_decoupling_ratio")(grinder, task=grinding_task, dt=0.1, grinding_force=30.0)
    with pytest.raises(TaskError, match=r"task\.loads\.wrench: force_decoupling_ratio needs a wrench with a force"):
        objectives.get("force_decoupling_ratio")(gs, task=_gs_task(wrench=[0, 0, 0, 1.0, 0, 0]))
    with pytest.raises(TaskError, match=r"task\.loads\.wrench: needed"):
        objectives.get("force_decoupling_ratio")(gs, task=_gs_task())
    with pytest.raises(TaskError, match=r"task\.trajectory"):
        objectives.get("max_force_trajectory")(gs, task=Task(poses=gs.home[None]))
    assert objectives.get("max_force_trajectory").without_task == ("4ups_1rps",)
    assert objectives.get("max_force_trajectory").runs_without_task("4ups_1rps")
    assert not objectives.get("task_coverage").runs_without_task("4ups_1rps")
    assert objectives.get("footprint_radius").runs_without_task("gough_stewart_6ups")


def _study(mechanism, task=None, objective="max_force_trajectory"):
    d = {"name": "t", "mechanism": mechanism, "variables": [{"name": "platform_radius", "values": ["100 mm"]}],
         "objectives": [{"name": objective}], "optimizer": {"kind": "sweep"}}
    if task is not None:
        d["task"] = task
    return yaml.safe_dump(d)


def test_a_study_names_the_grinding_task_file_and_needs_a_task_off_the_grinder():
    s = load_study(_study("4ups_1rps", {"file": str(GRINDING)}), is_text=True)
    assert s.task.n_poses == 201 and s.task.trajectory.times is not None
    load_study(_study("4ups_1rps"), is_text=True)  # the built-in path without a task
    with pytest.raises(StudyError, match=r"^objectives\[0\]\.name: 'max_force_trajectory' is a task measure"):
        load_study(_study("gough_stewart_6ups"), is_text=True)
    with pytest.raises(StudyError, match=r"task\.file: cannot read"):
        load_study(_study("4ups_1rps", {"file": "/nonexistent/task.yaml"}), is_text=True)


def test_the_interactive_report_moves_along_the_built_in_path_only_without_a_task():
    from parasynth.study.view import trajectory_of as _trajectory

    built_in = _trajectory(load_study(_study("4ups_1rps"), is_text=True))
    assert built_in is not None and built_in[1] == "max_force_trajectory"
    t, X = built_in[0](5)
    np.testing.assert_allclose(X[-1, :2], [0.1, 0.45], atol=1e-12)  # the circle closes at t = 50 s
    assert _trajectory(load_study(_study("4ups_1rps", {"file": str(GRINDING)}), is_text=True)) is None


def test_continuity_of_an_under_actuated_mechanism_skips_the_assembly_mode(grinder, grinding_task):
    """The 4-UPS/1-RPS has 4 actuators for 5 freedoms: forward kinematics from the actuators is
    not unique, so continuity checks feasibility and singularity only, and says so."""
    assert grinder.n_actuators == 4 and grinder.n_task == 5
    big = grinder.with_params(l_max=0.7656, d2_max=0.6843, base_radius=0.3458, platform_radius=0.1566,
                              l_s0=0.03738)
    ev = parasynth.measures.task.task_evaluation(big, grinding_task)
    assert ev.path_feasible.all()
    c = ev.continuity()
    assert c.first_break is None and "assembly mode not checked" in c.rule
    # the 6-UPS (6 actuators, 6 freedoms) keeps the check
    gs = parasynth.load_mechanism("gough_stewart_6ups")
    assert "assembly mode" not in parasynth.measures.task.task_evaluation(gs, _gs_task()).continuity().rule
