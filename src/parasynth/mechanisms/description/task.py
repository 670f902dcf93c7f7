"""The ``task:`` section: task coordinates, defined (dependent) names, the platform position
and orientation as expressions, validity conditions, home pose and ranges.
"""

from __future__ import annotations

import numpy as np

from ...model.spatial import EULER_CONVENTIONS
from .errors import DescriptionError
from .expressions import Expression, R_NAMES, _Scope
from .parameters import _Scalar, _UNITFUL, _bare_number_error, _check_identifier, _check_keys
from .legs import _NAMED_AXES

_TASK_KEYS = {"coordinates", "solve", "define", "position", "orientation", "valid", "home", "ranges", "restricted", "doc"}
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
        self.solve = None
        if raw.get("solve") is not None:
            self.solve = _Solve(raw["solve"], pscope, param_names, self.names)
            scope = scope.extended("solved unknowns", self.solve.names)
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


_SOLVE_KEYS = {"unknowns", "closure", "start", "doc"}
_CLOSURES = ("legs",)


class _Solve:
    """``task.solve``: dependent pose coordinates (``unknowns``, {name: length | angle}) found at
    each pose by a Gauss-Newton solve of the legs' closure equations (``closure: legs``, the only
    kind) from ``start`` ({unknown: value with unit}, default 0) at the home pose, and from the
    home solution elsewhere (:mod:`parasynth.model.parasitic`). The unknowns are names of the
    pose expressions as the task coordinates are."""

    def __init__(self, raw, pscope: _Scope, param_names, coord_names):
        path = "task.solve"
        if not isinstance(raw, dict):
            raise DescriptionError(f"{path}: give {{unknowns: {{name: length | angle}}, closure: legs}}, got {raw!r}")
        _check_keys(raw, _SOLVE_KEYS, path, "task.solve")
        unk = raw.get("unknowns")
        if not isinstance(unk, dict) or not unk:
            raise DescriptionError(f"{path}.unknowns: give a mapping {{name: length | angle}}, e.g. "
                                   f"{{x: length, gamma: angle}}")
        self.coords = []
        for c, kind in unk.items():
            p = f"{path}.unknowns.{c}"
            _check_identifier(c, p, "unknown")
            if c in param_names or c in coord_names:
                raise DescriptionError(f"{p}: {c!r} is also a parameter or task coordinate; use distinct names")
            if kind not in _COORD_KINDS:
                raise DescriptionError(f"{p}: kind must be length or angle, got {kind!r}")
            self.coords.append((c, kind))
        self.names = tuple(c for c, _ in self.coords)
        self.kinds = dict(self.coords)
        closure = raw.get("closure", "legs")
        if closure not in _CLOSURES:
            raise DescriptionError(f"{path}.closure: {closure!r} is not allowed; allowed: {', '.join(_CLOSURES)} "
                                   f"(the legs' closure equations)")
        self.closure = closure
        start = raw.get("start") or {}
        if not isinstance(start, dict):
            raise DescriptionError(f"{path}.start: give {{unknown: value with unit}}, got {start!r}")
        for c in start:
            if c not in self.kinds:
                raise DescriptionError(f"{path}.start.{c}: not an unknown; unknowns: {', '.join(self.names)}")
        zero = {"length": "0 mm", "angle": "0 deg"}
        self.start = [_Scalar(start.get(c, zero[k]), k, f"{path}.start.{c}", pscope) for c, k in self.coords]
