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

plus, with ``--split``, the CPU time per design (all threads) and the share of the compiled
(wall) time spent in each measure, in building the mechanism and in the kernels (every
compiled batch, timed around ``core._timed_claims`` and ``core._timed_blocks``).

``--figures`` instead prints, for the quick start (or the studies given), one design's
evaluation on the study's fixed samples (wall and CPU ms, in the kernels and outside them),
with new samples, drawing a new sample set alone, and the anchor's time for as many poses
(``benchmarks/anchor.py``) measured in the same run, with the ratio::

    figure design_evaluation ms=<f> cpu_ms=<f> kernels_ms=<f> outside_kernels_ms=<f> anchor_ms=<f> time_vs_anchor=<f>
    figure design_evaluation_new_samples ms=<f> cpu_ms=<f>
    figure new_samples_<n> ms=<f> min_ms=<f>

``--samplers`` prints what each of Optuna's samplers (``optimizer.algorithm``, as the study's
run makes it: :func:`parasynth.study.workers.make_sampler`, seeded per trial) costs per trial on
top of the design's evaluation: ask (the sampler's choice and the study's variables suggested)
and tell (the objectives and the constraint values) on an in-memory Optuna study with the
study's objectives, over the study's ``n_trials`` trials, with a cheap stand-in for the
evaluation, beside one design's evaluation on the fixed samples::

    sampler <name> ms_per_trial=<f> cpu_ms_per_trial=<f> bare_sampler_ms_per_trial=<f> bare_cpu_ms_per_trial=<f> evaluation_ms=<f> evaluation_cpu_ms=<f> sampler_vs_evaluation=<f>

(``bare``: Optuna's sampler alone, not made anew for every trial as the run's per-trial seeding
does.)

Usage::

    python benchmarks/study_throughput.py                  # every shipped study, 20 designs each
    python benchmarks/study_throughput.py studies/quickstart.yaml --designs 50 --split
    python benchmarks/study_throughput.py --figures --designs 100
    python benchmarks/study_throughput.py --samplers        # the quick start's trials, per sampler

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


def _compile_as_a_run_does() -> None:
    """Compile what a run of a study compiles from its start (``precompile.STUDY``: the
    feasibility, the singularity margin and the structural constraint rank, which a design asks
    for only once it is compiled), so that the designs are timed on the run's path whatever
    this installation compiled before."""
    from parasynth.engine import core, precompile

    if core.HAVE_NUMBA:
        todo = precompile.missing(precompile.STUDY)
        if todo:
            print(f"compiling as a run does: {', '.join(todo)}", file=sys.stderr, flush=True)
            precompile.compile_ahead(todo)


def _run(ev, designs, engine: str, split: bool):
    """Seconds per design of ``designs`` evaluated by ``ev`` (a fresh evaluator: it keeps the
    measures' arguments, the engine among them, for the designs of a run) with ``engine``."""
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
        undo_kernels = _kernel_timer(parts)
    for d in designs[:2]:  # warm-up: compilation, sample generation
        ev.evaluate(d)
    parts.clear()
    recs = []
    c0 = time.process_time()
    t0 = time.perf_counter()
    for d in designs:
        recs.append(ev.evaluate(d))
    dt = time.perf_counter() - t0
    parts["(cpu)"] = time.process_time() - c0
    if split:
        import parasynth.study.evaluate as E

        E.get_measure = objectives.get
        del ev.build
        undo_kernels()
    return dt / len(designs), recs, parts


#: The kernels a design's evaluation calls directly, one call over a whole batch or pose (not
#: through ``core.over_blocks``): the UPU legs' mean lengths over the margin's poses and the
#: structural constraint rank at home.
DIRECT_KERNELS = ("_upu_mean_lengths", "_constraint_rank_kernel")


