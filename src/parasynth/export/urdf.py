"""URDF writer of the kinematic tree (:mod:`parasynth.export.tree`) and its closure file.

URDF describes trees only. The file holds the spanning tree: the base link, the platform link on
a ``floating`` joint named :data:`ROOT_JOINT` (Pinocchio: a free flyer; the only frame named
``platform`` is then the platform link's, at the platform reference point) and every leg as a
serial chain; a universal joint is two ``revolute`` joints through a massless cross link, a
spherical joint the tree keeps (the
base joint of an SPS leg) three ``revolute`` joints about the body's x, y and z axes (URDF has no
spherical joint; intersecting revolute axes are one for any URDF reader, singular only 90 deg from
the export pose). Each loop is closed by two frames, massless links on ``fixed`` joints: the
leg's ``<leg>_tip`` at the end of its chain and the platform's ``platform_<leg>``.

The closure file (YAML, written next to the URDF with the same stem) follows the convention of
the Gepetto parallel-robot toolbox (``robot.urdf`` + ``robot.yaml``: ``closed_loop``, ``type``,
``name_mot``, ``joint_name``, ``joint_type``) and adds parasynth's own section; every key is
described in ``docs/export.md``.

URDF joints have no reference value: a joint's position ``q`` is zero at the export pose, so a
parasynth value is ``q + offset`` with the offsets the closure file lists.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import yaml

from .tree import STEEL_DENSITY, ExportError, Tree

__all__ = ["write_urdf", "closure_path", "ball_joint_names", "ROOT_JOINT"]

#: Name of the platform's ``floating`` joint. It is not ``platform``: Pinocchio makes a frame of
#: every joint and every link, and a joint named like the platform link would give two frames
#: ``platform`` (``model.getFrameId("platform")`` refuses an ambiguous name). ``root_joint`` is
#: the name Pinocchio gives a free-flyer root joint itself.
ROOT_JOINT = "root_joint"

#: The three revolute joints of a spherical joint ``name`` (about x, y, z of its body).
BALL_AXES = ("x", "y", "z")


def ball_joint_names(name: str) -> tuple:
    """The URDF joints of the kept spherical joint ``name``: ``name_x, name_y, name_z``."""
    return tuple(f"{name}_{a}" for a in BALL_AXES)


def closure_path(urdf_path) -> Path:
    """The closure file written next to ``urdf_path``: the same name with ``.yaml``."""
    return Path(urdf_path).with_suffix(".yaml")


def _f(x) -> str:
    return f"{float(x):.17g}"


def _vec(v) -> str:
    return " ".join(_f(x) for x in v)


def _rpy(rot) -> tuple:
    """URDF roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)) of a row-major 3x3 rotation."""
    R = np.asarray(rot, dtype=float).reshape(3, 3)
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if math.hypot(R[0, 0], R[1, 0]) > 1e-12:
        roll = math.atan2(R[2, 1], R[2, 2])
        yaw = math.atan2(R[1, 0], R[0, 0])
    else:  # pitch = +-90 deg: only roll -+ yaw is defined; take yaw = 0
        roll = math.atan2(-R[1, 2], R[1, 1])
        yaw = 0.0
    return roll, pitch, yaw


def _origin(parent, pos, rot=None):
    attrs = {"xyz": _vec(pos)}
    attrs["rpy"] = _vec(_rpy(rot)) if rot is not None else "0 0 0"
    ET.SubElement(parent, "origin", **attrs)


def _segment_frame(a, b):
    """Origin (midpoint) and rotation whose z axis runs from ``a`` to ``b``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    z = b - a
    h = float(np.linalg.norm(z))
    z = z / h
    t = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(t, z)
    x /= np.linalg.norm(x)
    R = np.column_stack([x, np.cross(z, x), z])
    return (a + b) / 2, R, h


def _inertial(link, geoms):
    """Mass, centre of mass and inertia of a link's capsules (cylinder + sphere) and spheres at
    :data:`STEEL_DENSITY`."""
    parts = []
    for g in geoms:
        r = g.radius
        ms = STEEL_DENSITY * 4.0 / 3.0 * math.pi * r**3
        if g.kind == "capsule":
            c, R, h = _segment_frame(g.a, g.b)
            mc = STEEL_DENSITY * math.pi * r * r * h
            Ic = np.diag([mc * (3 * r * r + h * h) / 12, mc * (3 * r * r + h * h) / 12, mc * r * r / 2])
            parts.append((mc, c, R @ Ic @ R.T))
            parts.append((ms, c, np.eye(3) * 0.4 * ms * r * r))  # the two caps, lumped at the middle
        else:
            parts.append((ms, np.asarray(g.a, float), np.eye(3) * 0.4 * ms * r * r))
    if not parts:
        return
    m = sum(p[0] for p in parts)
    com = sum(p[0] * p[1] for p in parts) / m
    inertia = np.zeros((3, 3))
    for mi, ci, Ii in parts:
        d = ci - com
        inertia += Ii + mi * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    el = ET.SubElement(link, "inertial")
    _origin(el, com)
    ET.SubElement(el, "mass", value=_f(m))
    ET.SubElement(el, "inertia", ixx=_f(inertia[0, 0]), ixy=_f(inertia[0, 1]), ixz=_f(inertia[0, 2]),
                  iyy=_f(inertia[1, 1]), iyz=_f(inertia[1, 2]), izz=_f(inertia[2, 2]))


