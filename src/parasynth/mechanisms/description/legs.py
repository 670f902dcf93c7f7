"""The ``legs:`` section: leg types of :mod:`parasynth.model.legs`, their options (joint axes,
link lengths, branches), anchor references and the actuated joint.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ...model.legs import _DOWN, _UP, LEG_TYPES, types_with
from .errors import DescriptionError
from .parameters import _Scalar, _check_keys
from .anchors import _Anchors, _PLANES, _float_directions

#: Options of each leg type: {key: "axis_base" | "axis_platform" | "length" | "branch"}, as the
#: leg types declare them (``description_options``, ``required_options``).
LEG_OPTIONS = {name: dict(cls.description_options) for name, cls in LEG_TYPES.items()
               if cls.description_options is not None}
_LEG_REQUIRED = {name: cls.required_options for name, cls in LEG_TYPES.items() if cls.required_options}


def _sync_options() -> None:
    """Add the leg types registered since import (``parasynth.model.chains.register_chain``) to
    :data:`LEG_OPTIONS` (in place)."""
    for name, cls in LEG_TYPES.items():
        if name not in LEG_OPTIONS and cls.description_options is not None:
            LEG_OPTIONS[name] = dict(cls.description_options)
            if cls.required_options:
                _LEG_REQUIRED[name] = cls.required_options
#: Names of the joints the leg library actuates, for messages.
_JOINT_WORDS = {"P": "prismatic", "R": "revolute"}
#: Leg types the leg library can build without an actuator (a constraining limb).
PASSIVE_CAPABLE = types_with("passive")
_LEG_COMMON = {"type", "name", "names", "base", "platform", "actuated", "doc"}
_NAMED_AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}
_ANCHOR_AXES = ("radial", "tangent", "normal")
_REF_RE = re.compile(r"^\s*([A-Za-z_]\w*)\s*(?:\[\s*(-?\d+(?:\s*,\s*-?\d+)*)\s*,?\s*\])?\s*$")


class _Axis:
    """A direction: a named axis (x, -y, ...), a direction of the leg's anchor (radial,
    tangent, normal, with an optional sign) or [ax, ay, az] (numbers or expressions)."""

    def __init__(self, raw, path, scope):
        self.path = path
        self.named = None
        self.vector = None
        self.constant = None  # a named axis (x, -y, ...): the same read-only vector for every leg
        self.constant_floats = None  # and its three floats
        if isinstance(raw, str):
            s = raw.strip()
            sign = -1.0 if s.startswith("-") else 1.0
            key = s.lstrip("+-").strip()
            if key in _NAMED_AXES or key in _ANCHOR_AXES:
                self.named = (sign, key)
                if key in _NAMED_AXES:
                    self.constant = sign * np.array(_NAMED_AXES[key], dtype=float)
                    self.constant.flags.writeable = False
                    self.constant_floats = tuple(self.constant.tolist())
                return
            raise DescriptionError(f"{path}: unknown direction {raw!r}; give x, y, z, radial, tangent or normal "
                                   f"(optionally with a sign, e.g. -z) or [ax, ay, az]")
        if isinstance(raw, list) and len(raw) == 3:
            self.vector = [_Scalar(v, "dimensionless", f"{path}[{i}]", scope) for i, v in enumerate(raw)]
            return
        raise DescriptionError(f"{path}: expected a direction (x, y, z, radial, tangent, normal or [ax, ay, az]), "
                               f"got {raw!r}")

    def __call__(self, env, anchors: _Anchors, k: int) -> np.ndarray:
        """The direction for anchor ``k`` of ``anchors`` (read-only for a named axis: the leg
        that takes it normalises it into an array of its own)."""
        if self.constant is not None:
            return self.constant
        if self.vector is not None:
            v = np.array([s(env) for s in self.vector])
        else:
            sign, key = self.named
            if key in _NAMED_AXES:
                v = sign * np.array(_NAMED_AXES[key], dtype=float)
            else:
                v = sign * (anchors.normal if key == "normal" else getattr(anchors, key)[k])
                x, y, z = v.tolist()  # three floats: Python's tests cost a tenth of NumPy's reductions
                if not (x or y or z):
                    raise DescriptionError(f"{self.path}: {key!r} is undefined for an anchor on the axis of its "
                                           f"set's plane (point {anchors.points[k].tolist()}); give the direction")
        x, y, z = v.tolist()
        if not x * x + y * y + z * z > 0:  # np.linalg.norm(v) > 0: the same squares and sum
            raise DescriptionError(f"{self.path}: the direction must not be zero")
        return v

    def floats(self, env, anchors: _Anchors, k: int):
        """The direction of :meth:`__call__` as three floats, read from the anchors' rows; None
        where :meth:`__call__` refuses it (it then says why)."""
        if self.constant_floats is not None:
            return self.constant_floats
        if self.vector is not None:
            x, y, z = (float(s(env)) for s in self.vector)
        else:  # a direction of the anchor (a named axis x, y, z is a constant)
            sign, key = self.named
            r = anchors.normal_row if key == "normal" else (anchors.radial_rows if key == "radial"
                                                             else anchors.tangent_rows)[k]
            x, y, z = sign * r[0], sign * r[1], sign * r[2]
        if not x * x + y * y + z * z > 0:
            return None
        return x, y, z


class _Ref:
    """A leg's reference to anchors: a set (all points, or listed indices) or an inline point."""

    def __init__(self, raw, side, path, sets, scope):
        self.path, self.side = path, side
        self.set = None
        self.indices = None
        self.point = None
        if raw is None:
            raise DescriptionError(f"{path}: missing anchor; give a {side} anchor set "
                                   f"({', '.join(sets) or 'none defined'}) or a point [x, y, z]")
        if isinstance(raw, list):
            if len(raw) != 3 or any(isinstance(v, (list, dict)) for v in raw):
                raise DescriptionError(f"{path}: an inline anchor is one point [x, y, z] with units, got {raw!r}")
            self.point = [_Scalar(v, "length", f"{path}[{i}]", scope) for i, v in enumerate(raw)]
            self.n = 1
            return
        m = _REF_RE.match(raw) if isinstance(raw, str) else None
        if m is None:
            raise DescriptionError(f"{path}: expected an anchor set name such as 'B', 'B[2]' or 'B[1, 2, 0]', "
                                   f"or a point [x, y, z], got {raw!r}")
        name = m.group(1)
        if name not in sets:
            raise DescriptionError(f"{path}: unknown {side} anchor set {name!r}; {side} sets: "
                                   f"{', '.join(sets) or '(none)'}")
        self.set = name
        size = sets[name]
        if m.group(2) is not None:
            idx = [int(x) for x in m.group(2).split(",")]
            bad = [i for i in idx if not -size <= i < size]
            if bad:
                raise DescriptionError(f"{path}: index {bad[0]} is out of range for {side} set {name!r} of "
                                       f"{size} point(s)")
            self.indices = [i % size for i in idx]
        else:
            self.indices = list(range(size))
        self.n = len(self.indices)

    def resolve(self, env, built: dict) -> _Anchors:
        """The anchors referred to, as arrays the caller's legs may keep (the set's own when it
        refers to every point in order: the set was built for this mechanism)."""
        if self.point is not None:
            return _float_directions([[float(s(env)) for s in self.point]], _PLANES["xy"])
        a = built[self.set]
        i = self.indices
        if self.__dict__.get("_all") is None:
            self._all = i == list(range(len(a.rows)))
        if self._all:
            return a
        return a.subset(i)


