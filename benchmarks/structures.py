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

The chain limbs (``model/chains.py``: joint strings solved numerically) against closed forms:
``us/pose`` of the inverse kinematics of one limb, NumPy, 4096 random poses, median of 5: the
chain ``UP*S`` against the hand-written ``UPS`` (the same limb), and the chain limbs of the
vocabulary on poses of their motion (x-y rotations; translations for RUU), with the fraction
reached; the enumeration of 3T2R above includes them
(the default vocabulary), their structures run on NumPy (no compiled kernel: the fallback
warnings are counted, and any fallback of a structure of hand-written limbs is an error).

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
from parasynth.model.chains import ChainLeg  # noqa: E402
from parasynth.model.legs import LEG_TYPES, UPS  # noqa: E402
from parasynth.model.spatial import euler_to_matrix, rot_x, rot_y  # noqa: E402

#: The leg types of the registry that are chain limbs (solved numerically).
CHAIN_TYPES = tuple(k for k, v in LEG_TYPES.items() if issubclass(v, ChainLeg))

LIMIT_S = 15 * 60


def _cpu() -> float:
    t = os.times()
    return t.user + t.system


def enumeration(motion: str):
    t0, c0 = time.perf_counter(), _cpu()
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always", EngineFallbackWarning)
        found = parasynth.structures(motion)
    wall, cpu = time.perf_counter() - t0, _cpu() - c0
    _only_chain_fallbacks(w)
    checked = found.enumerated - found.dropped["duplicate"] - found.dropped["no task rule"] \
        - found.dropped["under-actuated"] - found.dropped["over-actuated"]
    return found, wall, cpu, checked


def _only_chain_fallbacks(caught) -> int:
    """The number of engine fallbacks, all of them of chain limbs (else an error)."""
    n = 0
    for x in caught:
        if issubclass(x.category, EngineFallbackWarning):
            if not any(f"leg type {t} does not support 'compiled'" in str(x.message) for t in CHAIN_TYPES):
                raise AssertionError(f"a structure of hand-written limbs fell back to NumPy: {x.message}")
            n += 1
    return n


def _median_us(f, n, repeat=5) -> float:
    times = []
    for _ in range(repeat):
        c0 = time.process_time()
        f()
        times.append(time.process_time() - c0)
    return 1e6 * statistics.median(times) / n


def chain_cost(n: int = 4096):
    """us per pose of the inverse kinematics: numeric chain limbs against a closed form."""
    rng = np.random.default_rng(0)
    base, plat = np.array([0.3, 0.05, 0.0]), np.array([0.12, -0.06, 0.0])
    p = np.array([0.0, 0.0, 0.4]) + rng.uniform(-0.05, 0.05, (n, 3))
    R = euler_to_matrix("xyz", rng.uniform(-0.2, 0.2, (n, 3)))
    ups = UPS("L1", base=base, platform=plat)
    chain = ChainLeg("L1", base=base, platform=plat, chain="UP*S", axes=("tangent", "normal:prev", "limb"))
    Rxy = rot_x(rng.uniform(-0.2, 0.2, n)) @ rot_y(rng.uniform(-0.2, 0.2, n))
    rows = [("UPS (closed form)", lambda: ups.solve(p, R)), ("UP*S (chain, numeric)", lambda: chain.solve(p, R))]
    I = np.broadcast_to(np.eye(3), (n, 3, 3))
    for t in CHAIN_TYPES:
        leg = LEG_TYPES[t]("L1", base=base, platform=plat)
        # poses of the limb's motion: x-y rotations, or none for a translational limb (RUU)
        Rt = I if t == "RUU" else Rxy
        rows.append((f"{t} (chain, numeric)", lambda leg=leg, Rt=Rt: leg.solve(p, Rt)))
    print(f"\ninverse kinematics of one limb, us per pose (NumPy, {n} poses, CPU, median of 5; reached: the "
          f"fraction of the poses solved):")
    ref = None
    for name, f in rows:
        us = _median_us(f, n)
        ref = ref or us
        print(f"  {name:24s} {us:8.2f}  ({us / ref:5.0f} x the closed form)  reached {f().reachable.mean():.2f}")


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
    ap.add_argument("--chains", action="store_true", help="only the enumeration of 3T2R and the chain limbs' cost")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", EngineFallbackWarning)  # counted per enumeration (chain limbs only)
    print(f"load average {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores)")
    print(f"{'motion':6s} {'enumerated':>10s} {'kept':>5s} {'wall s':>7s} {'CPU s':>6s} {'checked/s':>10s} "
          f"{'built/s':>8s}")
    rows = []
    if args.chains:
        found, wall, cpu, checked = enumeration("3T2R")
        print(f"3T2R   {found.enumerated:10d} {len(found):5d} {wall:7.2f} {cpu:6.2f} {found.enumerated / wall:10.0f} "
              f"{checked / wall:8.1f}   (60 s allowed)")
        chain_cost()
        return 0 if wall <= 60 else 1
    for motion in ("3T3R", "3T2R", "2T2R"):
        found, wall, cpu, checked = enumeration(motion)
        print(f"{motion:6s} {found.enumerated:10d} {len(found):5d} {wall:7.2f} {cpu:6.2f} "
              f"{found.enumerated / wall:10.0f} {checked / wall:8.1f}")
        rows.append((motion, found))
    chain_cost()
    print("\nms per design (workspace volume + singularity margin q05, 8192 samples, CPU, median of 5; chain "
          "limbs on NumPy):")
    for motion, found in rows:
        for s in found:
            print(f"  {motion:5s} {s.name:14s} {s.arrangement[:60]:60s} {design_ms(s):7.1f}")
    return 0 if args.no_study else full_study()


if __name__ == "__main__":
    raise SystemExit(main())
