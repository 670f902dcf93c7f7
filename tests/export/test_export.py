"""``parasynth export`` and the written files, without the simulators (the MuJoCo and Pinocchio
checks are in test_export_mujoco.py and test_export_pinocchio.py): the command line for every
packaged mechanism and a user's description, run directories (``--trial``, the recommended
design), the limits written as joint ranges, the closure file's keys and names, and the errors."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml

import parasynth
from parasynth import cli
from parasynth.export import ExportError, closure_path, joint_positions, to_mjcf, to_urdf
from parasynth.study import load_study, run_study

from _export_cases import CASES, IDS, USER_DESCRIPTION, load

pytestmark = pytest.mark.filterwarnings("ignore::parasynth.model.mechanism.EngineFallbackWarning")

PLUGIN = str(Path(__file__).resolve().parents[1] / "data" / "analytic_plugin.py")
cli.load_plugins(PLUGIN)


def _run_cli(args, capsys):
    code = cli.main(args)
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("name,params", CASES, ids=IDS)
def test_cli_writes_both_formats(name, params, tmp_path, capsys):
    sets = [a for k, v in params.items() for a in ("--set", f"{k}={str(v).lower()}")]
    code, out, err = _run_cli(["export", name, *sets, "--format", "mjcf", "--out", str(tmp_path / "m.xml")], capsys)
    assert code == 0, err
    root = ET.parse(tmp_path / "m.xml").getroot()
    mech = load(name, params)
    assert root.tag == "mujoco" and len(root.find("actuator")) == mech.n_actuators
    assert [e.get("name") for e in root.find("actuator")] == list(mech.actuators)
    code, out, err = _run_cli(["export", name, *sets, "--format", "urdf", "--out", str(tmp_path / "m.urdf")], capsys)
    assert code == 0, err
    assert (tmp_path / "m.yaml").exists() and f"wrote {tmp_path / 'm.yaml'}" in out
    robot = ET.parse(tmp_path / "m.urdf").getroot()
    links = {e.get("name") for e in robot.findall("link")}
    joints = {e.get("name") for e in robot.findall("joint")}
    cl = yaml.safe_load((tmp_path / "m.yaml").read_text())
    for a, b in cl["closed_loop"]:  # the closure frames are links of the URDF
        assert a in links and b in links
    assert set(cl["name_mot"]) <= joints and cl["joint_name"] == [] and cl["joint_type"] == []
    assert set(cl["type"]) <= {"3D", "6D"}
    assert set(cl["parasynth"]["actuators"]) == set(mech.actuators)


def test_cli_set_and_pose_reach_the_written_model(tmp_path, capsys):
    out = tmp_path / "m.xml"
    code, text, err = _run_cli(["export", "5pus_upu", "--set", "link_length=190 mm", "--pose", "z=-20 mm",
                                "--pose", "alpha=3 deg", "--out", str(out)], capsys)
    assert code == 0, err
    assert "z=-20 mm" in text and "alpha=3 deg" in text
    root = ET.parse(out).getroot()
    link = root.find(".//body[@name='L1_link']/geom")
    a, b = np.array(link.get("fromto").split(), float).reshape(2, 3)
    assert np.linalg.norm(b - a) == pytest.approx(0.190, abs=1e-12)
    mech = parasynth.load_mechanism("5pus_upu", link_length=0.19)
    X = mech.home.copy()
    X[2], X[3] = -0.02, np.radians(3)
    plat = root.find(".//body[@name='platform']")
    np.testing.assert_allclose(np.array(plat.get("pos").split(), float), mech.pose(X)[0], atol=1e-15)
    ref = float(root.find(".//joint[@name='L1_P']").get("ref"))
    assert ref == pytest.approx(mech.inverse_kinematics(X).actuators[0], abs=1e-15)


def test_user_description_file(tmp_path, capsys):
    code, text, err = _run_cli(["export", USER_DESCRIPTION, "--set", "crank_length=110 mm", "--out",
                                str(tmp_path / "r.urdf")], capsys)
    assert code == 0, err
    cl = yaml.safe_load((tmp_path / "r.yaml").read_text())
    assert cl["parasynth"]["mechanism"] == "export_6rus" and cl["name_mot"] == [f"L{i}_R" for i in range(1, 7)]


@pytest.fixture(scope="module")
def sweep_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    study = load_study(yaml.safe_dump({
        "name": "export_sweep", "mechanism": "5pus_upu",
        "variables": [{"name": "link_length", "values": ["180 mm", "200 mm", "230 mm"]}],
        "objectives": [{"name": "test_quadratic", "goal": "maximize"}],
        "optimizer": {"kind": "sweep"}}), is_text=True)
    run_study(study, out_dir=d / "run", progress=False)
    return d / "run"


def _link_length(path):
    geom = ET.parse(path).getroot().find(".//body[@name='L1_link']/geom")
    a, b = np.array(geom.get("fromto").split(), float).reshape(2, 3)
    return float(np.linalg.norm(b - a))


def test_cli_run_directory_recommended_and_trial(sweep_run, tmp_path, capsys):
    # test_quadratic is largest at L = 200 mm: the recommended (best) design
    code, text, err = _run_cli(["export", str(sweep_run), "--out", str(tmp_path / "best.xml")], capsys)
    assert code == 0, err
    assert "recommended design (trial 1)" in text and "link_length = 200 mm" in text
    assert _link_length(tmp_path / "best.xml") == pytest.approx(0.200, abs=1e-12)
    code, text, err = _run_cli(["export", str(sweep_run), "--trial", "2", "--format", "mjcf", "--out",
                                str(tmp_path / "t2.xml")], capsys)
    assert code == 0, err
    assert _link_length(tmp_path / "t2.xml") == pytest.approx(0.230, abs=1e-12)


@pytest.mark.parametrize("args,message", [
    (["5pus_upu", "--out", "m.txt"], "--format: give mjcf or urdf"),
    (["5pus_upu", "--out", "m.xml", "--pose", "q=1 mm"], "--pose q: not a task coordinate of 5pus_upu"),
    (["5pus_upu", "--out", "m.xml", "--pose", "z=5"], "--pose z"),
    (["5pus_upu", "--out", "m.xml", "--pose", "x=400 mm"], "is not reachable by leg"),
    (["5pus_upu", "--out", "m.xml", "--trial", "2"], "--trial applies to a run directory"),
    (["5pus_upu", "--out", "m.xml", "--set", "link_length=190"], "--set link_length"),
    (["5pus_upu", "--out", "m.xml", "--set", "no_such=1 mm"], "unknown parameter(s) ['no_such']"),
    (["no_such_mechanism", "--out", "m.xml"], "unknown mechanism 'no_such_mechanism'"),
    (["5pus_upu", "--out", "no_dir/m.xml"], "does not exist"),
    (["5pus_upu", "--format", "urdf", "--out", "m.yaml"], "ends in .yaml"),
])
def test_cli_errors_are_one_line(args, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = _run_cli(["export", *args], capsys)
    assert code == 2
    assert err.startswith("error: ") and message in err and err.count("\n") == 1, err


def test_cli_run_directory_errors(sweep_run, tmp_path, capsys):
    code, _, err = _run_cli(["export", str(sweep_run), "--trial", "7", "--out", str(tmp_path / "m.xml")], capsys)
    assert code == 2 and "--trial 7: no such trial" in err and "from 0 to 2" in err
    code, _, err = _run_cli(["export", str(sweep_run), "--set", "link_length=1 mm", "--out",
                             str(tmp_path / "m.xml")], capsys)
    assert code == 2 and "--set applies to a mechanism" in err
    code, _, err = _run_cli(["export", str(tmp_path), "--out", str(tmp_path / "m.xml")], capsys)
    assert code == 2 and "not a run directory" in err


def test_infeasible_pose_is_written_with_a_warning(tmp_path, capsys):
    code, out, err = _run_cli(["export", "5pus_upu", "--pose", "z=200 mm", "--out", str(tmp_path / "m.xml")],
                              capsys)
    assert code == 0 and "warning: the pose violates the constraint(s) stroke" in err


def test_ranges_written_from_the_description_limits(tmp_path):
    mech = parasynth.load_mechanism("3rps")
    root = ET.parse(to_mjcf(mech, tmp_path / "m.xml")).getroot()
    p = mech.params
    for leg in mech.legs:
        r = np.array(root.find(f".//joint[@name='{leg.name}_R']").get("range").split(), float)
        np.testing.assert_allclose(r, [-p.revolute_max, p.revolute_max], rtol=0, atol=1e-15)
        r = np.array(root.find(f".//joint[@name='{leg.name}_P']").get("range").split(), float)
        np.testing.assert_allclose(r, [p.q_min, p.q_max], rtol=0, atol=1e-15)
    text = (tmp_path / "m.xml").read_text()
    assert "sphere_limit" in text and "interference" in text  # listed as not exported
    urdf, cpath = to_urdf(mech, tmp_path / "m.urdf")
    robot = ET.parse(urdf).getroot()
    ref = mech.inverse_kinematics(mech.home)
    lim = robot.find(".//joint[@name='L1_P']/limit")
    assert float(lim.get("lower")) == pytest.approx(p.q_min - ref.actuators[0], abs=1e-15)
    assert float(lim.get("upper")) == pytest.approx(p.q_max - ref.actuators[0], abs=1e-15)
    assert cpath == closure_path(urdf) == tmp_path / "m.yaml"


def test_diameters_from_the_description():
    from parasynth.export import build_tree

    for name, d in [("5pus_upu", 0.008), ("gough_stewart_6ups", 0.040), ("2rpu_2sps", 0.030)]:
        tree = build_tree(parasynth.load_mechanism(name))
        radii = {g.radius for b in tree.bodies if b.leg == "L1" for g in b.geoms if g.role in ("rod", "link")}
        assert len(radii) == 1 and radii.pop() == pytest.approx(d / 2), name


def test_api_errors(tmp_path):
    mech = parasynth.load_mechanism("3prs")
    with pytest.raises(ExportError, match="pose must have 3 task coordinates"):
        to_mjcf(mech, tmp_path / "m.xml", pose=[0.0, 0.0])
    with pytest.raises(ExportError, match="unknown option"):
        to_mjcf(mech, tmp_path / "m.xml", kp=3)
    with pytest.raises(ExportError, match="format must be one of mjcf, urdf"):
        joint_positions(mech, mech.home, format="sdf")
    with pytest.raises(ExportError, match="not reachable by leg L1"):
        joint_positions(parasynth.load_mechanism("5pus_upu"), [0.4, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ExportError, match="give the output file path"):
        to_urdf(mech, "")
    with pytest.raises(ExportError, match="gravity: give 3 finite numbers"):
        to_mjcf(mech, tmp_path / "m.xml", gravity=(0, -9.81))
    with pytest.raises(ExportError, match="timestep: give a positive number"):
        to_mjcf(mech, tmp_path / "m.xml", timestep=0)
    assert isinstance(ExportError("x"), ValueError)


def test_a_leg_type_the_exporter_does_not_know_is_refused(tmp_path):
    from parasynth.model.legs import UPS

    class CPS(UPS):  # a leg class from elsewhere, with a cylindrical base joint
        joints = "CPS"

    mech = parasynth.load_mechanism("gough_stewart_6ups")
    leg = mech.legs[0]
    mech.legs = (CPS(leg.name, leg.base, leg.platform, leg.base_ref, leg.platform_ref, leg.u_axis),) + mech.legs[1:]
    with pytest.raises(ExportError, match="leg L1: leg type CPS does not support 'export'"):
        to_mjcf(mech, tmp_path / "m.xml")


def test_joint_positions_read_as_parasynth_values():
    """The MJCF joint positions are parasynth's numbers: actuator values on the actuated joints,
    the named passive angles on their hinges, the platform pose on the free joint."""
    mech = parasynth.load_mechanism("gough_stewart_6ups")
    X = mech.home + np.array([0.01, -0.02, 0.03, 0.05, -0.04, 0.1])
    jp = joint_positions(mech, X)
    ik = mech.inverse_kinematics(X)
    for i, leg in enumerate(mech.legs):
        assert jp[f"{leg.name}_P"] == ik.actuators[i]
        assert jp[f"{leg.name}_U1"] == ik.passive_angles[f"{leg.name}.U_base_1"]
        assert jp[f"{leg.name}_U2"] == ik.passive_angles[f"{leg.name}.U_base_2"]
    p, R = mech.pose(X)
    np.testing.assert_array_equal(jp["platform"][:3], p)
    w, x, y, z = jp["platform"][3:]
    assert np.allclose(R[2, 1] - R[1, 2], 4 * w * x) and np.isclose(w * w + x * x + y * y + z * z, 1.0)
