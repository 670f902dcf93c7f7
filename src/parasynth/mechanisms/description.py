"""Mechanisms described in YAML, or in the equivalent Python dict.

A description gives a mechanism's design parameters (with units), its base and platform
anchor points (explicit or by patterns), its legs (types from :mod:`parasynth.legs`, joint
axes, actuated joint), its task coordinates and how they map to the platform pose, and its
pose constraints. :func:`description_class` turns it into a :class:`~parasynth.mechanism.Mechanism`
subclass whose ``Params`` is a frozen dataclass with ``UNITS``, so that
``load_mechanism("my_mech.yaml", radius=0.2)`` and YAML studies treat it like a built-in
model. The format is documented in ``docs/mechanisms.md``; a short example::

    name: my_3rps
    parameters: {base_radius: 300 mm, platform_radius: 150 mm, q_min: 300 mm, q_max: 700 mm}
    base:     {B: {pattern: polygon, n: 3, radius: base_radius}}
    platform: {A: {pattern: polygon, n: 3, radius: platform_radius}}
    legs:
      - {type: RPS, base: B, platform: A, r_axis: tangent, actuated: P}
    task:
      coordinates: {z: length, alpha: angle, beta: angle}
      define: {gamma: "-atan2(sin(alpha)*sin(beta), cos(alpha) + cos(beta))"}
      position: ["platform_radius/2*(R11 - R22)", "-platform_radius*R21", z]
      orientation: {convention: xyz, angles: [alpha, beta, gamma]}
      home: {z: 500 mm, alpha: 0 deg, beta: 0 deg}
    constraints:
      - {name: stroke, type: actuator_range, min: q_min, max: q_max}

Expressions are parsed with :mod:`ast` and evaluated by a small interpreter that admits only
numbers, names, ``+ - * / **``, a fixed set of functions and (in conditions) comparisons:
user text is never passed to ``eval``. The same interpreter evaluates the expressions on dual
numbers (forward-mode differentiation), which gives the exact derivatives the twist map needs.
"""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import json
import math
import operator
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import yaml

from ..constraints import (ActuatorRange, Constraint, CoordinateRange, JointAngleLimit, LegAxisAngle,
                           LegInterference, LegLengthRange)
from ..legs import LEG_TYPES
from ..mechanism import Mechanism, Mobility
from ..spatial import EULER_CONVENTIONS, euler_rate_map, euler_to_matrix, reciprocal_basis, rot_axis, skew
from ..units import QuantityError, parse_quantity

__all__ = [
    "DescriptionError",
    "DescriptionWarning",
    "DescribedMechanism",
    "DescribedMobility",
    "ExpressionConstraint",
    "Expression",
    "description_class",
    "load_description",
    "from_description",
]


class DescriptionError(ValueError):
    """A malformed mechanism description. The message names the key path, e.g.
    ``legs[2] (L3).actuated: ...``."""


class DescriptionWarning(UserWarning):
    """A described mechanism that can be built but whose analysis reveals a problem:
    under-actuation, or task coordinates inconsistent with what the legs allow."""


# ================================================================================================
# Expressions
# ================================================================================================
#: Units recognised inside expressions; each ``<number> <unit>`` is replaced by its SI value.
UNIT_FACTORS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "deg": math.pi / 180.0, "rad": 1.0}
_NUMBER = r"(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_UNIT_LITERAL = re.compile(r"(?<![\w.])(" + _NUMBER + r")\s*(mm|cm|um|µm|m|deg|rad)(?!\w)")
#: A string that is a single quantity such as "135 mm" (parsed by pint, so any unit works).
_PURE_QUANTITY = re.compile(r"^\s*[-+]?" + _NUMBER + r"\s*[^\W\d_][\w\s*/^.]*$")

_ARITY = {"sin": 1, "cos": 1, "tan": 1, "asin": 1, "acos": 1, "atan": 1, "atan2": 2, "sqrt": 1, "exp": 1,
          "log": 1, "abs": 1, "hypot": 2, "min": 2, "max": 2, "clip": 3, "sinh": 1, "cosh": 1, "tanh": 1}
_CONSTANTS = {"pi": np.float64(np.pi)}
#: Names of the platform pose inside constraint expressions (and R entries in positions).
R_NAMES = tuple(f"R{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))
POSE_NAMES = ("px", "py", "pz") + R_NAMES
RESERVED = frozenset(_ARITY) | frozenset(_CONSTANTS) | frozenset(POSE_NAMES)

_PLAIN = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos, "atan": np.arctan,
    "atan2": np.arctan2, "sqrt": np.sqrt, "exp": np.exp, "log": np.log, "abs": np.abs, "hypot": np.hypot,
    "min": np.minimum, "max": np.maximum, "clip": np.clip, "sinh": np.sinh, "cosh": np.cosh, "tanh": np.tanh,
}


def _scale(g, f):
    """Gradient ``g`` (N, n) times a per-sample factor ``f`` (scalar or (N,))."""
    f = np.asarray(f)
    return g * f[..., None] if f.ndim else g * f


class _Dual:
    """Forward-mode dual number: value ``v`` (N,) and gradient ``g`` (N, n_task)."""

    __slots__ = ("v", "g")

    def __init__(self, v, g):
        self.v, self.g = v, g

    def __add__(self, o):
        return _Dual(self.v + o.v, self.g + o.g) if isinstance(o, _Dual) else _Dual(self.v + o, self.g)

    __radd__ = __add__

    def __sub__(self, o):
        return _Dual(self.v - o.v, self.g - o.g) if isinstance(o, _Dual) else _Dual(self.v - o, self.g)

    def __rsub__(self, o):
        return _Dual(o - self.v, -self.g)

    def __mul__(self, o):
        if isinstance(o, _Dual):
            return _Dual(self.v * o.v, _scale(self.g, o.v) + _scale(o.g, self.v))
        return _Dual(self.v * o, _scale(self.g, o))

    __rmul__ = __mul__

    def __truediv__(self, o):
        if isinstance(o, _Dual):
            return _Dual(self.v / o.v, _scale(self.g, 1.0 / o.v) - _scale(o.g, self.v / o.v**2))
        return _Dual(self.v / o, _scale(self.g, 1.0 / o))

    def __rtruediv__(self, o):
        return _Dual(o / self.v, _scale(self.g, -o / self.v**2))

    def __pow__(self, o):
        if isinstance(o, _Dual):
            v = self.v**o.v
            return _Dual(v, _scale(self.g, o.v * self.v ** (o.v - 1)) + _scale(o.g, v * np.log(self.v)))
        return _Dual(self.v**o, _scale(self.g, o * self.v ** (o - 1)))

    def __rpow__(self, o):
        v = o**self.v
        return _Dual(v, _scale(self.g, v * np.log(o)))

    def __neg__(self):
        return _Dual(-self.v, -self.g)

    def __pos__(self):
        return self


def _val(a):
    return a.v if isinstance(a, _Dual) else a


def _grad(a):
    return a.g if isinstance(a, _Dual) else 0.0


def _unary(f, df):
    def fn(x):
        if isinstance(x, _Dual):
            return _Dual(f(x.v), _scale(x.g, df(x.v)))
        return f(x)

    return fn


def _atan2(y, x):
    if not isinstance(y, _Dual) and not isinstance(x, _Dual):
        return np.arctan2(y, x)
    yv, xv = _val(y), _val(x)
    r2 = xv * xv + yv * yv
    return _Dual(np.arctan2(yv, xv), _scale(_grad(y), xv / r2) - _scale(_grad(x), yv / r2))


