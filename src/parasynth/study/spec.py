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
import functools
import itertools
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, Strict, ValidationError, field_validator

from ..model.geometry_checks import degenerate_geometry
from ..model.task import Task, TaskError
from ..mechanisms import load_mechanism, mechanism_class, resolve_mechanism_name
from ..measures.measure_spec import SettingError
from ..measures.objectives import OBJECTIVES, get as get_measure
from ..measures.usable import SINGULARITY_FLOOR
from ..measures.robustness import RobustError, check_robust_spec, resolve_tolerances, robust
from ..common.validation import MAX_SAMPLES, MAX_SEED, MAX_TRIALS, is_real_number, numpy_reference
from ..common.units import ACTUATOR_KINDS, QuantityError, actuator_unit_kind, parse_quantity, si_unit
from ..common.yamlio import YamlError, load_yaml
from ..measures.display import actuators_of, fmt_quantity, fmt_study_design, unit_for_kind, written_unit
from .design import design_params, evaluation_sample, measure_arguments, with_pose_constraints
from .errors import StudyError
from .magnitudes import scale_warnings
from .space import DesignSpace, Variable, quantity
from .defaults import OPTUNA_TRIALS
from ..common.columns import DERIVED_SUFFIXES  # the suffixes of derived columns, in one module
from .optimizers.base import ALGORITHMS, kinds, optimizer_class
from .structure_space import (STRUCTURE, STRUCTURE_FLOOR_LABEL, box_centre, check_halving, check_structure_optimizer,
                              resolve_structures,
                              structure_variables)

__all__ = ["StudyError", "StudySpec", "ResolvedStudy", "load_study", "resolve_study", "check_study", "OPTIMIZERS",
           "RESERVED_COLUMNS"]

#: Optimiser kinds and their algorithms (a mapping read from the registry of
#: :mod:`parasynth.study.optimizers`).
OPTIMIZERS = ALGORITHMS

#: Columns of results.csv and final.csv besides the design variables, objectives and
#: constraints: a label may not take one of these names.
RESERVED_COLUMNS = ("trial", "source", "feasible", "status", "error", "seed", "samples", "time_s", "repeats",
                    "knee", "count", "role", "dominates_reference_screen", "verified", "verification",
                    "recommended", "home_margin")

# The settings of each measure (kinds, ranges, choices) are declared with the measure
# (parasynth.objectives, parasynth.measures.measure_spec) and checked by its own validator.
#: Most designs a sweep may list (the product of the variables' value counts).
MAX_DESIGNS = MAX_TRIALS


Scalar = float | int | str | bool
def _integral_float(value):
    """A count written in exponent form (``1.6e4``, a float in YAML) as the integer it is;
    anything else as it is, for the strict check."""
    if isinstance(value, float) and math.isfinite(value) and value.is_integer():
        return int(value)
    return value