def _visuals(link, geoms):
    for g in geoms:
        el = ET.SubElement(link, "visual")
        if g.kind == "capsule":
            c, R, h = _segment_frame(g.a, g.b)
            _origin(el, c, R.ravel())
            ET.SubElement(ET.SubElement(el, "geometry"), "cylinder", radius=_f(g.radius), length=_f(h))
        else:
            _origin(el, g.a)
            ET.SubElement(ET.SubElement(el, "geometry"), "sphere", radius=_f(g.radius))


def _limits(j, length_scale):
    """Lower and upper limits of ``q`` (zero at the export pose): the description's range less the
    export value, else +-pi (hinge) or +-10 length scales (slide)."""
    span = math.pi if j.kind == "hinge" else 10.0 * length_scale
    if j.range is None:
        return -span, span
    lo, hi = j.range
    return (lo - j.ref if np.isfinite(lo) else -span), (hi - j.ref if np.isfinite(hi) else span)


def write_urdf(tree: Tree, path) -> tuple[Path, Path]:
    """Write ``tree`` as a URDF file at ``path`` and its closure file next to it; returns both
    paths."""
    path = Path(path)
    cpath = closure_path(path)
    if cpath.resolve() == path.resolve():
        raise ExportError(f"the URDF path {str(path)!r} ends in .yaml, the name of its closure file; give a "
                          f"name ending in .urdf")
    root = ET.Element("robot", name=tree.mechanism)
    pose = ", ".join(f"{c}={v:.12g}" for c, v in zip(tree.task_coordinates, tree.pose))
    root.append(ET.Comment(f" parasynth export of {tree.mechanism} at the pose {pose} (SI: m, rad): the "
                           f"spanning tree; the closed loops are in {cpath.name} (docs/export.md) "))
    ET.SubElement(root, "link", name="base")
    offsets, balls = {}, {}
    for b in tree.bodies:
        parent = "base" if b.parent is None else b.parent
        links = []
        if b.free:
            links.append((b.name, ET.Element("joint", name=ROOT_JOINT, type="floating")))
        for j in b.joints:
            if j.kind == "ball":
                names = ball_joint_names(j.name)
                balls[j.name] = list(names)
                for nm, ax in zip(names, np.eye(3)):
                    el = ET.Element("joint", name=nm, type="revolute")
                    ET.SubElement(el, "axis", xyz=_vec(ax))
                    ET.SubElement(el, "limit", lower=_f(-math.pi), upper=_f(math.pi), effort="0", velocity="0")
                    links.append((nm, el))
                continue
            el = ET.Element("joint", name=j.name, type="revolute" if j.kind == "hinge" else "prismatic")
            ET.SubElement(el, "axis", xyz=_vec(j.axis))
            lo, hi = _limits(j, tree.length_scale)
            ET.SubElement(el, "limit", lower=_f(lo), upper=_f(hi), effort="0", velocity="0")
            links.append((j.name, el))
            offsets[j.name] = float(j.ref)
        # One link per joint; the last is the body, the others massless links between its joints.
        for k, (jname, el) in enumerate(links):
            child = b.name if k == len(links) - 1 else f"{b.name}__{jname}"
            ET.SubElement(el, "parent", link=parent)
            ET.SubElement(el, "child", link=child)
            if k == 0 and not b.free:
                _origin(el, b.pos, b.rot)
            else:  # the free joint's frame is the base frame: its q is the platform's pose
                _origin(el, (0.0, 0.0, 0.0))
            root.append(el)
            link = ET.SubElement(root, "link", name=child)
            if child == b.name:
                _inertial(link, b.geoms)
                _visuals(link, b.geoms)
            parent = child
        for s in b.sites:  # frames on fixed joints (closure frames, the platform point)
            if s.name == b.name:
                continue
            el = ET.SubElement(root, "joint", name=f"{s.name}_frame", type="fixed")
            ET.SubElement(el, "parent", link=b.name)
            ET.SubElement(el, "child", link=s.name)
            _origin(el, s.pos, s.rot)
            ET.SubElement(root, "link", name=s.name)
    ET.indent(root)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
    cpath.write_text(_closure_text(tree, path, offsets, balls), encoding="utf-8")
    return path, cpath


def _closure_text(tree: Tree, path: Path, offsets: dict, balls: dict) -> str:
    pose = {c: float(v) for c, v in zip(tree.task_coordinates, tree.pose)}
    doc = {
        "closed_loop": [[c.site1, c.site2] for c in tree.closures],
        "type": [c.kind for c in tree.closures],
        "name_mot": list(tree.actuators.values()),
        "joint_name": [],
        "joint_type": [],
        "parasynth": {
            "mechanism": tree.mechanism,
            "urdf": path.name,
            "pose": pose,
            "units": "SI (m, rad)",
            "root_joint": {"name": ROOT_JOINT, "type": "floating",
                           "q": "platform position (m) and orientation quaternion x y z w in the base frame"},
            "loops": {c.leg: {"frames": [c.site1, c.site2], "type": c.kind} for c in tree.closures},
            "actuators": dict(tree.actuators),
            "joint_offsets": offsets,
            "spherical_joints": balls,
            "hold_joints": list(tree.hold_joints),
            "not_exported": list(tree.not_exported),
        },
    }
    head = (f"# Closed loops of {path.name} (parasynth export of {tree.mechanism}), after the Gepetto parallel-robot\n"
            f"# toolbox convention (closed_loop, type, name_mot, joint_name, joint_type); the parasynth section is\n"
            f"# parasynth's own. Every key is described in docs/export.md.\n")
    return head + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=110)
