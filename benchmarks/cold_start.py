"""Cold start: the quick start with an empty compile cache, then warm, and the compile alone.

Fresh processes (``python -m parasynth.cli ...``), each with this benchmark's own temporary
cache folder (numba's ``NUMBA_CACHE_DIR``, and in it parasynth's ``PARASYNTH_CACHE_DIR`` of the
results kept on disk: sampled points, enumerated structures) and output directories:

1. **cold**: ``parasynth run STUDY`` with the cache empty (everything the run uses is
   compiled, then the run), timing the first line it writes on stderr (the compile notice:
   on a terminal a user sees it then);
2. **warm**: the same run again, the cache now filled;
3. **compile**: in a fresh process on another empty cache, ``parasynth.engine.warm_up`` of one
   design of the study (what the runner does before its timed loop): every kernel the study
   uses, and nothing else but the import and that one design;
4. **validate**: ``parasynth validate STUDY`` on a third empty cache.

A first run leaves background compiles running at a lower priority (the pose loops of
``parasynth.engine.posefn``, the compiled crew of ``parasynth.engine.core.spin_warm``): they go
on for seconds after it ends, on purpose. Before each of the four runs the benchmark waits for
every such process on the machine (``parasynth.engine.posefn`` or ``parasynth.engine.precompile``
in its command line; Linux), this run's or an earlier one's, and says how long it waited: so
the warm run is timed on a filled cache, and no run is slowed by another's helpers (a series of
cold runs one after the other was, by seconds).

The parasynth package these runs import is byte-compiled first (``compileall``, into its
``__pycache__`` folders), as ``pip install .`` of the quick start does at install: a source tree
run with ``PYTHONDONTWRITEBYTECODE=1`` (some sandboxes set it) would otherwise translate every
module of parasynth again in every process, ~0.3 s each, which no installed user pays.
``--no-bytecode`` leaves that out.

The ``results.csv`` of the cold and the warm run are compared column by column (``time_s``
excepted): they must be identical. Times are wall clock; the CPU time (user + sys of the
process and its children) follows each, and the load average of the machine is printed,
since on a shared machine wall time depends on it. The last line::

    cold_s=<float> warm_s=<float> compile_s=<float> validate_s=<float> cold_cpu_s=<float>
    warm_cpu_s=<float> first_line_s=<float or none> identical=<bool>

Usage::

    python benchmarks/cold_start.py                      # studies/quickstart.yaml
    python benchmarks/cold_start.py studies/quickstart.yaml --n-trials 80
    python benchmarks/cold_start.py studies/structures_1t2r.yaml   # a structure study

Not part of the test suite.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

COMPILE_ONLY = r"""
import sys, time, warnings
t0 = time.perf_counter()
from parasynth.engine import warm_up
from parasynth.study.problem import Problem
from parasynth.study.runner import _warm_up_design
from parasynth.study.spec import load_study
study = load_study(sys.argv[1])
problem = Problem(study)
n_warm = max(1, int(study.evaluation["n"]) // 2)  # as the runner's warm-up
t1 = time.perf_counter()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    w = warm_up(lambda: problem.evaluate(_warm_up_design(problem), n=n_warm, source="warm-up"), progress=None)
if w.error is not None:
    raise w.error
print(f"import_s={t1 - t0:.3f} warm_up_s={w.seconds:.3f} compiled={w.compiled} kernels={len(set(w.kernels))}")
"""


def _run(cmd, cache: str, cwd=ROOT, first: list | None = None) -> tuple[float, float, str]:
    """Wall and CPU seconds (the process and its children) and the output of ``cmd``; with
    ``first`` a list, the seconds until the first line on stderr are appended to it (None if
    there was none)."""
    # both of parasynth's caches in the folder: numba's compiled kernels and the results kept on
    # disk (sampled points, enumerated structures: parasynth.common.cache), so that an empty
    # folder is a first run on a fresh machine
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, PARASYNTH_CACHE_DIR=os.path.join(cache, "parasynth"),
               PYTHONUNBUFFERED="1")
    t0 = time.perf_counter()
    r0 = os.times()
    p = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out: list = []
    err: list = []
    seen: list = []

    def read_err():
        for line in p.stderr:
            if not seen:
                seen.append(time.perf_counter() - t0)
            err.append(line)

    reader = threading.Thread(target=read_err, daemon=True)
    reader.start()
    out.append(p.stdout.read())
    p.wait()
    reader.join()
    r1 = os.times()
    dt = time.perf_counter() - t0
    cpu = (r1.children_user - r0.children_user) + (r1.children_system - r0.children_system)
    if first is not None:
        first.append(seen[0] if seen else None)
    if p.returncode != 0:
        sys.stderr.write("".join(out) + "".join(err))
        raise SystemExit(f"{' '.join(map(str, cmd))}: exit status {p.returncode}")
    return dt, cpu, "".join(out) + "".join(err)


#: What the command line of a background compile of parasynth holds.
HELPERS = (b"parasynth.engine.posefn", b"parasynth.engine.precompile")


def _wait_for_helpers(limit: float = 300.0) -> float:
    """Seconds spent waiting (at most ``limit``) until no background compile of parasynth runs
    on the machine (read from ``/proc``; 0 where there is none)."""
    t0 = time.perf_counter()
    if not os.path.isdir("/proc"):
        return 0.0
    while time.perf_counter() - t0 < limit:
        running = False
        for pid in os.listdir("/proc"):
            if not pid.isdigit() or int(pid) == os.getpid():
                continue
            try:
                with open(f"/proc/{pid}/cmdline", "rb") as f:
                    cmd = f.read()
            except OSError:
                continue
            if any(h in cmd for h in HELPERS):
                running = True
                break
        if not running:
            break
        time.sleep(0.2)
    return time.perf_counter() - t0


def _settle(what: str) -> None:
    waited = _wait_for_helpers()
    if waited >= 0.5:
        print(f"(waited {waited:.1f} s for background compiles to end before the {what})", file=sys.stderr)


def _identical(a: Path, b: Path) -> bool:
    import pandas as pd

    ta = pd.read_csv(a).drop(columns=["time_s"], errors="ignore")
    tb = pd.read_csv(b).drop(columns=["time_s"], errors="ignore")
    return ta.shape == tb.shape and ta.equals(tb)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("study", nargs="?", default=str(ROOT / "studies" / "quickstart.yaml"))
    ap.add_argument("--n-trials", type=int, default=None, help="budget of the runs (default: the study's)")
    ap.add_argument("--keep", action="store_true", help="keep the temporary directories (printed)")
    ap.add_argument("--no-bytecode", action="store_true",
                    help="do not byte-compile the parasynth package first (pip install does it at install)")
    args = ap.parse_args(argv)
    if not args.no_bytecode:
        import compileall

        import parasynth

        compileall.compile_dir(str(Path(parasynth.__file__).parent), quiet=2, workers=0)
    tmp = Path(tempfile.mkdtemp(prefix="parasynth-cold-"))
    py = [sys.executable, "-m", "parasynth.cli"]
    extra = ["--n-trials", str(args.n_trials)] if args.n_trials else []
    try:
        _settle("cold run")
        load = os.getloadavg()[0]
        cache = str(tmp / "cache")
        first: list = []
        cold_s, cold_cpu, out = _run(py + ["run", args.study, "--no-report", "--out", str(tmp / "cold")] + extra,
                                     cache, first=first)
        line = "no line on stderr" if first[0] is None else f"first line on stderr after {first[0]:.1f} s"
        print(f"cold run: {cold_s:.1f} s wall, {cold_cpu:.1f} s CPU; {line}", file=sys.stderr)
        _settle("warm run")
        warm_s, warm_cpu, _ = _run(py + ["run", args.study, "--quiet", "--no-report", "--out", str(tmp / "warm")]
                                   + extra, cache)
        print(f"warm run: {warm_s:.1f} s wall, {warm_cpu:.1f} s CPU; the cold run's extra: "
              f"{cold_s - warm_s:.1f} s wall, {cold_cpu - warm_cpu:.1f} s CPU", file=sys.stderr)
        _settle("compile")
        comp_s, comp_cpu, comp_out = _run([sys.executable, "-c", COMPILE_ONLY, args.study], str(tmp / "cache2"))
        print(f"compile (fresh process, empty cache): {comp_s:.1f} s wall, {comp_cpu:.1f} s CPU; "
              f"{comp_out.strip()}", file=sys.stderr)
        _settle("validate")
        val_s, val_cpu, _ = _run(py + ["validate", args.study], str(tmp / "cache3"))
        print(f"validate (empty cache): {val_s:.1f} s wall, {val_cpu:.1f} s CPU", file=sys.stderr)
        same = _identical(tmp / "cold" / "results.csv", tmp / "warm" / "results.csv")
        print(f"load average: {load:.2f} before, {os.getloadavg()[0]:.2f} after ({os.cpu_count()} cores)",
              file=sys.stderr)
        fl = "none" if first[0] is None else f"{first[0]:.2f}"
        print(f"cold_s={cold_s:.2f} warm_s={warm_s:.2f} compile_s={comp_s:.2f} validate_s={val_s:.2f} "
              f"cold_cpu_s={cold_cpu:.2f} warm_cpu_s={warm_cpu:.2f} first_line_s={fl} identical={same}")
        return 0 if same else 1
    finally:
        if args.keep:
            print(f"kept {tmp}", file=sys.stderr)
        else:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    raise SystemExit(main())
