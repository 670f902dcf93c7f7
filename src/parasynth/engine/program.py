"""Translation of a description's task parametrisation into a register program.

A described mechanism states its pose as expressions (``task.define``, the orientation angles
of an Euler convention or a ``rotations:`` axis list, the position, ``task.valid`` conditions)
and may state constraint margins as expressions. This module turns those expression trees
(``Expression.tree``, Python ``ast`` nodes) into one small straight-line program that the
compiled kernels of :mod:`parasynth.engine.core` interpret over sub-blocks of poses, each
instruction a loop over the sub-block (so the interpretation cost is shared by ~64 poses and
the loops vectorise).

Stages
------
1. **Graph.** The trees become a hash-consed expression graph (common subexpressions shared),
   names resolved: task coordinates are inputs, defined names are their graphs, parameters
   are *parameter slots* (their values are read from ``mech._penv`` for each mechanism, so one
   program serves every design of a description), ``R11..R33`` are the rotation's entries,
   ``px, py, pz`` (in constraint margins) the position. Only subtrees of literals are folded.
2. **Rotation.** The orientation is the product of elementary rotations (an Euler convention's
   axes, or the ``rotations:`` axes), composed entry by entry with the structural zeros and
   ones of the elementary matrices folded away.
3. **Twist map** (optional). Forward-mode derivatives of the position and of the angles with
   respect to each task coordinate, symbolically on the graph; the angular velocity is
   ``omega = sum_k (R_1..R_{k-1} e_k) da_k/dX`` as in :func:`parasynth.model.spatial.euler_rate_map`.
4. **Emission.** The graph is emitted on demand, outputs first; ``sin``/``cos`` of one
   argument become one vectorisable sincos; the sine and cosine of an ``atan2`` are taken
   algebraically (``y/r``, ``x/r``) and of a sum or difference involving one by the addition
   formulas, so that an auxiliary angle such as ``q1 = atan2(x, z - z_B)`` is never
   evaluated as an angle when only its sine and cosine are needed.
5. **Registers.** Virtual registers are mapped to a few physical rows by liveness (the
   scratch of a sub-block stays in the L1 cache).

What a description may use that is not translated (an array parameter used whole, an index
into a non-parameter value, an unknown construct) raises :class:`Untranslatable` naming it;
the engine then runs the NumPy path and says why.
"""

from __future__ import annotations

import ast
import gc
import math
import operator

import numpy as np

from ..model.parasitic import CLOSURE_COUNTS, SOLVE_KEY
from ..model.spatial import EULER_CONVENTIONS, R_NAMES
from .parasitic import solve_nodes

__all__ = ["Untranslatable", "Program", "build_program", "OPS"]


class Untranslatable(Exception):
    """A construct of the description that the compiled path does not handle."""


#: Opcodes of the interpreter (see ``core._run``): instruction rows (op, d, a, b, c, e).
OPS = {name: i for i, name in enumerate(
    ["nop", "add", "sub", "mul", "div", "pow", "neg", "sqrt", "tan", "asin", "acos", "atan", "exp", "log",
     "abs", "sinh", "cosh", "tanh", "atan2", "hypot", "min", "max", "lt", "le", "gt", "ge", "and", "sincos",
     "sincos_atan2", "sign", "select", "square", "copy", "clip", "sin", "cos",
     # fused (see _fuse): the same operations and roundings in one pass over the sub-block
     "madd", "msub", "rmsub", "mmadd", "mmsub"])}

#: Fused opcodes: madd d = a*b + c, msub d = a*b - c, rmsub d = c - a*b, mmadd d = a*b + c*e,
#: mmsub d = a*b - c*e (each product and the sum rounded separately, as the unfused code: no
#: fused multiply-add).
_FUSED = ("madd", "msub", "rmsub", "mmadd", "mmsub")

_UNARY_NP = {"sqrt": np.sqrt, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos, "atan": np.arctan,
             "exp": np.exp, "log": np.log, "abs": np.abs, "sinh": np.sinh, "cosh": np.cosh, "tanh": np.tanh,
             "sin": np.sin, "cos": np.cos, "neg": np.negative, "sign": np.sign}
_BIN_NP = {"add": operator.add, "sub": operator.sub, "mul": operator.mul, "div": operator.truediv,
           "pow": operator.pow, "atan2": np.arctan2, "hypot": np.hypot, "min": np.minimum, "max": np.maximum,
           "lt": operator.lt, "le": operator.le, "gt": operator.gt, "ge": operator.ge}