def _hypot(a, b):
    if not isinstance(a, _Dual) and not isinstance(b, _Dual):
        return np.hypot(a, b)
    h = np.hypot(_val(a), _val(b))
    return _Dual(h, _scale(_grad(a), _val(a) / h) + _scale(_grad(b), _val(b) / h))


def _select(pick_first):
    def fn(a, b):
        if not isinstance(a, _Dual) and not isinstance(b, _Dual):
            return np.minimum(a, b) if pick_first else np.maximum(a, b)
        av, bv = _val(a), _val(b)
        first = av <= bv if pick_first else av >= bv
        v = np.where(first, av, bv)
        g = np.where(np.asarray(first)[..., None], _grad(a), _grad(b))
        return _Dual(v, g)

    return fn


def _clip(x, lo, hi):
    lo, hi = _val(lo), _val(hi)
    if not isinstance(x, _Dual):
        return np.clip(x, lo, hi)
    inside = (x.v >= lo) & (x.v <= hi)
    return _Dual(np.clip(x.v, lo, hi), _scale(x.g, inside.astype(float)))


_DUAL = {
    "sin": _unary(np.sin, np.cos),
    "cos": _unary(np.cos, lambda v: -np.sin(v)),
    "tan": _unary(np.tan, lambda v: 1.0 + np.tan(v) ** 2),
    "asin": _unary(np.arcsin, lambda v: 1.0 / np.sqrt(1.0 - v * v)),
    "acos": _unary(np.arccos, lambda v: -1.0 / np.sqrt(1.0 - v * v)),
    "atan": _unary(np.arctan, lambda v: 1.0 / (1.0 + v * v)),
    "atan2": _atan2,
    "sqrt": _unary(np.sqrt, lambda v: 0.5 / np.sqrt(v)),
    "exp": _unary(np.exp, np.exp),
    "log": _unary(np.log, lambda v: 1.0 / v),
    "abs": _unary(np.abs, np.sign),
    "hypot": _hypot,
    "min": _select(True),
    "max": _select(False),
    "clip": _clip,
    "sinh": _unary(np.sinh, np.cosh),
    "cosh": _unary(np.cosh, np.sinh),
    "tanh": _unary(np.tanh, lambda v: 1.0 - np.tanh(v) ** 2),
}

_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
           ast.Pow: operator.pow}
_CMPOPS = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge}
_ALLOWED_TEXT = ("numbers (with units such as '5 mm' or '15 deg' converted to SI), names, + - * / **, "
                 "parentheses, list[index] and the functions " + ", ".join(sorted(_ARITY)))


class Expression:
    """A restricted arithmetic expression over named values, evaluated on NumPy arrays (or, for
    derivatives, on dual numbers).

    ``text``: the expression; ``path``: where it appears (for messages); ``scope``: the names it
    may use (checked at construction); ``allow_compare``: admit one comparison chain at the top
    (for conditions such as ``abs(cos(theta)) > 1e-9``). Numbers followed by a unit (m, cm, mm,
    um, deg, rad) are converted to SI before parsing.
    """

    MAX_LENGTH = 2000

    def __init__(self, text, path: str, scope: "_Scope | None" = None, allow_compare: bool = False):
        if isinstance(text, bool) or not isinstance(text, (str, int, float)):
            raise DescriptionError(f"{path}: expected an expression (text or a number), got {text!r}")
        self.text = text if isinstance(text, str) else repr(float(text))
        self.path = path
        if len(self.text) > self.MAX_LENGTH:
            raise DescriptionError(f"{path}: expression longer than {self.MAX_LENGTH} characters")
        src, n_units = _UNIT_LITERAL.subn(
            lambda m: f"({float(m.group(1)) * UNIT_FACTORS[m.group(2)]!r})", self.text)
        #: Whether the text carries units (a unit literal or pi): a constant without them is a
        #: bare number, refused where a length or an angle is expected.
        self.has_units = n_units > 0
        self.names: set[str] = set()
        self.is_condition = False
        try:
            tree = ast.parse(src.strip(), mode="eval")
        except SyntaxError as e:
            raise DescriptionError(f"{path}: cannot parse {self.text!r} as an expression ({e.msg}); "
                                   f"allowed: {_ALLOWED_TEXT}") from None
        except (ValueError, RecursionError, MemoryError) as e:
            raise DescriptionError(f"{path}: cannot parse {self.text[:60]!r} as an expression "
                                   f"({type(e).__name__})") from None
        #: The parsed expression (``ast`` node, unit literals already converted to SI numbers):
        #: what code generators (the compiled engine) translate.
        self.tree = tree.body
        try:
            self._fn = self._compile(tree.body, allow_compare)
        except RecursionError:
            raise DescriptionError(f"{path}: expression {self.text[:60]!r}... is nested too deeply") from None
        if allow_compare and not self.is_condition:
            raise DescriptionError(f"{path}: {self.text!r} is not a condition; write a comparison such as "
                                   f"'q_min < q_max' or 'abs(cos(theta)) > 1e-9'")
        if scope is not None:
            scope.check(self, path)

    # -- compilation to closures ----------------------------------------------------------------
    def _bad(self, node, what=None):
        what = what or f"{type(node).__name__} ({ast.unparse(node)!r})"
        return DescriptionError(f"{self.path}: {what} is not allowed in expressions ({self.text!r}); "
                                f"allowed: {_ALLOWED_TEXT}")

    def _compile(self, node, top_compare=False) -> Callable:
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise self._bad(node, f"the constant {node.value!r}")
            v = np.float64(node.value)
            return lambda env, F: v
        if isinstance(node, ast.Name):
            name = node.id
            if name in _CONSTANTS:
                self.has_units = True  # pi carries its meaning (radians)
                v = _CONSTANTS[name]
                return lambda env, F: v
            if name in _ARITY:
                raise self._bad(node, f"the function {name!r} used without a call")
            self.names.add(name)
            return lambda env, F: env[name]
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            op = _BINOPS[type(node.op)]
            a, b = self._compile(node.left), self._compile(node.right)
            return lambda env, F: op(a(env, F), b(env, F))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            a = self._compile(node.operand)
            if isinstance(node.op, ast.USub):
                return lambda env, F: -a(env, F)
            return a
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in _ARITY:
                fname = node.func.id if isinstance(node.func, ast.Name) else ast.unparse(node.func)
                raise self._bad(node, f"the call of {fname!r}")
            if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
                raise self._bad(node, "keyword or starred arguments")
            fname = node.func.id
            if len(node.args) != _ARITY[fname]:
                raise DescriptionError(f"{self.path}: {fname}() takes {_ARITY[fname]} argument(s), "
                                       f"got {len(node.args)} in {self.text!r}")
            args = [self._compile(a) for a in node.args]
            return lambda env, F: F[fname](*[a(env, F) for a in args])
        if isinstance(node, ast.Subscript):
            if not isinstance(node.value, (ast.Name, ast.Subscript)):
                raise self._bad(node)
            idx = node.slice
            k = None
            if isinstance(idx, ast.Constant) and type(idx.value) is int:
                k = idx.value
            elif (isinstance(idx, ast.UnaryOp) and isinstance(idx.op, ast.USub) and isinstance(idx.operand, ast.Constant)
                  and type(idx.operand.value) is int):
                k = -idx.operand.value
            if k is None:
                raise self._bad(node, f"the index {ast.unparse(idx)!r} (use an integer, e.g. angles[0])")
            a = self._compile(node.value)
            return lambda env, F: a(env, F)[k]
        if isinstance(node, ast.Compare) and top_compare:
            if not all(type(op) in _CMPOPS for op in node.ops):
                raise self._bad(node, "a comparison other than < <= > >=")
            self.is_condition = True
            terms = [self._compile(node.left)] + [self._compile(c) for c in node.comparators]
            ops = [_CMPOPS[type(op)] for op in node.ops]

            def compare(env, F):
                vals = [t(env, F) for t in terms]
                out = True
                for op, a, b in zip(ops, vals, vals[1:]):
                    out = np.logical_and(out, op(_val(a), _val(b)))
                return out

            return compare
        raise self._bad(node)

    def __call__(self, env: dict, dual: bool = False):
        """Evaluate with names from ``env`` (arrays, scalars or dual numbers)."""
        try:
            return self._fn(env, _DUAL if dual else _PLAIN)
        except (KeyError, IndexError, TypeError, ValueError, OverflowError, ZeroDivisionError,
                FloatingPointError) as e:
            raise DescriptionError(f"{self.path}: cannot evaluate {self.text!r}: {type(e).__name__}: {e}") from None

    @property
    def is_constant(self) -> bool:
        return not self.names

    def __repr__(self) -> str:
        return f"Expression({self.text!r})"


