"""Export of a mechanism to simulation and control tools (``docs/export.md``).

* :func:`to_mjcf` -- an MJCF model for MuJoCo: the legs as joint chains, the platform on a free
  joint, each loop closed by a ``connect`` (a leg ending in S) or a ``weld`` (a leg ending in U)
  equality, position servos on the actuated joints;
* :func:`to_urdf` -- a URDF spanning tree and its closure file (YAML, next to it), after the
  convention of the Gepetto parallel-robot toolbox, for Pinocchio;
* :func:`joint_positions` -- the joint positions of either model at poses of the mechanism, from
  parasynth's inverse kinematics (actuator values and passive joint angles).

This package sits above the model (legs, mechanisms, descriptions) and below the command line;
it imports neither the study nor the report layer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..common.validation import InputError, check_pose_array
from .mjcf import DEFAULTS as MJCF_DEFAULTS, servo_gains, write_mjcf
from .tree import SUPPORTED_LEGS, ExportError, Tree, build_tree, joint_values, wxyz
from .urdf import ROOT_JOINT, ball_joint_names, closure_path, write_urdf

__all__ = ["to_mjcf", "to_urdf", "joint_positions", "build_tree", "joint_values", "closure_path", "ExportError",
           "Tree", "MJCF_DEFAULTS", "SUPPORTED_LEGS", "servo_gains", "FORMATS"]

#: Export formats of :func:`joint_positions` and the command line.
FORMATS = ("mjcf", "urdf")


def _checked_mech(mech, what: str):
    """``mech`` when it is a mechanism; :class:`ExportError` naming ``<what> mech`` otherwise (a
    model's name or a description file given where the model is expected, None, a number)."""
    if hasattr(mech, "task_coordinates") and callable(getattr(mech, "is_feasible", None)) and hasattr(mech, "legs"):
        return mech
    hint = repr(mech) if isinstance(mech, str) else "'5pus_upu'"
    got = repr(mech) if len(repr(mech)) <= 60 else repr(mech)[:57] + "..."
    raise ExportError(f"{what} mech must be a mechanism, e.g. parasynth.load_mechanism({hint}), got {got}")


def _checked_pose(mech, pose, what: str):
    """``pose`` (None: home) as a float array; :class:`ExportError` naming ``<what> pose`` for a
    string, a mapping, booleans or complex numbers. Its shape and reachability are checked where
    the model is laid out (:func:`build_tree`, naming the pose too)."""
    if pose is None:
        return None
    coords = ", ".join(mech.task_coordinates)
    allowed = f"None (the home pose) or {mech.n_task} numbers, the task coordinates {coords} (SI: m, rad)"
    try:
        X = check_pose_array(f"{what} pose", pose)
    except InputError:
        got = repr(pose) if len(repr(pose)) <= 60 else repr(pose)[:57] + "..."
        raise ExportError(f"{what} pose must be {allowed}, got {got}") from None
    return X


def _checked_path(path, what: str) -> Path:
    if not isinstance(path, (str, Path)) or not str(path).strip():
        raise ExportError(f"{what}: give the output file path (a string or Path), got {path!r}")
    return Path(path)


def to_mjcf(mech, path, pose=None, **options) -> Path:
    """Write ``mech`` as an MJCF file at ``path``, laid out at ``pose`` (task coordinates, SI;
    default the home pose), and return the path. ``options`` override
    :data:`MJCF_DEFAULTS` (``timestep``, ``gravity``, ``servo_frequency``, ``servo_damping_ratio``).
    Raises :class:`ExportError` (a ``ValueError``) for an unreachable pose or a leg type the
    exporter does not know, and naming the argument for a ``mech`` that is not a mechanism (a
    model's name: load it first) or a ``pose`` that is not its task coordinates."""
    _checked_mech(mech, "to_mjcf")
    path = _checked_path(path, "to_mjcf path")
    pose = _checked_pose(mech, pose, "to_mjcf")
    unknown = sorted(set(options) - {"timestep", "gravity", "servo_frequency", "servo_damping_ratio"})
    if unknown:
        raise ExportError(f"to_mjcf: unknown option(s) {unknown}; options: timestep, gravity, servo_frequency, "
                          f"servo_damping_ratio")
    for k, v in options.items():
        if k == "gravity":
            g = np.asarray(v, dtype=float) if not isinstance(v, str) else None
            if g is None or g.shape != (3,) or not np.all(np.isfinite(g)):
                raise ExportError(f"to_mjcf gravity: give 3 finite numbers (m/s^2, base frame), got {v!r}")
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v <= 0:
            raise ExportError(f"to_mjcf {k}: give a positive number, got {v!r}")
    return write_mjcf(build_tree(mech, pose), path, **options)


def to_urdf(mech, path, pose=None) -> tuple[Path, Path]:
    """Write ``mech`` as a URDF spanning tree at ``path`` (laid out at ``pose``, default home)
    and its closure file next to it (:func:`closure_path`: same name, ``.yaml``); returns both
    paths. Raises :class:`ExportError` as :func:`to_mjcf`."""
    _checked_mech(mech, "to_urdf")
    path = _checked_path(path, "to_urdf path")
    pose = _checked_pose(mech, pose, "to_urdf")
    return write_urdf(build_tree(mech, pose), path)


def joint_positions(mech, X, pose=None, format: str = "mjcf") -> dict:
    """{joint name: positions} of the model written by :func:`to_mjcf` (``format="mjcf"``) or
    :func:`to_urdf` (``"urdf"``) at ``pose`` (default home), for the mechanism's poses ``X``
    (N, n_task) or (n_task,), from parasynth's inverse kinematics.

    * ``mjcf``: slide and hinge joints (N,) read as parasynth's values (their ``ref`` is the
      export pose's value); ``ball`` joints (N, 4) quaternions w x y z relative to the export
      pose; ``platform`` (the free joint) (N, 7): position and quaternion w x y z. Set MuJoCo's
      ``qpos`` at ``model.jnt_qposadr`` of each joint.
    * ``urdf``: prismatic and revolute joints (N,) are zero at the export pose (parasynth's value
      less the closure file's ``joint_offsets``); a kept spherical joint is its three revolute
      joints ``<name>_x/_y/_z`` (intrinsic x-y-z angles); ``root_joint`` (the platform's
      floating joint, :data:`~parasynth.export.urdf.ROOT_JOINT`) (N, 7): position and quaternion
      x y z w (Pinocchio's free-flyer order).

    A single pose gives arrays without the leading axis. ``ExportError`` for an unreachable
    pose."""
    if format not in FORMATS:
        raise ExportError(f"joint_positions: format must be one of {', '.join(FORMATS)}, got {format!r}")
    single = np.ndim(X) == 1
    tree = build_tree(mech, pose)
    vals = joint_values(mech, np.atleast_2d(np.asarray(X, dtype=float)))
    out = {}
    at_export = None
    for name, j in tree.joints.items():
        v = vals[name]
        if j.kind == "ball":
            if at_export is None:  # the kept spherical joints' values at the export pose
                at_export = joint_values(mech, np.asarray(tree.pose))
            rel = Rotation.from_matrix(at_export[name].T @ v)
            if format == "mjcf":
                out[name] = rel.as_quat()[..., [3, 0, 1, 2]]
            else:
                for nm, a in zip(ball_joint_names(name), rel.as_euler("XYZ").T):
                    out[nm] = a
        else:
            out[name] = v if format == "mjcf" else v - j.ref
    T = vals["platform"]
    q = wxyz(T[:, :3, :3]) if format == "mjcf" else Rotation.from_matrix(T[:, :3, :3]).as_quat()
    out["platform" if format == "mjcf" else ROOT_JOINT] = np.concatenate([T[:, :3, 3], q], axis=1)
    if single:
        out = {k: v[0] for k, v in out.items()}
    return out
