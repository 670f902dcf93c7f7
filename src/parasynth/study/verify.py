"""The one rule by which a design is verified before a study names it (docs/verification.md).

A run screens designs on one sample each; the design it recommends (the knee, the best design,
a structure study's winner, a robust study's pick) must hold its requirements beyond that one
sample. :func:`verify` checks a design's re-evaluations (one :class:`~parasynth.study.evaluate.Record`
per re-evaluation seed) against every design constraint of the study, with a tolerance that
follows how the measure's value depends on the points it is computed on
(:meth:`parasynth.measures.objectives.Measure.estimate_of`):

* ``statistic`` (a volume, a mean, an inner quantile, a robust statistic, a chance constraint's
  probability): the mean over the seeds passes within :data:`NOISE_Z` combined standard errors
  of its bound (the seeds' spread and, for a robust measure, the standard error of its scatter
  draws), but never more than :data:`STATISTIC_RTOL` of the bound's magnitude: a noisy estimate
  (two seeds far apart) does not buy a design its pass;
* ``extreme`` (a least or largest value over the points: a minimum over more samples only gets
  worse): the worst seed passes within :data:`EXTREME_RTOL` of the bound's magnitude;
* ``grid`` (usable workspace, singularity-free radius, an inscribed box of the usable grid):
  exact on its grid, so the study's own value is checked without tolerance (not resampled);
* ``exact`` (no sample: the home pose, a path): checked without tolerance.

Besides the study's constraints, every design must be controlled at its home pose: the
singularity margin (:meth:`parasynth.model.mechanism.Mechanism.singularity_margin`, the least
singular value of the normalised wrench system) at home at least :data:`SINGULARITY_FLOOR`
(defined in :mod:`parasynth.measures.usable`, the one floor of parasynth, re-exported here;
``evaluation.singularity_floor`` of a study overrides it).
A margin of ~1e-16 is a layout singular by symmetry (a regular pentagon of five limbs); the
shipped paper designs have 0.016 (2-RPU&2-SPS) to 0.59 (6-UPS).

:class:`Verification` holds every :class:`Check` (requirement, kind, value, bound, tolerance,
where, passed); :meth:`Verification.reason` names what failed and where.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..measures.display import fmt_number, fmt_quantity, quantity_unit
from ..measures.objectives import get as get_measure
from ..measures.task import task_evaluation, task_margin_min
from ..measures.usable import SINGULARITY_FLOOR  # the one floor (a study's evaluation.singularity_floor overrides it)
from .design import design_mechanism, design_task, evaluation_sample, measure_arguments

__all__ = ["Check", "Verification", "verify", "estimate_of", "home_margin_check", "SINGULARITY_FLOOR", "EXTREME_RTOL",
           "NOISE_Z", "STATISTIC_RTOL", "VERIFY_LIMIT"]

#: Tolerance of an ``extreme`` measure (a least or largest value over the points), as a share of
#: its bound's magnitude: the worst re-evaluation seed may fall short of the bound by this much.
EXTREME_RTOL = 0.05
#: Tolerance of a ``statistic``, in combined standard errors.
NOISE_Z = 2.0
#: The most a ``statistic``'s tolerance may be, as a share of its bound's magnitude (a bound of 0:
#: no cap).
STATISTIC_RTOL = 0.05
#: How many designs beyond the final candidates a run re-evaluates at most while it looks for one
#: that passes.
VERIFY_LIMIT = 10


@dataclass(frozen=True)
class Check:
    """One requirement of a design checked on its re-evaluation.

    ``margin``: how far ``value`` lies inside its bound (>= 0 inside), in the value's unit;
    ``tolerance`` (>= 0): how far outside it may lie and still pass."""

    requirement: str  # the constraint's label, or "singularity margin at home"
    kind: str  # statistic | extreme | grid | exact | floor | task
    value: float
    bound: str  # ">= 2e+06" as the study states it, SI
    margin: float
    tolerance: float
    stderr: float = math.nan
    where: str = ""
    label: str = ""  # the column (constraint label) or "" for the singularity floor

    @property
    def passed(self) -> bool:
        return bool(np.isfinite(self.margin)) and self.margin >= -self.tolerance

    def describe(self, study=None) -> str:
        """``k_min = 2.4e+04 N/m, bound >= 2e+06 N/m, tolerance 1e+05 N/m (extreme, worst of 3
        seeds: seed 1002)``, in the study's display units when ``study`` is given."""
        unit = quantity_unit(study, self.label) if study is not None and self.label else None
        fq = (lambda x: fmt_quantity(x, unit)) if unit is not None else fmt_number
        side, _, num = self.bound.partition(" ")
        try:
            bound = f"{side} {fq(float(num))}"
        except ValueError:
            bound = self.bound
        val = "not computable" if not np.isfinite(self.value) else fq(self.value)
        tol = (f", tolerance {fq(self.tolerance)}" if self.tolerance > 0 and self.kind in ("statistic", "extreme", "task")
               else "")
        se = f" ± {fq(self.stderr)}" if np.isfinite(self.stderr) and self.kind == "statistic" else ""
        if self.kind in ("grid", "exact", "floor"):
            return f"{self.requirement} = {val}, required {bound} ({self.where or self.kind})"
        where = f"; {self.where}" if self.where else ""
        return f"{self.requirement} = {val}{se}, required {bound}{tol} ({self.kind}{where})"


