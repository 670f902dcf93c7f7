"""Leg types: inverse kinematics, passive joint angles, joint twists, actuation and constraint
wrenches, vectorised over N platform poses.

A leg joins a base anchor to a platform anchor through a chain of joints named base to
platform (``"UPS"`` = universal at the base, prismatic, spherical at the platform). Each leg
knows

* ``solve(p, R)``: its inverse kinematics for platform positions ``p`` (N, 3) and orientations
  ``R`` (N, 3, 3): the actuator value, reachability, joint centres and passive angles;
* ``joint_twists(state, P)``: the unit twists of all its joint freedoms at the current pose,
  taken at the platform reference point ``P`` -- the leg's twist system;
* ``actuation_wrench(state, P)``: the wrench it transmits through its actuated joint (a unit
  force along the line of the leg, reciprocal to every passive joint) and ``rate_scale`` such
  that ``actuator_rate = (wrench @ twist) / rate_scale``;
* ``constraint_wrenches(state, P)``: the wrenches reciprocal to all its joint twists.

Angles are radians and lengths metres; see :mod:`parasynth.model.spatial` for the twist/wrench
ordering.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .spatial import couple_wrench, cross, dot_rows, force_wrench, null_direction, prismatic_twist, revolute_twist, rotate_rows, unit

__all__ = [
    "Leg",
    "LegState",
    "SPS",
    "UPS",
    "PUS",
    "RPU",
    "RPS",
    "UPU",
    "RUS",
    "LEG_TYPES",
    "JOINT_DOF",
    "CAPABILITIES",
    "LegCapabilities",
    "LegCapabilityError",
    "capabilities_of",
    "supports",
    "types_with",
    "require",
    "unsupported_message",
]

#: Freedoms of each joint letter.
JOINT_DOF = {"R": 1, "P": 1, "U": 2, "S": 3, "C": 2}

#: Tolerance (m, or dimensionless for unit vectors) on the geometric conditions a pose must
#: satisfy for legs with planar or fixed-axis joints (RPU, RPS).
GEOM_TOL = 1e-9


def _label(name) -> str:
    """The name an error gives: ``name``, or for a pair (leg name, field) "leg <leg>: <field>"
    (the pair is made per check, the text only for an error)."""
    return f"leg {name[0]}: {name[1]}" if isinstance(name, tuple) else name


def _vec3_xyz(name, v):
    """``v`` as a float 3-vector and its three entries as Python floats; ``ValueError`` naming
    ``name`` (a text, or a pair (leg name, field): :func:`_label`) unless it is a finite 3-vector."""
    a = np.asarray(v, dtype=float)
    if a.shape != (3,):
        raise ValueError(f"{_label(name)} must be a 3-vector, got shape {a.shape}")
    x, y, z = a.tolist()  # three floats: math is ten times cheaper than NumPy's reductions here
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise ValueError(f"{_label(name)} must be finite, got {a.tolist()}")
    return a, x, y, z


def _vec3(name, v) -> np.ndarray:
    return _vec3_xyz(name, v)[0]


def _axis(name, v) -> np.ndarray:
    _, x, y, z = _vec3_xyz(name, v)
    return _unit_xyz(name, x, y, z)


def _unit_xyz(name, x: float, y: float, z: float) -> np.ndarray:
    """The unit vector along the finite (x, y, z), as :func:`_axis` makes it."""
    n = math.sqrt(x * x + y * y + z * z)
    if n == 0:
        raise ValueError(f"{_label(name)} must be a non-zero direction")
    return np.array((x / n, y / n, z / n))  # a / n, each entry as NumPy divides it (one IEEE division)


def _at_pose(a, p, R):
    """The point ``p + R a`` of three floats ``a``, ``p`` and ``R`` (nine floats, row-major)."""
    ax, ay, az = a
    return (p[0] + (R[0] * ax + R[1] * ay + R[2] * az), p[1] + (R[3] * ax + R[4] * ay + R[5] * az),
            p[2] + (R[6] * ax + R[7] * ay + R[8] * az))


def _fixed_line(b, A):
    """The leg direction from a fixed base joint ``b`` to ``A`` and its length (floats)."""
    dx, dy, dz = A[0] - b[0], A[1] - b[1], A[2] - b[2]
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    if not length > 0:
        return None, length
    return (dx / length, dy / length, dz / length), length


def _planar_line(leg, p, R):
    """The direction of a leg from a revolute base joint (RPS, RPU) to its anchor at one pose
    (floats), None unless the anchor lies in the joint's plane (within ``GEOM_TOL``)."""
    b = leg.base.tolist()
    A = _at_pose(leg.platform.tolist(), p, R)
    n, length = _fixed_line(b, A)
    rx, ry, rz = leg.r_axis.tolist()
    off = abs((A[0] - b[0]) * rx + (A[1] - b[1]) * ry + (A[2] - b[2]) * rz)
    return n if off <= GEOM_TOL * max(1.0, length) else None


def _slider_line(leg, S, e, L):
    """The link direction of a slider leg (PUS, PRS) to the sphere ``S`` (floats), None out of reach."""
    bx, by, bz = leg.base.tolist()
    dx, dy, dz = S[0] - bx, S[1] - by, S[2] - bz
    ex, ey, ez = e
    de = dx * ex + dy * ey + dz * ez
    disc = L * L - ((dx * dx + dy * dy + dz * dz) - de * de)
    if not disc >= 0:
        return None
    s = de + leg.branch * math.sqrt(disc)
    return ((S[0] - (bx + s * ex)) / L, (S[1] - (by + s * ey)) / L, (S[2] - (bz + s * ez)) / L)


def _unit_constant(v) -> np.ndarray:
    a = np.array(v, dtype=float)
    a.flags.writeable = False
    return a


#: The default neutral directions of a leg's end joints (:class:`Leg`), shared and read-only.
_UP = _unit_constant((0.0, 0.0, 1.0))
_DOWN = _unit_constant((0.0, 0.0, -1.0))


def _angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (rad) between unit vectors along the last axis, robust near 0 and pi."""
    sin = np.linalg.norm(cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    return np.arctan2(sin, dot)


def _perp_unit(a: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Unit vector along ``a x n`` (the cross axis of a U joint with fixed axis ``a`` whose
    link lies along ``n``)."""
    return unit(cross(a, n))