_AST_BIN = {ast.Add: "add", ast.Sub: "sub", ast.Mult: "mul", ast.Div: "div", ast.Pow: "pow"}
_AST_CMP = {ast.Lt: "lt", ast.LtE: "le", ast.Gt: "gt", ast.GtE: "ge"}
_CALLS = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sqrt", "exp", "log", "abs", "hypot", "min", "max",
          "clip", "sinh", "cosh", "tanh"}
_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


# ---------------------------------------------------------------------------------------------
# The expression graph
# ---------------------------------------------------------------------------------------------
class Graph:
    """Hash-consed expression nodes. A node is an int id; ``nodes[id]`` a tuple:
    ("c", value) literal, ("x", j) task coordinate, ("p", slot) parameter slot,
    (op, a, b...) operation."""

    def __init__(self):
        self.nodes: list[tuple] = []
        self._ids: dict = {}
        self.param_keys: list[tuple] = []  # slot -> (name, index path)
        self._slots: dict = {}

    def _node(self, t):
        i = self._ids.get(t)
        if i is None:
            i = len(self.nodes)
            self.nodes.append(t)
            self._ids[t] = i
        return i

    def const(self, v) -> int:
        v = float(v)
        # -0.0 and 0.0 are distinct literals (their products differ in sign)
        return self._node(("c", v, math.copysign(1.0, v) if v == 0 else 0.0) if v == v else ("c", v, "nan"))

    def x(self, j) -> int:
        return self._node(("x", int(j)))

    def param(self, key) -> int:
        s = self._slots.get(key)
        if s is None:
            s = len(self.param_keys)
            self.param_keys.append(key)
            self._slots[key] = s
        return self._node(("p", s))

    def cval(self, i):
        t = self.nodes[i]
        return t[1] if t[0] == "c" else None

    def is_const(self, i, v) -> bool:
        c = self.cval(i)
        return c is not None and c == v and math.copysign(1.0, c) == math.copysign(1.0, v)

    def op(self, name, *args) -> int:
        """An operation; folded when every operand is a literal (with NumPy, as the reference)."""
        nodes = self.nodes
        for a in args:
            if nodes[a][0] != "c":
                return self._node((name, *args))
        vv = [np.float64(nodes[a][1]) for a in args]
        with np.errstate(all="ignore"):
            if name in _UNARY_NP:
                r = _UNARY_NP[name](vv[0])
            elif name in _BIN_NP:
                r = _BIN_NP[name](vv[0], vv[1])
            elif name == "clip":
                r = np.clip(vv[0], vv[1], vv[2])
            elif name == "and":
                r = bool(vv[0]) and bool(vv[1])
            elif name == "select":
                r = vv[1] if vv[0] else vv[2]
            else:  # pragma: no cover
                raise Untranslatable(f"operation {name}")
        return self.const(float(r))

    # -- algebra with identities folded (only for generated terms: rotations, derivatives) -----
    def add(self, a, b):
        if self.is_const(a, 0.0) or self.is_const(a, -0.0):
            return b
        if self.is_const(b, 0.0) or self.is_const(b, -0.0):
            return a
        return self.op("add", a, b)

    def sub(self, a, b):
        if self.is_const(b, 0.0) or self.is_const(b, -0.0):
            return a
        if self.is_const(a, 0.0):
            return self.neg(b)
        return self.op("sub", a, b)

    def mul(self, a, b):
        if self.cval(a) == 0.0 or self.cval(b) == 0.0:
            return self.const(0.0)
        if self.is_const(a, 1.0):
            return b
        if self.is_const(b, 1.0):
            return a
        if self.is_const(a, -1.0):
            return self.neg(b)
        if self.is_const(b, -1.0):
            return self.neg(a)
        return self.op("mul", a, b)

    def div(self, a, b):
        if self.cval(a) == 0.0:
            return self.const(0.0)
        if self.is_const(b, 1.0):
            return a
        return self.op("div", a, b)

    def neg(self, a):
        t = self.nodes[a]
        if t[0] == "neg":
            return t[1]
        return self.op("neg", a)

    def sin(self, a):
        return self.op("sin", a)

    def cos(self, a):
        return self.op("cos", a)