def _kernel_timer(parts: dict):
    """Count the time spent inside the engine's kernels in ``parts["(kernels)"]``: every
    compiled batch, from its blocking to its end (``core._timed_claims``, ``core._timed_blocks``,
    and the index kernels' batches through the ``over_blocks`` imported in ``indices``; on one
    thread or several, through the compiled crew or the interpreter's), and the kernels called
    directly (:data:`DIRECT_KERNELS`); returns a function that undoes it."""
    from parasynth.engine import core, indices

    def timing(fn):
        def call(*args, **kw):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kw)
            finally:
                parts["(kernels)"] = parts.get("(kernels)", 0.0) + time.perf_counter() - t0
        return call

    real = {(core, "_timed_claims"): core._timed_claims, (core, "_timed_blocks"): core._timed_blocks,
            (indices, "over_blocks"): indices.over_blocks}
    real.update({(indices, name): getattr(indices, name) for name in DIRECT_KERNELS if hasattr(indices, name)})
    for (mod, name), fn in real.items():
        setattr(mod, name, timing(fn))

    def undo():
        for (mod, name), fn in real.items():
            setattr(mod, name, fn)

    return undo


def figures(study_file: str, k: int, seed: int) -> None:
    """The quick start's figures beside the anchor (benchmarks/anchor.py) in this process: a
    design evaluation on the study's fixed samples (wall and CPU time, the time in the
    kernels and outside them), with new samples (a new seed each design), drawing a new set
    of the study's samples alone, and the anchor's time for as many poses on all threads."""
    import os
    import shutil
    import tempfile

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import anchor

    from parasynth.common import qmc
    from parasynth.study.evaluate import Evaluator
    from parasynth.study.spec import load_study

    _compile_as_a_run_does()
    study = load_study(study_file)
    ev = Evaluator(study)
    designs = _designs(study, k, seed)
    n = int(study.evaluation["n"])
    d = len(study.evaluation.get("ranges") or {}) or 3
    load0 = os.getloadavg()[0]
    for x in designs[:3]:
        ev.evaluate(x)

    def timed(fn, reps=5):
        """(wall, cpu, kernels) per design of the fastest of ``reps`` passes."""
        best = (math.inf, math.inf, math.inf)
        parts: dict = {}
        undo = _kernel_timer(parts)
        try:
            for _ in range(reps):
                parts.clear()
                c0, t0 = time.process_time(), time.perf_counter()
                fn()
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                best = min(best, tuple(v / len(designs) for v in (wall, cpu, parts.get("(kernels)", 0.0))))
        finally:
            undo()
        return best

    fixed = timed(lambda: [ev.evaluate(x) for x in designs])
    kern = fixed[2]
    # seeds not drawn before (new samples each design), their points kept in a folder of this run
    # (as a run keeps them, written to disk) removed afterwards: made in the folder a run writes
    # them to (the user's cache folder, qmc.cache_dir), so that the writes cost what a run's do
    # (on this machine a file written under /tmp took twice as long as one under the home folder)
    base = 10**9 + int.from_bytes(os.urandom(4), "little") * 10**4
    it = iter(range(10**9))
    home = qmc.cache_dir()
    if home is not None:
        os.makedirs(home, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix="parasynth-new-samples-", dir=home)
    prev = os.environ.get("PARASYNTH_CACHE_DIR")
    os.environ["PARASYNTH_CACHE_DIR"] = tmp
    try:
        new = timed(lambda: [ev.evaluate(x, seed=base + next(it)) for x in designs], reps=3)
        draws = []
        for _ in range(30):
            t0 = time.perf_counter()
            qmc.sobol_points(d, base + next(it), n)
            draws.append(time.perf_counter() - t0)
    finally:
        if prev is None:
            os.environ.pop("PARASYNTH_CACHE_DIR", None)
        else:
            os.environ["PARASYNTH_CACHE_DIR"] = prev
        shutil.rmtree(tmp, ignore_errors=True)
    a2 = anchor.anchor_seconds(n, 2)
    load1 = os.getloadavg()[0]
    print(f"{study.name}: load average (1 min) {load0:.2f} before, {load1:.2f} after; anchor {n} poses "
          f"{a2 * 1e3:.3f} ms (benchmarks/anchor.py, all threads)", file=sys.stderr)
    print(f"figure design_evaluation ms={fixed[0] * 1e3:.3f} cpu_ms={fixed[1] * 1e3:.3f} "
          f"kernels_ms={kern * 1e3:.3f} outside_kernels_ms={(fixed[0] - kern) * 1e3:.3f} "
          f"anchor_ms={a2 * 1e3:.3f} time_vs_anchor={fixed[0] / a2:.3g} (targets: <= 5x the anchor, <= 2 ms, "
          f"outside the kernels < 0.5 ms)")
    print(f"figure design_evaluation_new_samples ms={new[0] * 1e3:.3f} cpu_ms={new[1] * 1e3:.3f} "
          f"kernels_ms={new[2] * 1e3:.3f}")
    print(f"figure new_samples_{n} ms={float(np.median(draws)) * 1e3:.3f} min_ms={min(draws) * 1e3:.3f} "
          f"(target <= 0.5)", flush=True)


