"""Command-line interface: ``parasynth <command>``.

Commands
--------
run STUDY.yaml       run a design study (sweep, NLopt or Optuna) and write its results
validate STUDY.yaml  check a study file and print it resolved to SI
evaluate STUDY.yaml  evaluate one design of a study (all objectives and constraints)
report RUN_DIR       write index.html, report.md and pareto.csv for a run
run-all [FOLDER]     run every study of a folder and write all reports (reports/README.md)
list                 mechanisms, objectives, optimisers
analyze NAME         kinematic analysis of a mechanism at its home pose and a pose sample
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from . import __version__
from .mechanisms import list_mechanisms, load_mechanism, mechanism_summaries
from .plugins import load_plugins  # noqa: F401  (also parasynth.cli.load_plugins)


def _parse_params(name: str, items: list[str]) -> dict:
    """--param NAME=VALUE items with units where the parameter has one ("link_length=205 mm")."""
    from .mechanisms import mechanism_class
    from .units import parse_quantity

    try:
        units = getattr(mechanism_class(name).Params, "UNITS", {})
    except ValueError:
        units = {}
    out = {}
    for it in items or []:
        if "=" not in it:
            raise ValueError(f"--param expects NAME=VALUE, with a unit where the parameter has one, got {it!r}")
        k, v = (x.strip() for x in it.split("=", 1))
        kind = units.get(k)
        if kind is not None:
            out[k] = parse_quantity(v, kind, field=f"--param {k}")
        elif v.lower() in ("true", "false"):
            out[k] = v.lower() == "true"
        else:
            out[k] = v
    return out


def _fmt_pose(mech, X) -> str:
    parts = []
    for name, v in zip(mech.task_coordinates, np.atleast_1d(X)):
        if name in mech.angular_coordinates:
            parts.append(f"{name}={np.rad2deg(v):.3f} deg")
        else:
            parts.append(f"{name}={v * 1e3:.3f} mm")
    return ", ".join(parts)


def cmd_list(args) -> int:
    from .objectives import OBJECTIVES
    from .study import OPTIMIZERS

    print("mechanisms:")
    for name, summary in mechanism_summaries().items():
        print(f"  {name:12s} {summary}")
        mech = load_mechanism(name)
        for cname, c in mech.constraints.items():
            print(f"      pose constraint {cname} [{c.unit}]: {c.doc}")
    print("\nobjectives and design-constraint measures (name [unit], natural goal):")
    for name, m in OBJECTIVES.items():
        doc = m.doc.splitlines()[0] if m.doc else ""
        print(f"  {name} [{m.unit}], {m.sense}: {doc}")
    print("\noptimisers (optimizer.kind: algorithms):")
    for kind, algs in OPTIMIZERS.items():
        print(f"  {kind}: {', '.join(algs)}")
    return 0


def _load_study_or_exit(path):
    from .study import StudyError, load_study

    try:
        return load_study(path)
    except StudyError as e:
        print(f"error: {e}", file=sys.stderr)
        raise SystemExit(2)


def cmd_validate(args) -> int:
    study = _load_study_or_exit(args.study)
    from .display import fmt_column_value as fq, fmt_evaluation

    print(f"{args.study}: valid study {study.name} ({study.optimizer.kind}) on {study.mechanism}")
    for v in study.variables:
        rng = f"[{fq(study, v.name, v.low)}, {fq(study, v.name, v.high)}]" if v.low is not None else ""
        vals = " values " + ", ".join(fq(study, v.name, x) for x in v.values) if v.values else ""
        ch = " choices " + ", ".join(fq(study, v.name, x) for x in v.choices) if v.choices else ""
        print(f"  variable {v.name} ({v.type}) {rng}{vals}{ch}".replace(")  ", ") "))
    for o in study.objectives:
        sets = ", ".join(f"{k}={x}" for k, x in (o.settings or {}).items())
        print(f"  objective {o.label}: {o.goal} {o.name}" + (f" ({sets})" if sets else ""))
    for c in study.constraints:
        bounds = [f"{b} {fq(study, c.label, x)}" for b, x in (("min", c.min), ("max", c.max)) if x is not None]
        print(f"  constraint {c.label}: {c.name} " + " ".join(bounds))
    print(f"  evaluation: {fmt_evaluation(study)}")
    return 0


def cmd_run(args) -> int:
    from .study import StudyError, run_study

    study = _load_study_or_exit(args.study)
    try:
        res = run_study(study, out_dir=args.out, resume=args.resume, n_trials=args.n_trials,
                        progress=not args.quiet)
    except StudyError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(res.summary(study))
    if res.interrupted:
        print(f"interrupted: {res.n_total} designs are saved; continue with "
              f"parasynth run {args.study} --resume" + (f" --out {args.out}" if args.out else ""), file=sys.stderr)
        return 130
    if not args.no_report:
        from .report import ReportError, write_report

        try:
            rdir = write_report(res.out_dir, out=args.report_dir)
            print(f"report: {rdir / 'index.html'}")
        except ReportError as e:
            print(f"no report: {e}", file=sys.stderr)
    return 0


def cmd_run_all(args) -> int:
    """Run every study of a folder (resuming finished or interrupted runs unless --fresh) and
    write each report, plus an index reports/README.md."""
    import shutil
    from pathlib import Path

    from .report import ReportError, write_report
    from .study import StudyError, load_study, run_study

    folder = Path(args.folder)
    files = sorted(folder.glob("*.yaml")) if folder.is_dir() else []
    if args.only:
        files = [f for f in files if f.stem in args.only]
    if not files:
        print(f"error: no study files (*.yaml) in {str(folder)!r}" + (f" matching {args.only}" if args.only else ""),
              file=sys.stderr)
        return 2
    index = []
    for f in files:
        try:
            study = load_study(f)
        except StudyError as e:
            print(f"error: {f}: {e}", file=sys.stderr)
            return 2
        out = Path(args.runs) / study.name
        if args.fresh and out.exists():
            shutil.rmtree(out)
        print(f"== {f} -> {out}", flush=True)
        res = run_study(study, out_dir=out, resume=out.exists(), progress=not args.quiet)
        print(res.summary(study))
        if res.interrupted:
            print("interrupted; run the same command again to continue", file=sys.stderr)
            return 130
        try:
            rdir = write_report(out, out=Path(args.reports) / study.name)
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
        rdir = Path(args.reports) / st.name
        if st.name not in done and (rdir / "index.html").exists():
            index.append((st.name, rdir, " ".join(st.spec.description.split())))
    index.sort(key=lambda item: item[0])
    idx = Path(args.reports) / "README.md"
    lines = ["# Study reports", "", "Regenerate with `parasynth run-all studies` (add `--fresh` to rerun from "
             "scratch).", ""]
    for name, rdir, desc in index:
        lines.append(f"- [{name}]({name}/report.md) ([HTML]({name}/index.html)): {desc}")
    idx.write_text("\n".join(lines) + "\n")
    print(f"index: {idx}")
    return 0


def cmd_report(args) -> int:
    from .report import ReportError, write_report

    try:
        rdir = write_report(args.run_dir, out=args.out)
    except ReportError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"report: {rdir / 'index.html'} (and report.md, pareto.csv)")
    return 0


def cmd_evaluate(args) -> int:
    from .study import Evaluator
    from .study.spec import StudyError, _q

    study = _load_study_or_exit(args.study)
    byname = {v.name: v for v in study.variables}
    values = {}
    base = dict(study.reference or {})
    for v in study.variables:
        if v.name in base:
            values[v.name] = base[v.name]
        elif v.low is not None:
            values[v.name] = 0.5 * (v.low + v.high)
        else:
            values[v.name] = (v.values or v.choices)[0]
    for item in args.set or []:
        if "=" not in item:
            print(f"error: --set expects NAME=VALUE with units, got {item!r}", file=sys.stderr)
            return 2
        k, val = item.split("=", 1)
        if k not in byname:
            print(f"error: --set {k}: not a design variable; variables: {', '.join(byname)}", file=sys.stderr)
            return 2
        try:
            values[k] = _q(val.strip(), byname[k].kind, f"--set {k}")
        except StudyError as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
    rec = Evaluator(study).evaluate(values, n=args.samples)
    from .display import fmt_column_value as fq, fmt_design

    print(f"design: {fmt_design(study, values)}")
    print(f"status: {rec.status} {rec.error}".rstrip())
    for k, v in rec.objectives.items():
        print(f"  objective {k} = {fq(study, k, v, 6)}")
    for k, v in rec.constraint_values.items():
        print(f"  constraint {k} = {fq(study, k, v, 6)} (margin {fq(study, k, rec.margins[k])})")
    print(f"feasible: {rec.feasible}; {rec.time_s:.2f} s")
    return 0 if rec.status == "ok" else 1


def cmd_analyze(args) -> int:
    try:
        mech = load_mechanism(args.name, **_parse_params(args.name, args.param))
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"parasynth {__version__} -- {mech.name}: {getattr(mech, 'paper', '')}")
    print("\nparameters (SI):")
    for f in dataclasses.fields(mech.params):
        print(f"  {f.name} = {getattr(mech.params, f.name)}")
    print(f"\ntask coordinates: {mech.task_coordinates}; actuators: {mech.actuators}")
    mob = mech.mobility()
    print(f"\nmobility: {mob.summary()}")
    print(f"\nhome pose: {_fmt_pose(mech, mech.home)}")
    ik = mech.inverse_kinematics(mech.home)
    print("actuators at home: " + ", ".join(f"{n}={v * 1e3:.4f} mm" for n, v in zip(mech.actuators, ik.actuators)))
    J = mech.jacobian(mech.home)
    print(f"actuator Jacobian at home ({J.shape[0]}x{J.shape[1]}):")
    for row in J:
        print("  [" + " ".join(f"{v:9.4f}" for v in row) + "]")
    print(f"singularity margin at home: {mech.singularity_margin(mech.home):.4g}")
    # A pose sample around home: reachability and margin statistics.
    rng = np.random.default_rng(args.seed)
    span = np.array([0.35 if c in mech.angular_coordinates else 0.15 * mech.length_scale * 2
                     for c in mech.task_coordinates])
    X = mech.home + span * rng.uniform(-1, 1, size=(args.samples, mech.n_task))
    ik = mech.inverse_kinematics(X)
    reach = ik.reachable
    print(f"\n{args.samples} random poses within +-{span.round(3).tolist()} of home: {reach.sum()} reachable")
    if reach.any():
        m = mech.singularity_margin(X[reach])
        print(f"singularity margin over reachable poses: min {np.nanmin(m):.4g}, median {np.nanmedian(m):.4g}, max {np.nanmax(m):.4g}")
        if mech.n_actuators >= mech.n_task:
            q = ik.actuators[reach][:5]
            Xfk = mech.forward_kinematics(q)
            err = np.max(np.abs(Xfk - X[reach][:5]))
            print(f"forward kinematics from home on 5 poses: max |X_fk - X| = {err:.2e} (a large value means another assembly mode)")
    return 0


def main(argv: list[str] | None = None) -> int:
    load_plugins()
    ap = argparse.ArgumentParser(prog="parasynth", description="Dimensional synthesis of parallel mechanisms")
    ap.add_argument("--version", action="version", version=f"parasynth {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("list", help="list mechanisms, objectives, optimisers")
    p.set_defaults(func=cmd_list)
    p = sub.add_parser("run", help="run a design study")
    p.add_argument("study", help="study YAML file")
    p.add_argument("--out", help="run directory (default runs/<study name>/)")
    p.add_argument("--resume", action="store_true", help="continue an interrupted run in the same directory")
    p.add_argument("--n-trials", type=int, help="evaluation budget (optuna trials / nlopt maxeval)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--no-report", action="store_true", help="do not write the report at the end")
    p.add_argument("--report-dir", help="report directory (default reports/<study name>/)")
    p.set_defaults(func=cmd_run)
    p = sub.add_parser("run-all", help="run every study in a folder and write the reports")
    p.add_argument("folder", nargs="?", default="studies")
    p.add_argument("--only", nargs="*", help="study file stems to run")
    p.add_argument("--fresh", action="store_true", help="delete existing run directories first")
    p.add_argument("--runs", default="runs", help="runs folder (default runs/)")
    p.add_argument("--reports", default="reports", help="reports folder (default reports/)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_run_all)
    p = sub.add_parser("report", help="write the report of a run directory")
    p.add_argument("run_dir", help="run directory (runs/<study name>/)")
    p.add_argument("--out", help="report directory (default reports/<study name>/)")
    p.set_defaults(func=cmd_report)
    p = sub.add_parser("validate", help="check a study file")
    p.add_argument("study")
    p.set_defaults(func=cmd_validate)
    p = sub.add_parser("evaluate", help="evaluate one design of a study")
    p.add_argument("study")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="design variable value with unit")
    p.add_argument("--samples", type=int, help="workspace samples (default: the study's)")
    p.set_defaults(func=cmd_evaluate)
    p = sub.add_parser("analyze", help="kinematic analysis of a mechanism")
    p.add_argument("name", help=f"one of: {', '.join(list_mechanisms())}, or a mechanism description file (.yaml)")
    p.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="override a parameter, with its unit (e.g. link_length='185 mm')")
    p.add_argument("--samples", type=int, default=2000, help="random poses to sample (default 2000)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_analyze)
    args = ap.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    raise SystemExit(main())