# ---------------------------------------------------------------------------------------------
# ast -> graph
# ---------------------------------------------------------------------------------------------
class _Translator:
    def __init__(self, g: Graph, penv: dict, scope: dict):
        self.g = g
        self.penv = penv
        self.scope = scope  # name -> node (coordinates, defines, pose names)

    def param_value(self, name, path):
        v = self.penv[name]
        for k in path:
            v = v[k]
        a = np.asarray(v)
        if a.ndim != 0 or not np.issubdtype(a.dtype, np.number):
            where = name + "".join(f"[{k}]" for k in path)
            raise Untranslatable(f"the parameter {where} used as a whole array (index it, e.g. {name}[0])")
        return float(a)

    def __call__(self, node):
        g = self.g
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise Untranslatable(f"the constant {node.value!r}")
            return g.const(node.value)
        if isinstance(node, ast.Name):
            n = node.id
            if n in self.scope:
                return self.scope[n]
            if n == "pi":
                return g.const(np.pi)
            if n in self.penv:
                self.param_value(n, ())
                return g.param((n, ()))
            raise Untranslatable(f"the name {n!r}")
        if isinstance(node, ast.BinOp) and type(node.op) in _AST_BIN:
            return g.op(_AST_BIN[type(node.op)], self(node.left), self(node.right))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            a = self(node.operand)
            return g.op("neg", a) if isinstance(node.op, ast.USub) else a
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _CALLS \
                and not node.keywords:
            f = node.func.id
            args = [self(a) for a in node.args]
            return g.op(f, *args)
        if isinstance(node, ast.Subscript):
            path = []
            v = node
            while isinstance(v, ast.Subscript):
                idx = v.slice
                if isinstance(idx, ast.Constant) and type(idx.value) is int:
                    k = idx.value
                elif (isinstance(idx, ast.UnaryOp) and isinstance(idx.op, ast.USub)
                      and isinstance(idx.operand, ast.Constant) and type(idx.operand.value) is int):
                    k = -idx.operand.value
                else:
                    raise Untranslatable(f"the index {ast.unparse(idx)!r}")
                path.append(k)
                v = v.value
            if not (isinstance(v, ast.Name) and v.id in self.penv and v.id not in self.scope):
                raise Untranslatable(f"an index into {ast.unparse(v)!r} (only parameters can be indexed)")
            path = tuple(reversed(path))
            try:
                self.param_value(v.id, path)
            except (IndexError, TypeError) as e:
                raise Untranslatable(f"the index {ast.unparse(node)!r} ({e})") from None
            return g.param((v.id, path))
        if isinstance(node, ast.Compare):
            terms = [self(node.left)] + [self(c) for c in node.comparators]
            out = None
            for op, a, b in zip(node.ops, terms, terms[1:]):
                if type(op) not in _AST_CMP:
                    raise Untranslatable(f"the comparison {type(op).__name__}")
                c = g.op(_AST_CMP[type(op)], a, b)
                out = c if out is None else g.op("and", out, c)
            return out
        raise Untranslatable(f"the construct {type(node).__name__} ({ast.unparse(node)!r})")


