"""Structural synthesis: enumeration and checks per motion, the cost of a design per structure,
and a full 3T2R synthesis study.

Per motion (3T3R, 3T2R, 2T2R, the default vocabulary):

* ``enumerated`` / ``kept``: candidates generated and structures kept (``parasynth.structures``);
* ``checked/s``: candidates through the whole pipeline per second (generated, deduplicated,
  written as descriptions, built and checked numerically), and ``built/s``: the candidates that
  reached the numerical check per second of the same run;
* ``ms/design``: per kept structure, one design of the shipped study's kind -- the workspace
  volume and the 5 % quantile of the singularity margin on 8192 Sobol samples of the structure's
  task box in its translations (the rotations at home), with the compiled engine warm -- the
  median of 5 evaluations (CPU time).

Then the full 3T2R study ``studies/structures_3t2r.yaml`` (every 3T2R structure of the default
vocabulary, 50 designs each in the screening, 200 for each survivor) is run from scratch in a
temporary directory: its wall and CPU time, the designs per structure, and whether every
structure that survived the screening got at least 200 designs within 15 minutes.

Times on a shared machine are noisy: compare the CPU times and the ratios of one run. Not part
of the test suite. Usage::

    python benchmarks/structures.py            # all of it
    python benchmarks/structures.py --no-study # enumeration and design costs only
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

import parasynth  # noqa: E402
from parasynth.measures import objectives  # noqa: E402
from parasynth.model.mechanism import EngineFallbackWarning  # noqa: E402
from parasynth.measures.workspace import WorkspaceSample  # noqa: E402

LIMIT_S = 15 * 60


def _cpu() -> float:
    t = os.times()
    return t.user + t.system


def enumeration(motion: str):
    t0, c0 = time.perf_counter(), _cpu()
    found = parasynth.structures(motion)
    wall, cpu = time.perf_counter() - t0, _cpu() - c0
    checked = found.enumerated - found.dropped["duplicate"] - found.dropped["no task rule"] \
        - found.dropped["under-actuated"] - found.dropped["over-actuated"]
    return found, wall, cpu, checked


def design_ms(s) -> float:
    m = s.mechanism()
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    names = list(m.task_coordinates)
    ranges = {k: (a, b) for k, a, b in zip(names, lo, hi) if k in ("x", "y", "z")}
    sample = WorkspaceSample(ranges=ranges, n=8192, method="sobol", seed=0)
    vol, marg = objectives.get("workspace_volume"), objectives.get("singularity_margin_min")
    times = []
    for _ in range(6):
        c0 = time.process_time()
        vol(m, sample=sample)
        marg(m, sample=sample, quantile=0.05)
        times.append(time.process_time() - c0)
    return 1e3 * statistics.median(times[1:])  # the first compiles / fills the sample cache


def full_study() -> int:
    from parasynth.study import load_study, run_study
    from parasynth.study.schedule import structure_schedule

    study = load_study(ROOT / "studies" / "structures_3t2r.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        t0, c0 = time.perf_counter(), _cpu()
        res = run_study(study, out_dir=Path(tmp) / "run", progress=False)
        wall, cpu = time.perf_counter() - t0, _cpu() - c0
    run = res.table[res.table["source"] == "run"]
    plan = structure_schedule(study).plan(res.new_records)
    counts = run.groupby("structure").size().to_dict()
    survivors = plan.rungs[1].alive if len(plan.rungs) > 1 else plan.current.alive
    ok = plan.done and all(counts.get(s, 0) >= 200 for s in survivors) and wall <= LIMIT_S
    print(f"\nfull 3T2R study (studies/structures_3t2r.yaml): {len(run)} designs, {wall:.1f} s wall, "
          f"{cpu:.1f} s CPU (final re-evaluation included)")
    for s in study.structures.labels:
        note = "survived the screening" if s in survivors else plan.stopped_at().get(s, (0, 0, ""))[2]
        print(f"  {s:12s} {counts.get(s, 0):4d} designs  ({note})")
    print(f"every survivor >= 200 designs within {LIMIT_S // 60} min: {ok}")
    return 0 if ok else 1


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--no-study", action="store_true", help="skip the full 3T2R study")
    args = ap.parse_args(argv)
    warnings.simplefilter("error", EngineFallbackWarning)  # every structure compiled
    print(f"load average {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores)")
    print(f"{'motion':6s} {'enumerated':>10s} {'kept':>5s} {'wall s':>7s} {'CPU s':>6s} {'checked/s':>10s} "
          f"{'built/s':>8s}")
    rows = []
    for motion in ("3T3R", "3T2R", "2T2R"):
        found, wall, cpu, checked = enumeration(motion)
        print(f"{motion:6s} {found.enumerated:10d} {len(found):5d} {wall:7.2f} {cpu:6.2f} "
              f"{found.enumerated / wall:10.0f} {checked / wall:8.1f}")
        rows.append((motion, found))
    print("\nms per design (workspace volume + singularity margin q05, 8192 samples, CPU, median of 5):")
    for motion, found in rows:
        for s in found:
            print(f"  {motion:5s} {s.name:14s} {s.arrangement[:60]:60s} {design_ms(s):7.1f}")
    return 0 if args.no_study else full_study()


if __name__ == "__main__":
    raise SystemExit(main())
