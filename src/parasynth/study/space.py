"""The design space of a study: its typed variables, in one place.

A :class:`Variable` is continuous, integer or categorical; a numeric variable may be on a
log scale (``log``) and may list sweep ``values``; a **conditional** variable (``when``)
exists only for some choices of categorical variables. A :class:`DesignSpace` owns what every
runner shares:

* the bounds and the normalisation of the numeric variables to and from the unit cube
  (log-aware), :meth:`DesignSpace.to_unit`, :meth:`DesignSpace.from_unit`;
* the centre (:func:`centre_value`, :meth:`DesignSpace.centre`);
* the sweep grid (:meth:`DesignSpace.grid`, :meth:`DesignSpace.grid_size`): the product of
  the values/choices of the active variables, for each categorical combination;
* Optuna suggestion (:meth:`DesignSpace.suggest`): a conditional variable is suggested only
  when it is active;
* the active variables of a design (:meth:`DesignSpace.active`): an inactive conditional
  variable is absent from the design's values (and empty in results.csv);
* the SI values of designs given in the study or on the command line (:meth:`DesignSpace.parse`,
  units parsed here, errors naming the key path);
* the identity of a design (:func:`design_key`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..common.units import QuantityError, parse_quantity
from .errors import StudyError

__all__ = ["Variable", "DesignSpace", "BOX_CENTRE_U", "centre_value", "design_key", "quantity"]

#: The centre of a variable's range in normalised coordinates (0 = low, 1 = high; on a log
#: scale for ``log`` variables).
BOX_CENTRE_U = 0.5


def quantity(value, kind, path):
    """A scalar quantity of ``kind`` (None: pass through) to SI; a :class:`StudyError` naming
    ``path`` when the value or its unit is wrong."""
    if kind is None:
        return value
    try:
        return parse_quantity(value, kind, field=path)
    except QuantityError as e:
        raise StudyError(str(e)) from None


@dataclass(frozen=True)
class Variable:
    name: str
    type: str
    kind: str | None  # quantity kind of the parameter (length, angle, None)
    low: float | None = None
    high: float | None = None
    values: tuple | None = None  # explicit values (SI) for sweeps
    choices: tuple | None = None
    log: bool = False
    when: tuple = ()  # ((categorical variable, (choice, ...)), ...): active only for these choices

    def normalize(self, v: float) -> float:
        if self.log:
            return (math.log(v) - math.log(self.low)) / (math.log(self.high) - math.log(self.low))
        return (v - self.low) / (self.high - self.low)

    def denormalize(self, u: float) -> float:
        if self.log:
            return math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low)))
        return self.low + u * (self.high - self.low)

    @property
    def is_numeric(self) -> bool:
        """A variable with a range [low, high] (continuous or integer)."""
        return self.type != "categorical" and self.low is not None and self.high is not None

    @property
    def sweep_values(self) -> tuple | None:
        """The values a sweep takes: ``values``, else ``choices``."""
        return self.values if self.values is not None else self.choices


def centre_value(v):
    """The centre of one variable: the middle of [low, high] on its scale (geometric mean for
    ``log``), rounded for an integer variable; the middle listed value of a variable with
    values only; the first choice of a categorical one."""
    if v.type != "categorical" and v.low is not None and v.high is not None:
        x = v.denormalize(BOX_CENTRE_U)
        return round(x) if v.type == "integer" else x
    if v.values:
        return v.values[len(v.values) // 2]
    if v.choices:
        return v.choices[0]
    return None


def _absent(x) -> bool:
    return x is None or (isinstance(x, (float, np.floating)) and math.isnan(x))


def design_key(variables, values) -> tuple:
    """Identity of a design: its design-variable values in the order of ``variables``, floats
    to 12 significant digits (so that a value read back from CSV or JSON matches the one
    evaluated), NumPy integers as ints, an absent (inactive) variable as None. ``values`` is
    a mapping or a table row."""
    out = []
    for v in variables:
        x = values.get(v.name) if hasattr(values, "get") else values[v.name]
        if _absent(x):
            x = None
        elif isinstance(x, (float, np.floating)) and np.isfinite(x):
            x = float(x)
            r = _ROUNDED.get(x) if x else None  # (a zero keeps its own sign: not kept)
            if r is None:
                r = float(f"{x:.12g}")
                if x:
                    if len(_ROUNDED) >= 1 << 16:
                        _ROUNDED.clear()
                    _ROUNDED[x] = r
            x = r
        elif isinstance(x, np.integer):
            x = int(x)
        out.append(x)
    return tuple(out)


#: {float: the float of its 12 significant digits} of :func:`design_key`: a study's tables give
#: the same values again and again (a report reads every design's key several times; the
#: formatting costs ten times a lookup).
_ROUNDED: dict = {}


def _order(variables, path="variables") -> list:
    """The variables with every ``when`` parent before its children (stable: the listed order
    when no variable is conditional); a :class:`StudyError` on a cycle."""
    index = {v.name: i for i, v in enumerate(variables)}
    done, out, visiting = set(), [], []

    def visit(v):
        if v.name in done:
            return
        if v.name in visiting:
            cyc = visiting[visiting.index(v.name):] + [v.name]
            raise StudyError(f"{path}[{index[cyc[0]]}].when: the conditions form a cycle: {' -> '.join(cyc)}")
        visiting.append(v.name)
        for parent, _ in v.when:
            if parent in index:
                visit(variables[index[parent]])
        visiting.pop()
        done.add(v.name)
        out.append(v)

    for v in variables:
        visit(v)
    return out


class DesignSpace:
    """The typed design variables of a study (see the module docstring)."""

    def __init__(self, variables):
        self.variables = tuple(variables)
        self.by_name = {v.name: v for v in self.variables}
        self.order = tuple(_order(self.variables))  # parents before the variables they condition
        parents = {p for v in self.variables for p, _ in v.when}
        self._branching = parents

    # -- the variables ------------------------------------------------------------------------------
    def __iter__(self):
        return iter(self.variables)

    def __len__(self):
        return len(self.variables)

    @property
    def names(self) -> list[str]:
        return [v.name for v in self.variables]

    @property
    def numeric(self) -> tuple:
        """The variables with a range [low, high], in the study's order."""
        return tuple(v for v in self.variables if v.is_numeric)

    @property
    def conditional(self) -> bool:
        return any(v.when for v in self.variables)

    def bounds(self) -> list[tuple]:
        """(low, high) of each numeric variable (SI)."""
        return [(v.low, v.high) for v in self.numeric]

    def is_active(self, v, values: dict) -> bool:
        """Whether variable ``v`` exists in design ``values`` (every condition of its ``when``
        met by an active parent)."""
        for parent, choices in v.when:
            if parent not in values or values[parent] not in choices:
                return False
        return True

    def active(self, values: dict) -> list:
        """The variables that exist in design ``values`` (study order)."""
        on = {}
        for v in self.order:
            if self.is_active(v, on):
                on[v.name] = values.get(v.name)
        return [v for v in self.variables if v.name in on]

    def restrict(self, values: dict) -> dict:
        """``values`` without the inactive conditional variables (study order)."""
        return {v.name: values[v.name] for v in self.active(values) if v.name in values}

    # -- the unit cube -------------------------------------------------------------------------------
    def to_unit(self, values: dict) -> list[float]:
        """The numeric variables of ``values`` in [0, 1] (log scale for ``log`` ones)."""
        return [v.normalize(values[v.name]) for v in self.numeric]

    def from_unit(self, u) -> dict:
        """Design values of a point of the unit cube (clipped to it; integers rounded)."""
        out = {}
        for v, x in zip(self.numeric, u):
            val = v.denormalize(float(np.clip(x, 0, 1)))
            out[v.name] = int(round(val)) if v.type == "integer" else val
        return out

    # -- the centre -----------------------------------------------------------------------------------
    def centre(self, chosen: dict | None = None) -> dict:
        """The centre of the box, {variable: value} (see :func:`centre_value`), with the values
        ``chosen`` in place of the centre's (e.g. a study's reference structure); with conditional
        variables only those active there. A study's centre is
        :func:`parasynth.study.structure_space.box_centre`, which calls this."""
        out = {}
        for v in self.variables:
            x = chosen[v.name] if chosen and v.name in chosen else centre_value(v)
            if x is not None:
                out[v.name] = x
        return self.restrict(out) if self.conditional or chosen else out

    # -- the sweep grid ---------------------------------------------------------------------------------
    def grid(self) -> list[dict]:
        """Every design of the sweep grid: the product of the values (or choices) of the active
        variables, the first variable varying slowest; keys in the study's order."""
        out = []
        names = self.names

        def walk(i, assigned):
            if i == len(self.order):
                out.append({k: assigned[k] for k in names if k in assigned})
                return
            v = self.order[i]
            if not self.is_active(v, assigned):
                walk(i + 1, assigned)
                return
            for x in v.sweep_values or ():
                assigned[v.name] = x
                walk(i + 1, assigned)
            assigned.pop(v.name, None)

        walk(0, {})
        return out

    def grid_size(self) -> int:
        """Designs of the sweep grid, without building it."""

        def count(i, assigned):
            n = 1
            for j in range(i, len(self.order)):
                v = self.order[j]
                if not self.is_active(v, assigned):
                    continue
                vals = v.sweep_values or ()
                if v.name in self._branching:
                    total = 0
                    for x in vals:
                        total += count(j + 1, {**assigned, v.name: x})
                    return n * total
                n *= len(vals)
            return n

        return count(0, {})

    # -- Optuna ---------------------------------------------------------------------------------------------
    def suggest(self, trial, fixed: dict | None = None) -> dict:
        """Ask an Optuna trial for a design: each active variable suggested once (parents
        before the variables they condition), keys in the study's order. Variables in ``fixed``
        (e.g. the structure a schedule chose) take that value and are not suggested."""
        values = {}
        fixed = fixed or {}
        for v in self.order:
            if not self.is_active(v, values):
                continue
            if v.name in fixed:
                values[v.name] = fixed[v.name]
            elif v.type == "categorical":
                values[v.name] = trial.suggest_categorical(v.name, list(v.choices))
            elif v.type == "integer":
                values[v.name] = trial.suggest_int(v.name, int(v.low), int(v.high), log=v.log)
            else:
                values[v.name] = trial.suggest_float(v.name, v.low, v.high, log=v.log)
        return {k: values[k] for k in self.names if k in values}

    # -- given designs --------------------------------------------------------------------------------------
    def parse(self, values: dict, path: str) -> dict:
        """SI values of a design given with units ({variable: value}), e.g. an entry of
        ``optimizer.designs`` or ``optimizer.start``; errors name ``path.<variable>``."""
        if not isinstance(values, dict):
            raise StudyError(f"{path}: give a mapping {{variable: value with unit}}")
        out = {}
        for k, x in values.items():
            if k not in self.by_name:
                raise StudyError(f"{path}.{k}: not a design variable; variables: {', '.join(self.names) or '(none)'}")
            out[k] = self.parse_value(k, x, f"{path}.{k}")
        return out

    def parse_value(self, name: str, value, where: str):
        """The SI value of variable ``name`` given as ``value`` (with its unit)."""
        return quantity(value, self.by_name[name].kind, where)

    def key(self, values) -> tuple:
        """The identity of a design (:func:`design_key`)."""
        return design_key(self.variables, values)