def samplers(study_file: str, k: int, seed: int) -> None:
    """Per Optuna sampler, the time of a trial's ask and tell (the sampler's own work) on an
    in-memory study shaped as ``study_file``'s, over its ``n_trials`` trials; beside it one
    design's evaluation on the fixed samples (the mean of ``k`` designs)."""
    import os

    import optuna

    from parasynth.study.evaluate import Evaluator
    from parasynth.study.spec import load_study
    from parasynth.study.workers import SAMPLERS, SINGLE_OBJECTIVE_SAMPLERS, make_sampler

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    _compile_as_a_run_does()
    study = load_study(study_file)
    ev = Evaluator(study)
    designs = _designs(study, k, seed)
    for x in designs[:3]:
        ev.evaluate(x)
    warnings.simplefilter("ignore")  # the samplers' experimental-feature warnings
    c0, t0 = time.process_time(), time.perf_counter()
    recs = [ev.evaluate(x) for x in designs]
    eval_s = (time.perf_counter() - t0) / len(designs)
    eval_cpu = (time.process_time() - c0) / len(designs)
    n_trials = int(getattr(study.optimizer, "n_trials", None) or 80)
    dirs = [o.goal for o in study.objectives]
    load0 = os.getloadavg()[0]
    rows = []
    for alg in SAMPLERS:
        if alg in SINGLE_OBJECTIVE_SAMPLERS and len(dirs) > 1:
            continue
        prev = study.optimizer.algorithm
        study.optimizer.algorithm = alg  # read by the sampler made for each trial
        try:
            seed0 = int(study.optimizer.seed or 0)
            bare = SAMPLERS[alg](optuna, seed0, None, study.optimizer.population_size)
            _trials(optuna, make_sampler(study, seed0), dirs, 3, study, recs)  # untimed: imports (QMC: scipy.stats)
            times = [_trials(optuna, make_sampler(study, seed0), dirs, n_trials, study, recs),
                     _trials(optuna, bare, dirs, n_trials, study, recs)]
        finally:
            study.optimizer.algorithm = prev
        rows.append((alg, *times[0], *times[1]))
    load1 = os.getloadavg()[0]
    print(f"{study.name}: {n_trials} trials per sampler, {len(dirs)} objective(s), {len(study.constraints)} "
          f"constraint(s); load average (1 min) {load0:.2f} before, {load1:.2f} after", file=sys.stderr)
    for alg, wall, cpu, bwall, bcpu in rows:
        print(f"sampler {alg} ms_per_trial={wall * 1e3:.3f} cpu_ms_per_trial={cpu * 1e3:.3f} "
              f"bare_sampler_ms_per_trial={bwall * 1e3:.3f} bare_cpu_ms_per_trial={bcpu * 1e3:.3f} "
              f"evaluation_ms={eval_s * 1e3:.3f} evaluation_cpu_ms={eval_cpu * 1e3:.3f} "
              f"sampler_vs_evaluation={cpu / eval_cpu:.3g} (CPU)", flush=True)


