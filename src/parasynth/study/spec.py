"""The YAML study format: schema (pydantic) and resolution to SI values.

A study file is validated in two passes. The schema pass (pydantic, ``extra="forbid"``)
checks structure and types; the resolution pass checks names against the mechanism and the
measure registry and converts every quantity with its unit to SI. Both raise
:class:`StudyError`, whose message names the key path (``variables[0].low``) and what is
allowed.

Example::

    name: 5pus_upu_link_length
    mechanism: 5pus_upu
    fixed: {slider_radius: 135 mm}
    variables:
      - {name: link_length, values: [165 mm, 185 mm, 205 mm, 225 mm]}
    objectives:
      - {name: workspace_volume, goal: maximize}
      - {name: extent, label: z_range, goal: maximize, settings: {axis: z}}
    evaluation: {method: sobol, samples: 8192, seed: 0,
                 ranges: {x: [-150 mm, 150 mm], y: [-150 mm, 150 mm], z: [-300 mm, 200 mm]}}
    optimizer: {kind: sweep}
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..units import QuantityError, parse_quantity

__all__ = ["StudyError", "StudySpec", "ResolvedStudy", "load_study", "resolve_study", "OPTIMIZERS"]

#: Optimiser kinds and their algorithms.
OPTIMIZERS = {
    "sweep": ("grid", "list"),
    "nlopt": ("LN_COBYLA", "LN_BOBYQA", "LN_NELDERMEAD", "LN_SBPLX", "GN_ISRES", "GN_DIRECT_L", "GN_CRS2_LM",
              "GN_ESCH"),
    "optuna": ("tpe", "nsga2", "nsga3", "random", "qmc", "cmaes"),
}
NLOPT_WITH_CONSTRAINTS = ("LN_COBYLA", "GN_ISRES")


class StudyError(ValueError):
    """An invalid study: the message names the key path and what is allowed."""


Scalar = float | int | str | bool


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


class VariableSpec(_Model):
    name: str
    type: Literal["continuous", "integer", "categorical"] = "continuous"
    low: Scalar | None = None
    high: Scalar | None = None
    values: list[Any] | None = None
    choices: list[Any] | None = None
    num: int | None = Field(default=None, ge=1)
    log: bool = False


class MeasureRef(_Model):
    name: str
    label: str | None = None
    goal: Literal["maximize", "minimize"] | None = None
    settings: dict[str, Any] = Field(default_factory=dict)


class ConstraintRef(_Model):
    name: str
    label: str | None = None
    min: Scalar | None = None
    max: Scalar | None = None
    settings: dict[str, Any] = Field(default_factory=dict)


class EvaluationSpec(_Model):
    method: Literal["sobol", "grid", "random"] = "sobol"
    samples: int = Field(default=4096, ge=1)
    seed: int = 0
    ranges: dict[str, list[Scalar]] | None = None
    fixed_pose: dict[str, Scalar] = Field(default_factory=dict)
    constraints: list[str] | None = None
    final_samples: int | None = Field(default=None, ge=1)
    final_repeats: int = Field(default=4, ge=1)
    final_top: int = Field(default=5, ge=0)


class OptimizerSpec(_Model):
    kind: Literal["sweep", "nlopt", "optuna"] = "sweep"
    algorithm: str | None = None
    n_trials: int | None = Field(default=None, ge=1)
    maxeval: int | None = Field(default=None, ge=1)
    xtol_rel: float | None = Field(default=None, gt=0)
    ftol_rel: float | None = Field(default=None, gt=0)
    start: dict[str, Any] | None = None
    n_jobs: int = Field(default=1, ge=1)
    storage: str | None = None
    seed: int | None = None
    designs: list[dict[str, Any]] | None = None
    population_size: int | None = Field(default=None, ge=2)


class StudySpec(_Model):
    name: str = Field(pattern=r"^[A-Za-z0-9_.\-]+$")
    description: str = ""
    mechanism: str
    fixed: dict[str, Any] = Field(default_factory=dict)
    variables: list[VariableSpec] = Field(default_factory=list)
    objectives: list[MeasureRef] = Field(min_length=1)
    constraints: list[ConstraintRef] = Field(default_factory=list)
    evaluation: EvaluationSpec = Field(default_factory=EvaluationSpec)
    optimizer: OptimizerSpec = Field(default_factory=OptimizerSpec)
    reference: dict[str, Any] | None = None
    tied: dict[str, str] = Field(default_factory=dict)
    output: str | None = None


# -- resolved, SI -------------------------------------------------------------------------------
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

    def normalize(self, v: float) -> float:
        if self.log:
            return (math.log(v) - math.log(self.low)) / (math.log(self.high) - math.log(self.low))
        return (v - self.low) / (self.high - self.low)

    def denormalize(self, u: float) -> float:
        if self.log:
            return math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low)))
        return self.low + u * (self.high - self.low)


@dataclass(frozen=True)
class Objective:
    name: str  # measure name
    label: str  # column name
    goal: str
    settings: dict


@dataclass(frozen=True)
class DesignConstraint:
    name: str
    label: str
    min: float | None
    max: float | None
    settings: dict

    def margin(self, value: float) -> float:
        m = math.inf
        if self.min is not None:
            m = min(m, value - self.min)
        if self.max is not None:
            m = min(m, self.max - value)
        return m


@dataclass(frozen=True)
class ResolvedStudy:
    """A validated study with every quantity in SI."""

    spec: StudySpec
    mechanism: str
    fixed: dict
    variables: tuple[Variable, ...]
    objectives: tuple[Objective, ...]
    constraints: tuple[DesignConstraint, ...]
    evaluation: dict  # method, n, seed, ranges (SI), fixed_pose (SI), constraints
    optimizer: OptimizerSpec
    reference: dict | None
    source: str | None = None
    tied: dict = dataclasses.field(default_factory=dict)  # parameter -> design variable it equals

    @property
    def name(self) -> str:
        return self.spec.name

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.spec.model_dump(exclude_none=True), sort_keys=False)


def _fmt_loc(loc) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def load_study(path_or_text, *, is_text: bool = False) -> ResolvedStudy:
    """Read, validate and resolve a study YAML file (or YAML text with ``is_text=True``)."""
    if is_text:
        text, source = path_or_text, None
    else:
        p = Path(path_or_text)
        if not p.exists():
            raise StudyError(f"study file {str(p)!r} does not exist")
        text, source = p.read_text(), str(p)
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise StudyError(f"{source or 'study'}: not valid YAML: {e}") from None
    if not isinstance(data, dict):
        raise StudyError(f"{source or 'study'}: the top level must be a mapping with keys name, mechanism, variables, objectives, ...")
    return resolve_study(data, source=source)


def parse_spec(data: dict) -> StudySpec:
    try:
        return StudySpec.model_validate(data)
    except ValidationError as e:
        msgs = []
        for err in e.errors():
            loc = _fmt_loc(err["loc"])
            if err["type"] == "extra_forbidden":
                parent = err["loc"][:-1]
                allowed = _allowed_keys(parent)
                msgs.append(f"{loc}: unknown key; allowed: {', '.join(allowed)}")
            elif err["type"] == "missing":
                msgs.append(f"{loc}: required key is missing")
            elif err["type"] == "literal_error":
                msgs.append(f"{loc}: {err['msg']} (got {err.get('input')!r})")
            else:
                msgs.append(f"{loc}: {err['msg']} (got {err.get('input')!r})")
        raise StudyError("invalid study:\n  " + "\n  ".join(msgs)) from None


def _allowed_keys(parent_loc) -> list[str]:
    model = StudySpec
    sub = {"variables": VariableSpec, "objectives": MeasureRef, "constraints": ConstraintRef,
           "evaluation": EvaluationSpec, "optimizer": OptimizerSpec}
    for part in parent_loc:
        if isinstance(part, str) and part in sub:
            model = sub[part]
    return list(model.model_fields)


def _param_kinds(mech_cls) -> dict:
    return dict(getattr(mech_cls.Params, "UNITS", {}))


def _q(value, kind, path):
    """A scalar quantity of ``kind`` (None: pass through) to SI."""
    if kind is None:
        return value
    try:
        return parse_quantity(value, kind, field=path)
    except QuantityError as e:
        raise StudyError(str(e)) from None


def _q_nested(value, kind, path):
    if isinstance(value, (list, tuple)):
        return tuple(_q_nested(v, kind, f"{path}[{i}]") for i, v in enumerate(value))
    return _q(value, kind, path)


def resolve_study(data: dict, source: str | None = None) -> ResolvedStudy:
    """Validate names and units of a parsed study mapping and convert to SI."""
    from ..mechanisms import mechanism_class, resolve_mechanism_name
    from ..objectives import OBJECTIVES, get as get_measure

    spec = parse_spec(data)
    # A registry name, or a mechanism description file: a relative path is taken from the study
    # file's directory and recorded as an absolute path (so that run copies still find it).
    try:
        mech_name = resolve_mechanism_name(spec.mechanism, Path(source).parent if source else None)
        mech_cls = mechanism_class(mech_name)
    except ValueError as e:
        raise StudyError(f"mechanism: {e}") from None
    if mech_name != spec.mechanism:
        spec = spec.model_copy(update={"mechanism": mech_name})
    kinds = _param_kinds(mech_cls)
    params = [f.name for f in dataclasses.fields(mech_cls.Params)]

    def check_param(name, path):
        if name not in params:
            raise StudyError(f"{path}: {name!r} is not a parameter of {spec.mechanism}; valid: {', '.join(params)}")

    fixed = {}
    for k, v in spec.fixed.items():
        check_param(k, f"fixed.{k}")
        fixed[k] = _q_nested(v, kinds.get(k), f"fixed.{k}")

    variables = []
    seen = set()
    for i, v in enumerate(spec.variables):
        path = f"variables[{i}]"
        check_param(v.name, f"{path}.name")
        if v.name in seen:
            raise StudyError(f"{path}.name: variable {v.name!r} is listed twice")
        if v.name in fixed:
            raise StudyError(f"{path}.name: {v.name!r} is both fixed and a design variable")
        seen.add(v.name)
        kind = kinds.get(v.name)
        low = _q(v.low, kind, f"{path}.low") if v.low is not None else None
        high = _q(v.high, kind, f"{path}.high") if v.high is not None else None
        values = tuple(_q(x, kind, f"{path}.values[{j}]") for j, x in enumerate(v.values)) if v.values else None
        choices = tuple(v.choices) if v.choices else None
        if v.type == "categorical":
            if not choices:
                raise StudyError(f"{path}.choices: a categorical variable needs a non-empty list of choices")
            choices = tuple(_q(x, kind, f"{path}.choices[{j}]") if kind else x for j, x in enumerate(choices))
        else:
            if values is None and (low is None or high is None):
                raise StudyError(f"{path}: give both low and high (with units), or a list of values")
            if low is not None and high is not None and not low < high:
                raise StudyError(f"{path}: empty bounds: low ({v.low}) must be below high ({v.high})")
            if v.log and low is not None and low <= 0:
                raise StudyError(f"{path}.log: log scale needs low > 0")
            if v.type == "integer":
                for nm, x in (("low", low), ("high", high)):
                    if x is not None and float(x) != int(x):
                        raise StudyError(f"{path}.{nm}: an integer variable needs integer bounds, got {x}")
        if v.num is not None and values is None and low is not None:
            n = v.num
            values = tuple(low + (high - low) * j / (n - 1) for j in range(n)) if n > 1 else (low,)
        variables.append(Variable(v.name, v.type, kind, low, high, values, choices, v.log))

    def resolve_settings(measure, settings, path):
        out = {}
        for k, val in settings.items():
            if k not in measure.settings:
                raise StudyError(
                    f"{path}.{k}: unknown setting of {measure.name!r}; allowed: {', '.join(measure.settings) or '(none)'}"
                )
            sk = measure.settings[k]
            if sk == "ranges":
                out[k] = _resolve_ranges(val, mech_cls, f"{path}.{k}")
            elif sk in ("length", "angle", "force", "mass", "time", "torque"):
                out[k] = _q_nested(val, sk, f"{path}.{k}")
            elif sk == "int":
                if not isinstance(val, int) or isinstance(val, bool):
                    raise StudyError(f"{path}.{k}: must be an integer, got {val!r}")
                out[k] = val
            elif sk == "float":
                try:
                    out[k] = float(val)
                except (TypeError, ValueError):
                    raise StudyError(f"{path}.{k}: must be a number, got {val!r}") from None
            else:
                out[k] = val
        return out

    objectives, labels = [], set()
    for i, o in enumerate(spec.objectives):
        path = f"objectives[{i}]"
        if o.name not in OBJECTIVES:
            raise StudyError(f"{path}.name: unknown objective {o.name!r}; valid: {', '.join(OBJECTIVES)}")
        m = get_measure(o.name)
        if m.models is not None and spec.mechanism not in m.models:
            raise StudyError(f"{path}.name: objective {o.name!r} applies to {list(m.models)}, not {spec.mechanism!r}")
        label = o.label or o.name
        if label in labels or label in seen:
            raise StudyError(f"{path}.label: column name {label!r} is used twice; give a distinct label")
        labels.add(label)
        objectives.append(Objective(o.name, label, o.goal or m.sense, resolve_settings(m, o.settings, f"{path}.settings")))

    constraints = []
    for i, c in enumerate(spec.constraints):
        path = f"constraints[{i}]"
        if c.name not in OBJECTIVES:
            raise StudyError(f"{path}.name: unknown measure {c.name!r}; valid: {', '.join(OBJECTIVES)}")
        m = get_measure(c.name)
        if c.min is None and c.max is None:
            raise StudyError(f"{path}: give a bound: min and/or max")
        kind = m.kind
        lo = _q(c.min, kind, f"{path}.min") if c.min is not None else None
        hi = _q(c.max, kind, f"{path}.max") if c.max is not None else None
        if kind is None:
            for nm, x in (("min", lo), ("max", hi)):
                if x is not None and not isinstance(x, (int, float)):
                    raise StudyError(f"{path}.{nm}: {c.name!r} is dimensionless here ({m.unit}); give a number, got {x!r}")
        label = c.label or c.name
        if label in labels:
            raise StudyError(f"{path}.label: column name {label!r} is used twice; give a distinct label")
        labels.add(label)
        constraints.append(DesignConstraint(c.name, label, lo, hi, resolve_settings(m, c.settings, f"{path}.settings")))

    ev = spec.evaluation
    ranges = _resolve_ranges(ev.ranges, mech_cls, "evaluation.ranges") if ev.ranges else None
    fixed_pose = {}
    task = _task_coordinates(mech_cls, fixed)
    for k, v in ev.fixed_pose.items():
        if k not in task:
            raise StudyError(f"evaluation.fixed_pose.{k}: not a task coordinate of {spec.mechanism}; valid: {', '.join(task)}")
        fixed_pose[k] = _q(v, "angle" if k in _angular(mech_cls) else "length", f"evaluation.fixed_pose.{k}")
    evaluation = dict(method=ev.method, n=ev.samples, seed=ev.seed, ranges=ranges,
                      fixed=fixed_pose or None, constraints=ev.constraints,
                      final_samples=ev.final_samples, final_repeats=ev.final_repeats, final_top=ev.final_top)

    opt = spec.optimizer
    allowed = OPTIMIZERS[opt.kind]
    if opt.algorithm is not None and opt.algorithm not in allowed:
        raise StudyError(f"optimizer.algorithm: {opt.algorithm!r} is not available for {opt.kind}; allowed: {', '.join(allowed)}")
    if opt.kind == "nlopt":
        if len(objectives) != 1:
            raise StudyError(f"objectives: nlopt optimises one objective, {len(objectives)} given; use optimizer.kind: optuna for several")
        for v in variables:
            if v.type != "continuous" or v.low is None:
                raise StudyError(f"variables: nlopt needs continuous variables with low/high; {v.name!r} is {v.type}")
    if opt.kind == "optuna":
        for v in variables:
            if v.type != "categorical" and (v.low is None or v.high is None):
                raise StudyError(f"variables: optuna needs low/high for {v.name!r} (or type: categorical with choices)")
    if opt.kind == "sweep" and not opt.designs:
        for v in variables:
            if v.values is None and v.choices is None:
                raise StudyError(f"variables: a sweep needs values (or num with low/high, or choices) for {v.name!r}")
    if opt.designs:
        for j, d in enumerate(opt.designs):
            for k in d:
                if k not in {v.name for v in variables}:
                    raise StudyError(f"optimizer.designs[{j}].{k}: not a design variable; variables: {', '.join(v.name for v in variables)}")

    reference = None
    if spec.reference is not None:
        reference = {}
        for k, v in spec.reference.items():
            check_param(k, f"reference.{k}")
            reference[k] = _q_nested(v, kinds.get(k), f"reference.{k}")

    tied = {}
    for k, src in spec.tied.items():
        check_param(k, f"tied.{k}")
        if src not in seen:
            raise StudyError(f"tied.{k}: {src!r} is not a design variable; variables: {', '.join(v.name for v in variables)}")
        if k in seen or k in fixed:
            raise StudyError(f"tied.{k}: {k!r} is already a design variable or fixed")
        if kinds.get(k) != kinds.get(src):
            raise StudyError(f"tied.{k}: {k!r} ({kinds.get(k)}) and {src!r} ({kinds.get(src)}) have different units")
        tied[k] = src

    return ResolvedStudy(spec, spec.mechanism, fixed, tuple(variables), tuple(objectives), tuple(constraints),
                         evaluation, opt, reference, source, tied)


_ANGULAR = {"alpha", "beta", "gamma", "psi", "theta", "phi"}


def _angular(mech_cls) -> set:
    """Angular task coordinates of a model class (by name for models that set them per instance)."""
    if getattr(mech_cls, "task_coordinates", ()):
        return set(getattr(mech_cls, "angular_coordinates", ()))
    return _ANGULAR


def _task_coordinates(mech_cls, fixed) -> tuple:
    try:
        return tuple(mech_cls(mech_cls.Params(**{k: v for k, v in fixed.items()})).task_coordinates)
    except Exception:
        return tuple(getattr(mech_cls, "task_coordinates", ()) or ("x", "y", "z", "alpha", "beta", "gamma", "psi", "theta"))


def _resolve_ranges(val, mech_cls, path) -> dict:
    if not isinstance(val, dict) or not val:
        raise StudyError(f"{path}: give a mapping {{coordinate: [low, high]}} with units, e.g. {{z: [600 mm, 900 mm]}}")
    out = {}
    for k, pair in val.items():
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise StudyError(f"{path}.{k}: give [low, high] with units, got {pair!r}")
        kind = "angle" if k in _angular(mech_cls) else "length"
        lo, hi = (_q(x, kind, f"{path}.{k}[{j}]") for j, x in enumerate(pair))
        if not lo < hi:
            raise StudyError(f"{path}.{k}: empty or inverted range [{pair[0]}, {pair[1]}]")
        out[k] = (lo, hi)
    return out
