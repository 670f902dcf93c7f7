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
  ``source``); all values SI; rewritten at most every few seconds during a run and at its end;
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
import json
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .evaluate import Evaluator, Record
from .final import _non_dominated, best_designs, reevaluate_best  # noqa: F401
from .journal import Journal, RunLock, json_default, read_journal, rewrite_journal
from .spec import NLOPT_WITH_CONSTRAINTS, ResolvedStudy, StudyError

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

    def summary(self, study: ResolvedStudy) -> str:
        from ..display import text_table

        t = self.table
        run = t[t["source"] == "run"] if len(t) else t
        n_new_run = sum(1 for r in self.new_records if r.source == "run") if self.new_records else self.n_new
        lines = [f"study {study.name}: {len(run)} designs evaluated ({n_new_run} in this run, "
                 f"{self.elapsed_s:.1f} s); {int(run['feasible'].sum()) if len(run) else 0} feasible, "
                 f"{int((run['status'] == 'failed').sum()) if len(run) else 0} failed"]
        best = best_designs(study, run, k=3)
        if len(best):
            lines.append("best feasible designs:")
            cols = [v.name for v in study.variables] + [o.label for o in study.objectives]
            lines.append(text_table(study, best, cols + (["count"] if "count" in best and (best["count"] > 1).any() else [])))
        ref = t[t["source"] == "reference"] if len(t) else t
        if len(ref):
            lines.append("reference design (paper):")
            lines.append(text_table(study, ref, [o.label for o in study.objectives] + ["feasible"]))
        lines.append(f"results: {self.out_dir / 'results.csv'}")
        return "\n".join(lines)


# -- journal and tables ----------------------------------------------------------------------------
_json_default = json_default


def results_table(study: ResolvedStudy, records: list[Record]) -> pd.DataFrame:
    rows = []
    for r in records:
        row = {"trial": r.trial, "source": r.source}
        for v in study.variables:
            row[v.name] = r.values.get(v.name)
        for o in study.objectives:
            row[o.label] = r.objectives.get(o.label, np.nan)
        for c in study.constraints:
            row[c.label] = r.constraint_values.get(c.label, np.nan)
            row[f"{c.label}_margin"] = r.margins.get(c.label, np.nan)
        row.update(feasible=r.feasible, status=r.status, error=r.error, seed=r.seed, samples=r.samples,
                   time_s=r.time_s)
        rows.append(row)
    cols = (["trial", "source"] + [v.name for v in study.variables] + [o.label for o in study.objectives]
            + sum(([c.label, f"{c.label}_margin"] for c in study.constraints), [])
            + ["feasible", "status", "error", "seed", "samples", "time_s"])
    df = pd.DataFrame(rows, columns=cols)
    if len(df):
        df = df.sort_values(["source", "trial"], ascending=[False, True], kind="stable").reset_index(drop=True)
    return df


def write_tables(study: ResolvedStudy, out_dir: Path, records: list[Record]) -> pd.DataFrame:
    df = results_table(study, records)
    tmp = out_dir / "results.csv.tmp"
    df.to_csv(tmp, index=False)
    os.replace(tmp, out_dir / "results.csv")
    try:
        df2 = df.copy()
        for v in study.variables:  # mixed-type object columns do not go to Parquet
            if df2[v.name].dtype == object:
                df2[v.name] = df2[v.name].astype(str)
        df2.to_parquet(out_dir / "results.parquet", index=False)
    except ImportError:
        pass
    return df


# -- run directory -------------------------------------------------------------------------------------
def prepare_dir(study: ResolvedStudy, out_dir: Path, resume: bool) -> list[Record]:
    out_dir = Path(out_dir)
    existing = list(out_dir.glob("journal*.jsonl")) if out_dir.exists() else []
    if existing and not resume:
        raise StudyError(
            f"run directory {str(out_dir)!r} already holds results; pass --resume to continue that run "
            f"or --out to start a new one"
        )
    out_dir.mkdir(parents=True, exist_ok=True)
    text = study.to_yaml()
    sy = out_dir / "study.yaml"
    if resume and sy.exists() and existing:
        if sy.read_text() != text:
            raise StudyError(
                f"cannot resume: the study differs from the one run in {str(out_dir)!r} (compare with its study.yaml)"
            )
    sy.write_text(text)
    return read_journal(out_dir) if resume else []


def _key(values: dict) -> str:
    return json.dumps({k: (round(v, 12) if isinstance(v, float) else v) for k, v in sorted(values.items())},
                      default=_json_default)


class _Progress:
    def __init__(self, total, enabled, desc):
        self.bar = None
        if enabled:
            try:
                from tqdm import tqdm

                # disable=None: a bar on a terminal, nothing in logs (the summary follows).
                self.bar = tqdm(total=total, desc=desc, unit="design", file=sys.stderr, dynamic_ncols=True,
                                disable=None, mininterval=0.5)
            except ImportError:
                self.bar = None

    def update(self, rec: Record, best=None):
        if self.bar is not None:
            self.bar.update(1)
            if best is not None:
                self.bar.set_postfix_str(best)

    def close(self):
        if self.bar is not None:
            self.bar.close()


# -- runners ---------------------------------------------------------------------------------------------
def run_study(study: ResolvedStudy, out_dir=None, resume: bool = False, n_trials: int | None = None,
              progress: bool = True) -> RunResult:
    """Run a resolved study; see the module docstring for the run directory."""
    out_dir = Path(out_dir or study.spec.output or Path("runs") / study.name)
    previous = prepare_dir(study, out_dir, resume)
    evaluator = Evaluator(study)
    worker = f"journal-{os.getpid()}.jsonl" if study.optimizer.n_jobs > 1 else "journal.jsonl"
    journal = Journal(out_dir / worker)
    t0 = time.perf_counter()
    records = list(previous)
    new = []
    interrupted = False

    def record(rec: Record):
        journal.append(rec)
        records.append(rec)
        new.append(rec)
        if len(new) % 10 == 0:
            write_tables(study, out_dir, records)

    try:
        if study.reference is not None and not any(r.source == "reference" for r in records):
            record(evaluator.evaluate(dict(study.reference), trial=-1, source="reference"))
        kind = study.optimizer.kind
        if kind == "sweep":
            _run_sweep(study, evaluator, records, record, progress)
        elif kind == "nlopt":
            _run_nlopt(study, evaluator, records, record, progress, n_trials)
        else:
            _run_optuna(study, evaluator, records, record, progress, n_trials, out_dir, resume)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        journal.close()
        table = write_tables(study, out_dir, records)
    final = None
    if not interrupted and study.evaluation.get("final_samples") and study.evaluation.get("final_top", 0) > 0:
        final = reevaluate_best(study, evaluator, table, out_dir)
    return RunResult(out_dir, table, final, len(new), len(records), time.perf_counter() - t0, interrupted, new)


def _sweep_designs(study: ResolvedStudy) -> list[dict]:
    if study.optimizer.designs:
        from .spec import _q

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
    return f"best {o.label}={b:.4g}"


def _run_sweep(study, evaluator, records, record, progress):
    designs = _sweep_designs(study)
    done = {_key(r.values) for r in records if r.source == "run"}
    todo = [(i, d) for i, d in enumerate(designs) if _key(d) not in done]
    bar = _Progress(len(todo), progress, f"sweep {study.name}")
    try:
        for i, d in todo:
            rec = evaluator.evaluate(d, trial=i)
            record(rec)
            bar.update(rec, _best_str(study, records))
    finally:
        bar.close()


def _run_nlopt(study, evaluator, records, record, progress, n_trials):
    import nlopt

    opt_spec = study.optimizer
    alg = opt_spec.algorithm or "LN_COBYLA"
    vars_ = study.variables
    nv = len(vars_)
    o = study.objectives[0]
    sign = -1.0 if o.goal == "maximize" else 1.0  # NLopt minimises sign * f
    maxeval = n_trials or opt_spec.maxeval or 100
    seed = opt_spec.seed if opt_spec.seed is not None else study.evaluation["seed"]
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
    cache = {_key(r.values): r for r in records if r.source == "run"}
    state = {"worst": None, "n": 0, "stop": None}
    bar = _Progress(int(maxeval), progress, f"nlopt {alg} {study.name}")

    def values_of(u):
        return {v.name: v.denormalize(float(np.clip(x, 0, 1))) for v, x in zip(vars_, u)}

    def get(u) -> Record:
        vals = values_of(u)
        k = _key(vals)
        rec = cache.get(k)
        if rec is None:
            rec = evaluator.evaluate(vals, trial=state["n"])
            cache[k] = rec
            record(rec)
            state["n"] += 1
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
        from .spec import _q

        byname = {v.name: v for v in vars_}
        x0 = [byname[v.name].normalize(_q(opt_spec.start[v.name], v.kind, f"optimizer.start.{v.name}"))
              if v.name in opt_spec.start else 0.5 for v in vars_]
    elif study.reference and all(v.name in study.reference for v in vars_):
        x0 = [v.normalize(study.reference[v.name]) for v in vars_]
    else:
        x0 = [0.5] * nv
    x0 = list(np.clip(x0, 0, 1))
    try:
        opt.optimize(x0)
    except nlopt.ForcedStop:
        if state["stop"] == "interrupt":
            raise KeyboardInterrupt
    except (nlopt.RoundoffLimited, ValueError, RuntimeError) as e:
        print(f"nlopt stopped: {type(e).__name__}: {e}", file=sys.stderr)
    finally:
        bar.close()


def _make_sampler(study, seed, constraints_func):
    import optuna

    alg = study.optimizer.algorithm or ("nsga2" if len(study.objectives) > 1 else "tpe")
    pop = study.optimizer.population_size
    if alg == "tpe":
        return optuna.samplers.TPESampler(seed=seed, constraints_func=constraints_func, multivariate=True)
    if alg == "nsga2":
        kw = {"population_size": pop} if pop else {}
        return optuna.samplers.NSGAIISampler(seed=seed, constraints_func=constraints_func, **kw)
    if alg == "nsga3":
        kw = {"population_size": pop} if pop else {}
        return optuna.samplers.NSGAIIISampler(seed=seed, constraints_func=constraints_func, **kw)
    if alg == "random":
        return optuna.samplers.RandomSampler(seed=seed)
    if alg == "qmc":
        return optuna.samplers.QMCSampler(seed=seed, scramble=True)
    if alg == "cmaes":
        if len(study.objectives) > 1:
            raise StudyError("optimizer.algorithm: cmaes is single-objective; use nsga2 or tpe")
        return optuna.samplers.CmaEsSampler(seed=seed)
    raise StudyError(f"optimizer.algorithm: unknown {alg!r}")


def _constraints_func(trial):
    return trial.user_attrs.get("constraints", [1.0])


def _set_optuna_constraints(trial, study, rec):
    """Our margins count >= 0 as feasible, Optuna's constraint values <= 0: convert here, in
    one place. Optuna >= 5 reads ``Trial.set_constraint``; older versions a
    ``constraints_func`` that returns the user attribute set here."""
    vals = [(-m if math.isfinite(m) else 1e9) for m in rec.margins.values()]
    if rec.status != "ok":
        vals = [1e9 for _ in study.constraints]
    trial.set_user_attr("constraints", vals or [0.0])
    if hasattr(trial, "set_constraint"):
        for c, v in zip(study.constraints, vals):
            trial.set_constraint(c.label, v)


def _uses_set_constraint() -> bool:
    import optuna

    return hasattr(optuna.trial.Trial, "set_constraint")


def _run_optuna(study, evaluator, records, record, progress, n_trials, out_dir, resume):
    import optuna

    optuna.logging.set_verbosity(optuna.logging.ERROR)
    opt_spec = study.optimizer
    total = n_trials or opt_spec.n_trials or 50
    seed = opt_spec.seed if opt_spec.seed is not None else study.evaluation["seed"]
    storage = opt_spec.storage or f"sqlite:///{(Path(out_dir) / 'optuna.db').resolve()}"
    directions = [o.goal for o in study.objectives]
    has_cons = bool(study.constraints) and not _uses_set_constraint()
    sampler = _make_sampler(study, seed, _constraints_func if has_cons else None)
    ostudy = optuna.create_study(study_name=study.name, storage=storage, directions=directions, sampler=sampler,
                                 load_if_exists=True)
    # Trials left running by a killed process are failed: their designs are evaluated anew.
    for t in ostudy.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        ostudy._storage.set_trial_state_values(t._trial_id, state=optuna.trial.TrialState.FAIL)
    finished = [t for t in ostudy.get_trials(deepcopy=False)
                if t.state in (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL)
                and t.user_attrs.get("evaluated")]
    remaining = max(0, total - len(finished))
    if remaining == 0:
        return
    if finished:
        # A resumed sampler must not replay the random stream of the first run (it would
        # propose the designs already evaluated): continue with a seed offset by the number
        # of finished trials, which keeps resumed runs deterministic.
        ostudy.sampler = _make_sampler(study, seed + len(finished), _constraints_func if has_cons else None)
    bar = _Progress(remaining, progress, f"optuna {sampler.__class__.__name__} {study.name}")

    def on_record(rec):
        record(rec)
        bar.update(rec, _best_str(study, records))

    objective = _optuna_objective(study, evaluator, on_record)

    try:
        if opt_spec.n_jobs > 1:
            _optuna_processes(study, storage, seed, remaining, opt_spec.n_jobs, out_dir)
            for r in read_journal(out_dir):
                if _key(r.values) not in {_key(x.values) for x in records}:
                    records.append(r)
        else:
            ostudy.optimize(objective, n_trials=remaining, catch=(Exception,), gc_after_trial=False)
    finally:
        bar.close()


def _optuna_objective(study, evaluator: Evaluator, on_record):
    """The Optuna objective of a study: suggest the design variables, evaluate the design,
    hand the record to ``on_record``, report constraints and objectives (NaN for a failed
    design, which Optuna records as a failed trial)."""

    def objective(trial):
        values = {}
        for v in study.variables:
            if v.type == "categorical":
                values[v.name] = trial.suggest_categorical(v.name, list(v.choices))
            elif v.type == "integer":
                values[v.name] = trial.suggest_int(v.name, int(v.low), int(v.high), log=v.log)
            else:
                values[v.name] = trial.suggest_float(v.name, v.low, v.high, log=v.log)
        rec = evaluator.evaluate(values, trial=trial.number)
        _set_optuna_constraints(trial, study, rec)
        trial.set_user_attr("evaluated", True)
        on_record(rec)
        if rec.status != "ok":
            trial.set_user_attr("error", rec.error)
            return tuple(float("nan") for _ in study.objectives) if len(study.objectives) > 1 else float("nan")
        vals = tuple(rec.objectives[o.label] for o in study.objectives)
        return vals if len(vals) > 1 else vals[0]

    return objective


def _optuna_worker(args):
    study_yaml, storage, seed, n, out_dir, idx = args
    from ..plugins import load_plugins
    from .spec import load_study

    load_plugins()  # user measures registered through PARASYNTH_PLUGINS

    study = load_study(study_yaml, is_text=True)
    import optuna

    optuna.logging.set_verbosity(optuna.logging.ERROR)
    evaluator = Evaluator(study)
    journal = Journal(Path(out_dir) / f"journal-w{idx}-{os.getpid()}.jsonl")
    sampler = _make_sampler(study, seed + idx,
                            _constraints_func if study.constraints and not _uses_set_constraint() else None)
    ostudy = optuna.load_study(study_name=study.name, storage=storage, sampler=sampler)

    objective = _optuna_objective(study, evaluator, journal.append)
    ostudy.optimize(objective, n_trials=n, catch=(Exception,))
    journal.close()


def _optuna_processes(study, storage, seed, remaining, n_jobs, out_dir):
    """Optuna's own n_jobs uses threads (no gain for CPU-bound objectives under the GIL):
    run ``n_jobs`` processes sharing the storage instead."""
    import multiprocessing as mp

    per = [remaining // n_jobs + (1 if i < remaining % n_jobs else 0) for i in range(n_jobs)]
    args = [(study.to_yaml(), storage, seed, n, str(out_dir), i) for i, n in enumerate(per) if n]
    ctx = mp.get_context("spawn")
    with ctx.Pool(len(args)) as pool:
        pool.map(_optuna_worker, args)