#: Integers of the study file: true/false and 4096.5 are not counts; 1.6e4 is 16000.
Int = Annotated[int, Strict(), BeforeValidator(_integral_float)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


class VariableSpec(_Model):
    name: str = Field(description="The mechanism parameter (see `parasynth list`).")
    type: Literal["continuous", "integer", "categorical"] = Field(default="continuous", description=(
        "continuous (default), integer or categorical."))
    low: Scalar | None = Field(default=None, description=(
        "Lower bound with the parameter's unit, e.g. 160 mm; a plain number for dimensionless "
        "parameters."))
    high: Scalar | None = Field(default=None, description="Upper bound with the parameter's unit; must be above low.")
    values: list[Any] | None = Field(default=None, description=(
        "Explicit values for a sweep, with units, e.g. [165 mm, 185 mm]."))
    choices: list[Any] | None = Field(default=None, description="The choices of a categorical variable.")
    num: Int | None = Field(default=None, ge=1, le=10_000, description=(
        "Number of evenly spaced sweep values from low to high (1 to 10000)."))
    log: bool = Field(default=False, description="Sample on a log scale (needs low > 0).")
    when: dict[str, list[Any]] | None = Field(default=None, description=(
        "Makes the variable conditional, {categorical variable: [choice, ...]}: it exists only "
        "when each named variable takes one of the listed choices (absent from the design and "
        "empty in results.csv otherwise)."))


class RobustSpec(_Model):
    tolerances: dict[str, Any] = Field(description=(
        "Scatter of the design, {name: tolerance with its unit}: a description parameter with a length or "
        "angle unit (slider_radius: 0.05 mm; the mechanism is rebuilt with the drawn value) or a per-leg "
        "tolerance of the accuracy module (actuator_tolerance, anchor_tolerance, link_tolerance, "
        "axis_tolerance, spherical_clearance, universal_clearance), each drawn uniformly within "
        "+-tolerance (clearances in a ball); per-leg scatter is evaluated on the mechanism as built."))
    statistic: Any = Field(default="mean", description=(
        "What the scatter draws give: mean (default), quantile (with level), worst (the least favourable "
        "draw) or first_order (nominal worsened by sum |sensitivity| x tolerance; not for measures counted "
        "on samples such as volumes)."))
    level: Any = Field(default=None, description="Level of the quantile statistic in (0, 1), e.g. 0.05.")
    samples: Any = Field(default=32, description=(
        "Scatter draws per design (2 to 4096, default 32), the same for every design (common random numbers)."))
    seed: Any = Field(default=0, description="Seed of the scatter draws (default 0).")
    probability: Any = Field(default=None, description=(
        "Constraints only: a chance constraint, the least fraction in (0, 1] of the scatter draws that "
        "must satisfy the bound (its value is that fraction, with its standard error in the report)."))


class MeasureRef(_Model):
    name: str = Field(description="A registered measure, e.g. workspace_volume.")
    label: str | None = Field(default=None, description=(
        "Column name in the results (default the measure name); must not clash with "
        "another column (trial, feasible, a design variable, <constraint>_margin, ...)."))
    goal: Literal["maximize", "minimize"] | None = Field(default=None, description=(
        "maximize or minimize (default the measure's natural goal)."))
    settings: dict[str, Any] = Field(default_factory=dict, description=(
        "Settings of the measure, {setting: value}, checked against the kinds, ranges and choices the "
        "measure declares (e.g. quantile in [0, 1]; see `parasynth list`). Workspace measures may override "
        "a field of their workspace sample here (samples as n, seed, ranges, fixed, method; the accuracy "
        "measures' sampling method is `sampling`, their `method` is the error model)."))
    robust: RobustSpec | None = Field(default=None, description=(
        "Evaluate the measure under manufacturing scatter (a robust objective): tolerances, statistic, "
        "level, samples, seed (docs/objectives.md, robust measures)."))


class ConstraintRef(_Model):
    name: str = Field(description="A registered measure, e.g. footprint_radius.")
    label: str | None = Field(default=None, description=(
        "Column name in the results (default the measure name); <label>_margin is added."))
    min: Scalar | None = Field(default=None, description=(
        "Lower bound with the measure's unit (a plain number for dimensionless measures)."))
    max: Scalar | None = Field(default=None, description=(
        "Upper bound with the measure's unit; min must not be above max."))
    settings: dict[str, Any] = Field(default_factory=dict, description="Settings of the measure, as for objectives.")
    robust: RobustSpec | None = Field(default=None, description=(
        "Evaluate the constraint under manufacturing scatter: as for objectives, plus probability for a "
        "chance constraint (the fraction of draws within the bound)."))


class EvaluationSpec(_Model):
    method: Literal["sobol", "grid", "random"] = Field(default="sobol", description=(
        "Sampling method: sobol (default), grid or random."))
    samples: Int = Field(default=4096, ge=1, le=MAX_SAMPLES, description=(
        f"Workspace samples per design (1 to {MAX_SAMPLES}, default 4096)."))
    seed: Int = Field(default=0, ge=0, le=MAX_SEED, description=(
        f"Seed of the sample (0 to {MAX_SEED}); the same points serve every design."))
    ranges: dict[str, list[Scalar]] | None = Field(default=None, description=(
        "Sampled task coordinates, {coordinate: [low, high]} with units, e.g. "
        "{z: [-450 mm, 300 mm]}; leave out for the model's default ranges (an empty "
        "mapping is an error)."))
    fixed_pose: dict[str, Scalar] = Field(default_factory=dict, description=(
        "Task coordinates held fixed while sampling, {coordinate: value with unit}."))
    constraints: list[str | dict[str, Any]] | None = Field(default=None, description=(
        "Pose constraints that define the workspace: names of the model's (default all of them; see "
        "`parasynth list`) and added constraints, {type: singularity_margin, min: 0.02, name: ...}: the "
        "normalised singularity margin at or above min (a number in [0, 1)); a list of added constraints only "
        "keeps all of the model's."))
    final_samples: Int | None = Field(default=None, ge=1, le=MAX_SAMPLES, description=(
        "Samples per seed of the final re-evaluation and verification of the best designs (1 to "
        f"{MAX_SAMPLES}); leave out to use the study's own samples."))
    final_repeats: Int = Field(default=4, ge=1, le=1000, description=(
        "Seeds of the final re-evaluation (1 to 1000, default 4): mean and standard "
        "error over them."))
    final_top: Int = Field(default=5, ge=0, le=1000, description=(
        "Front designs re-evaluated at the end (0 to 1000, default 5): the k best (one "
        "objective) or k spread along the front by crowding distance, plus the knee and up to "
        "max(3, final_top) designs that dominate the reference on single samples; 0 re-evaluates only the designs "
        "the verification walks (docs/verification.md)."))
    singularity_floor: Annotated[float, Strict(False)] = Field(default=SINGULARITY_FLOOR, ge=0.0, lt=1.0, description=(
        "The least singularity margin at the home pose and over the task of a design the study may recommend, and "
        f"of a structure study's designs (a number in [0, 1), default {SINGULARITY_FLOOR:g}, "
        "parasynth.measures.usable.SINGULARITY_FLOOR; docs/verification.md)."))
    verify_designs: Int = Field(default=10, ge=0, le=1000, description=(
        "Designs beyond the final candidates re-evaluated at most while looking for a recommendation that "
        "passes verification (0 to 1000, default 10; docs/verification.md)."))
    engine: Literal["compiled", "numpy"] = Field(default="compiled", description=(
        "Evaluation engine: compiled (default; NumPy, with a warning, for a mechanism it does "
        "not cover) or numpy (the NumPy reference)."))


class PolishSpec(_Model):
    method: Literal["cobyla", "bobyqa"] = Field(default="cobyla", description=(
        "Local NLopt search refining the best (or recommended) design: cobyla (takes the design constraints; "
        "default) or bobyqa (only for a study without design constraints)."))
    budget: Int = Field(ge=1, le=MAX_TRIALS, description=(
        "Designs the polish may evaluate, part of the study's budget (the global search gets the rest)."))


class OptimizerSpec(_Model):
    kind: str = Field(default="sweep", description="The optimiser: sweep (default), nlopt, optuna, ... (the registered "
                      "kinds; see `parasynth list`).", json_schema_extra=lambda s: s.update(enum=list(kinds())))
    algorithm: str | None = Field(default=None, description=(
        "Algorithm of the kind: sweep grid|list; NLopt LN_COBYLA, LN_BOBYQA, ...; Optuna "
        "tpe, nsga2, ... (see `parasynth list`)."))
    n_trials: Int | None = Field(default=None, ge=1, le=MAX_TRIALS, description=(
        f"Optuna trials, SciPy designs (1 to {MAX_TRIALS})."))
    maxeval: Int | None = Field(default=None, ge=1, le=MAX_TRIALS, description=(
        f"NLopt evaluations (1 to {MAX_TRIALS})."))
    xtol_rel: float | None = Field(default=None, gt=0, allow_inf_nan=False, description=(
        "NLopt relative tolerance on the design variables (> 0)."))
    ftol_rel: float | None = Field(default=None, gt=0, allow_inf_nan=False, description=(
        "NLopt relative tolerance on the objective (> 0)."))
    start: dict[str, Any] | None = Field(default=None, description=(
        "NLopt start design, {variable: value with unit} (default the reference or the box centre)."))
    n_jobs: Int = Field(default=1, ge=1, le=1024, description="Same as optimizer.workers (kept for older study files).")
    workers: Int | None = Field(default=None, ge=1, le=1024, description=(
        "Local worker processes of an Optuna study (1 to 1024, default 1; --workers overrides; "
        "see docs/scaling.md)."))
    storage: str | None = Field(default=None, description=(
        "Optuna storage URL: postgresql://USER:PASSWORD@HOST/DB, sqlite:///FILE or journal:FILE "
        "(default the run directory's optuna.journal; --storage overrides; see docs/scaling.md)."))
    seed: Int | None = Field(default=None, ge=0, le=MAX_SEED, description=f"Seed of the optimiser (0 to {MAX_SEED}).")
    designs: list[dict[str, Any]] | None = Field(default=None, description=(
        "For a sweep: the list of designs to evaluate, each {variable: value with unit}."))
    population_size: Int | None = Field(default=None, ge=2, le=100_000, description=(
        "Population of the evolutionary Optuna samplers (2 to 100000)."))
    polish: PolishSpec | None = Field(default=None, description=(
        "After a global optimiser, refine its best design (one objective) or recommended design (several) by a "
        "local NLopt search within the bounds, {method: cobyla | bobyqa, budget: N} (docs/study-format.md)."))

    @field_validator("kind")
    @classmethod
    def _registered_kind(cls, v):
        if v not in kinds():
            raise ValueError(f"{v!r} is not an optimiser; allowed: {', '.join(kinds())}")
        return v

    @property
    def plugin(self):
        """The registered optimiser class of :attr:`kind` (:mod:`parasynth.study.optimizers`)."""
        return optimizer_class(self.kind)


class StructureSpec(_Model):
    motion: str = Field(description=(
        "Motion type of the structures searched, translations T and rotations R, e.g. 3T2R (see "
        "docs/structures.md)."))
    leg_types: list[str] | None = Field(default=None, description=(
        "Limb types to draw from, e.g. [PUS, UPS, UPU] (default the whole vocabulary: SPS, UPS, PUS, RUS, RPS, "
        "PRS, RPU, UPU)."))
    legs: list[Int] | None = Field(default=None, description="Allowed total numbers of limbs, e.g. [6] (default any).")
    arrangements: list[str] | None = Field(default=None, description=(
        "Ring arrangements kept, e.g. [regular] (regular, paired, opposed; default all)."))
    axes: dict[str, list[str]] | None = Field(default=None, description=(
        "Required axes of the freedoms, {translations: [...], rotations: [...]}, e.g. {translations: [x, z], "
        "rotations: [y, moving x]} (default any)."))
    all_axes: bool = Field(default=False, description=(
        "Every joint-axis choice of the vocabulary, not only the first of each (default false)."))
    include: list[str] | None = Field(default=None, description=(
        "Only these structures (names or labels, e.g. [5-PUS/UPU, 5-UPS/UPU]; default every structure found)."))
    reference: str | None = Field(default=None, description=(
        "The reference structure (e.g. the paper's, 5-PUS/UPU): always given the full budget; its best design "
        "is marked in the report and the verdict says whether it is on the combined front."))
    screening: Int = Field(default=16, ge=1, le=MAX_TRIALS, description=(
        "Designs of every structure in the first rung, the screening (default 16)."))
    eta: Int = Field(default=2, ge=2, le=100, description=(
        "Successive-halving factor (default 2): after each rung the best 1/eta of the structures continue with "
        "eta times as many designs, up to optimizer.n_trials designs each."))
    keep: Int | None = Field(default=None, ge=1, le=1000, description=(
        "Structures that continue after each rung (default ceil(n / eta) of the n in the rung); the reference "
        "structure continues besides them."))


class StudySpec(_Model):
    """A parasynth design study (docs/study-format.md). Quantities are strings with units, e.g. '205 mm', '15 deg'."""

    model_config = ConfigDict(extra="forbid", title="parasynth study")

    name: str = Field(pattern=r"^[A-Za-z0-9_.\-]+$", description=(
        "Study name: letters, digits, '_', '.', '-'; names the run directory runs/<name>/ and the report."))
    description: str = Field(default="", description="Free text shown at the top of the report.")
    mechanism: str | None = Field(default=None, description=(
        "A registry name (see `parasynth list`) or a mechanism description file (.yaml; a relative "
        "path is taken from the study file's folder); or give structure: instead."))
    structure: StructureSpec | None = Field(default=None, description=(
        "Search the structure too, instead of mechanism: the candidate structures of a motion type "
        "(docs/structures.md); the structure becomes a categorical design variable and the budget is spread "
        "over the structures by successive halving."))
    fixed: dict[str, Any] = Field(default_factory=dict, description=(
        "Mechanism parameters held fixed, {parameter: value with unit}, e.g. {slider_radius: 135 mm}."))
    variables: list[VariableSpec] = Field(default_factory=list, description=(
        "Design variables: mechanism parameters the optimiser or sweep changes."))
    objectives: list[MeasureRef] = Field(min_length=1, description=(
        "Measures to optimise (at least one); see `parasynth list` for names and settings."))
    constraints: list[ConstraintRef] = Field(default_factory=list, description=(
        "Design constraints: a measure with a bound; a design is feasible when every margin >= 0."))
    evaluation: EvaluationSpec = Field(default_factory=EvaluationSpec, description=(
        "How every design is evaluated: the workspace sample shared by the workspace measures."))
    optimizer: OptimizerSpec = Field(default_factory=OptimizerSpec, description=(
        "The search: a sweep over listed values, NLopt (one objective) or Optuna (several)."))
    reference: dict[str, Any] | None = Field(default=None, description=(
        "A reference design (e.g. the paper's), {parameter: value with unit}: evaluated first and "
        "compared in the report."))
    tied: dict[str, str] = Field(default_factory=dict, description=(
        "Parameters that follow a design variable, {parameter: variable}; same unit."))
    output: str | None = Field(default=None, description="Run directory (default runs/<name>/); --out overrides it.")
    task: dict[str, Any] | None = Field(default=None, description=(
        "What the robot must do (docs/tasks.md): required poses, placement, tool, trajectory, loads, "
        "installation space and floors, read by parasynth.Task.from_mapping; the task measures (task_coverage, "
        "task_actuator_force_max, ...) are evaluated on it, and task.placement.* / task.tool.* may be design "
        "variables. Not the task: section of a mechanism description (its task coordinates)."))


#: The keys of ``reference`` that are not mechanism parameters (a mapping, so not fields of a model).
REFERENCE_KEYS = {
    "label": "What the reference design is, named so in the report and the summary (e.g. \"the "
             "paper's design\"; default \"the reference design\").",
    "source": "Where the reference design comes from (e.g. \"Wang, Lyu & Liu 2021, Table 2\"); "
              "shown beside its label.",
}


# -- resolved, SI -------------------------------------------------------------------------------
# Variable (a design variable, SI) is defined in parasynth.study.space and importable from here.


@dataclass(frozen=True)
class Objective:
    name: str  # measure name
    label: str  # column name
    goal: str
    settings: dict
    robust: object = None  # a parasynth.measures.robustness.RobustMeasure (the robust block), or None


@dataclass(frozen=True)
class DesignConstraint:
    name: str
    label: str
    min: float | None
    max: float | None
    settings: dict
    robust: object = None  # a parasynth.measures.robustness.RobustMeasure (the robust block), or None
    probability: float | None = None  # a chance constraint: the least fraction of draws within the bound

    @property
    def bound(self):
        """("min" | "max", value) of the bound the robust statistics take as unfavourable side."""
        return ("min", self.min) if self.min is not None else ("max", self.max)

    def margin(self, value: float) -> float:
        """``value - min`` / ``max - value``; for a chance constraint, ``value`` is the fraction
        of scatter draws within the bound and the margin ``value - probability``."""
        if self.probability is not None:
            return value - self.probability
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
    reference_label: str | None = None  # what the reference design is ("the paper's design")
    reference_source: str | None = None  # where it comes from (a paper, a drawing)
    structures: object = None  # StructureSetup of a study over structures (study.structure_space)
    task: object = None  # the parasynth.Task of the study's task: section, or None

    @property
    def name(self) -> str:
        return self.spec.name

    @functools.cached_property
    def space(self) -> DesignSpace:
        """The design space of the study's variables (:class:`~parasynth.study.space.DesignSpace`)."""
        return DesignSpace(self.variables)

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.spec.model_dump(exclude_none=True), sort_keys=False)

    def variable_path(self, name: str) -> str:
        """The key path of design variable ``name`` in the study file: ``variables[j]``, or
        ``structure`` for the structure variable a study over structures adds."""
        j = next((j for j, v in enumerate(self.spec.variables) if v.name == name), None)
        return "structure" if j is None else f"variables[{j}]"


