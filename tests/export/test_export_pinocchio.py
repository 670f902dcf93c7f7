"""The URDF export and its closure file checked by Pinocchio, on every packaged mechanism and
variant and on a user's description.

* **closures**: Pinocchio builds the model from the URDF (the platform's ``floating`` joint a
  free flyer); with its joint positions set from parasynth's inverse kinematics
  (:func:`parasynth.export.joint_positions`, ``format="urdf"``) at 20 feasible poses, the two
  frames of every loop the closure file names coincide (3D: positions within 1e-9 m; 6D: and
  orientations within 1e-9 rad) and the platform frame is at the pose. Pinocchio computes the
  frames from the URDF's joint tree alone.
* **mobility**: the closure file's loops as velocity constraints (the frames' velocities equal:
  3 rows for 3D, 6 for 6D, from Pinocchio's frame Jacobians) leave ``mobility().dof`` plus the
  local freedoms, as in MuJoCo.
* **the loader's keys**: the closure file has the keys of the Gepetto convention and every name
  it lists is a frame or a joint of the Pinocchio model.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from parasynth.export import joint_positions, to_urdf

from _export_cases import CASES, IDS, feasible_poses, load
from _optional import SIMULATORS, import_or_skip

pin = import_or_skip("pinocchio", SIMULATORS, "pin")

pytestmark = pytest.mark.filterwarnings("ignore::parasynth.model.mechanism.EngineFallbackWarning")


def _load(mech, tmp_path, pose=None):
    urdf, closures = to_urdf(mech, tmp_path / "robot.urdf", pose)
    assert closures == tmp_path / "robot.yaml"
    model = pin.buildModelFromUrdf(str(urdf))
    return model, model.createData(), yaml.safe_load(closures.read_text())


def _q(model, jp: dict, k: int) -> np.ndarray:
    q = pin.neutral(model)
    for name, v in jp.items():
        assert model.existJointName(name), name
        j = model.joints[model.getJointId(name)]
        q[j.idx_q:j.idx_q + j.nq] = v[k]
    return q


def _frame(model, name):
    return model.getFrameId(name, pin.BODY)


@pytest.mark.parametrize("name,params", CASES, ids=IDS)
def test_closure_frames_coincide_and_mobility_at_20_poses(name, params, tmp_path):
    mech = load(name, params)
    model, data, cl = _load(mech, tmp_path)
    assert {"closed_loop", "type", "name_mot", "joint_name", "joint_type"} <= set(cl)
    assert len(cl["closed_loop"]) == len(cl["type"]) == len(mech.legs)
    assert cl["type"] == ["6D" if leg.joints.endswith("U") else "3D" for leg in mech.legs]
    assert [model.existJointName(j) for j in cl["name_mot"]] == [True] * mech.n_actuators
    X = feasible_poses(mech)
    jp = joint_positions(mech, X, format="urdf")
    assert set(jp) == set(model.names[1:])
    mob = mech.mobility(X[0], warn=False)
    worst = 0.0
    for k in range(len(X)):
        q = _q(model, jp, k)
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        rows = []
        for (a, b), kind in zip(cl["closed_loop"], cl["type"]):
            Ma, Mb = data.oMf[_frame(model, a)], data.oMf[_frame(model, b)]
            worst = max(worst, float(np.linalg.norm(Ma.translation - Mb.translation)))
            if kind == "6D":
                worst = max(worst, float(np.linalg.norm(pin.log3(Ma.rotation.T @ Mb.rotation))))
            Ja = pin.computeFrameJacobian(model, data, q, _frame(model, a), pin.LOCAL_WORLD_ALIGNED)
            Jb = pin.computeFrameJacobian(model, data, q, _frame(model, b), pin.LOCAL_WORLD_ALIGNED)
            rows.append((Ja - Jb)[: 3 if kind == "3D" else 6])
        p, R = mech.pose(X[k])
        Mp = data.oMf[_frame(model, "platform")]
        assert np.linalg.norm(Mp.translation - p) < 1e-9 and np.abs(Mp.rotation - R).max() < 1e-9
        J = np.vstack(rows)
        s = np.linalg.svd(J, compute_uv=False)
        rank = int(np.sum(s > 1e-9 * s[0]))
        mob_k = mech.mobility(X[k], warn=False) if k % 5 == 0 else mob
        assert model.nv - rank == mob_k.dof + mob_k.local_dof, (k, model.nv, rank)
    assert worst < 1e-9, worst


@pytest.mark.parametrize("name,params", CASES, ids=IDS)
def test_the_platform_frame_is_one_frame_at_the_platform_pose(name, params, tmp_path):
    """``model.getFrameId("platform")`` without a frame type finds one frame (Pinocchio refuses a
    name that several frames carry), the platform link's; at q = 0 (the export pose) and at
    another pose its placement is the platform pose of parasynth's kinematics."""
    mech = load(name, params)
    X = feasible_poses(mech, 2, seed=4)
    model, data, _ = _load(mech, tmp_path, pose=X[0])
    assert [f.name for f in model.frames].count("platform") == 1
    fid = model.getFrameId("platform")
    assert model.frames[fid].type == pin.BODY
    jp = joint_positions(mech, X, pose=X[0], format="urdf")
    root = model.joints[model.getJointId("root_joint")]
    for k in range(2):
        if k == 0:  # the export pose: every leg joint at q = 0, the free flyer at the platform pose
            q = pin.neutral(model)
            p, R = mech.pose(X[0])
            q[root.idx_q:root.idx_q + 7] = np.concatenate([p, pin.Quaternion(R).coeffs()])
        else:
            q = _q(model, jp, k)
        pin.framesForwardKinematics(model, data, q)
        p, R = mech.pose(X[k])
        M = data.oMf[fid]
        assert np.linalg.norm(M.translation - p) < 1e-12 and np.abs(M.rotation - R).max() < 1e-12, (k, M)


