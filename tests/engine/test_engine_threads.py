"""Batches spread over threads (engine.core.blocking / over_blocks / set_threads): the split covers
every pose once, and the answers do not depend on it -- the same as on one thread and as the
NumPy reference."""

from __future__ import annotations

import time

import numpy as np
import pytest

from parasynth import load_mechanism
from parasynth.engine import core, kernels

numba = pytest.importorskip("numba")
pytestmark = pytest.mark.skipif(not core.HAVE_NUMBA, reason="numba not available")


@pytest.mark.parametrize("n", [0, 1, 63, 4096, core.PARALLEL_MIN - 1, core.PARALLEL_MIN, 10_000, 100_000, 2**20 + 5])
@pytest.mark.parametrize("threads", [1, 2, 3, 8])
def test_blocking_covers_every_pose_once(n, threads):
    block, nblk, par = core.blocking(n, threads)
    assert par == (threads > 1 and n >= core.PARALLEL_MIN)
    assert block >= 1 and block % core.SUB == 0
    assert (nblk - 1) * block < max(n, 1) <= nblk * block
    if par:  # ITEMS_PER_THREAD items a thread, as even as whole sub-blocks allow
        assert nblk == core.ITEMS_PER_THREAD * threads
        assert block - core.SUB < n / nblk <= block
    else:
        assert block <= core.BLOCK


def test_set_threads_refuses_bad_counts_and_keeps_the_ceiling():
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="threads"):
            core.set_threads(bad)
    try:
        core.set_threads(10**6)
        assert core.n_threads() == max(1, int(numba.config.NUMBA_NUM_THREADS))
        core.set_threads(1)
        assert core.n_threads() == 1
    finally:
        core.set_threads(None)


@pytest.mark.parametrize("n", [9000, 50_000])
def test_threaded_batches_answer_as_one_thread_and_numpy(n, monkeypatch):
    mech = load_mechanism("5pus_upu")
    rng = np.random.default_rng(3)
    lo = np.array([-0.06, -0.06, -0.10, -0.35, -0.35])
    X = rng.uniform(lo, -lo * np.array([1, 1, 0.8, 1, 1]), size=(n, 5))
    monkeypatch.setattr(core, "ITEMS_PER_THREAD", 7)  # uneven ranges
    monkeypatch.setattr(core, "ADAPTIVE", False)  # threads whether they pay now or not
    monkeypatch.setattr(core, "n_threads", lambda: 3)  # the pool is used even on a 1-core machine
    par = kernels.feasible_fast(mech, X)
    mpar = kernels.margins_fast(mech, X)
    monkeypatch.setattr(core, "n_threads", lambda: 1)
    one = kernels.feasible_fast(mech, X)
    mone = kernels.margins_fast(mech, X)
    assert core.blocking(n, 3)[2] and not core.blocking(n, 1)[2]
    assert 0 < np.count_nonzero(one) < n
    assert np.array_equal(par, one)
    for k in mone:
        assert np.array_equal(mpar[k], mone[k], equal_nan=True)
    assert np.array_equal(one, mech.is_feasible(X, engine="numpy"))


def test_the_timing_takes_the_faster_way_and_tries_the_other():
    t = core._Timing(explore=4, weight=0.5)
    n = core.PARALLEL_MIN
    assert t.threads_pay("k", n)  # nothing known: threads first
    t.record("k", True, n, 2e-3)
    assert not t.threads_pay("k", n)  # then one thread
    t.record("k", False, n, 1e-3)
    ways = [t.threads_pay("k", n) for _ in range(8)]
    assert ways.count(True) == 2 and ways.count(False) == 6  # the faster way, the other every 4th
    for _ in range(6):  # threads become faster (the machine got quiet): taken from then on
        t.record("k", True, n, 0.2e-3)
    ways = [t.threads_pay("k", n) for _ in range(8)]
    assert ways.count(True) == 6
    assert t.threads_pay("k", 4 * n)  # another batch size is timed apart: nothing known, threads first
    t.record("k", True, 4 * n, 1e-3)
    assert not t.threads_pay("k", 4 * n)  # then one thread
    t.record("small", True, n - 1, 1.0)  # batches that never use threads are not counted
    assert all(k[0] != "small" for k in t.stats)


