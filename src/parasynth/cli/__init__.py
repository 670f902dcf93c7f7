"""Command-line interface: ``parasynth <command>``.

Commands
--------
run STUDY.yaml       run a design study (sweep, NLopt or Optuna) and write its results and report
                     (runs/<name>/, the report in runs/<name>/report/)
validate STUDY.yaml  check a study file (builds its designs, probes its measures) and print it
evaluate STUDY.yaml  evaluate one design of a study (all objectives and constraints)
report RUN_DIR       write index.html, report.md and pareto.csv for a run (in RUN_DIR/report/)
run-all [FOLDER]     run every study of a folder and write all reports (reports/README.md)
list                 mechanisms with their parameters, measures with their settings, optimisers
analyze NAME         kinematic analysis of a mechanism at its home pose and a pose sample
schema               the study file format as JSON Schema (for editors)
structures MOTION    candidate structures (limbs, actuation, arrangement) for a motion type such as 3T2R
export NAME|RUN_DIR  a mechanism or a run's design as MJCF (MuJoCo) or URDF with a closure file (Pinocchio)

Errors are handled in one place (:func:`main`): bad input, bad files and environment faults
(permissions, a full disk, a closed pipe, a missing plugin) give one line ``error: ...`` on
stderr and a non-zero exit status, with no traceback; ``--debug`` (or ``PARASYNTH_DEBUG=1``)
shows the traceback. Exit status: 0 success, 1 a failed evaluation or an environment fault,
2 invalid input, 130 interrupted, 141 output closed (broken pipe).
"""

from __future__ import annotations

import argparse
import dataclasses
import errno
import gc
import os
import sys
import warnings
from pathlib import Path

import numpy as np

from .. import __version__
from ..mechanisms import list_mechanisms, load_mechanism, mechanism_summaries
from . import early
from .plugins import load_plugins  # noqa: F401  (also parasynth.cli.load_plugins)
from ..common.units import SI_UNIT_KINDS, UNIT_KINDS, format_pose, format_quantity, in_display
from ..common.processes import compile_ahead_off
from ..common.validation import MAX_LEGS, MAX_SAMPLES, MAX_SEED, MAX_TRIALS
from ..common import columns as derived

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED, EXIT_PIPE = 0, 1, 2, 130, 141


class CliError(Exception):
    """A problem reported to the user as one line; ``code`` is the exit status."""

    def __init__(self, message: str, code: int = EXIT_USAGE):
        super().__init__(message)
        self.code = code


# -- argument types ------------------------------------------------------------------------------
def _count_type(what: str, lo: int, hi: int):
    def parse(text: str) -> int:
        try:
            v = int(text.strip().replace("_", ""))
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be an integer >= {lo}, got {text!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"{what} must be an integer >= {lo}, got {text!r}")
        if v > hi:
            raise argparse.ArgumentTypeError(f"{what} must be at most {hi} (the documented maximum), got {text!r}")
        return v

    parse.__name__ = what
    return parse


_n_trials = _count_type("the evaluation budget", 1, MAX_TRIALS)
_samples = _count_type("the sample count", 1, MAX_SAMPLES)
_seed = _count_type("the seed", 0, MAX_SEED)


def _path_arg(what: str):
    def parse(text: str) -> str:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"{what} must not be empty")
        if "\x00" in text:
            raise argparse.ArgumentTypeError(f"{what} contains a NUL character")
        return text

    parse.__name__ = what
    return parse


def _out_dir(path, flag: str) -> Path:
    """An output directory that exists (created) and is writable, or a CliError naming ``flag``."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise CliError(f"{flag} {str(p)!r} is an existing file, not a directory; give a directory")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise CliError(f"{flag} {str(p)!r}: cannot create the directory ({e.strerror or e})", EXIT_USAGE) from None
    if not os.access(p, os.W_OK | os.X_OK):
        raise CliError(f"{flag} {str(p)!r}: the directory is not writable")
    return p


# -- helpers -------------------------------------------------------------------------------------
def _parse_params(name: str, items: list[str], flag: str = "--param") -> dict:
    """--param (or ``flag``) NAME=VALUE items with units where the parameter has one ("link_length=205 mm")."""
    from ..mechanisms import mechanism_class
    from ..common.units import parse_quantity

    try:
        units = getattr(mechanism_class(name).Params, "UNITS", {})
    except ValueError:
        units = {}
    out = {}
    for it in items or []:
        if "=" not in it:
            raise CliError(f"{flag} expects NAME=VALUE, with a unit where the parameter has one, got {it!r}")
        k, v = (x.strip() for x in it.split("=", 1))
        kind = units.get(k)
        if kind is not None:
            out[k] = parse_quantity(v, kind, field=f"{flag} {k}")
        elif v.lower() in ("true", "false"):
            out[k] = v.lower() == "true"
        else:
            out[k] = v
    return out


def _fmt_pose(mech, X) -> str:
    return format_pose(mech.task_coordinates, mech.angular_coordinates, np.atleast_1d(X), ".3f")


def _fmt_value(v, kind) -> str:
    """A parameter or variable value (SI) in display units: '205 mm', '25 deg', '0.8'."""
    if isinstance(v, bool) or isinstance(v, str):
        return str(v).lower() if isinstance(v, bool) else v
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_fmt_value(x, kind) for x in v) + "]"
    if isinstance(v, (int, float, np.floating, np.integer)):
        return format_quantity(float(v), kind if kind not in (None, "dimensionless") else None, digits=6)
    return repr(v)


def _fmt_robust(item) -> str:
    """'; robust: quantile 0.05 of 32 scatter draws (seed 0), tolerances ...' for a robust item."""
    rm = getattr(item, "robust", None)
    if rm is None:
        return ""
    tols = ", ".join(f"{k} {v:g}" for k, v in (*rm.param_tolerances, *rm.leg_tolerances) if v)
    p = getattr(item, "probability", None)
    what = (f"probability >= {p:g} over" if p is not None else
            f"{rm.statistic}{'' if rm.level is None else f' {rm.level:g}'} of")
    return f"; robust: {what} {rm.samples} scatter draws (seed {rm.seed}), tolerances (SI) {tols}"


def _fmt_settings(measure: str, settings: dict | None) -> str:
    """A measure's settings (SI inside) in display units: 'mass=20 kg, point=[0 mm, 75 mm, 0 mm]'."""
    from ..measures.objectives import get

    kinds = get(measure).settings
    parts = []
    for k, x in (settings or {}).items():
        kind = kinds.get(k)
        if kind == "ranges" and isinstance(x, dict):
            parts.append(f"{k}={{" + ", ".join(f"{c}: {_fmt_value(list(v), 'angle' if c in _ANGLES else 'length')}"
                                               for c, v in x.items()) + "}")
        elif kind in UNIT_KINDS and kind != "dimensionless":
            parts.append(f"{k}={_fmt_value(x, kind)}")
        elif isinstance(x, float):
            parts.append(f"{k}={x:.6g}")
        else:
            parts.append(f"{k}={x}")
    return ", ".join(parts)


