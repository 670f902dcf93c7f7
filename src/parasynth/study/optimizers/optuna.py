"""The Optuna optimiser: its storage (opened, checked, rebuilt on resume), the structure
schedule of a study over structures, and the trial loop of one process or of local worker
processes (``ctx.backend``: the Optuna study, its budget, its storage URL and whether the
storage is shared)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

from .. import storage as st
from ..budget import same_study
from ..defaults import OPTUNA_TRIALS, optimizer_seed, optuna_algorithm, optuna_budget
from ..errors import StudyError
from ..journal import jsonable, rewrite_journal
from ..optuna_adapter import fail_trial
from ..polish import polish_budget
from ..problem import Problem, RunContext
from ..progress import Progress
from ..schedule import structure_schedule
from ..structure_space import STRUCTURE_ALGORITHMS
from ..workers import SAMPLERS, make_sampler, optimize_budget, optuna_objective, run_local_workers
from .base import BaseOptimizer, register

__all__ = ["Optuna"]


@register("optuna")
class Optuna(BaseOptimizer):
    title = "Optuna run"
    algorithms = tuple(SAMPLERS)
    budget_key = "n_trials"
    default_budget = OPTUNA_TRIALS
    uses_storage = True
    runs_structures = True
    halving = True
    description = ("Optuna's samplers, one or several objectives; a storage shared by worker processes; "
                   "successive halving over structures")

    def __init__(self):
        self.backend: dict = {}

    @classmethod
    def check(cls, opt, variables, objectives, space) -> None:
        if not variables:
            raise StudyError("variables: optuna needs at least one design variable (with low and high); "
                             "to evaluate fixed designs use optimizer.kind: sweep")
        for v in variables:
            if v.type != "categorical" and (v.low is None or v.high is None):
                raise StudyError(f"variables: optuna needs low/high for {v.name!r} (or type: categorical with choices)")

    @classmethod
    def check_structures(cls, opt) -> None:
        if opt.algorithm not in (None,) + STRUCTURE_ALGORITHMS:
            raise StudyError(f"optimizer.algorithm: {opt.algorithm!r} keeps state across the trials of all "
                             f"structures; a study over structures uses one of {', '.join(STRUCTURE_ALGORITHMS)} "
                             f"(default tpe)")

    @classmethod
    def algorithm(cls, study) -> str:
        return optuna_algorithm(study)

    @classmethod
    def budget(cls, study, n_trials: int | None = None) -> int:
        return optuna_budget(study, n_trials)

    def open(self, problem, out_dir, resume, n_trials, storage, records) -> list:
        self.backend = _optuna_setup(problem.study, out_dir, resume, n_trials, storage, records)
        return self.backend["records"]

    def run(self, problem: Problem, ctx: RunContext) -> None:
        ctx.backend = self.backend
        run_optuna(problem, ctx)

    def stored_reference(self, rec) -> None:
        try:
            self.backend["ostudy"].set_user_attr(st.ATTR_REFERENCE, jsonable(rec.to_dict()))
        except Exception as e:  # the reference stays in the journal
            print(f"warning: could not store the reference design in the storage ({type(e).__name__})",
                  file=sys.stderr)

    def stored_final(self, out_dir) -> None:
        try:
            self.backend["ostudy"].set_user_attr(st.ATTR_FINAL, (Path(out_dir) / "final.csv").read_text())
        except Exception as e:
            print(f"warning: could not store final.csv in the storage ({type(e).__name__})", file=sys.stderr)

    def polish_trial(self, records) -> int:
        return len(self.backend["ostudy"].get_trials(deepcopy=False))

    def stored_polished(self, rec) -> None:
        """The polish's design as a finished trial of the storage (a resumed run reads it back)."""
        import optuna  # lazy: optuna takes about a second to import

        ostudy = self.backend["ostudy"]
        last = next((t for t in reversed(ostudy.get_trials(deepcopy=False)) if t.distributions), None)
        dists = {k: d for k, d in (last.distributions if last else {}).items() if k in rec.values}
        ok = rec.status == "ok"
        vals = [rec.objectives[lab] for lab in self.backend["labels"]] if ok else None
        cons = {c: (-m if ok and math.isfinite(m) else 1e9) for c, m in rec.margins.items()}
        ostudy.add_trial(optuna.trial.create_trial(
            state=optuna.trial.TrialState.COMPLETE if ok else optuna.trial.TrialState.FAIL,
            values=vals, params={k: rec.values[k] for k in dists}, distributions=dists,
            user_attrs={st.ATTR_RECORD: jsonable(rec.to_dict()), "constraints": list(cons.values()) or [0.0]},
            constraints=cons or None))

    @property
    def storage_url(self) -> str | None:
        b = self.backend
        return b.get("url") if b and b.get("explicit") else None


