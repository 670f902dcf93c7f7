"""Task evaluation: milliseconds per design of the task measures on the naval testbed.

The task of ``studies/naval_testbed.yaml`` (342 required tool poses, a hanging 6-UPS, a 54.2 kg
payload, a constant process wrench; docs/tasks.md) is evaluated on a new design each call
(base and platform radii drawn uniformly from a part of the study's box where every required
pose is reached, so every pose-wise measure does its whole work; a fresh mechanism, hence a
fresh task evaluation, each time). The mechanism and the design's task are built outside the
timed region; the compiled kernels are compiled (or loaded from the cache) by warm-up designs
that are not timed, which also compute the task's mechanism-independent work once (the poses
and the path's samples in the task frame, shared by the design's task copies as in a study).
Two workloads:

* ``task evaluation``: ``task_measures`` of ``task_coverage``, ``task_margin_min``,
  ``task_condition_max``, ``task_lti_min`` and ``task_actuator_force_max`` on the task
  without its path (what a study evaluates on the poses: platform poses, feasibility, the
  three compiled index kernels, the static forces with the wrench and the payload's weight);
* ``task with trajectory``: the same measures plus ``task_actuator_speed_max`` and
  ``task_actuator_power_max`` on the task with its path (~7,000 samples at 50 ms: the path's
  platform coordinates and twists, feasibility along it, the payload's inverse dynamics and
  the actuator rates at every sample; path continuity is not per design, it is part of the
  verification).

The baseline, timed in the same run on the same designs: a fused numba kernel written here
doing the bare inverse kinematics of the 6-UPS (platform position and x-y-z angles to the six
leg lengths, every pose feasible: no limit checked), on the design's platform poses (342) and
on its path samples; its answer is checked against ``mech.inverse_kinematics``. The printed
ratios say how many bare inverse kinematics one task evaluation costs.

Output ends with::

    task evaluation: <X> ms per design
    task with trajectory: <Y> ms per design

(medians over the timed designs), and the script exits with status 1, naming the limit, when
``X > 5`` or ``Y > 50`` (``--pose-limit``, ``--path-limit``).

Noise. On a shared machine other processes take the cores for a while and a timing grows by
what they took, never shrinks. So each design is evaluated ``--repeats`` times (default 5), each
time from scratch (a fresh mechanism and task, nothing cached), and its time is the **best** of
its repeats (the practice of Python's ``timeit``: the minimum is the measurement least disturbed
by other load; the mean and the largest only measure the load). The limits are asserted on the
median over designs of these best times. The CPU time of the process (``time.process_time``,
all its threads) is printed beside every wall time, best of the same repeats: CPU time does
not count the time the process waited for a core, so on a busy machine it stays near the
idle machine's wall time while the wall time grows. The machine's load average
(``/proc/loadavg``) is printed before and after.

Usage::

    python benchmarks/task.py                       # 200 designs without, 60 with the path, 5 repeats each
    python benchmarks/task.py --designs 400 --path-designs 100 --stages

``--stages`` also prints the median time of each stage of one evaluation (platform poses,
feasibility, each index, the static forces, the path, its feasibility, the dynamics, the
installation space's clearance). Beside the two limits it prints the time of one design of the
naval study as a run evaluates it (``Evaluator.evaluate``: the study's objectives and
constraints, ``envelope_clearance`` included; ``--study-designs``), with no limit asserted.

Not part of the test suite.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
STUDY = ROOT / "studies" / "naval_testbed.yaml"

#: The measures a study evaluates on the poses, and those the path adds.
POSE_MEASURES = ("task_coverage", "task_margin_min", "task_condition_max", "task_lti_min", "task_actuator_force_max")
PATH_MEASURES = POSE_MEASURES + ("task_actuator_speed_max", "task_actuator_power_max")

#: Radii (m) drawn per design: a part of the study's box (base 400-750 mm, platform 100-400 mm)
#: where the 342 poses are all reached (checked for every design, printed).
BASE_RADIUS = (0.56, 0.66)
PLATFORM_RADIUS = (0.26, 0.36)
#: The other design values, fixed: the study's task placement (base plane 800 mm above W's
#: origin) and the shipped pair separations.
FIXED = {"base_separation": math.radians(20.0), "platform_separation": math.radians(20.0),
         "task.placement.z": 0.8, "task.placement.yaw": 0.0, "task.tool.yaw": 0.0}


# ---------------------------------------------------------------------------------------------
# the baseline: bare inverse kinematics of the 6-UPS, one fused kernel
# ---------------------------------------------------------------------------------------------
def _baseline_kernel():
    from numba import njit

    @njit(cache=False, nogil=True)
    def leg_lengths(X, base, plat, out):
        """Leg lengths (N, 6) of poses X (N, 6) = x, y, z, alpha, beta, gamma with
        R = Rx(alpha) Ry(beta) Rz(gamma); base (6, 3), plat (6, 3) the anchors."""
        for k in range(X.shape[0]):
            ca, sa = math.cos(X[k, 3]), math.sin(X[k, 3])
            cb, sb = math.cos(X[k, 4]), math.sin(X[k, 4])
            cg, sg = math.cos(X[k, 5]), math.sin(X[k, 5])
            r00, r01, r02 = cb * cg, -cb * sg, sb
            r10, r11, r12 = sa * sb * cg + ca * sg, -sa * sb * sg + ca * cg, -sa * cb
            r20, r21, r22 = -ca * sb * cg + sa * sg, ca * sb * sg + sa * cg, ca * cb
            for i in range(base.shape[0]):
                ax, ay, az = plat[i, 0], plat[i, 1], plat[i, 2]
                dx = X[k, 0] + r00 * ax + r01 * ay + r02 * az - base[i, 0]
                dy = X[k, 1] + r10 * ax + r11 * ay + r12 * az - base[i, 1]
                dz = X[k, 2] + r20 * ax + r21 * ay + r22 * az - base[i, 2]
                out[k, i] = math.sqrt(dx * dx + dy * dy + dz * dz)

    return leg_lengths


# ---------------------------------------------------------------------------------------------
# designs
# ---------------------------------------------------------------------------------------------
class Designs:
    """A new design per call: the mechanism, the design's task with its path and without."""

    def __init__(self, seed: int):
        from parasynth.common.yamlio import load_yaml
        from parasynth.model.task import Task
        from parasynth.study import load_study
        from parasynth.study.design import design_mechanism, design_task

        self.study = load_study(str(STUDY))
        raw = load_yaml(str(STUDY))["task"]
        # the same task without its path (from the same section, so nothing else differs)
        self.pose_task = Task.from_mapping({k: v for k, v in raw.items() if k != "trajectory"},
                                           base_dir=str(STUDY.parent))
        assert np.array_equal(self.pose_task.poses, self.study.task.poses)
        self._mech, self._task = design_mechanism, design_task
        self.rng = np.random.default_rng(seed)

    def values(self) -> dict:
        return {"base_radius": float(self.rng.uniform(*BASE_RADIUS)),
                "platform_radius": float(self.rng.uniform(*PLATFORM_RADIUS)), **FIXED}

    def __call__(self, path: bool, v: dict | None = None):
        """A fresh mechanism and task (nothing cached) of the design ``v`` (a new one if None)."""
        v = self.values() if v is None else v
        mech = self._mech(self.study, v)
        task = self._task(self.study, v)
        if not path:
            task = self.pose_task.with_settings({k[5:]: x for k, x in v.items() if k.startswith("task.")})
        return mech, task