def _resolve_robust(spec, measure: str, mech_cls, path: str, constraint: bool):
    """The :class:`~parasynth.measures.robustness.RobustMeasure` of a ``robust:`` block (None without
    one); :class:`StudyError` naming ``<path>.<field>``."""
    if spec is None:
        return None
    if not constraint and spec.probability is not None:
        raise StudyError(f"{path}.probability: only a constraint takes a probability (a chance constraint)")
    if spec.probability is not None:  # a chance constraint counts the draws within the bound: no statistic
        # the defaults (statistic: mean, no level) are what a run's copy of the study file writes out
        for key, default in (("statistic", "mean"), ("level", None)):
            if key in spec.model_fields_set and getattr(spec, key) not in (None, default):
                raise StudyError(f"{path}.{key}: a chance constraint (probability) is the fraction of the draws "
                                 f"within the bound and takes no {key}; leave {key} out, or drop probability for "
                                 f"a constraint on the {key if key == 'statistic' else 'quantile'}")
    try:
        check_robust_spec(spec.statistic, spec.level, spec.samples, spec.seed, spec.probability, path, measure)
        params, legs = resolve_tolerances(spec.tolerances, _param_kinds(mech_cls), f"{path}.tolerances", study=True)
        if not any(params.values()) and not any(legs.values()):
            raise RobustError(f"{path}.tolerances: give at least one positive tolerance")
        return robust(measure, tolerances={**params, **legs}, statistic=spec.statistic, samples=spec.samples,
                      seed=spec.seed, level=spec.level)
    except RobustError as e:
        raise StudyError(str(e)) from None


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
    source = None if is_text else str(path_or_text)
    try:
        data = load_yaml(path_or_text, is_text=is_text, name="study" if is_text else None, what="study file")
    except YamlError as e:
        raise StudyError(str(e)) from None
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
        if len(msgs) == 1:
            raise StudyError(msgs[0]) from None
        raise StudyError(f"{len(msgs)} problems:\n  " + "\n  ".join(msgs)) from None