# ---------------------------------------------------------------------------------------------
# derivatives
# ---------------------------------------------------------------------------------------------
class _Diff:
    """d(node)/d(x_j) on the graph (forward mode, memoised)."""

    def __init__(self, g: Graph):
        self.g = g
        self.memo: dict = {}

    def __call__(self, i, j):
        key = (i, j)
        r = self.memo.get(key)
        if r is None:
            r = self._d(i, j)
            self.memo[key] = r
        return r

    def _d(self, i, j):
        g = self.g
        t = g.nodes[i]
        k = t[0]
        zero = g.const(0.0)
        if k in ("c", "p"):
            return zero
        if k == "x":
            return g.const(1.0 if t[1] == j else 0.0)
        a = t[1] if len(t) > 1 else None
        b = t[2] if len(t) > 2 else None
        d = self
        if k in ("lt", "le", "gt", "ge", "and", "sign"):
            return zero
        da = d(a, j)
        if k == "neg":
            return g.neg(da) if da != zero else zero
        if k == "add":
            return g.add(da, d(b, j))
        if k == "sub":
            return g.sub(da, d(b, j))
        if k == "mul":
            return g.add(g.mul(da, b), g.mul(a, d(b, j)))
        if k == "div":
            db = d(b, j)
            q = g.div(da, b)
            if db == zero:
                return q
            return g.sub(q, g.div(g.mul(a, db), g.mul(b, b)))
        if k == "pow":
            db = d(b, j)
            y = g.op("pow", a, b)
            if db == zero:
                if da == zero:
                    return zero
                return g.mul(g.mul(b, g.op("pow", a, g.op("sub", b, g.const(1.0)))), da)
            return g.mul(y, g.add(g.mul(g.op("log", a), db), g.div(g.mul(b, da), a)))
        if k in ("atan2", "hypot", "min", "max"):
            db = d(b, j)
            if da == zero and db == zero:
                return zero
            if k == "atan2":  # (x dy - y dx) / (x^2 + y^2), y = a, x = b
                r2 = g.op("add", g.op("mul", b, b), g.op("mul", a, a))
                return g.sub(g.div(g.mul(da, b), r2), g.div(g.mul(db, a), r2))
            if k == "hypot":
                h = g.op("hypot", a, b)
                return g.add(g.mul(da, g.div(a, h)), g.mul(db, g.div(b, h)))
            first = g.op("le" if k == "min" else "ge", a, b)
            return g.op("select", first, da, db)
        if k == "clip":
            if da == zero:
                return zero
            inside = g.op("and", g.op("ge", a, b), g.op("le", a, t[3]))
            return g.op("select", inside, da, zero)
        if da == zero:
            return zero
        one = g.const(1.0)
        if k == "sin":
            f = g.cos(a)
        elif k == "cos":
            f = g.neg(g.sin(a))
        elif k == "tan":
            tt = g.op("tan", a)
            f = g.op("add", one, g.op("mul", tt, tt))
        elif k == "asin":
            f = g.op("div", one, g.op("sqrt", g.op("sub", one, g.op("mul", a, a))))
        elif k == "acos":
            f = g.op("div", g.const(-1.0), g.op("sqrt", g.op("sub", one, g.op("mul", a, a))))
        elif k == "atan":
            f = g.op("div", one, g.op("add", one, g.op("mul", a, a)))
        elif k == "sqrt":
            f = g.op("div", g.const(0.5), g.op("sqrt", a))
        elif k == "exp":
            f = g.op("exp", a)
        elif k == "log":
            f = g.op("div", one, a)
        elif k == "abs":
            f = g.op("sign", a)
        elif k == "sinh":
            f = g.op("cosh", a)
        elif k == "cosh":
            f = g.op("sinh", a)
        elif k == "tanh":
            th = g.op("tanh", a)
            f = g.op("sub", one, g.op("mul", th, th))
        else:  # pragma: no cover
            raise Untranslatable(f"the derivative of {k}")
        return g.mul(f, da)


# ---------------------------------------------------------------------------------------------
# The program
# ---------------------------------------------------------------------------------------------
class Program:
    """A straight-line register program (see the module docstring).

    ``ins`` (n, 6) int64 rows (op, d, a, b, c, e); registers 0..n_task-1 hold the task
    coordinates, rows ``const_base..const_base+n_const-1`` the literals and parameter values
    (:meth:`constants`), the others temporaries; ``n_reg`` rows in all. ``n_pose``: the
    instructions that compute the pose (p, R, validity); the rest compute the margins
    (``margin_regs``) and, in a twist program, the twist map (``twist_regs``, (6, n_task)).
    """

    def __init__(self, ins, n_task, n_reg, const_base, literals, param_keys, const_param, n_pose, pose_regs,
                 valid_regs, margin_regs, twist_regs, unknown_regs=None):
        self.ins = ins
        self.n_task = n_task
        self.n_reg = n_reg
        self.const_base = const_base
        self.literals = literals  # (n_const,) with NaN where a parameter slot goes
        self.param_keys = param_keys
        self.const_param = const_param  # (n_const,) slot or -1
        self.n_pose = n_pose
        self.pose_regs = pose_regs  # (12,) p then R row-major
        self.valid_regs = valid_regs
        self.margin_regs = margin_regs  # {constraint name: register}
        self.twist_regs = twist_regs  # (6, n_task) or None
        self.unknown_regs = unknown_regs  # (m,): the solved unknowns of task.solve, or None
        #: Poses with a coordinate beyond this magnitude are invalid (as in the NumPy path).
        self.pose_limit = np.full(n_task, np.inf)  # per coordinate (core._pose_limit)

    def constants(self, penv) -> np.ndarray:
        """The constant rows' values for a parameter environment."""
        c = self.literals.copy()
        slots = self.__dict__.get("_param_slots")  # (row, parameter, index path) of the parameter rows, made once
        if slots is None:
            slots = self._param_slots = [(k, *self.param_keys[int(s)]) for k, s in enumerate(self.const_param) if s >= 0]
        for k, name, path in slots:
            v = penv[name]
            for q in path:
                v = v[q]
            c[k] = float(v)
        return c