class _Scope:
    """Names an expression may use, grouped for messages."""

    def __init__(self, *groups):
        self.groups = [(label, tuple(names)) for label, names in groups]

    def extended(self, label, names) -> "_Scope":
        return _Scope(*self.groups, (label, names))

    @property
    def names(self) -> set:
        return {n for _, g in self.groups for n in g}

    def check(self, expr: Expression, path: str) -> None:
        unknown = sorted(expr.names - self.names)
        if unknown:
            known = "; ".join(f"{label}: {', '.join(g) if g else '(none)'}" for label, g in self.groups)
            s = "s" if len(unknown) > 1 else ""
            raise DescriptionError(f"{path}: unknown name{s} {', '.join(map(repr, unknown))} in {expr.text!r}; "
                                   f"known here: {known}")


# ================================================================================================
# Scalars, parameters
# ================================================================================================
_UNITFUL = ("length", "angle")
_EXAMPLE_UNIT = {"length": "mm", "angle": "deg"}
_KIND_TEXT = {"length": "a length (e.g. '135 mm')", "angle": "an angle (e.g. '15 deg')",
              "dimensionless": "a number", None: "a number"}


def _bare_number_error(path, raw, kind):
    return DescriptionError(f"{path}: a bare number ({raw!r}) is not allowed for {_KIND_TEXT[kind]}; "
                            f"give a unit, e.g. '{raw} {_EXAMPLE_UNIT[kind]}', or an expression of parameters")


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
        if self.const is not None and not math.isfinite(self.const):
            raise DescriptionError(f"{path}: must be finite, got {raw!r}")

    def __call__(self, env) -> float:
        if self.const is not None:
            return self.const
        with np.errstate(all="ignore"):
            v = self.expr(env)
        if np.ndim(v) != 0:
            raise DescriptionError(f"{self.path}: {self.expr.text!r} is a list, not a single value; "
                                   f"index it, e.g. name[0]")
        v = float(v)
        if not math.isfinite(v):
            raise DescriptionError(f"{self.path}: {self.expr.text!r} evaluates to {v} (not finite)")
        return v


_PARAM_KINDS = ("length", "angle", "dimensionless")
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
                               f"give a length, an angle or a number")
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
                               f"'15 deg') or a plain number: unknown or unsuitable unit")
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


@dataclass(frozen=True)
class _Param:
    name: str
    kind: str
    default: Any
    shape: tuple
    lo: float | None = None
    hi: float | None = None
    doc: str = ""

    def coerce(self, value, where: str):
        unit = {"length": "m", "angle": "rad", "dimensionless": "a plain number"}[self.kind]
        if self.shape == ():
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise ValueError(f"{where} must be a number ({self.kind}, SI: {unit}), got {value!r}")
            a = np.asarray(float(value))
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
        if self.lo is not None and np.any(a < self.lo):
            raise ValueError(f"{where} must be >= {self.lo} ({unit}), got {value!r}")
        if self.hi is not None and np.any(a > self.hi):
            raise ValueError(f"{where} must be <= {self.hi} ({unit}), got {value!r}")
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
        lo = hi = None
        doc = ""
        if isinstance(spec, dict):
            _check_keys(spec, {"value", "kind", "min", "max", "doc"}, path, "a parameter")
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
            for nm, b in (("min", lo), ("max", hi)):
                if b is not None and not isinstance(b, float):
                    raise DescriptionError(f"{path}.{nm}: a bound must be a single value")
        p = _Param(name, kind, default, np.shape(default), lo, hi, doc)
        try:
            p.coerce(default, path)
        except ValueError as e:
            raise DescriptionError(str(e)) from None
        out.append(p)
    return out


def _param_env(params_obj, plist) -> dict:
    env = {}
    for p in plist:
        v = getattr(params_obj, p.name)
        env[p.name] = np.float64(v) if p.shape == () else np.asarray(v, dtype=float)
    return env


# ================================================================================================
# Anchor sets
# ================================================================================================
_PLANES = {"xy": (0, 1, 2), "yx": (1, 0, 2), "xz": (0, 2, 1), "zx": (2, 0, 1), "yz": (1, 2, 0), "zy": (2, 1, 0)}
_PATTERNS = {
    "points": ({"points"}, {"points"}),
    "circle": ({"radius", "angles"}, {"radius", "angles"}),
    "polygon": ({"n", "radius", "phase"}, {"n", "radius"}),
    "paired": ({"n", "radius", "phase", "separation"}, {"n", "radius", "separation"}),
    "rectangle": ({"length", "width"}, {"length", "width"}),
}
_SET_COMMON = {"pattern", "plane", "offset", "scale", "rotation", "shift", "doc"}


def _count(raw, path, lo=1) -> int:
    if isinstance(raw, bool) or not isinstance(raw, int) or raw < lo:
        raise DescriptionError(f"{path}: must be an integer >= {lo}, got {raw!r}")
    return raw


def _list_param(name, params, path, kind, ndim_ok):
    p = params.get(name)
    if p is None:
        raise DescriptionError(f"{path}: {name!r} is not a parameter; give a list here or the name of a list "
                               f"parameter (parameters: {', '.join(params) or '(none)'})")
    if len(p.shape) not in ndim_ok or p.kind != kind:
        raise DescriptionError(f"{path}: parameter {name!r} is a {p.kind} of shape {p.shape}; expected a list "
                               f"of {kind}s here")
    return p


@dataclass
class _Anchors:
    """Built anchor points (n, 3) with the directions of their set's plane."""

    points: np.ndarray
    radial: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray  # (3,)


