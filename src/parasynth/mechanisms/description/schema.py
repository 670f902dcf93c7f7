"""The whole description: :class:`Description` parses and validates a mapping (the YAML
document) section by section and builds the geometry for a parameter set; the ``Params``
dataclass of a described mechanism is generated from its parameters.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re

import numpy as np

from .errors import DescriptionError
from .expressions import Expression, _Scope
from .parameters import _Scalar, _check_identifier, _check_keys, _param_env, _parse_params, values_key
from .anchors import _AnchorSet
from .legs import _LegGroup
from .task import _Task
from .constraints import _ConstraintSpec
from .outputs import parse_outputs
from .stiffness import _StiffnessSpec
from .variants import apply_variants, parse_variants

_TOP_KEYS = {"name", "summary", "description", "parameters", "variants", "checks", "base", "platform", "legs",
             "task", "length_scale", "constraints", "outputs", "stiffness"}


class Description:
    """A parsed and validated mechanism description (structure only; numbers are evaluated for
    each parameter set by :meth:`build_geometry`).

    ``selection`` ({variant: choice}, missing ones at their defaults) picks the variants that
    are overlaid on the base description (:mod:`.variants`); ``variants`` lists them and
    ``selection`` is the complete choice this description was resolved for."""

    def __init__(self, data: dict, source: str | None = None, selection: dict | None = None,
                 outputs_taken=lambda name: False):
        if not isinstance(data, dict):
            raise DescriptionError("the description must be a mapping with name, parameters, base, platform, legs, "
                                   "task, constraints")
        _check_keys(data, _TOP_KEYS, "(top level)", "a mechanism description")
        name = data.get("name")
        if not isinstance(name, str) or not re.match(r"^[A-Za-z0-9_.\-]+$", name):
            raise DescriptionError(f"name: required, letters, digits, '_', '.', '-' only; got {name!r}")
        self.name = name
        self.source = source
        self.summary = str(data.get("summary", "") or f"mechanism described in {source or 'a description'}")
        self.params = _parse_params(data.get("parameters"))
        self.param_by_name = {p.name: p for p in self.params}
        self.variants = parse_variants(data.get("variants"), set(self.param_by_name))
        sel = {v.name: v.default for v in self.variants}
        for k, val in (selection or {}).items():
            var = next((v for v in self.variants if v.name == k), None)
            if var is None:
                raise DescriptionError(f"variants: {k!r} is not a variant; variants: "
                                       f"{', '.join(v.name for v in self.variants) or '(none)'}")
            try:
                sel[k] = var.coerce(val, f"variants.{k}")
            except ValueError as e:
                raise DescriptionError(str(e)) from None
        self.selection = sel
        self.digest = _digest(data)
        data = apply_variants(data, self.variants, sel)
        self.text = str(data.get("description", "") or "")
        pscope = _Scope(("parameters", [p.name for p in self.params]), kinds={p.name: p.kind for p in self.params})
        self.pscope = pscope
        checks = data.get("checks") or []
        if isinstance(checks, str):
            checks = [checks]
        if not isinstance(checks, list):
            raise DescriptionError("checks: give a list of conditions on parameters such as 'q_min < q_max'")
        self.checks = [Expression(c, f"checks[{i}]", pscope, allow_compare=True) for i, c in enumerate(checks)]
        default_env = {p.name: (np.float64(p.default) if p.shape == () else np.asarray(p.default, dtype=float))
                       for p in self.params}
        self.base_sets, self.plat_sets = {}, {}
        for side, store in (("base", self.base_sets), ("platform", self.plat_sets)):
            raw = data.get(side) or {}
            if not isinstance(raw, dict):
                raise DescriptionError(f"{side}: give a mapping {{set name: points or pattern}}")
            for sname, sraw in raw.items():
                _check_identifier(sname, f"{side}.{sname}", "anchor set")
                store[sname] = _AnchorSet(sname, sraw, f"{side}.{sname}", pscope, self.param_by_name)
        sizes = {}
        for side, store in (("base", self.base_sets), ("platform", self.plat_sets)):
            sizes[side] = {n: s.build(default_env).points.shape[0] for n, s in store.items()}
        legs = data.get("legs")
        if not isinstance(legs, list) or not legs:
            raise DescriptionError("legs: give a non-empty list of legs")
        self.legs = []
        k = 1
        for i, raw in enumerate(legs):
            g = _LegGroup(i, raw, sizes["base"], sizes["platform"], pscope, k)
            self.legs.append(g)
            k += g.n
        self.leg_names = [n for g in self.legs for n in g.names]
        dup = sorted({n for n in self.leg_names if self.leg_names.count(n) > 1})
        if dup:
            raise DescriptionError(f"legs: leg name(s) {dup} used twice")
        #: The mechanism's leg order as positions in the description's order (:func:`leg_order`).
        self.leg_order = leg_order(self.leg_names)
        self.leg_names = [self.leg_names[i] for i in self.leg_order]
        kinds = sorted({g.cls.actuator_kind for g in self.legs if g.actuated})
        #: What the actuators are: "length" (leg lengths, slider positions), "angle" (cranks),
        #: "mixed", or None without actuators.
        if not kinds:
            self.actuator_kind = None
        elif set(kinds) <= {"length", "slider"}:
            self.actuator_kind = "length"
        else:
            self.actuator_kind = "angle" if kinds == ["angle"] else "mixed"
        self.stiffness = _StiffnessSpec(data.get("stiffness"), self.legs, pscope,
                                        {p.name: p.kind for p in self.params})
        self.task = _Task(data.get("task"), pscope, set(self.param_by_name))
        self.length_scale = (_Scalar(data["length_scale"], "length", "length_scale", pscope)
                             if "length_scale" in data else None)
        cons = data.get("constraints") or []
        if not isinstance(cons, list):
            raise DescriptionError("constraints: give a list of constraints")
        self.constraints = [_ConstraintSpec(i, c, self.leg_names, self.task, pscope, self.actuator_kind)
                            for i, c in enumerate(cons)]
        names = [c.name for c in self.constraints]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise DescriptionError(f"constraints: name(s) {dup} used twice")
        self.outputs = parse_outputs(data.get("outputs"), self.task.pose_scope, outputs_taken)

    def build_geometry(self, env):
        base = {n: s.build(env) for n, s in self.base_sets.items()}
        plat = {n: s.build(env) for n, s in self.plat_sets.items()}
        legs = []
        for g in self.legs:
            legs += g.build(env, base, plat)
        legs = [legs[i] for i in self.leg_order]
        home = np.array([s(env) for s in self.task.home])
        for c, (lo, hi) in self.task.ranges.items():
            if not lo(env) < hi(env):
                raise DescriptionError(f"task.ranges.{c}: low ({lo(env):g}) must be below high ({hi(env):g}) (SI)")
        if self.length_scale is not None:
            L = self.length_scale(env)
            if not L > 0:
                raise DescriptionError(f"length_scale: must be a positive length, got {L} m")
        else:
            L = max(max(float(np.linalg.norm(leg.base)) for leg in legs), 1e-3)
        return legs, home, L


_NUMBERED = re.compile(r"^L([1-9]\d*)$")


def leg_order(names: list) -> list:
    """The order of the mechanism's legs, as positions in the description's order ``names``.

    When every leg's name has the form of the default names, ``L<number>``, and the numbers are
    1 to the number of legs, the legs are put in the order of their numbers: the leg named
    ``L<k>`` is the k-th leg, and its actuator the k-th (``q<k>``, ``s<k>`` or ``t<k>``), whatever
    the order of the entries that name them (a mirrored crank pair written as two entries,
    ``names: [L1, L3, L5]`` and ``names: [L2, L4, L6]``). Any other names keep the description's
    order, and a leg's number is its position there."""
    nums = [_NUMBERED.match(n) for n in names]
    if all(nums) and sorted(int(m.group(1)) for m in nums) == list(range(1, len(names) + 1)):
        return sorted(range(len(names)), key=lambda i: int(nums[i].group(1)))
    return list(range(len(names)))