_ANGLES = {"alpha", "beta", "gamma", "psi", "theta", "phi"}
#: How `parasynth list` names a parameter kind where the kind's own name does not read well.
_KIND_NOUN = {"rotational_stiffness": "rotational stiffness", "pressure": "modulus"}


def _first_paragraph(doc: str) -> str:
    """A docstring's first paragraph on one line (whole sentences, never cut mid-sentence)."""
    para = doc.strip().split("\n\n")[0] if doc else ""
    return " ".join(para.split())


def _param_range(spec, kind) -> str:
    """', > 0 mm', ', in [0 deg, 90 deg]' for a described parameter's declared bounds."""
    if spec is None:
        return ""
    parts = []
    for attr, op in (("above", ">"), ("lo", ">="), ("below", "<"), ("hi", "<=")):
        v = getattr(spec, attr, None)
        if v is not None:
            parts.append(f"{op} {_fmt_value(v, kind)}")
    return (", " + " and ".join(parts)) if parts else ""


def _load_study(path):
    from ..study import load_study

    return load_study(path)


def _checked_study(path):
    """The study of ``path``, refusing it when :func:`check_study` finds a problem."""
    from ..study.spec import check_study

    from ..study import StudyError

    try:
        study = _load_study(path)
    except StudyError as e:
        msg = str(e)
        raise CliError(msg if str(path) in msg else f"{path}: {msg}") from None
    warnings: list = []
    problems = check_study(study, warnings=warnings)
    if problems:
        raise CliError(f"{path}: {len(problems)} problem(s):\n  " + "\n  ".join(problems))
    _print_warnings(path, warnings)
    return study


def _print_warnings(path, warnings) -> None:
    """What :func:`check_study` accepts but doubts, one ``warning:`` line each on stderr."""
    for w in warnings:
        print(f"warning: {path}: {w}", file=sys.stderr)


# -- commands ------------------------------------------------------------------------------------
def cmd_list(args) -> int:
    from ..mechanisms import mechanism_class
    from ..measures.objectives import OBJECTIVES
    from ..study import OPTIMIZERS

    print("mechanisms (parameters with their defaults; give values with units):")
    for name, summary in mechanism_summaries().items():
        print(f"  {name}: {summary}")
        cls = mechanism_class(name)
        units = getattr(cls.Params, "UNITS", {})
        params = cls.Params()
        specs = getattr(getattr(cls, "description", None), "param_by_name", None) or {}
        for f in dataclasses.fields(params):
            kind = units.get(f.name)
            unit = ("number" if kind == "dimensionless" else
                    f"{_KIND_NOUN.get(kind, kind)}, {UNIT_KINDS[kind].display}" if kind in UNIT_KINDS else
                    kind or "option")
            rng = _param_range(specs.get(f.name), kind)
            print(f"      {f.name} ({unit}{rng}) = {_fmt_value(getattr(params, f.name), kind)}")
        mech = cls(params)
        print(f"      task coordinates: {', '.join(mech.task_coordinates)}")
        for cname, c in mech.constraints.items():
            print(f"      pose constraint {cname} [{c.unit}]: {c.doc}")
    print("\nobjectives and design-constraint measures (name [unit], natural goal; settings: kind):")
    for name, m in OBJECTIVES.items():
        doc = _first_paragraph(m.doc)
        only = f" (only {', '.join(m.models)})" if m.models else ""
        print(f"  {name} [{m.unit}], {m.sense}{only}: {doc}")
        if m.settings:
            parts = []
            for k, p in m.params.items():
                field = f", sets the workspace sample's {p.sample_field}" if p.sample_field else ""
                parts.append(f"{k} ({p.allowed()}{field})")
            print(f"      settings: {', '.join(parts)}")
    print("\noptimisers (optimizer.kind: algorithms):")
    for kind, algs in OPTIMIZERS.items():
        print(f"  {kind}: {', '.join(algs)}")
    return EXIT_OK


def cmd_validate(args) -> int:
    from ..study.spec import check_study

    study = _load_study(args.study)
    stats: dict = {}
    warnings: list = []
    problems = check_study(study, measures=not args.quick, stats=stats, warnings=warnings)
    if problems:
        raise CliError(f"{args.study}: {len(problems)} problem(s):\n  " + "\n  ".join(problems))
    _print_warnings(args.study, warnings)
    from ..measures.display import fmt_column_value as fq, fmt_evaluation

    on = (f"the {study.structures.motion} structures {', '.join(study.structures.labels)}" if study.structures
          else study.mechanism)
    print(f"{args.study}: valid study {study.name} ({study.optimizer.kind}) on {on}")
    for v in study.variables:
        rng = f"[{fq(study, v.name, v.low)}, {fq(study, v.name, v.high)}]" if v.low is not None else ""
        vals = " values " + ", ".join(fq(study, v.name, x) for x in v.values) if v.values else ""
        ch = " choices " + ", ".join(fq(study, v.name, x) for x in v.choices) if v.choices else ""
        print(f"  variable {v.name} ({v.type}) {rng}{vals}{ch}".replace(")  ", ") "))
    for o in study.objectives:
        sets = _fmt_settings(o.name, o.settings)
        print(f"  objective {o.label}: {o.goal} {o.name}" + (f" ({sets})" if sets else "") + _fmt_robust(o))
    for c in study.constraints:
        col = derived.nominal(c.label) if c.probability is not None else c.label  # a chance constraint's bound
        bounds = [f"{b} {fq(study, col, x)}" for b, x in (("min", c.min), ("max", c.max)) if x is not None]
        sets = _fmt_settings(c.name, c.settings)
        print(f"  constraint {c.label}: {c.name} " + " ".join(bounds) + (f" ({sets})" if sets else "")
              + _fmt_robust(c))
    print(f"  evaluation: {fmt_evaluation(study)}")
    probe = (f"; {stats['measures']} measure(s) evaluated once on the first of them"
             if stats.get("measures") else "")
    built = stats.get("corners_built", stats.get("corners", 0))
    corners = (f"{stats.get('corners', 0)} corner(s) of the variable box" if built == stats.get("corners", 0) else
               f"{stats.get('corners', 0)} corner(s) of the variable box, {built} of them buildable")
    print(f"  checked: {stats.get('designs', 0)} design(s) (the reference or the box centre, {corners}){probe}"
          + (f"; {len(warnings)} warning(s)" if warnings else ""))
    return EXIT_OK