def test_a_wrong_joint_position_opens_a_loop(tmp_path):
    """The check can fail: one passive angle off by 1 mrad separates that leg's frames."""
    mech = load("gough_stewart_6ups", {})
    model, data, cl = _load(mech, tmp_path)
    X = feasible_poses(mech, 1)
    jp = joint_positions(mech, X, format="urdf")
    jp["L3_U2"] = jp["L3_U2"] + 1e-3
    pin.framesForwardKinematics(model, data, _q(model, jp, 0))
    gaps = {a: np.linalg.norm(data.oMf[_frame(model, a)].translation - data.oMf[_frame(model, b)].translation)
            for a, b in cl["closed_loop"]}
    assert gaps["L3_tip"] > 1e-4 and max(v for k, v in gaps.items() if k != "L3_tip") < 1e-9


def test_offsets_and_export_pose(tmp_path):
    """q = 0 is the export pose; parasynth's value is q + the closure file's joint offset."""
    mech = load("3rps", {})
    X = feasible_poses(mech, 3, seed=2)
    model, data, cl = _load(mech, tmp_path, pose=X[0])
    off = cl["parasynth"]["joint_offsets"]
    ik = mech.inverse_kinematics(X[0])
    for i, leg in enumerate(mech.legs):
        assert off[f"{leg.name}_P"] == pytest.approx(ik.actuators[i], abs=1e-15)
        assert off[f"{leg.name}_R"] == pytest.approx(ik.passive_angles[f"{leg.name}.R_base"], abs=1e-15)
    jp = joint_positions(mech, X, pose=X[0], format="urdf")
    assert all(np.all(np.abs(v[0][()] if k != "root_joint" else 0) < 1e-15) for k, v in jp.items())
    pin.framesForwardKinematics(model, data, _q(model, jp, 2))
    for a, b in cl["closed_loop"]:
        assert np.linalg.norm(data.oMf[_frame(model, a)].translation - data.oMf[_frame(model, b)].translation) < 1e-9


def test_the_python_examples_of_docs_export_run(tmp_path, monkeypatch):
    """docs/export.md's Python blocks, in order, in a scratch directory (MuJoCo and Pinocchio)."""
    import re
    from pathlib import Path

    import_or_skip("mujoco", SIMULATORS, "mujoco")
    text = (Path(__file__).resolve().parents[2] / "docs" / "export.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) == 3
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(compile("\n".join(blocks), "docs/export.md", "exec"), scope)
    assert (tmp_path / "m.xml").exists() and (tmp_path / "m.yaml").exists()
    assert scope["model"].nq == len(scope["q"])
