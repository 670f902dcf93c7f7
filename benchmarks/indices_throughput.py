"""Pose-wise index throughput: compiled kernels against the NumPy reference.

For every shipped mechanism (``parasynth.list_mechanisms()``), on the same random reachable
poses, poses per second of

* ``margin`` -- ``mech.singularity_margin`` (the normalised wrench system's smallest singular
  value),
* ``lti``    -- ``parasynth.measures.indices.local_transmission_index``,
* ``kappa``  -- ``parasynth.measures.indices.local_condition_number`` (task space),

each with ``engine="compiled"`` (timed after a warm-up call, so JIT compilation is excluded)
and ``engine="numpy"``, and the largest difference between the two (the contract is 1e-9,
relative for kappa). Whole calls are timed, pose parametrisation included. One line per
(mechanism, index)::

    <mechanism> <index> compiled_poses_per_s=<f> numpy_poses_per_s=<f> speedup=<f> max_diff=<g>

and, per mechanism, the fixed per-design cost of the margin: a fresh mechanism instance (a new
design) evaluated on a typical design's batch of feasible poses (``--design-poses``), with the
constraint rank included::

    <mechanism> margin_per_design_ms compiled=<f> numpy=<f> speedup=<f>

Usage::

    python benchmarks/indices_throughput.py                  # 4096 poses per mechanism
    python benchmarks/indices_throughput.py --n 20000 --models 5pus_upu 3rps

Not part of the test suite.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np


def _box(mech):
    rg = mech.default_ranges()
    lo, hi = [], []
    for c, h in zip(mech.task_coordinates, mech.home):
        if c in rg:
            a, b = rg[c]
        else:
            w = 0.3 if c in mech.angular_coordinates else 0.06
            a, b = h - w, h + w
        lo.append(a)
        hi.append(b)
    return np.array(lo), np.array(hi)


def reachable_poses(mech, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo, hi = _box(mech)
    out, have = [], 0
    for _ in range(200):
        X = lo + (hi - lo) * rng.random((max(4 * n, 4096), mech.n_task))
        X = X[mech.inverse_kinematics(X).reachable]
        out.append(X)
        have += len(X)
        if have >= n:
            break
    return np.concatenate(out)[:n]


def rate(f, n_poses: int, min_time: float = 0.5, repeat: int = 3) -> float:
    """Best poses/s over ``repeat`` runs of at least ``min_time`` s each (after a warm-up)."""
    f()
    best = 0.0
    for _ in range(repeat):
        k, t0 = 0, time.perf_counter()
        while True:
            f()
            k += 1
            dt = time.perf_counter() - t0
            if dt >= min_time:
                break
        best = max(best, k * n_poses / dt)
    return best


def per_design_ms(load, X, engine: str, k: int = 10) -> float:
    """ms for a fresh instance (a new design) to evaluate the margin on X, constraint rank
    included; the best of ``k``."""
    best = np.inf
    for _ in range(k):
        m = load()
        t0 = time.perf_counter()
        m.singularity_margin(X, engine=engine)
        best = min(best, time.perf_counter() - t0)
    return best * 1e3


def main(argv=None) -> int:
    import parasynth
    from parasynth.measures.indices import local_condition_number, local_transmission_index

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=float, default=4096, help="poses per mechanism (default 4096)")
    ap.add_argument("--design-poses", type=int, default=2000, help="feasible poses of one design (default 2000)")
    ap.add_argument("--models", nargs="*", default=None, help="mechanisms (default: all shipped)")
    ap.add_argument("--min-time", type=float, default=0.3, help="seconds per timing run (default 0.3)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    names = args.models or parasynth.list_mechanisms()
    n = int(args.n)
    for name in names:
        mech = parasynth.load_mechanism(name)
        X = reachable_poses(mech, n)
        N = len(X)
        cases = {
            "margin": (lambda e: mech.singularity_margin(X, engine=e), False),
            "lti": (lambda e: local_transmission_index(mech, X, engine=e), False),
            "kappa": (lambda e: local_condition_number(mech, X, engine=e), True),
        }
        for label, (f, relative) in cases.items():
            a, b = f("compiled"), f("numpy")
            ok = np.isfinite(a) & np.isfinite(b)
            d = np.abs(a[ok] - b[ok])
            if relative:
                d = d / np.abs(b[ok])
            diff = float(d.max()) if d.size else float("nan")
            rc = rate(lambda: f("compiled"), N, args.min_time)
            rn = rate(lambda: f("numpy"), N, args.min_time, repeat=1)
            print(f"{name} {label} compiled_poses_per_s={rc:.4g} numpy_poses_per_s={rn:.4g} "
                  f"speedup={rc / rn:.3g} max_diff={diff:.3g}", flush=True)
        Xd = X[: args.design_poses]
        load = lambda: parasynth.load_mechanism(name)  # noqa: E731 - a fresh design each time
        tc = per_design_ms(load, Xd, "compiled")
        tn = per_design_ms(load, Xd, "numpy", k=3)
        print(f"{name} margin_per_design_ms compiled={tc:.3f} numpy={tn:.3f} speedup={tn / tc:.3g} "
              f"(poses={len(Xd)})", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