class _AnchorSet:
    def __init__(self, name: str, raw, path: str, scope: _Scope, params: dict):
        self.name, self.path = name, path
        if isinstance(raw, list):
            raw = {"pattern": "points", "points": raw}
        if not isinstance(raw, dict):
            raise DescriptionError(f"{path}: give a list of points or a mapping with a pattern "
                                   f"({', '.join(_PATTERNS)}), got {raw!r}")
        pat = raw.get("pattern")
        if pat is None:
            raise DescriptionError(f"{path}.pattern: required key is missing; one of {', '.join(_PATTERNS)}")
        if pat not in _PATTERNS:
            raise DescriptionError(f"{path}.pattern: unknown pattern {pat!r}; allowed: {', '.join(_PATTERNS)}")
        keys, required = _PATTERNS[pat]
        _check_keys(raw, _SET_COMMON | keys, path, f"a {pat} pattern")
        for k in sorted(required - set(raw)):
            raise DescriptionError(f"{path}.{k}: required key of a {pat} pattern is missing")
        self.pattern = pat
        plane = raw.get("plane", "xy")
        if plane not in _PLANES:
            raise DescriptionError(f"{path}.plane: {plane!r} is not a plane; allowed: {', '.join(_PLANES)}")
        self.axes = _PLANES[plane]
        S = lambda key, kind, default=None: _Scalar(raw.get(key, default), kind, f"{path}.{key}", scope)  # noqa: E731
        self.offset = S("offset", "length", 0)
        self.scale = S("scale", "dimensionless", 1)
        self.rotation = S("rotation", "angle", 0)
        shift = raw.get("shift", [0, 0, 0])
        if not isinstance(shift, list) or len(shift) != 3:
            raise DescriptionError(f"{path}.shift: give [dx, dy, dz] with units, got {shift!r}")
        self.shift = [_Scalar(v, "length", f"{path}.shift[{i}]", scope) for i, v in enumerate(shift)]
        self.points_param = None
        self.point_rows = None
        self.angles_param = None
        self.angles = None
        if pat == "points":
            pts = raw["points"]
            if isinstance(pts, str):
                self.points_param = _list_param(pts, params, f"{path}.points", "length", (2,))
                if self.points_param.shape[1] not in (2, 3):
                    raise DescriptionError(f"{path}.points: parameter {pts!r} must hold points of 2 or 3 coordinates")
            elif isinstance(pts, list) and pts:
                rows = []
                for i, row in enumerate(pts):
                    if not isinstance(row, list) or len(row) not in (2, 3):
                        raise DescriptionError(f"{path}.points[{i}]: a point is a list [x, y, z] (or [a, b] in the "
                                               f"set's plane) of lengths with units, got {row!r}")
                    rows.append([_Scalar(v, "length", f"{path}.points[{i}][{j}]", scope) for j, v in enumerate(row)])
                self.point_rows = rows
            else:
                raise DescriptionError(f"{path}.points: give a non-empty list of points or the name of a "
                                       f"list parameter, got {pts!r}")
        elif pat == "circle":
            self.radius = S("radius", "length")
            ang = raw["angles"]
            if isinstance(ang, str):
                self.angles_param = _list_param(ang, params, f"{path}.angles", "angle", (1,))
            elif isinstance(ang, list) and ang:
                self.angles = [_Scalar(v, "angle", f"{path}.angles[{i}]", scope) for i, v in enumerate(ang)]
            else:
                raise DescriptionError(f"{path}.angles: give a non-empty list of angles or the name of a list "
                                       f"parameter, got {ang!r}")
        elif pat in ("polygon", "paired"):
            self.n = _count(raw["n"], f"{path}.n")
            self.radius = S("radius", "length")
            self.phase = S("phase", "angle", 0)
            if pat == "paired":
                self.separation = S("separation", "angle")
        else:
            self.length = S("length", "length")
            self.width = S("width", "length")

    def build(self, env) -> _Anchors:
        i1, i2, i3 = self.axes
        off = self.offset(env)
        if self.pattern == "points":
            if self.points_param is not None:
                rows = np.asarray(env[self.points_param.name], dtype=float)
            else:
                rows = [[s(env) for s in row] for row in self.point_rows]
            P = []
            for row in rows:
                if len(row) == 3:
                    P.append(np.asarray(row, dtype=float))
                else:
                    v = np.zeros(3)
                    v[i1], v[i2], v[i3] = row[0], row[1], off
                    P.append(v)
            P = np.array(P)
        else:
            if self.pattern == "circle":
                ang = (np.asarray(env[self.angles_param.name], dtype=float) if self.angles_param is not None
                       else np.array([a(env) for a in self.angles]))
                r = self.radius(env)
                ab = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
            elif self.pattern in ("polygon", "paired"):
                r, ph = self.radius(env), self.phase(env)
                centres = ph + 2 * np.pi * np.arange(self.n) / self.n
                if self.pattern == "paired":
                    h = 0.5 * self.separation(env)
                    ang = np.column_stack([centres - h, centres + h]).ravel()
                else:
                    ang = centres
                ab = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
            else:
                a, b = 0.5 * self.length(env), 0.5 * self.width(env)
                ab = np.array([[a, b], [-a, b], [-a, -b], [a, -b]])
            P = np.zeros((ab.shape[0], 3))
            P[:, i1], P[:, i2], P[:, i3] = ab[:, 0], ab[:, 1], off
        s, rot = self.scale(env), self.rotation(env)
        if s != 1.0 or rot != 0.0:
            a, b = s * P[:, i1], s * P[:, i2]
            c, sn = np.cos(rot), np.sin(rot)
            P[:, i1], P[:, i2] = c * a - sn * b, sn * a + c * b
        P = P + np.array([v(env) for v in self.shift])
        return _directions(P, self.axes)


def _directions(P: np.ndarray, axes) -> _Anchors:
    i1, i2, i3 = axes
    e = np.eye(3)
    ab = P[:, [i1, i2]]
    n = np.linalg.norm(ab, axis=1, keepdims=True)
    u = np.divide(ab, n, out=np.zeros_like(ab), where=n > 1e-15)
    radial = u[:, :1] * e[i1] + u[:, 1:] * e[i2]
    tangent = -u[:, 1:] * e[i1] + u[:, :1] * e[i2]
    return _Anchors(P, radial, tangent, e[i3].copy())


# ================================================================================================
# Legs
# ================================================================================================
#: Options of each leg type: {key: "axis_base" | "axis_platform" | "length" | "branch"}.
LEG_OPTIONS = {
    "SPS": {},
    "UPS": {"u_axis": "axis_base"},
    "PUS": {"slider_axis": "axis_base", "u_axis": "axis_base", "link_length": "length", "branch": "branch"},
    "RPS": {"r_axis": "axis_base"},
    "RPU": {"r_axis": "axis_base", "u_platform_axis": "axis_platform"},
    "UPU": {"u_axis": "axis_base", "u_platform_axis": "axis_platform"},
    "PRS": {"slider_axis": "axis_base", "r_axis": "axis_base", "link_length": "length", "branch": "branch"},
}
_LEG_REQUIRED = {"PUS": ("link_length",), "PRS": ("link_length",)}
#: Leg types the leg library can build without an actuator (a constraining limb).
PASSIVE_CAPABLE = ("RPS", "UPU")
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
        if isinstance(raw, str):
            s = raw.strip()
            sign = -1.0 if s.startswith("-") else 1.0
            key = s.lstrip("+-").strip()
            if key in _NAMED_AXES or key in _ANCHOR_AXES:
                self.named = (sign, key)
                return
            raise DescriptionError(f"{path}: unknown direction {raw!r}; give x, y, z, radial, tangent or normal "
                                   f"(optionally with a sign, e.g. -z) or [ax, ay, az]")
        if isinstance(raw, list) and len(raw) == 3:
            self.vector = [_Scalar(v, "dimensionless", f"{path}[{i}]", scope) for i, v in enumerate(raw)]
            return
        raise DescriptionError(f"{path}: expected a direction (x, y, z, radial, tangent, normal or [ax, ay, az]), "
                               f"got {raw!r}")

    def __call__(self, env, anchors: _Anchors, k: int) -> np.ndarray:
        if self.vector is not None:
            v = np.array([s(env) for s in self.vector])
        else:
            sign, key = self.named
            if key in _NAMED_AXES:
                v = sign * np.array(_NAMED_AXES[key], dtype=float)
            else:
                v = sign * {"radial": anchors.radial[k], "tangent": anchors.tangent[k], "normal": anchors.normal}[key]
                if not np.any(v):
                    raise DescriptionError(f"{self.path}: {key!r} is undefined for an anchor on the axis of its "
                                           f"set's plane (point {anchors.points[k].tolist()}); give the direction")
        if not np.linalg.norm(v) > 0:
            raise DescriptionError(f"{self.path}: the direction must not be zero")
        return v


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
        if self.point is not None:
            return _directions(np.array([[s(env) for s in self.point]]), _PLANES["xy"])
        a = built[self.set]
        i = self.indices
        return _Anchors(a.points[i], a.radial[i], a.tangent[i], a.normal)


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
                                       f"actuated at its prismatic joint '{act_letter}'); passive legs: "
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
                                   f"its actuated joint is the prismatic joint '{act_letter}'{alt}")
        return True

    def build(self, env, built_base, built_plat) -> list:
        A = self.base.resolve(env, built_base)
        B = self.platform.resolve(env, built_plat)
        legs = []
        for j, name in enumerate(self.names):
            kb = 0 if self.base.n == 1 else j
            kp = 0 if self.platform.n == 1 else j
            kw = {}
            for k, spec in self.options.items():
                kind = LEG_OPTIONS[self.type][k]
                if kind == "axis_base":
                    kw[k] = spec(env, A, kb)
                elif kind == "axis_platform":
                    kw[k] = spec(env, B, kp)
                elif kind == "length":
                    kw[k] = spec(env)
                else:
                    kw[k] = spec
            if self.type in PASSIVE_CAPABLE:
                kw["passive"] = not self.actuated
            try:
                legs.append(self.cls(name, base=A.points[kb], platform=B.points[kp], **kw))
            except ValueError as e:
                raise DescriptionError(f"{self.label}: {e}") from None
        return legs