class _Emitter:
    def __init__(self, g: Graph, n_task: int):
        self.g = g
        self.n_task = n_task
        self.code: list[list[int]] = []  # virtual registers
        self.reg: dict = {}
        self.sc: dict = {}
        self.consts: list = []  # ("lit", v) or ("par", slot)
        self.n_virt = 0
        self.const_vregs: list[int] = []

    def new(self):
        self.n_virt += 1
        return self.n_virt - 1 + 1_000_000  # temporaries: offset, mapped later

    def emit(self, i) -> int:
        r = self.reg.get(i)
        if r is not None:
            return r
        g = self.g
        t = g.nodes[i]
        k = t[0]
        if k == "x":
            r = t[1]
        elif k in ("c", "p"):
            r = -1 - len(self.consts)  # constants: negative, mapped later
            self.consts.append(("lit", t[1]) if k == "c" else ("par", t[1]))
        elif k in ("sin", "cos"):
            s, c = self.sincos(t[1])
            r = s if k == "sin" else c
        elif k == "pow" and g.cval(t[2]) == 2.0:
            a = self.emit(t[1])
            r = self.new()
            self.code.append([OPS["square"], r, a, 0, 0, 0])
        elif k == "clip":
            a, b, c = (self.emit(x) for x in t[1:4])
            r = self.new()
            self.code.append([OPS["clip"], r, a, b, c, 0])
        elif k == "select":
            c, a, b = (self.emit(x) for x in t[1:4])
            r = self.new()
            self.code.append([OPS["select"], r, a, b, c, 0])
        else:
            reg = self.reg
            args = [reg[x] if x in reg else self.emit(x) for x in t[1:]]  # (the call only when new)
            r = self.new()
            row = [OPS[k], r] + args + [0] * (4 - len(args))
            self.code.append(row)
        self.reg[i] = r
        return r

    def _trig_friendly(self, i, depth=0) -> bool:
        """Whether sin/cos of node i are better taken algebraically (an atan2 inside sums)."""
        t = self.g.nodes[i]
        if t[0] == "atan2":
            return True
        if depth < 4 and t[0] in ("add", "sub"):
            return self._trig_friendly(t[1], depth + 1) or self._trig_friendly(t[2], depth + 1)
        if depth < 4 and t[0] == "neg":
            return self._trig_friendly(t[1], depth + 1)
        return False

    def sincos(self, i):
        """(sin, cos) registers of node i."""
        hit = self.sc.get(i)
        if hit is not None:
            return hit
        g = self.g
        t = g.nodes[i]
        if t[0] == "c":
            out = (self.emit(g.const(np.sin(np.float64(t[1])))), self.emit(g.const(np.cos(np.float64(t[1])))))
        elif t[0] == "atan2" and i not in self.reg:
            y, x = self.emit(t[1]), self.emit(t[2])
            s, c = self.new(), self.new()
            self.code.append([OPS["sincos_atan2"], s, y, x, c, 0])
            out = (s, c)
        elif t[0] in ("add", "sub") and i not in self.reg and self._trig_friendly(i):
            sa, ca = self.sincos(t[1])
            sb, cb = self.sincos(t[2])
            s, c = self.new(), self.new()
            m = [self.new() for _ in range(4)]
            self.code += [[OPS["mul"], m[0], sa, cb, 0, 0], [OPS["mul"], m[1], ca, sb, 0, 0],
                          [OPS["mul"], m[2], ca, cb, 0, 0], [OPS["mul"], m[3], sa, sb, 0, 0]]
            if t[0] == "add":
                self.code += [[OPS["add"], s, m[0], m[1], 0, 0], [OPS["sub"], c, m[2], m[3], 0, 0]]
            else:
                self.code += [[OPS["sub"], s, m[0], m[1], 0, 0], [OPS["add"], c, m[2], m[3], 0, 0]]
            out = (s, c)
        elif t[0] == "neg" and i not in self.reg and self._trig_friendly(i):
            sa, ca = self.sincos(t[1])
            s = self.new()
            self.code.append([OPS["neg"], s, sa, 0, 0, 0])
            out = (s, ca)
        else:
            a = self.emit(i)
            s, c = self.new(), self.new()
            self.code.append([OPS["sincos"], s, a, c, 0, 0])
            out = (s, c)
        self.sc[i] = out
        return out


# Operand positions that are registers, per opcode (for liveness): (sources, destinations)
def _operand_positions(op) -> tuple:
    if op == OPS["sincos"]:
        return (2,), (1, 3)
    if op == OPS["sincos_atan2"]:
        return (2, 3), (1, 4)
    if op in (OPS["clip"], OPS["select"], OPS["madd"], OPS["msub"], OPS["rmsub"]):
        return (2, 3, 4), (1,)
    if op in (OPS["mmadd"], OPS["mmsub"]):
        return (2, 3, 4, 5), (1,)
    if op in (OPS["neg"], OPS["sqrt"], OPS["tan"], OPS["asin"], OPS["acos"], OPS["atan"], OPS["exp"], OPS["log"],
              OPS["abs"], OPS["sinh"], OPS["cosh"], OPS["tanh"], OPS["sign"], OPS["square"], OPS["copy"],
              OPS["sin"], OPS["cos"]):
        return (2,), (1,)
    return (2, 3), (1,)