def test_a_batchs_one_off_costs_do_not_keep_the_threads_out():
    """A way's first batch in a process carries one-off costs (kernels loaded, threads or a
    background compile started): the way's second batch replaces it when faster, so threads that
    pay are taken again at their next try, not a hundred batches later; a single slow batch
    later moves the estimate by at most half, a lasting slowdown still shows."""
    t = core._Timing(explore=8, weight=0.25, clip=3.0)
    n = core.PARALLEL_MIN
    t.record("k", True, n, 100e-3)  # the first parallel batch: kernels loaded, the crew started
    t.record("k", False, n, 1e-3)
    ways = [t.threads_pay("k", n) for _ in range(8)]
    assert ways.count(True) == 1  # one thread, threads tried once in eight
    t.record("k", True, n, 0.6e-3)  # threads tried again: faster than one thread
    assert [t.threads_pay("k", n) for _ in range(8)].count(True) == 7  # taken from then on
    t.record("k", True, n, 50e-3)  # a crew thread descheduled once
    assert t.stats[("k", n.bit_length())][1] * n == pytest.approx(0.6e-3 * 1.5)  # counted as 3x at most (per pose)
    for _ in range(3):  # the machine got busy: threads slow for good
        t.record("k", True, n, 5e-3)
    assert t.stats[("k", n.bit_length())][1] * n > 1e-3  # one thread is taken again
    assert [t.threads_pay("k", n) for _ in range(8)].count(True) == 1
    # without the replacement and the clip (the exponential average alone) the first batch
    # alone would have kept threads out: 100 ms * 0.75**8 > 1 ms after eight more tries
    assert 100e-3 * 0.75 ** 8 > 1e-3


def test_adaptive_blocking_gives_the_same_answers(monkeypatch):
    mech = load_mechanism("5pus_upu")
    X = np.random.default_rng(5).uniform(-0.05, 0.05, size=(20_000, 5))
    monkeypatch.setattr(core, "n_threads", lambda: 2)
    monkeypatch.setattr(core, "TIMING", core._Timing(explore=2))
    answers = [kernels.feasible_fast(mech, X) for _ in range(5)]  # both ways, alternately
    assert {par for _, _, par in [core.blocking(20_000, None, "feasible") for _ in range(4)]} == {True, False}
    for a in answers[1:]:
        assert np.array_equal(a, answers[0])
    assert np.array_equal(answers[0], mech.is_feasible(X, engine="numpy"))


def _ranges_run(monkeypatch, nt, n_blocks, fn):
    monkeypatch.setattr(core, "n_threads", lambda: nt)
    core.over_blocks(fn, n_blocks, True)


@pytest.mark.parametrize("nt,n_blocks,per", [(2, 2, 1), (3, 7, 1), (2, 9, 4), (4, 3, 2)])
def test_the_crew_runs_every_range_once_and_the_caller_waits_for_it(monkeypatch, nt, n_blocks, per):
    import threading
    import time

    monkeypatch.setattr(core, "ITEMS_PER_THREAD", per)
    caller = threading.get_ident()
    seen, lock, done = [], threading.Lock(), np.zeros(n_blocks)

    def fn(b0, b1):
        if threading.get_ident() != caller:
            time.sleep(0.02)  # a slow crew thread: the caller must wait for its range
        for b in range(b0, b1):
            done[b] += 1
        with lock:
            seen.append((b0, b1))

    for _ in range(3):
        seen.clear()
        done[:] = 0
        _ranges_run(monkeypatch, nt, n_blocks, fn)
        assert np.array_equal(done, np.ones(n_blocks))  # every item once, finished before the return
        assert sorted(seen)[0][0] == 0 and sorted(seen)[-1][1] == n_blocks


def test_an_error_in_a_crew_thread_reaches_the_caller(monkeypatch):
    import threading

    caller = threading.get_ident()

    def fn(b0, b1):
        if threading.get_ident() != caller or b0 > 0:
            raise ValueError(f"range {b0}-{b1} failed")

    for _ in range(3):
        with pytest.raises(ValueError, match="failed"):
            _ranges_run(monkeypatch, 2, 4, fn)
    hits = []
    _ranges_run(monkeypatch, 2, 4, lambda b0, b1: hits.append((b0, b1)))  # the crew works on after an error
    assert sorted(hits) == [(0, 2), (2, 4)]


def test_the_waits_spin_kernel_sees_another_threads_write():
    import threading
    import time

    core.spin_warm()
    fin = np.zeros(3, dtype=np.int64)
    assert not core._spin_done(fin, 1000)  # nothing set: gives up after its rounds

    def later():
        time.sleep(0.01)
        fin[:] = 1

    t = threading.Thread(target=later)
    t.start()
    core._wait(fin)  # returns once the other thread wrote (spinning, then sleeping)
    t.join()
    assert fin.all() and core._spin_done(fin, 1)


