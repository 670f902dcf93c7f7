"""Limbs defined by their joint string: a serial chain of R, P, U and S joints with the actuated
joint marked and the relations of its axes, solved by a numerical inverse kinematics (the NumPy
reference; docs/structures.md, "Limbs from joint strings").

A limb is written as its joints from base to platform, the actuated joint followed by ``*``
(``"RP*UR"``: revolute, actuated prismatic, universal, revolute), or as the plain string with the
index of the actuated joint (``parse_chain("RPUR", actuated=1)``); ``actuated=None`` with no
marker is a passive limb only when ``passive=True`` is said. The axes of its freedoms, in chain
order (R: one axis; P: its direction; U: two axes, the second normal to the first; S: none, its
three freedoms are free), are given by *relations*:

* ``"parallel:REF"`` or just ``"REF"``: the axis is parallel to REF;
* ``"normal:REF"``: the axis is normal to REF; an axis normal to two references is along their
  cross product; an axis normal to one reference only is also taken normal to the limb's line
  (the usual cross axis of a universal joint), or, if REF is along the limb, normal to the base
  normal;

with REF one of ``prev`` (the previous rotational axis of the chain: of an R or U joint, not a
prismatic direction), ``axisK`` (the chain's axis number K, counted from 0, an earlier one),
``base_normal`` (the base's z axis),
``radial`` and ``tangent`` (of the limb's base anchor on its circle), ``limb`` (the line from
the base anchor to the platform anchor at the home pose) and the fixed axes ``x``, ``y``, ``z``.
Several relations of one axis are joined with ``&`` (``"normal:prev&normal:limb"``). Relations
that contradict each other (parallel and normal to the same reference, parallel to two
references that are never parallel, ...) are refused with one line naming the axis.

Geometry (an assumption, stated here and as parameters): at the home pose the joint centres of
the rotational joints (R, U, S) lie on the line from the base anchor to the platform anchor, at
the fractions ``stations`` of its length (default: evenly spread from 0 to 1 over the rotational
joints; a prismatic joint has no centre, it moves everything after it along its direction). The
chain's forward kinematics is the product of exponentials of its joint twists from this home
configuration; its inverse kinematics at a platform pose is a damped Gauss-Newton solve of the
anchor frame's position and orientation over the joint coordinates, started at the home
configuration (the branch of the home pose). A pose is reachable when the solve's residual is
below :data:`IK_TOL`; a limb of fewer than six freedoms reaches only the poses its constraints
allow. The actuator value is the actuated joint's coordinate from home (a prismatic joint
between two joint centres adds their home distance, so that it reads as the limb's length).

The chain's constraint wrenches are the wrenches reciprocal to its joint twists at the solved
configuration (an SVD), so the mobility of a structure follows from them as for the hand-written
leg types. The engine solves chain limbs with a compiled kernel of the same solve
(:mod:`parasynth.engine.chains`, from :meth:`ChainLeg.chain_arrays`) for feasibility and
constraint margins; a chain limb declares ``compiled=False`` (no compiled pose-wise index kernels:
those fall back to NumPy with the fallback warning) and every capability but ``stiffness`` and
``passive`` off, so the other parts refuse it by name (:func:`parasynth.model.legs.require`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .legs import JOINT_DOF, LEG_TYPES, Leg, LegCapabilities, LegState, _vec3
from .spatial import null_space, prismatic_twist, revolute_twist, rot_axis, unit

__all__ = ["ChainError", "ChainSpec", "ChainLeg", "parse_chain", "JOINT_LETTERS", "REFERENCES", "RELATIONS",
           "IK_TOL", "IK_ITERATIONS", "chain_class"]

#: The joint letters a joint string may hold, with their freedoms.
JOINT_LETTERS = {"R": "revolute", "P": "prismatic", "U": "universal", "S": "spherical"}
#: The references an axis relation may name.
REFERENCES = ("prev", "base_normal", "radial", "tangent", "limb", "x", "y", "z", "axisK")
#: The relations an axis may have to a reference.
RELATIONS = ("parallel", "normal")
#: Largest residual of a reached pose (position / length scale and orientation in rad).
IK_TOL = 1e-9
#: Gauss-Newton iterations of the inverse kinematics.
IK_ITERATIONS = 60
#: The axes of each joint letter that take a relation (S: none).
_AXES_PER_JOINT = {"R": 1, "P": 1, "U": 2, "S": 0}
#: References always normal to each other (at every anchor), and always the same direction.
_ALWAYS_NORMAL = {frozenset(p) for p in (("radial", "tangent"), ("radial", "base_normal"), ("tangent", "base_normal"),
                                         ("x", "y"), ("y", "z"), ("x", "z"), ("radial", "z"), ("tangent", "z"))}
_SAME = {frozenset(("z", "base_normal"))}
_ALLOWED = (f"relations {', '.join(RELATIONS)} (written 'parallel:REF', 'normal:REF' or 'REF', joined with '&') "
            f"to REF in {', '.join(REFERENCES)}")


class ChainError(ValueError):
    """A joint string, an actuated joint or axis relations that are not allowed; the message
    says what is wrong and what is allowed."""


def _fmt(x) -> str:
    return repr(x) if isinstance(x, str) else f"{x!r} ({type(x).__name__})"


@dataclass(frozen=True)
class ChainSpec:
    """A parsed limb: ``joints`` (the letters, base to platform), ``actuated`` (index of the
    actuated joint, None for a passive limb), ``relations`` (per axis of the chain, a tuple of
    (relation, reference) pairs) and ``stations`` (home fractions of the rotational joints'
    centres along the limb, None: evenly spread)."""

    joints: str
    actuated: int | None
    relations: tuple
    stations: tuple | None = None
    kinds: tuple = ()

    @property
    def name(self) -> str:
        """The joint string with the actuated joint marked (``RP*UR``)."""
        return "".join(j + ("*" if i == self.actuated else "") for i, j in enumerate(self.joints))

    @property
    def n_dof(self) -> int:
        return sum(JOINT_DOF[j] for j in self.joints)

    @property
    def n_axes(self) -> int:
        return sum(_AXES_PER_JOINT[j] for j in self.joints)


def _parse_relation(raw, where: str) -> tuple:
    if not isinstance(raw, str) or not raw.strip():
        raise ChainError(f"{where}: expected a relation string, got {_fmt(raw)}; allowed: {_ALLOWED}")
    out = []
    for part in raw.split("&"):
        part = part.strip()
        rel, _, ref = part.partition(":") if ":" in part else ("parallel", "", part)
        rel, ref = rel.strip(), ref.strip()
        if rel not in RELATIONS:
            raise ChainError(f"{where}: unknown relation {rel!r} in {raw!r}; allowed: {_ALLOWED}")
        if ref not in REFERENCES[:-1] and not (ref.startswith("axis") and ref[4:].isdigit()):
            raise ChainError(f"{where}: unknown reference {ref!r} in {raw!r}; allowed: {_ALLOWED}")
        out.append((rel, ref))
    return tuple(out)


def _check_symbolic(rels: tuple, where: str) -> None:
    """Contradictions that hold at every anchor and pose."""
    par = [r for k, r in rels if k == "parallel"]
    nor = [r for k, r in rels if k == "normal"]
    for r in par:
        if r in nor:
            raise ChainError(f"{where}: parallel and normal to {r!r} at once contradict each other; an axis is "
                             f"either parallel or normal to a reference ({_ALLOWED})")
    for a in par:
        for b in par:
            if a != b and frozenset((a, b)) in _ALWAYS_NORMAL:
                raise ChainError(f"{where}: parallel to {a!r} and to {b!r} contradict each other (they are normal); "
                                 f"give one parallel reference ({_ALLOWED})")
        for b in nor:
            if frozenset((a, b)) in _SAME:
                raise ChainError(f"{where}: parallel to {a!r} and normal to {b!r} contradict each other (the same "
                                 f"direction); {_ALLOWED}")


def parse_chain(spec, actuated=None, axes=None, *, passive: bool = False, stations=None) -> ChainSpec:
    """Parse a limb: ``spec`` its joint string (``"RP*UR"``, or ``"RPUR"`` with ``actuated``, the
    index of the actuated joint), ``axes`` the relations of its axes in chain order (a list of
    strings, one per axis: R and P one each, U two, S none; None: the defaults, first rotational
    axis ``tangent``, a prismatic joint ``limb``, every later rotational axis ``parallel:prev``
    except a universal joint's second axis ``normal:prev``), ``passive`` True for a limb without
    an actuator, ``stations`` the home fractions of the rotational joints' centres along the
    limb. :class:`ChainError` (one line: what is wrong, what is allowed) otherwise."""
    if not isinstance(spec, str) or not spec.strip():
        raise ChainError(f"joint string must be a non-empty string of {', '.join(JOINT_LETTERS)} (the actuated joint "
                         f"followed by '*', e.g. 'RP*UR'), got {_fmt(spec)}")
    s = spec.strip()
    letters, marks = [], []
    for ch in s:
        if ch == "*":
            if not letters:
                raise ChainError(f"joint string {s!r}: '*' must follow the joint it marks as actuated, e.g. 'RP*UR'")
            marks.append(len(letters) - 1)
        elif ch.upper() in JOINT_LETTERS and ch.isalpha():
            letters.append(ch.upper())
        else:
            raise ChainError(f"joint string {s!r}: unknown joint letter {ch!r}; allowed: "
                             f"{', '.join(f'{k} ({v})' for k, v in JOINT_LETTERS.items())}, the actuated one "
                             f"followed by '*'")
    joints = "".join(letters)
    if len(marks) != len(set(marks)):
        raise ChainError(f"joint string {s!r}: a joint is marked '*' twice; mark exactly one actuated joint")
    if actuated is not None:
        if isinstance(actuated, bool) or not isinstance(actuated, (int, np.integer)) \
                or not 0 <= int(actuated) < len(joints):
            raise ChainError(f"actuated must be the index (0 to {len(joints) - 1}) of a joint of {joints!r}, got "
                             f"{_fmt(actuated)}")
        marks = sorted(set(marks) | {int(actuated)})
    if len(marks) > 1:
        raise ChainError(f"joint string {s!r}: {len(marks)} actuated joints ({', '.join(str(m) for m in marks)}); a "
                         f"limb has exactly one actuated joint (or none with passive=True)")
    if not isinstance(passive, (bool, np.bool_)):
        raise ChainError(f"passive must be True or False, got {_fmt(passive)}")
    if not marks and not passive:
        raise ChainError(f"joint string {s!r}: no actuated joint; mark one with '*' (e.g. 'RP*UR') or give actuated=, "
                         f"or say passive=True for a constraining limb")
    if marks and passive:
        raise ChainError(f"joint string {s!r}: passive=True but joint {marks[0]} is marked actuated; give one or "
                         f"the other")
    act = marks[0] if marks else None
    if act is not None and joints[act] not in "RP":
        raise ChainError(f"joint string {s!r}: the actuated joint {act} is a {JOINT_LETTERS[joints[act]]} joint; "
                         f"only a revolute (R) or prismatic (P) joint can be actuated")
    n_dof = sum(JOINT_DOF[j] for j in joints)
    if n_dof > 6 + 1 or n_dof < 1:
        raise ChainError(f"joint string {s!r}: {n_dof} joint freedoms; a limb has 1 to 7 (six freedoms and at most "
                         f"an idle spin)")
    n_axes = sum(_AXES_PER_JOINT[j] for j in joints)
    if axes is None:
        axes, first = [], True
        for j in joints:
            if j == "P":
                axes.append("limb")
            elif j in "RU":
                axes.append("tangent" if first else "parallel:prev")
                first = False
                if j == "U":
                    axes.append("normal:prev")
    if not isinstance(axes, (list, tuple)):
        raise ChainError(f"axes must be a list of {n_axes} relation strings (one per axis of {joints}), got {_fmt(axes)}")
    if len(axes) != n_axes:
        raise ChainError(f"axes: {joints} has {n_axes} axes (R, P one each, U two, S none), {len(axes)} relations "
                         f"given")
    rels = []
    kinds = [j for j in joints for _ in range(_AXES_PER_JOINT[j])]
    k = 0
    for i, j in enumerate(joints):
        for m in range(_AXES_PER_JOINT[j]):
            where = f"axes[{k}] (joint {i} {j}{'' if j != 'U' else ' axis ' + str(m + 1)})"
            r = _parse_relation(axes[k], where)
            rot_before = [kk for kk in range(k) if kinds[kk] != "P"]
            if any(ref == "prev" for _, ref in r) and not rot_before:
                raise ChainError(f"{where}: no rotational axis comes before it to be 'prev'; "
                                 f"{_ALLOWED.replace('prev, ', '')}")
            for _, ref in r:
                if ref.startswith("axis") and int(ref[4:]) >= k:
                    raise ChainError(f"{where}: {ref!r} is not an earlier axis (axes 0 to {k - 1} come before it)")
            _check_symbolic(r, where)
            if j == "U" and m == 1 and ("parallel", "prev") in r:
                raise ChainError(f"{where}: a universal joint's second axis is normal to its first, not parallel; "
                                 f"give 'normal:prev' (with another normal reference to fix it)")
            rels.append(r)
            k += 1
    n_rot = sum(1 for j in joints if j in "RUS")
    if stations is not None:
        if not isinstance(stations, (list, tuple)) or len(stations) != n_rot or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and 0.0 <= v <= 1.0 for v in stations):
            raise ChainError(f"stations must be {n_rot} numbers in [0, 1] (the home fractions along the limb of its "
                             f"rotational joints' centres, non-decreasing), got {_fmt(stations)}")
        if any(b < a for a, b in zip(stations, stations[1:])):
            raise ChainError(f"stations must be non-decreasing (joint centres in chain order along the limb), got "
                             f"{list(stations)}")
        stations = tuple(float(v) for v in stations)
    spec_ = ChainSpec(joints, act, tuple(rels), stations, tuple(kinds))
    # the relations at a generic anchor: contradictions that depend on the previous axes
    _resolve_axes(spec_, np.array([math.cos(0.7), math.sin(0.7), 0.0]), np.array([-math.sin(0.7), math.cos(0.7), 0.0]),
                  unit(np.array([-0.31, 0.17, 0.93])))
    return spec_


def _resolve_axes(spec: ChainSpec, radial, tangent, limb, who: str = "") -> list[np.ndarray]:
    """The home directions of the chain's axes at an anchor (its radial and tangent directions,
    the limb's home line); :class:`ChainError` where relations contradict."""
    fixed = {"base_normal": np.array([0.0, 0.0, 1.0]), "radial": np.asarray(radial, float),
             "tangent": np.asarray(tangent, float), "limb": np.asarray(limb, float), "x": np.eye(3)[0],
             "y": np.eye(3)[1], "z": np.eye(3)[2]}
    out = []
    tol = 1e-9
    for k, rels in enumerate(spec.relations):
        where = f"{who}axes[{k}]"
        prev = [out[kk] for kk in range(k) if spec.kinds[kk] != "P"]
        vec = {ref: (prev[-1] if ref == "prev" else out[int(ref[4:])] if ref.startswith("axis") else fixed[ref])
               for _, ref in rels}
        par = [vec[r] for kind, r in rels if kind == "parallel"]
        nor = [vec[r] for kind, r in rels if kind == "normal"]
        for v in par + nor:
            if np.linalg.norm(v) < tol:
                raise ChainError(f"{where}: a reference direction is undefined at this anchor (radial or tangent of an "
                                 f"anchor on the centre); give x, y, z or base_normal")
        if par:
            a = unit(par[0])
        elif len(nor) >= 2 and np.linalg.norm(np.cross(nor[0], nor[1])) > 1e-6:
            a = unit(np.cross(nor[0], nor[1]))
        else:
            c = np.cross(nor[0], fixed["limb"])
            if np.linalg.norm(c) < 1e-6:
                c = np.cross(nor[0], fixed["base_normal"])
            if np.linalg.norm(c) < 1e-6:
                c = np.cross(nor[0], fixed["x"])
            a = unit(c)
        names = [f"{kind}:{r}" for kind, r in rels]
        for (kind, r) in rels:
            v = unit(vec[r])
            bad = (np.linalg.norm(np.cross(a, v)) > 1e-6) if kind == "parallel" else (abs(float(a @ v)) > 1e-6)
            if bad:
                raise ChainError(f"{where}: relations {' & '.join(names)} contradict each other here ({kind} to {r!r} "
                                 f"cannot hold with the others); {_ALLOWED}")
        out.append(a)
    return out


def _log_rot(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) of rotation matrices (N, 3, 3)."""
    v = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], -1)
    s = np.linalg.norm(v, axis=-1)
    c = 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0)
    th = np.arctan2(s, c)
    f = np.where(s > 1e-12, th / np.maximum(s, 1e-300), 1.0)
    return v * f[:, None]


@dataclass(frozen=True)
class ChainLeg(Leg):
    """A limb of any joint string (:func:`parse_chain`), solved numerically.

    ``chain``: the joint string with the actuated joint marked (``"RP*UR"``) or a passive one;
    ``axes``: the relations of its axes (None: the defaults of :func:`parse_chain`); ``passive``:
    no actuator; ``stations``: home fractions of the rotational joints' centres; ``home_point``:
    the platform anchor's position (base frame) at the home pose, level platform (None: the
    platform anchor raised by ``home_height`` above the base plane); ``radial`` and ``tangent``:
    the base anchor's directions (None: from the anchor's angle about z)."""

    chain: str = "RP*UR"
    axes: tuple | None = None
    passive: bool = False
    stations: tuple | None = None
    home_point: np.ndarray | None = None
    home_height: float = 0.4
    radial: np.ndarray | None = None
    tangent: np.ndarray | None = None

    joints: ClassVar[str] = "chain"
    actuated: ClassVar[int | None] = None
    capabilities: ClassVar[LegCapabilities] = LegCapabilities(stiffness=True, passive=True)
    #: What a mechanism description gives a chain limb: its anchor's directions and the height of
    #: its home configuration (the structures give ``radial``, ``tangent`` and ``height``).
    description_options: ClassVar[dict | None] = {"radial": "axis_base", "tangent": "axis_base",
                                                   "home_height": "length"}

    def __post_init__(self):
        super().__post_init__()
        chain = self.chain.replace("*", "") if self.passive and isinstance(self.chain, str) else self.chain
        try:
            spec = parse_chain(chain, axes=None if self.axes is None else list(self.axes), passive=self.passive,
                               stations=None if self.stations is None else list(self.stations))
        except ChainError as e:
            raise ChainError(f"leg {self.name}: {e}") from None
        A0 = (self.platform + np.array([0.0, 0.0, float(self.home_height)]) if self.home_point is None
              else _vec3(f"leg {self.name}: home_point", self.home_point))
        d = A0 - self.base
        L = float(np.linalg.norm(d))
        if L <= 0:
            raise ChainError(f"leg {self.name}: the home platform anchor coincides with the base anchor")
        rad = self.radial
        if rad is None:
            rad = np.array([self.base[0], self.base[1], 0.0])
            rad = rad / np.linalg.norm(rad) if np.linalg.norm(rad) > 1e-12 else np.zeros(3)
        tan = self.tangent if self.tangent is not None else np.cross([0.0, 0.0, 1.0], rad)
        axes = _resolve_axes(spec, rad, tan, d / L, who=f"leg {self.name}: ")
        n_rot = sum(1 for j in spec.joints if j in "RUS")
        st = spec.stations or tuple(np.linspace(0.0, 1.0, n_rot)) if n_rot > 1 else (spec.stations or (1.0,))
        # the freedoms as (kind, axis, point) at home
        free, joint_of, k, r = [], [], 0, 0
        centres = []
        for i, j in enumerate(spec.joints):
            if j == "P":
                free.append(("P", axes[k], None))
                joint_of.append(i)
                k += 1
                centres.append(None)
                continue
            c = self.base + st[r] * d
            r += 1
            centres.append(c)
            if j == "S":
                dirs = list(np.eye(3))
            else:
                dirs = axes[k:k + _AXES_PER_JOINT[j]]
                k += _AXES_PER_JOINT[j]
            for a in dirs:
                free.append(("R", np.asarray(a, float), c))
                joint_of.append(i)
        act_free = None if spec.actuated is None else joint_of.index(spec.actuated)
        act_home = 0.0
        if spec.actuated is not None and spec.joints[spec.actuated] == "P":
            before = [c for c in centres[:spec.actuated] if c is not None]
            after = [c for c in centres[spec.actuated + 1:] if c is not None]
            if before and after:
                act_home = float(abs((after[0] - before[-1]) @ free[act_free][1]))
        object.__setattr__(self, "_spec", spec)
        object.__setattr__(self, "_free", tuple(free))
        object.__setattr__(self, "_joint_of", tuple(joint_of))
        object.__setattr__(self, "_act", act_free)
        object.__setattr__(self, "_act_home", act_home)
        object.__setattr__(self, "_home", A0)
        object.__setattr__(self, "_L", L)

    # -- structure ---------------------------------------------------------------------------
    @property
    def spec(self) -> ChainSpec:
        return self._spec

    @property
    def n_joint_dof(self) -> int:
        return len(self._free)

    @property
    def is_actuated(self) -> bool:
        return self._spec.actuated is not None

    @property
    def actuator_kind(self) -> str:
        return _actuator_kind(self._spec)

    def chain_arrays(self) -> dict:
        """The chain as data, for a compiled solve (:mod:`parasynth.engine.chains`): ``kinds``
        (n,) int64 per freedom (0 revolute, 1 prismatic), ``axes`` (n, 3) and ``points`` (n, 3,
        zeros for a prismatic freedom) at home, ``home`` and ``platform`` (the anchor at home,
        base frame; the platform anchor, platform frame), ``length`` (the scale of the solve's
        position residual), ``actuated`` (the actuated freedom, -1 for none), ``act_home`` and
        ``joint_of`` (n,) the joint of each freedom."""
        n = len(self._free)
        kinds = np.array([1 if k == "P" else 0 for k, _, _ in self._free], dtype=np.int64)
        axes = np.array([a for _, a, _ in self._free], dtype=float).reshape(n, 3)
        points = np.array([np.zeros(3) if c is None else c for _, _, c in self._free], dtype=float).reshape(n, 3)
        return {"kinds": kinds, "axes": axes, "points": points, "home": np.array(self._home, float),
                "platform": np.array(self.platform, float), "length": float(self._L),
                "actuated": -1 if self._act is None else int(self._act), "act_home": float(self._act_home),
                "joint_of": np.array(self._joint_of, dtype=np.int64)}

    # -- kinematics --------------------------------------------------------------------------
    def forward(self, q: np.ndarray):
        """The anchor frame (position (N, 3), orientation (N, 3, 3)) and the freedoms' current
        axes and points at joint coordinates ``q`` (N, n) from home (product of exponentials)."""
        q = np.atleast_2d(np.asarray(q, float))
        N = q.shape[0]
        Rg = np.broadcast_to(np.eye(3), (N, 3, 3)).copy()
        tg = np.zeros((N, 3))
        axes, points = [], []
        for m, (kind, a, c) in enumerate(self._free):
            aw = Rg @ a
            axes.append(aw)
            if kind == "P":
                points.append(None)
                tg = tg + aw * q[:, m:m + 1]
            else:
                cw = np.einsum("nij,j->ni", Rg, c) + tg
                points.append(cw)
                Rj = rot_axis(aw, q[:, m])
                tg = np.einsum("nij,nj->ni", Rj, tg - cw) + cw
                Rg = Rj @ Rg
        pos = np.einsum("nij,j->ni", Rg, self._home) + tg
        return pos, Rg, axes, points

    def _twists_at(self, axes, points, ref):
        cols = []
        for (kind, _, _), a, c in zip(self._free, axes, points):
            cols.append(prismatic_twist(a) if kind == "P" else revolute_twist(a, c, ref))
        return np.stack(cols, axis=1)  # (N, n, 6): (v_ref, w)

    def inverse(self, p, R, q0=None):
        """Joint coordinates (N, n) reaching the platform poses ``(p, R)`` and the residual (N,)
        of the damped Gauss-Newton solve (position / length scale, orientation in rad)."""
        p = np.atleast_2d(np.asarray(p, float))
        R = np.asarray(R, float).reshape(-1, 3, 3)
        N, n = p.shape[0], len(self._free)
        target = p + np.einsum("nij,j->ni", R, self.platform)
        q = np.zeros((N, n)) if q0 is None else np.array(q0, float)
        L = self._L
        res = np.full(N, np.inf)
        act = np.arange(N)  # the poses still solved: a converged or stalled pose leaves the batch
        last = np.full(N, np.inf)
        for it in range(IK_ITERATIONS + 1):
            pos, Rc, axes, points = self.forward(q[act])
            e = np.concatenate([(target[act] - pos) / L, _log_rot(R[act] @ np.transpose(Rc, (0, 2, 1)))], axis=1)
            r = np.max(np.abs(e), axis=1)
            res[act] = r
            # stalled: a least-squares minimum off the limb's reach (no progress in a step)
            keep = (r >= IK_TOL) & np.isfinite(r) & (r < last[act] * (1.0 - 1e-6))
            last[act] = r
            if it == IK_ITERATIONS or not np.any(keep):
                break
            J = self._twists_at(axes, points, pos).transpose(0, 2, 1)[keep]  # (k, 6, n)
            J[:, :3, :] /= L
            act, e = act[keep], e[keep]
            # damped normal equations, batched: (J^T J + mu I) dq = J^T e (mu tiny: the least-squares
            # step where J has full column rank, a minimum-norm-like one where it does not)
            JTJ = np.einsum("nki,nkj->nij", J, J)
            mu = 1e-12 * (1.0 + np.einsum("nii->n", JTJ))
            dq = np.linalg.solve(JTJ + mu[:, None, None] * np.eye(n), np.einsum("nki,nk->ni", J, e)[..., None])[..., 0]
            step = np.max(np.abs(dq), axis=1, keepdims=True)
            dq *= np.minimum(1.0, 0.5 / np.maximum(step, 1e-300))
            q[act] += dq
        return q, res

    def solve(self, p, R, joint_angles: bool = True):
        p = np.atleast_2d(np.asarray(p, float))
        R = np.asarray(R, float).reshape(-1, 3, 3)
        q, res = self.inverse(p, R)
        pos, Rc, axes, points = self.forward(q)
        reachable = res < 1e3 * IK_TOL
        first = next((c for c in points if c is not None), None)
        B = np.broadcast_to(self.base, pos.shape).copy() if first is None else first
        A = pos
        n = unit(A - B)
        length = np.linalg.norm(A - B, axis=-1)
        act = np.full(len(q), np.nan) if self._act is None else q[:, self._act] + self._act_home
        act = np.where(reachable, act, np.nan)
        angles = {}
        if joint_angles:
            for m, j in enumerate(self._joint_of):
                angles[f"{self._spec.joints[j]}{j}_{m}"] = q[:, m]
        st = LegState(act, reachable, B, A, n, length, angles)
        st.extra.update({"q": q, "axes": axes, "points": points, "residual": res})
        return st

    def joint_twists(self, st, P):
        return self._twists_at(st.extra["axes"], st.extra["points"], np.broadcast_to(P, st.platform_point.shape))

    def actuator_value(self, A, p, R):
        return self.solve(p, R).actuator

    def constraint_wrenches(self, st, P):
        """The wrenches reciprocal to every joint twist (unit force, or unit couple)."""
        T = self.joint_twists(st, P)
        L = self._L
        Ts = T.copy()
        Ts[..., 3:] *= L
        Vt, rank = null_space(Ts)
        c = 6 - int(np.max(rank)) if len(rank) else 0
        W = Vt[:, 6 - c:].copy() if c else np.zeros((T.shape[0], 0, 6))
        if c:
            W[..., 3:] *= L
            f = np.linalg.norm(W[..., :3], axis=-1)
            m = np.linalg.norm(W[..., 3:], axis=-1)
            couple = f <= 1e-9 * np.maximum(m / L, 1e-300)
            W[couple, :3] = 0.0
            W = W / np.where(couple, m, f)[..., None]
        return W

    def actuation_wrench(self, st, P):
        """The wrench reciprocal to every passive joint twist and not to the actuated one (and
        orthogonal to the constraint wrenches), as a unit force or couple; ``rate_scale`` its
        power on the actuated joint's unit twist."""
        if self._act is None:
            raise ChainError(f"leg {self.name}: a passive limb has no actuation wrench")
        T = self.joint_twists(st, P)
        L = self._L
        Ts = T.copy()
        Ts[..., 3:] *= L
        passive = np.delete(Ts, self._act, axis=1)
        C = self.constraint_wrenches(st, P).copy()
        C[..., 3:] /= L  # scaled like the twists' dual
        out = np.zeros((T.shape[0], 6))
        for i in range(T.shape[0]):
            # the wrenches reciprocal to the passive twists, less the constraint wrenches
            _, s, V = np.linalg.svd(np.vstack([passive[i], np.zeros((1, 6))]))
            rk = int(np.sum(s > 1e-9 * max(s[0], 1e-300)))
            ns = V[rk:]
            if C.shape[1]:
                Q, _ = np.linalg.qr(C[i].T)
                ns = ns - (ns @ Q) @ Q.T
            w = ns[int(np.argmax(np.linalg.norm(ns, axis=1)))]
            w = np.concatenate([w[:3], w[3:] * L])
            f, m = np.linalg.norm(w[:3]), np.linalg.norm(w[3:])
            out[i] = w / (f if f > 1e-9 * m / L else m)
        rate = np.einsum("ij,ij->i", out, T[:, self._act])
        sign = np.where(rate < 0, -1.0, 1.0)
        return out * sign[:, None], rate * sign