def _trials(optuna, sampler, dirs, n_trials, study, recs):
    """(wall s, CPU s) per trial of ``n_trials`` asks and tells with ``sampler``; the stored
    records ``recs`` stand in for the evaluations (their objectives and margins, in turn)."""
    from parasynth.study.workers import _set_optuna_constraints

    ostudy = optuna.create_study(directions=dirs, sampler=sampler)
    c0, t0 = time.process_time(), time.perf_counter()
    for i in range(n_trials):
        trial = ostudy.ask()
        study.space.suggest(trial)
        rec = recs[i % len(recs)]
        _set_optuna_constraints(trial, study, rec)
        ostudy.tell(trial, [rec.objectives.get(o.label, 0.0) for o in study.objectives])
    wall, cpu = (time.perf_counter() - t0) / n_trials, (time.process_time() - c0) / n_trials
    bad = [t.number for t in ostudy.trials if t.state.name != "COMPLETE"]
    if bad:
        raise RuntimeError(f"trials {bad} did not complete")
    return wall, cpu


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("studies", nargs="*", help="study files (default: every studies/*.yaml)")
    ap.add_argument("--designs", type=int, default=20, help="designs per study (default 20)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--split", action="store_true", help="print where the compiled time goes")
    ap.add_argument("--figures", action="store_true",
                    help="the figures of one design evaluation beside the anchor (benchmarks/anchor.py): fixed "
                         "samples, new samples, drawing new samples (default study: studies/quickstart.yaml)")
    ap.add_argument("--samplers", action="store_true",
                    help="what each Optuna sampler costs per trial on top of a design's evaluation (default study: "
                         "studies/quickstart.yaml)")
    args = ap.parse_args(argv)
    if args.samplers:
        for f in args.studies or [str(ROOT / "studies" / "quickstart.yaml")]:
            samplers(f, args.designs, args.seed)
        return
    if args.figures:
        for f in args.studies or [str(ROOT / "studies" / "quickstart.yaml")]:
            figures(f, args.designs, args.seed)
        return
    from parasynth.study.evaluate import Evaluator
    from parasynth.study.spec import load_study

    files = [Path(f) for f in args.studies] or sorted((ROOT / "studies").glob("*.yaml"))
    _compile_as_a_run_does()
    lines = []
    for f in files:
        study = load_study(str(f))
        designs = _designs(study, args.designs, args.seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            # an evaluator for each engine: one keeps its measures' arguments (the engine among
            # them) for the designs of a run, so a second engine needs its own
            t_c, rc, parts = _run(Evaluator(study), designs, "compiled", args.split)
            t_n, rn, _ = _run(Evaluator(study), designs, "numpy", False)
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
        cpu = parts.pop("(cpu)", math.nan)
        if args.split and parts:
            print(f"  CPU time (all threads) {cpu / len(designs) * 1e3:.3f} ms per design; the parts below are wall "
                  f"time", file=sys.stderr)
            kern = parts.pop("(kernels)", 0.0)
            tot = t_c * len(designs)
            for k, v in sorted(parts.items(), key=lambda kv: -kv[1]):
                print(f"  {k}: {v / len(designs) * 1e3:.3f} ms per design ({v / tot:.0%})", file=sys.stderr)
            print(f"  of which in the kernels: {kern / len(designs) * 1e3:.3f} ms per design ({kern / tot:.0%}); "
                  f"outside the kernels {(tot - kern) / len(designs) * 1e3:.3f} ms", file=sys.stderr)
        lines.append(f"{study.name} ms_per_design={t_c * 1e3:.6g} speedup_vs_numpy={t_n / t_c:.6g}")
    for line in lines:
        print(line)


if __name__ == "__main__":
    main()