def test_blocking_by_work():
    """A batch's work, not its count of poses, decides the threads: a few thousand poses of a
    program kernel of many instructions (a 1T2R structure's solved parasitic coordinates) are
    spread over threads; the cheapest programs keep the threshold of PARALLEL_MIN poses; a
    batch of one sub-block never is."""
    assert core.program_work(1000, 23) == 1000  # the reference's programs: the poses themselves
    assert core.program_work(2048, 1667) > 25 * 2048  # ~1 us a pose
    assert not core.blocking(2048, 2)[2]
    assert core.blocking(2048, 2, work=core.program_work(2048, 1667))[2]
    assert not core.blocking(2048, 1, work=core.program_work(2048, 1667))[2]  # one thread
    assert not core.blocking(core.SUB, 2, work=1e9)[2]  # nothing to split
    block, nblk, par = core.blocking(core.SUB + 1, 2, work=1e9)
    assert par and nblk == 2 and block == core.SUB
    assert not core.blocking(core.PARALLEL_MIN - 1, 2, work=core.program_work(core.PARALLEL_MIN - 1, 8))[2]


def test_small_batches_of_costly_kernels_answer_as_one_thread(monkeypatch):
    """A 3-RPS of structures("1T2R") (its pose program solves x, y, gamma) and a 6-SPU of chain
    limbs at 1,500 poses: on three threads (the work-based split) the same answers as on one."""
    import warnings

    import parasynth
    from parasynth import engine
    from parasynth.model.mechanism import EngineFallbackWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        rps = next(s for s in parasynth.structures("1T2R") if s.name == "3-RPS").mechanism()
        spu = parasynth.structures("3T3R", leg_types=["SPU"], legs=[6])[0].mechanism()
    monkeypatch.setattr(core, "ADAPTIVE", False)  # threads whether they pay now or not
    for m in (rps, spu):
        lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
        X = lo + (hi - lo) * np.random.default_rng(4).uniform(0, 1, (1500, len(lo)))
        monkeypatch.setattr(core, "n_threads", lambda: 3)
        split = []
        over = core.over_blocks
        monkeypatch.setattr(core, "over_blocks", lambda fn, nb, par=True, **kw: (split.append(par and nb > 1), over(fn, nb, par, **kw))[1])
        f3, m3 = engine.feasible(m, X), engine.margins(m, X)
        monkeypatch.setattr(core, "over_blocks", over)
        assert any(split), m.name  # some batch was spread over threads
        monkeypatch.setattr(core, "n_threads", lambda: 1)
        f1, m1 = engine.feasible(m, X), engine.margins(m, X)
        assert 0 < f1.sum() < len(X), m.name
        assert np.array_equal(f3, f1)
        for k in m1:
            assert np.array_equal(m3[k], m1[k], equal_nan=True), k


def _crew_batch(monkeypatch, nt=3):
    """A parallel batch of ``nt`` ranges (the crew woken); returns the items done."""
    done = np.zeros(nt)

    def fn(b0, b1):
        done[b0:b1] += 1

    _ranges_run(monkeypatch, nt, nt, fn)
    return done


@pytest.mark.skipif(not core.APART, reason="the crew is kept apart on Linux only (sched_getcpu, sched_setaffinity)")
def test_the_crew_is_kept_off_the_callers_cpu(monkeypatch):
    import os

    allowed = os.sched_getaffinity(0)
    monkeypatch.setattr(core, "ITEMS_PER_THREAD", 1)
    monkeypatch.setattr(core, "_CREW", core._Crew())  # a crew of this test's own
    try:
        assert np.array_equal(_crew_batch(monkeypatch), np.ones(3))
        crew = core._CREW
        cpu = crew.apart_from
        assert len(crew.members) == 2
        if len(allowed) < 2:  # nowhere else to go: left as they are
            assert all(os.sched_getaffinity(t.native_id) == allowed for t, _ in crew.members)
            return
        assert cpu in allowed
        assert all(os.sched_getaffinity(t.native_id) == allowed - {cpu} for t, _ in crew.members)
        # the caller moved: the crew follows at the next batch (the test pins the caller)
        other = min(allowed - {cpu})
        os.sched_setaffinity(0, {other})
        try:
            assert np.array_equal(_crew_batch(monkeypatch), np.ones(3))
            assert crew.apart_from == other
            assert all(os.sched_getaffinity(t.native_id) == allowed - {other} for t, _ in crew.members)
        finally:
            os.sched_setaffinity(0, allowed)
    finally:
        core._CREW.batch = None


@pytest.mark.skipif(not core.APART, reason="the crew is kept apart on Linux only (sched_getcpu, sched_setaffinity)")
def test_a_failure_to_keep_the_crew_apart_turns_it_off_and_the_batch_still_runs(monkeypatch):
    import os

    def refuse(*_):
        raise OSError(22, "Invalid argument")

    monkeypatch.setattr(core, "_CREW", core._Crew())
    monkeypatch.setattr(core, "ITEMS_PER_THREAD", 1)
    monkeypatch.setattr(os, "sched_setaffinity", refuse)
    monkeypatch.setattr(os, "sched_getaffinity", lambda _: {0, 1})
    monkeypatch.setattr(core, "_sched_getcpu", lambda: 0)
    assert np.array_equal(_crew_batch(monkeypatch), np.ones(3))
    assert core.APART is False
    assert np.array_equal(_crew_batch(monkeypatch), np.ones(3))  # and without it


