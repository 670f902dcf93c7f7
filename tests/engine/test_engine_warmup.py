"""Compiling up front: the warm-up says so only when numba compiles, stays interruptible, and
``engine.reference()`` answers with the NumPy path without compiling; Ctrl-C during the
compile of a real run (empty cache) ends with the interrupt line, the resume hint and 130."""

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import yaml

from parasynth import engine
from parasynth.mechanisms import load_mechanism

pytestmark = pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba not available")


def _fresh_kernel():
    from numba import njit

    def f(x):  # a new function each time: never in the cache (cache=False)
        s = 0.0
        for i in range(x.shape[0]):
            s += x[i] * x[i]
        return s

    return njit(f)


def test_warm_up_reports_only_when_compiling():
    k = _fresh_kernel()
    x = np.arange(5.0)
    msgs = []
    w = engine.warm_up(lambda: k(x), progress=msgs.append)
    assert w.done and w.compiled and w.result == 30.0 and w.error is None
    assert msgs and msgs[0] == engine.COMPILING and "compiled in" in msgs[-1]
    assert "f" in w.kernels
    msgs.clear()
    w = engine.warm_up(lambda: k(x), progress=msgs.append)  # compiled now: silent
    assert w.done and not w.compiled and w.result == 30.0 and msgs == []


def test_the_compile_notice_said_ahead_is_not_said_again(monkeypatch):
    """A command says the notice once its input is checked (engine.announce_compile, on an
    empty cache); the next warm-up then goes on from it, and only that one."""
    from parasynth.engine import precompile

    monkeypatch.setattr(engine, "_ANNOUNCED", False)
    assert engine.announce_compile() is False  # the pose kernel is in this run's cache
    monkeypatch.setattr(precompile, "in_cache", lambda name: name != "_pose_kernel")
    monkeypatch.setenv("PARASYNTH_COMPILE_AHEAD", "0")
    assert engine.announce_compile() is False  # compiling ahead turned off: nothing said ahead
    monkeypatch.delenv("PARASYNTH_COMPILE_AHEAD")
    assert engine.announce_compile() is True
    k = _fresh_kernel()
    x = np.arange(3.0)
    msgs = []
    w = engine.warm_up(lambda: k(x), progress=msgs.append)
    assert w.done and w.compiled and w.result == 5.0
    assert engine.COMPILING not in msgs and msgs and "compiled in" in msgs[-1]
    msgs.clear()
    k2 = _fresh_kernel()
    engine.warm_up(lambda: k2(x), progress=msgs.append)  # the next one says it itself
    assert msgs[0] == engine.COMPILING


def test_a_compile_started_ahead_counts_its_time_from_its_start():
    """Helpers started ahead (precompile.start_early) compile while the work does other things
    first: the wait for them reports the time since they started, not since the wait began."""
    from parasynth.engine import warmup

    since = time.perf_counter() - 7.0  # started 7 s ago
    msgs = []
    w = warmup.warm_up(lambda: time.sleep(0.4), progress=msgs.append, busy=lambda: True, announced=True,
                       since=since, poll=0.02, every=0.1)
    assert w.done and w.compiled and w.compile_seconds >= 7.0
    ticks = [m for m in msgs if m.startswith("  ... ")]
    assert ticks and all(float(m.split()[1]) >= 7 for m in ticks), msgs
    assert engine.COMPILING not in msgs and msgs[-1].startswith("  compiled in 7.")
    msgs.clear()
    w = warmup.warm_up(lambda: time.sleep(0.2), progress=msgs.append, busy=lambda: True, announced=True,
                       poll=0.02, every=0.1)  # no start given: from the wait's first poll
    assert w.compile_seconds < 5 and msgs[-1].startswith("  compiled in 0.")


def test_warm_up_returns_errors_and_stops_on_request():
    w = engine.warm_up(lambda: 1 / 0, progress=None)
    assert w.done and isinstance(w.error, ZeroDivisionError)
    gate = threading.Event()
    t0 = time.perf_counter()
    w = engine.warm_up(lambda: gate.wait(30), progress=None, stop=lambda: time.perf_counter() - t0 > 0.3)
    assert not w.done and time.perf_counter() - t0 < 5
    gate.set()


ABANDONED = r"""
import atexit, sys, threading, time
from parasynth import cli
from parasynth.engine import warmup
gate = threading.Event()
print("before", warmup.abandoned(), flush=True)
w = warmup.warm_up(lambda: gate.wait(60), progress=None, stop=lambda: True)  # the wait ended at once
print("after", w.done, warmup.abandoned(), flush=True)
if sys.argv[1] == "ends":
    gate.set()
    time.sleep(0.5)
    print("ended", warmup.abandoned(), flush=True)
atexit.register(lambda: print("exit handlers ran", flush=True))
cli.main = lambda argv=None: (print("main", flush=True), 7)[1]
cli.entry()
"""