def _run_hint(args) -> str:
    out = f" --out {args.out}" if getattr(args, "out", None) else ""
    return f"parasynth run {args.study} --resume{out}"


def _compile_early(path, quiet: bool) -> None:
    """On an empty compile cache, start compiling in helper processes what the run will need
    before the study is even loaded (parasynth.engine.precompile.start_early), and say so: a
    structure study's kernels (``precompile.structure_kinds``) while its structures are
    enumerated, any other study's (``precompile.STUDY``: what nearly every study asks for) while
    it is loaded and checked -- whose probes draw the first sample points, which on a fresh
    machine imports scipy.stats (~0.6 s). The helper is started before the engine is imported
    when numba's cache seems empty (:mod:`parasynth.cli.early`). Anything unusual (an unreadable
    file, the NumPy engine asked for, no numba) starts nothing: the study's loading reports what
    is wrong, the run compiles as usual."""
    if compile_ahead_off():
        return
    try:
        import yaml

        with open(path, encoding="utf-8") as f:
            doc = yaml.safe_load(f)
        if not isinstance(doc, dict) or not isinstance(doc.get("evaluation") or {}, dict):
            return
        if (doc.get("evaluation") or {}).get("engine", "compiled") != "compiled":
            return
    except Exception:  # noqa: BLE001 - loading the study says what is wrong
        return
    structure = doc.get("structure")
    if isinstance(structure, dict):  # its own work first: the enumeration, seconds on one core
        what, legs = "structure", structure.get("leg_types")
        legs = [str(t) for t in legs] if isinstance(legs, list) else None
    else:  # its own work first: loading, the check's probes, the warm-up design on NumPy
        what, legs = "study", None
    helper = early.start(what, legs)  # before the engine's import (cli/early.py)
    from ..engine import COMPILING, core, precompile

    if not core.HAVE_NUMBA:  # (a broken numba the guess could not tell)
        early.stop(helper)
        return
    started = precompile.start_early(precompile.early_kinds(what, legs), helper=helper)
    if started and not quiet:
        print(COMPILING, file=sys.stderr, flush=True)


def _say_structures(study, quiet: bool) -> None:
    """For a study over structures, the structures it compares, once they are enumerated (the
    enumeration takes seconds, and a designer wants to know what the run weighs)."""
    setup = getattr(study, "structures", None)
    if setup is None or quiet:
        return
    ref = f"; reference {setup.reference}" if setup.reference else ""
    print(f"{setup.motion}: {len(setup.labels)} structure(s) to compare, of {setup.enumerated} candidate(s) "
          f"enumerated{ref}: {', '.join(setup.labels)}", file=sys.stderr, flush=True)


def _compile_chains_early(study) -> None:
    """Once a structure study's structures are enumerated: the kernels their chain limbs ask for
    (:func:`parasynth.engine.precompile.chain_kinds`) that were not started with the others
    (``leg_types`` not given, or the closure, which only a structure whose motion is computed
    from its limbs asks for; see :func:`parasynth.engine.precompile.structure_kinds`), started
    now, before the first design asks for them."""
    setup = getattr(study, "structures", None)
    if setup is None or compile_ahead_off():
        return
    from ..engine import core, precompile

    if core.HAVE_NUMBA and precompile.early():  # an empty cache: the early helpers were started
        kinds = precompile.chain_kinds(setup.structures.values())
        if kinds:
            precompile.start_early(kinds, processes=1)  # one helper for all of them


def cmd_run(args) -> int:
    _compile_early(args.study, args.quiet)
    try:
        return _run_command(args)
    finally:  # helpers started ahead and not waited for (the run failed or stopped before its warm-up)
        pre = sys.modules.get("parasynth.engine.precompile")
        if pre is not None:
            pre.stop_helpers()


def _run_command(args) -> int:
    from ..study import run_study

    study = _checked_study(args.study)
    _compile_chains_early(study)
    _say_structures(study, args.quiet)
    if args.resume:
        target = Path(args.out or study.spec.output or Path("runs") / study.name)
        shared = study.optimizer.plugin.uses_storage and (args.storage or study.optimizer.storage)
        if not target.exists() and not shared:
            raise CliError(f"--resume: the run directory {str(target)!r} does not exist, so there is nothing to "
                           f"resume; give the directory of the run (--out) or drop --resume to start a new run")
    if args.out is not None:
        _out_dir(args.out, "--out")
    if args.report_dir is not None and args.no_report:
        raise CliError("--report-dir and --no-report contradict each other: drop one")
    if args.report_dir is not None:
        _out_dir(args.report_dir, "--report-dir")
    res = run_study(study, out_dir=args.out, resume=args.resume, n_trials=args.n_trials, progress=not args.quiet,
                    storage=args.storage, workers=args.workers)
    from ..report.summary import run_summary

    print(run_summary(study, res))
    if res.interrupted:
        from .study_cmd import interrupted_run

        return interrupted_run(args, res)
    if not args.no_report:
        from ..report import ReportError, write_report

        try:
            rdir = write_report(res.out_dir, out=args.report_dir)
            print(f"report: {rdir / 'index.html'}")
        except ReportError as e:
            print(f"no report: {e}", file=sys.stderr)
    return EXIT_OK