def _anchors(mech):
    return (np.ascontiguousarray([np.asarray(leg.base, float) for leg in mech.legs]),
            np.ascontiguousarray([np.asarray(leg.platform, float) for leg in mech.legs]))


def _quartiles(ts) -> str:
    q = np.percentile(np.asarray(ts) * 1e3, [0, 25, 50, 75, 100])
    return "min {:.3f}, quartiles {:.3f} / {:.3f} / {:.3f}, max {:.3f} ms".format(*q)


def _loadavg() -> str:
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "n/a"


# ---------------------------------------------------------------------------------------------
# measurement
# ---------------------------------------------------------------------------------------------
def run(args) -> int:
    from parasynth.measures.task import task_evaluation, task_measures

    kernel = _baseline_kernel()
    designs = Designs(args.seed)
    load0 = _loadavg()

    # warm-up: compile or load every kernel (the engine's and the baseline's), not timed
    t0 = time.perf_counter()
    for path in (False, True, False, True):
        mech, task = designs(path)
        task_measures(mech, task, PATH_MEASURES if path else POSE_MEASURES)
        X = task.platform_poses(mech)
        out = np.empty((len(X), 6))
        kernel(X, *_anchors(mech), out)
        ref = mech.inverse_kinematics(X).actuators
        err = float(np.max(np.abs(out - ref)))
        if not err < 1e-12:
            print(f"baseline: leg lengths differ from mech.inverse_kinematics by {err:.3g} m", file=sys.stderr)
            return 2
    print(f"warm-up (compile or cache load, 4 designs): {time.perf_counter() - t0:.1f} s")

    reps = args.repeats

    def best_of(fn):
        """(best wall, best CPU, the last result) over ``reps`` calls of ``fn`` (fresh work each)."""
        walls, cpus, res = [], [], None
        for _ in range(reps):
            c0, t0 = time.process_time(), time.perf_counter()
            res = fn()
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
        return min(walls), min(cpus), res

    def evaluate(path, v):
        def fn():
            mech, task = built.pop()
            return task_measures(mech, task, PATH_MEASURES if path else POSE_MEASURES)
        built = [designs(path, v) for _ in range(reps)]  # built outside the timed calls
        return best_of(fn)

    def baseline(X, mech):
        base, plat = _anchors(mech)
        out = np.empty((len(X), 6))
        return best_of(lambda: kernel(X, base, plat, out))

    # the task evaluation without the path, and its baseline on the same poses
    t_pose, c_pose, t_base, c_base, cover = [], [], [], [], []
    for _ in range(args.designs):
        v = designs.values()
        mech, task = designs(False, v)
        X = task.platform_poses(mech)
        w, c, _ = baseline(X, mech)
        t_base.append(w)
        c_base.append(c)
        w, c, m = evaluate(False, v)
        t_pose.append(w)
        c_pose.append(c)
        cover.append(m["task_coverage"])
    n_poses = len(X)

    # with the path
    t_path, c_path, t_base_path, c_base_path, cover_path, n_samples = [], [], [], [], [], 0
    for _ in range(args.path_designs):
        v = designs.values()
        mech, task = designs(True, v)
        Xp = task_evaluation(mech, task).path.X  # not timed: the baseline's input
        w, c, _ = baseline(Xp, mech)
        t_base_path.append(w)
        c_base_path.append(c)
        n_samples = len(Xp)
        w, c, m = evaluate(True, v)
        t_path.append(w)
        c_path.append(c)
        cover_path.append(m["task_coverage"])

    # one design of the naval study as a run evaluates it: every objective and constraint
    # (force, power, coverage, condition number, envelope clearance), the record's bookkeeping
    from parasynth.study.evaluate import Evaluator
    t_study, c_study = [], []
    for _ in range(args.study_designs):
        v = designs.values()
        evaluators = [Evaluator(designs.study) for _ in range(reps)]  # fresh caches per repeat
        w, c, rec = best_of(lambda: evaluators.pop().evaluate(v))
        t_study.append(w)
        c_study.append(c)
        if rec.status != "ok":
            print(f"study design failed: {rec.error}", file=sys.stderr)
            return 2

    stages = _stages(designs, args.designs) if args.stages else None
    load1 = _loadavg()

    x, y = float(np.median(t_pose)) * 1e3, float(np.median(t_path)) * 1e3
    cx, cy = float(np.median(c_pose)) * 1e3, float(np.median(c_path)) * 1e3
    bx, by = float(np.median(t_base)) * 1e3, float(np.median(t_base_path)) * 1e3
    print(f"cores: {os.cpu_count()}; load average before {load0}, after {load1}")
    print(f"every time below: the best of {reps} repeats of a design from scratch, then over the designs")
    print(f"designs: base radius {BASE_RADIUS[0] * 1e3:.0f}-{BASE_RADIUS[1] * 1e3:.0f} mm, platform radius "
          f"{PLATFORM_RADIUS[0] * 1e3:.0f}-{PLATFORM_RADIUS[1] * 1e3:.0f} mm; task_coverage "
          f"{min(cover + cover_path):.3f}-{max(cover + cover_path):.3f}")
    print(f"{n_poses} poses, {args.designs} designs: task evaluation wall {_quartiles(t_pose)}")
    print(f"  CPU (this process) {_quartiles(c_pose)}")
    print(f"  baseline (bare IK of {n_poses} poses): wall {_quartiles(t_base)}, CPU median "
          f"{np.median(c_base) * 1e3:.3f} ms; ratio {x / bx:.1f}")
    print(f"path of {n_samples} samples, {args.path_designs} designs: task with trajectory wall {_quartiles(t_path)}")
    print(f"  CPU (this process) {_quartiles(c_path)}")
    print(f"  baseline (bare IK of {n_samples} samples): wall {_quartiles(t_base_path)}, CPU median "
          f"{np.median(c_base_path) * 1e3:.3f} ms; ratio {y / by:.1f}")
    z = float(np.median(t_study)) * 1e3
    print(f"naval study, {args.study_designs} designs (Evaluator.evaluate: objectives and constraints, "
          f"envelope_clearance included): wall {_quartiles(t_study)}; CPU median {np.median(c_study) * 1e3:.3f} ms")
    print(f"  3000 designs at this median on 2 workers: {3000 * z / 2 / 6e4:.1f} min (the issue's study limit: 10 min)")
    if stages:
        print("stages of one evaluation (median ms):")
        for k, v in stages.items():
            print(f"  {k:16s} {v:8.3f}")
    print(f"task evaluation: {x:.3f} ms per design (CPU {cx:.3f} ms)")
    print(f"task with trajectory: {y:.3f} ms per design (CPU {cy:.3f} ms)")
    print(f"baseline ratio: task evaluation / bare IK = {x / bx:.1f}, task with trajectory / bare IK = {y / by:.1f}")
    missed = []
    if not x <= args.pose_limit:
        missed.append(f"task evaluation {x:.3f} ms > {args.pose_limit:g} ms")
    if not y <= args.path_limit:
        missed.append(f"task with trajectory {y:.3f} ms > {args.path_limit:g} ms")
    if not min(cover + cover_path) == 1.0:
        missed.append("a design does not reach every pose (the timing is not the worst case)")
    for m in missed:
        print(f"LIMIT MISSED: {m}")
    return 1 if missed else 0