@dataclass(frozen=True)
class Verification:
    """The checks of one design. ``error``: why its re-evaluation could not run (then it fails)."""

    checks: tuple[Check, ...] = ()
    error: str = ""
    samples: int = 0
    seeds: tuple[int, ...] = field(default_factory=tuple)

    @property
    def passed(self) -> bool:
        return not self.error and all(c.passed for c in self.checks)

    @property
    def failed(self) -> list[Check]:
        return [c for c in self.checks if not c.passed]

    def reason(self, study=None) -> str:
        """``verified`` or what failed: the failing checks, most violated first."""
        if self.error:
            return f"re-evaluation failed: {self.error}"
        if self.passed:
            return "verified"
        bad = sorted(self.failed, key=lambda c: (c.margin + c.tolerance) / (abs(c.tolerance) + 1e-300))
        return "failed: " + "; ".join(c.describe(study) for c in bad)


def estimate_of(item) -> str:
    """How an objective or constraint of a study depends on its points (the kinds of
    :meth:`~parasynth.measures.objectives.Measure.estimate_of`); a robust block makes any measure
    a ``statistic`` of its scatter draws."""
    if getattr(item, "robust", None) is not None:
        return "statistic"
    return get_measure(item.name).estimate_of(item.settings)


def _bound_text(c) -> str:
    if c.probability is not None:
        return f">= {c.probability!r}"
    if c.min is not None and c.max is not None:
        return f"in [{c.min!r}, {c.max!r}]"
    return f">= {c.min!r}" if c.min is not None else f"<= {c.max!r}"


def _bound_scale(c) -> float:
    vals = [abs(x) for x in (c.min, c.max) if x is not None]
    return max(vals) if vals else 0.0


def _constraint_check(study, c, records, screened: float | None) -> Check:
    kind = estimate_of(c)
    label = c.label
    seeds = [r.seed for r in records]
    n = len(records)
    where = f"{n} seed{'s' if n != 1 else ''} x {records[0].samples} samples" if n else ""
    if c.probability is not None:
        requirement = f"P({label} within its bound)"
    else:
        requirement = label
    if kind in ("grid", "exact"):
        v = screened if screened is not None and math.isfinite(screened) else (
            records[0].constraint_values.get(label, math.nan) if records else math.nan)
        slack = 1e-9 * max(1.0, _bound_scale(c))  # the rounding of the value, not a tolerance
        what = "exact on its grid: the study's own value" if kind == "grid" else "exact, no sample"
        return Check(requirement, kind, float(v), _bound_text(c), c.margin(v) if math.isfinite(v) else -math.inf,
                     slack, where=what, label=label)
    vals = np.array([r.constraint_values.get(label, math.nan) for r in records], float)
    if not n or not np.all(np.isfinite(vals)):
        bad = [s for s, x in zip(seeds, vals) if not math.isfinite(x)]
        return Check(requirement, kind, math.nan, _bound_text(c), -math.inf, 0.0,
                     where=f"not computable on seed {bad[0]}" if bad else "not re-evaluated", label=label)
    margins = np.array([c.margin(x) for x in vals])
    if kind == "extreme":
        i = int(np.argmin(margins))
        tol = EXTREME_RTOL * _bound_scale(c)
        return Check(requirement, kind, float(vals[i]), _bound_text(c), float(margins[i]), tol,
                     where=f"worst of {n} seed{'s' if n != 1 else ''} x {records[0].samples} samples: seed {seeds[i]}",
                     label=label)
    mean = float(vals.mean())
    se_seeds = float(vals.std(ddof=1) / math.sqrt(n)) if n > 1 else math.nan
    rse = [r.robust.get(label, {}).get("stderr") for r in records]
    rse = np.array([x for x in rse if x is not None and math.isfinite(x)], float)
    parts = [x for x in (se_seeds,) if math.isfinite(x)]
    if len(rse):
        parts.append(float(np.sqrt(np.mean(rse ** 2) / n)))
    se = float(math.sqrt(sum(x * x for x in parts))) if parts else math.nan
    tol = NOISE_Z * se if math.isfinite(se) else 0.0
    scale = c.probability if c.probability is not None else _bound_scale(c)
    capped = scale > 0 and tol > STATISTIC_RTOL * scale
    if capped:
        tol = STATISTIC_RTOL * scale
    how = (f", within {fmt_number(100 * STATISTIC_RTOL)} % of the bound (less than {fmt_number(NOISE_Z)} standard "
           "errors)" if capped else f", within {fmt_number(NOISE_Z)} standard errors" if tol > 0 else "")
    return Check(requirement, kind, mean, _bound_text(c), float(c.margin(mean)), tol, stderr=se,
                 where=f"mean of {where}{how}", label=label)