#: The parts of parasynth that may support a leg type, with what each one means. A leg type
#: declares which it supports in one place, its ``capabilities`` (:class:`LegCapabilities`), and
#: every part asks it (:func:`require`) instead of keeping its own list of leg types.
CAPABILITIES = {
    "compiled": "compiled kernels (engine: indices, feasibility)",
    "closure": "compiled closure of the mechanism as built (engine: robust and as-built measures)",
    "stacked": "one geometry per pose in a compiled batch (robust measures over scatter draws)",
    "dynamics": "inverse dynamics with massive legs (measures.dynamics)",
    "accuracy": "closure residuals and error sensitivity (measures.accuracy)",
    "stiffness": "stiffness from the leg wrenches (measures.stiffness)",
    "export": "MJCF / URDF export (export.tree)",
    "view": "the report's interactive view (report.interactive)",
    "passive": "an unactuated leg in a description (a passive constraining limb)",
}


@dataclass(frozen=True)
class LegCapabilities:
    """What a leg type supports: one flag per part of :data:`CAPABILITIES` (False: the part
    refuses the leg by name, see :func:`require`)."""

    compiled: bool = False
    closure: bool = False
    stacked: bool = False
    dynamics: bool = False
    accuracy: bool = False
    stiffness: bool = False
    export: bool = False
    view: bool = False
    passive: bool = False

    def names(self) -> tuple[str, ...]:
        """The capabilities this leg type has, in the order of :data:`CAPABILITIES`."""
        return tuple(c for c in CAPABILITIES if getattr(self, c))


class LegCapabilityError(ValueError, NotImplementedError):
    """A part of parasynth asked to handle a leg type that does not declare the capability."""


def capabilities_of(leg) -> LegCapabilities:
    """The capabilities declared for the leg type of ``leg`` (a leg or a leg class). They belong
    to a joint string: a subclass that changes ``joints`` without declaring its own has none."""
    cls = leg if isinstance(leg, type) else type(leg)
    owner = next((c for c in cls.__mro__ if "capabilities" in vars(c)), None)
    if owner is None or getattr(owner, "joints", None) != getattr(cls, "joints", None):
        return LegCapabilities()
    return vars(owner)["capabilities"]


def supports(leg, capability: str) -> bool:
    """Whether ``leg`` (a leg or a leg class) declares ``capability`` (a key of :data:`CAPABILITIES`)."""
    if capability not in CAPABILITIES:
        raise ValueError(f"unknown leg capability {capability!r}; allowed: {', '.join(CAPABILITIES)}")
    return bool(getattr(capabilities_of(leg), capability))


def types_with(capability: str) -> tuple[str, ...]:
    """The names of the registered leg types (:data:`LEG_TYPES`) that declare ``capability``."""
    return tuple(name for name, cls in LEG_TYPES.items() if supports(cls, capability))


def unsupported_message(leg, capability: str) -> str:
    """``leg L1: leg type RUS does not support 'closure' (compiled closure ...); leg types that
    do: SPS, UPS, ...`` -- the one wording every part uses to refuse a leg."""
    cls = leg if isinstance(leg, type) else type(leg)
    who = "" if isinstance(leg, type) else f"leg {leg.name}: "
    name = getattr(cls, "joints", "") or cls.__name__
    return (f"{who}leg type {name} does not support {capability!r} ({CAPABILITIES[capability]}); "
            f"leg types that do: {', '.join(types_with(capability)) or 'none'}")


def require(leg, capability: str, error: type[Exception] = LegCapabilityError) -> None:
    """Raise ``error`` (default :class:`LegCapabilityError`, a ``ValueError`` and a
    ``NotImplementedError``) naming the leg, its type and ``capability`` unless ``leg`` declares it."""
    if not supports(leg, capability):
        raise error(unsupported_message(leg, capability))


def _anchor_distance(leg, A, p, R):
    """The actuator of a leg whose actuated prismatic joint spans the anchors: their distance."""
    return np.linalg.norm(A - leg.base, axis=-1)


def _slider_position(leg, A, p, R):
    """The actuator of a slider carrying a link of fixed length to the anchor ``A``: the slider
    position of the leg's assembly branch (NaN out of reach)."""
    d = A - leg.base
    de = dot_rows(d, leg.slider_axis)
    disc = leg.link_length ** 2 - (np.einsum("ij,ij->i", d, d) - de ** 2)
    return de + leg.branch * np.sqrt(np.where(disc >= 0, disc, np.nan))