def _stages(designs, n: int) -> dict:
    """Median time (ms) of each stage of one evaluation, in the order the measures need them."""
    from parasynth.measures.task import task_evaluation

    names = ("X", "feasible", "margin", "condition", "lti", "static_forces", "path", "path_feasible",
             "dynamic_forces", "clearance")
    acc = {k: [] for k in names}
    for _ in range(max(10, n // 4)):
        mech, task = designs(True)
        ev = task_evaluation(mech, task)
        for k in names:
            t0 = time.perf_counter()
            getattr(ev, k)
            acc[k].append(time.perf_counter() - t0)
    return {k: float(np.median(v)) * 1e3 for k, v in acc.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--designs", type=int, default=200, help="timed designs without the path (default 200)")
    ap.add_argument("--path-designs", type=int, default=60, help="timed designs with the path (default 60)")
    ap.add_argument("--pose-limit", type=float, default=5.0, help="limit of the task evaluation, ms (default 5)")
    ap.add_argument("--path-limit", type=float, default=50.0, help="limit with the trajectory, ms (default 50)")
    ap.add_argument("--study-designs", type=int, default=30,
                    help="timed designs of the naval study's whole evaluation (default 30; no limit asserted)")
    ap.add_argument("--repeats", type=int, default=5,
                    help="evaluations of each design from scratch; its time is the best (default 5)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--stages", action="store_true", help="also print the median time of each stage")
    args = ap.parse_args(argv)
    if args.designs < 1 or args.path_designs < 1 or args.study_designs < 1 or args.repeats < 1:
        ap.error("--designs, --path-designs, --study-designs and --repeats must be at least 1")
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