def run_optuna(problem: Problem, ctx: RunContext) -> None:
    study, records, record, guard = problem.study, ctx.records, ctx.record, ctx.guard
    backend = ctx.backend
    ostudy, total = backend["ostudy"], backend["total"]
    counted = sum(1 for r in records if r.source == "run")
    if counted >= total and not backend["shared"]:
        return
    alg = optuna_algorithm(study)
    bar = Progress(total, ctx.progress, f"optuna {alg} {study.name}", initial=min(counted, total))
    try:
        if ctx.workers > 1:
            def on_new(recs):
                for r in recs:
                    record(r)
                bar.update(None, lambda: problem.best_str(records), n=len(recs))

            codes = run_local_workers(Path(ctx.out_dir) / "study.yaml", backend["url"], ctx.workers, total, ostudy,
                                      guard, on_new=on_new, fork=(study, problem, backend["seed"]))
            bad = [c for c in codes if c not in (0, 130, -2)]
            if bad and not guard.requested:
                print(f"warning: {len(bad)} worker(s) stopped with an error (exit codes {bad}); the study keeps "
                      f"their stored trials", file=sys.stderr)
        else:
            def on_record(rec):
                record(rec)
                bar.update(rec, lambda: problem.best_str(records))

            objective = optuna_objective(study, problem, on_record, guard=guard, mark_owner=backend["shared"])
            optimize_budget(ostudy, objective, study, total, guard, shared=backend["shared"], counted=counted,
                          on_count=bar.set_count)
    finally:
        bar.close()
    if backend["shared"] or ctx.workers > 1:
        # Designs of every worker (other machines included), each trial once, in trial order.
        ref = [r for r in records if r.source == "reference"]
        recs = st.records_from_trials(ostudy.get_trials(deepcopy=False))
        records[:] = ref + recs
        ctx.journal.close()
        rewrite_journal(Path(ctx.out_dir) / "journal.jsonl", records)


def _optuna_setup(study, out_dir, resume, n_trials, storage_override, journal_records):
    """Open (and check) the storage, create or load the study, rebuild the embedded storage on
    resume, and return the records the run starts from (the reference from the journal, the
    designs from the storage)."""
    import optuna  # lazy: optuna takes about a second to import; sweeps and NLopt never need it

    optuna.logging.set_verbosity(optuna.logging.ERROR)
    url = st.resolve_storage_url(study, out_dir, storage_override)
    explicit = bool(storage_override or study.optimizer.storage)
    shared = st.is_shared_server(url)
    seed = optimizer_seed(study)
    total = optuna_budget(study, n_trials) - polish_budget(study)  # the polish takes the rest
    schedule = structure_schedule(study)
    if schedule is not None:  # a study over structures: n_trials designs per structure at most
        total = schedule.max_total
    if resume and not shared and st._is_journal(url):
        dropped = st.rebuild_journal_storage(url, study.name)
        if dropped:
            print(f"resume: {dropped} unfinished trial(s) of the interrupted run removed from the storage; "
                  f"their designs are proposed again", file=sys.stderr)
    storage = st.open_storage(url)
    exists = study.name in st.study_names(storage)
    if exists and not resume:
        raise st.StorageError(
            f"storage {st.describe_url(url)!r} already holds a study named {study.name!r}; pass --resume to "
            f"continue it, or give the study another name")
    directions = [o.goal for o in study.objectives]
    ostudy = optuna.create_study(study_name=study.name, storage=storage, directions=directions,
                                 sampler=None, load_if_exists=True)
    if [d.name.lower() for d in ostudy.directions] != [d.lower() for d in directions]:
        raise st.StorageError(f"storage {st.describe_url(url)!r}: study {study.name!r} there has other objectives "
                              f"({len(ostudy.directions)} directions); give the study another name")
    text = study.to_yaml()
    stored = ostudy.user_attrs.get(st.ATTR_STUDY)
    if stored is not None and not same_study(stored, text):
        raise st.StorageError(f"storage {st.describe_url(url)!r}: the study {study.name!r} stored there differs "
                              f"from this study file; give the study another name or use the same file")
    if stored is None:
        ostudy.set_user_attr(st.ATTR_STUDY, text)
    st.name_objectives(ostudy, study)
    ostudy.set_user_attr(st.ATTR_BUDGET, total)
    from optuna.trial import TrialState  # lazy: optuna

    if resume and not shared and not st._is_journal(url):
        # SQLite: trials left running by the killed process are failed, their designs
        # proposed again.
        for t in ostudy.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
            fail_trial(ostudy, t)
    ostudy.sampler = make_sampler(study, seed)
    trials = ostudy.get_trials(deepcopy=False)
    recs = st.records_from_trials(trials)
    ref = [r for r in journal_records if r.source == "reference"]
    if not ref:
        sref = st.reference_record(ostudy)
        ref = [sref] if sref is not None else []
    records = ref + recs
    # The journal mirrors the storage: rewrite it when they differ (a trial the interruption
    # left unfinished, designs of other workers).
    want = [(r.source, r.trial) for r in records]
    have = [(r.source, r.trial) for r in journal_records]
    jpath = Path(out_dir) / "journal.jsonl"
    if want != have and (records or jpath.exists()):
        rewrite_journal(jpath, records)
    return {"url": url, "explicit": explicit, "shared": shared, "storage": storage, "ostudy": ostudy,
            "total": total, "seed": seed, "records": records, "labels": [o.label for o in study.objectives]}
