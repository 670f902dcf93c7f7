"""Compiling ahead from the start of a run (precompile.start_early): a helper starts at once with
every kernel in a queue, the longest interpreter kernel first, and claims each before it
compiles it; compile_ahead claims those the helper has not begun and compiles them in its own
process (no more compiling processes than cores), waits for the others instead of compiling
them again, and afterwards every kernel is in the cache."""

import os
import subprocess
import sys

import numpy as np
import pytest

from parasynth import engine

pytestmark = pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba not available")

CODE = r"""
import os, time
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
folder = pre._QUEUES[pre._EARLY["_pose_kernel"]][0]
out = pre.compile_ahead(pre.missing(["constraint_rank"]), processes=2)
print("waited", sorted(out["waited"]), "local", out["local"], "helpers", out["helpers"], "failed", out["failed"],
      "claimed", out["claimed"])
print("cached", pre.in_cache("_pose_kernel"), pre.in_cache("_constraint_rank_kernel"))
print("claims", sorted(os.listdir(folder)))
pre.stop_helpers()
print("claims_after", os.path.exists(folder))
print("compiled_here", compiled)
print("started_s", started)
"""


def test_start_early_then_compile_ahead_waits(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-c", CODE], env=env, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    lines = dict(line.split(" ", 1) for line in r.stdout.strip().splitlines())
    # one helper (two cores: the work itself is the second compiling process) with both
    # kernels queued, the interpreter kernel first
    assert lines["shares"] == "[['_pose_kernel', '_constraint_rank_kernel']]"
    assert lines["running"] == "['_constraint_rank_kernel', '_pose_kernel']"
    assert lines["again"] == "[]"
    # compile_ahead, at once, claimed the rank kernel the helper had not begun, compiled it
    # here, and waited for the pose kernel's helper
    assert lines["waited"] == ("['_pose_kernel'] local [] helpers [] failed [] claimed "
                               "['_constraint_rank_kernel']")
    assert lines["cached"] == "True True"
    assert lines["claims"] == "['_constraint_rank_kernel', '_pose_kernel']"  # each claimed once
    assert lines["claims_after"] == "False"  # the claim folder goes with the helpers
    here = eval(lines["compiled_here"])  # the rank kernel and its callees, here
    assert here[0] == "_constraint_rank_kernel"
    assert "_pose_kernel" not in here and "_run" not in here  # the pose kernel by the helper only
    assert float(lines["started_s"]) < 10.0  # returns at once (imports of the engine included)


SHARES = r"""
import os
from parasynth.engine import precompile as pre
started = []
class P:  # a helper that is not started: the shares are what is asked
    def __init__(self, args, **kw):
        started.append(args[3:])
    def poll(self):
        return None
    def terminate(self):
        pass
    def wait(self, timeout=None):
        return 0
pre.subprocess.Popen = P
pre.missing = lambda kinds: list(dict.fromkeys(n for k in kinds for n in pre.KERNELS_OF[k] if n not in pre.CREW))
print(pre.start_early(["feasible", "singularity_margin"], processes=2))
folder = pre._QUEUES[pre._EARLY["_margin_kernel"]][0]
print(started[-1][:3] == ["_feasible_kernel", "--claims", folder], os.listdir(folder))
pre._EARLY.clear()
print(pre.start_early(["feasible", "singularity_margin", "constraint_rank"], processes=2))
pre._EARLY.clear()
print(pre.start_early(["feasible", "singularity_margin"], processes=1))
pre._EARLY.clear()
print(pre.start_early(["chains", "chain_closure"], processes=1))
print(len(started))
"""


def test_start_early_queues_longest_first():
    """One helper with every kernel in one queue, its claim folder given: the longest
    interpreter kernel first (it compiles the interpreter; claimed for the helper before it
    starts, so that a work quicker than the helper's start cannot take it), then longest first;
    on one core the kernels in the order asked."""
    r = subprocess.run([sys.executable, "-c", SHARES], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    out = r.stdout.strip().splitlines()
    # the feasibility kernel with the interpreter (2.8 + 8.9), then the margin kernel (5), the
    # pose kernel (2.3, the interpreter then cached) and the lengths (0.4)
    assert out[0] == "[['_feasible_kernel', '_margin_kernel', '_pose_kernel', '_upu_mean_lengths']]"
    assert out[1] == "True ['_feasible_kernel']"  # the first claimed for the helper, the others by it
    assert out[2] == ("[['_feasible_kernel', '_margin_kernel', '_constraint_rank_kernel', '_pose_kernel', "
                      "'_upu_mean_lengths']]")
    assert out[3] == "[['_pose_kernel', '_feasible_kernel', '_upu_mean_lengths', '_margin_kernel']]"  # one core
    assert out[4] == "[['_chain_kernel', '_chain_rows_kernel', '_closure_kernel']]"
    assert out[5] == "4"  # one helper each


def test_a_claimed_kernel_is_compiled_by_one_process(tmp_path, monkeypatch):
    """claim: the first to ask gets it, nobody else; a helper compiles the kernels named before
    --claims and of those after it only what it claims (the rest was claimed by the work), in
    its queue's order; a bad command line is refused."""
    from parasynth.engine import precompile as pre

    folder = str(tmp_path)
    assert pre.claim(folder, "_crew_spin") is True
    assert pre.claim(folder, "_crew_spin") is False
    assert pre.claim(str(tmp_path / "gone"), "_crew_spin") is True  # no folder: nobody else claims
    done = []
    monkeypatch.setattr(pre, "_compile", done.append)
    assert pre.main(["--claims", folder, "_spin_done", "_crew_spin", "_tickets_done"]) == 0
    assert done == ["_spin_done", "_tickets_done"]
    assert sorted(os.listdir(folder)) == ["_crew_spin", "_spin_done", "_tickets_done"]
    assert pre.main(["--claims", folder, "_spin_done"]) == 0 and done == ["_spin_done", "_tickets_done"]
    assert pre.main(["_spin_done"]) == 0 and done[-1] == "_spin_done"  # no --claims: compiled
    # the names before --claims are compiled as given, claimed or not
    assert pre.main(["_crew_spin", "--claims", folder, "_spin_done", "_cancel_tickets"]) == 0
    assert done[-2:] == ["_crew_spin", "_cancel_tickets"]
    assert pre.main(["--claims"]) == 2
    assert pre.main(["--claims", folder, "no_such_kernel"]) == 2
    assert pre.main(["no_such_kernel", "--claims", folder]) == 2


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
    calls, guessed = [], []
    monkeypatch.setattr(pre, "start_early", lambda kinds, processes=None, helper=None:
                        calls.append((tuple(kinds), helper)) or [["_feasible_kernel"]])
    monkeypatch.setattr(cli.early, "start", lambda what, legs: guessed.append((what, legs)) or ("helper", what))
    cli._compile_early(root / "studies" / "quickstart.yaml", quiet=False)
    # the helper started before the engine's import is handed to start_early with the same kinds
    assert calls == [(pre.STUDY, ("helper", "study"))] and guessed == [("study", None)]
    calls[:] = [k for k, _ in calls]
    assert set(pre.STUDY) == {"feasible", "singularity_margin", "constraint_rank"}
    assert capsys.readouterr().err == engine.COMPILING + "\n"
    cli._compile_early(root / "studies" / "structures_3t2r.yaml", quiet=True)
    doc = yaml.safe_load((root / "studies" / "structures_3t2r.yaml").read_text())
    assert guessed[-1] == ("structure", [str(t) for t in doc["structure"]["leg_types"]])
    assert calls[-1][1] == ("helper", "structure")
    calls[-1] = calls[-1][0]
    assert calls[-1] == pre.structure_kinds(doc["structure"]["leg_types"])
    assert pre.early_kinds("structure", guessed[-1][1]) == calls[-1]
    assert "chains" in calls[-1] and capsys.readouterr().err == ""
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
    assert len(calls) == 2 and len(guessed) == 2 and capsys.readouterr().err == ""


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
    folder = tmp_path / "claims"
    folder.mkdir()
    monkeypatch.setitem(pre._QUEUES, pre._EARLY["_feasible_kernel"], (str(folder), ("_feasible_kernel",)))
    pre._SINCE.append(1.0)
    assert engine.announce_compile() is False  # said when the helpers were started
    pre.stop_helpers()
    assert pre.early() == {} and pre._QUEUES == {} and pre.started_at() is None
    assert not folder.exists()
    assert engine.announce_compile() is True  # the next work's own notice
    monkeypatch.setattr(engine, "_ANNOUNCED", False)
    stopped = []
    monkeypatch.setattr(pre, "start_early", lambda kinds, processes=None, helper=None: [["_feasible_kernel"]])
    monkeypatch.setattr(cli.early, "start", lambda what, legs: None)
    monkeypatch.setattr(pre, "stop_helpers", lambda: stopped.append(True))
    (tmp_path / "bad.yaml").write_text("name: bad\nmechanism: no_such_mechanism\n")
    assert cli.main(["run", str(tmp_path / "bad.yaml"), "--out", str(tmp_path / "out")]) == 2
    assert stopped == [True]
