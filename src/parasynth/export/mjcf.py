"""MJCF (MuJoCo) writer of the kinematic tree (:mod:`parasynth.export.tree`).

What is written, and why (``docs/export.md`` says it for users):

* the base is the world; the platform is a body on a free joint (``freejoint`` named
  ``platform``) with a site ``platform`` at its reference point, so that MuJoCo, not the joint
  tree, decides whether the legs leave it the mechanism's freedoms;
* every leg is a chain of bodies: P a ``slide``, R a ``hinge``, U two hinges in one body (the
  first axis fixed in the parent, the second in the body), S kept in the chain a ``ball``;
* a leg ending in S is closed by a ``connect`` between the site at the end of its chain and the
  platform site of its anchor (the connect *is* the spherical joint); a leg ending in U keeps
  both hinges and closes its end body to the platform with a ``weld`` (a connect there would
  drop the leg's constraint and change the mobility);
* slide and hinge joints carry ``ref`` = their value at the export pose, so that MuJoCo's
  joint positions read as parasynth's actuator values and passive joint angles
  (:func:`parasynth.export.tree.joint_values`);
* a position servo per actuated joint (named like parasynth's actuators, ``q1``, ``s1``, ``t1``),
  its control range the description's actuator range where there is one;
* joint ranges from the description's actuator, leg-length and joint-angle limits (the other
  constraints, such as cone angles and interference, are listed in a comment);
* contacts are disabled (the bodies of a leg overlap at its joints by construction);
* the equality constraints are made stiff (``solref`` at twice the time step, ``solimp`` with
  impedance 0.9999) so that the loops stay closed to well under a micrometre under the
  servo forces and gravity, and the Newton solver runs to a tight tolerance.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .tree import STEEL_DENSITY, Tree, wxyz

__all__ = ["write_mjcf", "servo_gains", "keyframe_values", "DEFAULTS", "KEYFRAME"]

#: Defaults of the written model: time step (s), gravity (m/s^2, base frame), servo natural
#: frequency (Hz) and damping ratio, joint damping (N s/m or N m s/rad per kg of moving mass),
#: and the equality constraints' solver reference time constant (in time steps) and impedance.
DEFAULTS = {
    "timestep": 0.0005,
    "gravity": (0.0, 0.0, -9.81),
    "servo_frequency": 100.0,
    "servo_damping_ratio": 1.0,
    "equality_timeconst_steps": 2.0,
    "equality_impedance": 0.9999,
    "hold_timeconst_steps": 20.0,
}


#: The conditioning below which the servo damping stops growing (an export pose at or next to a
#: singularity would otherwise give a damping that makes the step unstable).
MIN_CONDITIONING = 0.01


def _f(x) -> str:
    return f"{float(x):.17g}"


def _vec(v) -> str:
    return " ".join(_f(x) for x in v)


def _quat(rot) -> str:
    """MuJoCo quaternion (w x y z) of a row-major 3x3 rotation tuple (scipy's method, accurate for
    small components, where square roots of 1 + trace combinations lose half the digits)."""
    return _vec(wxyz(np.asarray(rot, dtype=float).reshape(3, 3)))


def moving_mass(tree: Tree) -> float:
    """Mass (kg) of every moving body's geometry at :data:`~parasynth.export.tree.STEEL_DENSITY`."""
    m = 0.0
    for b in tree.bodies:
        for g in b.geoms:
            r = g.radius
            vol = 4.0 / 3.0 * math.pi * r**3
            if g.kind == "capsule":
                vol += math.pi * r * r * float(np.linalg.norm(np.subtract(g.b, g.a)))
            m += STEEL_DENSITY * vol
    return m


