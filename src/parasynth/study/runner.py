"""Study runners (sweep, NLopt, Optuna), the run directory and its result tables.

Run directory (default ``runs/<study name>/``):

* ``study.yaml``: the study as run (a copy, so a run can be resumed and reported alone);
* ``journal.jsonl``: one JSON line per evaluated design, appended and flushed as soon as the
  design is evaluated -- the source of truth for sweeps and NLopt, a mirror of the storage
  for Optuna (see :mod:`parasynth.study.journal`: torn last lines, ``PARASYNTH_FSYNC``);
* ``run.lock``: held by the process running in the directory (one writer at a time; a
  crashed run does not leave it held);
* ``results.csv`` and ``results.parquet``: every evaluated design (one column per design
  variable, objective and design constraint named as in the YAML, ``<constraint>_margin``,
  ``feasible``, ``status``, ``error``, ``seed``, ``samples``, ``time_s``, ``trial``,
  ``source``); all values SI, and in ``results.csv`` every column with a unit names it as a
  suffix (``link_length_m``, ``volume_m3``; :mod:`parasynth.study.columns`); rewritten at most
  every few seconds during a run and at its end;
* ``final.csv``: the best designs re-evaluated with more samples and several seeds (mean and
  standard error of each objective);
* ``optuna.journal``: the embedded Optuna storage of an Optuna study, unless ``--storage`` /
  ``optimizer.storage`` names another one (see :mod:`parasynth.study.storage`).

Interrupts (Ctrl-C, SIGTERM): the design being evaluated is finished and recorded (a second
Ctrl-C drops it), the tables are written and the result says ``interrupted``.

Resuming (``resume=True``) reads the journal (a torn last line is cut away, with a message):

* a sweep skips the designs already evaluated (trial = index of the design in the grid);
* an NLopt run replays its deterministic path, answering already-evaluated points from the
  journal (trial = order of first evaluation);
* an Optuna run on the embedded storage rebuilds it without the trials the interruption left
  unfinished and continues; the sampler is seeded per trial from (seed, trial number), so the
  designs, the results table and the Pareto front equal those of the uninterrupted run. On
  SQLite the unfinished trials are marked failed instead (the trial numbers then differ from
  an uninterrupted run: complete, but not the same sequence); on a database server they are
  left to the heartbeat (other workers may be running).

Completed evaluations are neither lost nor repeated.
"""

from __future__ import annotations

import itertools
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..display import fmt_column_value, reference_name
from ..engine import warm_up
from . import storage as st
from .budget import budget_for_run, same_study
from .defaults import nlopt_algorithm, nlopt_budget, optimizer_seed, optuna_algorithm, optuna_budget
from .design import BOX_CENTRE_U, design_key
from .evaluate import Evaluator, Record
from .final import reevaluate_best
from .journal import Journal, RunLock, jsonable, read_journal, rewrite_journal
from .optuna_adapter import fail_trial
from .progress import Progress
from .signals import Interrupt
from .spec import NLOPT_WITH_CONSTRAINTS, ResolvedStudy, StudyError, _q
from .tables import results_table, write_tables
from .workers import make_sampler, optimize_loop, optuna_objective, run_local_workers

__all__ = ["run_study", "RunResult", "results_table", "read_journal"]


@dataclass
class RunResult:
    out_dir: Path
    table: pd.DataFrame
    final: pd.DataFrame | None
    n_new: int
    n_total: int
    elapsed_s: float
    interrupted: bool = False
    new_records: list | None = None
    storage: str | None = None  # the storage URL when given explicitly (for the resume hint)

    def saved_counts(self) -> tuple[int, bool]:
        """(designs of the search saved in the run's table, whether the reference design is
        among them): the one count the summary and the interrupt message give."""
        t = self.table
        if not len(t):
            return 0, False
        return int((t["source"] == "run").sum()), bool((t["source"] == "reference").any())

    def summary(self, study: ResolvedStudy, details=()) -> str:
        """The counts line, then ``details`` (the report layer's recommendations:
        :func:`parasynth.report.summary.run_summary`), then where the results are."""
        t = self.table
        run = t[t["source"] == "run"] if len(t) else t
        n_new_run = sum(1 for r in self.new_records if r.source == "run") if self.new_records else self.n_new
        n_run, has_ref = self.saved_counts()
        ref = f" and {reference_name(study)}" if has_ref else ""
        lines = [f"study {study.name}: {n_run} designs evaluated{ref} ({n_new_run} in this run, "
                 f"{self.elapsed_s:.1f} s); {int(run['feasible'].sum()) if len(run) else 0} feasible, "
                 f"{int((run['status'] == 'failed').sum()) if len(run) else 0} failed"]
        lines += list(details)
        lines.append(f"results: {self.out_dir / 'results.csv'}")
        return "\n".join(lines)