def _allowed_keys(parent_loc) -> list[str]:
    model = StudySpec
    sub = {"variables": VariableSpec, "objectives": MeasureRef, "constraints": ConstraintRef,
           "evaluation": EvaluationSpec, "optimizer": OptimizerSpec, "structure": StructureSpec,
           "robust": RobustSpec}
    for part in parent_loc:
        if isinstance(part, str) and part in sub:
            model = sub[part]
    return list(model.model_fields)


#: Design variables a study's task offers: {name: kind} (docs/tasks.md, ``Task.with_settings``).
TASK_VARIABLES = {"task.placement.x": "length", "task.placement.y": "length", "task.placement.z": "length",
                  "task.placement.yaw": "angle", "task.tool.x": "length", "task.tool.y": "length",
                  "task.tool.z": "length", "task.tool.yaw": "angle"}


def _absolute_files(mapping, base_dir):
    """``mapping`` with every ``file:`` value that is a relative path made absolute against
    ``base_dir`` (a copy; the mapping itself when nothing changes)."""
    if base_dir is None:
        return mapping
    if isinstance(mapping, dict):
        out = {}
        for k, v in mapping.items():
            if k == "file" and isinstance(v, str) and v and not Path(v).is_absolute():
                out[k] = str((Path(base_dir) / v).resolve())
            else:
                out[k] = _absolute_files(v, base_dir)
        return out
    if isinstance(mapping, list):
        return [_absolute_files(v, base_dir) for v in mapping]
    return mapping


def _param_kinds(mech_cls) -> dict:
    return dict(getattr(mech_cls.Params, "UNITS", {}))


#: A scalar quantity to SI (:func:`parasynth.study.space.quantity`), under its former name.
_q = quantity


def _q_nested(value, kind, path):
    if isinstance(value, (list, tuple)):
        return tuple(_q_nested(v, kind, f"{path}[{i}]") for i, v in enumerate(value))
    return _q(value, kind, path)


def _check_variant_choices(mech_cls, name, choices, path, single=None):
    """Choices of a described mechanism's variant (a structural choice such as ``platform``)
    must be among the variant's choices; the message names them."""
    var = getattr(mech_cls, "variants", {}).get(name)
    if var is None:
        return
    items = [(path, single)] if choices is None else [(f"{path}[{j}]", x) for j, x in enumerate(choices)]
    for where, x in items:
        try:
            var.coerce(x, where)
        except ValueError as e:
            raise StudyError(str(e)) from None