def cmd_run_all(args) -> int:
    """Run every study of a folder (resuming finished or interrupted runs unless --fresh) and
    write each report, plus an index reports/README.md."""
    import shutil

    from ..report import ReportError, write_report
    from ..report.summary import run_summary
    from ..study import StudyError, load_study, run_study

    folder = Path(args.folder)
    if folder.exists() and not folder.is_dir():
        raise CliError(f"{str(folder)!r} is a file; give a folder of study files (*.yaml)")
    files = sorted(folder.glob("*.yaml")) if folder.is_dir() else []
    if args.only:
        files = [f for f in files if f.stem in args.only]
    if not files:
        raise CliError(f"no study files (*.yaml) in {str(folder)!r}" + (f" matching {args.only}" if args.only else ""))
    runs = _out_dir(args.runs, "--runs")
    reports = _out_dir(args.reports, "--reports")
    studies = [(f, _checked_study(f)) for f in files]  # every file is checked before any runs
    index = []
    for f, study in studies:
        out = runs / study.name
        if args.fresh and out.exists():
            shutil.rmtree(out)
        print(f"== {f} -> {out}", flush=True)
        res = run_study(study, out_dir=out, resume=out.exists(), progress=not args.quiet)
        print(run_summary(study, res))
        if res.interrupted:
            print("interrupted; run the same command again to continue", file=sys.stderr)
            return EXIT_INTERRUPTED
        try:
            rdir = write_report(out, out=reports / study.name, assets=reports / "assets")  # one plotly.js
        except ReportError as e:
            print(f"no report for {study.name}: {e}", file=sys.stderr)
            continue
        desc = " ".join(study.spec.description.split())
        index.append((study.name, rdir, desc))
    # The index lists every study of the folder that has a report, not only those run now.
    done = {name for name, _, _ in index}
    for f in sorted(folder.glob("*.yaml")):
        try:
            st = load_study(f)
        except StudyError:
            continue
        rdir = reports / st.name
        if st.name not in done and (rdir / "index.html").exists():
            index.append((st.name, rdir, " ".join(st.spec.description.split())))
    index.sort(key=lambda item: item[0])
    idx = reports / "README.md"
    lines = ["# Study reports", "", "Regenerate with `parasynth run-all studies` (add `--fresh` to rerun from "
             "scratch).", ""]
    for name, rdir, desc in index:
        lines.append(f"- [{name}]({name}/report.md) ([HTML]({name}/index.html)): {desc}")
    idx.write_text("\n".join(lines) + "\n")
    print(f"index: {idx}")
    return EXIT_OK


def cmd_report(args) -> int:
    from ..report import ReportError, write_report

    if args.storage or args.study:
        from .study_cmd import cmd_report_storage

        if not args.storage or args.run_dir:
            raise CliError("report --storage URL --study NAME rebuilds a run from a storage (no RUN_DIR); "
                           "report RUN_DIR reports a run directory")
        return cmd_report_storage(args)
    if args.rebuild_dir:
        raise CliError("--run-dir applies with --storage URL --study NAME (where the rebuilt run directory goes); "
                       "give the run directory to report as RUN_DIR")
    if not args.run_dir:
        raise CliError("report needs a RUN_DIR (or --storage URL --study NAME)")
    run_dir = Path(args.run_dir)
    if not run_dir.exists():
        raise CliError(f"run directory {str(run_dir)!r} does not exist")
    if not run_dir.is_dir():
        raise CliError(f"{str(run_dir)!r} is a file; give a run directory (runs/<study name>/)")
    if args.out is not None:
        _out_dir(args.out, "--out")
    try:
        rdir = write_report(run_dir, out=args.out)
    except (ReportError, OSError):
        raise
    except (ValueError, KeyError, IndexError, TypeError) as e:
        # A damaged run directory: a results.csv, final.csv or journal that does not parse.
        raise CliError(f"cannot report {str(run_dir)!r}: a file of the run is damaged or from another "
                       f"version ({type(e).__name__}: {e}); rerun the study or restore the file") from e
    print(f"report: {rdir / 'index.html'} (and report.md, pareto.csv)")
    return EXIT_OK


def cmd_worker(args) -> int:
    """``parasynth worker`` (:func:`parasynth.cli.study_cmd.cmd_worker`)."""
    from .study_cmd import cmd_worker as worker

    return worker(args)


def cmd_evaluate(args) -> int:
    from ..study import Evaluator
    from ..study.design import box_centre

    study = _checked_study(args.study)
    byname = {v.name: v for v in study.variables}
    base = dict(study.reference or {})
    centre = box_centre(study)  # the reference design, else the centre of the variable box
    values = {v.name: base[v.name] if v.name in base else centre[v.name] for v in study.variables
              if v.name in base or v.name in centre}
    for item in args.set or []:
        if "=" not in item:
            raise CliError(f"--set expects NAME=VALUE with units, got {item!r}")
        k, val = (x.strip() for x in item.split("=", 1))
        if k not in byname:
            raise CliError(f"--set {k}: not a design variable; variables: {', '.join(byname) or '(none)'}")
        var = byname[k]
        x = study.space.parse_value(k, val, f"--set {k}")
        if var.type == "categorical" and x not in var.choices:
            print(f"warning: --set {k}={val} is not one of the variable's choices "
                  f"{_fmt_value(list(var.choices), var.kind)}", file=sys.stderr)
        elif var.low is not None and not (var.low <= x <= var.high):
            print(f"warning: --set {k}={val} is outside the variable's bounds "
                  f"[{_fmt_value(var.low, var.kind)}, {_fmt_value(var.high, var.kind)}]; the optimiser never "
                  f"evaluates it", file=sys.stderr)
        elif var.low is None and var.values and x not in var.values:
            print(f"warning: --set {k}={val} is not one of the swept values "
                  f"{_fmt_value(list(var.values), var.kind)}", file=sys.stderr)
        values[k] = x
    if study.space.conditional:  # a conditional variable exists only for some choices
        values = study.space.restrict({**centre, **values})
    rec = Evaluator(study).evaluate(values, n=args.samples)
    from ..measures.display import fmt_column_value as fq, fmt_design

    print(f"design: {fmt_design(study, values)}")
    print(f"status: {rec.status} {rec.error}".rstrip())
    for k, v in rec.objectives.items():
        print(f"  objective {k} = {fq(study, k, v, 6)}")
    for k, v in rec.constraint_values.items():
        print(f"  constraint {k} = {fq(study, k, v, 6)} (margin {fq(study, k, rec.margins[k])})")
    print(f"feasible: {rec.feasible}; {rec.time_s:.2f} s")
    return EXIT_OK if rec.status == "ok" else EXIT_FAILED