#: Per opcode, the positions of its (sources, destinations) registers in an instruction row.
_OPERANDS = {op: _operand_positions(op) for op in OPS.values()}


def _operands(row):
    src, dst = _OPERANDS[row[0]]
    return [row[i] for i in src], [row[i] for i in dst]


def _fuse(code, uses):
    """Peephole: an add or sub whose operand(s) are products used nowhere else becomes one
    fused instruction (fewer passes over the registers, identical arithmetic). The code is
    in single assignment (every temporary written once), so a product can be computed at
    its use. ``uses``: {register: number of reads} over the whole program and its outputs."""
    mul = OPS["mul"]
    prod = {row[1]: row for row in code if row[0] == mul and row[1] >= 1_000_000}

    def single(r):
        return r in prod and uses.get(r, 0) == 1

    fused: set = set()
    out = []
    for row in code:
        op = row[0]
        if op in (OPS["add"], OPS["sub"]):
            a, b = row[2], row[3]
            if single(a) and single(b) and a != b:
                pa, pb = prod[a], prod[b]
                name = "mmadd" if op == OPS["add"] else "mmsub"
                row = [OPS[name], row[1], pa[2], pa[3], pb[2], pb[3]]
                fused.update((a, b))
            elif single(a):
                pa = prod[a]
                row = [OPS["madd" if op == OPS["add"] else "msub"], row[1], pa[2], pa[3], b, 0]
                fused.add(a)
            elif single(b):
                pb = prod[b]
                if op == OPS["add"]:  # a + p == p + a (IEEE addition commutes)
                    row = [OPS["madd"], row[1], pb[2], pb[3], a, 0]
                else:
                    row = [OPS["rmsub"], row[1], pb[2], pb[3], a, 0]
                fused.add(b)
        out.append(row)
    return [row for row in out if not (row[0] == mul and row[1] in fused)]


def _uses(code, keep):
    n: dict = {}
    for row in code:
        for r in _operands(row)[0]:
            n[r] = n.get(r, 0) + 1
    for r in keep:
        n[r] = n.get(r, 0) + 2  # outputs are never fused away
    return n


def _allocate(code, n_task, n_const, keep):
    """Map temporaries (>= 1e6) to physical rows by liveness; constants (< 0) to their rows;
    ``keep``: registers live to the end. Returns (ins, n_reg, mapping)."""
    const_base = n_task
    first_tmp = n_task + n_const
    last = {}
    operands = [_operands(row) for row in code]
    for k, (srcs, dsts) in enumerate(operands):
        for r in srcs:
            last[r] = k
        for r in dsts:
            last.setdefault(r, k)
    for r in keep:
        last[r] = len(code)
    free: list[int] = []
    n_phys = first_tmp
    phys: dict = {}

    def loc(r):
        if r < 0:
            return const_base + (-1 - r)
        if r < 1_000_000:
            return r
        return phys[r]

    out = []
    for k, row in enumerate(code):
        srcs, dsts = operands[k]
        src_p = [loc(r) for r in srcs]
        # sources dying here are freed before the destinations are placed (the kernel reads
        # every operand of a lane before writing), except for sincos, whose second pass
        # re-reads its argument
        dying = [phys[r] for r in set(srcs) if r >= 1_000_000 and last.get(r) == k]
        late = row[0] == OPS["sincos"]
        if not late:
            free.extend(dying)
        dst_p = []
        for r in dsts:
            if free:
                p = free.pop()
            else:
                p = n_phys
                n_phys += 1
            phys[r] = p
            dst_p.append(p)
            if last.get(r, k) <= k:  # dead result
                free.append(p)
        if late:
            free.extend(dying)
        new = list(row)
        op = row[0]
        if op == OPS["sincos"]:
            new[1], new[3] = dst_p
            new[2] = src_p[0]
        elif op == OPS["sincos_atan2"]:
            new[1], new[4] = dst_p
            new[2], new[3] = src_p
        elif op in (OPS["clip"], OPS["select"]):
            new[1] = dst_p[0]
            new[2], new[3], new[4] = src_p
        else:
            new[1] = dst_p[0]
            for q, p in enumerate(src_p):
                new[2 + q] = p
        out.append(new)
    ins = np.array(out, dtype=np.int64).reshape(-1, 6)
    return ins, n_phys, loc