def home_margin_check(mech, floor: float = SINGULARITY_FLOOR) -> Check:
    """The singularity margin of ``mech`` at its home pose against ``floor``."""
    try:
        # one pose: the NumPy reference (the compiled path would compile a kernel for it on a cold cache)
        s = float(np.asarray(mech.singularity_margin(np.atleast_2d(mech.home), engine="numpy")).ravel()[0])
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as e:
        return Check("singularity margin at home", "floor", math.nan, f">= {floor!r}", -math.inf, 0.0,
                     where=f"not computable: {e}")
    where = "at the home pose" if math.isfinite(s) else "the home pose is not reachable"
    return Check("singularity margin at home", "floor", s, f">= {floor!r}", s - floor if math.isfinite(s) else -math.inf,
                 0.0, where=where)


def _uses_task(item) -> bool:
    return any(p.kind == "task" for p in get_measure(item.name).params.values())


def task_checks(study, values: dict, mech, floor: float = SINGULARITY_FLOOR) -> list[Check]:
    """The dense re-check of a study with a task (docs/verification.md): the design's task
    refined (:meth:`parasynth.Task.refined`: with a path its poses kept and the path at 10x the
    sample rate, else grid poses 3x per axis; :meth:`parasynth.Task.refinement` says which);
    every task constraint of the study on it, within :data:`EXTREME_RTOL` of its bound (a
    least or largest value over more poses only gets worse); the singularity margin at every
    feasible pose and path sample at least ``floor``; and the path followed without a
    singularity crossed or a change of assembly mode (:func:`parasynth.measures.task.path_continuity`)."""
    task = design_task(study, values)
    if task is None:
        return []
    dense = task.refined()
    n_poses = len(dense.poses)
    ev = task_evaluation(mech, dense, study.evaluation.get("constraints"), study.evaluation.get("engine", "compiled"))
    where = f"dense task: {n_poses} poses" + (f", path every {fmt_number(1000 * dense.trajectory.dt)} ms"
                                              if dense.trajectory is not None and dense.trajectory.limits is not None
                                              else "")
    out = []
    for c in study.constraints:
        if not _uses_task(c) or getattr(c, "robust", None) is not None:
            continue
        args = measure_arguments(study, c.name, c.settings, evaluation_sample(study), task=dense)
        v = float(get_measure(c.name)(mech, **args))
        tol = EXTREME_RTOL * _bound_scale(c)
        out.append(Check(f"{c.label} on the dense task", "task", v, _bound_text(c),
                         c.margin(v) if math.isfinite(v) else -math.inf, tol, where=where, label=c.label))
    m = float(task_margin_min(mech, task=dense))
    out.append(Check("singularity margin over the task", "floor", m, f">= {floor!r}",
                     m - floor if math.isfinite(m) else -math.inf, 0.0, where=where))
    cont = ev.continuity(floor=floor)
    if cont.first_break is None:
        skipped = "; " + cont.rule.split("; ", 1)[1] if "; " in cont.rule else ""
        out.append(Check("path continuity", "floor", 1.0, ">= 1.0", 0.0, 0.0,
                         where=where + ": followed to its end" + skipped))
    else:
        n = len(ev.path.X) if dense.trajectory is not None else len(ev.X)
        out.append(Check("path continuity", "floor", cont.first_break / n, ">= 1.0", cont.first_break / n - 1.0, 0.0,
                         where=f"{where}: breaks at sample {cont.first_break} of {n} ({cont.reason})"))
    return out


def verify(study, values: dict, records, screened: dict | None = None, mech=None,
           floor: float = SINGULARITY_FLOOR) -> Verification:
    """Verify the design ``values`` of ``study`` on its re-evaluations ``records`` (one
    :class:`~parasynth.study.evaluate.Record` per seed; may be empty when the study has only
    grid and exact constraints): every design constraint with the tolerance of its kind
    (module docstring), the values of ``grid`` and ``exact`` measures taken from ``screened``
    ({constraint label: value} of the run's own evaluation) when given, and the singularity
    margin at home above ``floor``. ``mech``: the built design (built here otherwise)."""
    records = list(records)
    bad = [r for r in records if r.status != "ok"]
    seeds = tuple(int(r.seed) for r in records)
    samples = int(records[0].samples) if records else 0
    if bad:
        return Verification((), error=f"seed {bad[0].seed}: {bad[0].error}", samples=samples, seeds=seeds)
    checks = [_constraint_check(study, c, records, (screened or {}).get(c.label)) for c in study.constraints]
    try:
        mech = mech if mech is not None else design_mechanism(study, dict(values))
    except (ValueError, ArithmeticError) as e:
        return Verification(tuple(checks), error=f"the design cannot be built: {e}", samples=samples, seeds=seeds)
    checks.append(home_margin_check(mech, floor))
    try:
        checks += task_checks(study, values, mech, floor)
    except (ValueError, ArithmeticError) as e:
        return Verification(tuple(checks), error=f"the dense task could not be evaluated: {e}", samples=samples,
                            seeds=seeds)
    return Verification(tuple(checks), samples=samples, seeds=seeds)
