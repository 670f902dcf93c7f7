"""``parasynth export``: write a mechanism as MJCF or URDF (:mod:`parasynth.export`).

The mechanism is a registry name or a description file with parameter values (``--set``), or a
design of a run directory (``--trial N``, by default the design the run recommends: the knee of
its Pareto front, the best design for one objective), read through the study layer's
run-directory interface (:mod:`parasynth.study.rundir`). :mod:`parasynth.cli` parses the
arguments (the ``export`` subcommand is defined there with the others) and calls
:func:`export_command`; errors are ``ValueError``s with a one-line message,
which the command line prints as ``error: ...`` (exit status 2)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from ..measures.display import fmt_design
from ..export import ExportError, build_tree, to_mjcf, to_urdf
from ..export.mjcf import MIN_CONDITIONING
from ..mechanisms import load_mechanism
from ..study import rundir
from ..common.units import format_pose, parse_quantity

__all__ = ["export_command", "design_of_run", "parse_pose", "format_of"]

#: The file suffix of each format, for guessing --format from --out.
SUFFIXES = {".xml": "mjcf", ".mjcf": "mjcf", ".urdf": "urdf"}


def format_of(fmt: str | None, out: str) -> str:
    """The export format: ``--format`` or, without it, the suffix of ``--out``."""
    if fmt is not None:
        return fmt
    guess = SUFFIXES.get(Path(out).suffix.lower())
    if guess is None:
        raise ExportError(f"--format: give mjcf or urdf (the suffix of --out {out!r} does not tell; .xml/.mjcf are "
                          f"MJCF, .urdf URDF)")
    return guess


def parse_pose(mech, items: list[str] | None) -> np.ndarray:
    """The pose of ``--pose NAME=VALUE`` items (with units), the other coordinates at home."""
    X = np.array(mech.home, dtype=float)
    for it in items or []:
        if "=" not in it:
            raise ExportError(f"--pose expects COORDINATE=VALUE with a unit (e.g. 'z=650 mm', 'alpha=5 deg'), got {it!r}")
        k, v = (x.strip() for x in it.split("=", 1))
        if k not in mech.task_coordinates:
            raise ExportError(f"--pose {k}: not a task coordinate of {mech.name}; coordinates: "
                              f"{', '.join(mech.task_coordinates)}")
        kind = "angle" if k in mech.angular_coordinates else "length"
        X[mech.task_coordinates.index(k)] = parse_quantity(v, kind, field=f"--pose {k}")
    return X


def design_of_run(run_dir, trial: int | None):
    """(mechanism name, parameters (SI), what) of trial ``trial`` of a run directory, or of the
    design the run recommends when ``trial`` is None."""
    run = rundir.read_run(run_dir)
    study, table = run.study, run.table
    runs = table[table["source"] == "run"]
    if trial is None:
        row = rundir.knee_of(study, rundir.pareto_front(study, runs))
        if row is None:
            raise ExportError(f"{run_dir}: the run has no feasible design to recommend; give --trial N")
        what = f"the recommended design (trial {int(row['trial'])})"
    else:
        rows = runs[runs["trial"] == trial]
        if not len(rows):
            trials = runs["trial"].astype(int)
            raise ExportError(f"--trial {trial}: no such trial in {run_dir}; its trials run from {trials.min()} to "
                              f"{trials.max()}" if len(trials) else f"--trial {trial}: {run_dir} holds no trials")
        row = rows.iloc[0]
        if row["status"] != "ok":
            raise ExportError(f"--trial {trial}: the design failed to evaluate ({row['status']}); choose another trial")
        what = f"trial {trial}"
    values = {}
    for v in study.variables:
        x = row[v.name]
        if isinstance(x, float) and math.isnan(x):
            continue  # a conditional variable inactive in this design
        values[v.name] = x.item() if hasattr(x, "item") else x
    if values:
        what += f": {fmt_design(study, values)}"
    return study.mechanism, rundir.design_params(study, values), what


def export_command(args, params: dict | None) -> int:
    """Run ``parasynth export`` for parsed arguments; ``params`` are the parsed ``--set`` values of a
    mechanism (None for a run directory)."""
    target = Path(args.target)
    if target.is_dir():
        if args.set:
            raise ExportError("--set applies to a mechanism name or description file; a run's design is chosen with "
                              "--trial N (default: the recommended design)")
        name, params, what = design_of_run(target, args.trial)
    else:
        if args.trial is not None:
            raise ExportError(f"--trial applies to a run directory; {args.target!r} is not a directory")
        name, what = args.target, "the given parameters" if params else "the default parameters"
    fmt = format_of(args.format, args.out)
    mech = load_mechanism(name, **(params or {}))
    X = parse_pose(mech, args.pose)
    out = Path(args.out)
    if out.is_dir():
        raise ExportError(f"--out {str(out)!r} is a directory; give a file name such as m.xml or m.urdf")
    if not out.parent.exists():
        raise ExportError(f"--out {str(out)!r}: the directory {str(out.parent)!r} does not exist")
    tree = build_tree(mech, X)  # checks the pose before anything is written
    feasible = bool(np.all(mech.is_feasible(X)))
    if fmt == "mjcf":
        written = [to_mjcf(mech, out, X)]
    else:
        written = list(to_urdf(mech, out, X))
    kinds = [c.kind for c in tree.closures]
    print(f"{mech.name} ({what}) at {format_pose(mech.task_coordinates, mech.angular_coordinates, X)}")
    closes = f"{kinds.count('3D')} ball (connect), {kinds.count('6D')} rigid (weld)" if fmt == "mjcf" else \
        f"{kinds.count('3D')} 3D, {kinds.count('6D')} 6D"
    print(f"  {len(mech.legs)} legs, {len(tree.closures)} closed loops ({closes}), {len(tree.actuators)} actuated "
          f"joints ({', '.join(f'{a}={j}' for a, j in tree.actuators.items())})")
    if tree.hold_joints:
        print(f"  under-actuated: the passive joint(s) {', '.join(tree.hold_joints)} can be held"
              + (" (inactive equalities hold_*)" if fmt == "mjcf" else " (closure file: hold_joints)"))
    if tree.conditioning < MIN_CONDITIONING:
        print(f"warning: the pose is at or near a singularity (conditioning {tree.conditioning:.2g}); the servos are "
              f"soft there, and their damping is set as for {MIN_CONDITIONING}", file=sys.stderr)
    if not feasible:
        bad = [k for k, m in mech.constraint_margins(X).items() if not m >= 0]
        print(f"warning: the pose violates the constraint(s) {', '.join(bad)}; the model starts outside the "
              f"described limits", file=sys.stderr)
    for p in written:
        print(f"wrote {p}")
    return 0
