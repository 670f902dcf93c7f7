"""The kinematic tree of a described mechanism, as the MJCF and URDF writers need it.

A parallel mechanism is cut into a spanning tree: the base, the platform on a free joint, and
every leg as a serial chain of bodies from the base; each leg's loop is closed at the platform
by a *closure* between a frame at the end of the chain and a frame on the platform:

* a leg that ends in a spherical joint (SPS, UPS, PUS, RPS, PRS, RUS) is closed by a 3-D
  closure (the two points coincide: the closure *is* the spherical joint);
* a leg that ends in a universal joint (RPU, UPU) keeps both hinges of that joint in its chain
  and is closed by a 6-D closure (the end body is rigidly fixed to the platform).

Bodies, joints and joint values
-------------------------------
Every leg body has a frame whose orientation is the base frame's at the mechanism's **home
pose**: at a pose ``X`` the body's frame is rotated by ``G(X)``, its rotation from home
(``G(home) = I``). The platform body's frame is the platform frame (origin the platform
reference point ``P``, orientation ``R``). The tree is *written* at the export pose ``Xe``:
body positions and orientations relative to their parents, and every joint axis in its body's
frame, are those of ``Xe``.

Joint values (:func:`joint_values`) follow parasynth's conventions, so that a simulator's joint
positions read as parasynth's numbers:

* an actuated joint's value is the actuator value (leg length or slider position in m, crank
  angle in rad), a passive prismatic joint's the leg length (m);
* a hinge's value is the passive joint angle of the inverse kinematics where parasynth names one
  (``R_base``, ``U_base_1``, ``U_base_2``, ``U_platform_1``); the hinges it does not name (the
  platform-side hinge of an RPU's universal joint, both platform hinges of a UPU, the universal
  joint at a crank tip) get their angle from the leg states of the inverse kinematics, measured
  from the home pose like the named ones;
* a spherical joint that the tree keeps (the base joint of an SPS leg) has the rotation of its
  body relative to its parent from home as value; the spin of the leg about its own line, a
  freedom that does not move the platform, is taken as zero (the body turns by the smallest
  rotation that takes the leg's home direction to its direction at the pose).

Hinge angles are only defined up to the additive constant of their zero: the simulator sees the
difference from the export pose, so any consistent zero gives the same geometry.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from ..model.constraints import ActuatorRange, JointAngleLimit, LegInterference, LegLengthRange
from ..model.legs import LEG_TYPES, PRS, PUS, RPS, RPU, RUS, SPS, UPS, UPU, Leg, LegState, require, types_with
# The universal-joint angles of a direction about a fixed axis, as the legs define them.
from ..model.legs import _u_angles
from ..model.spatial import reciprocal_basis, rot_axis, unit

__all__ = ["JointSpec", "GeomSpec", "SiteSpec", "BodySpec", "Closure", "Tree", "build_tree", "joint_values",
           "ExportError", "SUPPORTED_LEGS"]

#: Leg types the exporter knows (joints base to platform): those that declare the ``export``
#: capability (:data:`parasynth.model.legs.CAPABILITIES`).
SUPPORTED_LEGS = types_with("export")
#: Density (kg/m^3) of every exported body: structural steel, an assumption (the descriptions
#: carry no masses). Masses only matter for simulation, never for the kinematic checks.
STEEL_DENSITY = 7850.0


class ExportError(ValueError):
    """A mechanism or pose the exporter cannot write (the message names what and why)."""


@dataclass(frozen=True)
class JointSpec:
    """One joint of a body: ``kind`` "slide", "hinge" or "ball"; ``axis`` (slide, hinge) in the
    body frame at the export pose; ``ref`` its value there; ``range`` (lo, hi) from the
    description's limits or None; ``actuator`` the actuator name (``q1``, ``s2``, ...) of an
    actuated joint, else None; ``source`` where its value comes from (an IK angle, the
    actuator, the leg state) and ``limit_names`` the description's constraints behind ``range``,
    for a reader of the tree."""

    name: str
    kind: str
    axis: tuple = (0.0, 0.0, 1.0)
    ref: float = 0.0
    range: tuple | None = None
    actuator: str | None = None
    source: str = ""
    limit_names: tuple = ()


@dataclass(frozen=True)
class GeomSpec:
    """A primitive: ``kind`` "capsule" (``a`` -> ``b``, ``radius``) or "sphere" (at ``a``), in
    the body frame."""

    kind: str
    a: tuple
    b: tuple | None
    radius: float
    role: str = ""


@dataclass(frozen=True)
class SiteSpec:
    """A named frame on a body: position and rotation (3x3, row-major tuple) in the body frame."""

    name: str
    pos: tuple
    rot: tuple


@dataclass(frozen=True)
class BodySpec:
    """A body of the tree: ``parent`` (None: the base), ``pos``/``rot`` relative to the parent
    at the export pose, its joints (applied in order), geometry and sites. ``leg`` names the leg
    it belongs to ("" for the base and the platform)."""

    name: str
    parent: str | None
    pos: tuple
    rot: tuple
    joints: tuple = ()
    geoms: tuple = ()
    sites: tuple = ()
    leg: str = ""
    free: bool = False


@dataclass(frozen=True)
class Closure:
    """The loop of leg ``leg`` closed between site ``site1`` on ``body1`` (the end of the leg's
    chain) and ``site2`` on the platform: ``kind`` "3D" (the points coincide) or "6D" (the
    frames coincide)."""

    name: str
    leg: str
    kind: str
    body1: str
    site1: str
    site2: str


@dataclass(frozen=True)
class Tree:
    """The exported mechanism: bodies (parents first; the platform first, then each leg),
    closures, the actuators in the mechanism's order ({name: joint name}), the export pose and
    the constraints of the description that are not joint ranges (they are listed, not
    exported)."""

    mechanism: str
    pose: tuple
    task_coordinates: tuple
    bodies: tuple
    closures: tuple
    actuators: dict
    not_exported: tuple = ()
    hold_joints: tuple = ()
    length_scale: float = 1.0
    #: smallest singular value of the map from the platform's controlled freedoms (unit twists,
    #: rotations times the length scale) to the actuator rates at the export pose (1: as well
    #: conditioned as a direct drive; near 0: near a singularity).
    conditioning: float = 1.0

    def body(self, name: str) -> BodySpec:
        for b in self.bodies:
            if b.name == name:
                return b
        raise KeyError(name)

    @property
    def joints(self) -> dict:
        """{joint name: JointSpec} of every leg joint (the platform's free joint excluded)."""
        return {j.name: j for b in self.bodies for j in b.joints}


# -- small rotation helpers ----------------------------------------------------------------------
def _t(a) -> tuple:
    return tuple(float(x) for x in np.asarray(a, dtype=float).ravel())


def wxyz(R) -> np.ndarray:
    """Quaternions w x y z (..., 4) of rotation matrices R (..., 3, 3) (scipy's accurate method;
    its x y z w order rolled, for scipy versions without ``scalar_first``)."""
    return Rotation.from_matrix(R).as_quat()[..., [3, 0, 1, 2]]


def _angle_about(axis, a, b) -> np.ndarray:
    """Signed angle (N,) about unit ``axis`` from vector ``a`` to vector ``b`` (both projected
    on the plane normal to the axis)."""
    axis = np.broadcast_to(axis, np.broadcast_shapes(np.shape(axis), np.shape(a), np.shape(b)))
    a = a - np.sum(a * axis, -1, keepdims=True) * axis
    b = b - np.sum(b * axis, -1, keepdims=True) * axis
    return np.arctan2(np.sum(np.cross(a, b) * axis, -1), np.sum(a * b, -1))


def _any_normal(v: np.ndarray) -> np.ndarray:
    """A unit vector normal to the unit vector ``v`` (3,)."""
    t = np.array([1.0, 0, 0]) if abs(v[0]) < 0.9 else np.array([0, 1.0, 0])
    return unit(np.cross(v, t))


def _rotation_about(axis: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Angle (N,) of rotations ``M`` (N, 3, 3) about the fixed unit ``axis`` (3,) (``M`` is
    assumed to be such a rotation)."""
    v = _any_normal(axis)
    return _angle_about(axis, v, M @ v)


def _min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotations (N, 3, 3) taking unit vector ``a`` (3,) to unit vectors ``b``
    (N, 3)."""
    ax = np.cross(a, b)
    s = np.linalg.norm(ax, axis=-1)
    c = b @ a
    ang = np.arctan2(s, c)
    fallback = _any_normal(a)
    ax = np.where(s[:, None] > 1e-12, ax / np.maximum(s, 1e-300)[:, None], fallback)
    return rot_axis(ax, ang)


def _u_rotation(a1: np.ndarray, n_home: np.ndarray, th1: np.ndarray, th2: np.ndarray) -> np.ndarray:
    """Rotation from home (N, 3, 3) of the body after a universal joint whose first axis ``a1``
    is fixed in the parent and whose link lies along ``n_home`` at home: ``Rot(a1, th1)
    Rot(k, th2)`` with the cross axis ``k = n_home x a1`` (a positive ``th2`` tilts the link
    towards ``+a1``, as ``U_base_2`` counts)."""
    return rot_axis(a1, th1) @ rot_axis(_cross_axis(a1, n_home), th2)


def _cross_axis(a1: np.ndarray, n_home: np.ndarray) -> np.ndarray:
    """The cross axis of a universal joint at home, ``n_home x a1`` (unit)."""
    return unit(np.cross(n_home, a1))


# -- one leg as a chain --------------------------------------------------------------------------
@dataclass
class _Body:
    """A leg body at N poses: origin ``c`` (N, 3), rotation from home ``G`` (N, 3, 3) and its
    joints ``(suffix, kind, world axis (N, 3) or None, value (N,) or rotation (N, 3, 3), actuated,
    source)``."""

    suffix: str
    c: np.ndarray
    G: np.ndarray
    joints: list
    geoms: list = field(default_factory=list)


def _chain(leg: Leg, st: LegState, R: np.ndarray, R_home: np.ndarray, act_home: float):
    """The bodies of ``leg`` at N poses (its states ``st``, platform rotations ``R``), and the
    kind of its closure ("3D" or "6D"). ``act_home`` is the leg's actuator value at home."""
    N = st.length.shape[0]
    t = LEG_TYPES[leg.joints]  # the registered leg type (its capabilities were checked)
    n, n_h = st.direction, leg.base_ref
    B, A = st.base_point, st.platform_point
    ang = st.angles
    act = leg.is_actuated
    I3 = np.broadcast_to(np.eye(3), (N, 3, 3))

    def axis(v):
        return np.broadcast_to(np.asarray(v, float), (N, 3))

    def base_u(a1):
        G = _u_rotation(a1, n_h, ang["U_base_1"], ang["U_base_2"])
        joints = [("U1", "hinge", axis(a1), ang["U_base_1"], False, f"{leg.name}.U_base_1"),
                  ("U2", "hinge", G @ _cross_axis(a1, n_h), ang["U_base_2"], False, f"{leg.name}.U_base_2")]
        return G, joints

    def telescope(G, lead_joints, lead):
        src = "actuator" if act else "leg length"
        return [_Body(lead, B, G, lead_joints),
                _Body("rod", A, G, [("P", "slide", n, st.length, act, src)])]

    if t is SPS:
        G = _min_rotation(n_h, n)
        bodies = telescope(G, [("S", "ball", None, G, False, "smallest rotation from the home direction")], "cyl")
        return bodies, "3D"
    if t is UPS:
        G, joints = base_u(leg.u_axis)
        return telescope(G, joints, "cyl"), "3D"
    if t is RPS:
        G = rot_axis(leg.r_axis, ang["R_base"])
        return telescope(G, [("R", "hinge", axis(leg.r_axis), ang["R_base"], False, f"{leg.name}.R_base")], "cyl"), "3D"
    if t is PUS:
        G, joints = base_u(leg.u_axis)
        return [_Body("slider", B, I3, [("P", "slide", axis(leg.slider_axis), st.actuator, True, "actuator")]),
                _Body("link", B, G, joints)], "3D"
    if t is PRS:
        G = rot_axis(leg.r_axis, ang["R_base"])
        return [_Body("slider", B, I3, [("P", "slide", axis(leg.slider_axis), st.actuator, True, "actuator")]),
                _Body("link", B, G, [("R", "hinge", axis(leg.r_axis), ang["R_base"], False, f"{leg.name}.R_base")])], "3D"
    if t is RUS:
        a = leg.r_axis
        Gc = rot_axis(a, st.actuator - act_home)
        n_loc = np.einsum("nji,nj->ni", Gc, n)  # the link direction in the crank's home frame
        u = _u_angles(a, n_h, n_loc, "U")
        G = Gc @ _u_rotation(a, n_h, u["U_1"], u["U_2"])
        return [_Body("crank", np.broadcast_to(leg.base, (N, 3)), Gc,
                      [("R", "hinge", axis(a), st.actuator, True, "actuator")]),
                _Body("link", B, G, [("U1", "hinge", axis(a), u["U_1"], False, "leg state (crank-tip U, axis 1)"),
                                     ("U2", "hinge", G @ _cross_axis(a, n_h), u["U_2"], False,
                                      "leg state (crank-tip U, axis 2)")])], "3D"
    G_end = R @ R_home.T
    a4_h = R_home @ leg.u_platform_axis
    a4 = R @ leg.u_platform_axis
    if t is RPU:
        r = leg.r_axis
        G = rot_axis(r, ang["R_base"])
        th1 = ang["U_platform_1"]
        M = np.swapaxes(G @ rot_axis(r, th1 - _rpu_u1_home(leg, R_home)), -1, -2) @ G_end
        th2 = _rotation_about(a4_h, M)
        bodies = telescope(G, [("R", "hinge", axis(r), ang["R_base"], False, f"{leg.name}.R_base")], "cyl")
        bodies.append(_Body("end", A, G_end, [("U1", "hinge", axis(r), th1, False, f"{leg.name}.U_platform_1"),
                                              ("U2", "hinge", a4, th2, False, "leg state (platform U, axis 2)")]))
        return bodies, "6D"
    if t is UPU:
        G, joints = base_u(leg.u_axis)
        a3_h = unit(np.cross(a4_h, n_h))
        M = np.swapaxes(G, -1, -2) @ G_end
        th3 = _angle_about(a3_h, a4_h, M @ a4_h)
        th4 = _rotation_about(a4_h, np.swapaxes(rot_axis(a3_h, th3), -1, -2) @ M)
        bodies = telescope(G, joints, "cyl")
        bodies.append(_Body("end", A, G_end, [("U3", "hinge", G @ a3_h, th3, False,
                                               "leg state (platform U, axis 1)"),
                                              ("U4", "hinge", a4, th4, False, "leg state (platform U, axis 2)")]))
        return bodies, "6D"
    raise ExportError(f"leg {leg.name}: the exporter does not know the leg type {type(leg).__name__} "
                      f"(joints {t!r}); it writes {', '.join(SUPPORTED_LEGS)}")


def _rpu_u1_home(leg, R_home) -> float:
    """``U_platform_1`` of an RPU leg at home (its angle is not zero there in general)."""
    n = leg.base_ref
    a4 = R_home @ leg.u_platform_axis
    return float(np.arctan2(np.cross(n, a4) @ leg.r_axis, n @ a4) - np.pi / 2)


# -- the tree -----------------------------------------------------------------------------------
def _states(mech, X):
    """Leg states, platform position and rotation at poses X (N, n_task); ExportError naming
    the first unreachable pose and leg."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    Xa, states, p = mech.leg_states(X)
    _, R = mech.pose(Xa)
    R = np.asarray(R).reshape(-1, 3, 3)
    for leg, st in zip(mech.legs, states):
        bad = np.flatnonzero(~st.reachable)
        if bad.size:
            raise ExportError(f"{mech.name}: pose {Xa[bad[0]].tolist()} is not reachable by leg {leg.name} "
                              f"({leg.joints}); give a reachable pose (task coordinates "
                              f"{', '.join(mech.task_coordinates)}, SI)")
    return Xa, states, np.asarray(p).reshape(-1, 3), R


def _home_actuators(mech) -> list[float]:
    _, states, _ = mech.leg_states(mech.home[None, :])
    return [float(st.actuator[0]) for st in states]


def _chains(mech, X):
    Xa, states, p, R = _states(mech, X)
    _, R_home = mech.pose(mech.home)
    homes = _home_actuators(mech)
    return Xa, p, R, [(leg, st, *_chain(leg, st, R, np.asarray(R_home), h))
                      for leg, st, h in zip(mech.legs, states, homes)]


def joint_values(mech, X) -> dict:
    """{joint name: values} at poses ``X`` (N, n_task) or (n_task,), in parasynth's conventions
    (see the module docstring): slides and hinges (N,) (m, rad), the kept spherical joints as
    rotations from home relative to their parent (N, 3, 3), and ``"platform"`` as (N, 4, 4)
    homogeneous transforms of the platform frame. A single pose gives arrays without the leading
    axis."""
    single = np.ndim(X) == 1
    _, p, R, chains = _chains(mech, X)
    out = {}
    for leg, _, bodies, _ in chains:
        parent_G = None
        for b in bodies:
            for suffix, kind, _, value, _, _ in b.joints:
                if kind == "ball":
                    rel = value if parent_G is None else np.swapaxes(parent_G, -1, -2) @ value
                    out[f"{leg.name}_{suffix}"] = rel
                else:
                    out[f"{leg.name}_{suffix}"] = np.asarray(value, dtype=float)
            parent_G = b.G
    T = np.zeros((p.shape[0], 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = R, p, 1.0
    out["platform"] = T
    if single:
        out = {k: v[0] for k, v in out.items()}
    return out


def _leg_diameters(mech) -> dict:
    """Diameter (m) of each leg's links: the description's stiffness diameter, else the
    diameter of an interference constraint naming the leg, else 2 % of the length scale."""
    out = {}
    declared = getattr(mech, "declared_stiffness", {}) or {}
    inter = [c for c in mech.constraints.values() if isinstance(c, LegInterference) and c.diameter > 0]
    for leg in mech.legs:
        d = (declared.get(leg.name) or {}).get("diameter")
        if d is None:
            for c in inter:
                names = set(c.legs) | {n for pair in c.pairs for n in pair}
                if not names or leg.name in names:
                    d = c.diameter
                    break
        out[leg.name] = float(d) if d else 0.02 * mech.length_scale
    return out


def _ranges(mech):
    """Joint ranges from the description's limits: {(leg, joint suffix): (lo, hi, [constraint
    names])}, and the names of the constraints that are not joint ranges."""
    out, skipped = {}, []
    keys = {"R_base": "R", "U_base_1": "U1", "U_base_2": "U2", "U_platform_1": "U1"}

    def put(leg, suffix, lo, hi, name):
        old = out.get((leg, suffix))
        if old is not None:
            lo, hi, names = max(lo, old[0]), min(hi, old[1]), old[2] + [name]
        else:
            names = [name]
        out[(leg, suffix)] = (lo, hi, names)

    for c in mech.constraints.values():
        if isinstance(c, ActuatorRange):
            for leg in mech.legs:
                if leg.is_actuated:
                    put(leg.name, "R" if leg.actuator_kind == "angle" else "P", c.lo, c.hi, c.name)
        elif isinstance(c, LegLengthRange):
            for leg in mech.legs:
                if leg.name in c.legs and isinstance(leg, (SPS, UPS, RPS, RPU, UPU)):
                    put(leg.name, "P", c.lo, c.hi, c.name)
        elif isinstance(c, JointAngleLimit) and c.key in keys:
            for leg in mech.legs:
                has = (c.key == "R_base" and isinstance(leg, (RPS, RPU, PRS))) or \
                      (c.key in ("U_base_1", "U_base_2") and isinstance(leg, (UPS, PUS, UPU))) or \
                      (c.key == "U_platform_1" and isinstance(leg, RPU))
                if has and (not c.legs or leg.name in c.legs):
                    put(leg.name, keys[c.key], c.lo, c.hi, c.name)
        else:
            skipped.append(f"{c.name} ({type(c).__name__}): {c.doc}" if c.doc else f"{c.name} ({type(c).__name__})")
    return out, tuple(skipped)


def build_tree(mech, pose=None) -> Tree:
    """The kinematic tree of ``mech`` written at ``pose`` (task coordinates, SI; default home).
    ``ExportError`` for an unreachable pose or a leg type the exporter does not know."""
    Xe = np.asarray(mech.home if pose is None else pose, dtype=float)
    if Xe.shape != (mech.n_task,):
        raise ExportError(f"{mech.name}: pose must have {mech.n_task} task coordinates "
                          f"({', '.join(mech.task_coordinates)}, SI), got shape {Xe.shape}")
    for leg in mech.legs:
        require(leg, "export", ExportError)
    _, p, R, chains = _chains(mech, Xe[None, :])
    p, R = p[0], R[0]
    diam = _leg_diameters(mech)
    ranges, skipped = _ranges(mech)
    actuator_of = dict(zip([leg.name for leg in mech.legs if leg.is_actuated], mech.actuators))
    plat_sites = [SiteSpec("platform", (0.0, 0.0, 0.0), _t(np.eye(3)))]
    plat_geoms = [GeomSpec("sphere", (0.0, 0.0, 0.0), None, 0.75 * max(diam.values()), "platform")]
    bodies, closures, actuators = [], [], {}
    for leg, st, chain, kind in chains:
        d = diam[leg.name]
        Ge_parent, c_parent, parent = np.eye(3), np.zeros(3), None
        for b in chain:
            G, c = b.G[0], b.c[0]
            rel = Ge_parent.T @ G
            pos = Ge_parent.T @ (c - c_parent)
            joints = []
            for suffix, jk, w, value, actuated, source in b.joints:
                name = f"{leg.name}_{suffix}"
                ax = (0.0, 0.0, 1.0) if w is None else _t(unit(G.T @ w[0]))
                ref = 0.0 if jk == "ball" else float(value[0])
                rng = ranges.get((leg.name, suffix))
                if rng is not None and not (np.isfinite(rng[0]) or np.isfinite(rng[1])):
                    rng = None
                act = actuator_of[leg.name] if actuated else None
                if act is not None:
                    actuators[act] = name
                joints.append(JointSpec(name, jk, ax, ref, None if rng is None else (float(rng[0]), float(rng[1])),
                                        act, source, tuple(rng[2]) if rng else ()))
            geoms = _geoms(leg, b.suffix, st, G, c, d)
            bodies.append(BodySpec(f"{leg.name}_{b.suffix}", parent, _t(pos), _t(rel), tuple(joints), tuple(geoms),
                                   (), leg.name))
            Ge_parent, c_parent, parent = G, c, f"{leg.name}_{b.suffix}"
        # The closure: a site at the platform anchor on the last body, and one on the platform.
        last = bodies[-1]
        A = st.platform_point[0]
        s1 = SiteSpec(f"{leg.name}_tip", _t(Ge_parent.T @ (A - c_parent)), _t(Ge_parent.T @ R))
        bodies[-1] = BodySpec(last.name, last.parent, last.pos, last.rot, last.joints, last.geoms, (s1,), last.leg)
        plat_sites.append(SiteSpec(f"platform_{leg.name}", _t(leg.platform), _t(np.eye(3))))
        if np.linalg.norm(leg.platform) > 1e-6 * mech.length_scale:  # a spoke to the anchor
            plat_geoms.append(GeomSpec("capsule", (0.0, 0.0, 0.0), _t(leg.platform), 0.5 * d, "platform"))
        closures.append(Closure(f"close_{leg.name}", leg.name, kind, last.name, s1.name, f"platform_{leg.name}"))
    platform = BodySpec("platform", None, _t(p), _t(R), (), tuple(plat_geoms), tuple(plat_sites), "", free=True)
    mob = mech.mobility(Xe, warn=False) if hasattr(mech, "description") else mech.mobility(Xe)
    holds = () if mob.controlled else _hold_joints(mech, Xe, chains, len(mob.uncontrolled_twists) or 1)
    return Tree(mech.name, _t(Xe), tuple(mech.task_coordinates), (platform, *bodies), tuple(closures),
                {a: actuators[a] for a in mech.actuators}, skipped, holds, float(mech.length_scale),
                _conditioning(mech, Xe, mob))


def _wrench_sigma(mech, states, p, held: set) -> float:
    """Smallest of the 6 singular values of the unit actuation wrenches and of every leg's
    reciprocal wrenches with the joint freedoms in ``held`` ({(leg index, twist index)}) locked
    (moments over the length scale); 0 when the rows span fewer than 6 directions."""
    L = mech.length_scale
    rows = [leg.actuation_wrench(st, p)[0][0] for leg, st in zip(mech.legs, states) if leg.is_actuated]
    for i, (leg, st) in enumerate(zip(mech.legs, states)):
        T = leg.joint_twists(st, p)
        keep = [k for k in range(T.shape[1]) if (i, k) not in held]
        rows += list(reciprocal_basis(T[:, keep], L)[0])
    W = np.array(rows, dtype=float)
    W[:, 3:] /= L
    W /= np.linalg.norm(W, axis=1, keepdims=True)
    s = np.linalg.svd(W, compute_uv=False)
    return float(s[5]) if s.size >= 6 else 0.0


def _hold_joints(mech, X, chains, count: int) -> tuple:
    """The passive joints of the constraining (unactuated) legs to hold for an under-actuated
    mechanism: ``count`` of them, chosen one at a time as the joint whose locking leaves the
    best-conditioned wrench system at pose X (largest 6th singular value of
    :func:`_wrench_sigma`). For the 4-UPS/1-RPS this is the revolute joint of the RPS leg: its
    prismatic joint, held, adds a force nearly along the leg line, which the uncontrolled rotation
    does almost no work on."""
    _, states, p = mech.leg_states(X[None, :])
    candidates = []
    for i, (leg, _, bodies, _) in enumerate(chains):
        if leg.is_actuated:
            continue
        k = 0
        for b in bodies:
            for suffix, kind, *_ in b.joints:
                if kind != "ball":
                    candidates.append((f"{leg.name}_{suffix}", (i, k)))
                k += 3 if kind == "ball" else 1
    held, names = set(), []
    for _ in range(min(count, len(candidates))):
        best = max((c for c in candidates if c[1] not in held),
                   key=lambda c: _wrench_sigma(mech, states, p, held | {c[1]}))
        held.add(best[1])
        names.append(best[0])
    return tuple(names)


def _conditioning(mech, X, mob) -> float:
    """The ``k``-th largest singular value, ``k = min(actuators, freedoms)``, of the actuator rates
    per unit platform motion along the freedoms ``mob.twist_basis`` at pose X (wrench moments over
    the length scale, twist rotations times it, crank rates times it), capped at 1: 0 at a
    singularity, small near one."""
    L = mech.length_scale
    W = mech.wrench_matrix(X[None, :])[0][: mech.n_actuators].copy()
    _, states, _ = mech.leg_states(X[None, :])
    # Rates of crank angles (rad) times the length scale, so that every actuator counts in m.
    scale = np.array([float(leg.actuation_wrench(st, st.platform_point)[1][0]) / (L if leg.actuator_kind == "angle" else 1.0)
                      for leg, st in zip(mech.legs, states) if leg.is_actuated])
    W[:, 3:] /= L
    T = mob.twist_basis.copy()
    T[:, 3:] *= L
    s = np.linalg.svd((W / np.abs(scale)[:, None]) @ T.T, compute_uv=False)
    k = min(mech.n_actuators, T.shape[0])
    return float(min(1.0, s[k - 1])) if k else 1.0


def _geoms(leg, suffix, st, G, c, d) -> list:
    """Capsules and spheres of a leg body (body frame), radius from the leg diameter ``d``."""
    r = 0.5 * d
    Gt = G.T
    B, A = st.base_point[0], st.platform_point[0]
    L = float(np.linalg.norm(A - B))
    n_loc = Gt @ st.direction[0]
    z = (0.0, 0.0, 0.0)
    if suffix == "cyl":  # the outer tube of a telescopic leg, from the base joint
        return [GeomSpec("capsule", z, _t(0.55 * L * n_loc), 1.3 * r, "tube")]
    if suffix == "rod":  # the inner rod, back from the platform joint
        return [GeomSpec("capsule", z, _t(-0.55 * L * n_loc), r, "rod")]
    if suffix == "link":
        return [GeomSpec("capsule", z, _t(Gt @ (A - B)), r, "link")]
    if suffix == "slider":
        return [GeomSpec("sphere", z, None, 1.5 * r, "slider")]
    if suffix == "crank":
        return [GeomSpec("capsule", z, _t(Gt @ (B - c)), r, "crank")]
    return [GeomSpec("sphere", z, None, 1.2 * r, "joint")]
