"""Scalars and design parameters of descriptions: quantities with units, plain numbers,
expressions of parameters; the ``parameters:`` section and its validation.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...common.units import DISPLAY_UNITS, UNIT_KINDS, QuantityError, parse_quantity
from .errors import DescriptionError
from .expressions import Expression, RESERVED, _PURE_QUANTITY, _Scope

_UNITFUL = ("length", "angle", "stiffness", "rotational_stiffness", "pressure")
#: Display unit of each parameter kind with a unit (examples in messages).
_EXAMPLE_UNIT = {k: DISPLAY_UNITS[k] for k in _UNITFUL}
_KIND_TEXT = {"length": f"a length (e.g. '135 {_EXAMPLE_UNIT['length']}')",
              "angle": f"an angle (e.g. '15 {_EXAMPLE_UNIT['angle']}')",
              "stiffness": f"a stiffness (e.g. '2e7 {_EXAMPLE_UNIT['stiffness']}')",
              "rotational_stiffness": f"a rotational stiffness (e.g. '3e5 {_EXAMPLE_UNIT['rotational_stiffness']}')",
              "pressure": f"a modulus (e.g. '210 {_EXAMPLE_UNIT['pressure']}')",
              "dimensionless": "a number", None: "a number"}
#: SI unit of each parameter kind (messages).
_SI_UNIT = {**{k: UNIT_KINDS[k].si for k in _UNITFUL}, "dimensionless": "a plain number"}
#: Kinds whose values are positive by nature: zero or negative is refused even without bounds.
_POSITIVE_KINDS = ("stiffness", "rotational_stiffness", "pressure")


def _bare_number_error(path, raw, kind):
    return DescriptionError(f"{path}: a bare number ({raw!r}) is not allowed for {_KIND_TEXT[kind]}; "
                            f"give a unit, e.g. '{raw} {_EXAMPLE_UNIT[kind]}', or an expression of parameters")


_F64 = np.float64


def values_key(env, names):
    """The values of ``names`` in ``env`` as an exact key of what they determine: float64
    scalars (as :func:`_param_env` gives them; a zero with its sign, as atan2 tells 0.0 from
    -0.0) and float64 arrays (list parameters, by shape and bytes). None if a name is missing
    or a value is of another type."""
    key = []
    for n in names:
        x = env.get(n, _MISSING)
        t = type(x)
        if t is _F64:
            key.append(x if x != 0.0 else (0.0, math.copysign(1.0, x)))
        elif t is np.ndarray and x.dtype == _F64:
            key.append((x.shape, x.tobytes()))
        else:
            return None
    return tuple(key)


_MISSING = object()


class _Scalar:
    """A scalar in the geometry: a quantity with its unit ("135 mm"), a plain number where the
    quantity is dimensionless (or 0), or an expression of parameters (SI)."""

    def __init__(self, raw, kind: str | None, path: str, scope: _Scope):
        self.kind, self.path = kind, path
        self.const: float | None = None
        self.expr: Expression | None = None
        if isinstance(raw, bool) or raw is None or not isinstance(raw, (int, float, str)):
            raise DescriptionError(f"{path}: expected {_KIND_TEXT[kind]}, got {raw!r}")
        if isinstance(raw, (int, float)):
            if kind in _UNITFUL and raw != 0:
                raise _bare_number_error(path, raw, kind)
            self.const = float(raw)
        elif _PURE_QUANTITY.match(raw):
            try:
                self.const = parse_quantity(raw, kind or "dimensionless", field=path)
            except QuantityError as e:
                raise DescriptionError(str(e)) from None
        else:
            self.expr = Expression(raw, path, scope)
            if self.expr.is_constant and not self.expr.has_units and kind in _UNITFUL:
                with np.errstate(all="ignore"):
                    v = float(self.expr({}))
                if v != 0:
                    raise _bare_number_error(path, raw, kind)
            elif kind in _UNITFUL and not self.expr.has_units and self.expr.names and scope is not None:
                # Only plain-number parameters and no unit: the value has no unit either.
                plain = sorted(n for n in self.expr.names if scope.kinds.get(n) == "dimensionless")
                if len(plain) == len(self.expr.names):
                    which = ", ".join(f"parameters.{n}" for n in plain)
                    raise DescriptionError(
                        f"{path}: {raw!r} is a plain number ({which} without a unit) where {_KIND_TEXT[kind]} is "
                        f"expected; give {'it' if len(plain) == 1 else 'them'} a unit, e.g. "
                        f"'300 {_EXAMPLE_UNIT[kind]}'")
        if self.const is not None and not math.isfinite(self.const):
            raise DescriptionError(f"{path}: must be finite, got {raw!r}")

    def __call__(self, env) -> float:
        if self.const is not None:
            return self.const
        # The value of the same inputs is the same: kept per input values (values_key: exact,
        # a zero with its sign), as a study's designs mostly repeat the parameters a value
        # depends on.
        names = self.__dict__.get("_names")
        if names is None:
            names = self._names = tuple(sorted(self.expr.names))
        key = values_key(env, names)
        if key is not None:
            memo = self.__dict__.get("_memo")
            if memo is None:
                memo = self._memo = {}
            hit = memo.get(key)
            if hit is not None:
                return hit
        with np.errstate(all="ignore"):
            v = self.expr(env)
        if np.ndim(v) != 0:
            raise DescriptionError(f"{self.path}: {self.expr.text!r} is a list, not a single value; "
                                   f"index it, e.g. name[0]")
        v = float(v)
        if not math.isfinite(v):
            raise DescriptionError(f"{self.path}: {self.expr.text!r} evaluates to {v} (not finite)")
        if key is not None:
            if len(memo) >= 256:
                memo.clear()
            memo[key] = v
        return v


#: Parameter kinds, in the order a value's unit is tried when no ``kind`` is given (a value in
#: N*m is taken as a rotational stiffness: a torque is not a parameter kind).
_PARAM_KINDS = ("length", "angle", "stiffness", "rotational_stiffness", "pressure", "dimensionless")
_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def _check_identifier(name, path, what):
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise DescriptionError(f"{path}: {what} name {name!r} must be an identifier (letters, digits, _)")
    if name in RESERVED:
        raise DescriptionError(f"{path}: {what} name {name!r} is reserved (a function, constant or pose name); "
                               f"reserved: {', '.join(sorted(RESERVED))}")


def _check_keys(raw: dict, allowed, path, what="this entry"):
    unknown = [k for k in raw if k not in allowed]
    if unknown:
        raise DescriptionError(f"{path}: unknown key{'s' if len(unknown) > 1 else ''} "
                               f"{', '.join(map(repr, unknown))} for {what}; allowed: {', '.join(sorted(allowed))}")


def _leaf(v):
    while isinstance(v, (list, tuple)):
        if not v:
            return None
        v = v[0]
    return v


def _infer_kind(value, path):
    leaf = _leaf(value)
    if leaf is None:
        raise DescriptionError(f"{path}: an empty list cannot be a parameter value")
    if isinstance(leaf, bool):
        raise DescriptionError(f"{path}: booleans are not parameters (descriptions have no switches); "
                               f"give a length, an angle, a stiffness, a modulus or a number")
    if isinstance(leaf, (int, float)):
        return "dimensionless"
    if isinstance(leaf, str):
        for kind in _PARAM_KINDS:
            try:
                parse_quantity(leaf, kind, field=path)
                return kind
            except QuantityError:
                continue
        raise DescriptionError(f"{path}: cannot read {leaf!r} as a length (e.g. '135 mm'), an angle (e.g. "
                               f"'15 deg'), a stiffness (e.g. '2e7 N/m', '3e5 N*m/rad'), a modulus (e.g. "
                               f"'210 GPa') or a plain number: unknown or unsuitable unit")
    raise DescriptionError(f"{path}: expected a value with its unit, got {value!r}")


def _parse_value(value, kind, path):
    if isinstance(value, (list, tuple)):
        out = tuple(_parse_value(v, kind, f"{path}[{i}]") for i, v in enumerate(value))
        try:
            np.asarray(out, dtype=float)
        except ValueError:
            raise DescriptionError(f"{path}: nested lists must be rectangular (all rows the same length)") from None
        return out
    if isinstance(value, bool) or value is None:
        raise DescriptionError(f"{path}: expected {_KIND_TEXT[kind]}, got {value!r}")
    if isinstance(value, (int, float)):
        if kind in _UNITFUL and value != 0:
            raise _bare_number_error(path, value, kind)
        v = float(value)
    elif isinstance(value, str):
        try:
            v = parse_quantity(value, kind, field=path)
        except QuantityError as e:
            raise DescriptionError(str(e)) from None
    else:
        raise DescriptionError(f"{path}: expected {_KIND_TEXT[kind]}, got {value!r}")
    if not math.isfinite(v):
        raise DescriptionError(f"{path}: must be finite, got {value!r}")
    return v


#: Largest |value| of a parameter (SI) by kind: a length or an angle beyond 1e6 (m, rad) is
#: no mechanism and would overflow when squared; other kinds (stiffness, modulus) up to 1e30.
MAX_PARAM_MAGNITUDE = {"length": 1e6, "angle": 1e6, None: 1e30}


@dataclass(frozen=True)
class _Param:
    name: str
    kind: str
    default: Any
    shape: tuple
    lo: float | None = None
    hi: float | None = None
    doc: str = ""
    above: float | None = None  # exclusive bounds
    below: float | None = None

    def coerce(self, value, where: str):
        if value is self.default:  # a parameter left at its default (an immutable float or tuple)
            hit = self.__dict__.get("_coerced_default")
            if hit is not None:
                return hit
            out = self._coerce(value, where)
            if type(value) in (float, tuple):
                self.__dict__["_coerced_default"] = out
            return out
        return self._coerce(value, where)

    def _coerce(self, value, where: str):
        unit = _SI_UNIT[self.kind]
        if self.shape == ():
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise ValueError(f"{where} must be a number ({self.kind}, SI: {unit}), got {value!r}")
            x = float(value)
            if math.isfinite(x) and abs(x) <= MAX_PARAM_MAGNITUDE.get(self.kind, MAX_PARAM_MAGNITUDE[None]) \
                    and (self.lo is None or x >= self.lo) and (self.hi is None or x <= self.hi) \
                    and (self.above is None or x > self.above) and (self.below is None or x < self.below) \
                    and (self.kind not in _POSITIVE_KINDS or x > 0):
                return x  # within every bound (the checks below say which one a value breaks)
            a = np.asarray(x)
        else:
            if isinstance(value, (str, bytes, bool)) or value is None:
                raise ValueError(f"{where} must be a list of shape {self.shape} ({self.kind}, SI: {unit}), got {value!r}")
            try:
                a = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                a = None
            if a is None or a.shape != self.shape:
                raise ValueError(f"{where} must have shape {self.shape} ({self.kind}, SI: {unit}); the number of "
                                 f"entries is fixed by the description, got {value!r}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{where} must be finite, got {value!r}")
        big = MAX_PARAM_MAGNITUDE.get(self.kind, MAX_PARAM_MAGNITUDE[None])
        if np.any(np.abs(a) > big):
            raise ValueError(f"{where} must be at most {big:g} {unit} in magnitude (the documented limit; a "
                             f"larger value would overflow the kinematics), got {value!r}")
        if self.lo is not None and np.any(a < self.lo):
            raise ValueError(f"{where} must be >= {self.lo} ({unit}), got {value!r}")
        if self.hi is not None and np.any(a > self.hi):
            raise ValueError(f"{where} must be <= {self.hi} ({unit}), got {value!r}")
        if self.above is not None and np.any(a <= self.above):
            raise ValueError(f"{where} must be > {self.above} ({unit}), got {value!r}")
        if self.below is not None and np.any(a >= self.below):
            raise ValueError(f"{where} must be < {self.below} ({unit}), got {value!r}")
        if self.kind in _POSITIVE_KINDS and np.any(a <= 0):
            raise ValueError(f"{where} must be > 0 ({unit}): {_KIND_TEXT[self.kind].split(' (')[0]} is positive, "
                             f"got {value!r}")
        return float(a) if self.shape == () else _to_tuple(a)


def _to_tuple(a: np.ndarray):
    return tuple(_to_tuple(x) for x in a) if a.ndim > 1 else tuple(float(x) for x in a)


def _parse_params(raw) -> list[_Param]:
    if raw is None:
        return []
    if not isinstance(raw, dict):
        raise DescriptionError("parameters: give a mapping {name: value with unit}, e.g. {radius: 135 mm}")
    out = []
    for name, spec in raw.items():
        path = f"parameters.{name}"
        _check_identifier(name, path, "parameter")
        lo = hi = above = below = None
        doc = ""
        if isinstance(spec, dict):
            _check_keys(spec, {"value", "kind", "min", "max", "above", "below", "doc"}, path, "a parameter")
            if "value" not in spec:
                raise DescriptionError(f"{path}.value: required key is missing")
            value, kind, doc = spec["value"], spec.get("kind"), str(spec.get("doc", ""))
            if kind is not None and kind not in _PARAM_KINDS:
                raise DescriptionError(f"{path}.kind: {kind!r} is not a kind; allowed: {', '.join(_PARAM_KINDS)}")
        else:
            value, kind = spec, None
        if kind is None:
            kind = _infer_kind(value, path)
        default = _parse_value(value, kind, path)
        if isinstance(spec, dict):
            lo = _parse_value(spec["min"], kind, f"{path}.min") if "min" in spec else None
            hi = _parse_value(spec["max"], kind, f"{path}.max") if "max" in spec else None
            above = _parse_value(spec["above"], kind, f"{path}.above") if "above" in spec else None
            below = _parse_value(spec["below"], kind, f"{path}.below") if "below" in spec else None
            for nm, b in (("min", lo), ("max", hi), ("above", above), ("below", below)):
                if b is not None and not isinstance(b, float):
                    raise DescriptionError(f"{path}.{nm}: a bound must be a single value")
        p = _Param(name, kind, default, np.shape(default), lo, hi, doc, above, below)
        try:
            p.coerce(default, path)
        except ValueError as e:
            raise DescriptionError(str(e)) from None
        out.append(p)
    return out


def _param_env(params_obj, plist) -> dict:
    """{parameter name: its value} of a ``Params`` object: a float64 scalar, or a float64 array
    for a list parameter."""
    d = params_obj.__dict__
    F64, asarray = np.float64, np.asarray
    return {p.name: F64(d[p.name]) if p.shape == () else asarray(d[p.name], dtype=float) for p in plist}