def _prune(code, needed):
    """Dead-code elimination: keep instructions whose results reach ``needed``."""
    live = set(needed)
    keep = [False] * len(code)
    for k in range(len(code) - 1, -1, -1):
        srcs, dsts = _operands(code[k])
        if any(d in live for d in dsts):
            keep[k] = True
            live.update(srcs)
    return [row for row, kp in zip(code, keep) if kp]


def _rotation(g: Graph, task, angle_nodes):
    """R (3x3 nodes) and the rate-map columns [R_1..R_{k-1} e_k] for the orientation."""
    if task.convention is not None:
        axes = [np.array(_AXES[a]) for a in EULER_CONVENTIONS[task.convention]]
    else:
        axes = [np.asarray(a, dtype=float) for a in task.rot_axes]
    one, zero = g.const(1.0), g.const(0.0)
    R = [[one if i == j else zero for j in range(3)] for i in range(3)]
    cols = []
    for ax, a in zip(axes, angle_nodes):
        cols.append([_dot_row(g, R[i], [g.const(v) for v in ax]) for i in range(3)])
        s, c = g.sin(a), g.cos(a)
        E = _elementary(g, ax, s, c)
        R = [[_dot_row(g, R[i], [E[0][j], E[1][j], E[2][j]]) for j in range(3)] for i in range(3)]
    return R, cols


def _dot_row(g, row, col):
    acc = None
    for u, v in zip(row, col):
        term = g.mul(u, v)
        if g.cval(term) == 0.0:
            continue
        acc = term if acc is None else g.add(acc, term)
    return g.const(0.0) if acc is None else acc


def _elementary(g, ax, s, c):
    """Rotation matrix nodes about unit axis ``ax`` (rot_x/rot_y/rot_z, or Rodrigues)."""
    one, zero = g.const(1.0), g.const(0.0)
    key = tuple(float(v) for v in ax)
    if key == _AXES["x"]:
        return [[one, zero, zero], [zero, c, g.neg(s)], [zero, s, c]]
    if key == _AXES["y"]:
        return [[c, zero, s], [zero, one, zero], [g.neg(s), zero, c]]
    if key == _AXES["z"]:
        return [[c, g.neg(s), zero], [s, c, zero], [zero, zero, one]]
    # spatial.rot_axis: I + sin K + (1 - cos) K K, K = skew(unit axis)
    a = np.asarray(ax, dtype=float)
    a = a / np.linalg.norm(a)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    KK = K @ K
    omc = g.op("sub", one, c)
    out = []
    for i in range(3):
        row = []
        for j in range(3):
            e = g.add(g.const(1.0 if i == j else 0.0), g.mul(s, g.const(K[i, j])))
            row.append(g.add(e, g.mul(omc, g.const(KK[i, j]))))
        out.append(row)
    return out


def build_program(mech, margin_exprs: dict, twist: bool = False, unknowns: bool = False) -> Program:
    """The program of a described mechanism ``mech``: pose, validity, the margins of
    ``margin_exprs`` ({constraint name: Expression}) and, with ``twist``, the twist map; with
    ``unknowns``, the solved unknowns of ``task.solve`` kept in registers too
    (``Program.unknown_regs``). Raises :class:`Untranslatable`.

    The cyclic garbage collector is paused while it builds: the graph of an unrolled solve is
    ~1e5 tuples, whose allocation otherwise sets off full collections that walk everything a
    run holds (Optuna, pandas, numba: 40-100 ms of a 45 ms build in a study run). The graph holds
    no reference cycles; the collector runs as before once the program is built."""
    paused = gc.isenabled()
    gc.disable()
    try:
        return _build_program(mech, margin_exprs, twist, unknowns)
    finally:
        if paused:
            gc.enable()