def _actuator_kind(spec: ChainSpec) -> str:
    """``slider`` (an actuated prismatic first joint), ``length`` (a prismatic joint further up
    the chain), ``angle`` (a revolute joint) or ``none`` (a passive limb)."""
    if spec.actuated is None:
        return "none"
    if spec.joints[spec.actuated] == "R":
        return "angle"
    return "slider" if spec.actuated == 0 else "length"


def chain_class(spec: str, *, axes=None, passive: bool = False, stations=None, capabilities=None,
                doc: str = "") -> type:
    """A leg type of its own (a subclass of :class:`ChainLeg`) for a joint string: its
    ``joints`` are the plain letters (``"RPUR"``), its defaults the given axis relations, and it
    declares its own ``capabilities`` (default: those of :class:`ChainLeg`)."""
    s = parse_chain(spec, axes=axes, passive=passive, stations=stations)
    caps = capabilities or ChainLeg.capabilities
    ns = {"joints": s.joints, "actuated": s.actuated, "capabilities": caps, "actuator_kind": _actuator_kind(s), "__doc__": doc or f"The {s.name} limb.",
          "__annotations__": {"chain": str, "axes": "tuple | None", "passive": bool, "stations": "tuple | None"}}
    ns.update(chain=spec if "*" in spec or passive else s.name, axes=None if axes is None else tuple(axes),
              passive=passive, stations=None if stations is None else tuple(stations))
    cls = type(s.joints, (ChainLeg,), ns)
    cls.__module__ = __name__
    cls = dataclass(frozen=True)(cls)
    cls.constraint_rows = _constraint_kinds(cls)
    return cls