# ================================================================================================
# Task parametrisation
# ================================================================================================
_TASK_KEYS = {"coordinates", "define", "position", "orientation", "valid", "home", "ranges", "restricted", "doc"}
_COORD_KINDS = ("length", "angle")


def _pose_expression(raw, path, scope, kind):
    e = Expression(raw, path, scope)
    if e.is_constant and not e.has_units and kind in _UNITFUL:
        with np.errstate(all="ignore"):
            v = float(e({}))
        if v != 0:
            raise _bare_number_error(path, raw, kind)
    return e


class _Task:
    def __init__(self, raw, pscope: _Scope, param_names):
        path = "task"
        if not isinstance(raw, dict):
            raise DescriptionError("task: required mapping with coordinates, position, orientation, home")
        _check_keys(raw, _TASK_KEYS, path, "task")
        coords = raw.get("coordinates")
        if not isinstance(coords, dict) or not coords:
            raise DescriptionError("task.coordinates: give a mapping {name: length | angle}, e.g. {z: length, theta: angle}")
        self.coords = []
        for c, kind in coords.items():
            _check_identifier(c, f"task.coordinates.{c}", "coordinate")
            if c in param_names:
                raise DescriptionError(f"task.coordinates.{c}: {c!r} is also a parameter; use distinct names")
            if kind not in _COORD_KINDS:
                raise DescriptionError(f"task.coordinates.{c}: kind must be length or angle, got {kind!r}")
            self.coords.append((c, kind))
        self.names = tuple(c for c, _ in self.coords)
        self.kinds = dict(self.coords)
        scope = pscope.extended("task coordinates", self.names)
        self.defines = []
        defs = raw.get("define") or {}
        if not isinstance(defs, dict):
            raise DescriptionError("task.define: give a mapping {name: expression}, evaluated in order")
        coord_scope = scope
        for name, text in defs.items():
            p = f"task.define.{name}"
            _check_identifier(name, p, "defined")
            if name in scope.names:
                raise DescriptionError(f"{p}: {name!r} is already a parameter, coordinate or defined name")
            self.defines.append((name, Expression(text, p, scope)))
            scope = coord_scope.extended("defined names", [d for d, _ in self.defines])
        self.pose_scope = scope
        # orientation
        orient = raw.get("orientation")
        self.convention = None
        self.rot_axes = []
        self.angles = []
        if orient is not None:
            if not isinstance(orient, dict):
                raise DescriptionError("task.orientation: give {convention: zyz, angles: [...]} or {rotations: [...]}")
            _check_keys(orient, {"convention", "angles", "rotations"}, "task.orientation", "the orientation")
            if "rotations" in orient:
                if "convention" in orient or "angles" in orient:
                    raise DescriptionError("task.orientation: give either convention with angles, or rotations")
                rots = orient["rotations"]
                if not isinstance(rots, list) or not rots:
                    raise DescriptionError("task.orientation.rotations: give a list of "
                                           "{axis: x | y | z | [ax, ay, az], angle: expression}")
                for k, r in enumerate(rots):
                    p = f"task.orientation.rotations[{k}]"
                    if not isinstance(r, dict) or set(r) != {"axis", "angle"}:
                        raise DescriptionError(f"{p}: give {{axis: ..., angle: ...}}, got {r!r}")
                    ax = r["axis"]
                    numeric = (isinstance(ax, list) and len(ax) == 3
                               and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in ax))
                    if isinstance(ax, str) and ax in _NAMED_AXES:
                        vec = np.array(_NAMED_AXES[ax], dtype=float)
                    elif numeric and np.linalg.norm(ax) > 0:
                        vec = np.asarray(ax, dtype=float) / np.linalg.norm(ax)
                    else:
                        raise DescriptionError(f"{p}.axis: give x, y, z or a non-zero [ax, ay, az] of numbers, "
                                               f"got {ax!r}")
                    self.rot_axes.append(vec)
                    self.angles.append(_pose_expression(r["angle"], f"{p}.angle", scope, "angle"))
            else:
                conv = orient.get("convention")
                if conv not in EULER_CONVENTIONS:
                    raise DescriptionError(f"task.orientation.convention: {conv!r} is not a convention; allowed: "
                                           f"{', '.join(sorted(EULER_CONVENTIONS))} (or give rotations: [...])")
                ang = orient.get("angles")
                k = len(EULER_CONVENTIONS[conv])
                if not isinstance(ang, list) or len(ang) != k:
                    raise DescriptionError(f"task.orientation.angles: convention {conv!r} takes {k} angles, got {ang!r}")
                self.convention = conv
                self.angles = [_pose_expression(a, f"task.orientation.angles[{j}]", scope, "angle")
                               for j, a in enumerate(ang)]
        # position
        pos = raw.get("position")
        if isinstance(pos, dict):
            _check_keys(pos, {"x", "y", "z"}, "task.position", "the position")
            missing = [c for c in "xyz" if c not in pos]
            if missing:
                raise DescriptionError(f"task.position.{missing[0]}: required component is missing")
            pos = [pos["x"], pos["y"], pos["z"]]
        if not isinstance(pos, list) or len(pos) != 3:
            raise DescriptionError(f"task.position: give [x, y, z] expressions of the task coordinates, got {pos!r}")
        rscope = scope.extended("orientation entries", R_NAMES)
        self.position = [_pose_expression(v, f"task.position[{j}]", rscope, "length") for j, v in enumerate(pos)]
        self.position_uses_R = any(e.names & set(R_NAMES) for e in self.position)
        # validity conditions
        valid = raw.get("valid") or []
        if isinstance(valid, str):
            valid = [valid]
        if not isinstance(valid, list):
            raise DescriptionError("task.valid: give a list of conditions such as 'abs(cos(theta)) > 1e-9'")
        self.valid = [Expression(v, f"task.valid[{j}]", scope, allow_compare=True) for j, v in enumerate(valid)]
        # home and ranges
        home = raw.get("home")
        if not isinstance(home, dict):
            raise DescriptionError(f"task.home: give {{coordinate: value with unit}} for {', '.join(self.names)}")
        for c in home:
            if c not in self.kinds:
                raise DescriptionError(f"task.home.{c}: not a task coordinate; coordinates: {', '.join(self.names)}")
        for c in self.names:
            if c not in home:
                raise DescriptionError(f"task.home.{c}: required coordinate is missing")
        self.home = [_Scalar(home[c], self.kinds[c], f"task.home.{c}", pscope) for c in self.names]
        ranges = raw.get("ranges") or {}
        if not isinstance(ranges, dict):
            raise DescriptionError("task.ranges: give {coordinate: [low, high]} with units")
        self.ranges = {}
        for c, pair in ranges.items():
            p = f"task.ranges.{c}"
            if c not in self.kinds:
                raise DescriptionError(f"{p}: not a task coordinate; coordinates: {', '.join(self.names)}")
            if not isinstance(pair, list) or len(pair) != 2:
                raise DescriptionError(f"{p}: give [low, high] with units, got {pair!r}")
            self.ranges[c] = [_Scalar(v, self.kinds[c], f"{p}[{j}]", pscope) for j, v in enumerate(pair)]
        restricted = raw.get("restricted", False)
        if not isinstance(restricted, bool):
            raise DescriptionError(f"task.restricted: true or false, got {restricted!r}")
        self.restricted = restricted