def cmd_analyze(args) -> int:
    mech = load_mechanism(args.name, **_parse_params(args.name, args.param))
    print(f"parasynth {__version__} -- {mech.name}: {getattr(mech, 'paper', '')}")
    units = getattr(type(mech.params), "UNITS", {}) or getattr(mech.params, "UNITS", {})
    print("\nparameters:")
    for f in dataclasses.fields(mech.params):
        print(f"  {f.name} = {_fmt_value(getattr(mech.params, f.name), units.get(f.name))}")
    print(f"\ntask coordinates: {', '.join(mech.task_coordinates)}; actuators: {', '.join(mech.actuators)}")
    mob = mech.mobility()
    print(f"\nmobility: {mob.summary()}")
    findings = _analyze_home(mech)
    # A pose sample around home: reachability and margin statistics.
    rng = np.random.default_rng(args.seed)
    span = np.array([0.35 if c in mech.angular_coordinates else 0.15 * mech.length_scale * 2
                     for c in mech.task_coordinates])
    X = mech.home + span * rng.uniform(-1, 1, size=(args.samples, mech.n_task))
    ik = mech.inverse_kinematics(X)
    reach = ik.reachable
    spans = ", ".join(f"{c} +-{in_display(w, 'angle' if c in mech.angular_coordinates else 'length', '.4g')}"
                      for c, w in zip(mech.task_coordinates, span))
    print(f"\n{args.samples} random poses around home ({spans}): {reach.sum()} reachable")
    if reach.any():
        m = mech.singularity_margin(X[reach])
        print(f"singularity margin over reachable poses (dimensionless): min {np.nanmin(m):.4g}, median "
              f"{np.nanmedian(m):.4g}, max {np.nanmax(m):.4g}")
        if mech.n_actuators >= mech.n_task:
            from ..model.mechanism import ForwardKinematicsError

            q = ik.actuators[reach][:5]
            try:
                Xfk = mech.forward_kinematics(q)
                err = np.abs(Xfk - X[reach][:5])
                ang = np.array([c in mech.angular_coordinates for c in mech.task_coordinates])
                print(f"forward kinematics from home on {len(q)} poses: max error "
                      f"{in_display(np.max(err[:, ~ang]) if (~ang).any() else 0.0, 'length', '.2e')}"
                      + (f", {in_display(np.max(err[:, ang]), 'angle', '.2e')}" if ang.any() else "")
                      + " (a large value means another assembly mode)")
            except ForwardKinematicsError as e:
                findings.append(f"forward kinematics fails on the sampled poses: {e}")
    from ..model.geometry_checks import degenerate_geometry

    findings += degenerate_geometry(mech)
    if findings:
        print("\nfindings:")
        for f in dict.fromkeys(findings):
            print(f"  - {f}")
    return EXIT_OK


def _analyze_home(mech) -> list[str]:
    """Print the home pose's actuators, pose limits, Jacobian and singularity margin; return
    the findings (an unreachable or singular home, a pose limit violated at home)."""
    from ..model.geometry_checks import SINGULAR_MARGIN

    findings = []
    print(f"\nhome pose: {_fmt_pose(mech, mech.home)}")
    ik = mech.inverse_kinematics(mech.home)
    if not bool(np.all(ik.reachable)):
        findings.append("the home pose is not reachable (a leg cannot close there)")
        print("actuators at home: not reachable")
        return findings
    acts = []
    for n, v in zip(mech.actuators, np.atleast_1d(ik.actuators)):
        kind = getattr(mech, "actuator_kinds", {}).get(n) if isinstance(getattr(mech, "actuator_kinds", None), dict) else None
        acts.append(f"{n}={in_display(v, 'angle' if kind == 'angle' else 'length', '.4f')}")
    print("actuators at home: " + ", ".join(acts))
    margins = mech.constraint_margins(mech.home)
    for cname, mv in margins.items():
        mv = float(np.asarray(mv))
        c = mech.constraints[cname]
        unit = getattr(c, "unit", "")
        shown = (in_display(mv, SI_UNIT_KINDS[unit], ".4g") if unit in ("m", "rad")
                 else f"{mv:.4g} {unit}".rstrip())
        print(f"pose limit {cname} at home: margin {shown}" + ("" if mv >= 0 else "  (violated)"))
        if mv < 0:
            findings.append(f"the pose limit {cname} is violated at home (margin {shown})")
    J = mech.jacobian(mech.home)
    print(f"actuator Jacobian at home ({J.shape[0]}x{J.shape[1]}; rows: actuators, columns: "
          f"{', '.join(mech.task_coordinates)}; SI: m or rad per m or rad):")
    for row in J:
        print("  [" + " ".join(f"{v:9.4f}" for v in row) + "]")
    sm = float(mech.singularity_margin(mech.home))
    print(f"singularity margin at home (dimensionless): {sm:.4g}")
    if not np.isfinite(sm) or sm < SINGULAR_MARGIN:
        findings.append(f"the home pose is singular (singularity margin {sm:.2g} < {SINGULAR_MARGIN:g}): the "
                        f"actuators do not determine the platform there")
    return findings


def cmd_schema(args) -> int:
    import json

    from ..study.spec import study_json_schema

    text = json.dumps(study_json_schema(), indent=2) + "\n"
    if args.out is None or args.out == "-":
        sys.stdout.write(text)
        return EXIT_OK
    p = Path(args.out)
    if p.is_dir():
        raise CliError(f"--out {str(p)!r} is a directory; give a file name such as study.schema.json")
    p.write_text(text)
    print(f"schema: {p}")
    return EXIT_OK