def _constraint_kinds(cls) -> tuple[str, ...]:
    """The kinds of the constraint wrenches of a chain limb type at a generic anchor and pose:
    ``angle`` for a couple, ``length`` for a force (its ``constraint_rows``)."""
    leg = cls("generic", base=[0.3 * math.cos(0.4), 0.3 * math.sin(0.4), 0.0], platform=[0.15, 0.02, 0.0])
    p, R = np.array([[0.0, 0.0, 0.4]]), np.eye(3)[None]
    W = leg.constraint_wrenches(leg.solve(p, R), p)[0]
    return tuple("angle" if np.linalg.norm(w[:3]) < 1e-9 else "length" for w in W)


def register_chain(spec: str, **kw) -> type:
    """:func:`chain_class` added to :data:`parasynth.model.legs.LEG_TYPES` under its joint
    letters (a hand-written leg type of the same letters is not replaced: :class:`ChainError`)."""
    cls = chain_class(spec, **kw)
    old = LEG_TYPES.get(cls.joints)
    if old is not None and not issubclass(old, ChainLeg):
        raise ChainError(f"joint string {spec!r}: {cls.joints} is a hand-written leg type already; its chain limb "
                         f"would replace a closed form")
    LEG_TYPES[cls.joints] = cls
    return cls


