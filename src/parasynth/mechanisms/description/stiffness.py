"""The ``stiffness:`` section: the spring values of the legs as model quantities.

A description may declare, per group of legs, the values :func:`parasynth.stiffness_matrix`
uses for them (each an expression of parameters with its unit, usually one parameter)::

    stiffness:
      - legs: [L1, L2, L3, L4]          # optional: default every leg
        axial: leg_stiffness            # N/m, along the leg line of an actuated leg
        actuator: drive_stiffness       # N/m, the drive in series along the actuator coordinate
        doc: rod and screw of the driving legs
      - legs: [L5]
        constraint_force: limb_force_stiffness     # N/m, every constraint force of the limb
        constraint_couple: limb_couple_stiffness   # N*m/rad, every constraint couple of the limb
        diameter: limb_diameter                    # m, the steel rod of the geometric estimate

A single mapping (no list) applies to every leg. ``axial`` and ``actuator`` need actuated legs,
``constraint_force`` and ``constraint_couple`` legs with constraint wrenches (RPS, RPU, UPU,
PRS); ``diameter`` (and ``youngs_modulus``, ``shear_modulus``) are the rod and the material of
the geometric estimate for whatever these legs do not declare. A leg may appear in several
entries but each key only once per leg.

Precedence, per value: an explicit setting of the measure / keyword of ``stiffness_matrix`` >
the value declared here > the geometric estimate (steel rod of the leg diameter, see
:mod:`parasynth.measures.stiffness`). Values are evaluated for each parameter set when the mechanism is
built; zero, negative or non-finite values are refused naming the key path.
"""

from __future__ import annotations

import math

from ...model.legs import LEG_TYPES
from .errors import DescriptionError
from .parameters import _EXAMPLE_UNIT, _Scalar, _check_keys, values_key

#: Keys of an entry and their quantity kinds.
STIFFNESS_KEYS = {
    "axial": "stiffness",
    "actuator": "stiffness",
    "constraint_force": "stiffness",
    "constraint_couple": "rotational_stiffness",
    "diameter": "length",
    "youngs_modulus": "pressure",
    "shear_modulus": "pressure",
}
#: Leg types with constraint wrenches (the others transmit only their actuation force): those
#: that declare constraint rows.
CONSTRAINING_TYPES = tuple(name for name, cls in LEG_TYPES.items() if cls.constraint_rows)
_ACTUATED_ONLY = ("axial", "actuator")
_CONSTRAINT_ONLY = ("constraint_force", "constraint_couple")


class _StiffnessSpec:
    """The parsed ``stiffness:`` section: per leg name, {key: (_Scalar, key path)}."""

    def __init__(self, raw, leg_groups, scope, param_kinds: dict):
        self.per_leg: dict[str, dict] = {}
        if raw is None:
            return
        entries = [raw] if isinstance(raw, dict) else raw
        if not isinstance(entries, list):
            raise DescriptionError("stiffness: give a mapping {axial: ..., constraint_force: ...} for every leg, or "
                                   "a list of such mappings with legs: [names]")
        info = {}  # leg name -> (type, actuated)
        for g in leg_groups:
            for nm in g.names:
                info[nm] = (g.type, g.actuated)
        for i, e in enumerate(entries):
            path = "stiffness" if isinstance(raw, dict) else f"stiffness[{i}]"
            if not isinstance(e, dict):
                raise DescriptionError(f"{path}: an entry is a mapping with legs and values such as axial: "
                                       f"leg_stiffness, got {e!r}")
            _check_keys(e, set(STIFFNESS_KEYS) | {"legs", "doc"}, path, "a stiffness entry")
            legs = e.get("legs")
            if legs is None:
                legs = list(info)
            elif isinstance(legs, str):
                legs = [legs]
            if not isinstance(legs, list) or not legs:
                raise DescriptionError(f"{path}.legs: give a non-empty list of leg names ({', '.join(info)})")
            for nm in legs:
                if nm not in info:
                    raise DescriptionError(f"{path}.legs: unknown leg {nm!r}; legs: {', '.join(info)}")
            values = [k for k in STIFFNESS_KEYS if k in e]
            if not values:
                raise DescriptionError(f"{path}: give at least one of {', '.join(STIFFNESS_KEYS)}")
            for key in values:
                kp = f"{path}.{key}"
                kind = STIFFNESS_KEYS[key]
                v = e[key]
                name = v.strip() if isinstance(v, str) else None
                pk = param_kinds.get(name)
                if pk is not None and pk != "dimensionless" and pk != kind:
                    # (a plain-number parameter gets the bare-number message of _Scalar)
                    raise DescriptionError(f"{kp}: parameters.{name} is a{'n' if pk[0] in 'aeiou' else ''} "
                                           f"{pk.replace('_', ' ')}, {key} needs a {kind.replace('_', ' ')} "
                                           f"(e.g. '{_EXAMPLE_UNIT[kind]}')")
                scalar = _Scalar(v, kind, kp, scope)
                if scalar.const is not None and not scalar.const > 0:
                    raise DescriptionError(f"{kp}: must be positive, got {v!r}")
                if key in _ACTUATED_ONLY:
                    passive = [nm for nm in legs if not info[nm][1]]
                    if passive and e.get("legs") is not None:
                        raise DescriptionError(f"{kp}: leg(s) {', '.join(passive)} are not actuated; {key} is the "
                                               f"stiffness of an actuated leg")
                    targets = [nm for nm in legs if info[nm][1]]
                elif key in _CONSTRAINT_ONLY:
                    free = [nm for nm in legs if info[nm][0] not in CONSTRAINING_TYPES]
                    if free and e.get("legs") is not None:
                        raise DescriptionError(f"{kp}: leg(s) {', '.join(free)} ({info[free[0]][0]}) have no constraint "
                                               f"wrench; {key} applies to {', '.join(CONSTRAINING_TYPES)} legs")
                    targets = [nm for nm in legs if info[nm][0] in CONSTRAINING_TYPES]
                else:
                    targets = legs
                if not targets:
                    raise DescriptionError(f"{kp}: no leg of this entry has {'an actuator' if key in _ACTUATED_ONLY else 'a constraint wrench'}")
                for nm in targets:
                    slot = self.per_leg.setdefault(nm, {})
                    if key in slot:
                        raise DescriptionError(f"{kp}: leg {nm}'s {key} is already given by {slot[key][1]}")
                    slot[key] = (scalar, kp)

    def values(self, env) -> dict:
        """{leg name: {key: SI value}} for the parameter values ``env`` (kept per the values of
        the parameters they name: a study's designs mostly share them; each call gets dicts of
        its own)."""
        names = self.__dict__.get("_names")
        if names is None:
            used = set()
            for slot in self.per_leg.values():
                for scalar, _ in slot.values():
                    used |= set(scalar.expr.names) if scalar.expr is not None else set()
            names = self._names = tuple(sorted(used))
        key = values_key(env, names)
        memo = self.__dict__.setdefault("_memo", {})
        hit = memo.get(key) if key is not None else None
        if hit is None:
            hit = self._values(env)
            if key is not None:
                if len(memo) >= 64:
                    memo.clear()
                memo[key] = hit
        return {nm: dict(d) for nm, d in hit.items()}

    def _values(self, env) -> dict:
        out = {}
        for nm, slot in self.per_leg.items():
            d = {}
            for key, (scalar, kp) in slot.items():
                v = scalar(env)
                if not (v > 0 and math.isfinite(v)):
                    raise DescriptionError(f"{kp}: must be a finite positive value, got {v!r} (SI) for leg {nm}")
                d[key] = v
            out[nm] = d
        return out