def _build_program(mech, margin_exprs: dict, twist: bool, unknowns: bool) -> Program:
    task = mech.description.task
    penv = mech._penv
    g = Graph()
    names = tuple(task.names)
    n = len(names)

    def pose_of(unknowns):
        """scope, angles, R, rate-map columns and position with the unknowns' nodes given."""
        scope = {c: g.x(j) for j, c in enumerate(names)}
        if solve is not None:
            scope.update(zip(solve.names, unknowns))
        tr = _Translator(g, penv, scope)
        for name, e in task.defines:
            scope[name] = tr(e.tree)
        angles = [tr(e.tree) for e in task.angles]
        R, cols = _rotation(g, task, angles)
        pose_scope = dict(scope)
        for nm in R_NAMES:
            pose_scope[nm] = R[int(nm[1]) - 1][int(nm[2]) - 1]
        pos = [_Translator(g, penv, pose_scope)(e.tree) for e in task.position]
        return scope, angles, R, cols, pose_scope, pos

    solve = getattr(task, "solve", None)
    chain, seed, solve_valid = [], {}, []
    unknowns = ()
    if solve is not None:  # the unrolled Gauss-Newton solve of the legs' closure equations
        if SOLVE_KEY not in penv:
            raise Untranslatable("task.solve without its solve data")
        chained = sorted({leg.joints for leg in mech.legs} - set(CLOSURE_COUNTS))
        if chained:  # their closure is a numerical solve of its own (model/chains.py)
            raise Untranslatable(f"a motion closing on {', '.join(chained)} limbs (the pose program solves the "
                                 f"closure of {', '.join(k for k, v in CLOSURE_COUNTS.items() if v)} limbs; the "
                                 f"feasibility, margins and indices of such a structure are compiled)")
        unknowns, chain, ok, seed = solve_nodes(
            g, _Diff, [leg.joints for leg in mech.legs], SOLVE_KEY, n, len(solve.names),
            lambda ph: (lambda o: (o[5], o[2]))(pose_of(ph)))
        solve_valid = [ok]
    scope, angles, R, cols, pose_scope, pos = pose_of(unknowns)
    tr = _Translator(g, penv, scope)
    valid = [tr(e.tree) for e in task.valid] + solve_valid
    mscope = dict(pose_scope)
    for k, nm in enumerate(("px", "py", "pz")):
        mscope[nm] = pos[k]
    tr_m = _Translator(g, penv, mscope)
    margins = {name: tr_m(e.tree) for name, e in margin_exprs.items()}
    twist_nodes = None
    if twist:
        d = _Diff(g)
        d.memo.update(seed)  # the solved unknowns' derivatives (implicit function theorem)
        twist_nodes = [[None] * n for _ in range(6)]
        for j in range(n):
            for i in range(3):
                twist_nodes[i][j] = d(pos[i], j)
            for i in range(3):
                acc = g.const(0.0)
                for col, a in zip(cols, angles):
                    acc = g.add(acc, g.mul(col[i], d(a, j)))
                twist_nodes[3 + i][j] = acc

    em = _Emitter(g, n)
    for U in chain:  # the solve's iterates in order (a shallow recursion in emit)
        for u in U:
            em.emit(u)
    pose_out = [em.emit(x) for x in pos] + [em.emit(R[i][j]) for i in range(3) for j in range(3)]
    valid_out = [em.emit(v) for v in valid]
    unknown_out = [em.emit(u) for u in unknowns] if unknowns and solve is not None else []
    n_pose_virt = len(em.code)
    margin_out = {name: em.emit(m) for name, m in margins.items()}
    twist_out = None
    if twist_nodes is not None:
        twist_out = [[em.emit(twist_nodes[i][j]) for j in range(n)] for i in range(6)]
    keep = (pose_out + valid_out + unknown_out + list(margin_out.values())
            + [r for row in (twist_out or []) for r in row])
    # pose part and the rest pruned separately so that the pose prefix stays a prefix
    rest = _prune(em.code[n_pose_virt:], keep)
    rest_srcs = [r for row in rest for r in _operands(row)[0]]
    pose_code = _prune(em.code[:n_pose_virt], pose_out + valid_out + unknown_out + rest_srcs)
    uses = _uses(pose_code + rest, keep)
    pose_code = _fuse(pose_code, uses)
    rest = _fuse(rest, uses)
    code = pose_code + rest
    n_const = len(em.consts)
    ins, n_reg, loc = _allocate(code, n, n_const, keep)
    literals = np.array([v if kind == "lit" else np.nan for kind, v in em.consts], dtype=np.float64)
    const_param = np.array([v if kind == "par" else -1 for kind, v in em.consts], dtype=np.int64)
    return Program(ins=ins, n_task=n, n_reg=max(n_reg, 1), const_base=n, literals=literals,
                   param_keys=list(g.param_keys), const_param=const_param, n_pose=len(pose_code),
                   pose_regs=np.array([loc(r) for r in pose_out], dtype=np.int64),
                   valid_regs=np.array([loc(r) for r in valid_out], dtype=np.int64),
                   margin_regs={k: loc(r) for k, r in margin_out.items()},
                   twist_regs=None if twist_out is None else np.array([[loc(r) for r in row] for row in twist_out],
                                                                      dtype=np.int64),
                   unknown_regs=np.array([loc(r) for r in unknown_out], dtype=np.int64) if unknown_out else None)