def servo_gains(tree: Tree, frequency: float, damping_ratio: float) -> dict:
    """{actuator: (kp, kv, armature)} of the position servos (an assumption of the exporter, not a
    property of the design: a designer replaces them by the real drives').

    ``M`` is the moving mass (:func:`moving_mass`). Each actuated joint gets the armature ``A = M``
    (the drive's reflected inertia: motor and screw), the stiffness ``kp = (M + A) w^2`` of a
    natural frequency ``frequency`` (Hz) and the damping ``kv = 2 zeta sqrt(kp (M + A))`` with
    ``zeta = damping_ratio / sqrt(c)``, ``c`` the conditioning of the actuation at the export pose
    (:attr:`Tree.conditioning`, at most 1). Along the platform direction where an actuator motion
    ``c`` moves the platform by 1 the servos act as a spring ``c^2 kp`` and a damper ``c^2 kv``, so
    a poorly conditioned design needs more damping for that slowest direction to settle; dividing
    by ``sqrt(c)`` rather than ``c`` is a compromise (too much joint-level damping beside the soft
    closures makes MuJoCo's step unstable) that the settling test checks on every shipped design
    (``c`` from 0.016 to 0.69); ``c`` is taken at least :data:`MIN_CONDITIONING`.
    The armature keeps the joint-level motion of the stiff servos slow beside the closures'
    constraint dynamics (without it the light limb bodies make the simulation unstable).
    Crank (hinge) values are multiplied by the length scale squared (N m/rad, kg m^2)."""
    M = max(moving_mass(tree), 1e-6)
    w = 2 * math.pi * frequency
    zeta = damping_ratio / math.sqrt(max(tree.conditioning, MIN_CONDITIONING))
    out = {}
    for act, jname in tree.actuators.items():
        s = tree.length_scale**2 if tree.joints[jname].kind == "hinge" else 1.0
        inertia = 2 * M * s
        kp = inertia * w * w
        out[act] = (kp, 2 * zeta * math.sqrt(kp * inertia), M * s)
    return out


def write_mjcf(tree: Tree, path, *, timestep=None, gravity=None, servo_frequency=None,
               servo_damping_ratio=None) -> Path:
    """Write ``tree`` as an MJCF file at ``path``; returns the path. Options default to
    :data:`DEFAULTS`."""
    o = dict(DEFAULTS)
    for k, v in (("timestep", timestep), ("gravity", gravity), ("servo_frequency", servo_frequency),
                 ("servo_damping_ratio", servo_damping_ratio)):
        if v is not None:
            o[k] = v
    root = ET.Element("mujoco", model=tree.mechanism)
    pose = ", ".join(f"{c}={v:.12g}" for c, v in zip(tree.task_coordinates, tree.pose))
    root.append(ET.Comment(f" parasynth export of {tree.mechanism} at the pose {pose} (SI: m, rad). "
                           f"Joint positions are parasynth's actuator values and passive joint angles "
                           f"(docs/export.md). "))
    # Every moving body at least 1 % of the moving mass, and its inertia at least that mass at half the
    # length scale: the tiny bodies between two hinges (a universal joint's end) would otherwise make the
    # closures soft, their constraint's regularisation growing with the inverse of the body's inertia.
    m_min = 0.01 * moving_mass(tree)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true", boundmass=_f(m_min),
                  boundinertia=_f(m_min * (0.5 * tree.length_scale) ** 2))
    opt = ET.SubElement(root, "option", timestep=_f(o["timestep"]), gravity=_vec(o["gravity"]),
                        integrator="implicitfast", solver="Newton", iterations="200", tolerance="1e-12")
    ET.SubElement(opt, "flag", contact="disable")
    dflt = ET.SubElement(root, "default")
    ET.SubElement(dflt, "geom", contype="0", conaffinity="0", density=_f(STEEL_DENSITY), rgba="0.6 0.65 0.7 1")
    tc = o["equality_timeconst_steps"] * o["timestep"]
    d = o["equality_impedance"]
    ET.SubElement(dflt, "equality", solref=f"{_f(tc)} 1", solimp=f"{_f(d)} {_f(d)} 0.001 0.5 2")
    ET.SubElement(dflt, "site", size=_f(0.01 * tree.length_scale), rgba="0.9 0.4 0.1 1")
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "site", name="base", pos="0 0 0")
    elems = {}
    gains = servo_gains(tree, o["servo_frequency"], o["servo_damping_ratio"])
    armature = {tree.actuators[a]: g[2] for a, g in gains.items()}
    for b in tree.bodies:
        parent = world if b.parent is None else elems[b.parent]
        el = ET.SubElement(parent, "body", name=b.name, pos=_vec(b.pos), quat=_quat(b.rot))
        elems[b.name] = el
        if b.free:
            ET.SubElement(el, "freejoint", name=b.name)
        for j in b.joints:
            attrs = {"name": j.name}
            if j.kind == "ball":
                attrs["type"] = "ball"
            else:
                attrs.update(type=j.kind, axis=_vec(j.axis), ref=_f(j.ref))
                if j.range is not None:
                    attrs["range"] = _vec(_finite_range(j, tree.length_scale))
                if j.name in armature:
                    attrs["armature"] = _f(armature[j.name])
            ET.SubElement(el, "joint", **attrs)
        for g in b.geoms:
            if g.kind == "capsule":
                ET.SubElement(el, "geom", type="capsule", fromto=f"{_vec(g.a)} {_vec(g.b)}", size=_f(g.radius))
            else:
                ET.SubElement(el, "geom", type="sphere", pos=_vec(g.a), size=_f(g.radius))
        for s in b.sites:
            ET.SubElement(el, "site", name=s.name, pos=_vec(s.pos), quat=_quat(s.rot))
    eq = ET.SubElement(root, "equality")
    for c in tree.closures:
        ET.SubElement(eq, "connect" if c.kind == "3D" else "weld", name=c.name, site1=c.site1, site2=c.site2)
    for jname in tree.hold_joints:
        # Under-actuated: a passive joint of a constraining leg can be held (Tree.hold_joints). MuJoCo's
        # joint equality holds qpos - qpos0 at polycoef[0]: 0 holds the export pose's value; inactive,
        # it changes nothing.
        # A hold as stiff as the closures made the step unstable: it acts like a stiff servo instead.
        ET.SubElement(eq, "joint", name=f"hold_{jname}", joint1=jname, polycoef="0 0 0 0 0", active="false",
                      solref=f"{_f(o['hold_timeconst_steps'] * o['timestep'])} 1")
    act = ET.SubElement(root, "actuator")
    for name, jname in tree.actuators.items():
        j = tree.joints[jname]
        kp, kv, _ = gains[name]
        attrs = {"name": name, "joint": jname, "kp": _f(kp), "kv": _f(kv)}
        if j.range is not None and all(np.isfinite(j.range)):
            attrs["ctrlrange"] = _vec(j.range)
        ET.SubElement(act, "position", **attrs)
    _keyframe(root, tree)
    if tree.not_exported:
        root.append(ET.Comment(" description constraints not written as joint ranges: "
                               + "; ".join(s.replace("--", "- -") for s in tree.not_exported) + " "))
    ET.indent(root)
    path = Path(path)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
    return path