@pytest.mark.parametrize("case", ["running", "ends"])
def test_a_process_with_an_abandoned_compile_ends_at_once_with_its_status(case):
    """warmup.abandoned: true while a compiling thread whose wait was ended still runs. The
    parasynth program then ends its process at once with its status, its output flushed
    (os._exit: the interpreter's shutdown would tear LLVM down under numba's compile, an
    LLVM assertion or a segmentation fault in place of the status); once the thread has ended,
    it exits as usual (exit handlers run)."""
    r = subprocess.run([sys.executable, "-c", ABANDONED, case], capture_output=True, text=True, timeout=120)
    lines = r.stdout.split()
    assert r.returncode == 7, r.stderr
    assert r.stdout.startswith("before False\nafter False True\n"), r.stdout
    if case == "running":
        assert "main" in lines and "handlers" not in lines
    else:
        assert "ended False" in r.stdout and "main" in lines and "handlers" in lines


def test_reference_uses_numpy_and_compiles_nothing():
    from numba.core import event

    mech = load_mechanism("5pus_upu")
    rng = np.random.default_rng(3)
    X = mech.home + rng.uniform(-1, 1, size=(500, mech.n_task)) * np.array([0.1, 0.1, 0.1, 0.3, 0.3])
    seen = []

    class L(event.Listener):
        def on_start(self, e):
            seen.append(e.data["dispatcher"].py_func.__name__)

        def on_end(self, e):
            pass

    lis = L()
    event.register("numba:compile", lis)
    try:
        with engine.reference():
            assert engine.check_engine("compiled") == "numpy"
            got = engine.feasible(mech, X)
            marg = mech.singularity_margin(X)
    finally:
        event.unregister("numba:compile", lis)
    assert engine.check_engine("compiled") == "compiled"
    assert seen == []
    np.testing.assert_array_equal(got, mech.is_feasible(X, engine="numpy"))
    np.testing.assert_array_equal(marg, mech.singularity_margin(X, engine="numpy"))


def test_validate_checks_never_use_the_compiled_kernels(monkeypatch):
    """``check_study`` (what ``parasynth validate`` and the start of a run do) evaluates with
    the NumPy reference only -- the degenerate-geometry probe included -- so that it never
    waits for a cold compile: any call into the compiled modules fails here."""
    from pathlib import Path

    from parasynth.study.spec import check_study, load_study

    def no_compiled():
        raise AssertionError("check_study called the compiled engine")

    monkeypatch.setattr(engine, "_compiled", no_compiled)
    study = load_study(Path(__file__).resolve().parents[2] / "studies" / "quickstart.yaml")
    stats = {}
    assert check_study(study, stats=stats) == []
    assert stats["measures"] == 3

def test_reference_results_are_not_cached_for_compiled_evaluations():
    """A workspace evaluated inside ``engine.reference()`` (a probe, ``validate``) is not the
    cached answer of a compiled evaluation with the same settings."""
    from parasynth.measures.objectives import workspace_of

    mech = load_mechanism("5pus_upu")
    with engine.reference():
        a = workspace_of(mech, n=300, seed=5)
    b = workspace_of(mech, n=300, seed=5)
    assert a is not b
    assert workspace_of(mech, n=300, seed=5) is b
    c = []
    engine.needs(lambda: c.append(workspace_of(mech, n=300, seed=5)))
    assert c and c[0] is not b


def test_needs_records_the_compiled_entry_points_without_compiling():
    mech = load_mechanism("5pus_upu")
    X = np.repeat(mech.home[None, :], 3, axis=0)
    assert engine.needs(lambda: engine.feasible(mech, X)) == {"feasible"}
    got = engine.needs(lambda: (mech.singularity_margin(X), engine.pose_batch(mech, X, twist=True)))
    # the margin scales by the constraint rank, which runs on NumPy until its kernel is compiled
    assert got == {"singularity_margin", "twist"}
    assert engine.needs(lambda: engine.feasible(mech, X, engine="numpy")) == set()
    assert engine.needs(lambda: 1 / 0) == set()  # errors are swallowed

    def in_reference():
        with engine.reference():
            engine.feasible(mech, X)

    assert engine.needs(in_reference) == set()


def test_kernel_signatures_are_the_ones_compiled():
    """Each kernel is called with exactly the one signature the compile helpers compile."""
    from parasynth.engine import core, precompile

    import warnings

    import parasynth
    from parasynth.model.chains import RPUR

    mech = load_mechanism("5pus_upu")
    engine.exercise(mech)
    # the chain limbs' kernels: a mechanism of chain limbs, and a chain limb's closure
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        chain_mech = parasynth.structures("3T3R", leg_types=["SPU"], legs=[6])[0].mechanism()
    engine.exercise(chain_mech, ("feasible", "singularity_margin", "constraint_rank"))
    leg = RPUR("L", base=[0.3, 0.0, 0.0], platform=[0.15, 0.0, 0.0])
    engine.closure_residuals([leg], np.array([[0.0, 0.0, 0.4]]), np.eye(3)[None], 0.4)
    sigs = precompile.signatures()
    # every kernel compiled ahead for an entry point, and the compiled crew's (compiled in the
    # background, core.spin_warm; exercise loads them at once)
    assert set(sigs) == {n for names in precompile.KERNELS_OF.values() for n in names} | set(core.SERVE_KERNELS)
    for name, (disp, sig) in sigs.items():
        assert [tuple(s) for s in disp.signatures] == [tuple(sig)], name
        assert precompile.in_cache(name)


