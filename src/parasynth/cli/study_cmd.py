"""The study commands of the command line that take parsed arguments: ``parasynth worker``,
``parasynth report --storage``, and what ``parasynth run`` does after an interrupt (partial
report, resume command). The command line orchestrates: the study layer runs, the report
layer writes reports; neither calls the other. :mod:`parasynth.cli` imports this module
when one of these commands runs."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from ..report import ReportError, write_report
from ..study.budget import same_study
from ..study.defaults import optimizer_seed, optuna_budget
from ..study.evaluate import Evaluator
from ..study.progress import Progress
from ..study.signals import Interrupt
from ..study.spec import StudyError, load_study
from ..study.storage import (ATTR_BUDGET, ATTR_STUDY, counts, describe_url, load_parasynth_study, materialize_run,
                             name_objectives, open_storage)
from ..study.workers import StorageLost, make_sampler, optimize_budget, optuna_objective, owner_id

__all__ = ["cmd_worker", "cmd_report_storage", "resume_command", "interrupted_run"]


def _err(msg) -> int:
    print(f"error: {msg}", file=sys.stderr)
    return 2


def cmd_worker(args) -> int:
    """``parasynth worker STUDY --storage URL``: join a study started by ``parasynth run``."""
    import optuna  # lazy: optuna takes about a second to import

    try:
        study = load_study(args.study)
        if not study.optimizer.plugin.uses_storage:
            return _err(f"{args.study}: optimizer.kind is {study.optimizer.kind!r}; workers join Optuna studies "
                        f"(the other optimisers run in one process: parasynth run)")
        url = args.storage or study.optimizer.storage
        if not url:
            return _err("parasynth worker needs the study's storage: --storage URL (or optimizer.storage in the file)")
        storage = open_storage(url)
        name = getattr(args, "study_name", None) or study.name
        seed = optimizer_seed(study)
        ostudy = load_parasynth_study(storage, url, name)
        stored = ostudy.user_attrs.get(ATTR_STUDY)
        if stored is not None and not same_study(stored, study.to_yaml()):
            return _err(f"{args.study}: differs from the study {name!r} stored in {describe_url(url)!r}; "
                        f"use the same study file as the run that started it")
        name_objectives(ostudy, study)
        ostudy.sampler = make_sampler(study, seed)
        total = optuna_budget(study, args.n_trials, stored=ostudy.user_attrs.get(ATTR_BUDGET))
        if total < 1:
            return _err(f"--n-trials must be a positive number of trials, got {total}")
    except StudyError as e:
        return _err(e)
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    evaluator = Evaluator(study)
    bar = Progress(int(total), not args.quiet, f"worker {name}")
    mine = []

    with Interrupt(quiet=args.quiet) as guard:
        objective = optuna_objective(study, evaluator, on_record=mine.append, guard=guard, mark_owner=True)
        try:
            optimize_budget(ostudy, objective, study, int(total), guard, shared=True, on_count=bar.set_count)
        except KeyboardInterrupt:
            guard.requested = True
        except StorageLost as e:
            bar.close()
            print(f"error: worker {owner_id()}: {e}", file=sys.stderr)
            return 3
        finally:
            bar.close()
    try:
        n = sum(1 for t in ostudy.get_trials(deepcopy=False) if counts(t))
    except Exception:
        n = None
    state = f"the study holds {n} of {total} designs" if n is not None else "the storage did not answer at the end"
    print(f"worker {owner_id()}: {len(mine)} designs evaluated here; {state}")
    if guard.requested:
        print(f"interrupted; join again with: parasynth worker {args.study} --storage URL", file=sys.stderr)
        return 130
    return 0


def cmd_report_storage(args) -> int:
    """``parasynth report --storage URL --study NAME``: rebuild the run directory from the
    storage (``--run-dir``, default ``runs/NAME``) and write its report."""
    name = args.study
    if not name:
        return _err("report --storage needs --study NAME (the study's name)")
    run_dir = Path(getattr(args, "rebuild_dir", None) or Path("runs") / name)
    try:
        materialize_run(args.storage, name, run_dir)
        rdir = write_report(run_dir, out=args.out)
    except (StudyError, ReportError) as e:
        return _err(e)
    print(f"run directory rebuilt from the storage: {run_dir}")
    print(f"report: {rdir / 'index.html'} (and report.md, pareto.csv)")
    return 0


def resume_command(args, res) -> str:
    """The command that continues an interrupted ``parasynth run``."""
    parts = ["parasynth", "run", str(args.study), "--resume"]
    if getattr(args, "out", None):
        parts += ["--out", str(args.out)]
    if getattr(args, "storage", None):
        parts += ["--storage", str(args.storage)]
    if getattr(args, "workers", None):
        parts += ["--workers", str(args.workers)]
    if getattr(args, "n_trials", None):
        parts += ["--n-trials", str(args.n_trials)]
    return " ".join(shlex.quote(p) for p in parts)


def interrupted_run(args, res) -> int:
    """After an interrupted ``parasynth run``: write the partial report (unless
    ``--no-report``), say how to resume, exit code 130."""
    if not getattr(args, "no_report", False) and res.n_total:
        try:
            rdir = write_report(res.out_dir, out=getattr(args, "report_dir", None))
            print(f"partial report: {rdir / 'index.html'}")
        except (ReportError, StudyError) as e:
            print(f"no report: {e}", file=sys.stderr)
    n_run, has_ref = res.saved_counts()
    ref = " and the reference design" if has_ref else ""
    print(f"interrupted: {n_run} designs{ref} are saved in {res.out_dir}; continue with: "
          f"{resume_command(args, res)}", file=sys.stderr)
    return 130