def test_the_crews_spin_marks_its_range_and_waits_for_a_batch_and_the_callers_first_claim():
    import threading
    import time

    core.spin_warm()
    mail, claim = np.zeros(2, dtype=np.int64), np.zeros(1, dtype=np.int64)
    fin = np.zeros(3, dtype=np.int64)
    # no batch: gives up after its rounds, having marked the range it ran last (and no other)
    assert not core._crew_spin(mail, 0, claim, 1000, fin, 1)
    assert fin.tolist() == [0, 1, 0]
    assert not core._crew_spin(mail, 0, claim, 1000, fin, -1) and fin.tolist() == [0, 1, 0]  # -1: none
    mail[0] = 1  # a batch posted whose ranges are claimed in Python: at once
    assert core._crew_spin(mail, 0, claim, 1, fin, -1)
    # a batch whose kernel claims from ``claim``: not before the caller's first claim
    mail[:] = (2, 1)
    wrote = []

    def later():
        time.sleep(0.02)
        wrote.append(time.perf_counter())
        claim[0] = 1

    t = threading.Thread(target=later)
    t.start()
    assert core._crew_spin(mail, 1, claim, 10**12, fin, -1)
    back = time.perf_counter()
    t.join()
    assert back >= wrote[0]


def test_a_deferred_drain_leaves_its_last_range_unmarked():
    ran = []
    b = core._Batch(lambda b0, b1: ran.append(b0), [0, 1, 2, 3])
    assert b.drain(defer=True) == 2
    assert ran == [0, 1, 2] and b.fin.tolist() == [1, 1, 0]
    assert b.drain(defer=True) == -1  # nothing left to run

    def fail(b0, b1):
        if b0 == 2:
            raise ValueError("range 2")

    b = core._Batch(fail, [0, 1, 2, 3])
    assert b.drain(defer=True) == -1  # the failed last range is marked (its error kept), not deferred
    assert b.fin.tolist() == [1, 1, 1] and isinstance(b.err, ValueError)
    b = core._Batch(fail, [0, 2, 3, 4])
    assert b.drain(defer=True) == 2 and b.fin.tolist() == [1, 1, 0]  # after a failed range: the last run
    b = core._Batch(lambda b0, b1: None, [0, 1, 2])
    assert b.drain() == -1 and b.fin.tolist() == [1, 1]


def test_a_spinning_crew_takes_the_next_batch_without_being_woken(monkeypatch):
    """After a batch, a crew thread spins for the next one (CREW_SPIN rounds) before it sleeps:
    a batch posted meanwhile reaches it with no wake-up at all."""
    import threading
    import time

    core.spin_warm()
    monkeypatch.setattr(core, "ITEMS_PER_THREAD", 1)
    monkeypatch.setattr(core, "_CREW", core._Crew())  # a crew of this test's own
    monkeypatch.setattr(core, "CREW_SPIN", 10**10)  # spins for seconds: the test does not race it
    monkeypatch.setattr(core, "n_threads", lambda: 2)
    caller = threading.get_ident()
    for woken in (True, False):
        if not woken:
            monkeypatch.setattr(core._CREW, "wake", lambda n: None)
            time.sleep(0.05)  # a crew thread that did not spin would be asleep by now
        took = threading.Event()
        by, ran = [], []

        def fn(b0, b1):
            ran.append(b0)
            if threading.get_ident() == caller:
                took.wait(10.0)  # the caller leaves the other range to the crew
            else:
                by.append(b0)
                took.set()

        core.over_blocks(fn, 2, True)
        assert sorted(ran) == [0, 1]
        assert by, f"woken={woken}: the crew ran no range"
    # end the long spin: a batch of nothing posted, then the crew spins briefly and sleeps
    monkeypatch.setattr(core, "CREW_SPIN", 1000)
    core._CREW.post(None, False)


def test_the_first_parallel_batch_loads_the_spin_kernels(monkeypatch):
    """A process that never ran the warm-up (a user's script, a benchmark) gets the waits' spin
    kernels at its first parallel batch (loaded from numba's cache or compiled once), so the
    caller and the crew spin rather than sleep; one-thread batches do not need them."""
    monkeypatch.setattr(core, "_SPIN_READY", False)
    monkeypatch.setattr(core, "n_threads", lambda: 1)
    core.over_blocks(lambda b0, b1: None, 4, True)
    assert not core._spin_ready()
    monkeypatch.setattr(core, "n_threads", lambda: 2)
    done = np.zeros(4)

    def fn(b0, b1):
        done[b0:b1] += 1

    core.over_blocks(fn, 4, True)
    assert core._spin_ready()
    assert np.array_equal(done, np.ones(4))