class _LegGroup:
    def __init__(self, i, raw, base_sets, plat_sets, scope, first_index):
        path = f"legs[{i}]"
        if not isinstance(raw, dict):
            raise DescriptionError(f"{path}: a leg is a mapping with type, base, platform, ..., got {raw!r}")
        self.base = _Ref(raw.get("base"), "base", f"{path}.base", base_sets, scope)
        self.platform = _Ref(raw.get("platform"), "platform", f"{path}.platform", plat_sets, scope)
        nb, nplat = self.base.n, self.platform.n
        if nb != nplat and 1 not in (nb, nplat):
            raise DescriptionError(f"{path}.platform: {nplat} platform anchor(s) for {nb} base anchor(s): the counts "
                                   f"must match (one leg per pair), or one side must be a single point")
        self.n = max(nb, nplat)
        if "name" in raw and "names" in raw:
            raise DescriptionError(f"{path}: give name (one leg) or names (a group), not both")
        if "name" in raw:
            if self.n != 1:
                raise DescriptionError(f"{path}.name: this entry makes {self.n} legs; give names: [...] with "
                                       f"{self.n} names, or leave it out for L{first_index}..L{first_index + self.n - 1}")
            names = [raw["name"]]
        elif "names" in raw:
            names = raw["names"]
            if not isinstance(names, list) or len(names) != self.n:
                raise DescriptionError(f"{path}.names: this entry makes {self.n} legs; give {self.n} names, got {names!r}")
        else:
            names = [f"L{first_index + j}" for j in range(self.n)]
        for nm in names:
            if not isinstance(nm, str) or not re.match(r"^[A-Za-z_][\w\-]*$", nm):
                raise DescriptionError(f"{path}: leg name {nm!r} must start with a letter (letters, digits, _, -)")
        self.names = names
        self.label = f"{path} ({names[0]})" if self.n == 1 else f"{path} ({names[0]}..{names[-1]})"
        lab = self.label
        t = raw.get("type")
        if len(LEG_OPTIONS) != len(LEG_TYPES):
            _sync_options()
        if t is None:
            raise DescriptionError(f"{lab}.type: required key is missing; leg types: {', '.join(sorted(LEG_OPTIONS))}")
        if t not in LEG_TYPES or t not in LEG_OPTIONS:
            raise DescriptionError(f"{lab}.type: unknown leg type {t!r}; leg types: {', '.join(sorted(LEG_OPTIONS))}")
        self.type, self.cls = t, LEG_TYPES[t]
        options = LEG_OPTIONS[t]
        _check_keys(raw, _LEG_COMMON | set(options), lab, f"the {t} leg")
        for k in _LEG_REQUIRED.get(t, ()):
            if k not in raw:
                raise DescriptionError(f"{lab}.{k}: required key of the {t} leg is missing")
        self.options = {}
        for k, kind in options.items():
            if k not in raw:
                continue
            p = f"{lab}.{k}"
            if kind.startswith("axis"):
                self.options[k] = _Axis(raw[k], p, scope)
            elif kind == "length":
                self.options[k] = _Scalar(raw[k], "length", p, scope)
            else:
                if raw[k] not in (1, -1) or isinstance(raw[k], bool):
                    raise DescriptionError(f"{p}: branch must be 1 or -1, got {raw[k]!r}")
                self.options[k] = int(raw[k])
        self.actuated = self._actuated(raw, lab)

    def _actuated(self, raw, lab) -> bool:
        t, cls = self.type, self.cls
        act_letter = t[cls.actuated]
        if "actuated" not in raw:
            if t == "UPU":  # the leg library's UPU is a passive constraining limb by default
                return False
            return True
        v = raw["actuated"]
        passive_words = ("none", "passive", "no", "false")
        if v is None or v is False or (isinstance(v, str) and v.strip().lower() in passive_words):
            if t not in PASSIVE_CAPABLE:
                raise DescriptionError(f"{lab}.actuated: the {t} leg cannot be passive in the leg library (it is "
                                       f"actuated at its {_JOINT_WORDS[act_letter]} joint '{act_letter}'); passive legs: "
                                       f"{', '.join(PASSIVE_CAPABLE)}")
            return False
        if v is True:
            return True
        if not isinstance(v, str) or len(v.strip()) != 1:
            raise DescriptionError(f"{lab}.actuated: expected a joint letter such as '{act_letter}' (or none for a "
                                   f"passive leg), got {v!r}")
        letter = v.strip().upper()
        if letter not in t:
            raise DescriptionError(f"{lab}.actuated: joint {v!r} does not exist in the {t} leg (its joints, base to "
                                   f"platform: {', '.join(t)})")
        if letter != act_letter:
            alt = "; or actuated: none for a passive leg" if t in PASSIVE_CAPABLE else ""
            raise DescriptionError(f"{lab}.actuated: joint {v!r} of the {t} leg cannot be actuated in the leg library; "
                                   f"its actuated joint is the {_JOINT_WORDS[act_letter]} joint '{act_letter}'{alt}")
        return True

    def build(self, env, built_base, built_plat) -> list:
        A = self.base.resolve(env, built_base)
        B = self.platform.resolve(env, built_plat)
        # the options that do not depend on the leg (lengths, flags): evaluated once per group
        shared, per_leg = {}, []
        for k, spec in self.options.items():
            kind = LEG_OPTIONS[self.type][k]
            if kind == "axis_base":
                per_leg.append((k, spec, A, True))
            elif kind == "axis_platform":
                per_leg.append((k, spec, B, False))
            elif kind == "length":
                shared[k] = spec(env)
            else:
                shared[k] = spec
        if self.type in PASSIVE_CAPABLE:
            shared["passive"] = not self.actuated
        if self.cls.__dict__.get("group_built") and all(k in self.cls.axis_fields for k, *_ in per_leg):
            return self._in_floats(env, A, B, shared, per_leg)
        return self._each(env, A, B, shared, per_leg)

    def _one(self, env, j, A, B, shared, per_leg):
        """Leg ``j`` of the group, built as any leg is: its options evaluated, then its type's
        constructor (which checks it)."""
        kb = 0 if self.base.n == 1 else j
        kp = 0 if self.platform.n == 1 else j
        kw = dict(shared)
        for k, spec, S, on_base in per_leg:
            kw[k] = spec(env, S, kb if on_base else kp)
        try:
            return self.cls(self.names[j], base=A.points[kb], platform=B.points[kp], **kw)
        except ValueError as e:
            raise DescriptionError(f"{self.label}: {e}") from None

    def _in_floats(self, env, A, B, shared, per_leg) -> list:
        """The group's legs of a type built in floats (:attr:`Leg.group_built`): the fields the
        legs share from a template leg built once as any leg is, the options every leg shares as
        given (checked once, by the first leg's ``_check_values``), each leg's anchors and axes
        checked and made unit vectors in floats with the operations of its type's constructor
        (:func:`_axis`), the same bits, as the rows of one array (each leg its own rows). Where
        the floats find a value wrong, the group is built as any group is, which says what is
        wrong."""
        cls = self.cls
        fields = cls.axis_fields
        hit = self.__dict__.get("_template")
        if hit is None:
            tmpl = self._one(env, 0, A, B, shared, per_leg)
            given = {k for k, *_ in per_leg}
            kept = {f: tuple(tmpl.__dict__[f].tolist()) for f in fields if f not in given}
            # the template's arrays are the leg's anchors and axes, and the shared default neutral
            # directions (read-only): any other array would be shared by the legs made from it
            arrays = {f for f, v in tmpl.__dict__.items() if isinstance(v, np.ndarray)}
            if not arrays <= {"base", "platform", "base_ref", "platform_ref", *fields} \
                    or tmpl.base_ref is not _UP or tmpl.platform_ref is not _DOWN:
                return [tmpl] + [self._one(env, j, A, B, shared, per_leg) for j in range(1, self.n)]
            hit = self._template = (tmpl.__dict__, kept)
        tdict, kept = hit
        nb1, np1 = self.base.n == 1, self.platform.n == 1
        isfinite = math.isfinite
        # every anchor finite (a sum is finite only if its terms are; one too large to add up
        # sends the group the constructors' way, which builds it)
        if not (isfinite(sum(map(sum, A.rows))) and isfinite(sum(map(sum, B.rows)))):
            return self._each(env, A, B, shared, per_leg)
        flat = []
        for j in range(self.n):
            kb = 0 if nb1 else j
            kp = 0 if np1 else j
            row = [*A.rows[kb], *B.rows[kp]]
            axes = {}
            for k, spec, S, on_base in per_leg:
                v = spec.floats(env, S, kb if on_base else kp)
                if v is None:
                    return self._each(env, A, B, shared, per_leg)
                x, y, z = v
                if not isfinite(x + y + z):
                    return self._each(env, A, B, shared, per_leg)
                n = math.sqrt(x * x + y * y + z * z)  # _unit_xyz: one division per entry
                axes[k] = (x / n, y / n, z / n)
            for f in fields:
                row.extend(axes[f] if f in axes else kept[f])
            flat.extend(row)
        rows = np.array(flat, dtype=float).reshape(self.n, 2 + len(fields), 3)
        legs = []
        new = object.__new__
        for j, name in enumerate(self.names):
            leg = new(cls)
            d = leg.__dict__
            d.update(tdict)
            d.update(shared)
            r = rows[j]
            d["name"], d["base"], d["platform"] = name, r[0], r[1]
            for m, f in enumerate(fields):
                d[f] = r[2 + m]
            legs.append(leg)
        try:
            legs[0]._check_values()  # the shared options, as the constructor checks them last
        except ValueError:
            return self._each(env, A, B, shared, per_leg)
        return legs

    def _each(self, env, A, B, shared, per_leg) -> list:
        return [self._one(env, j, A, B, shared, per_leg) for j in range(self.n)]
