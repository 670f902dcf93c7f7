"""The ``constraints:`` section: each entry becomes a constraint of
:mod:`parasynth.model.constraints`, or an :class:`ExpressionConstraint` for ``type: expression``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Callable, ClassVar

import numpy as np

from ...model.constraints import (ActuatorRange, Constraint, CoordinateRange, JointAngleLimit, LegAxisAngle,
                                  LegInterference, LegLengthRange, SingularityMarginFloor)
from ...model.mechanism import Mechanism
from ...common.units import format_quantity
from .errors import DescriptionError
from .expressions import Expression, POSE_NAMES, R_NAMES, _Scope
from .parameters import _Scalar, _check_keys
from .legs import _ANCHOR_AXES, _Axis
from .task import _Task


_CONSTRAINT_KEYS = {
    "actuator_range": {"min", "max"},
    "leg_length": {"legs", "min", "max"},
    "joint_angle": {"key", "legs", "min", "max"},
    "interference": {"diameter", "legs", "pairs"},
    "leg_axis_angle": {"legs", "axis", "frame", "max"},
    "coordinate_range": {"coordinate", "min", "max"},
    "expression": {"margin", "unit"},
    "singularity_margin": {"min"},
}
_CONSTRAINT_REQUIRED = {"leg_length": {"legs"}, "joint_angle": {"key"}, "interference": {"diameter"},
                        "leg_axis_angle": {"legs", "axis", "max"}, "coordinate_range": {"coordinate"},
                        "expression": {"margin"}, "singularity_margin": {"min"}}


@dataclass(frozen=True)
class ExpressionConstraint(Constraint):
    """A margin given as an expression of the parameters, task coordinates, defined names and
    the platform pose (``px, py, pz`` and ``R11 .. R33``), >= 0 where feasible."""

    reads_angles: ClassVar[bool] = False

    text: str = ""
    evaluate: Callable | None = dataclasses.field(default=None, repr=False, compare=False)
    unit: str = "1"

    def margin(self, ctx):
        return np.asarray(self.evaluate(ctx), dtype=float) * np.ones(ctx.X.shape[0])


def _check_kind_of_parameters(raw, kind: str, path: str, scope: _Scope) -> None:
    """Refuse a bound written as one parameter (or a sign and one parameter) of another kind than
    ``kind``: a crank range given a length, a stroke given an angle."""
    if not isinstance(raw, str):
        return
    name = raw.strip().lstrip("+-").strip()
    have = scope.kinds.get(name) if scope is not None else None
    if have in ("length", "angle") and have != kind:
        what = "crank angles (RUS legs)" if kind == "angle" else "lengths (leg lengths or slider positions)"
        raise DescriptionError(f"{path}: parameters.{name} is {'an' if have == 'angle' else 'a'} {have}, and this "
                               f"mechanism's actuators are {what}; give {'an' if kind == 'angle' else 'a'} {kind}")


def _exact(v):
    """A bound as a key that tells every float apart: a zero with its sign (0.0 == -0.0)."""
    return (v, math.copysign(1.0, v)) if v == 0 else v


class _ConstraintSpec:
    def __init__(self, i, raw, leg_names, task: _Task, pscope: _Scope, actuator_kind: str | None = "length"):
        path = f"constraints[{i}]"
        if not isinstance(raw, dict):
            raise DescriptionError(f"{path}: a constraint is a mapping with name and type, got {raw!r}")
        name = raw.get("name")
        if not isinstance(name, str) or not name:
            raise DescriptionError(f"{path}.name: required (a unique name such as 'stroke')")
        path = f"{path} ({name})"
        t = raw.get("type")
        if t not in _CONSTRAINT_KEYS:
            raise DescriptionError(f"{path}.type: unknown constraint type {t!r}; allowed: {', '.join(_CONSTRAINT_KEYS)}")
        _check_keys(raw, {"name", "type", "doc"} | _CONSTRAINT_KEYS[t], path, f"the {t} constraint")
        for k in sorted(_CONSTRAINT_REQUIRED.get(t, set()) - set(raw)):
            raise DescriptionError(f"{path}.{k}: required key of the {t} constraint is missing")
        self.name, self.type, self.path = name, t, path
        self.doc = str(raw.get("doc", ""))

        def legs_list(key):
            v = raw.get(key, [])
            if isinstance(v, str):
                v = [v]
            if not isinstance(v, list):
                raise DescriptionError(f"{path}.{key}: give a list of leg names")
            for n in v:
                if n not in leg_names:
                    raise DescriptionError(f"{path}.{key}: unknown leg {n!r}; legs: {', '.join(leg_names)}")
            return tuple(v)

        self.legs = legs_list("legs") if "legs" in _CONSTRAINT_KEYS[t] else ()
        kind = {"actuator_range": "length", "leg_length": "length", "joint_angle": "angle",
                "leg_axis_angle": "angle", "interference": "length"}.get(t)
        if t == "actuator_range":
            # The range of every actuator: lengths (m) for leg lengths and slider positions, angles
            # (rad) for cranks; one range cannot hold both.
            if actuator_kind == "mixed":
                raise DescriptionError(f"{path}: an actuator_range applies to every actuator, and this mechanism's "
                                       f"actuators are both lengths (legs, sliders) and crank angles (RUS legs); "
                                       f"limit the lengths with leg_length constraints instead")
            kind = "angle" if actuator_kind == "angle" else "length"
            for key in ("min", "max"):
                if key in raw:
                    _check_kind_of_parameters(raw[key], kind, f"{path}.{key}", pscope)
        self.actuator_kind = kind
        if t == "coordinate_range":
            c = raw["coordinate"]
            if c not in task.kinds:
                raise DescriptionError(f"{path}.coordinate: {c!r} is not a task coordinate; coordinates: "
                                       f"{', '.join(task.names)}")
            self.coordinate = c
            kind = task.kinds[c]
        self.min = _Scalar(raw["min"], kind, f"{path}.min", pscope) if "min" in raw else None
        self.max = _Scalar(raw["max"], kind, f"{path}.max", pscope) if "max" in raw else None
        if t == "interference":
            self.diameter = _Scalar(raw["diameter"], "length", f"{path}.diameter", pscope)
            pairs = raw.get("pairs", [])
            if not isinstance(pairs, list) or any(not isinstance(p, list) or len(p) != 2 for p in pairs):
                raise DescriptionError(f"{path}.pairs: give a list of [leg, leg] pairs")
            for p in pairs:
                for n in p:
                    if n not in leg_names:
                        raise DescriptionError(f"{path}.pairs: unknown leg {n!r}; legs: {', '.join(leg_names)}")
            self.pairs = tuple(tuple(p) for p in pairs)
        if t == "joint_angle":
            if not isinstance(raw["key"], str):
                raise DescriptionError(f"{path}.key: give a joint angle name such as 'S_platform_cone'")
            self.key = raw["key"]
        if t == "leg_axis_angle":
            self.axis = _Axis(raw["axis"], f"{path}.axis", pscope)
            if self.axis.named is not None and self.axis.named[1] in _ANCHOR_AXES:
                raise DescriptionError(f"{path}.axis: give x, y, z or [ax, ay, az] (anchor directions do not apply)")
            self.frame = raw.get("frame", "base")
            if self.frame not in ("base", "platform"):
                raise DescriptionError(f"{path}.frame: base or platform, got {self.frame!r}")
        if t == "expression":
            escope = task.pose_scope.extended("platform pose", POSE_NAMES)
            self.expr = Expression(raw["margin"], f"{path}.margin", escope)
            unit = raw.get("unit", "1")
            if unit not in ("m", "rad", "1"):
                raise DescriptionError(f"{path}.unit: the margin's unit: m, rad or 1, got {unit!r}")
            self.unit = unit

    def inputs(self) -> tuple | None:
        """The parameters the built constraint depends on (its bounds' and diameter's
        expressions' names), or None where it depends on more (an ``expression`` constraint
        reads the mechanism, a ``leg_axis_angle`` its axis)."""
        if self.type in ("expression", "leg_axis_angle"):
            return None
        scalars = [self.min, self.max, self.diameter if self.type == "interference" else None]
        return tuple(sorted({n for sc in scalars if sc is not None and sc.expr is not None for n in sc.expr.names}))

    def build(self, mech: Mechanism) -> Constraint:
        """The constraint for the described mechanism ``mech`` (a ``DescribedMechanism``): for
        every type but ``expression`` (whose margin reads ``mech``) one object per value of its
        bounds and sizes, shared by the mechanisms that give the same values -- constraints are
        frozen values, and a study's designs mostly share them (the engine then finds its check
        tables for them again, :func:`parasynth.engine.core.leg_tables`)."""
        env = mech._penv
        lo = self.min(env) if self.min is not None else None
        hi = self.max(env) if self.max is not None else None
        if lo is not None and hi is not None and not lo < hi:
            raise DescriptionError(f"{self.path}: min ({lo:g}) must be below max ({hi:g}) (SI)")
        if self.type == "expression":
            return self._build(mech, env, lo, hi)
        key = (_exact(lo), _exact(hi), _exact(self.diameter(env)) if self.type == "interference" else None,
               tuple(map(_exact, self.axis(env, None, 0).tolist())) if self.type == "leg_axis_angle" else None)
        memo = self.__dict__.setdefault("_built", {})
        hit = memo.get(key)
        if hit is None:
            hit = self._build(mech, env, lo, hi)
            if len(memo) >= 64:
                memo.clear()
            memo[key] = hit
        return hit

    def _build(self, mech: Mechanism, env, lo, hi) -> Constraint:
        lo_ = -np.inf if lo is None else lo
        hi_ = np.inf if hi is None else hi
        t = self.type
        if t == "actuator_range":
            if self.actuator_kind == "angle":
                # Crank angles are wrapped to (-pi, pi]: a range beyond it would never be reached.
                for key, v in (("min", lo), ("max", hi)):
                    if v is not None and not -np.pi <= v <= np.pi:
                        raise DescriptionError(f"{self.path}.{key}: a crank angle range lies within "
                                               f"[-180 deg, 180 deg] (crank angles are wrapped to (-180, 180] deg), "
                                               f"got {format_quantity(v, 'angle')}")
                return ActuatorRange(self.name, lo=-np.inf if lo is None else lo, hi=hi_, doc=self.doc, unit="rad")
            return ActuatorRange(self.name, lo=-np.inf if lo is None else lo, hi=hi_, doc=self.doc)
        if t == "leg_length":
            return LegLengthRange(self.name, legs=self.legs, lo=-np.inf if lo is None else lo, hi=hi_, doc=self.doc)
        if t == "joint_angle":
            return JointAngleLimit(self.name, key=self.key, lo=lo_, hi=hi_, legs=self.legs, doc=self.doc)
        if t == "interference":
            return LegInterference(self.name, diameter=self.diameter(env), legs=self.legs, pairs=self.pairs,
                                   doc=self.doc)
        if t == "leg_axis_angle":
            ax = self.axis(env, None, 0)
            return LegAxisAngle(self.name, legs=self.legs, axis=tuple(float(v) for v in ax / np.linalg.norm(ax)),
                                frame=self.frame, hi=hi_, doc=self.doc)
        if t == "singularity_margin":
            try:
                return SingularityMarginFloor(self.name, floor=lo, doc=self.doc or f"singularity margin >= {lo:g}")
            except ValueError as e:
                raise DescriptionError(f"{self.path}.min: {e}") from None
        if t == "coordinate_range":
            unit = "rad" if mech.description.task.kinds[self.coordinate] == "angle" else "m"
            return CoordinateRange(self.name, unit=unit, index=mech.task_coordinates.index(self.coordinate),
                                   lo=lo_, hi=hi_, doc=self.doc)
        expr = self.expr

        def evaluate(ctx, _mech=mech, _expr=expr):
            env = _mech._task_env(ctx.X)
            for k, nm in enumerate(("px", "py", "pz")):
                env[nm] = ctx.p[:, k]
            for nm in R_NAMES:
                env[nm] = ctx.R[:, int(nm[1]) - 1, int(nm[2]) - 1]
            with np.errstate(all="ignore"):
                return _expr(env)

        return ExpressionConstraint(self.name, unit=self.unit, doc=self.doc or f"margin {expr.text}",
                                    text=expr.text, evaluate=evaluate)