# ================================================================================================
# Constraints
# ================================================================================================
_CONSTRAINT_KEYS = {
    "actuator_range": {"min", "max"},
    "leg_length": {"legs", "min", "max"},
    "joint_angle": {"key", "legs", "min", "max"},
    "interference": {"diameter", "legs", "pairs"},
    "leg_axis_angle": {"legs", "axis", "frame", "max"},
    "coordinate_range": {"coordinate", "min", "max"},
    "expression": {"margin", "unit"},
}
_CONSTRAINT_REQUIRED = {"leg_length": {"legs"}, "joint_angle": {"key"}, "interference": {"diameter"},
                        "leg_axis_angle": {"legs", "axis", "max"}, "coordinate_range": {"coordinate"},
                        "expression": {"margin"}}


@dataclass(frozen=True)
class ExpressionConstraint(Constraint):
    """A margin given as an expression of the parameters, task coordinates, defined names and
    the platform pose (``px, py, pz`` and ``R11 .. R33``), >= 0 where feasible."""

    text: str = ""
    evaluate: Callable | None = dataclasses.field(default=None, repr=False, compare=False)
    unit: str = "1"

    def margin(self, ctx):
        return np.asarray(self.evaluate(ctx), dtype=float) * np.ones(ctx.X.shape[0])


class _ConstraintSpec:
    def __init__(self, i, raw, leg_names, task: _Task, pscope: _Scope):
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

    def build(self, mech: "DescribedMechanism") -> Constraint:
        env = mech._penv
        lo = self.min(env) if self.min is not None else None
        hi = self.max(env) if self.max is not None else None
        if lo is not None and hi is not None and not lo < hi:
            raise DescriptionError(f"{mech.name}: {self.path}: min ({lo:g}) must be below max ({hi:g}) (SI)")
        lo_ = -np.inf if lo is None else lo
        hi_ = np.inf if hi is None else hi
        t = self.type
        if t == "actuator_range":
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


# ================================================================================================
# The description and its mechanism class
# ================================================================================================
_TOP_KEYS = {"name", "summary", "description", "parameters", "checks", "base", "platform", "legs", "task",
             "length_scale", "constraints"}


class Description:
    """A parsed and validated mechanism description (structure only; numbers are evaluated for
    each parameter set by :meth:`build`)."""

    def __init__(self, data: dict, source: str | None = None):
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
        self.text = str(data.get("description", "") or "")
        self.params = _parse_params(data.get("parameters"))
        self.param_by_name = {p.name: p for p in self.params}
        pscope = _Scope(("parameters", [p.name for p in self.params]))
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
        self.task = _Task(data.get("task"), pscope, set(self.param_by_name))
        self.length_scale = (_Scalar(data["length_scale"], "length", "length_scale", pscope)
                             if "length_scale" in data else None)
        cons = data.get("constraints") or []
        if not isinstance(cons, list):
            raise DescriptionError("constraints: give a list of constraints")
        self.constraints = [_ConstraintSpec(i, c, self.leg_names, self.task, pscope) for i, c in enumerate(cons)]
        names = [c.name for c in self.constraints]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise DescriptionError(f"constraints: name(s) {dup} used twice")
        try:
            text = json.dumps(data, sort_keys=True, default=str)
        except TypeError:  # keys of mixed types
            text = repr(data)
        self.digest = hashlib.sha1(text.encode()).hexdigest()[:10]

    def build_geometry(self, env):
        base = {n: s.build(env) for n, s in self.base_sets.items()}
        plat = {n: s.build(env) for n, s in self.plat_sets.items()}
        legs = []
        for g in self.legs:
            legs += g.build(env, base, plat)
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


def _make_params_class(desc: Description, cls_name: str):
    plist = desc.params
    mname = desc.name
    checks = desc.checks
    units = {p.name: p.kind for p in plist}

    def __post_init__(self):
        for p in plist:
            object.__setattr__(self, p.name, p.coerce(getattr(self, p.name), f"{mname}.{p.name}"))
        env = _param_env(self, plist)
        for chk in checks:
            with np.errstate(all="ignore"):
                ok = chk(env)
            if not bool(np.all(ok)):
                vals = ", ".join(f"{n}={env[n]!r}" for n in sorted(chk.names))
                raise ValueError(f"{mname}: the parameters fail the check {chk.text!r} ({vals}, SI)")

    fields = [(p.name, float if p.shape == () else tuple, dataclasses.field(default=p.default)) for p in plist]
    doc = (f"Parameters of {mname} in SI (m, rad); defaults from its description. Units: "
           + ", ".join(f"{p.name} ({p.kind})" for p in plist))
    return dataclasses.make_dataclass(f"{cls_name}Params", fields, frozen=True,
                                      namespace={"UNITS": units, "__post_init__": __post_init__, "__doc__": doc})


@dataclass(frozen=True)
class DescribedMobility(Mobility):
    """:class:`~parasynth.mechanism.Mobility` of a described mechanism with the findings of
    its consistency checks: ``issues`` (messages, each also issued as a
    :class:`DescriptionWarning`), ``under_actuated`` (the actuators do not control every
    freedom) and ``consistent`` (the task parametrisation agrees with what the legs allow)."""

    issues: tuple = ()
    under_actuated: bool = False
    consistent: bool = True

    def summary(self) -> str:
        s = super().summary()
        if self.issues:
            s += "\nissues:\n  " + "\n  ".join(self.issues)
        return s


