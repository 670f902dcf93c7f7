"""The ``outputs:`` section: named quantities of a pose, each a method of the mechanism.

An output is an expression, or a list of three expressions (a point or a vector), of the
parameters, the task coordinates, the defined names and the platform pose (``px, py, pz``,
``R11 .. R33``)::

    outputs:
      x_of: px                                   # mech.x_of(X) -> (N,)
      grinding_point:                            # mech.grinding_point(X) -> (N, 3)
        value: ["px + y_t*R12", "py + y_t*R22", "pz + y_t*R32"]
        doc: the grinding point, platform point (0, y_t, 0), in the base frame

``mech.<name>(X)`` evaluates it for poses ``X`` (N, n_task) or one pose (n_task,) (then the
leading axis is dropped). Use them for tool points and dependent coordinates a paper reports.
"""

from __future__ import annotations

from dataclasses import dataclass

from .errors import DescriptionError
from .expressions import POSE_NAMES, Expression, _Scope
from .parameters import _check_identifier, _check_keys

__all__ = ["OutputSpec", "parse_outputs"]


@dataclass
class OutputSpec:
    name: str
    exprs: list  # one Expression (scalar output) or three (a vector)
    vector: bool
    doc: str = ""


def parse_outputs(raw, scope: _Scope, taken) -> dict:
    """{name: OutputSpec}; ``taken(name)`` is true for names that are attributes of mechanisms."""
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise DescriptionError("outputs: give a mapping {name: expression or [x, y, z] expressions}")
    escope = scope.extended("platform pose", POSE_NAMES)
    out = {}
    for name, spec in raw.items():
        path = f"outputs.{name}"
        _check_identifier(name, path, "output")
        if name.startswith("_") or taken(name):
            raise DescriptionError(f"{path}: {name!r} is already an attribute of every mechanism (or private); "
                                   f"choose another name")
        doc = ""
        if isinstance(spec, dict):
            _check_keys(spec, {"value", "doc"}, path, "an output")
            if "value" not in spec:
                raise DescriptionError(f"{path}.value: required key is missing")
            doc = str(spec.get("doc", "") or "")
            spec = spec["value"]
            path = f"{path}.value"
        if isinstance(spec, list):
            if len(spec) != 3:
                raise DescriptionError(f"{path}: a vector output has three components [x, y, z], got {spec!r}")
            exprs = [Expression(v, f"{path}[{j}]", escope) for j, v in enumerate(spec)]
            out[name] = OutputSpec(name, exprs, True, doc)
        else:
            out[name] = OutputSpec(name, [Expression(spec, path, escope)], False, doc)
    return out
