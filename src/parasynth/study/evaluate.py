"""Evaluation of one design: build the mechanism, compute design constraints and objectives.

Each design is evaluated on one workspace sample (:func:`~parasynth.study.design.evaluation_sample`,
from the study's evaluation section) passed whole to every measure that samples the workspace,
with that measure's own validated settings (:func:`~parasynth.study.design.measure_arguments`).

A design that cannot be built (non-physical parameters) or whose measures raise is recorded
with ``status = "failed"`` and its error message; a design that violates a constraint is
recorded with ``feasible = False``; neither stops a run. A design of a task study that reaches
none of the task's required poses (none feasible: reachable with every pose constraint the task
measures use) is recorded as failed too (:attr:`Evaluator.require_reachable`), not as a design
whose task measures hold their vacuous worst values (docs/tasks.md).
"""

from __future__ import annotations

import math
import time
import traceback
from dataclasses import dataclass, field

from ..measures.objectives import get as get_measure
from ..measures.task import task_evaluation
from .design import design_mechanism, design_task, evaluation_sample, measure_arguments, measure_settings
from .spec import ResolvedStudy

__all__ = ["Record", "Evaluator", "RequirementError"]


class RequirementError(ValueError):
    """A design that cannot be evaluated on the study's task: it reaches none of its poses."""