class DescribedMechanism(Mechanism):
    """A mechanism built from a :class:`Description`. Subclasses are made by
    :func:`description_class`; instantiate them with a ``Params`` object (SI) or nothing for the
    description's defaults."""

    description: Description
    Params: type

    def __init__(self, params=None):
        d = self.description
        P = self.Params() if params is None else params
        if not isinstance(P, self.Params):
            raise ValueError(f"{self.name}: params must be a {self.Params.__name__} (use {self.name}.Params(...) or "
                             f"load_mechanism(..., **params))")
        self.params = P
        self._penv = _param_env(P, d.params)
        try:
            legs, home, L = d.build_geometry(self._penv)
        except DescriptionError as e:
            raise DescriptionError(f"{self.name}: {e}") from None
        self.home = np.asarray(home, dtype=float)
        self._check_pose_expressions(self.home)
        self._check_home(legs)
        try:
            super().__init__(P, legs, home, L)
        except ValueError as e:
            raise DescriptionError(f"{self.name}: task.home: {e}") from None
        self._check_constraints()

    # -- pose ------------------------------------------------------------------------------------
    def _task_env(self, X, dual: bool = False) -> dict:
        """Parameters, task coordinates and defined names for poses X (N, n_task)."""
        env = dict(self._penv)
        N, n = X.shape
        if dual:
            eye = np.eye(n)
            for j, c in enumerate(self.task_coordinates):
                env[c] = _Dual(X[:, j], np.broadcast_to(eye[j], (N, n)))
        else:
            for j, c in enumerate(self.task_coordinates):
                env[c] = X[:, j]
        with np.errstate(all="ignore"):
            for name, e in self.description.task.defines:
                env[name] = e(env, dual)
        return env

    def _rotation(self, a: np.ndarray):
        """R (N, 3, 3) and E (N, 3, k) with omega = E @ angle rates, for angles a (N, k)."""
        t = self.description.task
        N = a.shape[0]
        if t.convention is not None:
            return euler_to_matrix(t.convention, a), euler_rate_map(t.convention, a)
        if not t.rot_axes:
            return np.broadcast_to(np.eye(3), (N, 3, 3)).copy(), np.zeros((N, 3, 0))
        R = np.broadcast_to(np.eye(3), (N, 3, 3))
        cols = []
        for k, ax in enumerate(t.rot_axes):
            cols.append(R @ ax)
            R = R @ rot_axis(ax, a[:, k])
        return R, np.stack(cols, axis=-1)

    def _pose_eval(self, X, dual: bool):
        t = self.description.task
        N, n = X.shape
        env = self._task_env(X, dual)
        with np.errstate(all="ignore"):
            angs = [e(env, dual) for e in t.angles]
            a = np.stack([np.broadcast_to(_val(v), (N,)) for v in angs], -1) if angs else np.zeros((N, 0))
            R, E = self._rotation(a)
            W = None
            if dual:
                da = (np.stack([np.broadcast_to(_grad(v), (N, n)) for v in angs], 1) if angs
                      else np.zeros((N, 0, n)))
                W = E @ da  # (N, 3, n): angular velocity per unit coordinate rate
            if t.position_uses_R:
                if dual:
                    # dR/dX_t = skew(omega_t) R, omega_t = W[:, :, t]
                    dR = np.einsum("ntij,njk->nikt", skew(np.moveaxis(W, -1, 1)), R)
                for nm in R_NAMES:
                    i, j = int(nm[1]) - 1, int(nm[2]) - 1
                    env[nm] = _Dual(R[:, i, j], dR[:, i, j, :]) if dual else R[:, i, j]
            pos = [e(env, dual) for e in t.position]
            p = np.stack([np.broadcast_to(_val(v), (N,)) for v in pos], -1).astype(float)
            dp = np.stack([np.broadcast_to(_grad(v), (N, n)) for v in pos], 1) if dual else None
        return p, np.ascontiguousarray(R, dtype=float), dp, W

    def _pose(self, X):
        p, R, _, _ = self._pose_eval(X, False)
        return p, R

    def _twist_map(self, X):
        _, _, dp, W = self._pose_eval(X, True)
        T = np.zeros((X.shape[0], 6, self.n_task))
        T[:, :3] = dp
        T[:, 3:] = W
        return T

    def pose_valid(self, X):
        ok = np.all(np.isfinite(X), axis=-1)
        Xs = np.where(ok[:, None], X, self.home)
        t = self.description.task
        if t.valid:
            env = self._task_env(Xs)
            with np.errstate(all="ignore"):
                for c in t.valid:
                    ok = ok & np.broadcast_to(np.asarray(c(env), dtype=bool), ok.shape)
        p, R = self._pose(Xs)
        return ok & np.all(np.isfinite(p), axis=-1) & np.all(np.isfinite(R), axis=(-1, -2))

    def default_ranges(self) -> dict:
        out = {}
        for c, (lo, hi) in self.description.task.ranges.items():
            out[c] = (lo(self._penv), hi(self._penv))
        return out

    def build_constraints(self):
        return [c.build(self) for c in self.description.constraints]

    # -- construction checks ---------------------------------------------------------------------
    def _check_pose_expressions(self, home):
        X = home[None, :]
        try:
            p, R = self._pose(X)
            T = self._twist_map(X)
        except DescriptionError as e:
            raise DescriptionError(f"{self.name}: {e}") from None
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(R)) and np.all(np.isfinite(T))):
            raise DescriptionError(f"{self.name}: task.home: the pose expressions are not finite at the home pose "
                                   f"{home.tolist()}")
        if not self.pose_valid(X)[0]:
            raise DescriptionError(f"{self.name}: task.home: the home pose {home.tolist()} fails task.valid")

    def _check_home(self, legs):
        p, R = self._pose(self.home[None, :])
        for leg in legs:
            with np.errstate(all="ignore"):
                st = leg.solve(p, R)
            if not (st.reachable[0] and np.all(np.isfinite(st.direction[0]))):
                why = ""
                if not np.isfinite(st.actuator[0]):
                    why = " (its platform anchor is further than link_length from its slider line)"
                elif "off_plane" in st.extra:
                    why = (f" (its platform anchor is {st.extra['off_plane'][0] * 1e3:.4g} mm off the plane its "
                           f"revolute joint allows: the position or orientation misses a dependent coordinate?)")
                raise DescriptionError(f"{self.name}: task.home: the home pose {self.home.tolist()} is not reachable "
                                       f"by leg {leg.name} ({leg.joints}){why}")

    def _check_constraints(self):
        try:
            cons = self.constraints
        except DescriptionError as e:
            raise DescriptionError(f"{self.name}: {e}") from None
        except ValueError as e:
            raise DescriptionError(f"{self.name}: constraints: {e}") from None
        ctx = self.pose_context(self.home[None, :])
        for spec, c in zip(self.description.constraints, cons.values()):
            try:
                with np.errstate(all="ignore"):
                    c.margin(ctx)
            except DescriptionError as e:
                raise DescriptionError(f"{self.name}: {e}") from None
            except (ValueError, KeyError) as e:
                raise DescriptionError(f"{self.name}: {spec.path}: {e}") from None

    # -- mobility with consistency checks ----------------------------------------------------------
    @property
    def constraint_rank(self) -> int:
        if self._constraint_rank is None:
            self._constraint_rank = Mechanism.mobility(self).constraint_rank
        return self._constraint_rank

    def mobility(self, X=None, warn: bool = True) -> DescribedMobility:
        """Screw-theory mobility (see :meth:`Mechanism.mobility`) plus checks of the description:

        * under-actuation: the actuators do not control every freedom;
        * more task coordinates than freedoms, or fewer without ``task.restricted: true``;
        * task coordinates that do not move the platform independently (at every pose near X);
        * a parametrisation that leaves the legs' constraints: a small step of a task coordinate
          makes a leg unreachable, or its motion does work against a leg's constraint wrench.

        Each finding is a message in ``issues`` and, with ``warn=True``, a
        :class:`DescriptionWarning`."""
        base = Mechanism.mobility(self, X)
        X0 = self.home if X is None else np.asarray(X, dtype=float)
        issues, inconsistent = [], False
        t = self.description.task
        n, dof = self.n_task, base.dof
        if not base.controlled:
            issues.append(
                f"{self.name}: under-actuated: the {self.n_actuators} actuator(s) {', '.join(self.actuators)} do not "
                f"control all {dof} freedoms ({base.type}); {max(len(base.uncontrolled_twists), 1)} freedom(s) stay "
                f"uncontrolled (see uncontrolled_twists; forward kinematics needs fixed={{...}})")
        if n > dof:
            inconsistent = True
            issues.append(
                f"{self.name}: inconsistent description: {n} task coordinates {self.task_coordinates} but the legs "
                f"leave {dof} freedom(s) ({base.type}, constraint rank {base.constraint_rank}); the parametrisation "
                f"describes motions the legs forbid")
        elif n < dof and not t.restricted:
            issues.append(
                f"{self.name}: the {n} task coordinates {self.task_coordinates} cover fewer than the {dof} freedoms "
                f"({base.type}) the legs allow; add coordinates, or set task.restricted: true if the restriction is "
                f"intended (e.g. a coupling such as x = z*tan(theta))")
        found = self._parametrisation_issues(X0)
        inconsistent |= bool(found)
        issues += found
        if warn:
            for msg in issues:
                warnings.warn(msg, DescriptionWarning, stacklevel=2)
        fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(Mobility)}
        return DescribedMobility(**fields, issues=tuple(issues), under_actuated=not base.controlled,
                                 consistent=not inconsistent)

    def _parametrisation_issues(self, X0) -> list[str]:
        L = self.length_scale
        n = self.n_task
        ang = np.array([c in self.angular_coordinates for c in self.task_coordinates])
        step = np.where(ang, 1e-3, 1e-3 * L)
        rng = np.random.default_rng(20240611)
        Xp = [X0 + s * step * np.eye(n)[j] for j in range(n) for s in (1.0, -1.0)]
        Xp += [X0 + step * rng.uniform(-1, 1, n) for _ in range(3)]
        Xp = np.array(Xp)
        out = []
        _, states, p = self.leg_states(Xp)
        reach = np.logical_and.reduce([st.reachable for st in states])
        if not np.all(reach[: 2 * n]):
            bad_coords = sorted({self.task_coordinates[k // 2] for k in np.flatnonzero(~reach[: 2 * n])},
                                key=self.task_coordinates.index)
            bad_legs = sorted({leg.name for leg, st in zip(self.legs, states) if not np.all(st.reachable[: 2 * n])})
            out.append(
                f"{self.name}: inconsistent parametrisation: a small step of {', '.join(bad_coords)} from the analysed "
                f"pose leaves the reach of leg(s) {', '.join(bad_legs)}; the task coordinates do not follow the motion "
                f"the legs allow (a dependent coordinate, e.g. a parasitic motion, is missing or wrong)")
            return out
        keep = np.flatnonzero(reach)  # (the random steps may leave the workspace near its boundary)
        Xp, p = Xp[keep], p[keep]
        states = [dataclasses.replace(st, **{f.name: _take(getattr(st, f.name), keep)
                                            for f in dataclasses.fields(st)}) for st in states]
        T = self._twist_map(Xp)
        Ts = T.copy()
        Ts[:, 3:] *= L
        colnorm = np.linalg.norm(Ts, axis=1)  # (M, n)
        # Task coordinates that do not move the platform independently, at every pose tried.
        deficient = []
        for k in range(Xp.shape[0]):
            s = np.linalg.svd(Ts[k], compute_uv=False)
            deficient.append(int(np.sum(s > 1e-8 * max(s[0], 1e-300))) < n if s.size else True)
        if all(deficient):
            zero = [c for c, v in zip(self.task_coordinates, colnorm[0]) if v <= 1e-12]
            extra = f" ({', '.join(zero)} do not move the platform)" if zero else ""
            out.append(f"{self.name}: the task coordinates {self.task_coordinates} are not independent: their rates "
                       f"move the platform in fewer than {n} directions at every pose near the analysed one{extra}")
        # Motions that do work against a leg's constraint wrench.
        worst = np.zeros(n)
        for leg, st in zip(self.legs, states):
            Tj = leg.joint_twists(st, p)
            for k, C in enumerate(reciprocal_basis(Tj, L)):
                if not C.shape[0]:
                    continue
                Cs = C.copy()
                Cs[:, 3:] /= L
                Cs /= np.linalg.norm(Cs, axis=1, keepdims=True)
                r = np.abs(Cs @ Ts[k]) / np.maximum(colnorm[k], 1e-300)
                worst = np.maximum(worst, np.max(r, axis=0))
        bad = [c for c, w in zip(self.task_coordinates, worst) if w > 1e-6]
        if bad:
            out.append(f"{self.name}: inconsistent parametrisation: the motion of {', '.join(bad)} does work against "
                       f"the legs' constraint wrenches (relative residual up to {worst.max():.2g}); the pose "
                       f"expressions do not follow the motion the legs allow")
        return out


def _take(v, idx):
    """Rows ``idx`` of a LegState field (arrays, or dicts of arrays)."""
    if isinstance(v, dict):
        return {k: _take(x, idx) for k, x in v.items()}
    return v[idx] if isinstance(v, np.ndarray) and v.ndim else v


def description_class(data: dict, source: str | None = None) -> type:
    """A :class:`DescribedMechanism` subclass for a description given as a dict (the parsed
    YAML). ``source`` names it in error messages. Raises :class:`DescriptionError` (a
    ``ValueError``) naming the key path of the first problem; the description is also built
    once with its default parameters, so that geometric problems surface here."""
    where = source or (data.get("name") if isinstance(data, dict) else None) or "description"
    try:
        desc = Description(data, source)
    except DescriptionError as e:
        raise DescriptionError(f"{where}: {e}") from None
    safe = re.sub(r"\W", "_", desc.name)
    cls_name = f"Described_{safe}_{desc.digest}"
    try:
        params_cls = _make_params_class(desc, cls_name)
        ns = {
            "name": desc.name,
            "summary": desc.summary,
            "paper": desc.summary,
            "source": source,
            "description": desc,
            "Params": params_cls,
            "task_coordinates": desc.task.names,
            "angular_coordinates": frozenset(c for c, k in desc.task.coords if k == "angle"),
            "__doc__": f"{desc.summary}\n\n{desc.text}".strip(),
            "__module__": __name__,
        }
        cls = type(cls_name, (DescribedMechanism,), ns)
        cls()  # build once with the defaults: geometry, home pose, constraints
    except DescriptionError as e:
        msg = str(e)
        raise DescriptionError(msg if msg.startswith(f"{where}:") else f"{where}: {msg}") from None
    except ValueError as e:
        raise DescriptionError(f"{where}: {e}") from None
    return cls


def load_description(path) -> type:
    """Read a YAML description file and return its mechanism class (see :func:`description_class`)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise DescriptionError(f"{p}: cannot read the description ({e.strerror})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise DescriptionError(f"{p.name}: not valid YAML: {e}") from None
    return description_class(data, source=p.name)


def from_description(source, **params) -> DescribedMechanism:
    """Build a described mechanism from a dict or a YAML file path with parameters in SI."""
    cls = description_class(source) if isinstance(source, dict) else load_description(source)
    fields = {f.name for f in dataclasses.fields(cls.Params)}
    unknown = sorted(set(params) - fields)
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown} for mechanism {cls.name!r}; valid: {', '.join(sorted(fields))}")
    return cls(cls.Params(**params))