def _digest(data) -> str:
    try:
        text = json.dumps(data, sort_keys=True, default=str)
    except TypeError:  # keys of mixed types
        text = repr(data)
    return hashlib.sha1(text.encode()).hexdigest()[:10]


def _check_params(chk, env: dict, mname: str) -> None:
    """``ValueError`` naming the check and the values unless the parameters ``env`` pass the
    check ``chk``; the values that passed it are kept (per the values of the parameters it
    names: :func:`values_key`), as a study's designs mostly repeat them."""
    names = chk.__dict__.get("_sorted_names")
    if names is None:
        names = chk._sorted_names = tuple(sorted(chk.names))
    key = values_key(env, names)
    passed = chk.__dict__.setdefault("_passed", set())
    if key is not None and key in passed:
        return
    with np.errstate(all="ignore"):
        ok = chk(env)
    if not (bool(ok) if isinstance(ok, (bool, np.bool_)) else bool(np.all(ok))):
        vals = ", ".join(f"{n}={env[n]!r}" for n in names)
        raise ValueError(f"{mname}: the parameters fail the check {chk.text!r} ({vals}, SI)")
    if key is not None:
        if len(passed) >= 256:
            passed.clear()
        passed.add(key)


def _make_params_class(desc: Description, cls_name: str, resolve=None):
    """The frozen ``Params`` dataclass: one field per parameter (SI), then one per variant
    (its choice). ``resolve(selection)`` gives the description of a selection (its checks
    apply); without it the checks of ``desc`` do."""
    plist = desc.params
    variants = desc.variants
    mname = desc.name
    units = {p.name: p.kind for p in plist}
    units.update({v.name: None for v in variants})

    # each field with the name its errors give (made once, not per instance)
    coerced = [(p, p.name, f"{mname}.{p.name}") for p in plist] + [(v, v.name, f"{mname}.{v.name}") for v in variants]

    def __post_init__(self):
        d = self.__dict__  # a frozen dataclass's fields, written as object.__setattr__ writes them
        for p, name, where in coerced:
            d[name] = p.coerce(d[name], where)
        checks = desc.checks
        if variants and resolve is not None:
            checks = resolve({v.name: d[v.name] for v in variants}).checks
        env = _param_env(self, plist)
        d["_env"] = (plist, env)  # the model built from these parameters starts from it
        if not checks:
            return
        for chk in checks:
            _check_params(chk, env, mname)

    fields = [(p.name, float if p.shape == () else tuple, dataclasses.field(default=p.default)) for p in plist]
    fields += [(v.name, bool if v.is_switch else str, dataclasses.field(default=v.default)) for v in variants]
    doc = (f"Parameters of {mname} in SI (m, rad, N/m, N*m/rad, Pa); defaults from its description. Units: "
           + ", ".join(f"{p.name} ({p.kind})" for p in plist))
    if variants:
        doc += ". Variants: " + "; ".join(f"{v.name} ({v.allowed}; default {v.default!r})" for v in variants)
    return dataclasses.make_dataclass(f"{cls_name}Params", fields, frozen=True,
                                      namespace={"UNITS": units, "__post_init__": __post_init__, "__doc__": doc})