def _int_list(text: str) -> list[int]:
    try:
        vals = [int(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--legs must be whole numbers separated by commas (e.g. 5,6), "
                                         f"got {text!r}") from None
    if not vals or min(vals) < 2:
        raise argparse.ArgumentTypeError(f"--legs must be numbers of limbs >= 2 (e.g. 5,6), got {text!r}")
    if max(vals) > MAX_LEGS:
        raise argparse.ArgumentTypeError(f"--legs must be at most {MAX_LEGS} (the documented maximum), got {text!r}")
    return vals


def cmd_export(args) -> int:
    """``parasynth export`` (:mod:`parasynth.cli.export_cmd`)."""
    from .export_cmd import export_command

    params = None if Path(args.target).is_dir() else _parse_params(args.target, args.set, flag="--set")
    return export_command(args, params)


def cmd_structures(args) -> int:
    from .. import structures as synthesis

    # an empty --types, --translations or --rotations is refused, never read as "any"
    types = args.types
    axes = {k: getattr(args, k) for k in ("translations", "rotations") if getattr(args, k) is not None} or None
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", synthesis.StructureWarning)
            found = synthesis.structures(args.motion, leg_types=types, legs=args.legs, axes=axes,
                                         all_axes=args.all_axes, seed=args.seed, show_dropped=args.show_dropped)
        for w in caught:
            if issubclass(w.category, synthesis.StructureWarning):
                print(f"warning: {w.message}", file=sys.stderr)
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    except ValueError as e:
        msg = str(e)
        for arg, flag in (("leg_types", "--types"), ("legs", "--legs"), ("axes.translations", "--translations"),
                          ("axes.rotations", "--rotations"), ("all_axes", "--all-axes"), ("seed", "--seed")):
            if msg.startswith(arg):
                msg = f"{flag} ({arg}){msg[len(arg):]}"
                break
        raise CliError(msg) from None
    kept = len(found)
    print(f"{found.motion}: {found.enumerated} candidate(s) enumerated, {kept} kept")
    out = _out_dir(args.out, "--out") if args.out else None
    for s in found:
        verdict, _, rest = synthesis.verdict_text(s).partition(": ")
        print(f"\n{s.label}  [{s.key}]")
        print(f"  limbs:       {s.limbs}")
        print(f"  actuation:   {s.actuation}")
        print(f"  arrangement: {s.arrangement}")
        print(f"  {verdict + ':':13s}{rest}")
        if out is not None:
            print(f"  written:     {s.write(out)}")
    dropped = {k: v for k, v in found.dropped.items() if v}
    print("\ndropped: " + (", ".join(f"{k} {v}" for k, v in dropped.items()) if dropped else "none"))
    if args.show_dropped:
        for line in found.dropped_lines():
            print(f"  {line}")
    return EXIT_OK


# -- parser --------------------------------------------------------------------------------------
class _Formatter(argparse.RawDescriptionHelpFormatter):
    pass


def build_parser() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show the Python traceback of an error (also PARASYNTH_DEBUG=1)")
    ap = argparse.ArgumentParser(
        prog="parasynth", description="Dimensional synthesis of parallel mechanisms", formatter_class=_Formatter,
        epilog="examples:\n  parasynth list\n  parasynth validate studies/quickstart.yaml\n"
               "  parasynth run studies/quickstart.yaml --n-trials 40\n  parasynth report runs/quickstart\n"
               "  parasynth schema --out study.schema.json", parents=[common])
    ap.add_argument("--version", action="version", version=f"parasynth {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(name, func, help, example):
        p = sub.add_parser(name, help=help, description=help[0].upper() + help[1:] + ".", parents=[common],
                           epilog=f"example:\n  {example}", formatter_class=_Formatter)
        p.set_defaults(func=func)
        return p

    p = add("list", cmd_list, "list mechanisms with their parameters, measures with their settings, optimisers",
            "parasynth list")
    p = add("run", cmd_run, "run a design study", "parasynth run studies/quickstart.yaml --out runs/qs --n-trials 40")
    p.add_argument("study", type=_path_arg("the study file"), help="study YAML file, e.g. studies/quickstart.yaml")
    p.add_argument("--out", type=_path_arg("--out"), help="run directory (default runs/<study name>/), e.g. --out runs/qs")
    p.add_argument("--resume", action="store_true",
                   help="continue an interrupted run in the same directory, e.g. --resume --out runs/qs")
    p.add_argument("--n-trials", type=_n_trials, metavar="N",
                   help=f"evaluation budget (optimizer.n_trials / maxeval, optimizer.polish's designs included), "
                        f"1 to {MAX_TRIALS}, e.g. --n-trials 40")
    p.add_argument("--quiet", action="store_true", help="no progress bar, e.g. --quiet")
    p.add_argument("--no-report", action="store_true", help="do not write the report at the end, e.g. --no-report")
    p.add_argument("--report-dir", type=_path_arg("--report-dir"),
                   help="report directory (default report/ in the run directory: runs/<study name>/report/), "
                        "e.g. --report-dir /tmp/qs-report")
    p.add_argument("--workers", type=_count_type("--workers", 1, 1024), metavar="N",
                   help="local worker processes for an Optuna study (e.g. --workers 2); the other optimisers run in one")
    p.add_argument("--storage", metavar="URL",
                   help="Optuna storage, e.g. postgresql://user:pw@host/db, sqlite:///optuna.db, journal:FILE "
                        "(default: optuna.journal in the run directory); see docs/scaling.md")
    p = add("worker", None, "join a running Optuna study from any machine",
            "parasynth worker studies/quickstart.yaml --storage postgresql://user:pw@host:5432/db")
    p.add_argument("study", type=_path_arg("the study file"),
                   help="the study YAML file the run was started with, e.g. studies/quickstart.yaml")
    p.add_argument("--storage", metavar="URL", help="the study's storage, e.g. postgresql://user:pw@host:5432/db")
    p.add_argument("--n-trials", type=_n_trials, metavar="N",
                   help="study budget (default: the one the run stored), e.g. --n-trials 200")
    p.add_argument("--quiet", action="store_true", help="no progress bar, e.g. --quiet")
    p.set_defaults(func=cmd_worker)
    p = add("run-all", cmd_run_all, "run every study in a folder and write the reports",
            "parasynth run-all studies --only quickstart")
    p.add_argument("folder", nargs="?", default="studies", help="folder of study files (default studies), e.g. studies")
    p.add_argument("--only", nargs="*", metavar="STEM", help="study file stems to run, e.g. --only quickstart")
    p.add_argument("--fresh", action="store_true", help="delete existing run directories first, e.g. --fresh")
    p.add_argument("--runs", default="runs", type=_path_arg("--runs"), help="runs folder (default runs/), e.g. --runs runs")
    p.add_argument("--reports", default="reports", type=_path_arg("--reports"),
                   help="reports folder (default reports/), e.g. --reports reports")
    p.add_argument("--quiet", action="store_true", help="no progress bars, e.g. --quiet")
    p = add("report", cmd_report, "write the report of a run directory",
            "parasynth report runs/quickstart --out /tmp/qs-report")
    p.add_argument("run_dir", nargs="?", type=_path_arg("the run directory"), help="run directory, e.g. runs/quickstart")
    p.add_argument("--out", type=_path_arg("--out"), help="report directory (default RUN_DIR/report/, where run "
                                                         "writes it), e.g. --out /tmp/qs-report")
    p.add_argument("--storage", metavar="URL", help="rebuild the run from this storage (with --study NAME), "
                                                     "e.g. --storage sqlite:///optuna.db")
    p.add_argument("--study", metavar="NAME", help="study name in --storage, e.g. --study quickstart")
    p.add_argument("--run-dir", dest="rebuild_dir", metavar="DIR",
                   help="where --storage rebuilds the run directory (default runs/NAME), e.g. --run-dir runs/qs")
    p = add("validate", cmd_validate, "check a study file: names, units, ranges, and that its designs can be built "
            "and its measures evaluated", "parasynth validate studies/quickstart.yaml")
    p.add_argument("study", type=_path_arg("the study file"), help="study YAML file, e.g. studies/quickstart.yaml")
    p.add_argument("--quick", action="store_true",
                   help="skip the probe evaluation of the measures (designs are still built), e.g. --quick")
    p = add("evaluate", cmd_evaluate, "evaluate one design of a study",
            "parasynth evaluate studies/quickstart.yaml --set 'link_length=190 mm' --samples 4096")
    p.add_argument("study", type=_path_arg("the study file"), help="study YAML file, e.g. studies/quickstart.yaml")
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="design variable value with its unit (repeatable), e.g. --set 'link_length=190 mm'; "
                        "a value outside the variable's bounds is evaluated with a warning")
    p.add_argument("--samples", type=_samples, metavar="N",
                   help=f"workspace samples (default: the study's), 1 to {MAX_SAMPLES}, e.g. --samples 4096")
    p = add("analyze", cmd_analyze, "kinematic analysis of a mechanism", "parasynth analyze 5pus_upu --param 'link_length=185 mm'")
    p.add_argument("name", help=f"one of: {', '.join(list_mechanisms())}, or a mechanism description file (.yaml), "
                                f"e.g. 5pus_upu")
    p.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="override a parameter, with its unit (repeatable), e.g. --param 'link_length=185 mm'")
    p.add_argument("--samples", type=_samples, default=2000, metavar="N",
                   help=f"random poses to sample (default 2000), 1 to {MAX_SAMPLES}, e.g. --samples 5000")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the pose sample (default 0), e.g. --seed 1")
    p = add("schema", cmd_schema, "write the study file format as JSON Schema (for editors)",
            "parasynth schema --out study.schema.json")
    p.add_argument("--out", type=_path_arg("--out"), help="output file (default: standard output), e.g. --out study.schema.json")
    p = add("structures", cmd_structures, "enumerate and check candidate structures for a motion type",
            "parasynth structures 3T2R --types PUS,UPS,UPU --legs 6 --out structures/")
    p.add_argument("motion", help="motion type: translations T and rotations R, e.g. 3T2R, 3T3R, 2T2R")
    p.add_argument("--types", metavar="LIST", help="limb types to draw from (default: the whole vocabulary), "
                                                   "e.g. --types PUS,UPS,UPU")
    p.add_argument("--legs", type=_int_list, metavar="LIST",
                   help="allowed total numbers of limbs (default: any), e.g. --legs 5,6")
    p.add_argument("--translations", metavar="LIST", help="required translation axes of the freedoms, e.g. "
                                                          "--translations x,z")
    p.add_argument("--rotations", metavar="LIST", help="required rotation axes of the freedoms, e.g. "
                                                       "--rotations 'y,moving x'")
    p.add_argument("--all-axes", action="store_true",
                   help="every joint-axis choice of the vocabulary, not only the first of each, e.g. --all-axes")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the checked poses (default 0), e.g. --seed 1")
    p.add_argument("--show-dropped", action="store_true",
                   help="list the dropped candidates by name under their reason (under-actuated, singular at home, "
                        "...), e.g. --show-dropped")
    p.add_argument("--out", type=_path_arg("--out"), help="directory to write the descriptions to, e.g. --out structures/")
    p = add("export", cmd_export, "write a mechanism or a run's design as MJCF (MuJoCo) or URDF with a closure file "
            "(Pinocchio)", "parasynth export 5pus_upu --format mjcf --out m.xml\n"
            "  parasynth export 5pus_upu --out m.urdf --set 'link_length=190 mm' --pose 'z=-50 mm'\n"
            "  parasynth export my_robot.yaml --format mjcf --out robot.xml\n"
            "  parasynth export runs/quickstart --format mjcf --out best.xml   # the recommended design\n"
            "  parasynth export runs/quickstart --trial 12 --format urdf --out t12.urdf")
    p.add_argument("target", type=_path_arg("the mechanism"),
                   help=f"a mechanism ({', '.join(list_mechanisms())}), a description file (.yaml) or a run directory "
                        f"(runs/<study name>/), e.g. 5pus_upu")
    p.add_argument("--format", choices=("mjcf", "urdf"),
                   help="mjcf or urdf (default: from the suffix of --out: .xml or .mjcf, .urdf), e.g. --format urdf")
    p.add_argument("--out", required=True, type=_path_arg("--out"),
                   help="output file, e.g. --out m.xml; a URDF's closure file is written next to it (m.yaml)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="a mechanism parameter with its unit (repeatable), e.g. --set 'link_length=190 mm', "
                        "--set platform=pentagonal")
    p.add_argument("--pose", action="append", metavar="COORD=VALUE",
                   help="the pose the model is written at: a task coordinate with its unit (repeatable; the others "
                        "at home), e.g. --pose 'z=650 mm' --pose 'alpha=5 deg'")
    p.add_argument("--trial", type=_count_type("--trial", 0, 10**9), metavar="N",
                   help="with a run directory: the trial to export (default: the recommended design), e.g. --trial 12")
    return ap


