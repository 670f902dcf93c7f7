"""Units follow the actuators: a largest actuator force on cranks (RUS legs) is a torque in N*m,
on telescopic legs and sliders a force in N; actuator speeds in rad/s and m/s; a mechanism (or a
set of structures) with both refuses such a measure by name.

Independent values: the crank torques balancing a wrench against virtual work, sum_i tau_i dq_i
= F . dp + M . dtheta, with dq from finite differences of the inverse kinematics (a value in N
would be off by the crank length); the units in the column headers, CSV names and the console
summary of small runs of a 6-RUS and a 6-PUS study.
"""

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

import parasynth
from parasynth import objectives
from parasynth.common.units import actuator_unit_kind, actuators_summary
from parasynth.measures.display import quantity_unit
from parasynth.measures.task import task_evaluation
from parasynth.report.render import load_run
from parasynth.report.summary import terminal_summary
from parasynth.study import StudyError, load_study
from parasynth.study.columns import csv_column
from parasynth.study.runner import run_study

ROOT = Path(__file__).resolve().parents[2]
POSES = [{"x": "0 mm", "y": "0 mm", "z": "{z}", "gamma": "0 deg"},
         {"x": "20 mm", "y": "-10 mm", "z": "{z}", "alpha": "3 deg"}]


def _study(mechanism, z, extra_objectives=()):
    poses = [{k: v.format(z=z) for k, v in p.items()} for p in POSES]
    return {
        "name": f"units_{mechanism}", "mechanism": mechanism,
        "variables": [{"name": "platform_radius", "values": ["250 mm", "280 mm"]}],
        "task": {"poses": {"list": poses}, "frame": "platform",
                 "trajectory": {"speed": "0.2 m/s", "acceleration": "1 m/s^2", "angular_speed": "0.5 rad/s",
                                "angular_acceleration": "2 rad/s^2", "jerk_time": "0.05 s", "dt": "50 ms"},
                 "loads": {"payload": {"mass": "20 kg", "com": ["0 mm", "0 mm", "0 mm"],
                                       "inertia": ["0.1 kg*m^2", "0.1 kg*m^2", "0.2 kg*m^2"]},
                           "wrench": {"force": ["10 N", "20 N", "30 N"], "moment": ["1 N*m", "2 N*m", "3 N*m"]}}},
        "objectives": [{"name": "task_actuator_force_max", "label": "force_max"},
                       {"name": "task_actuator_power_max", "label": "power_max"}, *extra_objectives],
        "constraints": [{"name": "task_actuator_speed_max", "label": "speed", "max": "{}".format(
            "100 rad/s" if mechanism == "hexapod_6rus" else "100 m/s")}],
        "optimizer": {"kind": "sweep"},
    }


def _home_z(name):
    return f"{parasynth.load_mechanism(name).home[2] * 1e3:.3f} mm"


def test_crank_forces_are_torques_by_virtual_work():
    mech = parasynth.load_mechanism("hexapod_6rus")
    assert set(mech.actuator_kinds.values()) == {"angle"}
    X = np.asarray(mech.home, float)[None, :] + np.array([[0.01, -0.02, 0.0, 0.02, -0.01, 0.03]])
    w = np.array([40.0, -25.0, 300.0, 6.0, -4.0, 9.0])  # applied to the platform at its centre, base frame
    task = parasynth.Task(poses=X, wrench=w)
    tau = task_evaluation(mech, task).static_forces[0]
    assert np.all(np.isfinite(tau))
    rng = np.random.default_rng(0)
    h = 1e-6
    for _ in range(4):
        d = rng.normal(size=6)
        d /= np.linalg.norm(d)
        # the small motion as a twist: dp of the centre, dtheta from the rotation matrices
        Xp, Xm = X + h * d, X - h * d
        dq = (mech.inverse_kinematics(Xp).actuators - mech.inverse_kinematics(Xm).actuators)[0] / (2 * h)
        (pp, Rp), (pm, Rm) = mech.pose(Xp), mech.pose(Xm)
        dR = (Rp[0] - Rm[0]) @ mech.pose(X)[1][0].T / (2 * h)
        dth = np.array([dR[2, 1], dR[0, 2], dR[1, 0]])
        dp = (pp[0] - pm[0]) / (2 * h)
        # actuator work balances the work of the applied wrench (the actuators hold the platform:
        # tau . dq + w . twist = 0, whatever the sign convention, |.| compared)
        assert abs(abs(tau @ dq) - abs(w[:3] @ dp + w[3:] @ dth)) < 1e-5 * (1 + abs(w[:3] @ dp + w[3:] @ dth))
    # the measure is the largest of them, a torque
    assert objectives.get("task_actuator_force_max")(mech, task=task) == pytest.approx(np.max(np.abs(tau)))