def resolve_study(data: dict, source: str | None = None) -> ResolvedStudy:
    """Validate names and units of a parsed study mapping and convert to SI."""
    spec = parse_spec(data)
    setup = None
    if spec.structure is not None:  # the structures' combined description (study.structure_space)
        if spec.mechanism is not None:
            raise StudyError("mechanism: give either mechanism: or structure:, not both")
        setup = resolve_structures(spec.structure)
        mech_name = setup.mechanism
        mech_cls = mechanism_class(mech_name)
    elif spec.mechanism is None:
        raise StudyError("mechanism: required key is missing (a registry name or a description file; or give "
                         "structure: to search the structure too)")
    else:
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
    study_task = None
    if spec.task is not None:
        base_dir = Path(source).parent if source else None
        task_map = _absolute_files(spec.task, base_dir)
        try:
            study_task = Task.from_mapping(task_map, base_dir=base_dir, where="task")
        except TaskError as e:
            raise StudyError(str(e)) from None
        if task_map != spec.task:  # recorded with absolute paths, so that run copies still find the files
            spec = spec.model_copy(update={"task": task_map})
        kinds.update(TASK_VARIABLES)
        params = params + list(TASK_VARIABLES)

    def check_param(name, path):
        if name.startswith("task.") and study_task is None and name in TASK_VARIABLES:
            raise StudyError(f"{path}: {name!r} is a variable of the study's task; give a task: section")
        if name not in params:
            raise StudyError(f"{path}: {name!r} is not a parameter of {spec.mechanism or 'the structures'}; valid: "
                             f"{', '.join(params)}")

    fixed = {}
    for k, v in spec.fixed.items():
        check_param(k, f"fixed.{k}")
        fixed[k] = _q_nested(v, kinds.get(k), f"fixed.{k}")
        _check_variant_choices(mech_cls, k, None, f"fixed.{k}", single=fixed[k])

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
            _check_variant_choices(mech_cls, v.name, choices, f"{path}.choices")
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
    variables = _resolve_when(spec.variables, variables)
    if setup is not None:
        variables = structure_variables(setup, variables)
        seen = {v.name for v in variables}
    space = DesignSpace(variables)  # checks the conditions for cycles

    def resolve_settings(measure, settings, path):
        # one validator per measure (its declared settings); the model-dependent kinds are
        # resolved here, against the mechanism's task coordinates and pose constraints
        resolve = {
            "ranges": lambda val, where: _resolve_ranges(val, mech_cls, where, task),
            "pose_constraints": lambda val, where: _check_pose_constraints(val, where, pose_constraints),
            "pose": _resolve_pose,
            "task": _refuse_task_setting,
        }
        if study_task is None and not measure.runs_without_task(mech_name):
            raise StudyError(f"{path.rsplit('.', 1)[0]}.name: {measure.name!r} is a task measure: give the study a "
                             "task: section (docs/tasks.md)")
        try:
            return measure.check_settings(settings, path, resolve)
        except SettingError as e:
            raise StudyError(str(e)) from None

    def _refuse_task_setting(val, where):
        raise StudyError(f"{where}: the task of a study is its task: section; leave {where.rsplit('.', 1)[-1]} out "
                         "of the settings")

    def _resolve_pose(val, where):
        if not isinstance(val, dict):
            raise StudyError(f"{where}: give a mapping {{coordinate: value with unit}}, e.g. {{alpha: 0 deg}}")
        return {c: _pose_value(c, x, f"{where}.{c}", task, mech_cls) for c, x in val.items()}

    # The model's task coordinates and pose constraints (from a model built with the fixed
    # parameters; a model that cannot be built is reported by check_study).
    task, pose_constraints = _model_names(mech_cls, fixed)
    ev_names, added = _split_pose_constraints(spec.evaluation.constraints, pose_constraints)
    if pose_constraints is not None and added:
        pose_constraints = tuple(pose_constraints) + tuple(a["name"] for a in added)
    reserved = set(RESERVED_COLUMNS) | set(seen) | set(spec.tied)

    def check_label(label, path, where):
        if not isinstance(label, str) or not label.strip():
            raise StudyError(f"{where}: give a non-empty column name")
        if label in reserved:
            what = "a design variable" if label in seen or label in spec.tied else "a column of the results table"
            raise StudyError(f"{where}: column name {label!r} is {what}; give a distinct label (reserved columns: "
                             f"{', '.join(RESERVED_COLUMNS)})")
        if label in labels:
            raise StudyError(f"{where}: column name {label!r} is used twice; give a distinct label")
        for suffix in DERIVED_SUFFIXES:
            if label.endswith(suffix) and label[: -len(suffix)] in labels:
                raise StudyError(f"{where}: column name {label!r} clashes with the derived column of "
                                 f"{label[: -len(suffix)]!r}; give a distinct label")
            if label + suffix in labels:
                raise StudyError(f"{where}: the derived column {label + suffix!r} of {label!r} is already a column; "
                                 f"give a distinct label")
        labels.add(label)

    actuators = []  # what the actuators are, computed on the first measure whose unit follows them

    def measure_kind(m, settings, path):
        kind = m.kind_of(settings)
        if kind not in ACTUATOR_KINDS:
            return kind
        if not actuators:
            actuators.append(actuators_of(mech_cls, setup))
        try:
            return actuator_unit_kind(kind, actuators[0], f"{path}.name: {m.name!r}")
        except ValueError as e:
            raise StudyError(str(e)) from None

    objectives, labels = [], set()
    for i, o in enumerate(spec.objectives):
        path = f"objectives[{i}]"
        if o.name not in OBJECTIVES:
            raise StudyError(f"{path}.name: unknown objective {o.name!r}; valid: {', '.join(OBJECTIVES)}")
        m = get_measure(o.name)
        if m.models is not None and mech_name not in m.models:
            raise StudyError(f"{path}.name: objective {o.name!r} applies to {list(m.models)}, not {spec.mechanism!r}")
        label = o.label if o.label is not None else o.name
        check_label(label, path, f"{path}.label" if o.label is not None else f"{path}.name")
        rb = _resolve_robust(o.robust, o.name, mech_cls, f"{path}.robust", constraint=False)
        settings = resolve_settings(m, o.settings, f"{path}.settings")
        measure_kind(m, settings, path)  # a largest actuator force over linear actuators and cranks: refused
        objectives.append(Objective(o.name, label, o.goal or m.sense, settings, rb))

    constraints = []
    for i, c in enumerate(spec.constraints):
        path = f"constraints[{i}]"
        if c.name not in OBJECTIVES:
            raise StudyError(f"{path}.name: unknown measure {c.name!r}; valid: {', '.join(OBJECTIVES)}")
        m = get_measure(c.name)
        if c.min is None and c.max is None:
            raise StudyError(f"{path}: give a bound: min and/or max")
        settings = resolve_settings(m, c.settings, f"{path}.settings")
        kind = measure_kind(m, settings, path)  # stiffness_min: follows settings.part; N or N*m: the actuators
        lo = _bound(c.min, kind, f"{path}.min", m, settings) if c.min is not None else None
        hi = _bound(c.max, kind, f"{path}.max", m, settings) if c.max is not None else None
        if kind is None:
            for nm, x in (("min", lo), ("max", hi)):
                if x is not None:
                    if not is_real_number(x):
                        raise StudyError(f"{path}.{nm}: {c.name!r} is dimensionless here ({m.unit}); give a number, "
                                         f"got {x!r}")
                    if not math.isfinite(x):
                        raise StudyError(f"{path}.{nm}: must be a finite number, got {x!r}")
            lo = float(lo) if lo is not None else None
            hi = float(hi) if hi is not None else None
        if lo is not None and hi is not None and lo > hi:
            raise StudyError(f"{path}: min ({c.min}) is above max ({c.max}); no design can be feasible")
        if m.models is not None and mech_name not in m.models:
            raise StudyError(f"{path}.name: measure {c.name!r} applies to {list(m.models)}, not {spec.mechanism!r}")
        label = c.label if c.label is not None else c.name
        check_label(label, path, f"{path}.label" if c.label is not None else f"{path}.name")
        rb = _resolve_robust(c.robust, c.name, mech_cls, f"{path}.robust", constraint=True)
        prob = c.robust.probability if c.robust is not None else None
        if prob is not None and lo is not None and hi is not None:
            raise StudyError(f"{path}.robust.probability: a chance constraint takes one bound, min or max")
        constraints.append(DesignConstraint(c.name, label, lo, hi, settings, rb, None if prob is None else float(prob)))

    ev = spec.evaluation
    if spec.structure is not None and not any(c.name == "home_singularity_margin" for c in constraints):
        # a study over structures compares designs that pass the same singularity floor: every design is
        # controlled at its home pose with margin >= evaluation.singularity_floor (docs/structures.md)
        check_label(STRUCTURE_FLOOR_LABEL, "constraints", "constraints (the structure study's home floor)")
        constraints.append(DesignConstraint("home_singularity_margin", STRUCTURE_FLOOR_LABEL,
                                            float(ev.singularity_floor), None, {}))
    ranges = _resolve_ranges(ev.ranges, mech_cls, "evaluation.ranges", task) if ev.ranges is not None else None
    fixed_pose = {}
    for k, v in ev.fixed_pose.items():
        fixed_pose[k] = _pose_value(k, v, f"evaluation.fixed_pose.{k}", task, mech_cls)
        if ranges and k in ranges:
            raise StudyError(f"evaluation.fixed_pose.{k}: {k!r} is also sampled in evaluation.ranges; give each "
                             f"coordinate in one of them")
    ev_constraints = None
    if ev_names is not None:
        ev_constraints = _check_pose_constraints(ev_names, "evaluation.constraints", pose_constraints)
        if added and ev_constraints:
            ev_constraints += [a["name"] for a in added]
        elif added:  # added constraints only: all of the model's are kept
            ev_constraints = None
    evaluation = dict(method=ev.method, n=ev.samples, seed=ev.seed, ranges=ranges,
                      fixed=fixed_pose or None, constraints=ev_constraints, added_constraints=tuple(added),
                      final_samples=ev.final_samples, final_repeats=ev.final_repeats, final_top=ev.final_top,
                      engine=ev.engine, singularity_floor=float(ev.singularity_floor),
                      verify_designs=ev.verify_designs)

    opt = spec.optimizer
    plugin = opt.plugin
    if opt.algorithm is not None and opt.algorithm not in plugin.algorithms:
        raise StudyError(f"optimizer.algorithm: {opt.algorithm!r} is not available for {opt.kind}; allowed: "
                         f"{', '.join(plugin.algorithms)}")
    plugin.check(opt, variables, objectives, space)
    if opt.designs:
        if len(opt.designs) > MAX_DESIGNS:
            raise StudyError(f"optimizer.designs: {len(opt.designs)} designs; the maximum is {MAX_DESIGNS}")
        for j, d in enumerate(opt.designs):
            space.parse(d, f"optimizer.designs[{j}]")

    reference = None
    ref_label = ref_source = None
    if spec.reference is not None:
        reference = {}
        for k, v in spec.reference.items():
            if k in REFERENCE_TEXT_KEYS:
                if not isinstance(v, str) or not v.strip() or "\n" in v.strip():
                    raise StudyError(f"reference.{k}: give one line of text, e.g. {REFERENCE_TEXT_KEYS[k]!r}, "
                                     f"got {v!r}")
                if k == "label":
                    ref_label = " ".join(v.split())
                else:
                    ref_source = " ".join(v.split())
                continue
            check_param(k, f"reference.{k}")
            reference[k] = _q_nested(v, kinds.get(k), f"reference.{k}")

    if opt.start:
        byname = {v.name: v for v in variables}
        for k, x in opt.start.items():
            where = f"optimizer.start.{k}"
            if k not in byname:
                raise StudyError(f"{where}: not a design variable; variables: {', '.join(byname) or '(none)'}")
            v = byname[k]
            val = space.parse_value(k, x, where)
            if v.low is not None and is_real_number(val) and not v.low <= val <= v.high:
                raw = next((r for r in spec.variables if r.name == v.name), None)  # the unit the file uses
                u = (raw and (written_unit(raw.low, v.kind) or written_unit(raw.high, v.kind))) or unit_for_kind(v.kind)
                raise StudyError(f"{where}: {x!r} is outside the variable's bounds [{fmt_quantity(v.low, u)}, "
                                 f"{fmt_quantity(v.high, u)}]")

    if opt.storage is not None and "://" not in opt.storage and not opt.storage.startswith("journal:"):
        raise StudyError(f"optimizer.storage: {opt.storage!r} is neither a URL (postgresql://user:password@host/db, "
                         f"sqlite:///FILE) nor a journal file (journal:FILE)")
    if spec.output is not None and (not spec.output.strip() or "\x00" in spec.output):
        raise StudyError("output: give a run directory (e.g. runs/my_study) or leave the key out for runs/<name>/")

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

    if setup is not None:
        check_structure_optimizer(opt)
        choices = next(v.choices for v in variables if v.name == STRUCTURE)
        check_halving(spec.structure, opt, choices, int(opt.n_trials or OPTUNA_TRIALS))
    check_polish(opt, plugin, variables, constraints, setup is not None,
                 (getattr(opt, plugin.budget_key) or plugin.default_budget) if plugin.budget_key else None)
    return ResolvedStudy(spec, mech_name, fixed, tuple(variables), tuple(objectives), tuple(constraints),
                         evaluation, opt, reference, source, tied, ref_label, ref_source, setup, study_task)


