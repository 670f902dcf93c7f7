"""Compiling ahead from the start of a run (precompile.start_early): a helper starts at once with
the interpreter kernels, the other kernels go to the helper or are left to the work by their
cost (no more compiling processes than cores), compile_ahead waits for the helper instead of
compiling the same kernels again and compiles the work's share in its own process, and
afterwards every kernel is in the cache."""

import os
import subprocess
import sys

import numpy as np
import pytest

from parasynth import engine

pytestmark = pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba not available")

CODE = r"""
import time
from parasynth.engine import precompile as pre
from numba.core import event
compiled = []
class L(event.Listener):
    def on_start(self, e):
        compiled.append(getattr(e.data.get("dispatcher"), "py_func", None).__name__)
    def on_end(self, e):
        pass
event.register("numba:compile", L())
t0 = time.perf_counter()
shares = pre.start_early(["constraint_rank"], processes=2)
started = time.perf_counter() - t0
print("shares", shares)
print("running", sorted(n for n, r in pre.early().items() if r))
print("again", pre.start_early(["constraint_rank"]))  # nothing twice
print("left", pre.left())
out = pre.compile_ahead(pre.missing(["constraint_rank"]), processes=2)
print("waited", sorted(out["waited"]), "local", out["local"], "helpers", out["helpers"], "failed", out["failed"])
print("cached", pre.in_cache("_pose_kernel"), pre.in_cache("_constraint_rank_kernel"))
print("left_after", pre.left())
print("compiled_here", compiled)
print("started_s", started)
"""


