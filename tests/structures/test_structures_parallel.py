"""The candidates' checks and motion rules spread over forked processes
(``structures(..., processes=)``): the same structures, drops and reasons as in one process,
the processes actually used, bad ``processes`` refused, and a structure study's enumeration
kept to its own process while compiling helpers hold the cores."""

from __future__ import annotations


import pytest

from parasynth.common.validation import numpy_reference
from parasynth.structures import StructureError, structures
from parasynth.structures import synthesis

pytestmark = pytest.mark.skipif(not synthesis._CAN_FORK, reason="the checks are forked on Linux only")


def _answer(found):
    """Everything an enumeration answers, as plain values compared exactly (floats too)."""
    return ([(s.label, s.name, s.description, s.home_margin, s.checked_margin, s.checked_poses,
              s.controlled_poses, s.equivalents, s.template, s.axes) for s in found],
            found.enumerated, dict(found.dropped), {k: list(v) for k, v in found.dropped_names.items()},
            dict(found.no_task_rule))


@pytest.fixture(autouse=True)
def _computed(monkeypatch):
    """Every enumeration here computed, none read back from the disk cache (parasynth.common.cache)."""
    monkeypatch.setenv("PARASYNTH_CACHE_DIR", "off")


@pytest.fixture
def forks(monkeypatch):
    """The process pools the enumeration opens (their sizes)."""
    opened = []
    real = synthesis.mp.get_context

    class _Ctx:
        def __init__(self, ctx):
            self._ctx = ctx

        def Pool(self, n, *a, **k):  # noqa: N802 - multiprocessing's name
            opened.append(n)
            return self._ctx.Pool(n, *a, **k)

    monkeypatch.setattr(synthesis.mp, "get_context", lambda method=None: _Ctx(real(method)))
    return opened


def test_spread_over_processes_the_same_structures(forks):
    """1T2R with every axis choice: 63 candidates need a motion rule and 24 the checks, both
    above PARALLEL_CHECKS; on two processes the answer is the one process's, to the bit."""
    with numpy_reference():
        one = structures("1T2R", all_axes=True, processes=1)
        assert forks == []
        two = structures("1T2R", all_axes=True, processes=2)
    assert forks == [2, 2]  # the motion rules, then the checks
    assert _answer(two) == _answer(one)
    assert [s.label for s in one][:2] == ["3-RPS", "3-PRS"]
    # the classes of structures checked in another process are built again here and work
    for s in two:
        mech = s.mechanism()
        assert mech.n_task == 3


def test_few_candidates_stay_in_this_process(forks):
    found = structures("3T3R", leg_types="UPS", processes=2)
    assert forks == []
    assert found and {s.name for s in found} == {"6-UPS"}


@pytest.mark.parametrize("bad", [0, -1, 1.5, "2", True, 10**6])
def test_bad_processes_refused(bad):
    with pytest.raises(StructureError, match="processes"):
        structures("3T3R", leg_types="UPS", processes=bad)


def test_default_processes_follow_the_engine_threads(monkeypatch):
    monkeypatch.setattr(synthesis._engine, "n_threads", lambda: 3)
    assert synthesis._check_processes(None, 40) == 3
    assert synthesis._check_processes(None, synthesis.PARALLEL_CHECKS - 1) == 1
    assert synthesis._check_processes(2, 40) == 2
    assert synthesis._check_processes(1, 40) == 1
    monkeypatch.setattr(synthesis._engine, "n_threads", lambda: 1)
    assert synthesis._check_processes(None, 40) == 1


def test_spread_keeps_the_order_and_the_reference_engine():
    """Items come back in order; inside numpy_reference() the forked processes evaluate on the
    NumPy reference as the parent does."""
    from parasynth.common.validation import check_engine

    items = list(range(20))
    out = synthesis._spread(lambda i: (i * i, check_engine("compiled")), items, 2)
    assert out == [(i * i, "compiled") for i in items]
    with numpy_reference():
        out = synthesis._spread(lambda i: check_engine("compiled"), items, 2)
    assert out == ["numpy"] * 20


def test_study_enumeration_left_serial_while_compiling_early(monkeypatch):
    """A structure study's enumeration runs in its own process while early compiling helpers
    hold the cores (engine.compiling_early), else on the engine's threads."""
    from parasynth.study import structure_space
    from parasynth.study.spec import StructureSpec

    seen = []
    real = synthesis.structures

    def spy(*a, **k):
        seen.append(k.get("processes"))
        return real(*a, **k)

    monkeypatch.setattr(structure_space.synthesis, "structures", spy)
    monkeypatch.setattr(structure_space, "_CACHE", {})
    sec = StructureSpec(motion="3T3R", leg_types=["UPS", "PUS"], legs=[6])
    monkeypatch.setattr(structure_space, "compiling_early", lambda: True)
    structure_space.resolve_structures(sec)
    monkeypatch.setattr(structure_space, "_CACHE", {})
    monkeypatch.setattr(structure_space, "compiling_early", lambda: False)
    structure_space.resolve_structures(sec)
    assert seen == [1, None]


def test_compiling_early_false_without_helpers(monkeypatch):
    from parasynth import engine
    from parasynth.engine import precompile

    class _Running:
        def poll(self):
            return None

    monkeypatch.setattr(precompile, "_EARLY", {})
    assert engine.compiling_early() is False
    monkeypatch.setattr(precompile, "_EARLY", {"_feasible_kernel": _Running()})
    assert engine.compiling_early() is True


def test_engine_threads_without_loading_numba():
    """engine.n_threads reads NUMBA_NUM_THREADS (a study worker's share) before the kernels are
    loaded, and the engine's own count once they are."""
    import os
    import subprocess
    import sys

    code = ("import sys\nfrom parasynth import engine\nprint(engine.n_threads(), 'numba' in sys.modules)\n"
            "from parasynth.engine import core\ncore.set_threads(1)\nprint(engine.n_threads())")
    src = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "src")
    env = dict(os.environ, NUMBA_NUM_THREADS="2", PYTHONPATH=src + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert out.split() == ["2", "False", "1"]


def test_spread_from_two_threads_at_once_keeps_each_its_own_work():
    """Two threads spreading different work at the same time: each call's forked processes
    run that call's function (the fork takes its work under a lock)."""
    import threading

    out = {}

    def run(k):
        out[k] = synthesis._spread(lambda i: (k, i), list(range(24)), 2)

    ts = [threading.Thread(target=run, args=(k,)) for k in ("a", "b", "c")]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    for k in ("a", "b", "c"):
        assert out[k] == [(k, i) for i in range(24)]