class _Helper:
    """A stand-in for the compiled crew's background helper: running until ``finish``."""

    def __init__(self, code=0):
        self.code, self.running = code, True

    def poll(self):
        return None if self.running else self.code

    @property
    def returncode(self):
        return self.poll()


def test_the_compiled_crew_compiles_in_the_background_while_batches_go_through_the_interpreter(monkeypatch):
    """The first parallel batch of a process whose cache lacks the compiled crew's kernels starts
    one background helper for them and does not load them: the feasibility batches then go
    through the interpreter's crew and answer as one thread; the first batch after the helper
    has finished loads them and the next ones go to the compiled crew. A helper that fails
    leaves the process on the interpreter's crew; with PARASYNTH_COMPILE_AHEAD=0, or called
    without ``background`` (a warm-up), they are loaded (compiled if need be) at once."""
    mech = load_mechanism("5pus_upu")
    X = _box_poses(mech, 9000, 3)
    monkeypatch.setattr(core, "ADAPTIVE", False)
    monkeypatch.setattr(core, "n_threads", lambda: 1)
    one = kernels.feasible_fast(mech, X)
    cached = [False]
    started = []
    monkeypatch.setattr(core, "_serve_cached", lambda: cached[0])
    monkeypatch.setattr(core, "_start_serve_helper", lambda: (started.append(1), setattr(core, "_SERVE_HELPER", h)))
    monkeypatch.setattr(core, "_SPIN_READY", False)
    monkeypatch.setattr(core, "_SERVE_READY", False)
    monkeypatch.setattr(core, "_SERVE_HELPER", None)
    monkeypatch.delenv("PARASYNTH_COMPILE_AHEAD", raising=False)
    monkeypatch.setattr(core, "n_threads", lambda: 2)
    h = _Helper()
    compiled = []
    real_batch = core._compiled_batch
    monkeypatch.setattr(core, "_compiled_batch", lambda *a: (compiled.append(1), real_batch(*a))[1])
    for _ in range(3):
        assert np.array_equal(kernels.feasible_fast(mech, X), one)
    assert started == [1] and core._SPIN_READY and not core._SERVE_READY and not compiled
    h.running, cached[0] = False, True  # the helper is done: its kernels are in the cache
    assert np.array_equal(kernels.feasible_fast(mech, X), one)  # this batch loads them
    assert core._SERVE_READY and core._SERVE_HELPER is None
    assert np.array_equal(kernels.feasible_fast(mech, X), one)
    assert compiled  # now through the compiled crew
    # a helper that failed: the interpreter's crew for the rest of the process
    monkeypatch.setattr(core, "_SPIN_READY", False)
    monkeypatch.setattr(core, "_SERVE_READY", False)
    cached[0] = False
    h = _Helper(code=1)
    compiled.clear()
    assert np.array_equal(kernels.feasible_fast(mech, X), one)
    h.running = False
    for _ in range(2):
        assert np.array_equal(kernels.feasible_fast(mech, X), one)
    assert not core._SERVE_READY and core._SERVE_HELPER is None and not compiled and started == [1, 1]
    # at once: without background (a warm-up; also while a helper compiles them), or with
    # compiling ahead turned off
    h = _Helper()
    monkeypatch.setattr(core, "_SERVE_HELPER", h)
    core.spin_warm()
    assert core._SERVE_READY
    monkeypatch.setattr(core, "_SERVE_READY", False)
    monkeypatch.setenv("PARASYNTH_COMPILE_AHEAD", "0")
    core.spin_warm(background=True)
    assert core._SERVE_READY and started == [1, 1]