#: The chain limbs of the vocabulary (docs/structures.md, "Limbs from joint strings"): their axes
#: as in the type synthesis of 3T2R mechanisms (Masouleh, Gosselin et al.): the base-side
#: revolute axes all along x, the platform-side ones along the platform's y, so that every limb
#: imposes the same couple about x x (R y) and the platform turns about x and the moving y.
_3T2R_AXES = ("x", "parallel:prev", "normal:prev&normal:base_normal", "parallel:prev")
RPUR = register_chain("RP*UR", axes=(_3T2R_AXES[0], "limb") + _3T2R_AXES[1:], stations=(0.0, 0.8, 1.0),
                      capabilities=LegCapabilities(stiffness=True),
                      doc="revolute (x), actuated prismatic along the limb, universal (x, then y), revolute (the "
                          "platform's y): one constraint couple about x x (R y) -- the limb of the 5-RPUR")
PRUR = register_chain("P*RUR", axes=("base_normal",) + _3T2R_AXES, stations=(0.0, 0.3, 1.0),
                      capabilities=LegCapabilities(stiffness=True),
                      doc="actuated slider along the base normal, revolute (x), universal (x, then y), revolute "
                          "(the platform's y): one constraint couple about x x (R y) -- the limb of the 5-PRUR")
SPU = register_chain("SP*U", axes=("limb", "tangent", "normal:prev&normal:limb"),
                     capabilities=LegCapabilities(stiffness=True),
                     doc="spherical, actuated prismatic, universal (the platform's tangent, then normal to it and the "
                         "limb): six freedoms -- the inversion of the UPS, the limb of the 6-SPU")
RRPS = register_chain("RRP*S", axes=("tangent", "normal:prev&normal:limb", "limb"), stations=(0.0, 0.1, 1.0),
                      capabilities=LegCapabilities(stiffness=True),
                      doc="revolute (tangent) at the base anchor, revolute normal to it and the limb a tenth of the "
                          "limb further (an offset universal joint), actuated prismatic, spherical: six freedoms -- "
                          "the limb of a 6-RRPS")
__all__ += ["register_chain", "RPUR", "PRUR", "SPU", "RRPS"]