def test_units_follow_the_actuators_in_columns():
    rus = load_study(yaml.safe_dump(_study("hexapod_6rus", _home_z("hexapod_6rus"))), is_text=True)
    pus = load_study(yaml.safe_dump(_study("hexapod_6pus", _home_z("hexapod_6pus"))), is_text=True)
    assert quantity_unit(rus, "force_max").symbol == "N*m" and quantity_unit(pus, "force_max").symbol == "N"
    assert quantity_unit(rus, "speed").symbol == "rad/s" and quantity_unit(pus, "speed").symbol == "m/s"
    assert quantity_unit(rus, "power_max").symbol == quantity_unit(pus, "power_max").symbol == "W"
    assert csv_column(rus, "force_max") == "force_max_N_m" and csv_column(pus, "force_max") == "force_max_N"
    # the shipped naval studies: the 6-RUS in N*m, the 6-UPS and 6-PUS in N
    for f, sym in (("naval_testbed_6rus", "N*m"), ("naval_testbed_6pus", "N"), ("naval_testbed", "N")):
        s = load_study(ROOT / "studies" / f"{f}.yaml")
        assert quantity_unit(s, "force_max").symbol == sym, f


def test_a_bound_is_given_in_the_actuators_unit():
    d = _study("hexapod_6rus", _home_z("hexapod_6rus"))
    d["constraints"] = [{"name": "task_actuator_force_max", "label": "f", "max": "500 N*m"}]
    assert load_study(yaml.safe_dump(d), is_text=True).constraints[0].max == pytest.approx(500.0)
    d["constraints"] = [{"name": "task_actuator_force_max", "label": "f", "max": "500 N"}]
    with pytest.raises(StudyError, match=r"constraints\[0\]\.max"):
        load_study(yaml.safe_dump(d), is_text=True)
    d = _study("hexapod_6pus", _home_z("hexapod_6pus"))
    d["constraints"] = [{"name": "task_actuator_speed_max", "label": "v", "max": "1 rad/s"}]
    with pytest.raises(StudyError, match=r"constraints\[0\]\.max"):
        load_study(yaml.safe_dump(d), is_text=True)


@pytest.mark.parametrize("mechanism, sym", [("hexapod_6rus", "N*m"), ("hexapod_6pus", "N")])
def test_the_summary_prints_the_actuators_unit(tmp_path, mechanism, sym):
    study = load_study(yaml.safe_dump(_study(mechanism, _home_z(mechanism))), is_text=True)
    run_study(study, tmp_path / "run", progress=False)
    table = load_run(tmp_path / "run").table
    assert table["feasible"].any()
    lines = "\n".join(terminal_summary(study, table, None, tmp_path / "run"))
    assert f"force_max [{sym}]" in lines or f" {sym}" in lines
    other = "N" if sym == "N*m" else "N*m"
    assert f"force_max [{other}]" not in lines
    vals = re.findall(r"force_max = [-0-9.e]+ ([^\s,]+)", lines)
    assert vals and set(vals) == {sym}, lines


def test_mixed_actuators_are_refused_by_name():
    assert actuators_summary(["length", "slider"]) == "length" and actuators_summary(["angle"]) == "angle"
    assert actuators_summary(["slider", "angle"]) == "mixed" and actuators_summary([]) is None
    assert actuator_unit_kind("actuator_force", "angle") == "torque"
    assert actuator_unit_kind("actuator_speed", "length") == "speed"
    with pytest.raises(ValueError, match="task_actuator_force_max: .*linear.*cranks"):
        actuator_unit_kind("actuator_force", "mixed", "task_actuator_force_max")
    # a study over structures driven some by cranks, some by linear actuators (2T2R: RUS and SPS)
    d = yaml.safe_load(open(ROOT / "studies" / "structures_2t2r.yaml"))
    d["objectives"].append({"name": "max_actuator_force", "label": "force"})
    with pytest.raises(StudyError, match=r"objectives\[2\]\.name: 'max_actuator_force'.*linear.*cranks"):
        load_study(yaml.safe_dump(d), is_text=True)