def test_precompile_helper_fills_the_cache(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    run = [sys.executable, "-m", "parasynth.engine.precompile"]
    p = subprocess.run(run + ["_upu_mean_lengths"], env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    check = ("from parasynth.engine import precompile as p; "
             "print(p.in_cache('_upu_mean_lengths'), p.in_cache('_dir_kernel'), p.missing(['singularity_margin']))")
    p = subprocess.run([sys.executable, "-c", check], env=env, capture_output=True, text=True, timeout=300)
    assert p.stdout.split("\n")[0] == "True False ['_pose_kernel', '_margin_kernel']", p.stderr
    p = subprocess.run(run + ["_no_such_kernel"], env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and "unknown kernel(s) _no_such_kernel" in p.stderr

def _helpers_of(cache: str) -> list[str]:
    """The command lines of the compiling helpers (parasynth.engine.precompile) running with
    the numba cache ``cache`` (read from /proc; [] where there is none)."""
    out = []
    for pid in (p for p in os.listdir("/proc") if p.isdigit()) if os.path.isdir("/proc") else ():
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                cmd = f.read().replace(b"\0", b" ").decode(errors="replace")
            with open(f"/proc/{pid}/environ", "rb") as f:
                envs = f.read().split(b"\0")
        except OSError:
            continue
        if "parasynth.engine.precompile" in cmd and f"NUMBA_CACHE_DIR={cache}".encode() in envs:
            out.append(cmd)
    return out


def test_sigint_during_compile_ends_with_resume_hint(tmp_path):
    """A run on an empty compile cache, Ctrl-C as soon as it says it is compiling: the run
    stops at once (not after the compile), with the interrupt line, the resume hint and exit
    status 130 -- no traceback, no "Exception ignored"."""
    study = {"name": "cold_sigint", "mechanism": "5pus_upu",
             "variables": [{"name": "link_length", "values": ["190 mm", "210 mm"]}],
             "objectives": [{"name": "workspace_volume", "goal": "maximize"}],
             "evaluation": {"samples": 256, "ranges": {"x": ["-200 mm", "200 mm"], "y": ["-200 mm", "200 mm"],
                                                       "z": ["-450 mm", "300 mm"]}},
             "optimizer": {"kind": "sweep"}}
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(study))
    out = tmp_path / "run"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache"), "PYTHONUNBUFFERED": "1"}
    env.pop("PARASYNTH_DEBUG", None)
    proc = subprocess.Popen([sys.executable, "-m", "parasynth.cli", "run", str(path), "--out", str(out),
                             "--no-report"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    err_lines = []

    def read():
        for line in proc.stderr:
            err_lines.append(line)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    deadline = time.time() + 120
    while time.time() < deadline and not any(engine.COMPILING in x for x in err_lines):
        if proc.poll() is not None:
            break
        time.sleep(0.05)
    assert any(engine.COMPILING in x for x in err_lines), "".join(err_lines)
    # said from the start (helpers compile while the study is loaded and checked): Ctrl-C once
    # the run itself has begun (its lock file), while its warm-up waits for the compile
    while time.time() < deadline and not (out / "run.lock").exists() and proc.poll() is None:
        time.sleep(0.05)
    assert (out / "run.lock").exists(), "".join(err_lines)
    time.sleep(0.5)
    # the helper started before the run imported the engine (parasynth.cli.early) compiles
    if os.path.isdir("/proc"):  # (how the helpers are told apart)
        assert any("--early" in cmd for cmd in _helpers_of(env["NUMBA_CACHE_DIR"])), _helpers_of(env["NUMBA_CACHE_DIR"])
    t0 = time.time()
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=60)  # stderr is read by the reader thread alone, to its end
    waited = time.time() - t0
    reader.join(10)
    proc.stdout.read()
    stderr = "".join(err_lines)
    assert proc.returncode == 130, stderr
    assert waited < 10, f"the run went on compiling for {waited:.1f} s after Ctrl-C"
    assert "Traceback" not in stderr and "Exception ignored" not in stderr
    assert _helpers_of(env["NUMBA_CACHE_DIR"]) == []  # stopped with the run
    assert stderr.count(engine.COMPILING) == 1, stderr  # said once, when the helpers started
    last = [x for x in stderr.splitlines() if x.strip()][-1]
    assert last.startswith("interrupted:") and "--resume" in last and str(out) in last, stderr
    assert not (out / "journal.jsonl").exists() or not (out / "journal.jsonl").read_text().strip()