@dataclass
class Record:
    """One evaluated design (SI values)."""

    values: dict
    objectives: dict = field(default_factory=dict)
    constraint_values: dict = field(default_factory=dict)
    margins: dict = field(default_factory=dict)
    status: str = "ok"  # ok | failed
    error: str = ""
    seed: int = 0
    samples: int = 0
    time_s: float = 0.0
    trial: int = -1
    source: str = "run"
    #: {label: {"nominal", "stderr", "statistic", "level", "samples", "probability"}} of each robust
    #: objective or constraint (parasynth.measures.robustness): the nominal value beside the robust one
    robust: dict = field(default_factory=dict)

    @property
    def feasible(self) -> bool:
        return self.status == "ok" and all(m >= 0 for m in self.margins.values())

    def to_dict(self) -> dict:
        return {
            "trial": self.trial, "source": self.source, "values": self.values, "objectives": self.objectives,
            "constraint_values": self.constraint_values, "margins": self.margins, "status": self.status,
            "feasible": self.feasible, "error": self.error, "seed": self.seed, "samples": self.samples,
            "time_s": self.time_s, **({"robust": self.robust} if self.robust else {}),
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Record":
        return cls(values=d["values"], objectives=d.get("objectives", {}), constraint_values=d.get("constraint_values", {}),
                   margins=d.get("margins", {}), status=d.get("status", "ok"), error=d.get("error", ""),
                   seed=d.get("seed", 0), samples=d.get("samples", 0), time_s=d.get("time_s", 0.0),
                   trial=d.get("trial", -1), source=d.get("source", "run"), robust=d.get("robust", {}))


def _frozen(v):
    """A hashable stand-in for a measure's argument ``v``: plain values by type and value,
    containers item by item, any other object by identity."""
    if isinstance(v, float):
        return ("float", v.hex())  # exactly: -0.0 is not 0.0, and a NaN is itself
    if v is None or isinstance(v, (bool, int, str)):
        return (type(v).__name__, v)
    if isinstance(v, (list, tuple)):
        return (type(v).__name__,) + tuple(_frozen(x) for x in v)
    if isinstance(v, dict):
        return ("dict",) + tuple(sorted((str(k), _frozen(x)) for k, x in v.items()))
    return ("id", id(v))


class Evaluator:
    """Evaluates designs of a resolved study with its evaluation settings.

    Design constraints are computed first, cheapest first; objectives after. With the study's
    fixed seed the same sample points serve every design (common random numbers)."""

    def __init__(self, study: ResolvedStudy, require_reachable: bool = True):
        self.study = study
        #: a design of a task study that reaches none of the task's poses is recorded as failed
        #: (RequirementError), its measures not computed
        self.require_reachable = bool(require_reachable)
        items = list(study.constraints) + list(study.objectives)
        #: the first task measure of the study (its constraints and engine select the poses)
        self._task_item = next((c for c in items if any(p.kind == "task" for p in get_measure(c.name).params.values())),
                               None)

    def settings_for(self, measure_name: str, own: dict, n: int | None = None, seed: int | None = None) -> dict:
        """Settings of a measure for this study in the older flat call form
        (:func:`~parasynth.study.design.measure_settings`)."""
        return measure_settings(self.study, measure_name, own, n, seed)

    def sample(self, n: int | None = None, seed: int | None = None):
        """The workspace sample of a design (:func:`~parasynth.study.design.evaluation_sample`),
        one object per (n, seed): a frozen value, made and checked once rather than per design."""
        kept = self.__dict__.setdefault("_samples", {})
        hit = kept.get((n, seed))
        if hit is None:
            hit = kept[(n, seed)] = evaluation_sample(self.study, n, seed)
        return hit

    def build(self, values: dict):
        return design_mechanism(self.study, values)

    def evaluate(self, values: dict, n: int | None = None, seed: int | None = None, trial: int = -1,
                 source: str = "run") -> Record:
        ev = self.study.evaluation
        rec = Record(values=dict(values), seed=ev["seed"] if seed is None else seed,
                     samples=ev["n"] if n is None else n, trial=trial, source=source)
        # n and seed of a re-evaluation win over a measure's own sample settings
        pinned = tuple(f for f, x in (("n", n), ("seed", seed)) if x is not None)
        t0 = time.perf_counter()
        try:
            sample = self.sample(n, seed)
            mech = self.build(values)
            task = design_task(self.study, values)  # one object per design: the task measures share its evaluation
            if self.require_reachable and task is not None and self._task_item is not None:
                self._check_reachable(mech, task, sample, pinned)
            cons, objs = self._arguments(sample, pinned, task)
            memo = {}  # a measure asked twice with the same arguments (a constraint and an objective)
            for c, args, key in cons:
                v = self._once(memo, c, mech, args, rec, bound=c.bound, probability=c.probability, key=key)
                rec.constraint_values[c.label] = v
                rec.margins[c.label] = c.margin(v) if math.isfinite(v) else -math.inf
            for o, args, key in objs:
                v = self._once(memo, o, mech, args, rec, key=key)
                if not math.isfinite(v):
                    raise FloatingPointError(f"objective {o.label!r} is not finite ({v})")
                rec.objectives[o.label] = v
        except KeyboardInterrupt:
            raise
        except Exception as e:  # recorded, the run continues
            rec.status = "failed"
            rec.error = f"{type(e).__name__}: {e}"
            rec.error_trace = traceback.format_exc(limit=3)
        rec.time_s = time.perf_counter() - t0
        return rec

    def _check_reachable(self, mech, task, sample, pinned) -> None:
        """RequirementError when ``mech`` reaches none of ``task``'s required poses (with the pose
        constraints and engine of the study's task measures: the evaluation they share)."""
        item = self._task_item
        args = measure_arguments(self.study, item.name, item.settings, sample, pinned, task)
        ev = task_evaluation(mech, task, args.get("constraints"), args.get("engine", "compiled"))
        if not ev.feasible.any():
            raise RequirementError(f"reaches none of the task's {task.n_poses} required poses (none reachable with "
                                   "every pose constraint met); its task measures would have no pose to hold on")

    def _arguments(self, sample, pinned: tuple, task):
        """([(constraint, arguments, memo key)], [(objective, arguments, memo key)]): the
        constraints cheapest first, each item's :func:`measure_arguments` and its :meth:`_once`
        key. The same for every design of one sample and the study's own task: kept for them
        (the arguments are only read)."""
        shared = task is None or task is getattr(self.study, "task", None)
        kept = self.__dict__.setdefault("_args", {})
        hit = kept.get((id(sample), pinned)) if shared else None
        if hit is not None and hit[0] is sample:
            return hit[1]

        def entry(item):
            args = measure_arguments(self.study, item.name, item.settings, sample, pinned, task)
            return item, args, self._memo_key(item, args)

        cons = sorted(self.study.constraints, key=lambda c: get_measure(c.name).cost != "cheap")
        out = ([entry(c) for c in cons], [entry(o) for o in self.study.objectives])
        if shared:
            if len(kept) >= 16:
                kept.clear()
            kept[(id(sample), pinned)] = (sample, out)  # the sample kept alive: its id stays its own
        return out

    @staticmethod
    def _memo_key(item, args):
        """The key of ``item`` with ``args`` in :meth:`_once` (None: not kept)."""
        if getattr(item, "robust", None) is not None:
            return None
        try:
            return (item.name, _frozen(args))
        except TypeError:
            return None

    @classmethod
    def _once(cls, memo: dict, item, mech, args, rec, bound=None, probability=None, key=False) -> float:
        """:meth:`_value`, computed once per design for a measure without a ``robust`` block
        asked again with the same arguments (the structure studies' margin quantile is both an
        objective and a constraint): measures are functions of the design and their
        arguments, so the value is the same. Arguments other than plain values (the workspace
        sample, the task) are compared by identity, and kept alive in ``memo`` meanwhile."""
        if key is False:
            key = cls._memo_key(item, args)
        if key is not None and key in memo:
            return memo[key][0]
        v = cls._value(item, mech, args, rec, bound=bound, probability=probability)
        if key is not None:
            memo[key] = (v, args)
        return v

    @staticmethod
    def _value(item, mech, args, rec, bound=None, probability=None) -> float:
        """The value of an objective or constraint ``item``: its measure, or under a ``robust``
        block its robust statistic (or a chance constraint's fraction of draws within the
        bound), the nominal value and standard error recorded in ``rec.robust``."""
        rm = getattr(item, "robust", None)
        if rm is None:
            return get_measure(item.name)(mech, **args)
        if probability is not None:
            P, se, nominal = rm.probability_of(mech, bound, **args)
            rec.robust[item.label] = {"nominal": nominal, "stderr": se, "statistic": "probability", "level": None,
                                      "samples": rm.samples, "probability": probability}
            return P
        rv = rm.evaluate(mech, bound=bound, **args)
        rec.robust[item.label] = {"nominal": rv.nominal, "stderr": rv.standard_error, "statistic": rv.statistic,
                                  "level": rv.level, "samples": rv.samples, "probability": None}
        return rv.value