# -- error handling ------------------------------------------------------------------------------
def _one_line(e: BaseException) -> str:
    msg = str(e).strip() or type(e).__name__
    return msg


def _describe_error(e: BaseException) -> tuple[str, int]:
    """(message, exit status) for an exception that reached :func:`main`."""
    from ..study import StudyError
    from ..common.units import QuantityError
    from ..common.validation import InputError
    from ..common.yamlio import YamlError

    if isinstance(e, CliError):
        return str(e), e.code
    if isinstance(e, (StudyError, QuantityError, YamlError, InputError)):
        return _one_line(e), EXIT_USAGE
    name = type(e).__name__
    text = str(e)
    # Storage back-ends (SQLAlchemy / sqlite3 errors are not imported here).
    if "disk I/O error" in text or "database or disk is full" in text:
        return f"the storage cannot be written (disk full or I/O error): {text.splitlines()[0]}", EXIT_FAILED
    if name in ("OperationalError", "DatabaseError", "ArgumentError", "NoSuchModuleError") or \
            type(e).__module__.startswith(("sqlalchemy", "sqlite3")):
        return f"storage error ({name}): {text.splitlines()[0] if text else name}", EXIT_FAILED
    if isinstance(e, OSError):
        where = f" {e.filename!r}" if getattr(e, "filename", None) else ""
        if e.errno == errno.ENOSPC:
            return f"disk full while writing{where}; free some space and run again (with --resume for a run)", EXIT_FAILED
        if e.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
            return f"permission denied{where}: {e.strerror}", EXIT_FAILED
        if e.errno == errno.EISDIR:
            return f"{where.strip() or 'path'} is a directory, not a file", EXIT_USAGE
        if e.errno == errno.ENOENT:
            return f"no such file or directory{where}", EXIT_USAGE
        return f"{e.strerror or text or name}{where}", EXIT_FAILED
    if isinstance(e, UnicodeError):
        return f"not UTF-8 text: {e}", EXIT_USAGE
    if isinstance(e, RecursionError):
        return "the input is nested too deeply", EXIT_USAGE
    if isinstance(e, MemoryError):
        return "out of memory; reduce the sample count or the number of designs", EXIT_FAILED
    if isinstance(e, ValueError):  # library validation errors are ValueErrors naming the field
        return _one_line(e), EXIT_USAGE
    return f"internal error ({name}: {text.splitlines()[0] if text else ''}); run with --debug for the " \
           f"traceback and report it", EXIT_FAILED