# -- run directory -------------------------------------------------------------------------------------
def prepare_dir(study: ResolvedStudy, out_dir: Path, resume: bool, lock: RunLock | None = None) -> list[Record]:
    """Create or check the run directory; with ``lock`` it is acquired before anything is
    read. Returns the journal's records on resume (a torn last line cut away)."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise StudyError(f"run directory {str(out_dir)!r} is a file; choose a directory with --out")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise StudyError(f"cannot create the run directory {str(out_dir)!r}: {e.strerror or e}") from None
    if lock is not None:
        lock.acquire()
    existing = list(out_dir.glob("journal*.jsonl")) + list(out_dir.glob("optuna.journal"))
    if existing and not resume:
        raise StudyError(
            f"run directory {str(out_dir)!r} already holds results; pass --resume to continue that run "
            f"or --out to start a new one"
        )
    text = study.to_yaml()
    sy = out_dir / "study.yaml"
    if resume and sy.exists() and existing:
        if not same_study(sy.read_text(), text):
            raise StudyError(
                f"cannot resume: the study differs from the one run in {str(out_dir)!r} (compare with its study.yaml)"
            )
    tmp = out_dir / "study.yaml.tmp"
    tmp.write_text(text)
    os.replace(tmp, sy)
    return read_journal(out_dir, repair=True) if resume else []


TABLES_EVERY_S = 5.0


# -- runners ---------------------------------------------------------------------------------------------
def run_study(study: ResolvedStudy, out_dir=None, resume: bool = False, n_trials: int | None = None,
              progress: bool = True, storage: str | None = None, workers: int | None = None,
              study_file=None) -> RunResult:
    """Run a resolved study; see the module docstring for the run directory.

    ``storage``: an Optuna storage URL (overrides ``optimizer.storage``); ``workers``: local
    worker processes for an Optuna study (default ``optimizer.workers`` / ``n_jobs``, 1).
    Sweeps and NLopt run in one process (a note is printed when more workers are asked for)."""
    if n_trials is not None and (not isinstance(n_trials, int) or isinstance(n_trials, bool) or n_trials < 1):
        raise StudyError(f"n_trials: a positive whole number of designs is needed, got {n_trials!r}")
    kind = study.optimizer.kind
    n_workers = _workers_of(study, workers)
    if kind != "optuna":
        if storage:
            raise StudyError(f"--storage applies to Optuna studies; a {kind} run keeps its designs in the run "
                             f"directory's journal")
        if n_workers > 1:
            print(f"note: a {'sweep' if kind == 'sweep' else 'NLopt run'} runs in one process; "
                  f"--workers applies to Optuna studies", file=sys.stderr)
            n_workers = 1
    out_dir = Path(out_dir or study.spec.output or Path("runs") / study.name)
    if resume and not out_dir.exists() and not (kind == "optuna" and (storage or study.optimizer.storage)):
        raise StudyError(f"--resume: the run directory {str(out_dir)!r} does not exist, so there is nothing to "
                         f"resume; give the directory of the run (--out) or drop --resume to start a new run")
    study = budget_for_run(study, out_dir, resume, n_trials, note=lambda m: print(m, file=sys.stderr))
    lock = RunLock(out_dir)
    try:
        previous = prepare_dir(study, out_dir, resume, lock=lock)
        return _run_locked(study, out_dir, previous, resume, n_trials, progress, storage, n_workers)
    finally:
        lock.release()


def _workers_of(study, workers):
    if workers is not None:
        if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
            raise StudyError(f"--workers: a positive whole number of processes is needed, got {workers!r}")
        return workers
    opt = study.optimizer
    return max(int(getattr(opt, "workers", None) or 1), int(getattr(opt, "n_jobs", 1) or 1))


def _run_locked(study, out_dir, previous, resume, n_trials, progress, storage, n_workers) -> RunResult:
    evaluator = Evaluator(study)
    t0 = time.perf_counter()
    records = list(previous)
    new = []
    last_tables = [time.monotonic()]
    ctx = {}

    with Interrupt(quiet=not progress) as guard:
        journal = None
        try:
            if study.optimizer.kind == "optuna":
                # Set up (and check) the storage before any work, and reconcile the journal
                # with it: the storage is the record of an Optuna study.
                ctx = _optuna_setup(study, out_dir, resume, n_trials, storage, records)
                records[:] = ctx["records"]

            n_warm = max(1, int(study.evaluation["n"]) // 2)  # not the run's sample count: no cache hit later
            warm_up(lambda: evaluator.evaluate(_warm_up_design(study), n=n_warm, source="warm-up"),
                    progress=None if not progress else print_err, stop=lambda: guard.requested)
            journal = Journal(out_dir / "journal.jsonl")

            def record(rec: Record):
                journal.append(rec)
                records.append(rec)
                new.append(rec)
                now = time.monotonic()
                if now - last_tables[0] > TABLES_EVERY_S:
                    write_tables(study, out_dir, records)
                    last_tables[0] = now

            if guard.requested:
                pass
            elif study.reference is not None and not any(r.source == "reference" for r in records):
                with guard.evaluating():
                    rec = evaluator.evaluate(dict(study.reference), trial=-1, source="reference")
                record(rec)
                if ctx:
                    _store_reference(ctx["ostudy"], rec)
            kind = study.optimizer.kind
            if guard.requested:
                pass
            elif kind == "sweep":
                _run_sweep(study, evaluator, records, record, progress, guard)
            elif kind == "nlopt":
                _run_nlopt(study, evaluator, records, record, progress, n_trials, guard)
            else:
                _run_optuna(study, evaluator, records, record, progress, ctx, n_workers, out_dir, guard, journal)
        except KeyboardInterrupt:
            guard.requested = True
        finally:
            if journal is not None:
                journal.close()
            if records:
                table = write_tables(study, out_dir, records)
            else:
                table = results_table(study, records)
        interrupted = guard.requested
    final = None
    if not interrupted and study.evaluation.get("final_samples") and study.evaluation.get("final_top", 0) > 0:
        with Interrupt(quiet=not progress) as guard2:
            try:
                final = reevaluate_best(study, evaluator, table, out_dir)
            except KeyboardInterrupt:
                interrupted = True
            interrupted = interrupted or guard2.requested
        if final is not None and ctx:
            _store_final(ctx["ostudy"], out_dir)
    # New designs of this run, those of other workers on the same study included.
    before = {(r.source, r.trial) for r in previous}
    new = [r for r in records if (r.source, r.trial) not in before]
    return RunResult(out_dir, table, final, len(new), len(records), time.perf_counter() - t0, interrupted, new,
                     storage=ctx.get("url") if ctx and ctx.get("explicit") else None)


def _warm_up_design(study: ResolvedStudy) -> dict:
    """A design whose evaluation compiles what the run needs: the reference, else the first
    listed design, else the centre of the variable box (its record is not kept)."""
    if study.reference is not None:
        return dict(study.reference)
    if study.optimizer.designs:
        return _sweep_designs(study)[0]
    d = {}
    for v in study.variables:
        if v.low is not None and v.high is not None and v.type == "continuous":
            d[v.name] = v.denormalize(0.5)
        elif v.low is not None and v.high is not None:
            d[v.name] = round(0.5 * (v.low + v.high))
        else:
            d[v.name] = (v.values or v.choices)[0]
    return d


def print_err(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _sweep_designs(study: ResolvedStudy) -> list[dict]:
    if study.optimizer.designs:
        out = []
        byname = {v.name: v for v in study.variables}
        for j, d in enumerate(study.optimizer.designs):
            out.append({k: _q(x, byname[k].kind, f"optimizer.designs[{j}].{k}") for k, x in d.items()})
        return out
    axes = [(v.name, v.values if v.values is not None else v.choices) for v in study.variables]
    return [dict(zip([a for a, _ in axes], combo)) for combo in itertools.product(*[vals for _, vals in axes])]


def _best_str(study, records):
    ok = [r for r in records if r.feasible and r.source == "run"]
    if not ok or len(study.objectives) != 1:
        return f"{len(ok)} feasible"
    o = study.objectives[0]
    vals = [r.objectives[o.label] for r in ok]
    b = max(vals) if o.goal == "maximize" else min(vals)
    return f"best {o.label} = {fmt_column_value(study, o.label, b)}"


def _run_sweep(study, evaluator, records, record, progress, guard):
    designs = _sweep_designs(study)
    done = {r.trial for r in records if r.source == "run"}
    todo = [(i, d) for i, d in enumerate(designs) if i not in done]
    bar = Progress(len(designs), progress, f"sweep {study.name}", initial=len(designs) - len(todo))
    try:
        for i, d in todo:
            if guard.requested:
                break
            with guard.evaluating():
                rec = evaluator.evaluate(d, trial=i)
            record(rec)
            bar.update(rec, _best_str(study, records))
    finally:
        bar.close()


def _run_nlopt(study, evaluator, records, record, progress, n_trials, guard):
    import nlopt  # lazy: only NLopt runs need it

    opt_spec = study.optimizer
    alg = nlopt_algorithm(study)
    vars_ = study.variables
    nv = len(vars_)
    o = study.objectives[0]
    sign = -1.0 if o.goal == "maximize" else 1.0  # NLopt minimises sign * f
    maxeval = nlopt_budget(study, n_trials)
    seed = optimizer_seed(study)
    nlopt.srand(int(seed))
    opt = nlopt.opt(getattr(nlopt, alg), nv)
    opt.set_lower_bounds([0.0] * nv)
    opt.set_upper_bounds([1.0] * nv)
    opt.set_maxeval(int(maxeval))
    if opt_spec.xtol_rel:
        opt.set_xtol_rel(opt_spec.xtol_rel)
    if opt_spec.ftol_rel:
        opt.set_ftol_rel(opt_spec.ftol_rel)
    if alg.startswith("LN_"):
        opt.set_initial_step([0.1] * nv)
    if opt_spec.population_size:
        opt.set_population(int(opt_spec.population_size))
    # Trial numbers are the order of first evaluation along the (deterministic) path, the same
    # in an uninterrupted and a resumed run.
    cache = {design_key(study, r.values): r for r in records if r.source == "run"}
    state = {"worst": None, "stop": None}
    bar = Progress(int(maxeval), progress, f"nlopt {alg} {study.name}", initial=min(len(cache), int(maxeval)))

    def values_of(u):
        return {v.name: v.denormalize(float(np.clip(x, 0, 1))) for v, x in zip(vars_, u)}

    def get(u) -> Record:
        vals = values_of(u)
        k = design_key(study, vals)
        rec = cache.get(k)
        if rec is None:
            if guard.requested:
                raise KeyboardInterrupt
            with guard.evaluating():
                rec = evaluator.evaluate(vals, trial=len(cache))
            cache[k] = rec
            record(rec)
            bar.update(rec, _best_str(study, list(cache.values())))
        return rec

    use_constraints = alg in NLOPT_WITH_CONSTRAINTS
    penalty_weight = 10.0

    def penalty_value(rec):
        # NLopt has no "infeasible" return: a failed design gets a value worse than any seen.
        w = state["worst"]
        return (abs(w) * 2 + 1.0) if w is not None else 1e6

    def get_or_stop(u) -> Record:
        # NLopt swallows Python exceptions: turn an interrupt into its forced stop.
        try:
            return get(u)
        except KeyboardInterrupt:
            state["stop"] = "interrupt"
            raise nlopt.ForcedStop

    def f(u, grad):
        rec = get_or_stop(u)
        if rec.status != "ok":
            return penalty_value(rec)
        val = sign * rec.objectives[o.label]
        state["worst"] = val if state["worst"] is None else max(state["worst"], val)
        if not use_constraints and rec.margins:
            viol = sum(max(0.0, -m) for m in rec.margins.values() if math.isfinite(m))
            if any(not math.isfinite(m) for m in rec.margins.values()):
                return penalty_value(rec)
            val += penalty_weight * viol * (1 + abs(val))
        return val

    if use_constraints:
        for c in study.constraints:
            def g(u, grad, label=c.label):
                rec = get_or_stop(u)
                if rec.status != "ok":
                    return 1.0
                m = rec.margins[label]
                return -m if math.isfinite(m) else 1e6
            opt.add_inequality_constraint(g, 0.0)
    opt.set_min_objective(f)
    if opt_spec.start:
        byname = {v.name: v for v in vars_}
        x0 = [byname[v.name].normalize(_q(opt_spec.start[v.name], v.kind, f"optimizer.start.{v.name}"))
              if v.name in opt_spec.start else BOX_CENTRE_U for v in vars_]
    elif study.reference and all(v.name in study.reference for v in vars_):
        x0 = [v.normalize(study.reference[v.name]) for v in vars_]
    else:
        x0 = [BOX_CENTRE_U] * nv  # the centre of the box
    x0 = list(np.clip(x0, 0, 1))
    try:
        opt.optimize(x0)
    except nlopt.ForcedStop:
        if state["stop"] == "interrupt":
            guard.requested = True
    except (nlopt.RoundoffLimited, ValueError, RuntimeError) as e:
        print(f"nlopt stopped: {type(e).__name__}: {e}", file=sys.stderr)
    finally:
        bar.close()


# -- Optuna ----------------------------------------------------------------------------------------------
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
    total = optuna_budget(study, n_trials)
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
            "total": total, "seed": seed, "records": records}


def _store_reference(ostudy, rec):
    try:
        ostudy.set_user_attr(st.ATTR_REFERENCE, jsonable(rec.to_dict()))
    except Exception as e:  # the reference stays in the journal
        print(f"warning: could not store the reference design in the storage ({type(e).__name__})", file=sys.stderr)


def _store_final(ostudy, out_dir):
    try:
        ostudy.set_user_attr(st.ATTR_FINAL, (Path(out_dir) / "final.csv").read_text())
    except Exception as e:
        print(f"warning: could not store final.csv in the storage ({type(e).__name__})", file=sys.stderr)


def _run_optuna(study, evaluator, records, record, progress, ctx, n_workers, out_dir, guard, journal):
    ostudy, total = ctx["ostudy"], ctx["total"]
    counted = sum(1 for r in records if r.source == "run")
    if counted >= total and not ctx["shared"]:
        return
    alg = optuna_algorithm(study)
    bar = Progress(total, progress, f"optuna {alg} {study.name}", initial=min(counted, total))
    try:
        if n_workers > 1:
            def on_new(recs):
                for r in recs:
                    record(r)
                bar.update(None, _best_str(study, records), n=len(recs))

            codes = run_local_workers(Path(out_dir) / "study.yaml", ctx["url"], n_workers, total, ostudy, guard,
                                      on_new=on_new)
            bad = [c for c in codes if c not in (0, 130, -2)]
            if bad and not guard.requested:
                print(f"warning: {len(bad)} worker(s) stopped with an error (exit codes {bad}); the study keeps "
                      f"their stored trials", file=sys.stderr)
        else:
            def on_record(rec):
                record(rec)
                bar.update(rec, _best_str(study, records))

            objective = optuna_objective(study, evaluator, on_record, guard=guard, mark_owner=ctx["shared"])
            optimize_loop(ostudy, objective, total, guard, shared=ctx["shared"], counted=counted,
                          on_count=bar.set_count)
    finally:
        bar.close()
    if ctx["shared"] or n_workers > 1:
        # Designs of every worker (other machines included), each trial once, in trial order.
        ref = [r for r in records if r.source == "reference"]
        recs = st.records_from_trials(ostudy.get_trials(deepcopy=False))
        records[:] = ref + recs
        journal.close()
        rewrite_journal(Path(out_dir) / "journal.jsonl", records)
