"""Pose constraints as margins (>= 0 feasible), vectorised over poses.

A constraint is a *condition* on a pose (CASPR's workspace conditions): given the legs'
inverse kinematics at N poses it returns a margin (N,) in its own unit (m or rad), positive
inside the feasible set, negative outside, and -inf for poses the legs cannot reach at all.
A model declares its constraints from its parameters; ``Mechanism.constraint_margins`` and
``Mechanism.is_feasible`` evaluate them. Limits a paper states are the defaults of the model
parameters; limits it does not state are parameters with documented defaults.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations
from typing import ClassVar

import numpy as np

from .legs import LegState
from .spatial import segment_distance

__all__ = [
    "Constraint",
    "ActuatorRange",
    "LegLengthRange",
    "JointAngleLimit",
    "LegInterference",
    "LegAxisAngle",
    "CoordinateRange",
    "SingularityMarginFloor",
    "PoseContext",
    "feasible_rows",
    "leg_gate",
    "state_rows",
]


@dataclass
class PoseContext:
    """What constraints need at N poses: task poses, platform position and orientation,
    per-leg states, the joint reachability of every leg and the mechanism evaluated (for the
    constraints on the wrench system, :class:`SingularityMarginFloor`)."""

    X: np.ndarray
    p: np.ndarray
    R: np.ndarray
    legs: list  # Leg objects
    states: list[LegState]
    reachable: np.ndarray
    actuators: np.ndarray  # (N, n_act)
    mechanism: object = None

    def state(self, leg_name: str) -> LegState:
        for leg, st in zip(self.legs, self.states):
            if leg.name == leg_name:
                return st
        raise KeyError(leg_name)

    def rows(self, idx) -> "PoseContext":
        """The context at the poses ``idx`` (indices into the N poses): every per-pose array
        (leading dimension N, also inside a state's ``angles`` and ``extra``) taken at ``idx``.
        A constraint's margin is a function of each pose alone, so ``c.margin(ctx.rows(idx))``
        is ``c.margin(ctx)[idx]``: the feasibility tests evaluate a constraint only at the poses
        the constraints before it left feasible."""
        idx = np.asarray(idx)
        N = self.X.shape[0]
        states = [state_rows(st, idx, N) for st in self.states]
        return PoseContext(self.X[idx], self.p[idx], self.R[idx], self.legs, states, self.reachable[idx],
                           _take(self.actuators, idx, N), self.mechanism)


def state_rows(st: LegState, idx, N: int) -> LegState:
    """The leg state ``st`` of N poses at the poses ``idx``: every per-pose array (leading
    dimension N, also inside ``angles`` and ``extra``) taken at ``idx``."""
    return LegState(*(_take(getattr(st, f), idx, N) for f in ("actuator", "reachable", "base_point",
                                                              "platform_point", "direction", "length")),
                    _take(st.angles, idx, N), _take(st.extra, idx, N))


def _take(v, idx, N: int):
    """``v`` at the poses ``idx``: an array of leading dimension N indexed, a list, tuple or dict
    taken item by item, anything else (None, constants) kept."""
    if isinstance(v, np.ndarray):
        return v[idx] if v.ndim and v.shape[0] == N else v
    if isinstance(v, dict):
        return {k: _take(x, idx, N) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return type(v)(_take(x, idx, N) for x in v)
    return v


def feasible_rows(ctx: PoseContext, constraints) -> np.ndarray:
    """Whether each pose of ``ctx`` is reachable and meets every constraint (N,): each
    constraint evaluated at the poses the ones before it left feasible only (all of them while
    at least half are; a margin is a function of each pose alone, so the answer is the one
    of every constraint at every pose)."""
    ok = np.asarray(ctx.reachable, dtype=bool).copy()
    N = ok.shape[0]
    with np.errstate(invalid="ignore"):
        for c in constraints:
            live = np.flatnonzero(ok)
            if not live.size:
                break
            if 2 * live.size >= N:
                ok &= np.asarray(c.margin(ctx)) >= 0
            else:
                ok[live] = np.asarray(c.margin(ctx.rows(live))) >= 0
    return ok


def leg_gate(constraints, leg, st: LegState) -> np.ndarray | None:
    """Where the state ``st`` (N poses) of ``leg`` alone leaves every constraint of
    ``constraints`` possibly met (N,) bool; None when none of them looks at that leg alone.

    The constraints whose margin is the least of per-leg parts (:class:`ActuatorRange`,
    :class:`LegLengthRange`, :class:`JointAngleLimit`, exactly these classes) break at a pose
    where one leg's part is negative (or NaN): such a pose is infeasible whatever the other
    legs do, so a feasibility test may skip solving the other legs there (the chain limbs'
    numerical inverse kinematics, :func:`parasynth.engine.chains.feasible`). The answer is that
    of :func:`feasible_rows` on the full context."""
    ok = None
    with np.errstate(invalid="ignore"):
        for c in constraints:
            part = c.leg_part(leg, st) if type(c) in _PER_LEG else None
            if part is not None:
                ok = (part >= 0) if ok is None else ok & (part >= 0)
    return ok


def _within(v, lo, hi):
    """The margin of values ``v`` inside [lo, hi]: min(v - lo, hi - v)."""
    return np.minimum(v - lo, hi - v)


@dataclass(frozen=True)
class Constraint:
    """Base class: ``name`` (unique in a mechanism), ``unit`` of the margin, ``doc``.

    ``reads_angles``: whether the margin reads the legs' passive joint angles (``LegState.angles``);
    a pose context for constraints that do not is built without them (the chain engine's
    feasibility and margins: the angles are most of a closed-form leg's NumPy solve, and a chain
    limb's frames). True unless a class says otherwise, so that a constraint written elsewhere
    gets them."""

    reads_angles: ClassVar[bool] = True

    name: str
    unit: str = "m"
    doc: str = ""

    def margin(self, ctx: PoseContext) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError


@dataclass(frozen=True)
class ActuatorRange(Constraint):
    """Every actuator value within [lo, hi] (m): margin min_i min(q_i - lo, hi - q_i)."""

    reads_angles: ClassVar[bool] = False

    lo: float = 0.0
    hi: float = np.inf

    def margin(self, ctx):
        return np.min(_within(ctx.actuators, self.lo, self.hi), axis=1)

    def leg_part(self, leg, st):
        """The margin's part of ``leg`` alone (its actuator), None for a passive leg."""
        return _within(st.actuator, self.lo, self.hi) if leg.is_actuated else None


@dataclass(frozen=True)
class LegLengthRange(Constraint):
    """Distance between the end joint centres of the named legs within [lo, hi] (m) -- for
    passive legs whose stroke is limited (e.g. the grinding robot's d2)."""

    reads_angles: ClassVar[bool] = False

    legs: tuple[str, ...] = ()
    lo: float = 0.0
    hi: float = np.inf

    def margin(self, ctx):
        m = [_within(ctx.state(n).length, self.lo, self.hi) for n in self.legs]
        return np.min(np.stack(m, 1), axis=1)

    def leg_part(self, leg, st):
        """The margin's part of ``leg`` alone, None for a leg it does not name."""
        return _within(st.length, self.lo, self.hi) if leg.name in self.legs else None


@dataclass(frozen=True)
class JointAngleLimit(Constraint):
    """Passive joint angles ``key`` (e.g. "S_platform_cone", "U_base_1") of the named legs
    (all legs that have it when ``legs`` is empty) within [lo, hi] rad."""

    key: str = ""
    lo: float = -np.inf
    hi: float = np.inf
    legs: tuple[str, ...] = ()
    unit: str = "rad"

    def margin(self, ctx):
        vals = [v for v in (self.leg_part(leg, st) for leg, st in zip(ctx.legs, ctx.states)) if v is not None]
        if not vals:
            raise ValueError(f"constraint {self.name!r}: no leg has a joint angle {self.key!r}")
        return np.min(np.stack(vals, 1), axis=1)

    @property
    def vacuous(self) -> bool:
        """Whether the limit holds at every pose a leg reaches: a cone angle (a key ending in
        ``_cone``: the angle between two directions, in [0, pi]) limited to a range that holds
        [0, pi] (a study's ``platform_joint_max: 180 deg``, no limit)."""
        return self.key.endswith("_cone") and self.lo <= 0.0 and self.hi >= np.pi

    def leg_part(self, leg, st):
        """The margin's part of ``leg`` alone, None for a leg it does not name or without the angle."""
        if (not self.legs or leg.name in self.legs) and self.key in st.angles:
            return _within(st.angles[self.key], self.lo, self.hi)
        return None


@dataclass(frozen=True)
class LegInterference(Constraint):
    """Leg-leg interference: the minimum distance between the centre lines of leg segments
    (base joint centre to platform joint centre) minus ``diameter`` (m), over ``pairs``
    (default: every pair of the named legs, or of all legs). The 2022 paper's D <= D_i of
    eq. (9) with D the cylinder diameter."""

    reads_angles: ClassVar[bool] = False

    diameter: float = 0.0
    legs: tuple[str, ...] = ()
    pairs: tuple[tuple[str, str], ...] = ()

    def _pairs(self, names):
        if self.pairs:
            return self.pairs
        use = self.legs or tuple(names)
        return tuple(combinations(use, 2))

    def distances(self, ctx) -> np.ndarray:
        """The distances (N, pairs) of the pairs' centre lines, all pairs in one vectorised
        :func:`segment_distance` (the same arithmetic, pose by pose and pair by pair, as one
        call per pair)."""
        names = [leg.name for leg in ctx.legs]
        pairs = self._pairs(names)
        used = list(dict.fromkeys(n for pair in pairs for n in pair))
        at = {n: k for k, n in enumerate(used)}
        sts = [ctx.state(n) for n in used]
        B = np.stack([st.base_point for st in sts], 1)
        P = np.stack([st.platform_point for st in sts], 1)
        ia = [at[a] for a, _ in pairs]
        ib = [at[b] for _, b in pairs]
        return segment_distance(B[:, ia], P[:, ia], B[:, ib], P[:, ib])

    def margin(self, ctx):
        return np.min(self.distances(ctx), axis=1) - self.diameter


@dataclass(frozen=True)
class LegAxisAngle(Constraint):
    """Angle between the leg line (base -> platform) of the named legs and an axis, at most
    ``hi`` rad. The axis is fixed in the base frame (``frame="base"``) or in the platform
    (``frame="platform"``, rotated with it). This is the form of the 2022 paper's eq. (9)
    joint-angle rows, e.g. phi_i^m = arccos(L_i . R n_mi / l_i) with n_mi = (0, 1, 0)."""

    reads_angles: ClassVar[bool] = False

    legs: tuple[str, ...] = ()
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    frame: str = "base"
    hi: float = np.pi
    unit: str = "rad"

    def angles(self, ctx) -> np.ndarray:
        a = np.asarray(self.axis, dtype=float)
        a = a / np.linalg.norm(a)
        ax = ctx.R @ a if self.frame == "platform" else np.broadcast_to(a, ctx.p.shape)
        out = []
        for name in self.legs:
            n = ctx.state(name).direction
            out.append(np.arccos(np.clip(np.sum(n * ax, -1), -1.0, 1.0)))
        return np.stack(out, 1)

    def margin(self, ctx):
        return self.hi - np.max(self.angles(ctx), axis=1)


@dataclass(frozen=True)
class CoordinateRange(Constraint):
    """A task coordinate (column ``index``) within [lo, hi] (its own unit)."""

    reads_angles: ClassVar[bool] = False

    index: int = 0
    lo: float = -np.inf
    hi: float = np.inf

    def margin(self, ctx):
        x = ctx.X[:, self.index]
        return np.minimum(x - self.lo, self.hi - x)


@dataclass(frozen=True)
class SingularityMarginFloor(Constraint):
    """The normalised singularity margin (:meth:`Mechanism.singularity_margin`, 0 at a
    singularity) at or above ``floor``: margin ``singularity_margin - floor`` (dimensionless).

    With it every workspace measure is taken over well-conditioned poses only. The NumPy
    reference computes the margin from the legs' states of the pose context
    (``PoseContext.mechanism`` is the mechanism evaluated); the compiled engine applies the
    floor with its singularity-margin kernel to the poses its feasibility kernel accepts
    (docs/architecture.md)."""

    reads_angles: ClassVar[bool] = False

    floor: float = 0.0
    unit: str = "1"

    def __post_init__(self):
        f = self.floor
        if isinstance(f, (bool, np.bool_)) or not isinstance(f, (int, float, np.integer, np.floating)) \
                or not np.isfinite(f) or not 0.0 <= f < 1.0:
            raise ValueError(f"constraint {self.name!r}: the singularity-margin floor must be a number in [0, 1) "
                             f"(the margin is a normalised singular value), got {f!r}")
        object.__setattr__(self, "floor", float(f))

    def margin(self, ctx):
        mech = ctx.mechanism
        if mech is None:
            raise ValueError(f"constraint {self.name!r}: the pose context carries no mechanism")
        m = mech.singularity_margin_of_states(ctx.states, ctx.p, ctx.reachable)
        return m - self.floor


#: The constraints whose margin is the least of their legs' parts (``leg_part``), read by
#: :func:`leg_gate` (exactly these classes: a subclass may change its margin).
_PER_LEG = (ActuatorRange, LegLengthRange, JointAngleLimit)
