"""Successive halving over the structures of a study: which structure the next design is for.

A study over structures (``structure:``, :mod:`parasynth.study.structure_space`) spreads its
evaluations over the structures in **rungs**. Every structure gets ``structure.screening``
designs in the first rung (the screening); after each rung the structures are ranked and the
best ``ceil(n / eta)`` (or ``structure.keep``) continue with ``eta`` times as many designs each, up to
``optimizer.n_trials`` designs per structure in the last rung (the full budget). A structure
with no feasible design in its rung stops whatever its rank; the reference structure
(``structure.reference``) always continues, so that it gets the full budget and the verdict
about it is decided at the same budget as the best structures.

The rank of a structure after a rung is the **hypervolume** of its feasible designs of that
rung, in the objectives turned into minimisation and normalised by their range over the
feasible designs of every structure in the rung, bounded by the reference point 1.1 (10 %
beyond the worst value) in each objective; for one objective that is the distance of its best
value from the bound. Ties go to the structure enumerated first. The ranking uses each
structure's first ``target`` designs in trial order, and only designs with a record: the
decisions are a function of the stored designs, so a resumed run (or any worker) recomputes
the same survivors and continues the same schedule (:meth:`Schedule.plan`).

Within a rung each new design goes to the surviving structure with the fewest designs
(stored and running), ties to the first (:meth:`Schedule.next_structure`): one process
interleaves the structures in a fixed order, several workers fill the rung evenly. A rung
ends when every surviving structure holds its target; the loop over rungs
(:func:`parasynth.study.workers.optimize_budget`) runs the Optuna trial loop up to each rung's
total, then decides the next rung. Each structure's trials are proposed by a sampler that sees
only that structure's trials
(:class:`parasynth.study.optuna_adapter.StructureView`), seeded per trial as every Optuna study.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..common.pareto import hypervolume, to_min
from .defaults import optuna_budget
from .optimizers.base import optimizer_class
from .structure_space import STRUCTURE

__all__ = ["Rung", "Plan", "Schedule", "structure_schedule", "ATTR_STRUCTURE", "REF_POINT"]

#: Trial system attribute holding the structure a trial was assigned (set when it is asked).
ATTR_STRUCTURE = "parasynth:structure"
#: Reference point of the rung hypervolumes, in normalised objectives (0 best, 1 worst seen).
REF_POINT = 1.1


@dataclass(frozen=True)
class Rung:
    """One rung: ``index``, ``target`` (designs per structure), ``alive`` (the structures in it),
    and once it is complete ``scores`` ({structure: hypervolume, None without a feasible
    design}) and ``stopped`` ({structure: why it does not continue})."""

    index: int
    target: int
    alive: tuple
    scores: dict = field(default_factory=dict)
    stopped: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Plan:
    """The schedule given the stored designs: the ``rungs`` decided so far (the last is the
    current one), whether the schedule is ``done``, the designs stored per structure
    (``counts``), and ``total``: the designs stored once the current rung is complete."""

    rungs: tuple
    done: bool
    counts: dict

    @property
    def current(self) -> Rung:
        return self.rungs[-1]

    @property
    def counted(self) -> int:
        return int(sum(self.counts.values()))

    @property
    def total(self) -> int:
        r = self.current
        return self.counted + sum(max(0, r.target - self.counts[s]) for s in r.alive) if not self.done else self.counted

    def stopped_at(self) -> dict:
        """{structure: (rung index, designs, reason)} of the structures that stopped."""
        return {s: (r.index, r.target, why) for r in self.rungs for s, why in r.stopped.items()}

    def full(self) -> tuple:
        """The structures that reached (or are in) the last rung."""
        return self.rungs[-1].alive


class Schedule:
    """The successive-halving schedule of a study over structures (module docstring)."""

    def __init__(self, labels, reference, screening: int, eta: int, n_full: int, objectives, keep: int | None = None):
        self.labels = tuple(labels)
        self.reference = reference
        self.eta = int(eta)
        self.keep = keep
        n_full = max(1, int(n_full))
        targets = [min(int(screening), n_full)]
        while targets[-1] < n_full:
            targets.append(min(n_full, targets[-1] * self.eta))
        self.targets = tuple(targets)
        self.labels_obj = [o.label for o in objectives]
        self.senses = [o.goal for o in objectives]
        self._decided: dict = {}
        self._grouped = None  # (records grouped, their last record, {structure: records}): _per_structure

    @property
    def max_total(self) -> int:
        """Designs of the schedule if every structure reached the last rung (an upper bound)."""
        return len(self.labels) * self.targets[-1]

    def _per_structure(self, records) -> dict:
        """{structure: its run records in trial order}. A run asks with the records of its last
        call and the new ones after them (the stored trials in number order, each counted
        trial's record the same object from call to call): then only the new ones are read;
        any other list is read whole."""
        g = self._grouped
        n0 = g[0] if g is not None else 0
        if n0 and len(records) >= n0 and records[n0 - 1] is g[1]:
            per, new, last = {s: list(v) for s, v in g[2].items()}, records[n0:], g[1].trial
        else:
            per, new, last = {s: [] for s in self.labels}, records, None
        ordered = True
        for r in new:
            if last is not None and r.trial <= last:
                ordered = False
                break
            last = r.trial
        if not ordered:  # read whole, in trial order, and not kept
            per = {s: [] for s in self.labels}
            new = sorted(records, key=lambda r: r.trial)
        for r in new:
            if r.source != "run":
                continue
            s = r.values.get(STRUCTURE)
            if s in per:
                per[s].append(r)
        self._grouped = (len(records), records[-1], per) if ordered and records else None
        return per

    def scores(self, alive, per, target) -> dict:
        """{structure: hypervolume of its feasible designs among its first ``target``, or None}."""
        F = {}
        for s in alive:
            rows = [[r.objectives.get(k, np.nan) for k in self.labels_obj] for r in per[s][:target] if r.feasible]
            Fm = to_min(np.array(rows, float).reshape(-1, len(self.labels_obj)), self.senses)
            F[s] = Fm[np.all(np.isfinite(Fm), axis=1)]
        allF = np.vstack([f for f in F.values() if len(f)] or [np.zeros((0, len(self.labels_obj)))])
        if not len(allF):
            return {s: None for s in alive}
        lo, hi = allF.min(axis=0), allF.max(axis=0)
        span = np.where(hi > lo, hi - lo, 1.0)
        ref = np.full(len(self.labels_obj), REF_POINT)
        return {s: (hypervolume((F[s] - lo) / span, ref) if len(F[s]) else None) for s in alive}

    def _decide(self, k, alive, per, target):
        # the first `target` records of a structure are those up to the target-th trial number:
        # records are only ever added, so that number names them (for every alive structure,
        # which holds at least `target` here)
        key = (k, tuple((s, per[s][target - 1].trial) for s in alive))
        hit = self._decided.get(key)
        if hit is None:
            sc = self.scores(alive, per, target)
            n_keep = self.keep if self.keep is not None else math.ceil(len(alive) / self.eta)
            ranked = sorted((s for s in alive if sc[s] is not None), key=lambda s: (-sc[s], self.labels.index(s)))
            keep = set(ranked[:n_keep])
            if self.reference in alive:
                keep.add(self.reference)
            stopped = {}
            for s in alive:
                if s in keep:
                    continue
                if sc[s] is None:
                    stopped[s] = f"no feasible design among its {target}"
                else:
                    stopped[s] = (f"hypervolume {sc[s]:.3g}, not among the best {n_keep} of {len(alive)} "
                                  f"after {target} designs each")
            hit = (sc, stopped, tuple(s for s in alive if s in keep))
            self._decided[key] = hit
        return hit

    def plan(self, records) -> Plan:
        """The schedule given the stored ``records`` (a run's records; only ``source == "run"``
        counts), deterministic: the same records give the same plan."""
        per = self._per_structure(records)
        counts = {s: len(v) for s, v in per.items()}
        alive = tuple(self.labels)
        rungs = []
        for k, target in enumerate(self.targets):
            if any(counts[s] < target for s in alive):
                rungs.append(Rung(k, target, alive))
                return Plan(tuple(rungs), False, counts)
            if k == len(self.targets) - 1:
                rungs.append(Rung(k, target, alive))
                return Plan(tuple(rungs), True, counts)
            sc, stopped, keep = self._decide(k, alive, per, target)
            rungs.append(Rung(k, target, alive, sc, stopped))
            alive = keep
            if not alive:
                return Plan(tuple(rungs), True, counts)
        raise AssertionError("unreachable")  # pragma: no cover

    def next_structure(self, plan: Plan, running: dict) -> str:
        """The structure of a new design: the surviving structure of the current rung with the
        fewest designs (stored plus ``running``: {structure: designs being evaluated}) below
        the rung's target, ties to the first enumerated; if every slot is taken (workers
        racing), the one with the fewest."""
        r = plan.current
        n = {s: plan.counts[s] + running.get(s, 0) for s in r.alive}
        open_ = [s for s in r.alive if n[s] < r.target] or list(r.alive)
        return min(open_, key=lambda s: (n[s], self.labels.index(s)))


def structure_schedule(study) -> Schedule | None:
    """The schedule of an Optuna study over structures (None for every other study)."""
    setup = getattr(study, "structures", None)
    if setup is None or not optimizer_class(study.optimizer.kind).halving:
        return None
    sec = study.spec.structure
    choices = study.space.by_name[STRUCTURE].choices
    ref = setup.reference if setup.reference in choices else None
    return Schedule(choices, ref, sec.screening, sec.eta, optuna_budget(study), study.objectives, sec.keep)
