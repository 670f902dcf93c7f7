"""Study throughput: milliseconds per design evaluation, compiled engine against NumPy.

For every study file in ``studies/`` (or those given), the same designs (drawn uniformly from
the study's variables with a fixed seed; the study's reference design first) are evaluated by
the study's evaluator (``parasynth.study.evaluate.Evaluator``: mechanism construction, design
constraints, objectives, with the study's workspace samples) twice in one run: with
``evaluation.engine = compiled`` and with ``evaluation.engine = numpy``. Warm-up designs
(compilation, first sample generation) are excluded. The objective values of the two engines
are compared (they agree except where a sample lies within rounding of a constraint
boundary) and the largest relative difference is printed.

Output, one line per study::

    <study> ms_per_design=<float> speedup_vs_numpy=<float>

plus, with ``--split``, the share of the compiled time spent in each measure and in building
the mechanism.

Usage::

    python benchmarks/study_throughput.py                  # every shipped study, 20 designs each
    python benchmarks/study_throughput.py studies/quickstart.yaml --designs 50 --split

Not part of the test suite.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _designs(study, k: int, seed: int) -> list[dict]:
    rng = np.random.default_rng(seed)
    out = []
    ref = getattr(study, "reference", None)
    if isinstance(ref, dict) and ref:
        out.append(dict(ref))
    while len(out) < k:
        d = {}
        for v in study.variables:
            if getattr(v, "choices", None):
                d[v.name] = v.choices[int(rng.integers(len(v.choices)))]
            elif getattr(v, "values", None):
                d[v.name] = v.values[int(rng.integers(len(v.values)))]
            elif v.type == "integer":
                d[v.name] = int(rng.integers(int(v.low), int(v.high) + 1))
            elif getattr(v, "log", False):
                d[v.name] = float(math.exp(rng.uniform(math.log(v.low), math.log(v.high))))
            else:
                d[v.name] = float(rng.uniform(v.low, v.high))
        out.append(d)
    return out[:k]


def _run(ev, designs, engine: str, split: bool):
    from parasynth.measures import objectives

    ev.study.evaluation["engine"] = engine
    parts: dict = {}
    if split:
        real_get = objectives.get

        def timed_get(name):
            m = real_get(name)

            class _Timed:
                cost = m.cost
                settings = m.settings

                def __call__(self, mech, **kw):
                    t0 = time.perf_counter()
                    try:
                        return m(mech, **kw)
                    finally:
                        parts[name] = parts.get(name, 0.0) + time.perf_counter() - t0

            return _Timed()

        import parasynth.study.evaluate as E

        E.get_measure = timed_get
        real_build = ev.build

        def timed_build(values):
            t0 = time.perf_counter()
            try:
                return real_build(values)
            finally:
                parts["(build mechanism)"] = parts.get("(build mechanism)", 0.0) + time.perf_counter() - t0

        ev.build = timed_build
    for d in designs[:2]:  # warm-up: compilation, sample generation
        ev.evaluate(d)
    parts.clear()
    recs = []
    t0 = time.perf_counter()
    for d in designs:
        recs.append(ev.evaluate(d))
    dt = time.perf_counter() - t0
    if split:
        import parasynth.study.evaluate as E

        E.get_measure = objectives.get
        del ev.build
    return dt / len(designs), recs, parts


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("studies", nargs="*", help="study files (default: every studies/*.yaml)")
    ap.add_argument("--designs", type=int, default=20, help="designs per study (default 20)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--split", action="store_true", help="print where the compiled time goes")
    args = ap.parse_args(argv)
    from parasynth.study.evaluate import Evaluator
    from parasynth.study.spec import load_study

    files = [Path(f) for f in args.studies] or sorted((ROOT / "studies").glob("*.yaml"))
    lines = []
    for f in files:
        study = load_study(str(f))
        ev = Evaluator(study)
        designs = _designs(study, args.designs, args.seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t_c, rc, parts = _run(ev, designs, "compiled", args.split)
            t_n, rn, _ = _run(ev, designs, "numpy", False)
        worst = 0.0
        failed = sum(r.status != "ok" for r in rc)
        for a, b in zip(rc, rn):
            for k, va in a.objectives.items():
                vb = b.objectives.get(k)
                if vb is not None and math.isfinite(va) and math.isfinite(vb):
                    worst = max(worst, abs(va - vb) / max(abs(va), abs(vb), 1e-300))
        print(f"{study.name}: {len(designs)} designs ({failed} failed), compiled {t_c * 1e3:.3f} ms, "
              f"numpy {t_n * 1e3:.3f} ms per design; largest relative objective difference {worst:.3g}",
              file=sys.stderr)
        if args.split and parts:
            tot = sum(parts.values())
            for k, v in sorted(parts.items(), key=lambda kv: -kv[1]):
                print(f"  {k}: {v / len(designs) * 1e3:.3f} ms per design ({v / tot:.0%})", file=sys.stderr)
        lines.append(f"{study.name} ms_per_design={t_c * 1e3:.6g} speedup_vs_numpy={t_n / t_c:.6g}")
    for line in lines:
        print(line)


if __name__ == "__main__":
    main()
