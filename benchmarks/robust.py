"""Robust measures: the cost of a design evaluation under scatter against the nominal one.

The user's path: a study's design evaluation (``parasynth.study.evaluate.Evaluator``: the
mechanism built, the design constraints, the objectives, with the study's workspace sample) of
``studies/quickstart.yaml`` (default), once as shipped (the baseline, measured in the same run)
and once per scatter case with a ``robust:`` block of ``k`` draws (default 32) on its objectives
or constraint:

* ``legs``: per-leg scatter only (anchors 0.02 mm, joint axes 0.01 deg, actuators 0.01 mm) on
  both objectives, evaluated on the mechanism as built;
* ``params``: description-parameter scatter only (slider radius, link length, pentagon radius
  0.05 mm) on both objectives, the mechanism rebuilt per draw;
* ``both``: the two together;
* ``chance``: the footprint constraint as a chance constraint (probability 0.95, slider radius
  0.05 mm), the objectives nominal.

The same designs (drawn uniformly from the study's variables with a fixed seed, the reference
first) are evaluated in every case, after a warm-up design per case (compilation, first
samples); each pass evaluates every design as a study does, for the first time (the workspace
cache of the previous pass is emptied); the fastest of ``--repeat`` passes counts, and the baseline is measured again
beside every case (the fastest kept), so that a load on the machine does not favour either
side. Printed per case: milliseconds per design and ``ratio_per_draw = t_robust / (k
t_nominal)`` (the target is at most 1.5)::

    python benchmarks/robust.py                     # quickstart, k = 32, 6 designs
    python benchmarks/robust.py --draws 16 --designs 10

Not part of the test suite.
"""

from __future__ import annotations

import argparse
import copy
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent

LEGS = {"anchor_tolerance": "0.02 mm", "axis_tolerance": "0.01 deg", "actuator_tolerance": "0.01 mm"}
PARAMS = {"slider_radius": "0.05 mm", "link_length": "0.05 mm", "pentagon_radius": "0.05 mm"}


def _designs(study, k: int, seed: int) -> list[dict]:
    rng = np.random.default_rng(seed)
    out = [dict(study.reference)] if study.reference else []
    while len(out) < k:
        out.append({v.name: float(rng.uniform(v.low, v.high)) for v in study.variables})
    return out


def _case(data: dict, case: str, k: int) -> dict:
    d = copy.deepcopy(data)
    d["name"] = f"{data['name']}_{case}"
    if case in ("legs", "params", "both"):
        tol = {"legs": LEGS, "params": PARAMS, "both": {**PARAMS, **LEGS}}[case]
        for o in d["objectives"]:
            o["robust"] = {"tolerances": dict(tol), "samples": k, "seed": 0}
    elif case == "chance":
        d["constraints"][0]["robust"] = {"tolerances": {"slider_radius": "0.05 mm"}, "probability": 0.95,
                                         "samples": k, "seed": 0}
    return d


def _time(study, designs, repeat: int = 1) -> float:
    from parasynth.measures import objectives
    from parasynth.study.evaluate import Evaluator

    ev = Evaluator(study)
    rec = ev.evaluate(designs[0])  # warm-up
    if rec.status != "ok":
        raise SystemExit(f"{study.name}: {rec.error}")
    best = np.inf
    for _ in range(repeat):
        # each design evaluated for the first time, as in a study: the workspaces of the
        # previous pass (module cache, keyed by the design's parameters) are not reused
        objectives._CACHE.clear()
        t0 = time.perf_counter()
        for d in designs[1:]:
            r = ev.evaluate(d)
            if r.status != "ok":
                raise SystemExit(f"{study.name}: {r.error}")
        best = min(best, (time.perf_counter() - t0) / max(1, len(designs) - 1))
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("study", nargs="?", default=str(ROOT / "studies" / "quickstart.yaml"))
    ap.add_argument("--draws", type=int, default=32)
    ap.add_argument("--designs", type=int, default=6)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cases", default="legs,params,both,chance")
    ap.add_argument("--repeat", type=int, default=2, help="timed passes per case (the fastest counts)")
    args = ap.parse_args(argv)
    from parasynth.study.spec import resolve_study

    data = yaml.safe_load(Path(args.study).read_text())
    nominal = resolve_study(copy.deepcopy(data))
    designs = _designs(nominal, args.designs + 1, args.seed)
    warnings.simplefilter("ignore")
    t_nom = _time(nominal, designs, repeat=3)
    print(f"{nominal.name}: nominal {t_nom * 1e3:.3f} ms per design ({len(designs) - 1} designs, k = {args.draws})")
    for case in args.cases.split(","):
        study = resolve_study(_case(data, case, args.draws))
        t = _time(study, designs, repeat=args.repeat)
        t_nom = min(t_nom, _time(nominal, designs, repeat=3))  # the baseline again, under the same load
        print(f"{case:>7}: {t * 1e3:9.2f} ms per design  ratio_per_draw={t / (args.draws * t_nom):.3f}")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