def _bound(value, kind, path, measure, settings):
    """A constraint's bound in SI; for a measure whose unit follows a setting (``stiffness_min``'s
    ``part``) a bound in the other setting's unit is refused naming both."""
    try:
        return _q(value, kind, path)
    except StudyError as e:
        setting = measure.kind_setting()
        if setting is None:
            raise
        chosen = settings.get(setting, measure.params[setting].default)
        wants = si_unit(kind)
        for other, k in measure.kind_by[1].items():
            if k != kind and isinstance(value, str):
                try:
                    parse_quantity(value, k, path)
                except QuantityError:
                    continue
                raise StudyError(f"{path}: {value!r} is in {si_unit(k)}, the unit of {setting}: {other}; with "
                                 f"settings.{setting}: {chosen} give the bound in {wants}, e.g. "
                                 f"'{_number_of(value)} {wants}'") from None
        raise StudyError(f"{e} (the unit follows settings.{setting}: {chosen})") from None


def _number_of(value: str) -> str:
    m = re.match(r"\s*([-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?)", value)
    return m.group(1) if m else "1"


#: Text keys of ``reference`` beside the parameter values, with an example each.
REFERENCE_TEXT_KEYS = {"label": "the paper's design", "source": "Wang, Lyu & Liu 2021, Table 2"}


def _resolve_when(specs, variables) -> list:
    """The variables with their ``when`` conditions resolved: each names another categorical
    variable and some of its choices (with units, as the choices)."""
    byname = {v.name: v for v in variables}
    out = []
    for i, (vs, var) in enumerate(zip(specs, variables)):
        if not vs.when:
            out.append(var)
            continue
        conds = []
        for parent, choices in vs.when.items():
            where = f"variables[{i}].when.{parent}"
            if parent == var.name:
                raise StudyError(f"{where}: a variable cannot depend on itself")
            if parent not in byname:
                raise StudyError(f"{where}: not a design variable; variables: {', '.join(byname)}")
            p = byname[parent]
            if p.type != "categorical":
                raise StudyError(f"{where}: {parent!r} is {p.type}; a condition names a categorical variable")
            if not isinstance(choices, list) or not choices:
                raise StudyError(f"{where}: give a non-empty list of choices of {parent!r}")
            vals = []
            for j, x in enumerate(choices):
                val = quantity(x, p.kind, f"{where}[{j}]") if p.kind else x
                if val not in p.choices:
                    raise StudyError(f"{where}[{j}]: {x!r} is not a choice of {parent!r}; choices: "
                                     f"{', '.join(str(c) for c in p.choices)}")
                vals.append(val)
            conds.append((parent, tuple(vals)))
        out.append(dataclasses.replace(var, when=tuple(conds)))
    return out


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


def _resolve_ranges(val, mech_cls, path, task=None) -> dict:
    if not isinstance(val, dict) or not val:
        raise StudyError(f"{path}: give a non-empty mapping {{coordinate: [low, high]}} with units, e.g. "
                         f"{{z: [600 mm, 900 mm]}} (leave the key out for the model's default ranges)")
    out = {}
    for k, pair in val.items():
        if task is not None and k not in task:
            raise StudyError(f"{path}.{k}: {k!r} is not a task coordinate of the model; valid: {', '.join(task)}")
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise StudyError(f"{path}.{k}: give [low, high] with units, got {pair!r}")
        kind = "angle" if k in _angular(mech_cls) else "length"
        lo, hi = (_q(x, kind, f"{path}.{k}[{j}]") for j, x in enumerate(pair))
        if not lo < hi:
            raise StudyError(f"{path}.{k}: empty or inverted range [{pair[0]}, {pair[1]}]")
        out[k] = (lo, hi)
    return out


_MODEL_NAMES: dict = {}


def _model_names(mech_cls, fixed) -> tuple[tuple, tuple | None]:
    """Task coordinates and pose-constraint names of the model (None: unknown, not checked)."""
    try:
        key = (mech_cls, tuple(sorted(fixed.items())))
        hash(key)
    except TypeError:
        key = None
    if key is not None and key in _MODEL_NAMES:
        return _MODEL_NAMES[key]
    out = _model_names_uncached(mech_cls, fixed)
    if key is not None:
        if len(_MODEL_NAMES) > 64:
            _MODEL_NAMES.clear()
        _MODEL_NAMES[key] = out
    return out


def _model_names_uncached(mech_cls, fixed) -> tuple[tuple, tuple | None]:
    try:
        mech = mech_cls(mech_cls.Params(**dict(fixed)))
    except Exception:
        try:
            mech = mech_cls(mech_cls.Params())
        except Exception:
            return _task_coordinates(mech_cls, fixed), None
    try:
        cons = tuple(mech.constraints)
    except Exception:
        cons = None
    return tuple(mech.task_coordinates), cons


def _pose_value(k, v, where, task, mech_cls) -> float:
    if k not in task:
        raise StudyError(f"{where}: {k!r} is not a task coordinate of the model; valid: {', '.join(task)}")
    return _q(v, "angle" if k in _angular(mech_cls) else "length", where)