#: Name of the keyframe at the export pose (:func:`write_mjcf`).
KEYFRAME = "export_pose"


def keyframe_values(tree: Tree) -> tuple[np.ndarray, np.ndarray]:
    """``qpos`` and ``ctrl`` of the model written from ``tree`` at its export pose, in MuJoCo's
    order: joints in the order of the bodies in the file (the platform's free joint first: its
    position and quaternion w x y z; a kept ball joint the identity quaternion; a slide or hinge
    its ``ref``, parasynth's value at the export pose), and one control per actuator, the
    actuator's value at the export pose (what the position servos must be told to hold it)."""
    qpos = []
    for b in tree.bodies:
        if b.free:
            qpos += [*b.pos, *wxyz(np.asarray(b.rot, dtype=float).reshape(3, 3))]
        for j in b.joints:
            qpos += [1.0, 0.0, 0.0, 0.0] if j.kind == "ball" else [j.ref]
    ctrl = [tree.joints[jname].ref for jname in tree.actuators.values()]
    return np.array(qpos, dtype=float), np.array(ctrl, dtype=float)


def _keyframe(root, tree: Tree) -> None:
    qpos, ctrl = keyframe_values(tree)
    root.append(ET.Comment(f" keyframe {KEYFRAME}: the export pose, its servo targets the actuator values there "
                           f"(mj_resetDataKeyframe(model, data, 0) loads it; without it ctrl is 0 and the servos "
                           f"drive the actuators to 0) "))
    key = ET.SubElement(ET.SubElement(root, "keyframe"), "key", name=KEYFRAME, qpos=_vec(qpos))
    if len(ctrl):
        key.set("ctrl", _vec(ctrl))


def _finite_range(j, length_scale: float) -> tuple:
    """A joint range with an open side closed far outside the motion: +-pi for a hinge, 0 and
    100 length scales for a slide (MuJoCo needs both ends)."""
    lo, hi = j.range
    if j.kind == "hinge":
        return (lo if np.isfinite(lo) else -math.pi, hi if np.isfinite(hi) else math.pi)
    return (lo if np.isfinite(lo) else 0.0, hi if np.isfinite(hi) else 100.0 * length_scale)
