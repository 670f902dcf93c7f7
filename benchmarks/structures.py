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

The chain limbs (``model/chains.py``: joint strings solved numerically, or by a closed form where
their geometry has one, then also solved numerically for comparison, ``<limb>/num``) against
closed forms:
``us/pose`` of the inverse kinematics of one limb, 4096 random poses, one thread, median of 5:
the NumPy reference (``ChainLeg.solve``) and the compiled kernel (``engine/chains.py``) of the
chain ``UP*S`` (the hand-written ``UPS``'s limb) and of the chain limbs of the vocabulary on
poses of their motion (x-y rotations; translations for RUU), with the fraction reached, each
against the closed-form ``UPS`` (NumPy) and the compiled against the NumPy chain; then the
feasibility of a whole mechanism per pose, a 6-UPS (closed form, the fused kernels) against a
6-SPU (chain limbs: compiled inverse kinematics, the constraints on NumPy). The enumeration of
3T2R above includes the chain limbs (the default vocabulary); their pose-wise indices and their
closure equations in the motion rule run on the compiled engine too; the only fallback allowed
is the pose of a structure of chain limbs whose motion is solved (counted), any other is an
error. The cost
of a design is summed up per motion: the median over the structures of chain limbs against the
median over those of closed-form legs.

Then the full 3T2R study ``studies/structures_3t2r.yaml`` (every 3T2R structure of the default
vocabulary, 50 designs each in the screening, 200 for each survivor) is run from scratch in a
temporary directory: its wall and CPU time, the designs per structure, and whether every
structure that survived the screening got at least 200 designs within 15 minutes.

Every enumeration is computed, none read back from the disk cache (``PARASYNTH_CACHE_DIR=off``
for this process and the study's, as on a machine that has not enumerated yet). Times on a
shared machine are noisy: compare the CPU times and the ratios of one run. Not part of the test
suite. Usage::

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
    """CPU seconds of this process and its ended children (the enumeration's checking
    processes)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def enumeration(motion: str, processes: int | None = None):
    t0, c0 = time.perf_counter(), _cpu()
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always", EngineFallbackWarning)
        found = parasynth.structures(motion, processes=processes)
    wall, cpu = time.perf_counter() - t0, _cpu() - c0
    _only_chain_fallbacks(w)
    checked = found.enumerated - found.dropped["duplicate"] - found.dropped["no task rule"] \
        - found.dropped["under-actuated"] - found.dropped["over-actuated"]
    return found, wall, cpu, checked


def _only_chain_fallbacks(caught) -> int:
    """The number of engine fallbacks, all of them the pose of a structure of chain limbs whose
    motion is solved (its pose program cannot hold the chains' nested closure solve); any other
    fallback (chain limbs' indices included: they are compiled) is an error."""
    n = 0
    for x in caught:
        if issubclass(x.category, EngineFallbackWarning):
            msg = str(x.message)
            if not ("pose_batch runs on NumPy" in msg and "a motion closing on" in msg
                    and any(t in msg for t in CHAIN_TYPES)):
                raise AssertionError(f"a structure fell back to NumPy: {msg}")
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
    """us per pose of the inverse kinematics: numeric chain limbs (NumPy reference and the
    compiled kernel, engine/chains.py) against a closed form; then per pose of a mechanism's
    feasibility, a 6-UPS on the kernels against a 6-SPU of chain limbs."""
    from parasynth.engine import chains as compiled_chains

    rng = np.random.default_rng(0)
    base, plat = np.array([0.3, 0.05, 0.0]), np.array([0.12, -0.06, 0.0])
    p = np.array([0.0, 0.0, 0.4]) + rng.uniform(-0.05, 0.05, (n, 3))
    R = euler_to_matrix("xyz", rng.uniform(-0.2, 0.2, (n, 3)))
    ups = UPS("L1", base=base, platform=plat)
    chain = ChainLeg("L1", base=base, platform=plat, chain="UP*S", axes=("tangent", "normal:prev", "limb"))
    Rxy = rot_x(rng.uniform(-0.2, 0.2, n)) @ rot_y(rng.uniform(-0.2, 0.2, n))
    rows = [("UP*S", chain, R)]
    I = np.broadcast_to(np.eye(3), (n, 3, 3))
    for t in CHAIN_TYPES:
        # poses of the limb's motion: x-y rotations, or none for a translational limb (RUU)
        leg = LEG_TYPES[t]("L1", base=base, platform=plat)
        rows.append((t, leg, I if t == "RUU" else Rxy))
        if leg.closed_form:  # the same limb solved numerically, to say what its closed form saves
            rows.append((f"{t}/num", LEG_TYPES[t]("L1", base=base, platform=plat, closed=False), Rxy))
    compiled_chains.solve(chain, p[:2], R[:2])  # compiled (or loaded) once, not timed
    ref = _median_us(lambda: ups.solve(p, R), n)
    print(f"\ninverse kinematics of one limb, us per pose ({n} poses, one thread, CPU, median of 5); "
          f"closed-form UPS (NumPy): {ref:.3f} us")
    print(f"  {'limb':8s} {'NumPy chain':>12s} {'compiled chain':>15s} {'compiled / UPS':>15s} "
          f"{'NumPy / compiled':>17s} {'reached':>8s}  solve")
    for name, leg, Rr in rows:
        us_np = _median_us(lambda: leg.solve(p, Rr), n)
        us_c = _median_us(lambda: compiled_chains.solve(leg, p, Rr), n)
        print(f"  {name:8s} {us_np:12.2f} {us_c:15.3f} {us_c / ref:14.1f}x {us_np / us_c:16.1f}x "
              f"{leg.solve(p, Rr).reachable.mean():8.2f}  {leg.closed_form or 'numerical'}")
    # a mechanism: feasibility per pose, 6-UPS (closed form, the kernels) against 6-SPU (chain limbs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        # each limb type alone: together the 6-SPU is reported as the inverted 6-UPS, one structure
        found = [s for t in ("UPS", "SPU") for s in parasynth.structures("3T3R", leg_types=[t], legs=[6])]
    mechs = {}
    for s in found:
        mechs.setdefault(s.name, s.mechanism())
    X = None
    out = {}
    for name, m in mechs.items():
        lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
        X = lo + (hi - lo) * np.random.default_rng(1).uniform(0, 1, (n, len(lo)))
        m.is_feasible(X[:8])  # compiled or loaded once
        out[name] = (_median_us(lambda: m.is_feasible(X), n), _median_us(lambda: m.is_feasible(X, engine="numpy"), n))
    if "6-UPS" in out and "6-SPU" in out:
        (u_c, u_n), (s_c, s_n) = out["6-UPS"], out["6-SPU"]
        print(f"\nfeasibility of a mechanism, us per pose ({n} poses in its task box, CPU, median of 5):")
        print(f"  6-UPS (closed form): compiled {u_c:.3f}, NumPy {u_n:.2f}")
        print(f"  6-SPU (chain limbs): compiled {s_c:.3f} ({s_c / u_c:.0f}x the 6-UPS), NumPy {s_n:.2f} "
              f"({s_n / s_c:.1f}x the compiled)")


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
    os.environ["PARASYNTH_CACHE_DIR"] = "off"  # every enumeration computed (parasynth.common.cache)
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
    walls = {}
    for motion in ("3T3R", "3T2R", "2T2R"):
        found, wall, cpu, checked = enumeration(motion)
        print(f"{motion:6s} {found.enumerated:10d} {len(found):5d} {wall:7.2f} {cpu:6.2f} "
              f"{found.enumerated / wall:10.0f} {checked / wall:8.1f}")
        rows.append((motion, found))
        walls[motion] = wall
    # the checks spread over the cores (structures' default) against one process
    one, wall1, cpu1, _ = enumeration("3T2R", processes=1)
    print(f"3T2R on one process: {wall1:.2f} s wall, {cpu1:.2f} s CPU ({len(one)} structures); on the cores "
          f"{walls['3T2R']:.2f} s, {wall1 / walls['3T2R']:.2f}x faster")
    chain_cost()
    print("\nms per design (workspace volume + singularity margin q05, 8192 samples, CPU, median of 5; chain "
          "limbs: compiled inverse kinematics and indices):")
    summary = []
    for motion, found in rows:
        cost = {"chain": [], "closed": []}
        for s in found:
            ms = design_ms(s)
            chain = any(g.limb in CHAIN_TYPES for g in s.groups)
            cost["chain" if chain else "closed"].append(ms)
            print(f"  {motion:5s} {s.name:14s} {s.arrangement[:60]:60s} {ms:7.1f}")
        if cost["chain"] and cost["closed"]:
            summary.append((motion, statistics.median(cost["chain"]), len(cost["chain"]),
                            statistics.median(cost["closed"]), len(cost["closed"])))
    for motion, mc, nc, mo, no in summary:
        print(f"{motion}: a design of chain limbs {mc:.1f} ms (median of {nc} structures), of closed-form legs "
              f"{mo:.1f} ms (median of {no}): {mc / mo:.1f}x; load average {os.getloadavg()[0]:.2f}")
    return 0 if args.no_study else full_study()


if __name__ == "__main__":
    raise SystemExit(main())