def _print_error(msg: str) -> None:
    try:
        print(f"error: {msg}", file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def _silence_stdout() -> None:
    """After a broken pipe: point stdout at /dev/null so that the final flush does not fail."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def _load_user_plugins() -> None:
    spec = os.environ.get("PARASYNTH_PLUGINS", "")
    try:
        load_plugins(spec)
    except SystemExit as e:  # the loader's own message for a missing file
        raise CliError(str(e.code).removeprefix("error: ")) from None
    except ImportError as e:
        raise CliError(f"PARASYNTH_PLUGINS: cannot import {getattr(e, 'name', None) or spec!r} ({e})") from None
    except Exception as e:
        raise CliError(f"PARASYNTH_PLUGINS: a plugin failed while loading ({type(e).__name__}: {e})",
                       EXIT_FAILED) from None


#: The program's full collections (``gc``'s third threshold): one per this many collections of
#: the middle generation, against Python's 10 (see :func:`entry`).
FULL_COLLECTION_EVERY = 100


def entry() -> None:
    """The ``parasynth`` program (console script and ``python -m parasynth.cli``): :func:`main`,
    then the process exits with its status.

    The cyclic garbage collector's full collections are ten times rarer than Python's default
    (:data:`FULL_COLLECTION_EVERY`): with the default, the imports of numba, pandas and SciPy
    set off three of them in a run's first 1.5 s, each walking every object loaded so far
    (0.12 s of a 2.2 s warm quick start; docs/performance.md, "Tenth pass"), and none found
    garbage worth it. The young generations are collected as before, and a full collection still
    comes in a long run, ten times less often.

    Before the interpreter shuts down, every object still alive is frozen out of the cyclic
    garbage collector (``gc.freeze``): the shutdown's last collection would otherwise walk the
    ~2e5 objects of NumPy, numba, Optuna and pandas once more, 0.3-0.45 s of a 2.6 s warm quick
    start (docs/performance.md, "Ninth pass"). Nothing of the run's output depends on it: files
    are closed and the standard streams flushed by then, and exit handlers run as before.

    A run interrupted while the engine compiles leaves numba compiling on an abandoned thread
    (:func:`parasynth.engine.warmup.abandoned`): the interpreter's shutdown would tear LLVM
    down under it (an LLVM assertion, or a segmentation fault, in place of the exit status), so
    the process then ends at once with its status (``os._exit``): its files are closed, its
    helper processes stopped and the standard streams flushed by then."""
    young, middle, _ = gc.get_threshold()
    gc.set_threshold(young, middle, FULL_COLLECTION_EVERY)
    code = main()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: main already said so
            pass
    warmup = sys.modules.get("parasynth.engine.warmup")  # loaded if the engine warmed up
    if warmup is not None and warmup.abandoned():
        os._exit(code)
    gc.freeze()
    sys.exit(code)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (see the module docstring)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = os.environ.get("PARASYNTH_DEBUG", "") not in ("", "0") or "--debug" in argv
    try:
        _load_user_plugins()
        args = build_parser().parse_args(argv)
        debug = debug or getattr(args, "debug", False)
        code = args.func(args)
        sys.stdout.flush()
        return code
    except SystemExit:
        raise
    except KeyboardInterrupt:
        if debug:
            raise
        _print_error("interrupted")
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        _silence_stdout()
        if debug:
            raise
        _print_error("the output was closed before it was complete (broken pipe)")
        return EXIT_PIPE
    except Exception as e:
        if debug:
            raise
        msg, code = _describe_error(e)
        _print_error(msg)
        return code

