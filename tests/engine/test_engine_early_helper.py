"""The first run's helper started before the run imports the engine (parasynth.cli.early): when
numba's cache has no index of the feasibility kernel, ``parasynth run`` starts ``python -m
parasynth.engine.precompile --early ...``, which computes the queue start_early would and claims
each kernel before compiling it; start_early takes that helper as its queue's."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import pytest

from parasynth import engine
from parasynth.cli import early

pytestmark = pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba not available")


def test_the_guess_looks_where_numba_keeps_the_feasibility_kernel(tmp_path, monkeypatch):
    from numba.core.caching import UserProvidedCacheLocator

    from parasynth.engine import core

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("PARASYNTH_NO_NUMBA", raising=False)
    (d,) = early._numba_dirs(core.__file__)
    # numba's own locator for the kernels' file (the independent value)
    assert d == tmp_path / UserProvidedCacheLocator.get_suitable_cache_subpath(core.__file__)
    assert not early.probably_cached()
    d.mkdir(parents=True)
    tag = f"py{sys.version_info[0]}{sys.version_info[1]}"
    (d / f"core._feasible_batch-12.{tag}.nbi").write_text("")  # another kernel's index
    assert not early.probably_cached()
    (d / f"core._feasible_kernel-2266.{tag}.nbi").write_text("")
    assert early.probably_cached()
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    dirs = early._numba_dirs(core.__file__)
    assert dirs[0] == Path(core.__file__).parent / "__pycache__"  # in-tree first, as numba


def test_the_early_helper_is_started_only_for_an_empty_cache(tmp_path, monkeypatch):
    started = []

    class P:
        def __init__(self, cmd, **kw):
            started.append(cmd)

    monkeypatch.setattr(early.subprocess, "Popen", P)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    import parasynth.engine.core  # noqa: F401

    assert early.start("study") is None  # the engine's kernels imported here: start_early tells exactly
    assert started == []
    monkeypatch.delitem(sys.modules, "parasynth.engine.core")  # as in a run before its engine's import
    monkeypatch.delenv("PARASYNTH_NO_NUMBA", raising=False)
    monkeypatch.delenv("PARASYNTH_COMPILE_AHEAD", raising=False)
    t0 = time.perf_counter()
    p, folder, at = early.start("structure", ["RPS", "PRS"])
    assert started[0][1:] == ["-m", "parasynth.engine.precompile", "--early", "structure", "RPS", "PRS",
                              "--claims", folder]
    assert os.path.isdir(folder) and os.listdir(folder) == [] and at >= t0
    os.rmdir(folder)
    monkeypatch.setenv("PARASYNTH_COMPILE_AHEAD", "0")
    assert early.start("study") is None
    monkeypatch.delenv("PARASYNTH_COMPILE_AHEAD")
    monkeypatch.setenv("PARASYNTH_NO_NUMBA", "1")
    assert early.start("study") is None
    monkeypatch.delenv("PARASYNTH_NO_NUMBA")
    monkeypatch.setattr(early, "probably_cached", lambda: True)
    assert early.start("study") is None
    assert len(started) == 1


def test_the_early_helper_claims_each_kernel_of_its_queue(tmp_path, monkeypatch):
    from parasynth.engine import precompile as pre

    asked, compiled = [], []
    monkeypatch.setattr(pre, "early_queue", lambda kinds, processes=None: asked.append(kinds) or ["a", "b", "c"])
    monkeypatch.setattr(pre, "_compile", compiled.append)
    pre.claim(str(tmp_path), "b")  # the run took it
    assert pre.main(["--early", "structure", "RPS", "--claims", str(tmp_path)]) == 0
    assert asked == [pre.structure_kinds(["RPS"])] and compiled == ["a", "c"]
    assert sorted(os.listdir(tmp_path)) == ["a", "b", "c"]
    assert pre.main(["--early", "study", "--claims", str(tmp_path)]) == 0
    assert asked[-1] == pre.STUDY and compiled == ["a", "c"]  # all claimed already
    for bad in (["--early"], ["--early", "study"], ["--early", "study", "--claims"],
                ["--early", "everything", "--claims", str(tmp_path)]):
        assert pre.main(bad) == 2


class _Helper:
    def __init__(self, status=None):
        self.status, self.killed = status, False

    def poll(self):
        return self.status

    def terminate(self):
        self.killed = True
        self.status = -15

    def wait(self, timeout=None):
        return self.status


@pytest.fixture
def pre(monkeypatch):
    from parasynth.engine import precompile as pre

    pre.stop_helpers()
    monkeypatch.setattr(pre, "missing", lambda kinds: ["_margin_kernel", "_feasible_kernel", "_pose_kernel"])
    started = []
    monkeypatch.setattr(pre.subprocess, "Popen", lambda cmd, **kw: started.append(cmd) or _Helper())
    pre.started = started
    yield pre
    pre.stop_helpers()
    del pre.started


def test_start_early_takes_the_early_helper_as_its_queues(tmp_path, pre):
    h = _Helper()
    expected = pre.early_queue(pre.STUDY, processes=2)  # what the helper computes for itself
    queue = pre.start_early(pre.STUDY, processes=2, helper=(h, str(tmp_path), 12.5))
    assert queue == [expected] == [["_feasible_kernel", "_margin_kernel", "_pose_kernel"]]
    assert pre.started == []  # no second helper
    assert pre._QUEUES[h] == (str(tmp_path), tuple(queue[0])) and all(pre._EARLY[n] is h for n in queue[0])
    assert os.listdir(tmp_path) == []  # nothing claimed for it: it claims its first kernel itself
    assert pre.started_at() == 12.5  # the compile timed from the helper's start
    pre.stop_helpers()
    assert h.killed and not tmp_path.exists()


def test_a_failed_early_helper_is_replaced_and_its_folder_removed(tmp_path, pre):
    folder = tmp_path / "early"
    folder.mkdir()
    h = _Helper(status=1)
    queue = pre.start_early(pre.STUDY, processes=2, helper=(h, str(folder), 1.0))
    assert len(pre.started) == 1 and pre.started[0][3] == queue[0][0] == "_feasible_kernel"
    assert pre.started_at() != 1.0
    pre.stop_helpers()
    assert not folder.exists()


def test_an_early_helper_with_nothing_to_do_is_stopped_with_its_folder(tmp_path, pre, monkeypatch):
    monkeypatch.setattr(pre, "missing", lambda kinds: [])
    h = _Helper()
    assert pre.start_early(pre.STUDY, helper=(h, str(tmp_path), 1.0)) == []
    assert pre.started == [] and pre.started_at() is None
    pre.stop_helpers()
    assert h.killed and not tmp_path.exists()