@dataclass
class LegState:
    """Result of a leg's inverse kinematics for N poses.

    ``base_point`` is the centre of the first joint that moves with the leg (the universal
    joint on a slider for PUS), ``platform_point`` the platform anchor in the base frame,
    ``direction`` the unit vector base -> platform along the leg line and ``length`` the
    distance between the two. ``angles`` holds the passive joint angles (rad) by name.
    """

    actuator: np.ndarray
    reachable: np.ndarray
    base_point: np.ndarray
    platform_point: np.ndarray
    direction: np.ndarray
    length: np.ndarray
    angles: dict[str, np.ndarray] = field(default_factory=dict)
    extra: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class Leg:
    """Base class of a leg: base anchor ``base`` (base frame) and platform anchor
    ``platform`` (platform frame), both in metres.

    ``base_ref`` and ``platform_ref`` are the neutral directions of the end joints (base
    frame and platform frame respectively): the passive angles ``*_cone`` are measured
    from them. Models set them to the leg direction at their home pose unless a paper says
    otherwise.
    """

    name: str
    base: np.ndarray
    platform: np.ndarray
    base_ref: np.ndarray = field(default_factory=lambda: _UP)
    platform_ref: np.ndarray = field(default_factory=lambda: _DOWN)

    joints: ClassVar[str] = ""
    actuated: ClassVar[int | None] = 1  # index in ``joints`` of the actuated joint
    actuator_kind: ClassVar[str] = "length"
    #: Freedoms of the leg that do not move the platform (e.g. the spin of an SPS leg).
    local_dof: ClassVar[int] = 0
    #: The options a mechanism description gives a leg of this type, {field: "axis_base" |
    #: "axis_platform" | "length" | "branch"} (None: the type cannot be described), and those
    #: it must give.
    description_options: ClassVar[dict | None] = None
    required_options: ClassVar[tuple[str, ...]] = ()
    #: What the parts of parasynth support for this leg type (:data:`CAPABILITIES`).
    capabilities: ClassVar[LegCapabilities] = LegCapabilities()
    #: The kind ("length" or "angle") of each closure row beyond the actuator: one per
    #: constraint wrench, in the order of :meth:`constraint_residuals`.
    constraint_rows: ClassVar[tuple[str, ...]] = ()
    #: The fields holding a direction of the leg type, checked by :meth:`__post_init__` in this
    #: order after the anchors and neutral directions: each a finite non-zero 3-vector, kept as
    #: the unit vector along it (:func:`_axis`).
    axis_fields: ClassVar[tuple[str, ...]] = ()
    #: Whether the type's construction is :meth:`Leg.__post_init__` alone: the anchors and
    #: :attr:`axis_fields` checked and made unit vectors, then :meth:`_check_values` (which sets
    #: nothing), every other field kept as given. A described group of such legs is then made
    #: from one leg built as any other (the fields the legs share) and each leg's anchors and axes
    #: checked and computed in floats (``parasynth.mechanisms.description.legs``), the same
    #: fields to the bit.
    group_built: ClassVar[bool] = False

    def __post_init__(self):
        object.__setattr__(self, "base", _vec3((self.name, "base"), self.base))
        object.__setattr__(self, "platform", _vec3((self.name, "platform"), self.platform))
        # the default neutral directions are unit vectors already (shared, read-only): a
        # described leg is given its own at home (Mechanism._neutral_refs) right after
        if self.base_ref is not _UP:
            object.__setattr__(self, "base_ref", _axis((self.name, "base_ref"), self.base_ref))
        if self.platform_ref is not _DOWN:
            object.__setattr__(self, "platform_ref", _axis((self.name, "platform_ref"), self.platform_ref))
        for f in self.axis_fields:
            object.__setattr__(self, f, _axis((self.name, f), getattr(self, f)))
        self._check_values()

    def _check_values(self) -> None:
        """``ValueError`` unless the leg's values other than its anchors and axes (lengths,
        branch) are allowed; the last check of :meth:`__post_init__`, changing nothing."""

    # -- structure -------------------------------------------------------------------------
    @property
    def n_joint_dof(self) -> int:
        return sum(JOINT_DOF[j] for j in self.joints)

    @property
    def n_links(self) -> int:
        """Moving bodies of the leg (between base and platform)."""
        return len(self.joints) - 1

    @property
    def is_actuated(self) -> bool:
        return self.actuated is not None

    # -- kinematics ------------------------------------------------------------------------
    def platform_points(self, p: np.ndarray, R: np.ndarray) -> np.ndarray:
        return p + rotate_rows(R, self.platform)

    def solve(self, p: np.ndarray, R: np.ndarray, joint_angles: bool = True) -> LegState:  # pragma: no cover
        """The leg's state at platform poses ``(p, R)``; ``joint_angles=False`` leaves the passive
        joint angles out (``angles`` empty) where only the geometry is wanted."""
        raise NotImplementedError

    def joint_twists(self, st: LegState, P: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def home_direction(self, p, R):
        """The leg's direction (three floats) at one platform pose, ``p`` three floats and ``R``
        nine (row-major), computed in Python floats: what :meth:`solve` gives as
        ``direction[0]`` there, to a few units in the last place (NumPy's products of small
        matrices may round otherwise), for a mechanism's neutral joint directions at home
        without a dozen NumPy calls per leg. None where :meth:`solve` finds the pose out of
        the leg's reach; ``NotImplemented`` for a leg type without it (then :meth:`solve`)."""
        return NotImplemented

    def with_unit_neutral(self, base_ref, platform_ref) -> "Leg":
        """:meth:`with_neutral` of two directions given as finite floats (x, y, z)."""
        return self._with_refs(_unit_xyz((self.name, "base_ref"), *base_ref),
                               _unit_xyz((self.name, "platform_ref"), *platform_ref))

    def _with_refs(self, base_ref: np.ndarray, platform_ref: np.ndarray) -> "Leg":
        """A copy with the neutral directions ``base_ref`` and ``platform_ref`` as given: unit
        3-vectors made as :func:`_unit_xyz` makes them (the caller's word)."""
        new = object.__new__(type(self))  # copy.copy, without its reduce protocol (~1.5 us)
        d = new.__dict__
        d.update(self.__dict__)
        d["base_ref"] = base_ref
        d["platform_ref"] = platform_ref
        return new

    def with_neutral(self, base_ref, platform_ref) -> "Leg":
        """A copy with the neutral joint directions ``base_ref`` (base frame) and
        ``platform_ref`` (platform frame) -- ``dataclasses.replace`` without re-checking the
        other fields, which are unchanged."""
        return self.with_unit_neutral(_vec3_xyz((self.name, "base_ref"), base_ref)[1:],
                                      _vec3_xyz((self.name, "platform_ref"), platform_ref)[1:])

    def actuation_wrench(self, st: LegState, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit force along the leg line through the platform anchor, and ``rate_scale``."""
        w = force_wrench(st.direction, st.platform_point, P)
        return w, np.ones(st.length.shape)

    def constraint_wrenches(self, st: LegState, P: np.ndarray) -> np.ndarray:
        """Wrenches (N, c, 6) reciprocal to every joint twist of the leg."""
        return np.zeros(st.length.shape + (0, 6))

    def actuator_value(self, A: np.ndarray, p: np.ndarray, R: np.ndarray) -> np.ndarray:
        """The actuator value (N,) for platform anchor points ``A`` (N, 3) at poses ``(p, R)``,
        by a closed form where the leg type has one (evaluated also off the leg's constraint
        manifold, for closure residuals), else by :meth:`solve`."""
        return self.solve(p, R).actuator

    def constraint_residuals(self, A: np.ndarray, R: np.ndarray) -> list[np.ndarray]:
        """The closure residuals (N,) each of the leg's constraints for anchor points ``A`` and
        platform orientations ``R``, one per :attr:`constraint_rows` (zero where the pose
        satisfies the leg's constraint)."""
        return []

    # shared pieces --------------------------------------------------------------------------
    def _line(self, base_pts: np.ndarray, plat_pts: np.ndarray):
        d = plat_pts - base_pts
        length = np.linalg.norm(d, axis=-1)
        # unit(d) with the norm computed once: the same norm, the same division
        ln = length[..., None]
        n = np.divide(d, ln, out=np.zeros_like(d), where=ln > 0)
        return n, length

    def _cone_angles(self, n: np.ndarray, R: np.ndarray, prefix_base: str, prefix_plat: str):
        base_cone = _angle_between(n, np.broadcast_to(self.base_ref, n.shape))
        plat_ref = rotate_rows(R, self.platform_ref)
        # The platform joint sees the leg arriving, i.e. the direction platform -> base.
        plat_cone = _angle_between(-n, plat_ref)
        return {f"{prefix_base}_cone": base_cone, f"{prefix_plat}_cone": plat_cone}


def solve_geometry(leg, p, R) -> LegState:
    """``leg.solve(p, R, joint_angles=False)``: the state without the passive joint angles (for a
    leg class of its own whose ``solve`` takes no ``joint_angles``, its full state)."""
    try:
        return leg.solve(p, R, joint_angles=False)
    except TypeError:
        return leg.solve(p, R)


def _spherical_twists(point: np.ndarray, P: np.ndarray) -> list[np.ndarray]:
    N = point.shape[0]
    return [revolute_twist(np.broadcast_to(e, (N, 3)), point, P) for e in np.eye(3)]


@dataclass(frozen=True)
class SPS(Leg):
    """Spherical - actuated prismatic - spherical leg. Actuator: length |S_p - S_b| (m).

    Its six joint freedoms span all twists (the seventh, the spin about the leg line, is a
    local freedom), so it imposes no constraint."""

    joints: ClassVar[str] = "SPS"
    description_options: ClassVar[dict | None] = {}
    capabilities: ClassVar[LegCapabilities] = LegCapabilities(
        compiled=True, closure=True, dynamics=True, accuracy=True, stiffness=True, export=True, view=True,
        stacked=True)
    actuator_value = _anchor_distance
    local_dof: ClassVar[int] = 1
    group_built: ClassVar[bool] = True

    def home_direction(self, p, R):
        return _fixed_line(self.base.tolist(), _at_pose(self.platform.tolist(), p, R))[0]

    def solve(self, p, R, joint_angles: bool = True):
        A = self.platform_points(p, R)
        B = np.broadcast_to(self.base, A.shape)
        n, length = self._line(B, A)
        return LegState(
            actuator=length,
            reachable=length > 0,
            base_point=B,
            platform_point=A,
            direction=n,
            length=length,
            angles=self._cone_angles(n, R, "S_base", "S_platform") if joint_angles else {},
        )

    def joint_twists(self, st, P):
        tw = _spherical_twists(st.base_point, P)
        tw.append(prismatic_twist(st.direction))
        tw += _spherical_twists(st.platform_point, P)
        return np.stack(tw, axis=1)


@dataclass(frozen=True)
class UPS(Leg):
    """Universal - actuated prismatic - spherical leg. ``u_axis`` is the universal joint's
    axis fixed to the base (its second axis is carried by the cross, perpendicular to both
    the first axis and the leg). Actuator: length (m).

    Passive angles: ``U_base_cone`` (leg against ``base_ref``), ``U_base_1``/``U_base_2``
    (rotation about the fixed axis, and tilt out of the plane normal to it),
    ``S_platform_cone``."""

    u_axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    joints: ClassVar[str] = "UPS"
    description_options: ClassVar[dict | None] = {"u_axis": "axis_base"}
    capabilities: ClassVar[LegCapabilities] = LegCapabilities(
        compiled=True, closure=True, dynamics=True, accuracy=True, stiffness=True, export=True, view=True,
        stacked=True)
    actuator_value = _anchor_distance
    axis_fields: ClassVar[tuple[str, ...]] = ("u_axis",)
    group_built: ClassVar[bool] = True

    def home_direction(self, p, R):
        return _fixed_line(self.base.tolist(), _at_pose(self.platform.tolist(), p, R))[0]

    def solve(self, p, R, joint_angles: bool = True):
        A = self.platform_points(p, R)
        B = np.broadcast_to(self.base, A.shape)
        n, length = self._line(B, A)
        angles = {}
        if joint_angles:
            angles = self._cone_angles(n, R, "U_base", "S_platform")
            angles.update(_u_angles(self.u_axis, self.base_ref, n, "U_base"))
        return LegState(length, length > 0, B, A, n, length, angles)

    def joint_twists(self, st, P):
        N = st.length.shape[0]
        a1 = np.broadcast_to(self.u_axis, (N, 3))
        a2 = _perp_unit(a1, st.direction)
        tw = [revolute_twist(a1, st.base_point, P), revolute_twist(a2, st.base_point, P)]
        tw.append(prismatic_twist(st.direction))
        tw += _spherical_twists(st.platform_point, P)
        return np.stack(tw, axis=1)


def _u_angles(a1: np.ndarray, ref: np.ndarray, n: np.ndarray, prefix: str) -> dict:
    """Angles of a universal joint with fixed axis ``a1`` whose link lies along ``n``.

    The neutral link direction ``ref`` is projected normal to ``a1``; angle 1 is the rotation
    about ``a1`` (of the projection of ``n``) from that projection, angle 2 the tilt of ``n``
    out of the plane normal to ``a1`` relative to the tilt of ``ref``. Both are zero when
    ``n == ref``."""
    if np.ndim(a1) == 2:  # one axis per pose (scatter draws stacked, parasynth.measures.robustness)
        r0 = unit(ref - dot_rows(a1, ref)[:, None] * a1)
        b = cross(a1, r0)
        ang1 = np.arctan2(dot_rows(n, b), dot_rows(n, r0))
        ang2 = (np.arcsin(np.clip(dot_rows(n, a1), -1.0, 1.0))
                - np.arcsin(np.clip(dot_rows(a1, unit(ref)), -1.0, 1.0)))
        return {f"{prefix}_1": ang1, f"{prefix}_2": ang2}
    r0 = unit(ref - np.dot(ref, a1) * a1)
    if not np.any(r0):
        r0 = unit(cross(a1, [1.0, 0, 0]) if abs(a1[0]) < 0.9 else cross(a1, [0, 1.0, 0]))
    b = cross(a1, r0)
    ang1 = np.arctan2(n @ b, n @ r0)
    ang2 = np.arcsin(np.clip(n @ a1, -1.0, 1.0)) - np.arcsin(np.clip(unit(ref) @ a1, -1.0, 1.0))
    return {f"{prefix}_1": ang1, f"{prefix}_2": ang2}


@dataclass(frozen=True)
class PUS(Leg):
    """Actuated prismatic (slider) - universal - spherical leg with a link of fixed length.

    The slider moves along the unit ``slider_axis`` through ``base`` (the slider origin); the
    universal joint centre is ``U = base + s * slider_axis`` and the actuator is ``s`` (m).
    The link ``U -> S`` has constant ``link_length``. Of the two assembly modes the one with
    ``branch = +1`` puts the universal joint further along ``slider_axis`` than the sphere
    (the 2021 paper's eq. (11) with the positive sign: sliders above the platform).

    A pose is unreachable when the sphere is further than ``link_length`` from the slider
    line. ``u_axis`` is the universal joint's axis fixed to the slider.
    """

    slider_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    link_length: float = 0.2
    branch: int = 1
    u_axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    joints: ClassVar[str] = "PUS"
    description_options: ClassVar[dict | None] = {"slider_axis": "axis_base", "u_axis": "axis_base", "link_length": "length",
                                                            "branch": "branch"}
    required_options: ClassVar[tuple[str, ...]] = ("link_length",)
    capabilities: ClassVar[LegCapabilities] = LegCapabilities(
        compiled=True, closure=True, dynamics=True, accuracy=True, stiffness=True, export=True, view=True,
        stacked=True)
    actuator_value = _slider_position
    actuated: ClassVar[int | None] = 0
    actuator_kind: ClassVar[str] = "slider"

    axis_fields: ClassVar[tuple[str, ...]] = ("slider_axis", "u_axis")
    group_built: ClassVar[bool] = True

    def _check_values(self) -> None:
        L = float(self.link_length)
        if not math.isfinite(L) or L <= 0:
            raise ValueError(f"leg {self.name}: link_length must be a positive length in m, got {L}")
        if self.branch not in (1, -1):
            raise ValueError(f"leg {self.name}: branch must be +1 or -1, got {self.branch}")

    def home_direction(self, p, R):
        if not isinstance(self.link_length, float):
            return NotImplemented  # a link length per pose
        return _slider_line(self, _at_pose(self.platform.tolist(), p, R), self.slider_axis.tolist(), self.link_length)

    def solve(self, p, R, joint_angles: bool = True):
        S = self.platform_points(p, R)
        e = self.slider_axis
        d = S - self.base
        de = dot_rows(d, e)
        perp2 = np.einsum("ij,ij->i", d, d) - de**2
        disc = self.link_length**2 - perp2
        reachable = disc >= 0
        s = de + self.branch * np.sqrt(np.where(reachable, disc, np.nan))
        U = self.base + s[:, None] * e
        L = self.link_length
        one = isinstance(L, float) or np.ndim(L) == 0  # one geometry, or one link length per pose
        # a float64 divisor as np.reshape(L, ()) gave (np.ndim and np.reshape cost ~3 us each)
        n = (S - U) / (np.float64(L) if isinstance(L, float) else np.reshape(L, () if one else (-1, 1)))
        angles = {}
        if joint_angles:
            angles = self._cone_angles(n, R, "U_base", "S_platform")
            angles.update(_u_angles(self.u_axis, self.base_ref, n, "U_base"))
            # Angle between link and slider axis: transmission degrades as it nears 90 deg.
            angles["link_slider"] = _angle_between(-n, np.broadcast_to(e, n.shape))
        if one:  # a filled array (broadcast_to and a copy cost ~10 us a leg)
            length = np.full(s.shape, float(L))
        else:
            length = np.broadcast_to(np.asarray(L, dtype=float), s.shape).copy()
        return LegState(s, reachable, U, S, n, length, angles)

    def joint_twists(self, st, P):
        N = st.length.shape[0]
        e = np.broadcast_to(self.slider_axis, (N, 3))
        a1 = np.broadcast_to(self.u_axis, (N, 3))
        a2 = _perp_unit(a1, st.direction)
        tw = [prismatic_twist(e)]
        tw += [revolute_twist(a1, st.base_point, P), revolute_twist(a2, st.base_point, P)]
        tw += _spherical_twists(st.platform_point, P)
        return np.stack(tw, axis=1)

    def actuation_wrench(self, st, P):
        # The link is a two-force member: it pushes along its own line through S. A slider
        # rate s' moves U along e, so n.(S' - s' e) = 0 gives s' = (n . v_S) / (n . e).
        w = force_wrench(st.direction, st.platform_point, P)
        return w, dot_rows(st.direction, self.slider_axis)


def _in_plane_residual(n_vec: np.ndarray, axis: np.ndarray) -> np.ndarray:
    return np.abs(n_vec @ axis)


@dataclass(frozen=True)
class RPS(Leg):
    """Revolute - actuated prismatic - spherical leg. The revolute axis ``r_axis`` (base
    frame) passes through ``base``; the leg moves in the plane through ``base`` normal to it,
    so a pose is reachable only if the platform anchor lies in that plane (within
    ``GEOM_TOL``). Constraint: a force through the sphere centre parallel to ``r_axis``.

    With ``passive=True`` the prismatic joint is free and the leg only constrains (the
    grinding robot's constraining branch)."""

    r_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    passive: bool = False
    joints: ClassVar[str] = "RPS"
    description_options: ClassVar[dict | None] = {"r_axis": "axis_base"}
    capabilities: ClassVar[LegCapabilities] = LegCapabilities(
        compiled=True, closure=True, dynamics=True, accuracy=True, stiffness=True, export=True, view=True,
        stacked=True, passive=True)
    constraint_rows: ClassVar[tuple[str, ...]] = ("length",)
    actuator_value = _anchor_distance

    axis_fields: ClassVar[tuple[str, ...]] = ("r_axis",)
    group_built: ClassVar[bool] = True

    @property
    def is_actuated(self) -> bool:
        return not self.passive

    def home_direction(self, p, R):
        return _planar_line(self, p, R)

    def solve(self, p, R, joint_angles: bool = True):
        A = self.platform_points(p, R)
        B = np.broadcast_to(self.base, A.shape)
        n, length = self._line(B, A)
        off_plane = np.abs(dot_rows(A - B, self.r_axis))
        # Tolerance per pose (never relative to the batch: a pose's answer must not depend on
        # the other poses evaluated with it).
        reachable = (off_plane <= GEOM_TOL * np.maximum(1.0, length)) & (length > 0)
        angles = {}
        if joint_angles:
            angles = self._cone_angles(n, R, "R_base", "S_platform")
            # Revolute angle: rotation of the leg about r_axis from base_ref (projected).
            angles.update({"R_base": _u_angles(self.r_axis, self.base_ref, n, "R")["R_1"]})
        return LegState(length, reachable, B, A, n, length, angles, {"off_plane": off_plane})

    def joint_twists(self, st, P):
        N = st.length.shape[0]
        a = np.broadcast_to(self.r_axis, (N, 3))
        tw = [revolute_twist(a, st.base_point, P), prismatic_twist(st.direction)]
        tw += _spherical_twists(st.platform_point, P)
        return np.stack(tw, axis=1)

    def constraint_residuals(self, A, R):
        """The anchor's offset (m) from the plane through ``base`` normal to ``r_axis``."""
        return [dot_rows(A - self.base, self.r_axis)]

    def constraint_wrenches(self, st, P):
        N = st.length.shape[0]
        return force_wrench(np.broadcast_to(self.r_axis, (N, 3)), st.platform_point, P)[:, None, :]


@dataclass(frozen=True)
class RPU(Leg):
    """Revolute - actuated prismatic - universal leg.

    The base revolute axis ``r_axis`` passes through ``base``; the universal joint at the
    platform has one axis parallel to ``r_axis`` (carried by the leg) and one fixed to the
    platform, ``u_platform_axis`` (platform frame). As in the 2T2R paper (Section 2) the two
    axes of the universal joint are perpendicular, so a pose is reachable only if the leg lies
    in the plane normal to ``r_axis`` through ``base`` and ``R @ u_platform_axis`` is normal to
    ``r_axis``. Constraints: a force parallel to ``r_axis`` through the universal joint centre
    and a couple about ``r_axis x (R @ u_platform_axis)``.
    """

    r_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    u_platform_axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    joints: ClassVar[str] = "RPU"
    description_options: ClassVar[dict | None] = {"r_axis": "axis_base", "u_platform_axis": "axis_platform"}
    capabilities: ClassVar[LegCapabilities] = LegCapabilities(
        compiled=True, closure=True, dynamics=True, accuracy=True, stiffness=True, export=True, view=True,
        stacked=True)
    constraint_rows: ClassVar[tuple[str, ...]] = ("length", "angle")
    actuator_value = _anchor_distance

    axis_fields: ClassVar[tuple[str, ...]] = ("r_axis", "u_platform_axis")
    group_built: ClassVar[bool] = True

    def home_direction(self, p, R):
        n = _planar_line(self, p, R)
        rx, ry, rz = self.r_axis.tolist()
        a4 = _at_pose(self.u_platform_axis.tolist(), (0.0, 0.0, 0.0), R)
        return n if abs(a4[0] * rx + a4[1] * ry + a4[2] * rz) <= GEOM_TOL else None

    def solve(self, p, R, joint_angles: bool = True):
        A = self.platform_points(p, R)
        B = np.broadcast_to(self.base, A.shape)
        n, length = self._line(B, A)
        a4 = rotate_rows(R, self.u_platform_axis)
        off_plane = np.abs(dot_rows(A - B, self.r_axis))
        skew_u = np.abs(dot_rows(a4, self.r_axis))
        reachable = (off_plane <= GEOM_TOL * np.maximum(1.0, length)) & (skew_u <= GEOM_TOL) & (length > 0)
        angles = {}
        if joint_angles:
            angles = self._cone_angles(n, R, "R_base", "U_platform")
            angles["R_base"] = _u_angles(self.r_axis, self.base_ref, n, "R")["R_1"]
            # Platform universal joint: rotation about the leg-side axis (parallel to r_axis)
            # between the leg and the platform axis, minus 90 deg at the perpendicular neutral.
            angles["U_platform_1"] = np.arctan2(dot_rows(cross(n, a4), self.r_axis), np.sum(n * a4, -1)) - np.pi / 2
        return LegState(length, reachable, B, A, n, length, angles, {"off_plane": off_plane, "a4": a4})

    def joint_twists(self, st, P):
        N = st.length.shape[0]
        a = np.broadcast_to(self.r_axis, (N, 3))
        a4 = st.extra["a4"]
        tw = [revolute_twist(a, st.base_point, P), prismatic_twist(st.direction)]
        tw += [revolute_twist(a, st.platform_point, P), revolute_twist(a4, st.platform_point, P)]
        return np.stack(tw, axis=1)

    def constraint_residuals(self, A, R):
        """The anchor's offset (m) from the R joint's plane, and the platform U axis's component
        along ``r_axis`` (the two stay normal)."""
        return [dot_rows(A - self.base, self.r_axis), dot_rows(rotate_rows(R, self.u_platform_axis), self.r_axis)]

    def constraint_wrenches(self, st, P):
        N = st.length.shape[0]
        a = np.broadcast_to(self.r_axis, (N, 3))
        f = force_wrench(a, st.platform_point, P)
        c = couple_wrench(unit(cross(a, st.extra["a4"])))
        return np.stack([f, c], axis=1)


@dataclass(frozen=True)
class UPU(Leg):
    """Universal - prismatic - universal leg, by default passive (a constraining limb).

    Base universal joint: axis ``u_axis`` fixed to the base, cross axis normal to it and to
    the leg. Platform universal joint: axis ``u_platform_axis`` fixed to the platform (platform
    frame), cross axis normal to it and to the leg. Its five joint freedoms leave one
    reciprocal wrench, computed numerically at each pose (a pure couple about the base normal
    in the 2021 paper's reference pose, eq. (6)). ``passive=False`` makes the prismatic joint
    actuated."""

    u_axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    u_platform_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    passive: bool = True
    joints: ClassVar[str] = "UPU"
    description_options: ClassVar[dict | None] = {"u_axis": "axis_base", "u_platform_axis": "axis_platform"}
    capabilities: ClassVar[LegCapabilities] = LegCapabilities(
        compiled=True, closure=True, dynamics=True, accuracy=True, stiffness=True, export=True, view=True,
        stacked=True, passive=True)
    constraint_rows: ClassVar[tuple[str, ...]] = ("angle",)
    actuator_value = _anchor_distance

    axis_fields: ClassVar[tuple[str, ...]] = ("u_axis", "u_platform_axis")
    group_built: ClassVar[bool] = True

    @property
    def is_actuated(self) -> bool:
        return not self.passive

    def home_direction(self, p, R):
        return _fixed_line(self.base.tolist(), _at_pose(self.platform.tolist(), p, R))[0]

    def solve(self, p, R, joint_angles: bool = True):
        A = self.platform_points(p, R)
        B = np.broadcast_to(self.base, A.shape)
        n, length = self._line(B, A)
        angles = {}
        if joint_angles:
            angles = self._cone_angles(n, R, "U_base", "U_platform")
            angles.update(_u_angles(self.u_axis, self.base_ref, n, "U_base"))
        st = LegState(length, length > 0, B, A, n, length, angles)
        st.extra["a4"] = rotate_rows(R, self.u_platform_axis)
        return st

    def joint_twists(self, st, P):
        N = st.length.shape[0]
        a1 = np.broadcast_to(self.u_axis, (N, 3))
        a2 = _perp_unit(a1, st.direction)
        a4 = st.extra["a4"]
        a3 = _perp_unit(a4, st.direction)
        tw = [revolute_twist(a1, st.base_point, P), revolute_twist(a2, st.base_point, P)]
        tw.append(prismatic_twist(st.direction))
        tw += [revolute_twist(a3, st.platform_point, P), revolute_twist(a4, st.platform_point, P)]
        return np.stack(tw, axis=1)

    def constraint_residuals(self, A, R):
        """The twist (rad) about the leg line between the cross axes of the two U joints."""
        n = unit(A - self.base)
        cb = unit(cross(self.u_axis, n))
        cp = unit(cross(rotate_rows(R, self.u_platform_axis), n))
        return [np.arctan2(np.sum(cross(cb, cp) * n, -1), np.sum(cb * cp, -1))]

    def constraint_wrenches(self, st, P, length_scale: float | None = None):
        T = self.joint_twists(st, P)
        L = float(length_scale or max(float(np.mean(st.length)), 1e-3))
        Ts = T.copy()
        Ts[..., 3:] *= L
        w = null_direction(Ts)  # the one reciprocal direction (rank 5)
        w[:, 3:] *= L
        fnorm = np.linalg.norm(w[:, :3], axis=-1)
        mnorm = np.linalg.norm(w[:, 3:], axis=-1)
        is_couple = fnorm <= 1e-9 * np.maximum(mnorm / L, 1e-300)
        w[is_couple, :3] = 0.0
        scale = np.where(is_couple, mnorm, fnorm)
        w = w / scale[:, None]
        return w[:, None, :]


#: Leg classes by name, for descriptions and error messages.
LEG_TYPES = {cls.joints: cls for cls in (SPS, UPS, PUS, RPU, RPS, UPU)}


@dataclass(frozen=True)
class PRS(Leg):
    """Actuated prismatic (slider) - revolute - spherical leg with a link of fixed length (the
    leg of a 3-PRS).

    The slider moves along the unit ``slider_axis`` through ``base`` (the slider origin); the
    revolute joint centre is ``J = base + s * slider_axis`` and the actuator is ``s`` (m). The
    revolute axis ``r_axis`` (base frame, normal to ``slider_axis``) is carried by the slider,
    so the link ``J -> S`` of constant ``link_length`` turns in the plane through the slider
    line normal to ``r_axis``: a pose is reachable only if the sphere lies in that plane
    (within ``GEOM_TOL``) and no further than ``link_length`` from the slider line. As for
    :class:`PUS`, ``branch = +1`` puts the revolute joint further along ``slider_axis`` than
    the sphere.

    Passive angles: ``R_base`` (rotation of the link about ``r_axis`` from ``base_ref``),
    ``R_base_cone``, ``S_platform_cone`` and ``link_slider`` (link against the slider axis).
    Constraint: a force parallel to ``r_axis`` through the sphere centre.
    """

    slider_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    r_axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    link_length: float = 0.2
    branch: int = 1
    joints: ClassVar[str] = "PRS"
    description_options: ClassVar[dict | None] = {"slider_axis": "axis_base", "r_axis": "axis_base", "link_length": "length",
                                                            "branch": "branch"}
    required_options: ClassVar[tuple[str, ...]] = ("link_length",)
    capabilities: ClassVar[LegCapabilities] = LegCapabilities(
        compiled=True, accuracy=True, closure=True, stiffness=True, export=True, view=True)
    constraint_rows: ClassVar[tuple[str, ...]] = ("length",)
    actuator_value = _slider_position
    actuated: ClassVar[int | None] = 0
    actuator_kind: ClassVar[str] = "slider"

    axis_fields: ClassVar[tuple[str, ...]] = ("slider_axis", "r_axis")

    def __post_init__(self):
        super().__post_init__()
        if abs(float(self.slider_axis @ self.r_axis)) > 1e-9:
            raise ValueError(
                f"leg {self.name}: r_axis must be perpendicular to slider_axis (the revolute joint "
                f"turns the link in a plane containing the slider line), got r_axis "
                f"{self.r_axis.tolist()} and slider_axis {self.slider_axis.tolist()}"
            )
        L = float(self.link_length)
        if not math.isfinite(L) or L <= 0:
            raise ValueError(f"leg {self.name}: link_length must be a positive length in m, got {L}")
        if self.branch not in (1, -1):
            raise ValueError(f"leg {self.name}: branch must be +1 or -1, got {self.branch}")

    def home_direction(self, p, R):
        S = _at_pose(self.platform.tolist(), p, R)
        L = float(self.link_length)
        bx, by, bz = self.base.tolist()
        ax, ay, az = self.r_axis.tolist()
        off = abs((S[0] - bx) * ax + (S[1] - by) * ay + (S[2] - bz) * az)
        n = _slider_line(self, S, self.slider_axis.tolist(), L)
        return n if off <= GEOM_TOL * max(1.0, L) else None

    def solve(self, p, R, joint_angles: bool = True):
        S = self.platform_points(p, R)
        e, a = self.slider_axis, self.r_axis
        L = float(self.link_length)
        d = S - self.base
        off_plane = np.abs(d @ a)
        de = d @ e
        perp2 = np.einsum("ij,ij->i", d, d) - de**2
        disc = L**2 - perp2
        reachable = (disc >= 0) & (off_plane <= GEOM_TOL * max(1.0, L))
        s = de + self.branch * np.sqrt(np.where(disc >= 0, disc, np.nan))
        J = self.base + s[:, None] * e
        n = (S - J) / L
        angles = {}
        if joint_angles:
            angles = self._cone_angles(n, R, "R_base", "S_platform")
            angles["R_base"] = _u_angles(a, self.base_ref, n, "R")["R_1"]
            angles["link_slider"] = _angle_between(-n, np.broadcast_to(e, n.shape))
        return LegState(s, reachable, J, S, n, np.full(s.shape, L), angles, {"off_plane": off_plane})

    def joint_twists(self, st, P):
        N = st.length.shape[0]
        e = np.broadcast_to(self.slider_axis, (N, 3))
        a = np.broadcast_to(self.r_axis, (N, 3))
        tw = [prismatic_twist(e), revolute_twist(a, st.base_point, P)]
        tw += _spherical_twists(st.platform_point, P)
        return np.stack(tw, axis=1)

    def actuation_wrench(self, st, P):
        # The link carries a force along its line through S (reciprocal to the revolute and the
        # spherical joint); a slider rate s' moves J along e, so s' = (n . v_S) / (n . e).
        w = force_wrench(st.direction, st.platform_point, P)
        return w, dot_rows(st.direction, self.slider_axis)

    def constraint_residuals(self, A, R):
        """The anchor's offset (m) from the plane through ``base`` normal to ``r_axis``."""
        return [dot_rows(A - self.base, self.r_axis)]

    def constraint_wrenches(self, st, P):
        N = st.length.shape[0]
        return force_wrench(np.broadcast_to(self.r_axis, (N, 3)), st.platform_point, P)[:, None, :]


LEG_TYPES["PRS"] = PRS
__all__.append("PRS")


@dataclass(frozen=True)
class RUS(Leg):
    """Actuated revolute (crank) - universal - spherical leg with a crank and a link of fixed
    lengths (the leg of a 6-RUS platform).

    The crank turns about the unit ``r_axis`` (base frame) through ``base``; at crank angle
    ``t`` its tip, the universal joint centre, is ``C = base + crank_length (cos t c0 + sin t
    (r_axis x c0))``, where ``c0`` is ``crank_direction`` made normal to ``r_axis`` (default: the
    horizontal direction ``r_axis x z``, radial outwards for a tangential crank axis). The
    actuator is ``t`` (rad). The link ``C -> S`` has constant ``link_length``; of the two
    assembly modes ``branch = +1`` takes the larger crank angle of the solution pair. A pose is
    unreachable when the sphere is out of the link's reach from every crank position. The
    universal joint's first axis is parallel to ``r_axis`` (carried by the crank), its cross
    axis normal to it and to the link.

    Passive angles: ``U_base_cone`` (link against ``base_ref``), ``S_platform_cone`` and
    ``link_crank`` (link against the crank tip's direction of motion; transmission degrades as
    it nears 90 deg). The leg's six joint freedoms impose no constraint.
    """

    r_axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    crank_direction: np.ndarray | None = None
    crank_length: float = 0.1
    link_length: float = 0.3
    branch: int = 1
    joints: ClassVar[str] = "RUS"
    description_options: ClassVar[dict | None] = {"r_axis": "axis_base", "crank_direction": "axis_base", "crank_length": "length",
                                                            "link_length": "length", "branch": "branch"}
    required_options: ClassVar[tuple[str, ...]] = ("crank_length", "link_length")
    capabilities: ClassVar[LegCapabilities] = LegCapabilities(
        compiled=True, accuracy=True, stiffness=True, export=True, view=True)
    actuated: ClassVar[int | None] = 0
    actuator_kind: ClassVar[str] = "angle"

    axis_fields: ClassVar[tuple[str, ...]] = ("r_axis",)

    def __post_init__(self):
        super().__post_init__()
        a = self.r_axis
        c = self.crank_direction
        if c is None:
            c = cross(a, [0.0, 0.0, 1.0])
            if np.linalg.norm(c) < 1e-9:
                c = cross(a, [0.0, 1.0, 0.0])
        c = _vec3((self.name, "crank_direction"), c)
        c = c - (c @ a) * a
        if np.linalg.norm(c) < 1e-9:
            raise ValueError(f"leg {self.name}: crank_direction must not be parallel to r_axis "
                             f"{a.tolist()}, got {np.asarray(self.crank_direction, float).tolist()}")
        object.__setattr__(self, "crank_direction", c / np.linalg.norm(c))
        for nm in ("crank_length", "link_length"):
            v = float(getattr(self, nm))
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"leg {self.name}: {nm} must be a positive length in m, got {v}")
        if self.branch not in (1, -1):
            raise ValueError(f"leg {self.name}: branch must be +1 or -1, got {self.branch}")

    def _crank(self, t: np.ndarray) -> np.ndarray:
        """Unit crank directions (N, 3) at crank angles ``t``."""
        c0 = self.crank_direction
        c1 = cross(self.r_axis, c0)
        return np.cos(t)[:, None] * c0 + np.sin(t)[:, None] * c1

    def home_direction(self, p, R):
        S = _at_pose(self.platform.tolist(), p, R)
        h, L = float(self.crank_length), float(self.link_length)
        bx, by, bz = self.base.tolist()
        c0 = self.crank_direction.tolist()
        c1 = cross(self.r_axis, self.crank_direction).tolist()
        dx, dy, dz = S[0] - bx, S[1] - by, S[2] - bz
        P = dx * c0[0] + dy * c0[1] + dz * c0[2]
        Q = dx * c1[0] + dy * c1[1] + dz * c1[2]
        K = ((dx * dx + dy * dy + dz * dz) + h * h - L * L) / (2 * h)
        rho = math.hypot(P, Q)
        if not rho > 0 or not abs(K / rho) <= 1.0:
            return None
        t = math.atan2(Q, P) + self.branch * math.acos(K / rho)
        t = math.atan2(math.sin(t), math.cos(t))
        ct, st = math.cos(t), math.sin(t)
        return tuple((S[i] - ((bx, by, bz)[i] + h * (ct * c0[i] + st * c1[i]))) / L for i in range(3))

    def solve(self, p, R, joint_angles: bool = True):
        S = self.platform_points(p, R)
        h, L = float(self.crank_length), float(self.link_length)
        c0 = self.crank_direction
        c1 = cross(self.r_axis, c0)
        d = S - self.base
        # |d - h c(t)|^2 = L^2  <=>  P cos t + Q sin t = K
        P, Q = d @ c0, d @ c1
        K = (np.einsum("ij,ij->i", d, d) + h * h - L * L) / (2 * h)
        rho = np.hypot(P, Q)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = K / rho
        reachable = np.abs(ratio) <= 1.0
        t = np.arctan2(Q, P) + self.branch * np.arccos(np.where(reachable, ratio, np.nan))
        t = np.arctan2(np.sin(t), np.cos(t))
        C = self.base + h * self._crank(t)
        n = (S - C) / L
        angles = {}
        if joint_angles:
            angles = self._cone_angles(n, R, "U_base", "S_platform")
            tangent = cross(np.broadcast_to(self.r_axis, C.shape), C - self.base)
            angles["link_crank"] = _angle_between(n, unit(tangent))
        return LegState(t, reachable, C, S, n, np.full(t.shape, L), angles)

    def joint_twists(self, st, P):
        N = st.length.shape[0]
        a = np.broadcast_to(self.r_axis, (N, 3))
        a2 = _perp_unit(a, st.direction)
        base = np.broadcast_to(self.base, (N, 3))
        tw = [revolute_twist(a, base, P), revolute_twist(a, st.base_point, P), revolute_twist(a2, st.base_point, P)]
        tw += _spherical_twists(st.platform_point, P)
        return np.stack(tw, axis=1)

    def actuation_wrench(self, st, P):
        # The link is a two-force member along its line through S; a crank rate t' moves C by
        # t' r_axis x (C - base), so n.(v_S - t' r_axis x (C - base)) = 0 gives
        # t' = (n . v_S) / (n . (r_axis x (C - base))).
        w = force_wrench(st.direction, st.platform_point, P)
        tangent = cross(np.broadcast_to(self.r_axis, st.base_point.shape), st.base_point - self.base)
        return w, np.einsum("ij,ij->i", st.direction, tangent)


LEG_TYPES["RUS"] = RUS
