"""Anchor sets of the ``base:`` and ``platform:`` sections: explicit points or patterns
(points, circle, polygon, paired, rectangle) with the radial, tangent and normal directions of
each point.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import DescriptionError
from .expressions import _Scope
from .parameters import _Scalar, _check_keys, values_key

_PLANES = {"xy": (0, 1, 2), "yx": (1, 0, 2), "xz": (0, 2, 1), "zx": (2, 0, 1), "yz": (1, 2, 0), "zy": (2, 1, 0)}
_PATTERNS = {
    "points": ({"points"}, {"points"}),
    "circle": ({"radius", "angles"}, {"radius", "angles"}),
    "polygon": ({"n", "radius", "phase"}, {"n", "radius"}),
    "paired": ({"n", "radius", "phase", "separation"}, {"n", "radius", "separation"}),
    "rectangle": ({"length", "width"}, {"length", "width"}),
}
_SET_COMMON = {"pattern", "plane", "offset", "scale", "rotation", "shift", "doc"}


#: Most points a pattern may generate (a resource limit: each point is usually a leg).
MAX_PATTERN_POINTS = 1000


def _count(raw, path, lo=1, hi=MAX_PATTERN_POINTS) -> int:
    if isinstance(raw, bool) or not isinstance(raw, int) or not lo <= raw <= hi:
        raise DescriptionError(f"{path}: must be an integer from {lo} to {hi}, got {raw!r}")
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


class _Anchors:
    """Built anchor points with the directions of their set's plane: as rows of three Python
    floats (``rows``, ``radial_rows``, ``tangent_rows``: tuples of tuples, and ``normal_row``,
    never written: several built anchors may share them) and, made when first asked for, as
    arrays of this object's own (``points`` (n, 3), ``radial``, ``tangent``, ``normal`` (3,)).
    A described leg group of a type built in floats reads the rows alone."""

    __slots__ = ("rows", "radial_rows", "tangent_rows", "normal_row", "_arrays")

    def __init__(self, rows: tuple, radial_rows: tuple, tangent_rows: tuple, normal_row: tuple):
        self.rows, self.radial_rows, self.tangent_rows, self.normal_row = rows, radial_rows, tangent_rows, normal_row
        self._arrays = None

    def _made(self) -> tuple:
        a = self._arrays
        if a is None:
            a = self._arrays = (np.array(self.rows, dtype=float).reshape(-1, 3),
                                np.array(self.radial_rows, dtype=float).reshape(-1, 3),
                                np.array(self.tangent_rows, dtype=float).reshape(-1, 3),
                                np.array(self.normal_row, dtype=float))
        return a

    @property
    def points(self) -> np.ndarray:
        return self._made()[0]

    @property
    def radial(self) -> np.ndarray:
        return self._made()[1]

    @property
    def tangent(self) -> np.ndarray:
        return self._made()[2]

    @property
    def normal(self) -> np.ndarray:
        return self._made()[3]

    def subset(self, indices) -> "_Anchors":
        """The anchors at ``indices`` (rows shared, arrays its own)."""
        return _Anchors(tuple(self.rows[i] for i in indices), tuple(self.radial_rows[i] for i in indices),
                        tuple(self.tangent_rows[i] for i in indices), self.normal_row)


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

    def _input_names(self) -> tuple:
        """The parameters the set's geometry reads: those its scalars' expressions name and its
        list parameter of points or angles."""
        scalars = [self.offset, self.scale, self.rotation, *self.shift]
        scalars += [getattr(self, k) for k in ("radius", "phase", "separation", "length", "width") if hasattr(self, k)]
        scalars += list(self.angles or ()) + [v for row in (self.point_rows or ()) for v in row]
        names = {n for sc in scalars if sc.expr is not None for n in sc.expr.names}
        names |= {p.name for p in (self.points_param, self.angles_param) if p is not None}
        return tuple(sorted(names))

    def build(self, env) -> _Anchors:
        """The anchors for the parameter values ``env``: kept per the values of the parameters the
        set's expressions name (as :class:`_Scalar` keeps a value), so that a study's designs
        that leave the set unchanged (the platform's while the legs vary) share its build; each
        call gets arrays of its own (made when asked for: :class:`_Anchors`)."""
        names = self.__dict__.get("_names")
        if names is None:
            names = self._names = self._input_names()
        key = values_key(env, names)
        memo = self.__dict__.setdefault("_memo", {})
        hit = memo.get(key) if key is not None else None
        if hit is None:
            hit = self._build(env)
            if key is None:
                return hit
            if len(memo) >= 64:
                memo.clear()
            memo[key] = hit
        return _Anchors(hit.rows, hit.radial_rows, hit.tangent_rows, hit.normal_row)

    def _build(self, env) -> _Anchors:
        """The set's anchors and directions, computed in Python floats: the same operations in
        the same order as the array form (the pattern's points, then the norms, unit vectors and
        directions of the whole set), a few points each, where NumPy's calls cost more than the
        arithmetic."""
        i1, i2, i3 = self.axes
        off = self.offset(env)
        if self.pattern == "points":
            if self.points_param is not None:
                rows = np.asarray(env[self.points_param.name], dtype=float).tolist()
            else:
                rows = [[s(env) for s in row] for row in self.point_rows]
            P = []
            for row in rows:
                if len(row) == 3:
                    P.append([float(v) for v in row])
                else:
                    v = [0.0, 0.0, 0.0]
                    v[i1], v[i2], v[i3] = float(row[0]), float(row[1]), float(off)
                    P.append(v)
        else:
            if self.pattern == "rectangle":
                a, b = 0.5 * self.length(env), 0.5 * self.width(env)
                ab = [(a, b), (-a, b), (-a, -b), (a, -b)]
            else:
                if self.pattern == "circle":
                    ang = (np.asarray(env[self.angles_param.name], dtype=float).tolist() if self.angles_param is not None
                           else [float(a(env)) for a in self.angles])
                    r = float(self.radius(env))
                else:  # polygon, paired: centres ph + 2 pi k / n, as np.arange's
                    r, ph = float(self.radius(env)), float(self.phase(env))
                    centres = [ph + 2 * math.pi * k / self.n for k in range(self.n)]
                    if self.pattern == "paired":
                        h = 0.5 * self.separation(env)
                        ang = [a for c in centres for a in (c - h, c + h)]
                    else:
                        ang = centres
                ab = [(r * math.cos(t), r * math.sin(t)) for t in ang]
            P = []
            for a, b in ab:
                v = [0.0, 0.0, 0.0]
                v[i1], v[i2], v[i3] = float(a), float(b), float(off)
                P.append(v)
        s, rot = float(self.scale(env)), float(self.rotation(env))
        if s != 1.0 or rot != 0.0:
            c, sn = math.cos(rot), math.sin(rot)
            for v in P:
                a, b = s * v[i1], s * v[i2]
                v[i1], v[i2] = c * a - sn * b, sn * a + c * b
        shift = self.__dict__.get("_shift_floats")  # a shift of constants: computed once
        if shift is None:
            shift = [float(v(env)) for v in self.shift]
            if all(v.expr is None for v in self.shift):
                self._shift_floats = shift
        P = [[v[0] + shift[0], v[1] + shift[1], v[2] + shift[2]] for v in P]
        return _float_directions(P, self.axes)


def _float_directions(P: list, axes) -> _Anchors:
    """The anchors ``P`` (rows of three floats) with the radial and tangent directions of their
    set's plane ``axes`` and its normal, computed in floats: the
    norm sqrt(a a + b b), the unit in-plane vector (zero below 1e-15), radial = u1 e1 + u2 e2
    and tangent = -u2 e1 + u1 e2 component by component, as the array form computes them."""
    i1, i2, i3 = axes
    e1, e2 = _EYE_ROWS[i1], _EYE_ROWS[i2]
    radial, tangent = [], []
    for v in P:
        a, b = v[i1], v[i2]
        n = math.sqrt(a * a + b * b)
        u1, u2 = (a / n, b / n) if n > 1e-15 else (0.0, 0.0)
        radial.append((u1 * e1[0] + u2 * e2[0], u1 * e1[1] + u2 * e2[1], u1 * e1[2] + u2 * e2[2]))
        tangent.append((-u2 * e1[0] + u1 * e2[0], -u2 * e1[1] + u1 * e2[1], -u2 * e1[2] + u1 * e2[2]))
    return _Anchors(tuple(map(tuple, P)), tuple(radial), tuple(tangent),
                    _EYE_TUPLES[i3])


_EYE = np.eye(3)
_EYE.flags.writeable = False
_EYE_ROWS = _EYE.tolist()
_EYE_TUPLES = tuple(tuple(r) for r in _EYE_ROWS)