#: Types of the pose constraints a study may add in evaluation.constraints, with their keys.
ADDED_POSE_CONSTRAINTS = {"singularity_margin": ("type", "name", "min")}


def _split_pose_constraints(val, known) -> tuple[list | None, list[dict]]:
    """evaluation.constraints as (the names of the model's constraints, or None when the key is
    left out; the added constraints as {type, name, min} with min in SI)."""
    if val is None:
        return None, []
    names, added = [], []
    taken = set(known or ())
    for j, item in enumerate(val):
        where = f"evaluation.constraints[{j}]"
        if isinstance(item, str):
            names.append(item)
            continue
        unknown = sorted(set(item) - set(ADDED_POSE_CONSTRAINTS["singularity_margin"]))
        if item.get("type") not in ADDED_POSE_CONSTRAINTS:
            raise StudyError(f"{where}.type: an added pose constraint needs type: singularity_margin, got "
                             f"{item.get('type')!r}")
        if unknown:
            raise StudyError(f"{where}: unknown key {unknown[0]!r}; allowed: type, name, min")
        if "min" not in item:
            raise StudyError(f"{where}.min: required (the floor of the singularity margin, e.g. 0.02)")
        lo = item["min"]
        if not is_real_number(lo) or not 0.0 <= float(lo) < 1.0:
            raise StudyError(f"{where}.min: the singularity margin is a normalised singular value; give a plain "
                             f"number in [0, 1), got {lo!r}")
        name = item.get("name", "singularity_margin")
        if not isinstance(name, str) or not name.strip():
            raise StudyError(f"{where}.name: give a non-empty constraint name")
        if name in taken:
            raise StudyError(f"{where}.name: {name!r} is already a pose constraint of the model or of the study; give "
                             f"the added constraint another name")
        taken.add(name)
        added.append({"type": item["type"], "name": name, "min": float(lo)})
    return names, added


def _check_pose_constraints(val, where, known) -> list:
    names = [val] if isinstance(val, str) else val
    if not isinstance(names, list) or not all(isinstance(x, str) for x in names):
        raise StudyError(f"{where}: give a list of pose constraint names" +
                         (f"; valid: {', '.join(known)}" if known else ""))
    if known is not None:
        for j, x in enumerate(names):
            if x not in known:
                raise StudyError(f"{where}[{j}]: {x!r} is not a pose constraint of the model; valid: "
                                 f"{', '.join(known) or '(none)'}")
    return list(names)


# -- checks that build designs ------------------------------------------------------------------
#: Corners of the variable box built by :func:`check_study` (a deterministic subset beyond).
MAX_CORNERS = 64
#: Workspace samples of the probe evaluation of each measure in :func:`check_study`.
PROBE_SAMPLES = 256


def _fmt_si(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, tuple):
        return "(" + ", ".join(_fmt_si(x) for x in v) + ")"
    return repr(v)


def check_study(study: ResolvedStudy, *, measures: bool = True, max_corners: int = MAX_CORNERS,
                probe_samples: int = PROBE_SAMPLES, stats: dict | None = None,
                warnings: list | None = None) -> list[str]:
    """Problems that would make designs of ``study`` fail when it runs, each with its key path.

    Builds the mechanism with each ``fixed`` and ``reference`` value and each variable's
    bounds, values and choices alone (naming the key that is at fault), then the reference
    design (or the centre of the variable box), up to ``max_corners`` corners of the box and
    every listed design (``optimizer.designs``); with ``measures`` it evaluates every objective
    and design constraint once on the reference design with ``probe_samples`` workspace samples
    and the NumPy reference engine (nothing waits for compilation), so that a setting the
    measure rejects is reported here and not as a failure of every design. An empty list means
    none was found. A model whose designs are valid at the corners may still be invalid inside
    the box (a non-convex parameter set); such designs are recorded as failed by the run, with
    their reason. ``stats``, when given, receives the
    counts of what was checked (``designs``, ``corners``, ``corners_built``, ``measures``).

    ``warnings``, when given, receives what is accepted but doubtful, one line each: a box some
    of whose corners cannot be built (the share that builds and one failing corner, in the
    study's units; the box is refused only when no corner builds and neither does its centre),
    and lengths far from the mechanism's scale (:func:`parasynth.study.magnitudes.scale_warnings`).
    """
    problems: list[str] = []
    stats = {} if stats is None else stats
    stats.update(designs=0, corners=0, corners_built=0, measures=0)
    warnings = [] if warnings is None else warnings
    warnings += scale_warnings(study)
    mech = study.mechanism

    def try_build(params):
        try:
            return with_pose_constraints(study, load_mechanism(mech, **params)), None
        except Exception as e:  # every model error is a problem of the file
            return None, f"{type(e).__name__}: {e}" if not isinstance(e, ValueError) else str(e)

    for k, v in study.fixed.items():
        _, err = try_build({k: v})
        if err:
            problems.append(f"fixed.{k}: {err}")
    if problems:
        return problems
    for k, v in (study.reference or {}).items():
        if k in study.fixed:
            continue
        _, err = try_build({**study.fixed, k: v})
        if err:
            problems.append(f"reference.{k}: {err}")
    if problems:
        return problems
    given = {v.name: v for v in study.spec.variables}
    for var in study.variables:
        path = study.variable_path(var.name)
        probes = []
        if var.low is not None:
            probes += [(f"{path}.low", var.low), (f"{path}.high", var.high)]
        for key, seq in (("values", var.values), ("choices", var.choices)):
            if seq and not (key == "values" and var.low is not None and var.values is not None
                            and given[var.name].values is None):
                probes += [(f"{path}.{key}[{j}]", x) for j, x in enumerate(seq)]
        for where, x in probes:
            _, err = try_build(design_params(study, {var.name: x}))
            if err:
                problems.append(f"{where}: {err}")
                break
    if problems:
        return problems

    # The reference design (or the box centre), then the corners of the box.
    if study.reference is not None:
        base = dict(study.reference)
        base_where = "reference"
    else:
        base = box_centre(study)
        base_where = "variables (the centre of the box)"
    base_mech, err = try_build(design_params(study, base))
    if err:
        problems.append(f"{base_where}: the design {_design_str(study, base)} cannot be built: {err}")
    else:
        problems += [f"mechanism: {why} (design {_design_str(study, base)})"
                     for why in degenerate_geometry(base_mech, study.evaluation.get("ranges"))]
    axes = []
    for v in study.variables:
        if v.low is not None and v.high is not None and v.type != "categorical":
            axes.append((v.name, (v.low, v.high)))
        elif v.values:
            axes.append((v.name, (min(v.values), max(v.values)) if all(is_real_number(x) for x in v.values)
                         else tuple(v.values)))
        elif v.choices:
            axes.append((v.name, tuple(v.choices)))
    combos = list(itertools.islice(itertools.product(*[vals for _, vals in axes]), 100_000))
    if len(combos) > max_corners:
        step = len(combos) / max_corners
        combos = [combos[int(j * step)] for j in range(max_corners - 1)] + [combos[-1]]
    bad = []
    stats["corners"] = len(combos)
    stats["designs"] = 1 + len(combos) + len(study.optimizer.designs or ())
    for combo in combos:
        d = dict(zip([a for a, _ in axes], combo))
        _, err = try_build(design_params(study, d))
        if err:
            bad.append((d, err))
    stats["corners_built"] = len(combos) - len(bad)
    if bad and study.structures is None:  # structures differ in where they can be built: their
        # designs that cannot are recorded as failed, with the reason, per structure in the report
        refused, msg = _box_check(study, combos, bad, try_build)
        (problems if refused else warnings).append(msg)
    for j, d in enumerate(study.optimizer.designs or ()):
        dd = study.space.parse(d, f"optimizer.designs[{j}]")
        _, err = try_build(design_params(study, dd))
        if err:
            problems.append(f"optimizer.designs[{j}]: the design cannot be built: {err}")
    if not measures or base_mech is None:
        return problems

    n = min(int(study.evaluation["n"]), probe_samples)
    sample = evaluation_sample(study, n=n)
    items = [(f"objectives[{i}]", o) for i, o in enumerate(study.objectives)]
    items += [(f"constraints[{i}]", c) for i, c in enumerate(study.constraints)]
    stats["measures"] = len(items)
    for where, item in items:
        m = get_measure(item.name)
        try:
            with numpy_reference():  # a probe: no wait for a cold compile
                m(base_mech, **measure_arguments(study, item.name, item.settings, sample, pinned=("n",)))
        except KeyboardInterrupt:
            raise
        except Exception as e:
            msg = str(e) if isinstance(e, ValueError) else f"{type(e).__name__}: {e}"
            named = [k for k in item.settings if re.search(rf"\b{re.escape(k)}\b", msg)]
            if len(named) == 1:  # the message names the setting at fault
                where = f"{where}.settings.{named[0]}"
            problems.append(f"{where} ({item.label}): measure {item.name!r} fails on the {base_where.split(' ')[0]} "
                            f"design with these settings: {msg}")
        if getattr(item, "robust", None) is not None:
            try:
                item.robust.check(base_mech)
            except KeyboardInterrupt:
                raise
            except Exception as e:
                msg = str(e) if isinstance(e, ValueError) else f"{type(e).__name__}: {e}"
                problems.append(f"{where}.robust.tolerances ({item.label}): the scatter cannot be applied to the "
                                f"{base_where.split(' ')[0]} design: {msg}")
    return problems