def test_start_early_then_compile_ahead_waits(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-c", CODE], env=env, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    lines = dict(line.split(" ", 1) for line in r.stdout.strip().splitlines())
    # one helper (two cores: the work itself is the second compiling process), with the
    # interpreter kernel; the constraint-rank kernel (cost 4.5 against the pose kernel's 6.5,
    # the work's own 5 s of other work counted first) is left to the work
    assert lines["shares"] == "[['_pose_kernel']]"
    assert lines["running"] == "['_pose_kernel']"
    assert lines["again"] == "[]"
    assert lines["left"] == "['_constraint_rank_kernel']"  # the warm-up's compile_ahead takes it
    # compile_ahead compiled the rank kernel here (no free core for a new helper) and waited
    # for the pose kernel's helper
    assert lines["waited"].startswith("['_pose_kernel'] local ['_constraint_rank_kernel'] helpers [] failed []")
    assert lines["cached"] == "True True"
    assert lines["left_after"] == "[]"
    here = eval(lines["compiled_here"])  # the rank kernel and its callees, here
    assert here[0] == "_constraint_rank_kernel"
    assert "_pose_kernel" not in here and "_run" not in here  # the pose kernel by the helper only
    assert float(lines["started_s"]) < 10.0  # returns at once (imports of the engine included)


SHARES = r"""
from parasynth.engine import precompile as pre
started = []
class P:  # a helper that is not started: the shares are what is asked
    def __init__(self, args, **kw):
        started.append(args[3:])
    def poll(self):
        return None
pre.subprocess.Popen = P
pre.missing = lambda kinds: list(dict.fromkeys(n for k in kinds for n in pre.KERNELS_OF[k] if n not in pre.CREW))
print(pre.start_early(["feasible", "singularity_margin"], processes=2, busy=5.0))
pre._EARLY.clear(); pre._LEFT.clear()
print(pre.start_early(["feasible", "singularity_margin"], processes=2, busy=30.0))
pre._EARLY.clear(); pre._LEFT.clear()
print(pre.start_early(["feasible", "singularity_margin"], processes=1))
pre._EARLY.clear(); pre._LEFT.clear()
print(pre.start_early(["chains", "chain_closure"], processes=1))
"""


def test_start_early_shares_by_cost():
    """The helper takes the longest interpreter kernel and, by their cost, what the work (busy
    with its own ``busy`` seconds) would finish later; on one core it takes everything."""
    r = subprocess.run([sys.executable, "-c", SHARES], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    out = r.stdout.strip().splitlines()
    # the feasibility kernel with the interpreter (2.8 + 8.9) to the helper; the margin kernel
    # (5) and the pose kernel (2.3, the interpreter then cached) to the work busy for 5 s
    # (10, 12.3); the lengths (0.8) to the helper, now the less loaded (11.7 + 0.8)
    assert out[0] == "[['_feasible_kernel', '_upu_mean_lengths']]"
    # a work busy for 30 s: the helper takes them all
    assert out[1] == "[['_feasible_kernel', '_margin_kernel', '_pose_kernel', '_upu_mean_lengths']]"
    assert out[2] == "[['_pose_kernel', '_feasible_kernel', '_upu_mean_lengths', '_margin_kernel']]"  # one core
    assert out[3] == "[['_chain_kernel', '_chain_rows_kernel', '_closure_kernel']]"


def test_structure_kinds_and_chain_kinds():
    from parasynth.engine import precompile as pre
    from parasynth.structures import structures

    assert pre.structure_kinds(None) == pre.STRUCTURE_STUDY  # known only once enumerated
    assert pre.structure_kinds(["UPS", "RPS"]) == pre.STRUCTURE_STUDY
    # the chains' closure only once the structures say they need it (chain_kinds)
    assert pre.structure_kinds(["UPS", "RPUR"]) == pre.STRUCTURE_STUDY + ("chains",)
    found = structures("3T2R", leg_types=["UPU", "RPUR"])
    assert any("RPUR" in s.leg_counts for s in found)
    # a motion template poses the platform: the chains' solve, not their closure
    assert all((s.description.get("task") or {}).get("solve") is None for s in found)
    assert pre.chain_kinds(list(found)) == ("chains",)
    assert pre.chain_kinds([s for s in found if "RPUR" not in s.leg_counts]) == ()
    # the 3-RUU's translation is computed from its limbs' closure (task.solve): the closure too
    ruu = structures("3T0R", leg_types=["RUU"])
    assert ruu and all((s.description.get("task") or {}).get("solve") is not None for s in ruu)
    assert pre.chain_kinds(list(ruu)) == pre.STRUCTURE_CHAINS
    # and such a design's evaluation runs the closure kernel, a template's does not
    from parasynth.engine import chains

    calls = []
    orig = chains._closure_kernel
    chains._closure_kernel = lambda *a: (calls.append(1), orig(*a))[1]
    try:
        for s, closes in ((ruu[0], True), (next(s for s in found if "RPUR" in s.leg_counts), False)):
            design = s.mechanism()
            calls.clear()
            X = design.home + np.zeros((4, design.n_task))
            engine.pose_batch(design, X)
            engine.feasible(design, X)
            assert bool(calls) == closes, s.name
    finally:
        chains._closure_kernel = orig


def test_a_run_compiling_on_its_own_compiles_the_rank_kernel_with_the_margin(monkeypatch):
    """On an empty cache a run that asks for the singularity margin compiles the structural
    constraint rank's kernel too (precompile.WITH: the margin asks for the rank, which runs on
    NumPy until its kernel is compiled); a structure study, whose early helpers are running, does
    not (its compile has no room for it)."""
    from parasynth.engine import precompile as pre

    monkeypatch.setattr(engine, "needs", lambda work: {"feasible", "singularity_margin"})
    monkeypatch.setattr(pre, "in_cache", lambda name: False)
    monkeypatch.setattr(pre, "_EARLY", {})
    monkeypatch.setattr(pre, "_LEFT", set())
    alone = engine._ahead(lambda: None)
    assert "_constraint_rank_kernel" in alone
    assert {"_pose_kernel", "_feasible_kernel", "_margin_kernel"} <= set(alone)

    class Running:
        def poll(self):
            return None

    monkeypatch.setattr(pre, "_EARLY", {"_feasible_kernel": Running()})
    early = engine._ahead(lambda: None)
    assert "_constraint_rank_kernel" not in early
    assert "_margin_kernel" in early


def test_the_warm_up_waits_for_what_early_helpers_compile_though_the_work_does_not_ask(monkeypatch):
    """A study's early helper compiles the constraint rank's kernel (precompile.STUDY), which a
    design asks for only once it is compiled. With every other kernel cached the warm-up's work
    does not ask for it, and the warm-up used to stop that helper half done: every later run
    started it again and evaluated its designs' rank on NumPy. The warm-up now waits for it; a
    helper that has finished (its kernel cached) is not waited for."""
    from parasynth.engine import precompile as pre

    class Helper:
        def __init__(self, running):
            self.running = running

        def poll(self):
            return None if self.running else 0

    monkeypatch.setattr(engine, "needs", lambda work: {"feasible", "singularity_margin"})
    monkeypatch.setattr(pre, "in_cache", lambda name: name != "_constraint_rank_kernel")
    monkeypatch.setattr(pre, "_LEFT", set())
    monkeypatch.setattr(pre, "_EARLY", {"_constraint_rank_kernel": Helper(True)})
    assert engine._ahead(lambda: None) == ["_constraint_rank_kernel"]
    monkeypatch.setattr(pre, "_EARLY", {"_constraint_rank_kernel": Helper(False)})
    monkeypatch.setattr(pre, "in_cache", lambda name: True)
    assert engine._ahead(lambda: None) == []


def test_a_run_starts_the_helpers_before_loading_its_study(monkeypatch, tmp_path, capsys):
    """``parasynth run`` on an empty compile cache starts the helpers before the study is loaded
    and checked: a study over structures with the kernels of its limb types (its enumeration
    first), any other study with those nearly every study asks for (its loading and check
    first), and says so once; the NumPy engine, PARASYNTH_COMPILE_AHEAD=0 or a file that does
    not read start nothing (the run then reports what is wrong, or compiles as before)."""
    from pathlib import Path

    import yaml

    from parasynth import cli
    from parasynth.engine import precompile as pre

    root = Path(__file__).resolve().parents[2]
    calls = []
    monkeypatch.setattr(pre, "start_early", lambda kinds, processes=None, busy=5.0:
                        calls.append((tuple(kinds), busy)) or [["_feasible_kernel"]])
    cli._compile_early(root / "studies" / "quickstart.yaml", quiet=False)
    assert calls == [(pre.STUDY, 1.5)]
    assert set(pre.STUDY) == {"feasible", "singularity_margin", "constraint_rank"}
    assert capsys.readouterr().err == engine.COMPILING + "\n"
    cli._compile_early(root / "studies" / "structures_3t2r.yaml", quiet=True)
    doc = yaml.safe_load((root / "studies" / "structures_3t2r.yaml").read_text())
    assert calls[-1] == (pre.structure_kinds(doc["structure"]["leg_types"]), 5.0)
    assert "chains" in calls[-1][0] and capsys.readouterr().err == ""
    numpy_study = yaml.safe_load((root / "studies" / "quickstart.yaml").read_text())
    numpy_study["evaluation"]["engine"] = "numpy"
    path = tmp_path / "numpy.yaml"
    path.write_text(yaml.safe_dump(numpy_study))
    cli._compile_early(path, quiet=False)
    (tmp_path / "bad.yaml").write_text("evaluation: [unclosed")
    cli._compile_early(tmp_path / "bad.yaml", quiet=False)
    cli._compile_early(tmp_path / "missing.yaml", quiet=False)
    monkeypatch.setenv("PARASYNTH_COMPILE_AHEAD", "0")
    cli._compile_early(root / "studies" / "quickstart.yaml", quiet=False)
    assert len(calls) == 2 and capsys.readouterr().err == ""


def test_helpers_started_ahead_are_forgotten_once_stopped(monkeypatch, tmp_path):
    """After the work (its warm-up, or a run that failed before it), the helpers started ahead
    are forgotten: the next work of the process -- another run in a script or a test -- says
    the notice itself and leaves nothing to anyone; and ``parasynth run`` stops them however
    it ends."""
    from parasynth import cli
    from parasynth.engine import precompile as pre

    class Finished:
        returncode = 0

        def poll(self):
            return 0

    monkeypatch.setattr(engine, "_ANNOUNCED", False)
    monkeypatch.setattr(pre, "in_cache", lambda name: name != "_pose_kernel")
    monkeypatch.setitem(pre._EARLY, "_feasible_kernel", Finished())
    pre._LEFT.add("_margin_kernel")
    pre._SINCE.append(1.0)
    assert engine.announce_compile() is False  # said when the helpers were started
    pre.stop_helpers()
    assert pre.early() == {} and pre.left() == [] and pre.started_at() is None
    assert engine.announce_compile() is True  # the next work's own notice
    monkeypatch.setattr(engine, "_ANNOUNCED", False)
    stopped = []
    monkeypatch.setattr(pre, "start_early", lambda kinds, processes=None, busy=5.0: [["_feasible_kernel"]])
    monkeypatch.setattr(pre, "stop_helpers", lambda: stopped.append(True))
    (tmp_path / "bad.yaml").write_text("name: bad\nmechanism: no_such_mechanism\n")
    assert cli.main(["run", str(tmp_path / "bad.yaml"), "--out", str(tmp_path / "out")]) == 2
    assert stopped == [True]
