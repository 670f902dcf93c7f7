"""The expression language of descriptions.

Expressions are parsed with :mod:`ast` and evaluated by a small interpreter that admits only
numbers, names, ``+ - * / **``, a fixed set of functions and (in conditions) comparisons:
user text is never passed to ``eval``. The same interpreter evaluates the expressions on dual
numbers (:class:`_Dual`, forward-mode differentiation), which gives the exact derivatives the
twist map needs. ``Expression.tree`` keeps the parsed tree (unit literals already SI numbers)
for code generators.
"""

from __future__ import annotations

import ast
import operator
import re
from typing import Callable

import numpy as np

from ...model.spatial import R_NAMES
from ...common.units import LITERAL_UNITS
from .errors import DescriptionError

#: Units recognised inside expressions (:data:`parasynth.common.units.LITERAL_UNITS`) and their factor to
#: SI; each ``<number> <unit>`` is replaced by its SI value.
UNIT_FACTORS = {unit: factor for unit, (_kind, factor) in LITERAL_UNITS.items()}
_NUMBER = r"(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_UNIT_LITERAL = re.compile(r"(?<![\w.])(" + _NUMBER + r")\s*(" + "|".join(sorted(UNIT_FACTORS, key=len, reverse=True)) + r")(?!\w)")
#: A string that is a single quantity such as "135 mm" (parsed by pint, so any unit works).
_PURE_QUANTITY = re.compile(r"^\s*[-+]?" + _NUMBER + r"\s*[^\W\d_][\w\s*/^.]*$")

_ARITY = {"sin": 1, "cos": 1, "tan": 1, "asin": 1, "acos": 1, "atan": 1, "atan2": 2, "sqrt": 1, "exp": 1,
          "log": 1, "abs": 1, "hypot": 2, "min": 2, "max": 2, "clip": 3, "sinh": 1, "cosh": 1, "tanh": 1}
_CONSTANTS = {"pi": np.float64(np.pi)}
#: Names of the platform pose inside constraint expressions (and R entries in positions).
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

    def __init__(self, *groups, kinds: dict | None = None):
        self.groups = [(label, tuple(names)) for label, names in groups]
        #: Quantity kind of the parameters (length, angle, dimensionless), for unit checks.
        self.kinds = dict(kinds or {})

    def extended(self, label, names) -> "_Scope":
        return _Scope(*self.groups, (label, names), kinds=self.kinds)

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