def _box_check(study, combos, bad, try_build) -> tuple[bool, str]:
    """(refused, message) on a variable box some of whose corners cannot be built: a warning
    with the share that builds and one failing corner, refused when no corner builds and
    neither does the box centre."""
    d, err = bad[0]
    n, ok = len(combos), len(combos) - len(bad)
    corner = _design_str(study, d)
    if ok:
        return False, (f"variables: {ok} of {n} corners of the variable box ({100.0 * ok / n:.0f} %) can be "
                       f"built; the corner {corner} cannot: {err}; designs that cannot be built are recorded as "
                       f"failed")
    centre = box_centre(study)
    if try_build(design_params(study, centre))[1] is None:
        return False, (f"variables: none of the {n} corners of the variable box can be built, its centre "
                       f"{_design_str(study, centre)} can; e.g. the corner {corner} cannot: {err}; designs that "
                       f"cannot be built are recorded as failed")
    return True, (f"variables: no corner of the variable box can be built ({n} checked), nor its centre; e.g. the "
                  f"corner {corner}: {err}; narrow the bounds")


def _design_str(study, d: dict) -> str:
    """A design in the units the study file writes its variables in (``{link_length=160 mm}``)."""
    try:
        return fmt_study_design(study, d)
    except Exception:  # a value the display cannot format: SI, as it is
        return "{" + ", ".join(f"{k}={_fmt_si(v)}" for k, v in d.items()) + "}"


# -- the polish (optimizer.polish; the run is parasynth.study.polish) ---------------------------------
def check_polish(opt, plugin, variables, constraints, structures: bool, total: int | None) -> None:
    """:class:`StudyError` naming ``optimizer.polish.*`` when the polish cannot run: after a
    local or listing optimiser, BOBYQA with design constraints, no continuous variable, a study
    over structures, or a budget not below the study's (``total``)."""
    pol = opt.polish
    if pol is None:
        return
    if not plugin.searches_globally(opt):
        alg = opt.algorithm or (plugin.algorithms or ("",))[0]
        raise StudyError(f"optimizer.polish: refines the result of a global optimiser; {opt.kind} {alg} is not "
                         f"one (use optuna, scipy or an NLopt GN_ algorithm), or leave polish out")
    if pol.method == "bobyqa" and constraints:
        raise StudyError(f"optimizer.polish.method: bobyqa takes no constraints and the study has "
                         f"{len(constraints)} ({', '.join(c.label for c in constraints)}); use cobyla")
    if not any(v.type == "continuous" and v.low is not None for v in variables):
        raise StudyError("optimizer.polish: needs a continuous design variable with low/high to refine")
    if structures:
        raise StudyError("optimizer.polish: a study over structures is not polished; leave polish out")
    if total is not None and pol.budget >= total:
        raise StudyError(f"optimizer.polish.budget: {pol.budget} designs of a budget of {total}; give fewer than "
                         f"{total} (the global search gets the rest)")



# -- documentation of every key, for the JSON Schema and docs/study-format.md -------------------
# The text of each key is the description of its field in the models above; docs/study-format.md
# documents each key (a test checks it).


def _model_keys(model, prefix="") -> list[str]:
    out = []
    subs = {"variables": VariableSpec, "objectives": MeasureRef, "constraints": ConstraintRef,
            "evaluation": EvaluationSpec, "optimizer": OptimizerSpec, "structure": StructureSpec}
    for name in model.model_fields:
        key = f"{prefix}{name}"
        out.append(key)
        if model is StudySpec and name in subs:
            sep = "[]." if name in ("variables", "objectives", "constraints") else "."
            out += _model_keys(subs[name], f"{key}{sep}")
        elif model in (MeasureRef, ConstraintRef) and name == "robust":
            out += _model_keys(RobustSpec, f"{key}.")
        elif model is OptimizerSpec and name == "polish":
            out += _model_keys(PolishSpec, f"{key}.")
    return out


def study_keys() -> list[str]:
    """Every key path of the study format (``variables[].low``, ``evaluation.samples``, ...)."""
    return _model_keys(StudySpec)


def key_docs() -> dict[str, str]:
    """{key path: description} of every key of the study format (``[]`` marks the entries of a
    list): the fields' descriptions, and the keys of ``reference`` (:data:`REFERENCE_KEYS`)."""
    models = {"": StudySpec, "variables[].": VariableSpec, "objectives[].": MeasureRef,
              "constraints[].": ConstraintRef, "evaluation.": EvaluationSpec, "optimizer.": OptimizerSpec,
              "optimizer.polish.": PolishSpec, "structure.": StructureSpec, "objectives[].robust.": RobustSpec, "constraints[].robust.": RobustSpec}
    docs = {}
    for key in study_keys():
        prefix, _, leaf = key.rpartition(".")
        docs[key] = models[prefix + "." if prefix else ""].model_fields[leaf].description
    docs.update({f"reference.{k}": v for k, v in REFERENCE_KEYS.items()})
    return docs


#: {key path: description} of every key (:func:`key_docs`).
KEY_DOCS = key_docs()


def study_json_schema() -> dict:
    """The study file format as JSON Schema (draft 2020-12), from the pydantic models: each key's
    description is its field's."""
    schema = StudySpec.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema

