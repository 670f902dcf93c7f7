"""Optuna studies on several processes and machines.

Interrupts are handled by :class:`~parasynth.study.signals.Interrupt` (also importable from
here). The command ``parasynth worker`` that runs this loop in a process of its own is
:func:`parasynth.cli.study_cmd.cmd_worker`.

Reproducible proposals
----------------------
:class:`PerTrialSeeded` wraps an Optuna sampler so that every trial is proposed by a fresh
sampler seeded from ``(seed, trial number)``: a proposal depends only on the seed, the trial
number, the trials stored before it and the sampler state Optuna keeps in the study (NSGA-II's
cached parents of each generation, QMC's point counter), not on how many proposals a process
made before. A run killed and resumed (the storage rebuilt without the interrupted trials and
with the study's sampler state from before the first of them was asked, see
:func:`~parasynth.study.storage.rebuild_journal_storage`) therefore proposes, evaluates and
stores exactly what the uninterrupted run would have. With several workers the trials
finish in an order set by timing, so a parallel run is complete and every trial is recorded
once, but it is not the same sequence as a one-process run.

Workers
-------
``parasynth run STUDY --workers N`` starts N worker processes on the run's storage (each in its
own session, evaluations single-threaded unless ``NUMBA_NUM_THREADS`` is set) and follows the
storage: the progress bar, the journal and the tables count every worker's designs. On Linux,
with a file storage (the embedded journal, SQLite) and single-threaded evaluations, the workers
are forked from the run once it has checked the study and loaded the compiled kernels, so a
worker starts in milliseconds instead of seconds (imports, the study, the kernels); otherwise
each is a ``parasynth worker`` process. ``parasynth worker STUDY --storage URL`` joins a study
from any machine that reaches the storage. Every worker asks the storage for a trial, evaluates
it and stores the result with the design's record; a worker stops when the study holds its
budget of counted trials, and waits (instead of stopping early) while trials of other workers
are still running, so a trial of a killed worker is retried rather than lost. A worker that
loses the storage retries ``PARASYNTH_STORAGE_RETRIES`` times (default 3, after 1, 2, 4 s),
then exits with a message; its unfinished trial is failed by the heartbeat (server storage)
or when its process is found dead (local storage) and is proposed again.
"""

from __future__ import annotations

import contextlib
import datetime
import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import traceback
import warnings
from pathlib import Path

import numpy as np

from .defaults import optuna_algorithm
from .evaluate import Evaluator
from .journal import jsonable
from .optuna_adapter import (StructureIndex, StructureView, fail_stale, fail_trial, heartbeat_enabled, heartbeat_thread,
                             set_trial_system_attr, study_identity)
from .schedule import ATTR_STRUCTURE, structure_schedule
from .signals import Interrupt
from .spec import StudyError
from .storage import (ATTR_OVER_BUDGET, ATTR_RECORD, counts, is_shared_server, load_parasynth_study, name_objectives,
                      open_storage, trial_record)
from .structure_space import STRUCTURE

__all__ = ["Interrupt", "PerTrialSeeded", "make_sampler", "optuna_objective", "optimize_loop", "run_local_workers",
           "StorageLost", "owner_id", "budget_state", "within_budget", "can_fork_workers", "forked_worker_main",
           "optimize_budget", "assign_structure"]


class StorageLost(StudyError):
    """The storage stopped answering and did not come back within the retries."""


# -- samplers --------------------------------------------------------------------------------------------
def derive_seed(seed: int, number: int) -> int:
    return int(np.random.SeedSequence([int(seed) % 2**32, int(number)]).generate_state(1)[0])


def _with_population(cls):
    def make(optuna, seed, cf, pop):
        return getattr(optuna.samplers, cls)(seed=seed, constraints_func=cf, **({"population_size": pop} if pop else {}))
    return make


#: Optuna's samplers by ``optimizer.algorithm``: (optuna, seed, constraints function, population) -> sampler.
SAMPLERS = {
    "tpe": lambda optuna, seed, cf, pop: optuna.samplers.TPESampler(seed=seed, constraints_func=cf, multivariate=True),
    "nsga2": _with_population("NSGAIISampler"),
    "nsga3": _with_population("NSGAIIISampler"),
    "random": lambda optuna, seed, cf, pop: optuna.samplers.RandomSampler(seed=seed),
    "qmc": lambda optuna, seed, cf, pop: optuna.samplers.QMCSampler(seed=seed, scramble=True),
    "cmaes": lambda optuna, seed, cf, pop: optuna.samplers.CmaEsSampler(seed=seed),
}
#: Samplers of one objective only.
SINGLE_OBJECTIVE_SAMPLERS = ("cmaes",)


def _base_sampler(study, seed, constraints_func):
    import optuna  # lazy: optuna takes about a second to import; sweeps and NLopt never need it

    alg = optuna_algorithm(study)
    if alg not in SAMPLERS:
        raise StudyError(f"optimizer.algorithm: unknown {alg!r}; allowed: {', '.join(SAMPLERS)}")
    if alg in SINGLE_OBJECTIVE_SAMPLERS and len(study.objectives) > 1:
        raise StudyError(f"optimizer.algorithm: {alg} is single-objective; use nsga2 or tpe")
    return SAMPLERS[alg](optuna, seed, constraints_func, study.optimizer.population_size)


_PER_TRIAL_CLASS = None


def _per_trial_class():
    """:class:`PerTrialSeeded`, built on first use (Optuna is imported only by Optuna runs)."""
    global _PER_TRIAL_CLASS
    if _PER_TRIAL_CLASS is not None:
        return _PER_TRIAL_CLASS
    from optuna.samplers import BaseSampler  # lazy: optuna takes about a second to import

    class PerTrialSeeded(BaseSampler):
        """A sampler whose proposal for trial ``k`` comes from ``factory(derive_seed(seed, k))``;
        ``per_trial=False`` (QMC: the scrambling must be the same for every point, the sequence
        index is stored in the study) keeps one sampler seeded with ``seed``."""

        def __init__(self, factory, seed: int, per_trial: bool = True, assign=None):
            self._factory = factory
            self._seed = int(seed)
            self._per_trial = per_trial
            self._fixed = factory(self._seed)
            self._cur = (None, None)
            self._assign = assign  # (study, trial) -> structure, asked before the trial's proposal
            self._assigned = {}
            self._spaces = {}  # {structure or None: the search space kept across trials (_keep_space)}
            self._index = (None, None)  # (the study's key, its StructureIndex): see _view

        @property
        def inner(self):
            return self._fixed

        def _for(self, trial):
            if not self._per_trial:
                return self._fixed
            n = trial.number
            if self._cur[0] != n:
                self._cur = (n, self._keep_space(self._factory(derive_seed(self._seed, n)), n))
            return self._cur[1]

        def _keep_space(self, sampler, number: int):
            """``sampler`` with the intersection search space of the trials it sees (those of
            trial ``number``'s structure) kept from the trials before it: a multivariate TPE
            sampler computes that space incrementally (Optuna's ``IntersectionSearchSpace``,
            exact: it resumes after the last trial it read, and before the first that was
            still running), but a new sampler each trial started from none and compared
            every stored trial's distributions again (~15 % of a structure study's proposal
            time, O(n^2) over a study). The same space, so the same proposals. A sampler without
            that attribute (another algorithm, a grouped TPE, another Optuna) keeps its own."""
            space = getattr(sampler, "_search_space", None)
            if type(space).__name__ != "IntersectionSearchSpace" or getattr(sampler, "_group", False):
                return sampler
            key = self._assigned.get(number)
            kept = self._spaces.get(key)
            if kept is None:
                kept = self._spaces[key] = space
            else:
                sampler._search_space = kept
            return sampler

        def fixed(self, number: int) -> dict:
            """Design values fixed for trial ``number`` by the schedule (the structure), else {}."""
            s = self._assigned.get(number)
            return {} if s is None else {STRUCTURE: s}

        def _view(self, study, trial):
            """The study as the trial's sampler sees it: only its structure's trials, picked by
            the study's :class:`StructureIndex` (kept while the sampler proposes for the same
            study)."""
            s = self._assigned.get(trial.number)
            if s is None:
                return study
            key = study_identity(study)
            if self._index[0] != key:
                self._index = (key, StructureIndex(ATTR_STRUCTURE))
            return StructureView(study, ATTR_STRUCTURE, s, self._index[1])

        def infer_relative_search_space(self, study, trial):
            return self._for(trial).infer_relative_search_space(self._view(study, trial), trial)

        def sample_relative(self, study, trial, search_space):
            return self._for(trial).sample_relative(self._view(study, trial), trial, search_space)

        def sample_independent(self, study, trial, param_name, param_distribution):
            return self._for(trial).sample_independent(self._view(study, trial), trial, param_name, param_distribution)

        def before_trial(self, study, trial):
            if self._assign is not None:
                s = self._assign(study, trial)
                set_trial_system_attr(study, trial, ATTR_STRUCTURE, s)
                self._assigned = {trial.number: s}
            self._for(trial).before_trial(self._view(study, trial), trial)

        def after_trial(self, study, trial, state, values):
            self._for(trial).after_trial(self._view(study, trial), trial, state, values)

        def reseed_rng(self):
            pass  # proposals are seeded per trial

    _PER_TRIAL_CLASS = PerTrialSeeded
    return PerTrialSeeded


def PerTrialSeeded(factory, seed: int, per_trial: bool = True, assign=None):  # noqa: N802 (a class, built lazily)
    """A sampler proposing trial ``k`` with ``factory(derive_seed(seed, k))`` (see the module
    docstring); with ``assign(study, trial) -> structure`` (a study over structures) each trial is
    first given its structure and proposed from that structure's trials only."""
    return _per_trial_class()(factory, seed, per_trial, assign)


def _uses_set_constraint() -> bool:
    import optuna  # lazy: optuna takes about a second to import

    return hasattr(optuna.trial.Trial, "set_constraint")


def _constraints_func(trial):
    return trial.user_attrs.get("constraints", [1.0])


def make_sampler(study, seed):
    """The study's sampler, seeded per trial (see :class:`PerTrialSeeded`)."""
    cf = _constraints_func if study.constraints and not _uses_set_constraint() else None
    alg = optuna_algorithm(study)
    schedule = structure_schedule(study)
    known: dict = {}  # the sampler's parsed records of counted trials (see _stored_records)
    assign = (lambda ostudy, trial: assign_structure(schedule, ostudy, known)) if schedule is not None else None
    return PerTrialSeeded(lambda s: _base_sampler(study, s, cf), seed, per_trial=(alg != "qmc"), assign=assign)


def _stored_records(ostudy, known: dict | None = None) -> list:
    """The records of the counted trials of ``ostudy``. With ``known`` (a dict kept by the caller
    between calls) each counted trial's record is parsed once: a counted trial is finished and
    its record no longer changes, and a structure study asks for all of them before every trial
    (parsing every one each time made a study of n trials parse n^2 / 2 records: 550,000 and ~4 s
    of a 1,050-trial run)."""
    trials = ostudy.get_trials(deepcopy=False)
    if known is None:
        return [r for r in (trial_record(t) for t in trials if counts(t)) if r is not None]
    # the trials before the first one still running or waiting are final (a trial that finished
    # uncounted, failed without a record, never counts): their records are kept in ``known``
    # with their number, and only the later trials are read
    head = ("final", ostudy.study_name)
    done, kept = known.get(head, (0, ()))
    if done > len(trials) or (done and trials[done - 1].number != done - 1):
        done, kept = 0, ()
    out = list(kept)
    n_final = len(out)
    final = True
    for t in trials[done:]:
        key = (ostudy.study_name, t.number)
        if key in known:
            r = known[key]
        elif counts(t):
            r = known[key] = trial_record(t)
        else:
            r = None
        if r is not None:
            out.append(r)
        if final and t.state.is_finished():
            done += 1
            n_final = len(out)
        else:
            final = False
    known[head] = (done, tuple(out[:n_final]))
    return out


def assign_structure(schedule, ostudy, known: dict | None = None) -> str:
    """The structure of the trial being asked (:meth:`~parasynth.study.schedule.Schedule.next_structure`
    given the stored designs and the trials other processes are evaluating); ``known``: the
    caller's records already parsed (:func:`_stored_records`)."""
    from optuna.trial import TrialState  # lazy: optuna takes about a second to import

    running = {}
    for t in ostudy.get_trials(deepcopy=False, states=(TrialState.RUNNING, TrialState.WAITING)):
        s = t.system_attrs.get(ATTR_STRUCTURE)
        if s is not None:
            running[s] = running.get(s, 0) + 1
    return schedule.next_structure(schedule.plan(_stored_records(ostudy, known)), running)


def _set_optuna_constraints(trial, study, rec):
    """Our margins count >= 0 as feasible, Optuna's constraint values <= 0: convert here, in
    one place. Optuna >= 5 reads ``Trial.set_constraint``; older versions a
    ``constraints_func`` that returns the user attribute set here."""
    vals = [(-m if math.isfinite(m) else 1e9) for m in rec.margins.values()]
    if rec.status != "ok":
        vals = [1e9 for _ in study.constraints]
    if hasattr(trial, "set_constraint"):
        for c, v in zip(study.constraints, vals):
            trial.set_constraint(c.label, v)
    else:
        trial.set_user_attr("constraints", vals or [0.0])


OWNER_ATTR = "parasynth:owner"


def owner_id() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def optuna_objective(study, evaluator: Evaluator, on_record=None, guard: Interrupt | None = None,
                     mark_owner: bool = False):
    """The Optuna objective of a study: suggest the design variables, evaluate the design
    (``evaluator.evaluate(values, trial=k)``: the run's :class:`~parasynth.study.problem.Problem`,
    or an :class:`Evaluator` in a worker process),
    store its record (trial user attribute ``record``) and constraints, hand the record to
    ``on_record``, return the objectives (NaN for a failed design, which Optuna records as a
    failed trial that still counts as an evaluated design)."""
    guard = guard or Interrupt()

    def objective(trial):
        if mark_owner:
            trial.set_user_attr(OWNER_ATTR, owner_id())
        fixed = trial.study.sampler.fixed(trial.number) if hasattr(trial.study.sampler, "fixed") else {}
        values = study.space.suggest(trial, fixed=fixed)  # conditional variables only when active
        with guard.evaluating():
            rec = evaluator.evaluate(values, trial=trial.number)
        _set_optuna_constraints(trial, study, rec)
        trial.set_user_attr(ATTR_RECORD, jsonable(rec.to_dict()))
        objective.stats["records"] += 1
        if on_record is not None:
            on_record(rec)
        if rec.status != "ok":
            return tuple(float("nan") for _ in study.objectives) if len(study.objectives) > 1 else float("nan")
        vals = tuple(rec.objectives[o.label] for o in study.objectives)
        return vals if len(vals) > 1 else vals[0]

    objective.stats = {"records": 0}
    return objective


# -- the loop every process runs -------------------------------------------------------------------------
def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _stale_here(t) -> bool:
    """A running trial owned by a process of this host that no longer exists."""
    owner = t.user_attrs.get(OWNER_ATTR)
    if not isinstance(owner, str) or ":" not in owner:
        return False
    host, _, pid = owner.rpartition(":")
    return host == socket.gethostname() and pid.isdigit() and int(pid) != os.getpid() and not _pid_alive(int(pid))


#: Seconds after which a running trial that never recorded its owner counts as abandoned: its
#: process stopped between asking for the trial and its first write (e.g. the storage went away
#: then), so neither the owner check below nor Optuna's heartbeat (no beat was ever stored) can
#: fail it. A live process records its owner milliseconds after asking.
ORPHAN_AGE_S = float(os.environ.get("PARASYNTH_ORPHAN_AGE", "30"))


def _orphaned(t) -> bool:
    """A running trial without a recorded owner, started over ``ORPHAN_AGE_S`` seconds ago."""
    if t.user_attrs.get(OWNER_ATTR) is not None or t.datetime_start is None:
        return False
    start = t.datetime_start
    now = datetime.datetime.now(start.tzinfo) if start.tzinfo is not None else datetime.datetime.now()
    return (now - start).total_seconds() > ORPHAN_AGE_S


def budget_state(ostudy):
    """(counted, running, waiting) trials of the study; running trials of dead local
    processes, and trials abandoned before their owner was recorded, are marked failed on the
    way (their designs are proposed again)."""
    from optuna.trial import TrialState  # lazy: optuna takes about a second to import

    counted = running = waiting = 0
    for t in ostudy.get_trials(deepcopy=False):
        if counts(t):
            counted += 1
        elif t.state == TrialState.RUNNING:
            if _stale_here(t) or _orphaned(t):
                with contextlib.suppress(Exception):
                    fail_trial(ostudy, t)
            else:
                running += 1
        elif t.state == TrialState.WAITING:
            waiting += 1
    return counted, running, waiting


def _storage_errors():
    import optuna  # lazy: optuna takes about a second to import

    errs = [optuna.exceptions.StorageInternalError, OSError, ConnectionError]
    # SQLAlchemy's errors, when a storage loaded it (a server or SQLite storage): importing it
    # for a journal file would cost a worker 0.2 s of start-up for nothing.
    sa_exc = sys.modules.get("sqlalchemy.exc")
    if sa_exc is not None:
        errs += [sa_exc.OperationalError, sa_exc.DBAPIError]
    return tuple(errs)


def _root_cause(e: BaseException) -> str:
    """The first line of the innermost cause (the driver's message, not Optuna's wrapper)."""
    seen = set()
    while (e.__cause__ or e.__context__) is not None and id(e) not in seen:
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    orig = getattr(e, "orig", None)
    if orig is not None:
        e = orig
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0]}" if text else type(e).__name__


def within_budget(ostudy, number: int, total: int, targets: dict | None = None) -> bool:
    """May trial ``number`` (just asked for, running) be evaluated within a budget of
    ``total`` counted trials? Yes when fewer than ``total`` trials of lower number count or
    are still running: of two workers that both saw one place left and asked at once, the one
    with the lower trial number is given it. ``targets`` ({structure: designs}, a study over
    structures): the same rule per structure, for the trial's structure and its rung's target."""
    from optuna.trial import TrialState  # lazy: optuna takes about a second to import

    trials = ostudy.get_trials(deepcopy=False)
    mine = None
    if targets is not None:
        me = next((t for t in trials if t.number == number), None)
        mine = me.system_attrs.get(ATTR_STRUCTURE) if me is not None else None
        for _ in range(20):  # a trial asked for just before this one may not have its structure yet
            if not any(t.number < number and t.state == TrialState.RUNNING and ATTR_STRUCTURE not in t.system_attrs
                       for t in trials):
                break
            time.sleep(0.01)
            trials = ostudy.get_trials(deepcopy=False)
    ahead = same = 0
    for t in trials:
        if t.number < number and (counts(t) or t.state == TrialState.RUNNING):
            ahead += 1
            if mine is not None and t.system_attrs.get(ATTR_STRUCTURE) == mine:
                same += 1
    if ahead >= total:
        return False
    return mine is None or mine not in targets or same < targets[mine]


def run_one_trial(ostudy, objective, storage_errors=(), admit=None):
    """Ask for a trial, evaluate it, tell the result: Optuna's ask-and-tell with its heartbeat
    (server storages), so that a storage error reaches the caller as itself (Optuna's own
    loop turns a storage error while telling into an ``UnboundLocalError``).

    ``admit(trial)``: checked once the trial is asked for; a trial it refuses is failed
    unevaluated, without a record (it does not count) and marked ``parasynth:over_budget``.
    Returns the trial's number, or None when it was refused."""
    from optuna.trial import TrialState  # lazy: optuna takes about a second to import

    if heartbeat_enabled(ostudy):
        fail_stale(ostudy)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "heartbeat is supposed to be used with Study.optimize": it is, below
        trial = ostudy.ask()
    if admit is not None and not admit(trial):
        trial.set_user_attr(ATTR_OVER_BUDGET, True)
        ostudy.tell(trial, state=TrialState.FAIL, skip_if_finished=True)
        return None
    with heartbeat_thread(ostudy, trial):
        try:
            value = objective(trial)
        except KeyboardInterrupt:
            with contextlib.suppress(Exception):
                ostudy.tell(trial, state=TrialState.FAIL, skip_if_finished=True)
            raise
        except storage_errors:
            raise  # the trial stays running; it is failed as stale and proposed again
        except Exception:  # noqa: BLE001 (a fault outside the design evaluation: the trial fails)
            ostudy.tell(trial, state=TrialState.FAIL, skip_if_finished=True)
            return trial.number
    vals = value if isinstance(value, tuple) else (value,)
    if any(v is None or (isinstance(v, float) and math.isnan(v)) for v in vals):
        ostudy.tell(trial, state=TrialState.FAIL, skip_if_finished=True)  # a failed design (recorded)
    else:
        ostudy.tell(trial, list(vals) if len(vals) > 1 else vals[0])
    return trial.number


def optimize_loop(ostudy, objective, total: int, guard: Interrupt, shared: bool, counted: int = 0,
                  on_count=None, poll_s: float = 0.5, retries: int | None = None, log=None, targets=None):
    """Run trials until the study holds ``total`` counted trials or an interrupt is asked for.

    ``shared``: other processes may work on the study (count in the storage before every
    trial, wait for their running trials); otherwise ``counted`` is the number of counted
    trials at the start and this process is the only one. ``targets``: designs per structure
    of a rung (:func:`within_budget`). Returns the number of trials run here."""
    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    retries = int(os.environ.get("PARASYNTH_STORAGE_RETRIES", "3")) if retries is None else retries
    errors = _storage_errors()
    old_hook = threading.excepthook

    def quiet_hook(hook_args):
        # Optuna's heartbeat thread meets a lost storage first: this loop reports it once.
        if not issubclass(hook_args.exc_type, errors):
            old_hook(hook_args)

    threading.excepthook = quiet_hook
    try:
        return _loop(ostudy, objective, total, guard, shared, counted, on_count, poll_s, retries, log, errors,
                     targets)
    finally:
        threading.excepthook = old_hook


def optimize_budget(ostudy, objective, study, total: int, guard: Interrupt, shared: bool, counted: int = 0,
                    **kw) -> int:
    """:func:`optimize_loop` to ``total`` counted trials; for a study over structures rung by
    rung (:mod:`parasynth.study.schedule`): the loop runs to the current rung's total, then the
    next rung is decided from the stored designs, until the schedule is done (``total`` is then
    only an upper bound). Returns the number of trials run here."""
    schedule = structure_schedule(study)
    if schedule is None:
        return optimize_loop(ostudy, objective, total, guard, shared, counted=counted, **kw)
    ran = 0
    while not guard.requested:
        plan = schedule.plan(_stored_records(ostudy))
        if plan.done:
            break
        targets = {st: plan.current.target for st in plan.current.alive}
        ran += optimize_loop(ostudy, objective, plan.total, guard, shared, counted=plan.counted, targets=targets, **kw)
    return ran


def _loop(ostudy, objective, total, guard, shared, counted, on_count, poll_s, retries, log, errors, targets=None):
    import optuna  # lazy: optuna takes about a second to import

    failures = 0
    ran = 0
    while not guard.requested:
        try:
            if shared:
                counted, running, waiting = budget_state(ostudy)
                if on_count is not None:
                    on_count(counted)
                if counted >= total:
                    break
                if waiting == 0 and counted + running >= total:
                    # The others' trials complete the budget unless their worker died:
                    # wait for them (a dead worker's trial is failed and proposed again).
                    fail_stale(ostudy)
                    time.sleep(poll_s)
                    continue
            elif counted >= total:
                break
            n0 = objective.stats["records"]
            admit = (lambda trial: within_budget(ostudy, trial.number, total, targets)) if shared else None
            if run_one_trial(ostudy, objective, errors, admit=admit) is None:
                continue  # another worker took the last place first: wait for it above
            ran += 1
            if not shared:
                counted += objective.stats["records"] - n0
            failures = 0
        except KeyboardInterrupt:
            raise
        except optuna.exceptions.UpdateFinishedTrialError:
            # our trial was failed by another process that took this one for dead
            failures = 0
            continue
        except errors as e:
            failures += 1
            if failures > retries:
                raise StorageLost(f"lost the storage ({_root_cause(e)}); "
                                  f"gave up after {retries} retries. The study stays consistent: trials stored "
                                  f"are kept and an unfinished one is proposed again; start the worker again "
                                  f"when the storage is back") from None
            wait = 2 ** (failures - 1)
            log(f"storage error ({_root_cause(e)}); retrying in {wait} s ({failures}/{retries})")
            time.sleep(wait)
    return ran


# -- local worker processes ------------------------------------------------------------------------------
def worker_env(n_workers: int) -> dict:
    """Environment of a worker process: single-threaded evaluations when the workers share
    the cores (unless the user set the thread counts)."""
    env = dict(os.environ)
    threads = str(max(1, (os.cpu_count() or 1) // max(1, n_workers)))
    for k in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(k, threads)
    return env


def _env_threads(env: dict) -> int:
    try:
        return int(env.get("NUMBA_NUM_THREADS", "1"))
    except ValueError:
        return 0


def can_fork_workers(url: str, n_workers: int) -> bool:
    """Are local workers forked from the run (see the module docstring)? On Linux, with a file
    storage (a server storage's connections are not shared with a child) and one evaluation
    thread per worker (the engine's crew of threads does not survive a fork: a forked worker
    evaluates on its own thread)."""
    return (sys.platform.startswith("linux") and hasattr(os, "fork") and not is_shared_server(url)
            and _env_threads(worker_env(n_workers)) == 1
            and os.environ.get("PARASYNTH_SPAWN_WORKERS", "").strip().lower() not in ("1", "true", "yes", "on"))


class _Forked:
    """A forked worker, with the part of ``subprocess.Popen``'s interface used here."""

    def __init__(self, pid: int):
        self.pid = pid
        self.returncode = None

    def _reap(self, flags: int):
        if self.returncode is None:
            try:
                pid, status = os.waitpid(self.pid, flags)
            except ChildProcessError:  # reaped elsewhere
                self.returncode = -1
                return self.returncode
            if pid:
                self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def poll(self):
        return self._reap(os.WNOHANG)

    def wait(self):
        return self._reap(0)

    def send_signal(self, sig):
        if self.returncode is None:
            os.kill(self.pid, sig)

    def kill(self):
        self.send_signal(signal.SIGKILL)


def _single_threaded_evaluations() -> None:
    """In a forked worker: evaluations on the worker's own thread (the engine spreads a
    batch over ``numba.config.NUMBA_NUM_THREADS`` threads of a pool the fork did not copy)."""
    numba = sys.modules.get("numba")
    if numba is not None:
        numba.config.NUMBA_NUM_THREADS = 1
    for k in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[k] = "1"


def forked_worker_main(study, evaluator, url: str, name: str, total: int, seed: int) -> int:
    """The loop of a forked worker (what ``parasynth worker`` does, without loading and
    checking the study again: the run did). Returns the exit code (0, 130 interrupted, 3 lost
    the storage)."""
    import optuna  # lazy: optuna takes about a second to import (already imported by the run)

    optuna.logging.set_verbosity(optuna.logging.ERROR)
    with Interrupt(quiet=True) as guard:
        try:
            ostudy = load_parasynth_study(open_storage(url), url, name)
            name_objectives(ostudy, study)
            ostudy.sampler = make_sampler(study, seed)
            objective = optuna_objective(study, evaluator, guard=guard, mark_owner=True)
            # A file storage is cheap to poll: a worker waiting for the others' last trials
            # sees the budget reached within milliseconds.
            optimize_budget(ostudy, objective, study, int(total), guard, shared=True, poll_s=0.05)
        except KeyboardInterrupt:
            guard.requested = True
        except StorageLost as e:
            print(f"error: worker {owner_id()}: {e}", file=sys.stderr, flush=True)
            return 3
        except StudyError as e:
            print(f"error: worker {owner_id()}: {e}", file=sys.stderr, flush=True)
            return 2
    return 130 if guard.requested else 0


def _fork_worker(target, quiet: bool) -> _Forked:
    """Fork a worker running ``target()`` (its exit code) in a session of its own."""
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid:
        return _Forked(pid)
    code = 1
    try:  # the child: never returns into the parent's code, never runs its exit handlers
        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, signal.SIG_DFL)  # the run's handlers (and their forwarding) are not ours
        os.setsid()  # a terminal's Ctrl-C reaches the run, which forwards it once
        if quiet:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 1)
            os.close(devnull)
        _single_threaded_evaluations()
        code = target()
    except BaseException:  # noqa: BLE001 (reported; the exit code tells the run)
        with contextlib.suppress(Exception):
            traceback.print_exc()
    finally:
        with contextlib.suppress(Exception):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(code)


def run_local_workers(study_file: Path, url: str, n_workers: int, total: int, ostudy, guard: Interrupt,
                      on_new=None, poll_s: float = 0.3, quiet: bool = True, fork=None):
    """Start ``n_workers`` workers on ``url`` and follow the storage until they exit;
    ``on_new(records)`` receives the newly counted designs. Signals that reach this process are
    forwarded to the workers (each in its own session, so a terminal Ctrl-C reaches them once,
    through here). Returns the workers' exit codes.

    ``fork``: ``(study, evaluator, seed)`` of this run: the workers are forked from this
    process when :func:`can_fork_workers` (they start at once, with the study checked and the
    kernels loaded); otherwise, and without it, each is a ``parasynth worker`` process."""
    procs = []

    def forward(signum):
        for p in procs:
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    p.send_signal(signal.SIGINT)

    guard.on_signal = forward
    seen = set()

    def sync():
        new = []
        for t in ostudy.get_trials(deepcopy=False):
            if t.number not in seen and counts(t):
                rec = trial_record(t)
                if rec is not None:
                    seen.add(t.number)
                    new.append(rec)
        if new and on_new is not None:
            on_new(sorted(new, key=lambda r: r.trial))

    for t in ostudy.get_trials(deepcopy=False):
        if counts(t):
            seen.add(t.number)
    if fork is not None and can_fork_workers(url, n_workers):
        study, evaluator, seed = fork
        name = ostudy.study_name
        for _ in range(n_workers):
            procs.append(_fork_worker(lambda: forked_worker_main(study, evaluator, url, name, total, seed), quiet))
    else:
        cmd = [sys.executable, "-m", "parasynth.cli", "worker", str(study_file), "--storage", url,
               "--n-trials", str(total), "--quiet"]
        env = worker_env(n_workers)
        for _ in range(n_workers):
            procs.append(subprocess.Popen(cmd, env=env, start_new_session=True,
                                          stdout=subprocess.DEVNULL if quiet else None))
    try:
        last = time.monotonic()
        while any(p.poll() is None for p in procs):
            time.sleep(min(poll_s, 0.02))  # a worker's end is seen at once, the storage read every poll_s
            if time.monotonic() - last >= poll_s:
                sync()
                last = time.monotonic()
    except KeyboardInterrupt:  # a third signal: stop the workers now
        for p in procs:
            with contextlib.suppress(ProcessLookupError):
                p.kill()
        for p in procs:
            p.wait()
        raise
    finally:
        guard.on_signal = None
    sync()
    return [p.returncode for p in procs]