def test_the_compiled_crews_helper_compiles_into_the_cache(tmp_path):
    """The background helper's command (``python -m parasynth.engine.precompile`` with
    core.SERVE_KERNELS' small ones, here) compiles them into numba's cache, where a process
    then finds them."""
    import os
    import subprocess
    import sys

    env = {**core.helper_env(), "NUMBA_CACHE_DIR": str(tmp_path)}
    code = ("from parasynth.engine import core, precompile as pre; "
            "print([pre.in_cache(n) for n in ('_cancel_tickets', '_tickets_done')])")
    before = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert before.stdout.strip() == "[False, False]", before.stderr
    r = subprocess.run([sys.executable, "-m", "parasynth.engine.precompile", "_cancel_tickets", "_tickets_done"],
                       env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    after = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert after.stdout.strip() == "[True, True]", after.stderr
    assert {"_cancel_tickets", "_tickets_done"} <= set(core.SERVE_KERNELS)
    assert os.environ.get("PYTHONPATH", "") in env["PYTHONPATH"]


def _posted_batch(mech, X, nt, names=None, kaddr=None):
    """The feasibility batch of ``X`` posted for ``nt`` threads as a run posts it (the caller's
    ticket taken), without running anything: (its number, out, amb, ext, the crew's arrays).
    ``kaddr``: the kernel's address (default the feasibility kernel's)."""
    from parasynth.engine import evaluate

    core.spin_warm()
    p, _ = evaluate.plan(mech, names)
    kernels.feasible_fast(mech, X[:4])  # the kernel compiled here: its entry address known
    Xr = core._readonly(np.ascontiguousarray(X))
    n = Xr.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    amb = np.zeros(max(1, (n + core.SUB - 1) // core.SUB), dtype=np.int64)
    ext = np.empty((amb.shape[0], 6))
    ext[:, :3], ext[:, 3:] = np.inf, -np.inf
    claim = np.zeros(1, dtype=np.int64)
    mail, buf, tickets = np.zeros(3, dtype=np.int64), np.zeros(core.CREW_BUF, dtype=np.int64), np.zeros(1, dtype=np.int64)
    block = core.SUB * 2
    nblk = (n + block - 1) // block
    if kaddr is None:
        kaddr = core._entry_address("_feasible_kernel")
    g = core._post_feasible(Xr, *p.args(), block, out, amb, ext, claim, nblk, kaddr, nt, buf, mail, tickets)
    return g, out, amb, ext, claim, mail, buf, tickets


def _box_poses(mech, n, seed):
    """``n`` poses uniform in the model's default ranges, its home values elsewhere."""
    rng = np.random.default_rng(seed)
    X = np.tile(np.asarray(mech.home, dtype=float), (n, 1))
    for c, (lo, hi) in mech.default_ranges().items():
        X[:, mech.task_coordinates.index(c)] = rng.uniform(lo, hi, n)
    return X


# every table of the kernel's arguments non-empty in one of them: coordinate limits (2-RPU/2-SPS),
# cones (5-PUS/UPU, 3-PRS), leg lengths, revolute ranges, axis angles, an expression (4-UPS/1-RPS's
# sphere constraint, alone: among all its constraints it never decides a pose of the box)
@pytest.mark.parametrize("name, n, names", [("5pus_upu", 1000, None), ("5pus_upu", 9000, None),
                                            ("4ups_1rps", 3000, None), ("4ups_1rps", 3000, ("sphere_constraint",)),
                                            ("2rpu_2sps", 3000, None), ("3prs", 3000, None)])
def test_a_batch_served_from_its_posted_arguments_answers_as_the_kernel(name, n, names):
    """The compiled crew's side alone, on this thread: the arguments the caller posts (data
    pointers, shapes, scalars) rebuilt and the feasibility kernel called through its entry
    point give the feasibility and the extents of ``feasible_extents`` on one thread."""
    from parasynth.engine import evaluate

    mech = load_mechanism(name)
    X = _box_poses(mech, n, 7)
    g, out, amb, ext, claim, mail, buf, tickets = _posted_batch(mech, X, 2, names)
    assert mail[0] == g == 1 and mail[2] == 1
    done = np.full(4, -1, dtype=np.int64)
    r = core._crew_serve(mail, 0, claim, 50, core._NO_FIN, -1, buf, tickets, done)
    assert r == -1  # served the compiled batch itself, then nothing for 50 rounds
    assert done[1] == g  # ticket 1 ran batch g
    assert core._cancel_tickets(tickets, 2) == 0  # no ticket left for the caller to cancel
    assert core._tickets_done(done, g, 2, 0, 1)
    ok = mech.is_feasible(X, names, engine="numpy")
    assert np.array_equal(out, ok) and 0 < ok.sum() < n and not amb.any()
    core.set_threads(1)
    try:
        ok1, _, lo_ref, hi_ref = core.run_feasible(evaluate.plan(mech, names)[0], np.ascontiguousarray(X), extents=True)
    finally:
        core.set_threads(None)
    assert np.array_equal(ok1, ok)
    assert np.array_equal(ext[:, :3].min(axis=0), lo_ref) and np.array_equal(ext[:, 3:].max(axis=0), hi_ref)
    # the same batch seen again by a late crew thread: its ticket is past the batch's, it runs nothing
    out[:] = False
    assert core._crew_serve(mail, 0, claim, 50, core._NO_FIN, -1, buf, tickets, done) == -1
    assert not out.any()


def test_tickets_no_crew_thread_took_are_cancelled_and_not_waited_for():
    mech = load_mechanism("5pus_upu")
    X = np.zeros((300, 5)) + np.array([0.0, 0.0, 0.0, 0.0, 0.0])
    g, out, amb, ext, claim, mail, buf, tickets = _posted_batch(mech, X, 3)
    done = np.full(4, -1, dtype=np.int64)
    assert core._cancel_tickets(tickets, 3) == 0b110  # tickets 1 and 2: nobody came
    assert core._tickets_done(done, g, 3, 0b110, 1)  # nothing to wait for
    assert not core._tickets_done(done, g, 3, 0b100, 10)  # ticket 1 not cancelled, never done


def test_the_crew_serve_hands_a_batch_for_python_back():
    core.spin_warm()
    mail = np.array([5, 0, 0], dtype=np.int64)  # batch 5, for Python, not claiming
    one = np.zeros(1, dtype=np.int64)
    done = np.full(2, -1, dtype=np.int64)
    assert core._crew_serve(mail, 4, one, 10, core._NO_FIN, -1, np.zeros(core.CREW_BUF, dtype=np.int64), one, done) == 5
    assert core._crew_serve(mail, 5, one, 10, core._NO_FIN, -1, np.zeros(core.CREW_BUF, dtype=np.int64), one, done) == -1
    fin = np.zeros(2, dtype=np.int64)
    core._crew_serve(mail, 5, one, 1, fin, 1, np.zeros(core.CREW_BUF, dtype=np.int64), one, done)
    assert fin.tolist() == [0, 1]  # the range it ran last marked first


@pytest.mark.parametrize("threads", [2, 3])
@pytest.mark.parametrize("n", [9000, 50_000])
def test_compiled_crew_batches_answer_as_one_thread(n, threads, monkeypatch):
    """Real batches through the compiled crew (crew threads serving them while spinning, or woken
    from their sleep: a short spin), against one thread; the crew ran some of them."""
    mech = load_mechanism("5pus_upu")
    rng = np.random.default_rng(11)
    lo = np.array([-0.06, -0.06, -0.10, -0.35, -0.35])
    X = rng.uniform(lo, -lo * np.array([1, 1, 0.8, 1, 1]), size=(n, 5))
    monkeypatch.setattr(core, "ADAPTIVE", False)
    monkeypatch.setattr(core, "n_threads", lambda: 1)
    one = kernels.feasible_fast(mech, X)
    core.spin_warm()
    monkeypatch.setattr(core, "n_threads", lambda: threads)
    for spin in (core.CREW_SPIN, 20):
        monkeypatch.setattr(core, "CREW_SPIN", spin)
        before = core._CREW.done.copy()
        start = time.monotonic()
        for i in range(2000):
            assert np.array_equal(kernels.feasible_fast(mech, X), one)
            # 30 batches, and more while the crew has served none (its CPU busy with other work)
            if i >= 29 and ((core._CREW.done != before).any() or time.monotonic() - start > 20):
                break
        served = core._CREW.done != before
        assert served.any() or spin == 20  # spinning, the crew takes its tickets
    assert core._SERVE_READY and core._CREW.mail[2] == 1


def _failing_kernel_address():
    """The address (as ``_entry_address`` gives the kernel's) of a compiled function of the
    feasibility kernel's signature that raises."""
    import numba

    types = tuple(core.signatures()["_feasible_kernel"][1])

    @numba.njit(nogil=True)
    def failing(X, ins, consts, cbase, n_reg, n_pose, pose_regs, valid_regs, plim, loop, expr, tol, leg_kind, leg_act,
                leg_f, coord, actr, lenr, cone, rang, axang, pair, offs, block, out, amb, ext, claim, b1):
        if b1 >= 0:
            raise ValueError("a kernel that fails")

    failing.compile(types)
    cres = failing.overloads[types]
    return int(cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name))


def test_a_kernel_call_that_fails_is_reported_by_the_crew_and_the_caller():
    """A kernel called at its address does not raise: its failure comes back as a status, set
    in ``buf`` by a crew thread and in ``state[3]`` by the caller's compiled call (which then
    runs the batch again through the interpreter); a call that returns reports nothing."""
    mech = load_mechanism("5pus_upu")
    X = _box_poses(mech, 2000, 3)
    bad = _failing_kernel_address()
    g, out, amb, ext, claim, mail, buf, tickets = _posted_batch(mech, X, 2, kaddr=bad)
    done = np.full(4, -1, dtype=np.int64)
    assert core._crew_serve(mail, 0, claim, 50, core._NO_FIN, -1, buf, tickets, done) == -1
    assert done[1] == g and buf[core._B_ERR] == 1  # ran (and failed), marked done, failure said
    # the caller's side, on one thread: the failing address, then the kernel's
    from parasynth.engine import evaluate

    p, _ = evaluate.plan(mech)
    Xr = core._readonly(np.ascontiguousarray(X))
    for kaddr, failed in ((bad, 1), (core._entry_address("_feasible_kernel"), 0)):
        out = np.zeros(len(X), dtype=np.bool_)
        amb = np.zeros(len(X) // core.SUB + 1, dtype=np.int64)
        claim, state = np.zeros(1, dtype=np.int64), np.full(4, -7, dtype=np.int64)
        core._feasible_batch(Xr, *p.args(), core.SUB, out, amb, core._NO_EXT, claim, len(amb), kaddr, 1,
                             np.zeros(core.CREW_BUF, dtype=np.int64), np.zeros(3, dtype=np.int64),
                             np.zeros(1, dtype=np.int64), done, 10, state)
        assert state.tolist() == [state[0], 0, 1, failed] and state[0] >= 1
        if not failed:
            assert np.array_equal(out, mech.is_feasible(X, engine="numpy"))


def _stand_in_run(state_of, raises=None):
    """A stand-in for a compiled batch's ``run`` that only sets ``state`` (and raises)."""
    def run(block, claim, b1, nt, buf, mail, tickets, done, max_iter, state):
        state[:] = state_of
        if raises is not None:
            raise raises
    return run


def test_a_failed_compiled_batch_runs_again_through_the_interpreter_and_raises(monkeypatch):
    """A kernel call reported failed: the batch runs again on the calling thread through the
    interpreter, whose call raises the error; the crew's counter is released, the next batch runs."""
    mech = load_mechanism("5pus_upu")
    X = np.zeros((20_000, 5))
    monkeypatch.setattr(core, "ADAPTIVE", False)
    monkeypatch.setattr(core, "n_threads", lambda: 2)
    core.spin_warm()
    ran = []

    def fn(block, claim, b1):
        ran.append(int(claim[0]))
        raise RuntimeError("the kernel's error")

    with pytest.raises(RuntimeError, match="kernel's error"):
        core._timed_claims("feasible", fn, 20_000, run=_stand_in_run([3, 0, 1, 1]))
    assert ran == [0]  # again from the first item
    assert not core._CREW.busy.locked()
    assert kernels.feasible_fast(mech, X).shape == (20_000,)
    ran.clear()
    core._timed_claims("feasible", fn, 20_000, run=_stand_in_run([4, 0, 1, 0]))  # none failed: not again
    assert ran == []


def test_an_interrupt_right_after_the_compiled_call_still_waits_for_the_crew(monkeypatch):
    """Ctrl-C raised as the caller's compiled call returns, the crew not done with the batch:
    the caller waits for the crew's mark before it raises (the crew reads the batch's arrays)."""
    import threading
    import time

    core.spin_warm()
    crew = core._CREW
    monkeypatch.setattr(core, "SPIN_ITERATIONS", 10)
    g = 9
    crew.done[1] = -1

    def crew_finishes():
        time.sleep(0.05)
        crew.done[1] = g

    t = threading.Thread(target=crew_finishes)
    t.start()
    run = _stand_in_run([g, 0, 0, 0], raises=KeyboardInterrupt)
    with pytest.raises(KeyboardInterrupt):
        core._compiled_batch(crew, run, None, core.SUB, np.zeros(1, dtype=np.int64), 4, 2)
    assert crew.done[1] == g  # raised only after the crew's mark
    t.join()
    crew.done[1] = -1


def test_an_interrupt_while_waiting_for_the_crew_is_raised_once_the_crew_is_done(monkeypatch):
    """Ctrl-C while the caller waits for a crew thread still running the batch (which reads its
    arrays by address): the wait goes on until the ticket is marked done, then raises."""
    import threading
    import time

    core.spin_warm()
    done = np.full(3, -1, dtype=np.int64)
    calls = []
    real_sleep = time.sleep

    def sleep(s):
        calls.append(s)
        if len(calls) == 1:
            raise KeyboardInterrupt
        real_sleep(s)

    monkeypatch.setattr(core, "SPIN_ITERATIONS", 10)
    monkeypatch.setattr(core.time, "sleep", sleep)

    def crew_finishes():
        real_sleep(0.05)
        done[1] = 7

    t = threading.Thread(target=crew_finishes)
    t.start()
    with pytest.raises(KeyboardInterrupt):
        core._wait_tickets(done, 7, 2, 0)
    assert done[1] == 7  # raised only after the crew's mark
    t.join()
    assert len(calls) > 1  # it went on waiting after the interrupt


def test_the_thread_count_follows_numbas_setting_after_it_was_read(monkeypatch):
    """A forked study worker sets numba's thread count to 1 after the run's process has read it
    (study/workers.py): the engine's count follows, and ``set_threads`` stays a ceiling below it."""
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 3)
    assert core.n_threads() == 3
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 1)
    assert core.n_threads() == 1
    core.set_threads(2)
    try:
        assert core.n_threads() == 1
        monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 4)
        assert core.n_threads() == 2
    finally:
        core.set_threads(None)
