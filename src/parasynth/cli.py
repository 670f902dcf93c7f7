"""Command-line interface: ``parasynth <command>``.

Commands
--------
list                 mechanisms (and, as they arrive, objectives, constraints, optimisers)
analyze NAME         kinematic analysis of a mechanism at its home pose and a pose sample
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from . import __version__
from .mechanisms import list_mechanisms, load_mechanism, mechanism_summaries


def _parse_params(items: list[str]) -> dict:
    out = {}
    for it in items or []:
        if "=" not in it:
            raise SystemExit(f"error: --param expects NAME=VALUE (SI units), got {it!r}")
        k, v = it.split("=", 1)
        try:
            out[k] = float(v)
        except ValueError:
            out[k] = {"true": True, "false": False}.get(v.lower(), v)
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
    print("mechanisms:")
    for name, summary in mechanism_summaries().items():
        print(f"  {name:12s} {summary}")
    return 0


def cmd_analyze(args) -> int:
    try:
        mech = load_mechanism(args.name, **_parse_params(args.param))
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
    ap = argparse.ArgumentParser(prog="parasynth", description="Dimensional synthesis of parallel mechanisms")
    ap.add_argument("--version", action="version", version=f"parasynth {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("list", help="list mechanisms")
    p.set_defaults(func=cmd_list)
    p = sub.add_parser("analyze", help="kinematic analysis of a mechanism")
    p.add_argument("name", help=f"one of: {', '.join(list_mechanisms())}")
    p.add_argument("--param", action="append", metavar="NAME=VALUE", help="override a parameter (SI units)")
    p.add_argument("--samples", type=int, default=2000, help="random poses to sample (default 2000)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_analyze)
    args = ap.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    raise SystemExit(main())
