"""The compiled kernels (numba) and the plans that feed them; see :mod:`parasynth.engine`.

One kernel set serves every mechanism description: the legs' geometry and every limit are
read into arrays at each plan (so parameter changes need no recompilation), and the task
parametrisation -- defined coordinates, Euler conventions or rotation axis lists, positions
that may use ``R11..R33``, validity conditions -- and the ``expression`` constraint margins
are a register program (:mod:`parasynth.engine.program`) interpreted per sub-block of ``SUB``
poses. Per sub-block: the task-coordinate ranges and finiteness, the program's pose part,
then leg by leg its inverse kinematics and that leg's checks (actuator range, passive length,
joint cone angles, leg-axis angles, revolute angle), each a straight loop over the sub-block
with the leg's geometry and limits as loop invariants (SIMD across poses), then the
expression margins and, last and most expensive, leg interference (the two segments projected
on the pair's direction settle most pairs, the distance of the two lines most of the rest;
the segment distance is computed only for a sub-block with a feasible pose neither settles). A sub-block stops at the
first stage after which none of its poses is feasible, and before each leg a sub-block whose
feasible poses are at most half is compacted (the later stages run on those alone). Nothing
of size N is allocated but the result (and, for a workspace, the per-block extents of the
feasible poses' positions).

Costs per pose (5pus_upu, every pose feasible, one core, ~36 ns in all once the program's
generated pose loop, :mod:`parasynth.engine.posefn`, is compiled; a perf profile's shares):
the coordinates in and the pose part ~10 ns (the loop ~5 ns of it), the six legs' inverse
kinematics ~8 ns (the five square roots of the PUS legs a floor), the ten cone limits ~6 ns,
the ten interference pairs ~8 ns (the projections and, for two pairs, the line distance), the
rest (actuator ranges, the result) ~2 ns. Coordinate magnitudes are tested in the kernel
(``Program.pose_limit`` per coordinate), so the entry points make no NumPy pass over a float
batch.

Agreement with the NumPy path
-----------------------------
The kernels evaluate the same conditions, not always in the same arithmetic form: a cone
limit ``angle(u, v) <= hi`` is tested as ``sin(hi) (u.v) - cos(hi) |u x v| >= 0`` (on
squares, signs handled; for a unit ``v`` and an upper limit below pi/2, ``|u x v|^2`` as
``|u|^2 - (u.v)^2``), ``arccos(c) <= hi`` as ``c >= cos(hi)``, a distance limit
``d >= D`` as ``d^2 >= D^2``; the sine and cosine of an ``atan2`` are taken algebraically; the
vectorised sin/cos (Cephes) may differ from NumPy's by an ulp; sums may associate
differently. The booleans therefore agree exactly except at poses within rounding of a
boundary: the contract (``tests/engine/test_kernels.py``) is that ``feasible`` and the NumPy
``is_feasible`` disagree only at poses whose NumPy feasibility margin is within 1e-12 of zero.
Margins agree to ~1e-15 except where rounding is amplified (``arccos`` near 0 and pi, the
square root of a PUS discriminant at the reach limit).

RPS/RPU legs accept an off-plane error up to ``GEOM_TOL * max(1, leg length)`` (a batch-
dependent tolerance in NumPy). The kernel decides reachability itself whenever the off-plane
error is at most ``GEOM_TOL`` (in consistent descriptions it is ~1e-16) and otherwise hands
the whole batch to NumPy.
"""

from __future__ import annotations

import bisect
import ctypes
import logging
import functools
import itertools
import math
import os
import subprocess as _subprocess
import sys
import threading
import time
import warnings
import weakref

import numpy as np

from ..model.constraints import (ActuatorRange, CoordinateRange, JointAngleLimit, LegAxisAngle, LegInterference,
                                 LegLengthRange, SingularityMarginFloor)
from ..model.mechanism import EngineFallbackWarning
from ..model.legs import GEOM_TOL, PRS, PUS, RPS, RPU, RUS, SPS, UPS, UPU
from ..model.spatial import unit
from ..common import cache as _disk
from ..common.processes import helper_env
from ..common.validation import MAX_POSE_MAGNITUDE
from .program import OPS, Program, Untranslatable, build_program
from .warmup import compile_ahead_off

try:  # pragma: no cover - depends on the environment
    if os.environ.get("PARASYNTH_NO_NUMBA", "").strip() not in ("", "0"):
        raise ImportError("disabled by PARASYNTH_NO_NUMBA")
    from numba import carray, njit
    from numba import config as _nb_config
    from numba import types as _nbt

    from . import posefn as _posefn

    HAVE_NUMBA = True
except Exception:  # ImportError, or a broken numba/llvmlite install
    HAVE_NUMBA = False

# Leg kinds in the kernel; the legs with a link of fixed length (PUS, PRS, RUS) are the kinds
# 1 and >= 4.
_FREE, _PUS, _RPS, _RPU, _PRS, _RUS = 0, 1, 2, 3, 4, 5

# Leg float-array layout (leg_f columns); RUS: crank zero direction c0 in _AX, r_axis x c0 in
# _AX2, crank length in _CRANK.
_B, _A, _AX, _AX2, _BREF, _PREF, _LEN, _BRANCH, _PTOL, _CRANK = 0, 3, 6, 9, 12, 15, 18, 19, 20, 21
_NLF = 22

#: Cone-angle keys of each leg class: (base end, platform end).
_CONE_KEYS = {
    SPS: ("S_base_cone", "S_platform_cone"),
    UPS: ("U_base_cone", "S_platform_cone"),
    PUS: ("U_base_cone", "S_platform_cone"),
    RPS: ("R_base_cone", "S_platform_cone"),
    RPU: ("R_base_cone", "U_platform_cone"),
    PRS: ("R_base_cone", "S_platform_cone"),
    UPU: ("U_base_cone", "U_platform_cone"),
    RUS: ("U_base_cone", "S_platform_cone"),
}

#: Poses per work item of a batch on one thread (one scratch allocation of SUB poses per item).
BLOCK = 4096
#: Poses per SIMD sub-block: the interpreter's per-instruction cost and each loop's set-up are
#: shared by SUB poses. 128 measured 3-6 % faster than 64 (5-PUS/UPU worst case, the quick
#: start's designs, a 6-PUS workspace; one core, docs/performance.md) although the scratch of a
#: six-leg sub-block (~70 KiB) then exceeds a 32 KiB L1 cache; 256 gains little more.
SUB = 128
#: Batches of fewer poses run on the calling thread only: handing work to another thread costs
#: ~0.02-0.05 ms (a sleeping crew thread's wake-up on this kind of virtual machine), 10-20 % of
#: the time of 4096 poses (measured with ``benchmarks/workspace_throughput.py --figures``, see
#: docs/performance.md).
PARALLEL_MIN = 8192
#: Work items per thread of a parallel batch: a batch is cut into about this many ranges per
#: thread (a multiple of SUB poses each), claimed in turn. One range per thread
#: measured fastest (2 threads / 1 thread at 8192 poses: 1.34 with one range a thread, 1.13-1.29
#: with two to eight): each range a thread claims costs it the interpreter lock, and a thread
#: that has to wait for that lock sleeps, and wakes ~50 us later. A thread that falls behind
#: has its range taken by another only if it has not started it (see :func:`over_blocks`).
ITEMS_PER_THREAD = 1

_THREADS = None


def n_threads() -> int:
    """Threads a batch is spread over: numba's thread count (``NUMBA_NUM_THREADS``, default
    the number of cores; a study's worker processes get ``cores // workers`` of it, see
    :func:`parasynth.study.workers.worker_env`, and a forked worker sets it to 1), or fewer if
    :func:`set_threads` asked so. Read from numba's configuration at each call (an attribute,
    not an import: a batch asks two or three times)."""
    if not HAVE_NUMBA:
        return 1
    nt = max(1, int(_nb_config.NUMBA_NUM_THREADS))
    return nt if _THREADS is None else min(nt, _THREADS)


def set_threads(n: int | None) -> None:
    """Spread batches over at most ``n`` threads from now on (``None``: numba's thread count
    again); numba's thread count stays the ceiling, so a worker process kept to one thread
    stays there."""
    global _THREADS
    if n is not None and (not isinstance(n, int) or isinstance(n, bool) or n < 1):
        raise ValueError(f"threads: {n!r} is not allowed; give a whole number >= 1 or None")
    _THREADS = n


#: What a pose costs the program kernels (feasibility, margins, pose) on one core, ~``POSE_NS +
#: INSTRUCTION_NS * instructions`` ns, against ``REFERENCE_NS`` for the cheapest described
#: mechanism (the quick start's 5-PUS/UPU, 23 instructions): measured 26-37 ns a pose for
#: programs of 8-23 instructions (closed-form legs) and 1,040-1,960 ns for the 1,667-3,511 of
#: the 1T2R structures, whose parasitic coordinates the program solves by an unrolled
#: Gauss-Newton (0.55-0.63 ns an instruction; docs/performance.md). A batch's work in
#: reference poses (:func:`program_work`) decides whether threads pay for it, not its count of
#: poses: 2048 poses of a 3-RPS are ~60,000 of the quick start's.
POSE_NS = 20.0
INSTRUCTION_NS = 0.6
REFERENCE_NS = 34.0


def program_work(n: int, n_instructions: int) -> float:
    """The work of ``n`` poses of a program of ``n_instructions``, in poses of the reference
    mechanism (never fewer than ``n``)."""
    return n * max(1.0, (POSE_NS + INSTRUCTION_NS * n_instructions) / REFERENCE_NS)


def blocking(n: int, threads: int | None = None, kind: str | None = None,
             work: float | None = None, per_thread: int = ITEMS_PER_THREAD, unit: int = SUB) -> tuple[int, int, bool]:
    """``(block, n_blocks, parallel)`` for a batch of ``n`` poses: on the calling thread in
    blocks of BLOCK poses below PARALLEL_MIN poses' work (``work``: the batch's work in poses
    of the cheapest kernel, :func:`program_work`; default ``n``), or for SUB poses or fewer, or
    with one thread, or when :data:`TIMING` finds that threads do not pay for the kernel
    ``kind`` now; else in ITEMS_PER_THREAD blocks per thread (a multiple of ``unit``, SUB for the
    program kernels: a block's scratch is of SUB poses, so its size costs nothing). The result
    does not depend on the blocking: every pose is computed alone."""
    nt = n_threads() if threads is None else threads
    w = n if work is None else max(float(n), float(work))
    if nt <= 1 or w < PARALLEL_MIN or n <= unit or getattr(_IN_POOL, "active", False):
        return BLOCK, max(1, (n + BLOCK - 1) // BLOCK), False
    if threads is None and kind is not None and not TIMING.threads_pay(kind, int(w)):
        return BLOCK, (n + BLOCK - 1) // BLOCK, False
    per = -(-n // (per_thread * nt))
    block = max(unit, -(-per // unit) * unit)  # rounded up: at most per_thread items a thread
    return block, (n + block - 1) // block, True


class _Timing:
    """Whether spreading a kernel's batches over threads pays, from the batches themselves.

    On an idle machine two threads nearly halve a batch of 8192 poses; on a machine whose
    cores are busy with other work a crew thread is often descheduled while it holds a range,
    and the batch waits for it (twice the serial time, measured at load 5-6 on 2 cores). So
    per kernel and batch size (to a power of 2) the wall time per pose of recent batches is
    kept for both ways (an exponential average), the faster way is taken, and every
    ``explore``-th batch tries the other way. The way never changes an answer, only the
    time.

    A batch can carry costs of its own once: a way's first batch in a process loads kernels,
    starts the crew's threads or its background compile (a structure study's first parallel
    batch took 100 times the time per pose of the next ones). Averaged in, such a batch kept
    the threads out for a hundred batches, since the way it slowed is tried only every
    ``explore``-th batch. So a way's second batch replaces its first when it is faster, and a
    later batch counts at most ``clip`` times the estimate (a lasting slowdown, a busy machine,
    still raises it: by half at each batch with the defaults)."""

    def __init__(self, explore: int = 8, weight: float = 0.25, clip: float = 3.0):
        self.explore = explore
        self.weight = weight
        self.clip = clip
        # (kind, size class) -> [serial s/pose or None, parallel s/pose or None, batches,
        #                        serial batches timed, parallel batches timed]
        self.stats: dict = {}
        self.lock = threading.Lock()

    def threads_pay(self, kind: str, n: int) -> bool:
        if not ADAPTIVE:
            return True
        with self.lock:
            st = self.stats.setdefault((kind, int(n).bit_length()), [None, None, 0, 0, 0])
            st[2] += 1
            if st[1] is None:
                return True
            if st[0] is None:
                return False
            faster = st[1] <= st[0]
            return (not faster) if st[2] % self.explore == 0 else faster

    def record(self, kind: str, parallel: bool, n: int, seconds: float) -> None:
        if n < PARALLEL_MIN or n_threads() <= 1:
            return
        with self.lock:
            st = self.stats.setdefault((kind, int(n).bit_length()), [None, None, 0, 0, 0])
            i = 1 if parallel else 0
            v = seconds / n
            if st[i] is None:
                st[i] = v
            elif st[3 + i] == 1:  # the way's first batch may have carried one-off costs
                st[i] = min(st[i], v)
            else:
                st[i] += self.weight * (min(v, self.clip * st[i]) - st[i])
            st[3 + i] += 1


#: Threads for a kernel's batches only while they pay (see :class:`_Timing`); False: always
#: (from PARALLEL_MIN poses up, with several threads).
ADAPTIVE = True
TIMING = _Timing()


def _timed_blocks(kind: str, fn, n: int, work: float | None = None) -> None:
    """``over_blocks`` of ``fn`` over a batch of ``n`` poses (``work``: in poses of the cheapest
    kernel, see :func:`blocking`), blocked by :func:`blocking`; ``fn(block, b0, b1)``. The
    batch's time goes to :data:`TIMING` (by its work)."""
    block, nblk, par = blocking(n, kind=kind, work=work)
    t0 = time.perf_counter()
    over_blocks(lambda b0, b1: fn(block, b0, b1), nblk, par)
    TIMING.record(kind, par, int(max(n, work or 0)), time.perf_counter() - t0)


#: Work items per thread of a batch whose kernel claims its items itself (:func:`_timed_claims`):
#: a thread that starts late (a crew thread woken from its sleep starts ~0.09 ms after the
#: caller) takes fewer of them, and the threads end within about an item of each other. 16: with
#: the compiled crew (no thread's way back through the interpreter to hide it) 8 items a thread
#: left the caller waiting ~3.5 us for the crew's last item at 8192 poses; 16 measured 1.86 /
#: 1.76 times one thread at 8192 poses, 1.94 / 1.87 at 16384 (docs/performance.md).
CLAIMS_PER_THREAD = 16


def _timed_claims(kind: str, fn, n: int, work: float | None = None, unit: int = SUB, run=None) -> None:
    """As :func:`_timed_blocks` for a kernel that claims its work items itself
    (``fn(block, claim, n_blocks)``, each item taken by an atomic increment of ``claim[0]``):
    every thread of the batch calls it once and takes items until none is left, so a thread
    that starts late takes fewer and none waits for another's range; the items are finer
    (:data:`CLAIMS_PER_THREAD` a thread). One thread: one call takes them all in order.

    ``run(block, claim, n_blocks, threads, buf, mail, tickets, done, max_iter, state)``, where
    given, runs the caller's whole part of the batch in compiled code (:func:`_feasible_batch`):
    the crew threads, spinning in :func:`_crew_serve`, run the kernel without the interpreter
    (:func:`_compiled_batch`)."""
    block, nblk, par = blocking(n, kind=kind, work=work, per_thread=CLAIMS_PER_THREAD, unit=unit)
    t0 = time.perf_counter()
    if not par:
        fn(block, np.zeros(1, dtype=np.int64), nblk)
    else:
        crew = _CREW
        shared = crew.busy.acquire(blocking=False)  # the crew's counter, which its spin watches
        try:
            claim = crew.claim if shared else np.zeros(1, dtype=np.int64)
            claim[0] = 0
            nt = n_threads()
            if _SERVE_HELPER is not None:  # compiling the compiled crew's kernels (spin_warm)
                _serve_helper_done()
            if shared and run is not None and _SERVE_READY and nt <= MAX_TICKETS:
                _compiled_batch(crew, run, fn, block, claim, nblk, nt)
            else:
                over_blocks(lambda p0, p1: fn(block, claim, nblk), nt, True, claiming=shared)
        finally:
            if shared:
                crew.busy.release()
    w = n if work is None or work < n else int(work)
    if w >= PARALLEL_MIN:
        TIMING.record(kind, par, w, time.perf_counter() - t0)


def _compiled_batch(crew, run, fn, block, claim, nblk, nt) -> None:
    """A claiming batch on ``nt`` threads whose crew part runs in compiled code: the crew woken
    where it sleeps (it then finds the batch in its spin), and ``run`` posting the batch (the
    kernel's arguments into the crew's ``buf``, ``nt`` tickets, the first the caller's),
    running the caller's items, cancelling the tickets no crew thread took and waiting a while
    for the others (:func:`_feasible_batch`); then, if they are not done yet, waiting for them
    (sleeping 20 us at a time) -- also when an interrupt came meanwhile, since a crew thread
    may still be reading the batch's arrays. If a call of the kernel failed, the batch runs
    again on this thread through the interpreter, which raises the error."""
    st = crew.state
    st[0] = -1
    try:
        crew.wake(nt - 1)
        run(block, claim, nblk, nt, crew.buf, crew.mail, crew.tickets, crew.done, SPIN_ITERATIONS, st)
    finally:
        if st[0] >= 0 and not st[2]:  # posted, and the crew is not done with it yet
            _wait_tickets(crew.done, int(st[0]), nt, int(st[1]))
    if st[3] or crew.buf[_B_ERR]:
        claim[0] = 0
        fn(block, claim, nblk)


def _wait_tickets(done, g, nt, cancelled) -> None:
    """Until every ticket of batch ``g`` not ``cancelled`` is marked done: spinning in compiled
    code, then sleeping 20 us at a time. An interrupt (Ctrl-C) meanwhile is raised only once
    they are: a crew thread reads the batch's arrays by their addresses alone, so they must
    outlive its call."""
    interrupted = None
    while True:
        try:
            while not _tickets_done(done, g, nt, cancelled, SPIN_ITERATIONS):
                time.sleep(2e-5)
            break
        except BaseException as e:  # noqa: BLE001 - raised below, once the crew is done
            interrupted = e
    if interrupted is not None:
        raise interrupted


_IN_POOL = threading.local()
_NO_FIN = np.zeros(1, dtype=np.int64)
#: Length of the crew's ``buf``, where a compiled batch's arguments are posted (:func:`_post_feasible`).
CREW_BUF = 72
#: Threads a compiled batch can have (its tickets' bit mask, :func:`_cancel_tickets`).
MAX_TICKETS = 62


class _Batch:
    """One parallel batch: ``fn(edges[i], edges[i + 1])`` for each range i, each claimed once
    (``next`` of an :func:`itertools.count` is one call under the interpreter lock) by the
    calling thread or a crew thread; ``fin[i]`` set to 1 once range i is done (or skipped
    after another range failed)."""

    __slots__ = ("fn", "edges", "claim", "fin", "err")

    def __init__(self, fn, edges):
        self.fn = fn
        self.edges = edges
        self.claim = itertools.count()
        self.fin = np.zeros(len(edges) - 1, dtype=np.int64)
        self.err = None

    def drain(self, defer: bool = False) -> int:
        """Run the ranges not yet claimed; with ``defer``, the last one run is not marked
        finished but returned (-1 if none: every other is marked), for the caller to mark from
        compiled code once it has released the interpreter lock (:meth:`_Crew._loop`)."""
        edges, fin, n = self.edges, self.fin, len(self.edges) - 1
        last = -1
        for i in self.claim:
            if i >= n:
                break
            if last >= 0:
                fin[last] = 1
                last = -1
            try:
                if self.err is None:
                    self.fn(edges[i], edges[i + 1])
            except BaseException as e:  # noqa: BLE001 - handed to the calling thread
                if self.err is None:
                    self.err = e
                fin[i] = 1
                continue
            last = i
        if last >= 0 and not defer:
            fin[last] = 1
            last = -1
        return last


class _Crew:
    """Threads kept for the engine's batches, each asleep on a raw lock of its own until a
    batch wakes it (no futures, no queue: the fewest hand-offs of the interpreter lock). The
    calling thread takes ranges too and then waits for the ranges the crew took, spinning in
    compiled code (:func:`_spin_done`, the lock released) rather than sleeping: a sleeping
    thread woke ~50 us after the last range ended on the development machine (a third of a
    batch of 8192 poses on two threads). On Linux the crew is kept off the CPU of the thread
    that wakes it (:meth:`_keep_apart`). After a batch a crew thread spins for the next one
    (:data:`CREW_SPIN`, ~1 ms, in compiled code with the lock released) before it sleeps, and
    takes a batch posted meanwhile once the caller is inside its kernel: no wake-up, and no
    wait for the interpreter lock (a thread that sleeps on it wakes ~0.05-0.1 ms later here).
    The feasibility kernel's batches do not go through the interpreter at all once the
    compiled crew is loaded (:func:`_compiled_batch`): the spin (:func:`_crew_serve`) runs them
    from the arguments the caller posted in ``buf``, and marks them done itself."""

    def __init__(self):
        self.lock = threading.Lock()
        self.members: list = []  # (thread, wake lock)
        self.batch = None
        # a batch posted: mail[0] counts them, mail[1] says whether its kernel claims its items
        # from ``claim`` (then the crew's spin waits until the poster is inside its kernel),
        # mail[2] whether it is a compiled batch (its arguments in ``buf``, see _compiled_batch)
        self.mail = np.zeros(3, dtype=np.int64)
        self.buf = np.zeros(CREW_BUF, dtype=np.int64)
        self.tickets = np.zeros(1, dtype=np.int64)  # a compiled batch's: its number, tickets taken
        self.done = np.full(MAX_TICKETS + 2, -1, dtype=np.int64)  # per ticket: the batch it ran last
        self.state = np.zeros(4, dtype=np.int64)  # a compiled batch's, see _feasible_batch
        self.claim = np.zeros(1, dtype=np.int64)
        self.busy = threading.Lock()  # held by the thread whose batch uses ``claim``
        self.apart_from = None  # the CPU the crew was last kept off (see _keep_apart)
        self.cpus = None  # the CPUs the crew may use: the caller's when the first was started

    def _loop(self, wake) -> None:
        _IN_POOL.active = True
        mail, seen, fin, last = self.mail, 0, _NO_FIN, -1
        while True:
            # after a batch, spin a while (CREW_SPIN) for the next one before sleeping: a
            # sleeping thread starts ~0.1 ms after the caller's wake-up (its own and the
            # interpreter lock's, on a virtual machine), a third of a batch of 16384 poses. The
            # spin marks the last range done (fin[last]) once the interpreter lock is released,
            # so the calling thread, seeing it, does not wait for the lock (and sleep).
            if _SERVE_READY:  # compiled batches served in the spin itself, never in Python
                g = _crew_serve(mail, seen, self.claim, CREW_SPIN, fin, last, self.buf, self.tickets, self.done)
                fin, last = _NO_FIN, -1
                if g < 0:
                    wake.acquire()
                    continue  # look again: what woke it may be a compiled batch
                seen = g
            elif _spin_ready():
                if not _crew_spin(mail, seen, self.claim, CREW_SPIN, fin, last):
                    wake.acquire()
                seen = int(mail[0])
            else:
                if last >= 0:
                    fin[last] = 1
                if int(mail[0]) == seen:
                    wake.acquire()
                seen = int(mail[0])
            b = self.batch
            fin, last = _NO_FIN, -1
            if b is not None:
                last = b.drain(defer=True)
                fin = b.fin

    def post(self, batch, claiming: bool) -> None:
        """``batch`` for the crew: spinning members see it at once, sleeping ones at
        :meth:`wake`."""
        self.batch = batch
        self.mail[1] = 1 if claiming else 0
        self.mail[2] = 0
        self.mail[0] += 1

    def wake(self, n: int) -> None:
        """Wake ``n`` crew threads (started at the first need)."""
        with self.lock:
            while len(self.members) < n:
                wake = threading.Lock()
                wake.acquire()
                t = threading.Thread(target=self._loop, args=(wake,), daemon=True,
                                     name=f"parasynth-engine-{len(self.members)}")
                t.start()
                self.members.append((t, wake))
                self.apart_from = None  # the new one is kept apart too
            if APART:
                self._keep_apart()
            for _, wake in self.members[:n]:
                if wake.locked():  # else it has not taken the last wake-up yet: it will see this batch
                    wake.release()

    def _keep_apart(self) -> None:
        """Keep the crew off the calling thread's CPU (Linux): a crew thread woken from its
        sleep is placed by the scheduler on the CPU of the thread that woke it, which that
        thread is about to use for its own range; the two then share one core while another
        idles, and a batch on two threads took as long as on one after an idle gap (measured
        on a 2-core virtual machine, docs/performance.md). The crew's CPUs are set again only
        when the calling thread has moved; any failure turns this off for the process."""
        global APART
        try:
            cpu = _sched_getcpu()
            if cpu == self.apart_from or cpu < 0:
                return
            if self.cpus is None:
                self.cpus = frozenset(os.sched_getaffinity(0))
            others = self.cpus - {cpu}
            if others:
                for t, _ in self.members:
                    os.sched_setaffinity(t.native_id, others)
            self.apart_from = cpu
        except (OSError, AttributeError, TypeError, ValueError):
            APART = False


def _libc_sched_getcpu():
    """``sched_getcpu`` of the C library (Linux), or None."""
    if not sys.platform.startswith("linux") or not hasattr(os, "sched_setaffinity"):
        return None
    try:
        fn = ctypes.CDLL(None, use_errno=True).sched_getcpu
        fn.restype = ctypes.c_int
        fn.argtypes = []
        return fn if fn() >= 0 else None
    except (OSError, AttributeError):
        return None


_sched_getcpu = _libc_sched_getcpu()
#: Whether the crew is kept off the calling thread's CPU (:meth:`_Crew._keep_apart`): on Linux,
#: where the C library tells the calling thread's CPU.
APART = _sched_getcpu is not None

_CREW = _Crew()


def _after_fork() -> None:  # a forked process has none of the crew's threads, nor the helper
    global _CREW, _SERVE_HELPER
    _CREW = _Crew()
    _SERVE_HELPER = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork)

#: Iterations of the calling thread's spin while the crew finishes (~0.5-1 ms); then it polls
#: with short sleeps (a crew thread descheduled by other work on the machine).
SPIN_ITERATIONS = 200_000
#: Rounds of a crew thread's spin for the next batch before it sleeps (~1 ms).
CREW_SPIN = 2_000_000


def _wait(fin: np.ndarray) -> None:
    """Until every ``fin`` is set: spinning in compiled code (:func:`_spin_done`), then
    sleeping 20 us at a time."""
    if _spin_ready() and _spin_done(fin, SPIN_ITERATIONS):
        return
    while not fin.all():
        time.sleep(2e-5)


_SPIN_READY = False
#: Whether the compiled crew's kernels are loaded (:func:`spin_warm`): crew threads then wait in
#: :func:`_crew_serve` and the feasibility kernel's batches go to them in compiled code.
_SERVE_READY = False
#: Whether to hand the feasibility kernel's batches to the crew in compiled code at all.
COMPILED_CREW = True
#: The compiled crew's kernels (the crew's spin that serves compiled batches, and the caller's
#: side of such a batch): ~3.5 s of compile on an empty cache, done by a background helper
#: while the batches go through the interpreter (:func:`spin_warm`).
SERVE_KERNELS = ("_crew_serve", "_feasible_batch", "_cancel_tickets", "_tickets_done")
#: The helper process compiling :data:`SERVE_KERNELS` for this process, or None.
_SERVE_HELPER = None


def compiled_or_cached(disp, sig) -> bool:
    """Whether the kernel ``disp`` is compiled for ``sig`` in this process or in numba's cache
    on disk (read from the cache index without loading anything). True when that cannot be
    told (a numba whose cache internals differ)."""
    try:
        if disp.signatures:
            return True
        key = disp._cache._index_key(tuple(sig), disp.targetctx.codegen())
        return key in disp._cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 - numba internals: assume cached, compile on demand
        return True


def _spin_ready() -> bool:
    """Whether the waits' spin kernels are loaded in this process (:func:`spin_warm`, which the
    first parallel batch of a process calls); until then the caller and the crew sleep."""
    return _SPIN_READY


def spin_warm(background: bool = False) -> None:
    """Load the spin kernels of the threads' waits (:func:`_spin_done`, :func:`_crew_spin`) and,
    with :data:`COMPILED_CREW`, the compiled crew's (:data:`SERVE_KERNELS`) from numba's cache,
    or compile them (~0.2 s, then cached; a run compiles them ahead with the feasibility kernel,
    :mod:`parasynth.engine.precompile`; any other process at its first parallel batch). Without
    the spin kernels the caller and the crew sleep where they would spin (a batch of 8192 poses
    on two threads took twice its time on one).

    The compiled crew's kernels take ~3.5 s to compile: with ``background`` (the first parallel
    batch of a process, :func:`over_blocks`), when they are not cached, a helper process
    compiles them at a lower priority (``python -m parasynth.engine.precompile``, on a core the
    work leaves idle) and the batches go through the interpreter's crew meanwhile (a few
    microseconds more a batch); the first parallel batch after the helper is done loads them
    (:func:`_serve_helper_done`). So a first run on an empty cache does not wait for them.
    Without ``background``, or with ``PARASYNTH_COMPILE_AHEAD=0`` (each process compiles what it
    uses as it meets it), they are compiled here."""
    global _SPIN_READY
    if HAVE_NUMBA:
        _spin_done(np.ones(1, dtype=np.int64), 1)
        _crew_spin(np.ones(2, dtype=np.int64), 0, np.ones(1, dtype=np.int64), 1, _NO_FIN, -1)
        _SPIN_READY = True
        if COMPILED_CREW and not _SERVE_READY:
            if not background or compile_ahead_off():
                _load_serve()  # here, even while a helper compiles them (numba's cache takes both)
            elif _SERVE_HELPER is None:
                if _serve_cached():
                    _load_serve()
                else:
                    _start_serve_helper()


def _serve_cached() -> bool:
    sigs = signatures()
    return all(compiled_or_cached(*sigs[n]) for n in SERVE_KERNELS)


def _load_serve() -> None:
    """Load (or compile) the compiled crew's kernels; batches then go to the crew in compiled
    code."""
    global _SERVE_READY
    one = np.zeros(1, dtype=np.int64)
    _crew_serve(np.zeros(3, dtype=np.int64), 0, one, 1, _NO_FIN, -1, np.zeros(CREW_BUF, dtype=np.int64), one, one)
    _cancel_tickets(np.zeros(1, dtype=np.int64), 0)
    _tickets_done(one, 0, 1, 0, 1)
    _feasible_batch.compile(tuple(signatures()["_feasible_batch"][1]))
    _SERVE_READY = True


def _serve_mark():
    """The file one helper compiling :data:`SERVE_KERNELS` into this process's numba cache holds
    (:mod:`parasynth.engine.held`; a study's workers start one helper each), or None without a
    cache folder."""
    p = _disk.path_for("held", ("compiled crew", os.environ.get("NUMBA_CACHE_DIR", ""), sys.executable))
    if p is None:
        return None
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return p.with_suffix(".held")


def _start_serve_helper() -> None:
    global _SERVE_HELPER
    mark = _serve_mark()
    try:
        _SERVE_HELPER = _subprocess.Popen(
            [sys.executable, "-m", "parasynth.engine.precompile", *SERVE_KERNELS,
             *(("--hold", str(mark)) if mark is not None else ())], env=helper_env(),
            stdin=_subprocess.DEVNULL, stdout=_subprocess.DEVNULL, stderr=_subprocess.DEVNULL,
            preexec_fn=_posefn._lower_priority if hasattr(os, "nice") else None)
    except OSError:  # no process to be had: compiled here
        _load_serve()


def _serve_helper_done() -> None:
    """Once the helper of :func:`spin_warm` has finished, load the kernels it compiled (a
    helper that failed leaves this process on the interpreter's crew; the next process
    tries again)."""
    global _SERVE_HELPER
    p = _SERVE_HELPER
    if p is None or p.poll() is None:
        return
    _SERVE_HELPER = None
    if p.returncode == 0 and _serve_cached():
        _load_serve()


def over_blocks(fn, n_blocks: int, parallel: bool = True, claiming: bool = False) -> None:
    """Run ``fn(b0, b1)`` over the work items ``0 .. n_blocks - 1``: on the calling thread, or,
    when ``parallel`` and there are several items and threads, as contiguous ranges (about
    ITEMS_PER_THREAD a thread) claimed in turn by the calling thread and ``n_threads() - 1``
    crew threads (a range not yet claimed by a thread that wakes late is taken by another).
    The kernels are compiled ``nogil`` and write disjoint parts of their outputs, so the
    threads run in parallel and the result does not depend on the split."""
    nt = n_threads() if parallel else 1
    if nt <= 1 or n_blocks < 2 or getattr(_IN_POOL, "active", False):
        fn(0, n_blocks)
        return
    if not _SPIN_READY:
        spin_warm(background=True)
    parts = min(n_blocks, ITEMS_PER_THREAD * nt)
    batch = _Batch(fn, [n_blocks * i // parts for i in range(parts + 1)])
    crew = _CREW
    crew.post(batch, claiming)
    crew.wake(min(nt, parts) - 1)
    _IN_POOL.active = True  # a range's own batches run on its thread
    try:
        batch.drain()
    finally:
        _IN_POOL.active = False
    _wait(batch.fin)
    if crew.batch is batch:
        crew.batch = None
    if batch.err is not None:
        raise batch.err


_log = logging.getLogger("parasynth.engine")
#: (what, model class, reason) already said: one warning each (the one fallback policy of
#: the engine, for feasibility, margins, poses and the pose-wise indices alike).
_WARNED: set = set()


def warn_fallback(what: str, mech, reason: str, stacklevel: int = 4) -> None:
    """Say once per (what, model class, reason) that ``what`` runs on NumPy for ``mech`` and
    why: an :class:`EngineFallbackWarning` and a record on the ``parasynth.engine`` logger."""
    key = (what, type(mech), reason)
    if key in _WARNED:
        return
    _WARNED.add(key)
    d = getattr(mech, "description", None)
    src = getattr(d, "source", None) if d is not None else None
    kind = f"{getattr(mech, 'name', type(mech).__name__)}" + (f" ({src})" if src else "")
    msg = f"{kind}: {what} runs on NumPy: the compiled engine does not cover {reason}"
    _log.info(msg)
    warnings.warn(msg, EngineFallbackWarning, stacklevel=stacklevel)


#: Per mechanism object, what the engine derived from it (the one plan record of a
#: mechanism): ``"feasibility"`` {constraint selection: (legs, constraints, key, KernelPlan
#: or None, reason, constraints)} and ``"indices"`` (legs, leg arrays). Weak keys: a
#: mechanism's record goes with it; nothing is stored on the mechanism itself.
_RECORDS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def record_of(mech) -> dict:
    """The engine's record of ``mech`` (a dict; a fresh one, not kept, for an object that
    cannot be weakly referenced or hashed)."""
    try:
        rec = _RECORDS.get(mech)
    except TypeError:
        return {}
    if rec is None:
        rec = {}
        try:
            _RECORDS[mech] = rec
        except TypeError:
            pass
    return rec


class Unsupported(Exception):
    """The mechanism uses something the kernels do not implement (use NumPy); the message
    names the construct."""


# ---------------------------------------------------------------------------------------------
# Plan: the mechanism's program, geometry and constraints packed into arrays.
# ---------------------------------------------------------------------------------------------
class KernelPlan:
    """Arrays describing one mechanism (and one selection of its constraints) for the kernels.

    Program: ``ins`` (n, 6) instructions, ``consts`` the constant rows' values (literals and
    parameter values), ``n_reg`` register rows, ``n_pose`` instructions of the pose part,
    ``pose_regs`` (12,) the registers of p and R (row-major), ``valid_regs`` the validity
    conditions, ``expr`` (k, 2) int rows (register, constraint column) of expression margins.

    Check tables (float64, one row per elementary check; integer fields stored as floats):

    * ``coord``  (col, lo, hi, ci): CoordinateRange
    * ``actr``   (lo, hi, ci): ActuatorRange over all actuated legs
    * ``lenr``   (leg, lo, hi, ci): LegLengthRange
    * ``cone``   (leg, end, lo, hi, ci, lo_mode, hi_mode, sin^2 lo, cos^2 lo, sin^2 hi, cos^2 hi)
    * ``rang``   (leg, r0[3], b[3], lo, hi, ci): signed revolute angle atan2(n.b, n.r0)
    * ``axang``  (leg, axis[3], frame, hi, ci, cos hi): LegAxisAngle
    * ``pair``   (leg i, leg j, D, ci, D^2 or -1): LegInterference

    ``ci`` is the column of the constraint in ``names``. The per-leg tables (lenr, cone, rang,
    axang) are sorted by leg; ``offs`` (4, n_legs + 1) holds each leg's row range in them.
    Leg geometry ``leg_f`` (n_legs, 22): base anchor, platform anchor, slider/revolute axis
    (RUS: the crank's zero direction), RPU platform axis (RUS: ``r_axis x`` that direction),
    base_ref, platform_ref, link length, branch, PRS off-plane tolerance, RUS crank length.
    """

    def __init__(self, program: Program, consts, leg_kind, leg_act, leg_f, names, tables, expr, floors=()):
        self.program = program
        #: ((column, floor), ...) of the SingularityMarginFloor constraints: not checked by the
        #: kernels (their column stays +inf where reachable), applied after them by
        #: :mod:`parasynth.engine.evaluate` with the compiled singularity margin.
        self.floors = tuple(floors)
        self.consts = consts
        self.leg_kind = leg_kind
        self.leg_act = leg_act
        self.leg_f = leg_f
        self.names = tuple(names)
        self.tables = tables  # dict name -> (k, m) float64
        self.expr = expr
        self._args = None

    def args(self):
        """The kernels' arguments for this plan (kept while its pose loop, program, constants and
        expression rows stay the same objects)."""
        p = self.program
        loop = _posefn.function(p, SUB).address
        a = self._args
        if a is None or a[8] != loop or a[0] is not p.ins or a[1] is not self.consts or a[9] is not self.expr:
            t = self.tables
            a = self._args = (p.ins, self.consts, p.const_base, p.n_reg, p.n_pose, p.pose_regs, p.valid_regs,
                              p.pose_limit, loop, self.expr, GEOM_TOL, self.leg_kind, self.leg_act, self.leg_f,
                              t["coord"], t["actr"], t["lenr"], t["cone"], t["rang"], t["axang"], t["pair"], t["offs"])
        return a


def _first(row):
    return row[0]


def _table(rows, width):
    a = np.asarray(rows, dtype=np.float64).reshape(-1, width) if rows else np.zeros((0, width))
    return np.ascontiguousarray(a)


@functools.lru_cache(maxsize=256)
def _angle_modes(lo: float, hi: float):
    """Encode cone-angle bounds [lo, hi] (rad, angle in [0, pi]) for the boolean test (kept
    per bounds: a study's designs share them)."""
    if np.isnan(lo) or np.isnan(hi):
        raise Unsupported("a NaN angle limit")
    if hi <= 0 or lo >= np.pi:
        raise Unsupported("a degenerate cone-angle limit")
    if hi >= np.pi:
        hi_mode, sh2, ch2 = 0, 0.0, 0.0
    else:
        sh, ch = math.sin(hi), math.cos(hi)
        hi_mode, sh2, ch2 = (1 if ch >= 0 else 2), sh * sh, ch * ch
    if lo <= 0:
        lo_mode, sl2, cl2 = 0, 0.0, 0.0
    else:
        sl, cl = math.sin(lo), math.cos(lo)
        lo_mode, sl2, cl2 = (1 if cl >= 0 else 2), sl * sl, cl * cl
    return lo_mode, hi_mode, sl2, cl2, sh2, ch2


def _cos_limit(hi: float) -> float:
    """Threshold c such that ``arccos(clip(x, -1, 1)) <= hi`` iff ``x >= c`` (NaN never)."""
    if np.isnan(hi):
        raise Unsupported("a NaN angle limit")
    if hi >= np.pi:
        return -np.inf
    if hi < 0:
        return np.inf
    return math.cos(hi)


def _revolute_frame(r_axis: np.ndarray, ref: np.ndarray):
    """r0 and b of legs._u_angles (same operations), for the signed revolute angle."""
    a1 = r_axis
    r0 = unit(ref - np.dot(ref, a1) * a1)
    if not np.any(r0):
        r0 = unit(np.cross(a1, [1.0, 0, 0]) if abs(a1[0]) < 0.9 else np.cross(a1, [0, 1.0, 0]))
    b = np.cross(a1, r0)
    return r0, b


def expression_of(mech, c):
    """The margin :class:`Expression` of the expression constraint ``c`` of a described
    ``mech`` (None if ``c`` is not one of the description's expression constraints)."""
    e = getattr(c, "expression", None)
    if e is not None and hasattr(e, "tree"):
        return e
    ev = getattr(c, "evaluate", None)
    for v in (getattr(ev, "__defaults__", None) or ()):
        if hasattr(v, "tree") and getattr(v, "text", None) == getattr(c, "text", object()):
            return v
    for spec in getattr(mech.description, "constraints", ()):
        if getattr(spec, "name", None) == c.name and getattr(spec, "type", None) == "expression":
            e = spec.expr
            if e.text == getattr(c, "text", None):
                return e
    return None


def _is_described(mech) -> bool:
    """Whether ``mech`` carries a mechanism description the programs translate (its
    ``description`` with a task section, and the parameter values ``_penv``), as
    :class:`parasynth.mechanisms.description.DescribedMechanism` does. Asked of the object: the
    engine does not import the description layer above it."""
    d = getattr(mech, "description", None)
    return d is not None and hasattr(d, "task") and hasattr(mech, "_penv")


_KEYS: dict = {}


def _angle_keys(mech, legs):
    """The joint-angle keys each leg's ``solve`` reports (found once per leg class: the keys
    of a leg type do not depend on its geometry)."""
    missing = [leg for leg in legs if type(leg) not in _KEYS]
    if missing:
        p, R = mech.pose(mech.home[None, :])
        for leg in missing:
            _KEYS[type(leg)] = frozenset(leg.solve(p, R).angles)
    return [_KEYS[type(leg)] for leg in legs]


def leg_tables(mech, cons):
    """Leg arrays and check tables of ``mech`` for the constraints ``cons`` (a list), the
    expression constraints found ({name: Expression}) and their columns."""
    legs = list(mech.legs)
    nl = len(legs)
    names = [leg.name for leg in legs]
    index = {n: i for i, n in enumerate(names)}
    kinds = [0] * nl
    acts = [0] * nl  # 1 for an actuated leg
    rows = []  # the legs' rows of F as floats, one after the other (one array made of them: the same values)
    for i, leg in enumerate(legs):
        t = type(leg)
        f = [0.0] * _NLF
        if t in (SPS, UPS, UPU):
            kinds[i] = _FREE
        elif t is PUS:
            kinds[i] = _PUS
            f[_AX:_AX + 3] = leg.slider_axis.tolist()
            f[_LEN] = float(leg.link_length)
            f[_BRANCH] = float(leg.branch)
        elif t is PRS:  # a PUS-like slider and link, in the plane normal to r_axis
            kinds[i] = _PRS
            f[_AX:_AX + 3] = leg.slider_axis.tolist()
            f[_AX2:_AX2 + 3] = leg.r_axis.tolist()
            f[_LEN] = float(leg.link_length)
            f[_BRANCH] = float(leg.branch)
            f[_PTOL] = GEOM_TOL * max(1.0, float(leg.link_length))
        elif t is RPS:
            kinds[i] = _RPS
            f[_AX:_AX + 3] = leg.r_axis.tolist()
        elif t is RPU:
            kinds[i] = _RPU
            f[_AX:_AX + 3] = leg.r_axis.tolist()
            f[_AX2:_AX2 + 3] = leg.u_platform_axis.tolist()
        elif t is RUS:  # a crank about r_axis through the base anchor, then a link of fixed length
            kinds[i] = _RUS
            f[_AX:_AX + 3] = leg.crank_direction.tolist()
            f[_AX2:_AX2 + 3] = np.cross(leg.r_axis, leg.crank_direction).tolist()  # as RUS._crank
            f[_LEN] = float(leg.link_length)
            f[_BRANCH] = float(leg.branch)
            f[_CRANK] = float(leg.crank_length)
        else:
            raise Unsupported(f"the leg type {t.__name__} (leg {leg.name})")
        acts[i] = 1 if leg.is_actuated else 0
        f[_B:_B + 3] = leg.base.tolist()
        f[_A:_A + 3] = leg.platform.tolist()
        f[_BREF:_BREF + 3] = leg.base_ref.tolist()
        f[_PREF:_PREF + 3] = leg.platform_ref.tolist()
        rows += f
    F = np.array(rows, dtype=np.float64).reshape(nl, _NLF)
    kind, act = np.array(kinds, dtype=np.int64), np.array(acts, dtype=np.int64)

    # The check tables depend on the constraint objects, the legs' names, types and actuation
    # and the description -- not on the legs' geometry, but for revolute-joint angle limits
    # ("rang" rows) -- so the designs of a study, whose described constraints are shared objects
    # while their values are (parasynth.mechanisms.description.constraints), share them too.
    key = (id(getattr(mech, "description", None)), mech.n_task, tuple(map(id, cons)),
           tuple((type(leg), leg.name, bool(acts[i])) for i, leg in enumerate(legs)))
    hit = _CHECK_TABLES.get(key)
    if hit is not None and hit[0] is getattr(mech, "description", None):
        tables, exprs, expr_rows = hit[2]
        return kind, act, F, dict(tables), dict(exprs), list(expr_rows)
    tables, exprs, expr_rows = _check_tables(mech, legs, cons, kind, act, index, names)
    if not len(tables["rang"]) and not exprs:  # an expression constraint is a new object per design
        if len(_CHECK_TABLES) >= 64:
            _CHECK_TABLES.clear()
        # the description and the constraints kept alive: their ids stay theirs
        _CHECK_TABLES[key] = (getattr(mech, "description", None), tuple(cons), (tables, exprs, expr_rows))
    return kind, act, F, dict(tables), dict(exprs), list(expr_rows)


#: {key: (description, constraints, (tables, exprs, expr_rows))} of :func:`leg_tables`: the
#: check tables (read-only arrays) of the constraint objects, leg names and types.
_CHECK_TABLES: dict = {}


def _check_tables(mech, legs, cons, kind, act, index, names):
    """The check tables of the constraints ``cons`` of ``mech`` (see :func:`leg_tables`)."""
    nl = len(legs)
    rows = {k: [] for k in ("coord", "actr", "lenr", "cone", "rang", "axang", "pair")}
    exprs = {}
    expr_rows = []
    keys = None
    for ci, c in enumerate(cons):
        t = type(c)
        if t is ActuatorRange:
            if not act.any():
                raise Unsupported("an actuator_range constraint without actuators (NumPy raises)")
            rows["actr"].append((c.lo, c.hi, ci))
        elif t is CoordinateRange:
            if not 0 <= c.index < mech.n_task:
                raise Unsupported(f"constraint {c.name}: coordinate index out of range")
            rows["coord"].append((c.index, c.lo, c.hi, ci))
        elif t is LegLengthRange:
            if not c.legs:
                raise Unsupported(f"constraint {c.name}: leg_length without legs")
            for n in c.legs:
                rows["lenr"].append((index[n], c.lo, c.hi, ci))
        elif t is JointAngleLimit:
            if keys is None:  # angle keys each leg actually reports (checked, not assumed)
                keys = _angle_keys(mech, legs)
            sel = [i for i, leg in enumerate(legs) if (not c.legs or leg.name in c.legs) and c.key in keys[i]]
            if not sel:
                raise Unsupported(f"constraint {c.name}: joint angle {c.key!r} matches no leg (NumPy raises)")
            for i in sel:
                ckeys = _CONE_KEYS[type(legs[i])]
                if c.key in ckeys:
                    end = ckeys.index(c.key)
                    rows["cone"].append((i, end, c.lo, c.hi, ci) + _angle_modes(float(c.lo), float(c.hi)))
                elif c.key == "R_base" and kind[i] in (_RPS, _RPU, _PRS):
                    r0, b = _revolute_frame(legs[i].r_axis, legs[i].base_ref)
                    rows["rang"].append((i, *r0, *b, c.lo, c.hi, ci))
                else:
                    raise Unsupported(f"constraint {c.name}: the joint angle {c.key!r} of leg {legs[i].name}")
        elif t is LegAxisAngle:
            if c.frame not in ("base", "platform") or not c.legs:
                raise Unsupported(f"constraint {c.name}: leg_axis_angle frame {c.frame!r} or no legs")
            a = np.asarray(c.axis, dtype=float)
            a = a / np.linalg.norm(a)
            for n in c.legs:
                rows["axang"].append((index[n], *a, 1.0 if c.frame == "platform" else 0.0, c.hi, ci,
                                      _cos_limit(float(c.hi))))
        elif t is LegInterference:
            D = float(c.diameter)
            pairs = c._pairs(names)
            if not pairs:
                raise Unsupported(f"constraint {c.name}: interference without pairs (NumPy raises)")
            for a_, b_ in pairs:
                rows["pair"].append((index[a_], index[b_], D, ci, D * D if D > 0 else -1.0))
        elif t is SingularityMarginFloor:
            continue  # not a kernel check: evaluate.py applies it with the singularity-margin kernel
        elif t.__name__ == "ExpressionConstraint" and _is_described(mech):
            e = expression_of(mech, c)
            if e is None:
                raise Unsupported(f"constraint {c.name}: an expression constraint not from the description")
            exprs[c.name] = e
            expr_rows.append((c.name, ci))
        else:
            raise Unsupported(f"constraint {c.name}: the constraint type {t.__name__}")
    widths = {"coord": 4, "actr": 3, "lenr": 4, "cone": 11, "rang": 10, "axang": 8, "pair": 5}
    offs = []
    for k in ("lenr", "cone", "rang", "axang"):  # the rows by leg, and where each leg's rows start
        rows[k] = sorted(rows[k], key=_first)
        legs_of = [r[0] for r in rows[k]]
        offs.append([bisect.bisect_left(legs_of, i) for i in range(nl + 1)])
    tables = {k: _table(v, widths[k]) for k, v in rows.items()}
    tables["offs"] = np.array(offs, dtype=np.int64).reshape(4, nl + 1)
    return tables, exprs, expr_rows  # shared by the plans of designs that share constraints: read only


# ---------------------------------------------------------------------------------------------
# Programs (one per description and twist flag, parameters as constants) and plans
# ---------------------------------------------------------------------------------------------
_PROGRAMS: dict = {}


#: The pose methods a program stands for: one replaced on an instance is not what the program computes.
_PATCHABLE_ORDER = ("_pose", "pose", "pose_valid", "_twist_map", "twist_map", "_task_env")
_PATCHABLE = frozenset(_PATCHABLE_ORDER)


def _program_key(mech, exprs, twist, unknowns=False):
    d = mech.description
    # the shapes of the parameters that are not float64 scalars (those are all of shape ())
    shapes = tuple(sorted((k, v.shape if type(v) is np.ndarray else np.shape(v))
                          for k, v in mech._penv.items() if type(v) is not np.float64))
    return (type(mech), id(d), tuple((n, e.text) for n, e in exprs.items()), bool(twist), shapes, bool(unknowns))


def _program_content(mech, exprs, twist, unknowns) -> tuple:
    """What :func:`~parasynth.engine.program.build_program` reads of ``mech``, as a key of the
    programs kept on disk (:mod:`parasynth.common.cache`, kind ``programs``): the description's
    digest and variant selection, and, whatever that digest covers, the task's expressions and
    rotation, the legs' joints, the parameters' names and shapes (their values are the
    program's constants, read per design), the margins' expressions and the flags. Parameter
    values never enter a program, so every design of a description shares it."""
    d = mech.description
    t = d.task
    solve = getattr(t, "solve", None)
    conv = getattr(t, "convention", None)
    axes = None if conv is not None else tuple(tuple(float(v) for v in np.ravel(a)) for a in (t.rot_axes or ()))
    return (f"{type(mech).__module__}.{type(mech).__qualname__}", d.name, getattr(d, "digest", None),
            tuple(sorted((str(k), str(v)) for k, v in (getattr(d, "selection", None) or {}).items())),
            tuple(t.names), tuple((n, e.text) for n, e in t.defines), tuple(e.text for e in t.angles), conv, axes,
            tuple(e.text for e in t.position), tuple(e.text for e in t.valid),
            None if solve is None else (tuple(solve.names), repr(getattr(solve, "closure", None))),
            tuple(leg.joints for leg in mech.legs),
            tuple(sorted((k, tuple(int(x) for x in np.shape(v))) for k, v in mech._penv.items())),
            tuple((n, e.text) for n, e in exprs.items()), bool(twist), bool(unknowns))


def program_for(mech, exprs: dict, twist: bool = False, unknowns: bool = False) -> Program:
    """The (cached) program of a described ``mech`` with the margins ``exprs`` (and, with
    ``unknowns``, the solved unknowns of ``task.solve`` kept); checked against
    ``mech.pose``/``mech.pose_valid`` (and ``mech.twist_map``) when first built. Raises
    :class:`Unsupported`."""
    patched = [] if _PATCHABLE.isdisjoint(vars(mech)) else [k for k in _PATCHABLE_ORDER if k in vars(mech)]
    if patched:
        raise Unsupported(f"a pose method replaced on the instance ({', '.join(patched)})")
    key = _program_key(mech, exprs, twist, unknowns)
    hit = _PROGRAMS.get(key)
    if hit is not None and hit[0] is mech.description:
        if isinstance(hit[1], Exception):
            raise hit[1]
        return hit[1]
    try:
        content = _program_content(mech, exprs, twist, unknowns)
    except Exception:  # noqa: BLE001 - a description the key does not describe: built, not kept
        content = None
    kept = None if content is None else _disk.load("programs", content, Program)
    try:
        if kept is not None:
            prog = kept
        else:
            try:
                prog = build_program(mech, exprs, twist, unknowns)
            except Untranslatable as e:
                raise Unsupported(str(e)) from None
            except (KeyError, IndexError, TypeError, ValueError, RecursionError) as e:
                raise Unsupported(f"the task parametrisation ({type(e).__name__}: {e})") from None
        _check_program(mech, prog, twist)  # a program read back is checked as a new one
        if kept is None and content is not None:
            _disk.save("programs", content, prog)
        prog.pose_limit = _pose_limit(mech)
    except Unsupported as e:
        _PROGRAMS[key] = (mech.description, e)
        raise
    _PROGRAMS[key] = (mech.description, prog)
    return prog


def program_constants(mech, exprs: dict, twist: bool = False, unknowns: bool = False):
    """``(program_for(mech, exprs, twist), its constants for mech._penv)``, kept in the
    engine's record of ``mech`` while its parameter environment and description are the same
    objects: the feasibility plan, the poses of the extents and those of the indices of one
    design look them up once (the program's cache key and constants cost ~50 us a lookup).
    The constants array is shared: the kernels only read it."""
    patched = [] if _PATCHABLE.isdisjoint(vars(mech)) else [k for k in _PATCHABLE_ORDER if k in vars(mech)]
    if patched:
        raise Unsupported(f"a pose method replaced on the instance ({', '.join(patched)})")
    memo = record_of(mech).setdefault("programs", {})
    key = (tuple((n, e.text) for n, e in exprs.items()), bool(twist), bool(unknowns))
    hit = memo.get(key)
    penv, d = mech._penv, mech.description
    if hit is not None and hit[0] is penv and hit[1] is d:
        return hit[2], hit[3]
    prog = program_for(mech, exprs, twist, unknowns)
    consts = prog.constants(penv)
    memo[key] = (penv, d, prog, consts)
    return prog, consts


def _pose_limit(mech) -> np.ndarray:
    """Per task coordinate, the magnitude beyond which the NumPy path treats a pose as
    unreachable: ``parasynth.common.validation.MAX_POSE_MAGNITUDE`` for lengths (``Mechanism._poses``
    masks them; a length beyond it is unreachable either way) and, for angles, that value if
    the NumPy path masks huge angles too, else inf -- probed with the home pose turned by a
    whole number of turns past that magnitude in an angular coordinate, which is the home pose
    again to rounding. The kernels test ``|x| <= limit`` per coordinate, so the compiled entry
    points need no separate NumPy pass over the poses."""
    lim = MAX_POSE_MAGNITUDE
    ang = [j for j, c in enumerate(mech.task_coordinates) if c in mech.angular_coordinates]
    out = np.full(mech.n_task, float(lim))
    if not ang:
        return out
    X = np.array([mech.home, mech.home])
    X[1, ang[0]] += 2 * np.pi * math.ceil(2 * lim / (2 * np.pi))
    with np.errstate(all="ignore"):
        reach = mech.pose_context(X).reachable
    if not (reach[0] and not reach[1]):
        out[ang] = np.inf
    return out


def _probe_poses(mech) -> np.ndarray:
    rng = np.random.default_rng(7)
    n = mech.n_task
    scale = np.array([0.5 if c in mech.angular_coordinates else 0.3 * mech.length_scale
                      for c in mech.task_coordinates])
    X = mech.home + scale * rng.uniform(-1, 1, size=(48, n))
    return np.vstack([mech.home, X, np.zeros((1, n))])


def _check_program(mech, prog: Program, twist: bool) -> None:
    """Compare the compiled pose with ``mech.pose_valid``/``mech.pose`` (and the twist map)
    on deterministic poses around home: a translation that does not reproduce the
    description is never used."""
    if not HAVE_NUMBA:
        return
    X = _probe_poses(mech)
    with np.errstate(all="ignore"):
        valid = mech.pose_valid(X)
        p0, R0 = mech.pose(X[valid])
        T0 = mech.twist_map(X[valid]) if twist else None
    consts = prog.constants(mech._penv)
    ok, p1, R1, T1 = run_pose(prog, consts, X, twist)
    if not np.array_equal(ok, valid):
        raise Unsupported(f"a task parametrisation whose compiled pose validity differs from mech.pose_valid at "
                          f"{int(np.count_nonzero(ok != valid))} of {len(X)} probe poses around home")
    scale = max(1.0, float(np.max(np.abs(p0), initial=0.0)))
    if not (np.allclose(p0, p1[valid], rtol=0, atol=1e-12 * scale)
            and np.allclose(R0, R1[valid], rtol=0, atol=1e-12)):
        raise Unsupported("a task parametrisation whose compiled pose differs from mech.pose (beyond 1e-12) at "
                          "probe poses around home")
    if twist:
        tscale = max(1.0, float(np.max(np.abs(T0), initial=0.0)))
        fin = np.isfinite(T0)
        if not (np.array_equal(fin, np.isfinite(T1[valid]))
                and np.allclose(T0[fin], T1[valid][fin], rtol=0, atol=1e-10 * tscale)):
            raise Unsupported("a task parametrisation whose compiled twist map differs from mech.twist_map at probe "
                              "poses around home")


def build_plan(mech, cons) -> KernelPlan:
    """Pack ``mech`` and the constraints ``cons`` (a list of its Constraint objects) for the
    kernels; raises :class:`Unsupported` naming what cannot be represented."""
    if not _is_described(mech):
        raise Unsupported(f"the model class {type(mech).__name__} is not a mechanism description")
    kind, act, F, tables, exprs, expr_rows = leg_tables(mech, cons)
    try:
        prog, consts = program_constants(mech, exprs)
    except (KeyError, IndexError, TypeError, ValueError) as e:
        raise Unsupported(f"a parameter of the task parametrisation ({type(e).__name__}: {e})") from None
    expr = np.array([(prog.margin_regs[n], ci) for n, ci in expr_rows], dtype=np.int64).reshape(-1, 2)
    floors = [(ci, c.floor) for ci, c in enumerate(cons) if type(c) is SingularityMarginFloor]
    return KernelPlan(prog, consts, kind, act, F, [c.name for c in cons], tables, expr, floors)


def _readonly(X: np.ndarray) -> np.ndarray:
    """``X`` as a read-only array (a view if needed, no copy): numba types read-only and
    writable arrays differently, and the poses come both ways (a study's cached samples are
    read-only), so the kernels always get read-only poses -- one specialisation each."""
    if X.flags.writeable:
        X = X.view()
        X.flags.writeable = False
    return X


_NO_EXT = np.empty((0, 6))


def run_feasible(plan: KernelPlan, X: np.ndarray, extents: bool = False):
    """(out (N,) bool, ambiguous: bool) for contiguous float64 poses X; with ``extents``
    (out, ambiguous, lo (3,), hi (3,)): also the least and greatest platform position
    (x, y, z) over the feasible poses, taken in the kernel from the pose it computed (the
    values ``run_pose`` gives; +inf / -inf when no pose is feasible)."""
    X = _readonly(X)
    n = X.shape[0]
    out = np.empty(n, dtype=np.bool_)
    amb = np.zeros(max(1, (n + SUB - 1) // SUB), dtype=np.int64)  # one per block, any blocking
    if extents:  # per block (lo x, y, z, hi x, y, z), any blocking
        ext = np.empty((amb.shape[0], 6))
        ext[:, :3] = np.inf
        ext[:, 3:] = -np.inf
    else:
        ext = _NO_EXT
    args = plan.args()
    kaddr = _entry_address("_feasible_kernel") if _SERVE_READY and COMPILED_CREW and X.flags.c_contiguous else 0
    run = None
    if kaddr:
        def run(block, claim, b1, nt, buf, mail, tickets, done, max_iter, state):
            _feasible_batch(X, *args, block, out, amb, ext, claim, b1, kaddr, nt, buf, mail, tickets, done, max_iter,
                            state)
    _timed_claims("feasible", lambda block, claim, b1: _feasible_kernel(X, *args, block, out, amb, ext, claim, b1),
                  n, program_work(n, plan.program.ins.shape[0]), run=run)
    ambiguous = np.count_nonzero(amb) != 0
    if not extents:
        return out, ambiguous
    return out, ambiguous, ext[:, :3].min(axis=0), ext[:, 3:].max(axis=0)


_ENTRIES: dict = {}


def _entry_address(name: str) -> int:
    """The address of the kernel ``name`` (of :func:`signatures`) as compiled in this process,
    in numba's calling convention (a status returned, the exception not raised), which
    :func:`_call_status_at` calls; 0 while it is not compiled or loaded here yet (its first
    call does that)."""
    a = _ENTRIES.get(name)
    if a is None:
        disp, types = signatures()[name]
        cres = getattr(disp, "overloads", {}).get(tuple(types))  # (not a dispatcher: a test's stand-in)
        if cres is None:
            return 0
        a = int(cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name))
        _ENTRIES[name] = a
    return a


def run_margins(plan: KernelPlan, X: np.ndarray):
    """(M (N, n_constraints), ambiguous: bool)."""
    X = _readonly(X)
    M = np.empty((X.shape[0], len(plan.names)))
    amb = np.zeros(max(1, (X.shape[0] + SUB - 1) // SUB), dtype=np.int64)  # one per block, any blocking
    args = plan.args()
    _timed_claims("margins", lambda block, claim, b1: _margins_kernel(X, *args, block, M, amb, claim, b1), X.shape[0],
                  program_work(X.shape[0], plan.program.ins.shape[0]))
    return M, bool(amb.any())


def run_unknowns(prog: Program, consts, X: np.ndarray):
    """(valid (N,), U (N, m)): the solved unknowns of ``task.solve`` at poses X, by the pose
    kernel reading the registers of a program built with ``unknowns=True`` in place of its
    outputs (no kernel of its own)."""
    m = len(prog.unknown_regs)
    regs = np.concatenate([prog.unknown_regs, prog.pose_regs])[:12]
    if m > 12:  # pragma: no cover - task.solve has at most 6 unknowns
        raise Unsupported(f"{m} unknowns")
    X = _readonly(np.ascontiguousarray(X, dtype=np.float64))
    N = X.shape[0]
    ok = np.empty(N, dtype=np.bool_)
    P = np.empty((N, 3))
    Rm = np.empty((N, 9))
    tr = np.zeros((0, 0), dtype=np.int64)
    Tw = np.empty((0, 0, 0))
    _timed_claims("pose", lambda block, claim, b1: _pose_kernel(X, prog.ins, consts, prog.const_base, prog.n_reg,
                                                             prog.n_pose, regs, prog.valid_regs, prog.pose_limit,
                                                             _posefn.function(prog, SUB).address, tr,
                                                             block, ok, P, Rm, Tw, claim, b1), N, program_work(N, prog.n_pose))
    return ok, np.concatenate([P, Rm], axis=1)[:, :m].copy()


def run_pose(prog: Program, consts, X: np.ndarray, twist: bool = False):
    """(valid (N,), p (N, 3), R (N, 3, 3), T (N, 6, n_task) or None)."""
    X = _readonly(np.ascontiguousarray(X, dtype=np.float64))
    N = X.shape[0]
    ok = np.empty(N, dtype=np.bool_)
    P = np.empty((N, 3))
    Rm = np.empty((N, 9))
    if twist:
        tr = prog.twist_regs
        Tw = np.empty((N, 6, prog.n_task))
        n_run = prog.n_pose
    else:
        tr = np.zeros((0, 0), dtype=np.int64)
        Tw = np.empty((0, 0, 0))
        n_run = prog.n_pose
    _timed_claims("pose", lambda block, claim, b1: _pose_kernel(X, prog.ins, consts, prog.const_base, prog.n_reg, n_run,
                                                             prog.pose_regs, prog.valid_regs, prog.pose_limit,
                                                             _posefn.function(prog, SUB).address, tr,
                                                             block, ok, P, Rm, Tw, claim, b1), N,
                  program_work(N, prog.ins.shape[0] if twist else prog.n_pose))
    return ok, P, Rm.reshape(N, 3, 3), (Tw if twist else None)


# ---------------------------------------------------------------------------------------------
# Kernels
# ---------------------------------------------------------------------------------------------
if HAVE_NUMBA:
    _jit = dict(nogil=True, error_model="numpy", fastmath=False, cache=True)
    # Helpers are ordinary calls (LLVM inlines the small ones); numba-level inlining
    # (inline="always") re-types a helper at every call site and is kept for _pose_prog and
    # _fill_consts, whose own compiled module would just repeat the interpreter's, and for the
    # helpers inside vectorised loops (_sincos, _clip01, _any), which LLVM does not always
    # inline (see docs/architecture.md).
    _jit_inline = _jit
    _jit_ir_inline = dict(_jit, inline="always")

    from llvmlite import ir as _llir
    from numba.core import cgutils as _cgutils
    from numba.core.extending import intrinsic as _intrinsic

    @_intrinsic
    def _load_acquire(typingctx, arr, idx):
        """``arr[idx]`` read with acquire ordering: read again at every call (a plain load in
        a loop would be hoisted out of it), and what the writing thread wrote before it is
        visible after it."""
        sig = _nbt.int64(arr, idx)

        def codegen(context, builder, signature, args):
            aryty = signature.args[0]
            ary = context.make_array(aryty)(context, builder, args[0])
            ptr = _cgutils.get_item_pointer(context, builder, aryty, ary, [args[1]])
            return builder.load_atomic(ptr, "acquire", align=8)

        return sig, codegen

    @_intrinsic
    def _call_loop(typingctx, addr, ptr, nb):
        """The generated pose loop at address ``addr`` (a :data:`posefn.SIG` C function, see
        :func:`posefn.function`) called on ``(ptr, nb)``. The kernels take the loop's address,
        an integer, rather than the loop as a first-class function, whose every call unboxed it
        in Python (~8 us of a kernel call's ~17 us)."""
        sig = _nbt.int64(_nbt.int64, _nbt.CPointer(_nbt.float64), _nbt.int64)

        def codegen(context, builder, signature, args):
            fnty = _llir.FunctionType(_llir.IntType(64), [_llir.DoubleType().as_pointer(), _llir.IntType(64)])
            fn = builder.inttoptr(args[0], fnty.as_pointer())
            return builder.call(fn, [args[1], args[2]])

        return sig, codegen

    @_intrinsic
    def _store_release(typingctx, arr, idx, val):
        """``arr[idx] = val`` with release ordering: what this thread wrote before is visible
        to a thread that reads it with :func:`_load_acquire`."""
        sig = _nbt.void(arr, idx, val)

        def codegen(context, builder, signature, args):
            aryty = signature.args[0]
            ary = context.make_array(aryty)(context, builder, args[0])
            ptr = _cgutils.get_item_pointer(context, builder, aryty, ary, [args[1]])
            builder.store_atomic(context.cast(builder, args[2], signature.args[2], aryty.dtype), ptr,
                                 "release", align=8)
            return context.get_dummy_value()

        return sig, codegen

    @_intrinsic
    def _swap_add(typingctx, arr, delta):
        """``arr[0] += delta`` atomically (acquire and release), its value before returned."""
        sig = _nbt.int64(arr, _nbt.int64)

        def codegen(context, builder, signature, args):
            aryty = signature.args[0]
            ary = context.make_array(aryty)(context, builder, args[0])
            ptr = _cgutils.get_item_pointer(context, builder, aryty, ary, [context.get_constant(_nbt.intp, 0)])
            return builder.atomic_rmw("add", ptr, args[1], "acq_rel")

        return sig, codegen

    @njit(**_jit_ir_inline)
    def _claim(arr):
        """The next work item of a batch shared by threads: ``arr[0]`` incremented atomically,
        its value before returned (each item goes to exactly one caller)."""
        return _swap_add(arr, 1)

    @_intrinsic
    def _data(typingctx, arr):
        """The data pointer of a C-contiguous array: what a generated pose loop is given
        (passing the array itself made the whole feasibility kernel ~13 ns a pose slower,
        docs/performance.md)."""
        sig = _nbt.CPointer(arr.dtype)(arr)

        def codegen(context, builder, signature, args):
            return context.make_array(signature.args[0])(context, builder, args[0]).data

        return sig, codegen

    @njit(**_jit)
    def _crew_spin(mail, gen, claim, max_iter, fin, last):
        """A crew thread's wait for the next batch, spinning with the interpreter lock released:
        first ``fin[last] = 1`` (the range it ran last is done; ``last`` < 0: none), then True
        once ``mail[0]`` differs from ``gen`` (a batch was posted) and, for a batch whose
        kernel claims its items from ``claim`` (``mail[1]`` set), once the posting thread has
        claimed its first item -- it is then inside its kernel and has released the lock, so
        the crew thread takes the lock without sleeping on it; False after ``max_iter`` rounds
        without a batch."""
        if last >= 0:
            _store_release(fin, last, 1)
        for _ in range(max_iter):
            if _load_acquire(mail, 0) != gen:
                if _load_acquire(mail, 1) != 0:
                    for _ in range(max_iter):
                        if _load_acquire(claim, 0) != 0:
                            break
                return True
        return False

    # -- the compiled crew: a feasibility batch handed to a spinning crew thread by pointer ----
    # The calling thread writes the kernel's arguments (data pointers, shapes, scalars) into the
    # crew's ``buf`` (_post_feasible); a crew thread spinning in _crew_serve rebuilds the arrays
    # from them and calls the feasibility kernel at its address (_call_status_at), then marks
    # its ticket done -- neither thread's hand-off goes through the interpreter. The caller posts,
    # runs its own share and waits for the crew's in one compiled call (_feasible_batch).

    @_intrinsic
    def _addr(typingctx, arr):
        """The data pointer of a C-contiguous array, as an integer."""
        sig = _nbt.int64(arr)

        def codegen(context, builder, signature, args):
            data = context.make_array(signature.args[0])(context, builder, args[0]).data
            return builder.ptrtoint(data, _llir.IntType(64))

        return sig, codegen

    @_intrinsic
    def _vptr(typingctx, addr):
        """An integer address as a ``void *``."""
        sig = _nbt.voidptr(_nbt.int64)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], _llir.IntType(8).as_pointer())

        return sig, codegen

    @_intrinsic
    def _readonly_view(typingctx, arr):
        """``arr`` typed read-only (the same array: the kernels take their poses read-only)."""
        sig = arr.copy(readonly=True)(arr)

        def codegen(context, builder, signature, args):
            return args[0]

        return sig, codegen

    @_intrinsic
    def _f8_bits(typingctx, x):
        """The bits of a float64 as an int64."""
        sig = _nbt.int64(_nbt.float64)

        def codegen(context, builder, signature, args):
            return builder.bitcast(args[0], _llir.IntType(64))

        return sig, codegen

    @_intrinsic
    def _bits_f8(typingctx, x):
        """The float64 of the bits ``x``."""
        sig = _nbt.float64(_nbt.int64)

        def codegen(context, builder, signature, args):
            return builder.bitcast(args[0], _llir.DoubleType())

        return sig, codegen

    @_intrinsic
    def _call_status_at(typingctx, addr, args):
        """The compiled function at ``addr`` (a kernel as numba compiled it, in numba's own
        calling convention: see :func:`_entry_address`) called on the tuple ``args``, which must
        be of the types it was compiled for: 0 when it returned, 1 when it failed (an
        exception, which is not raised here: the caller runs the batch again through the
        interpreter, where it is)."""
        sig = _nbt.int64(addr, args)

        def codegen(context, builder, signature, llargs):
            tys = signature.args[1].types
            vals = _cgutils.unpack_tuple(builder, llargs[1], len(tys))
            fnty = context.call_conv.get_function_type(_nbt.none, tys)
            fn = builder.inttoptr(llargs[0], fnty.as_pointer())
            status, _ = context.call_conv.call_function(builder, fn, _nbt.none, tys, vals)
            i64 = _llir.IntType(64)
            return builder.select(status.is_error, _llir.Constant(i64, 1), _llir.Constant(i64, 0))

        return sig, codegen

    # buf's layout: each array as (data pointer, its shape), each scalar as one int64 (a float by
    # its bits); then the kernel's address, the number of threads' tickets, and whether a crew
    # thread's call of the kernel failed
    _B_B1 = 63
    _B_KADDR = 64
    _B_PARTS = 65
    _B_ERR = 66
    #: Tickets of a compiled batch: the batch number above these bits, the tickets taken below.
    _TICKET_BITS = 16

    @njit(**_jit_ir_inline)
    def _put1(buf, k, a):
        buf[k] = _addr(a)
        buf[k + 1] = a.shape[0]
        return k + 2

    @njit(**_jit_ir_inline)
    def _put2(buf, k, a):
        buf[k] = _addr(a)
        buf[k + 1] = a.shape[0]
        buf[k + 2] = a.shape[1]
        return k + 3

    @njit(**_jit)
    def _post_feasible(X, ins, consts, cbase, n_reg, n_pose, pose_regs, valid_regs, plim, loop, expr, tol, leg_kind,
                       leg_act, leg_f, coord, actr, lenr, cone, rang, axang, pair, offs, block, out, amb, ext, claim,
                       b1, kaddr, parts, buf, mail, tickets):
        """Post a feasibility batch (the arguments of :func:`_feasible_kernel`) to the crew:
        its arguments into ``buf``, ``parts`` tickets of which the caller holds the first, then
        ``mail[0]`` (the batch count) raised with release ordering -- a crew thread that sees
        it sees the rest. Returns the batch's number."""
        k = _put2(buf, 0, X)
        k = _put2(buf, k, ins)
        k = _put1(buf, k, consts)
        buf[k] = cbase
        buf[k + 1] = n_reg
        buf[k + 2] = n_pose
        k = _put1(buf, k + 3, pose_regs)
        k = _put1(buf, k, valid_regs)
        k = _put1(buf, k, plim)
        buf[k] = loop
        k = _put2(buf, k + 1, expr)
        buf[k] = _f8_bits(tol)
        k = _put1(buf, k + 1, leg_kind)
        k = _put1(buf, k, leg_act)
        k = _put2(buf, k, leg_f)
        k = _put2(buf, k, coord)
        k = _put2(buf, k, actr)
        k = _put2(buf, k, lenr)
        k = _put2(buf, k, cone)
        k = _put2(buf, k, rang)
        k = _put2(buf, k, axang)
        k = _put2(buf, k, pair)
        k = _put2(buf, k, offs)
        buf[k] = block
        k = _put1(buf, k + 1, out)
        k = _put1(buf, k, amb)
        k = _put2(buf, k, ext)
        k = _put1(buf, k, claim)
        buf[_B_B1] = b1
        buf[_B_KADDR] = kaddr
        buf[_B_PARTS] = parts
        buf[_B_ERR] = 0
        g = mail[0] + 1
        _store_release(tickets, 0, (g << _TICKET_BITS) | 1)
        mail[2] = 1
        _store_release(mail, 0, g)
        return g

    @njit(**_jit)
    def _run_posted_feasible(buf):
        """The posted feasibility batch's kernel on this thread (see :func:`_post_feasible`):
        0, or 1 when the kernel failed."""
        X = _readonly_view(carray(_vptr(buf[0]), (buf[1], buf[2]), np.float64))
        ins = carray(_vptr(buf[3]), (buf[4], buf[5]), np.int64)
        consts = carray(_vptr(buf[6]), (buf[7],), np.float64)
        pose_regs = carray(_vptr(buf[11]), (buf[12],), np.int64)
        valid_regs = carray(_vptr(buf[13]), (buf[14],), np.int64)
        plim = carray(_vptr(buf[15]), (buf[16],), np.float64)
        expr = carray(_vptr(buf[18]), (buf[19], buf[20]), np.int64)
        leg_kind = carray(_vptr(buf[22]), (buf[23],), np.int64)
        leg_act = carray(_vptr(buf[24]), (buf[25],), np.int64)
        leg_f = carray(_vptr(buf[26]), (buf[27], buf[28]), np.float64)
        coord = carray(_vptr(buf[29]), (buf[30], buf[31]), np.float64)
        actr = carray(_vptr(buf[32]), (buf[33], buf[34]), np.float64)
        lenr = carray(_vptr(buf[35]), (buf[36], buf[37]), np.float64)
        cone = carray(_vptr(buf[38]), (buf[39], buf[40]), np.float64)
        rang = carray(_vptr(buf[41]), (buf[42], buf[43]), np.float64)
        axang = carray(_vptr(buf[44]), (buf[45], buf[46]), np.float64)
        pair = carray(_vptr(buf[47]), (buf[48], buf[49]), np.float64)
        offs = carray(_vptr(buf[50]), (buf[51], buf[52]), np.int64)
        out = carray(_vptr(buf[54]), (buf[55],), np.bool_)
        amb = carray(_vptr(buf[56]), (buf[57],), np.int64)
        ext = carray(_vptr(buf[58]), (buf[59], buf[60]), np.float64)
        claim = carray(_vptr(buf[61]), (buf[62],), np.int64)
        return _call_status_at(buf[_B_KADDR], (X, ins, consts, buf[8], buf[9], buf[10], pose_regs, valid_regs, plim, buf[17], expr,
                                               _bits_f8(buf[21]), leg_kind, leg_act, leg_f, coord, actr, lenr, cone,
                                               rang, axang, pair, offs, buf[53], out, amb, ext, claim, buf[_B_B1]))

    @njit(**_jit)
    def _crew_serve(mail, gen, claim, max_iter, fin, last, buf, tickets, done):
        """A crew thread's wait for the next batch, in compiled code with the interpreter lock
        released, as :func:`_crew_spin` (``fin[last] = 1`` first), serving the compiled
        feasibility batches posted meanwhile itself (``mail[2]`` set, see
        :func:`_post_feasible`): a ticket taken, the kernel run if the ticket is one of the
        batch's, the ticket marked done with the batch's number (``done[ticket]``). Returns the
        batch count of a batch for the interpreter (``mail[2]`` zero: the caller drains it),
        -1 after ``max_iter`` rounds without a batch."""
        if last >= 0:
            _store_release(fin, last, 1)
        mask = (1 << _TICKET_BITS) - 1
        idle = 0
        while idle < max_iter:
            m = _load_acquire(mail, 0)
            if m == gen:
                idle += 1
                continue
            if _load_acquire(mail, 2) == 0:
                if _load_acquire(mail, 1) != 0:
                    for _ in range(max_iter):
                        if _load_acquire(claim, 0) != 0:
                            break
                return m
            old = _swap_add(tickets, 1)
            t = old & mask
            gb = old >> _TICKET_BITS
            gen = max(m, gb)  # the tickets of batch gb are stored before its count: gb >= m
            if t < buf[_B_PARTS]:
                if _run_posted_feasible(buf) != 0:
                    buf[_B_ERR] = 1  # seen by the caller with the mark below
                _store_release(done, t, gb)
            idle = 0
        return -1

    @njit(**_jit)
    def _cancel_tickets(tickets, parts):
        """The caller, its own items done: takes every ticket no crew thread took (no thread
        will run them); returns them as a bit mask."""
        mask = (1 << _TICKET_BITS) - 1
        cancelled = 0
        while True:
            t = _swap_add(tickets, 1) & mask
            if t >= parts:
                return cancelled
            cancelled |= 1 << t

    @njit(**_jit)
    def _tickets_done(done, g, parts, cancelled, max_iter):
        """Whether every ticket 1 .. parts - 1 of batch ``g`` not in ``cancelled`` was marked done
        within ``max_iter`` rounds."""
        for t in range(1, parts):
            if cancelled & (1 << t):
                continue
            ok = False
            for _ in range(max_iter):
                if _load_acquire(done, t) == g:
                    ok = True
                    break
            if not ok:
                return False
        return True

    @njit(**_jit)
    def _feasible_batch(X, ins, consts, cbase, n_reg, n_pose, pose_regs, valid_regs, plim, loop, expr, tol, leg_kind,
                        leg_act, leg_f, coord, actr, lenr, cone, rang, axang, pair, offs, block, out, amb, ext, claim,
                        b1, kaddr, parts, buf, mail, tickets, done, max_iter, state):
        """The caller's whole part of a compiled feasibility batch on ``parts`` threads, in one
        call from the interpreter: the batch posted to the crew (:func:`_post_feasible`), the
        caller's own items run (:func:`_run_posted_feasible`, as the crew runs them), the tickets no
        crew thread took cancelled, and up to ``max_iter`` rounds of waiting for the others.
        ``state`` receives (the batch's number, the cancelled tickets, whether the crew's
        tickets are all done, whether a call of the kernel failed) -- as each becomes known, so
        an interrupt raised right after the call still finds what to wait for."""
        g = _post_feasible(X, ins, consts, cbase, n_reg, n_pose, pose_regs, valid_regs, plim, loop, expr, tol,
                           leg_kind, leg_act, leg_f, coord, actr, lenr, cone, rang, axang, pair, offs, block, out, amb,
                           ext, claim, b1, kaddr, parts, buf, mail, tickets)
        state[0] = g
        bad = _run_posted_feasible(buf)  # the caller's items, called as the crew calls them
        cancelled = _cancel_tickets(tickets, parts)
        state[1] = cancelled
        ok = _tickets_done(done, g, parts, cancelled, max_iter)
        state[2] = 1 if ok else 0
        state[3] = 1 if bad != 0 or (ok and _load_acquire(buf, _B_ERR) != 0) else 0

    @njit(**_jit)
    def _spin_done(fin, max_iter):
        """Whether every ``fin`` became non-zero within ``max_iter`` rounds (the interpreter
        lock released meanwhile)."""
        n = fin.shape[0]
        i = 0
        for _ in range(max_iter):
            while i < n and _load_acquire(fin, i) != 0:
                i += 1
            if i == n:
                return True
        return False

    # Opcodes: the one table, parasynth.engine.program.OPS (module constants, which numba
    # folds into the interpreter)
    _NOP = OPS["nop"]
    _ADD = OPS["add"]
    _SUBT = OPS["sub"]
    _MUL = OPS["mul"]
    _DIV = OPS["div"]
    _POW = OPS["pow"]
    _NEG = OPS["neg"]
    _SQRT = OPS["sqrt"]
    _TAN = OPS["tan"]
    _ASIN = OPS["asin"]
    _ACOS = OPS["acos"]
    _ATAN = OPS["atan"]
    _EXP = OPS["exp"]
    _LOG = OPS["log"]
    _ABS = OPS["abs"]
    _SINH = OPS["sinh"]
    _COSH = OPS["cosh"]
    _TANH = OPS["tanh"]
    _ATAN2 = OPS["atan2"]
    _HYPOT = OPS["hypot"]
    _MIN = OPS["min"]
    _MAX = OPS["max"]
    _LT = OPS["lt"]
    _LE = OPS["le"]
    _GT = OPS["gt"]
    _GE = OPS["ge"]
    _AND = OPS["and"]
    _SINCOS = OPS["sincos"]
    _SINCOS_ATAN2 = OPS["sincos_atan2"]
    _SIGN = OPS["sign"]
    _SELECT = OPS["select"]
    _SQUARE = OPS["square"]
    _COPY = OPS["copy"]
    _CLIP = OPS["clip"]
    _SIN1 = OPS["sin"]
    _COS1 = OPS["cos"]
    _MADD = OPS["madd"]
    _MSUB = OPS["msub"]
    _RMSUB = OPS["rmsub"]
    _MMADD = OPS["mmadd"]
    _MMSUB = OPS["mmsub"]

    # The pose travels as a tuple T = (px, py, pz, R00, R01, R02, R10, ..., R22) in the scalar
    # kernel so that it stays in registers.

    @njit(**_jit_inline)
    def _rot(T, x, y, z):
        """R @ (x, y, z)."""
        return (T[3] * x + T[4] * y + T[5] * z,
                T[6] * x + T[7] * y + T[8] * z,
                T[9] * x + T[10] * y + T[11] * z)

    @njit(**_jit_inline)
    def crank_tip(dx, dy, dz, c0x, c0y, c0z, c1x, c1y, c1z, h, L, branch):
        """(t, cos t, sin t, reachable): the crank angle t of a RUS leg whose sphere is at
        base + d, in the operations of legs.RUS.solve (``P cos t + Q sin t = K``,
        ``t = atan2(Q, P) + branch arccos(K / hypot(P, Q))`` wrapped by ``atan2(sin t, cos t)``,
        so that the wrap at +-pi falls as in NumPy); NaN when the sphere is out of the link's
        reach."""
        P = dx * c0x + dy * c0y + dz * c0z
        Q = dx * c1x + dy * c1y + dz * c1z
        K = ((dx * dx + dy * dy + dz * dz) + h * h - L * L) / (2.0 * h)
        r = K / math.hypot(P, Q)
        ok = abs(r) <= 1.0
        t = math.atan2(Q, P) + branch * (math.acos(r) if ok else np.nan)
        t = math.atan2(math.sin(t), math.cos(t))
        return t, math.cos(t), math.sin(t), ok

    @njit(**_jit_inline)
    def _leg(k, kind, leg_f, T, tol):
        """Inverse kinematics of leg k: (status, actuator, length, base joint centre (3),
        platform joint centre (3)); status 0 reachable, 1 unreachable, 2 undecidable here
        (batch-dependent RPS/RPU tolerance)."""
        rx, ry, rz = _rot(T, leg_f[k, 3], leg_f[k, 4], leg_f[k, 5])
        Ax = T[0] + rx
        Ay = T[1] + ry
        Az = T[2] + rz
        bx = leg_f[k, 0]
        by = leg_f[k, 1]
        bz = leg_f[k, 2]
        dx = Ax - bx
        dy = Ay - by
        dz = Az - bz
        if kind == 1 or kind == 4:  # PUS, PRS: slider along e through base, link of length L
            ex = leg_f[k, 6]
            ey = leg_f[k, 7]
            ez = leg_f[k, 8]
            L = leg_f[k, 18]
            de = dx * ex + dy * ey + dz * ez
            disc = L * L - ((dx * dx + dy * dy + dz * dz) - de * de)
            if not disc >= 0.0:
                return 1, 0.0, L, bx, by, bz, Ax, Ay, Az
            if kind == 4 and not abs(dx * leg_f[k, 9] + dy * leg_f[k, 10] + dz * leg_f[k, 11]) <= leg_f[k, 20]:
                return 1, 0.0, L, bx, by, bz, Ax, Ay, Az
            s = de + leg_f[k, 19] * math.sqrt(disc)
            return 0, s, L, bx + s * ex, by + s * ey, bz + s * ez, Ax, Ay, Az
        if kind == 5:  # RUS: the crank tip C, a link of length L to the sphere
            t, ct, st, ok = crank_tip(dx, dy, dz, leg_f[k, 6], leg_f[k, 7], leg_f[k, 8], leg_f[k, 9], leg_f[k, 10],
                                      leg_f[k, 11], leg_f[k, 21], leg_f[k, 18], leg_f[k, 19])
            h = leg_f[k, 21]
            return (0 if ok else 1), t, leg_f[k, 18], bx + h * (ct * leg_f[k, 6] + st * leg_f[k, 9]), \
                by + h * (ct * leg_f[k, 7] + st * leg_f[k, 10]), bz + h * (ct * leg_f[k, 8] + st * leg_f[k, 11]), Ax, Ay, Az
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        if not length > 0.0:
            return 1, length, length, bx, by, bz, Ax, Ay, Az
        if kind == 0:
            return 0, length, length, bx, by, bz, Ax, Ay, Az
        ux = leg_f[k, 6]
        uy = leg_f[k, 7]
        uz = leg_f[k, 8]
        if kind == 3:  # RPU: the platform axis must be normal to the revolute axis
            a4x, a4y, a4z = _rot(T, leg_f[k, 9], leg_f[k, 10], leg_f[k, 11])
            if not abs(a4x * ux + a4y * uy + a4z * uz) <= tol:
                return 1, length, length, bx, by, bz, Ax, Ay, Az
        off = abs(dx * ux + dy * uy + dz * uz)
        if off <= tol:
            return 0, length, length, bx, by, bz, Ax, Ay, Az
        if not off == off:
            return 1, length, length, bx, by, bz, Ax, Ay, Az
        return 2, length, length, bx, by, bz, Ax, Ay, Az

    @njit(**_jit_inline)
    def _cone_uv(k, end, leg_f, T, wx, wy, wz):
        """(u, v) whose angle is the cone angle at ``end`` (0 base, 1 platform) of leg k with
        leg vector w: base (w, base_ref); platform (-w, R @ platform_ref)."""
        if end == 0:
            return wx, wy, wz, leg_f[k, 12], leg_f[k, 13], leg_f[k, 14]
        vx, vy, vz = _rot(T, leg_f[k, 15], leg_f[k, 16], leg_f[k, 17])
        return -wx, -wy, -wz, vx, vy, vz

    @njit(**_jit_inline)
    def _clip1(c):
        """np.clip(c, -1, 1) (NaN stays NaN)."""
        if c > 1.0:
            return 1.0
        if c < -1.0:
            return -1.0
        return c

    @njit(**_jit_inline)
    def _pt_seg2(x, y, z, px, py, pz, dx, dy, dz, dd):
        """Squared distance from a point to the segment p + u d, u in [0, 1]."""
        u = 0.0
        if dd > 1e-300:
            u = min(max(((x - px) * dx + (y - py) * dy + (z - pz) * dz) / dd, 0.0), 1.0)
        cx = x - px - u * dx
        cy = y - py - u * dy
        cz = z - pz - u * dz
        return cx * cx + cy * cy + cz * cz

    @njit(**_jit_inline)
    def _parallel_seg2(p1x, p1y, p1z, d1x, d1y, d1z, a, p2x, p2y, p2z, d2x, d2y, d2z, e):
        """(Nearly) parallel segments: the closest pair involves an endpoint (as the
        endpoint candidates of spatial.segment_distance)."""
        m = _pt_seg2(p1x, p1y, p1z, p2x, p2y, p2z, d2x, d2y, d2z, e)
        m = min(m, _pt_seg2(p1x + d1x, p1y + d1y, p1z + d1z, p2x, p2y, p2z, d2x, d2y, d2z, e))
        m = min(m, _pt_seg2(p2x, p2y, p2z, p1x, p1y, p1z, d1x, d1y, d1z, a))
        m = min(m, _pt_seg2(p2x + d2x, p2y + d2y, p2z + d2z, p1x, p1y, p1z, d1x, d1y, d1z, a))
        return m

    @njit(**_jit_inline)
    def _seg_dist2(seg, i, j):
        """Squared distance between segments seg[i] and seg[j], each (start, end) -- the
        operations of spatial.segment_distance."""
        p1x = seg[i, 0]
        p1y = seg[i, 1]
        p1z = seg[i, 2]
        p2x = seg[j, 0]
        p2y = seg[j, 1]
        p2z = seg[j, 2]
        d1x = seg[i, 3] - p1x
        d1y = seg[i, 4] - p1y
        d1z = seg[i, 5] - p1z
        d2x = seg[j, 3] - p2x
        d2y = seg[j, 4] - p2y
        d2z = seg[j, 5] - p2z
        rx = p1x - p2x
        ry = p1y - p2y
        rz = p1z - p2z
        a = d1x * d1x + d1y * d1y + d1z * d1z
        e = d2x * d2x + d2y * d2y + d2z * d2z
        f = d2x * rx + d2y * ry + d2z * rz
        c = d1x * rx + d1y * ry + d1z * rz
        b = d1x * d2x + d1y * d2y + d1z * d2z
        denom = a * e - b * b
        if denom > 1e-12 * max(a * e, 1e-300):
            s = min(max((b * f - c * e) / denom, 0.0), 1.0)
        else:
            return _parallel_seg2(p1x, p1y, p1z, d1x, d1y, d1z, a, p2x, p2y, p2z, d2x, d2y, d2z, e)
        if e > 1e-300:
            t = (b * s + f) / e
        else:
            t = 0.0
        if t < 0.0:
            s = min(max(-c / a, 0.0), 1.0) if a > 1e-300 else 0.0
        elif t > 1.0:
            s = min(max((b - c) / a, 0.0), 1.0) if a > 1e-300 else 0.0
        t = min(max(t, 0.0), 1.0)
        cx = (p1x + s * d1x) - (p2x + t * d2x)
        cy = (p1y + s * d1y) - (p2y + t * d2y)
        cz = (p1z + s * d1z) - (p2z + t * d2z)
        return cx * cx + cy * cy + cz * cz


    @njit(**_jit_inline)
    def _pair_directions(pair, leg_f):
        """(n_pairs, 3): for each interference pair (legs a, b) the unit vector from leg a to
        leg b, (base b + platform anchor b) - (base a + platform anchor a) normalised (the x
        axis where that is zero or not finite): the direction the feasibility kernel projects
        the two segments on first. Any unit vector proves what it proves; this one is close
        to the legs' separating direction near the neutral pose."""
        pu = np.empty((pair.shape[0], 3))
        for q in range(pair.shape[0]):
            ka = int(pair[q, 0])
            kb = int(pair[q, 1])
            ux = (leg_f[kb, 0] + leg_f[kb, 3]) - (leg_f[ka, 0] + leg_f[ka, 3])
            uy = (leg_f[kb, 1] + leg_f[kb, 4]) - (leg_f[ka, 1] + leg_f[ka, 4])
            uz = (leg_f[kb, 2] + leg_f[kb, 5]) - (leg_f[ka, 2] + leg_f[ka, 5])
            n = math.sqrt(ux * ux + uy * uy + uz * uz)
            if n > 0.0 and n < np.inf:
                pu[q, 0] = ux / n
                pu[q, 1] = uy / n
                pu[q, 2] = uz / n
            else:
                pu[q, 0] = 1.0
                pu[q, 1] = 0.0
                pu[q, 2] = 0.0
        return pu

    @njit(**_jit_ir_inline)
    def _clip01(x):
        return min(max(x, 0.0), 1.0)

    @njit(**_jit_ir_inline)
    def _any(m, nb):
        r = False
        for ii in range(nb):
            r |= m[ii] != 0
        return r

    # the vectorisable sin/cos (Cephes) of the pose stage, in a module of its own: the generated
    # pose loops (parasynth.engine.posefn) embed its source
    from .sincos import _BIG_ANGLE, _sincos

    _DBL_MAX = float(np.finfo(np.float64).max)  # the pose limit of inf, as a finite bound

    # ------------------------------------------------------------------------------------------
    # The program interpreter: each instruction a loop over the nb lanes of a sub-block.
    # Every operand of a lane is read before its results are written (registers may be reused
    # in place); two-result instructions write the sine first, then the cosine.
    # ------------------------------------------------------------------------------------------
    @njit(**_jit)
    def _run(ins, lo, hi, Rg, Sc, nb):
        for k in range(lo, hi):
            op = ins[k, 0]
            d = ins[k, 1]
            a = ins[k, 2]
            b = ins[k, 3]
            c = ins[k, 4]
            if op == _ADD:
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii] + Rg[b, ii]
            elif op == _SUBT:
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii] - Rg[b, ii]
            elif op == _MUL:
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii] * Rg[b, ii]
            elif op == _MMADD:
                e = ins[k, 5]
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii] * Rg[b, ii] + Rg[c, ii] * Rg[e, ii]
            elif op == _MMSUB:
                e = ins[k, 5]
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii] * Rg[b, ii] - Rg[c, ii] * Rg[e, ii]
            elif op == _MADD:
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii] * Rg[b, ii] + Rg[c, ii]
            elif op == _MSUB:
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii] * Rg[b, ii] - Rg[c, ii]
            elif op == _RMSUB:
                for ii in range(nb):
                    Rg[d, ii] = Rg[c, ii] - Rg[a, ii] * Rg[b, ii]
            elif op == _DIV:
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii] / Rg[b, ii]
            elif op == _SQUARE:
                for ii in range(nb):
                    u = Rg[a, ii]
                    Rg[d, ii] = u * u
            elif op == _NEG:
                for ii in range(nb):
                    Rg[d, ii] = -Rg[a, ii]
            elif op == _SINCOS:  # (the allocator never places a result on the argument)
                big = False
                for ii in range(nb):  # into separate scratch rows, so that the loop vectorises
                    x = Rg[a, ii]
                    sv, cv = _sincos(x)
                    Sc[0, ii] = sv
                    Sc[1, ii] = cv
                    big |= abs(x) > _BIG_ANGLE
                for ii in range(nb):
                    Rg[d, ii] = Sc[0, ii]
                    Rg[b, ii] = Sc[1, ii]
                if big:
                    for ii in range(nb):
                        x = Rg[a, ii]
                        if abs(x) > _BIG_ANGLE:
                            Rg[d, ii] = math.sin(x)
                            Rg[b, ii] = math.cos(x)
            elif op == _SINCOS_ATAN2:  # sin, cos of atan2(y, x) = y / r, x / r
                bad = False
                for ii in range(nb):
                    y = Rg[a, ii]
                    x = Rg[b, ii]
                    r = math.sqrt(x * x + y * y)
                    Sc[0, ii] = y / r
                    Sc[1, ii] = x / r
                    bad |= not ((r > 0.0) & (r < np.inf))
                if bad:  # r = 0 or not finite: as sin(atan2(y, x)), cos(atan2(y, x))
                    for ii in range(nb):
                        y = Rg[a, ii]
                        x = Rg[b, ii]
                        r = math.sqrt(x * x + y * y)
                        if not ((r > 0.0) & (r < np.inf)):
                            t = math.atan2(y, x)
                            Sc[0, ii] = math.sin(t)
                            Sc[1, ii] = math.cos(t)
                for ii in range(nb):
                    Rg[d, ii] = Sc[0, ii]
                    Rg[c, ii] = Sc[1, ii]
            elif op == _SQRT:
                for ii in range(nb):
                    Rg[d, ii] = math.sqrt(Rg[a, ii])
            elif op == _POW:
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii] ** Rg[b, ii]
            elif op == _ATAN2:
                for ii in range(nb):
                    Rg[d, ii] = math.atan2(Rg[a, ii], Rg[b, ii])
            elif op == _HYPOT:
                for ii in range(nb):
                    Rg[d, ii] = math.hypot(Rg[a, ii], Rg[b, ii])
            elif op == _MIN:
                for ii in range(nb):
                    u = Rg[a, ii]
                    v = Rg[b, ii]
                    Rg[d, ii] = np.nan if (u != u or v != v) else (u if u <= v else v)
            elif op == _MAX:
                for ii in range(nb):
                    u = Rg[a, ii]
                    v = Rg[b, ii]
                    Rg[d, ii] = np.nan if (u != u or v != v) else (u if u >= v else v)
            elif op == _CLIP:  # np.clip = minimum(maximum(x, lo), hi), NaN propagating
                for ii in range(nb):
                    u = Rg[a, ii]
                    lo_ = Rg[b, ii]
                    hi_ = Rg[c, ii]
                    if u != u or lo_ != lo_ or hi_ != hi_:
                        Rg[d, ii] = np.nan
                    else:
                        u = u if u >= lo_ else lo_
                        Rg[d, ii] = u if u <= hi_ else hi_
            elif op == _LT:
                for ii in range(nb):
                    Rg[d, ii] = 1.0 if Rg[a, ii] < Rg[b, ii] else 0.0
            elif op == _LE:
                for ii in range(nb):
                    Rg[d, ii] = 1.0 if Rg[a, ii] <= Rg[b, ii] else 0.0
            elif op == _GT:
                for ii in range(nb):
                    Rg[d, ii] = 1.0 if Rg[a, ii] > Rg[b, ii] else 0.0
            elif op == _GE:
                for ii in range(nb):
                    Rg[d, ii] = 1.0 if Rg[a, ii] >= Rg[b, ii] else 0.0
            elif op == _AND:
                for ii in range(nb):
                    Rg[d, ii] = 1.0 if (Rg[a, ii] != 0.0 and Rg[b, ii] != 0.0) else 0.0
            elif op == _SELECT:  # d = cond(c) ? a : b
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii] if Rg[c, ii] != 0.0 else Rg[b, ii]
            elif op == _SIGN:
                for ii in range(nb):
                    u = Rg[a, ii]
                    Rg[d, ii] = np.nan if u != u else (1.0 if u > 0.0 else (-1.0 if u < 0.0 else 0.0))
            elif op == _ABS:
                for ii in range(nb):
                    Rg[d, ii] = abs(Rg[a, ii])
            elif op == _COPY:
                for ii in range(nb):
                    Rg[d, ii] = Rg[a, ii]
            else:
                for ii in range(nb):
                    Rg[d, ii] = _unary(op, Rg[a, ii])

    @njit(**_jit)
    def _unary(op, u):
        if op == _TAN:
            return math.tan(u)
        if op == _ASIN:
            return math.asin(u) if -1.0 <= u <= 1.0 else np.nan
        if op == _ACOS:
            return math.acos(u) if -1.0 <= u <= 1.0 else np.nan
        if op == _ATAN:
            return math.atan(u)
        if op == _EXP:
            return math.exp(u)
        if op == _LOG:
            if u > 0.0:
                return math.log(u)
            if u == 0.0:
                return -np.inf
            return np.nan
        if op == _SINH:
            return math.sinh(u)
        if op == _COSH:
            return math.cosh(u)
        if op == _TANH:
            return math.tanh(u)
        if op == _SIN1:
            return math.sin(u)
        if op == _COS1:
            return math.cos(u)
        return np.nan

    @njit(**_jit_ir_inline)
    def _fill_consts(Rg, consts, cbase):
        for j in range(consts.shape[0]):
            v = consts[j]
            for ii in range(Rg.shape[1]):
                Rg[cbase + j, ii] = v

    @njit(**_jit_ir_inline)
    def _coords_in(X, j0, nb, Rg):
        """The task coordinates of poses X[j0:j0+nb] into their registers (rows 0..n_task-1),
        through the data pointers of the (C-contiguous) poses and registers:
        ``Rg[j, ii] = X[j0 + ii, j]`` tested ``j0 + ii`` for a negative index at every element,
        a scalar loop that took ~11-14 % of the feasibility kernel's time (a perf profile of the
        worst case; 3.5 -> 1.4 ns a pose alone, docs/performance.md). (Unrolled per count of
        coordinates it took 0.7-1.1 ns, but 1.4-2.3 s more of compile for each kernel.)"""
        nt = X.shape[1]
        xp = _data(X)
        rp = _data(Rg)
        w = Rg.shape[1]
        base = j0 * nt
        for j in range(nt):
            for ii in range(nb):
                rp[j * w + ii] = xp[base + ii * nt + j]

    @njit(**_jit_ir_inline)
    def _zero_rejected(Rg, okm, nt, nb):
        """The task coordinates of the rejected lanes set to 0 (their pose is computed but not used)."""
        for j in range(nt):
            for ii in range(nb):
                Rg[j, ii] = Rg[j, ii] if okm[ii] else 0.0

    @njit(**_jit_ir_inline)
    def _pose_prog(X, j0, nb, coord, okm, Rg, Sc, Tm, ins, n_pose, pose_regs, valid_regs, plim, loop):
        """Task-coordinate ranges, finiteness, the pose part of the program and the pose's
        validity for poses X[j0:j0+nb]: okm, and Tm (12, nb) = (p, R row-major)."""
        nt = X.shape[1]
        # column by column (straight loops over the sub-block): the coordinates into their
        # registers, then finiteness and magnitude in one test (a limit of inf is taken as
        # the greatest double, so |x| <= lim is false for NaN and inf), the coordinate ranges,
        # then the coordinates of rejected poses set to 0. Loading apart from testing: the
        # strided loads alone, then a loop over the registers that vectorises (~3 ns a pose
        # less for 5 coordinates than both in one loop)
        _coords_in(X, j0, nb, Rg)
        for ii in range(nb):
            okm[ii] = 1
        for j in range(nt):
            lim = min(plim[j], _DBL_MAX)
            for ii in range(nb):
                okm[ii] = okm[ii] & (abs(Rg[j, ii]) <= lim)
        for q in range(coord.shape[0]):
            c = int(coord[q, 0])
            lo = coord[q, 1]
            hi = coord[q, 2]
            for ii in range(nb):
                x = Rg[c, ii]
                okm[ii] = okm[ii] & (x - lo >= 0.0) & (hi - x >= 0.0)
        rejected = False
        for ii in range(nb):
            rejected |= okm[ii] == 0
        if rejected:
            _zero_rejected(Rg, okm, nt, nb)
        # the pose part: the program's generated loop (parasynth.engine.posefn) if it has one,
        # else (or for a sub-block with a lane the loop leaves to libm) the interpreter
        st = _call_loop(loop, _data(Rg), nb)
        if st != 0:
            if st > 0:  # the loop ran: the coordinates again (it may have reused their rows)
                _coords_in(X, j0, nb, Rg)
                if rejected:
                    _zero_rejected(Rg, okm, nt, nb)
            _run(ins, np.int64(0), n_pose, Rg, Sc, nb)  # (not a literal: one specialisation)
        for q in range(valid_regs.shape[0]):
            r = valid_regs[q]
            for ii in range(nb):
                okm[ii] = okm[ii] & (Rg[r, ii] != 0.0)
        for j in range(12):
            r = pose_regs[j]
            for ii in range(nb):
                t = Rg[r, ii]
                Tm[j, ii] = t
                okm[ii] = okm[ii] & (abs(t) < np.inf)

    @njit(**_jit)
    def _pose_kernel(X, ins, consts, cbase, n_reg, n_run, pose_regs, valid_regs, plim, loop, twist_regs, block, ok, P, Rm,
                     Tw, claim, b1):
        """Validity, positions, rotations (row-major) and, if twist_regs is not empty, the
        twist map of poses X: the program alone. Blocks claimed from ``claim`` (see
        :func:`_timed_claims`) until ``b1``."""
        N = X.shape[0]
        coord = np.zeros((0, 4))
        n_pose = n_run
        # the scratch once a call, not once a claimed block (9 allocations ~2 us)
        Rg = np.empty((n_reg, SUB))
        _fill_consts(Rg, consts, cbase)
        Sc = np.empty((2, SUB))
        Tm = np.empty((12, SUB))
        okm = np.empty(SUB, dtype=np.uint8)
        while True:
            blk = _claim(claim)
            if blk >= b1:
                break
            i1 = min(N, (blk + 1) * block)
            for j0 in range(blk * block, i1, SUB):
                nb = min(SUB, i1 - j0)
                _pose_prog(X, j0, nb, coord, okm, Rg, Sc, Tm, ins, n_pose, pose_regs, valid_regs, plim, loop)
                if twist_regs.shape[0] > 0:
                    _run(ins, n_pose, ins.shape[0], Rg, Sc, nb)
                for ii in range(nb):
                    i = j0 + ii
                    ok[i] = okm[ii] != 0
                    for j in range(3):
                        P[i, j] = Tm[j, ii]
                    for j in range(9):
                        Rm[i, j] = Tm[3 + j, ii]
                    for r in range(twist_regs.shape[0]):
                        for j in range(twist_regs.shape[1]):
                            Tw[i, r, j] = Rg[twist_regs[r, j], ii]

    @njit(**_jit)
    def _feasible_kernel(X, ins, consts, cbase, n_reg, n_pose, pose_regs, valid_regs, plim, loop, expr, tol, leg_kind,
                         leg_act,
                         leg_f, coord, actr, lenr, cone, rang, axang, pair, offs, block, out, amb, ext, claim, b1):
        """Boolean feasibility of poses X (N, n_task) -> out (N,), amb[block] = number of
        poses whose RPS/RPU reachability NumPy decides batch-dependently; if ``ext`` has rows,
        ext[block] = (least x, y, z, greatest x, y, z) of the feasible poses' platform position.

        Work items (prange) are blocks of ``block`` poses, processed in sub-blocks of SUB
        poses laid out structure-of-arrays: the pose (_pose_block), then leg by leg and check
        by check a straight loop over the sub-block that the compiler vectorises (the leg
        geometry and limits are loop invariants). A sub-block stops as soon as none of its
        poses is feasible; interference, the most expensive check, comes last (see the
        module docstring)."""
        N = X.shape[0]
        nl = leg_kind.shape[0]
        # the scratch once a call, not once a claimed block (the registers' constant rows are
        # never written by the program)
        Tm = np.empty((12, SUB))
        Rg = np.empty((n_reg, SUB))
        _fill_consts(Rg, consts, cbase)
        Sc = np.empty((2, SUB))
        okm = np.empty(SUB, dtype=np.uint8)
        und = np.empty(SUB, dtype=np.uint8)
        pend = np.empty(SUB, dtype=np.uint8)
        lane = np.empty(SUB, dtype=np.int64)
        Sg = np.empty((nl, 6, SUB))
        Q = np.empty((nl, SUB))
        pu = _pair_directions(pair, leg_f)
        outv = out.view(np.uint8)  # okm's 0/1 bytes are the booleans
        while True:
            blk = _claim(claim)
            if blk >= b1:
                break
            n_amb = 0
            i1 = min(N, (blk + 1) * block)
            for j0 in range(blk * block, i1, SUB):
                nb = min(SUB, i1 - j0)
                nb0 = nb
                # 1. task-coordinate ranges and the pose (the program's pose part)
                _pose_prog(X, j0, nb, coord, okm, Rg, Sc, Tm, ins, n_pose, pose_regs, valid_regs, plim, loop)
                for ii in range(nb):
                    und[ii] = 0
                    lane[ii] = ii
                # 2. leg by leg: inverse kinematics, then that leg's checks
                for k in range(nl):
                    # Compaction: when at most half of the lanes are still feasible, the
                    # feasible ones are moved to the front (their pose, the legs solved so
                    # far, the registers if expression margins follow) and the next stages
                    # run on them alone; lane[] keeps each one's pose. Every lane is
                    # computed alone, so the answers do not change.
                    cnt = 0
                    for ii in range(nb):
                        cnt += okm[ii]
                    if cnt == 0:
                        break
                    if 2 * cnt <= nb:
                        w = 0
                        for ii in range(nb):
                            if okm[ii] != 0:
                                lane[w] = lane[ii]
                                und[w] = und[ii]
                                okm[w] = 1
                                for r in range(12):
                                    Tm[r, w] = Tm[r, ii]
                                for kk in range(k):
                                    Q[kk, w] = Q[kk, ii]
                                    for r in range(6):
                                        Sg[kk, r, w] = Sg[kk, r, ii]
                                if expr.shape[0] > 0:
                                    for r in range(Rg.shape[0]):
                                        Rg[r, w] = Rg[r, ii]
                                w += 1
                        nb = w
                    kind = leg_kind[k]
                    a0 = leg_f[k, 3]
                    a1 = leg_f[k, 4]
                    a2 = leg_f[k, 5]
                    bx = leg_f[k, 0]
                    by = leg_f[k, 1]
                    bz = leg_f[k, 2]
                    ex = leg_f[k, 6]
                    ey = leg_f[k, 7]
                    ez = leg_f[k, 8]
                    if kind == 1 or kind == 4:  # PUS, PRS: slider along e through base, link L
                        L = leg_f[k, 18]
                        br = leg_f[k, 19]
                        is_prs = kind == 4
                        r0_ = leg_f[k, 9]
                        r1_ = leg_f[k, 10]
                        r2_ = leg_f[k, 11]
                        ptol = leg_f[k, 20]
                        for ii in range(nb):
                            Sx = Tm[0, ii] + (Tm[3, ii] * a0 + Tm[4, ii] * a1 + Tm[5, ii] * a2)
                            Sy = Tm[1, ii] + (Tm[6, ii] * a0 + Tm[7, ii] * a1 + Tm[8, ii] * a2)
                            Sz = Tm[2, ii] + (Tm[9, ii] * a0 + Tm[10, ii] * a1 + Tm[11, ii] * a2)
                            dx = Sx - bx
                            dy = Sy - by
                            dz = Sz - bz
                            de = dx * ex + dy * ey + dz * ez
                            disc = L * L - ((dx * dx + dy * dy + dz * dz) - de * de)
                            s = de + br * math.sqrt(disc)
                            off_ok = abs(dx * r0_ + dy * r1_ + dz * r2_) <= ptol
                            okm[ii] = okm[ii] & (disc >= 0.0) & (off_ok | (not is_prs))
                            Q[k, ii] = s
                            Sg[k, 0, ii] = bx + s * ex
                            Sg[k, 1, ii] = by + s * ey
                            Sg[k, 2, ii] = bz + s * ez
                            Sg[k, 3, ii] = Sx
                            Sg[k, 4, ii] = Sy
                            Sg[k, 5, ii] = Sz
                    elif kind == 5:  # RUS: crank tip C = base + h (cos t c0 + sin t c1), link L to S
                        h = leg_f[k, 21]
                        L = leg_f[k, 18]
                        br = leg_f[k, 19]
                        f0 = leg_f[k, 9]
                        f1 = leg_f[k, 10]
                        f2 = leg_f[k, 11]
                        for ii in range(nb):
                            Sx = Tm[0, ii] + (Tm[3, ii] * a0 + Tm[4, ii] * a1 + Tm[5, ii] * a2)
                            Sy = Tm[1, ii] + (Tm[6, ii] * a0 + Tm[7, ii] * a1 + Tm[8, ii] * a2)
                            Sz = Tm[2, ii] + (Tm[9, ii] * a0 + Tm[10, ii] * a1 + Tm[11, ii] * a2)
                            t, ct, st, ok = crank_tip(Sx - bx, Sy - by, Sz - bz, ex, ey, ez, f0, f1, f2, h, L, br)
                            okm[ii] = okm[ii] & ok
                            Q[k, ii] = t
                            Sg[k, 0, ii] = bx + h * (ct * ex + st * f0)
                            Sg[k, 1, ii] = by + h * (ct * ey + st * f1)
                            Sg[k, 2, ii] = bz + h * (ct * ez + st * f2)
                            Sg[k, 3, ii] = Sx
                            Sg[k, 4, ii] = Sy
                            Sg[k, 5, ii] = Sz
                    else:  # fixed base joint: SPS, UPS, UPU, RPS, RPU
                        for ii in range(nb):
                            Ax = Tm[0, ii] + (Tm[3, ii] * a0 + Tm[4, ii] * a1 + Tm[5, ii] * a2)
                            Ay = Tm[1, ii] + (Tm[6, ii] * a0 + Tm[7, ii] * a1 + Tm[8, ii] * a2)
                            Az = Tm[2, ii] + (Tm[9, ii] * a0 + Tm[10, ii] * a1 + Tm[11, ii] * a2)
                            dx = Ax - bx
                            dy = Ay - by
                            dz = Az - bz
                            length = math.sqrt(dx * dx + dy * dy + dz * dz)
                            okm[ii] = okm[ii] & (length > 0.0)
                            Q[k, ii] = length
                            Sg[k, 0, ii] = bx
                            Sg[k, 1, ii] = by
                            Sg[k, 2, ii] = bz
                            Sg[k, 3, ii] = Ax
                            Sg[k, 4, ii] = Ay
                            Sg[k, 5, ii] = Az
                        if kind == 2 or kind == 3:  # planar leg: off-plane error, axis r = e
                            is_rpu = kind == 3
                            u0 = leg_f[k, 9]
                            u1 = leg_f[k, 10]
                            u2 = leg_f[k, 11]
                            for ii in range(nb):
                                off = abs((Sg[k, 3, ii] - bx) * ex + (Sg[k, 4, ii] - by) * ey
                                          + (Sg[k, 5, ii] - bz) * ez)
                                a4x = Tm[3, ii] * u0 + Tm[4, ii] * u1 + Tm[5, ii] * u2
                                a4y = Tm[6, ii] * u0 + Tm[7, ii] * u1 + Tm[8, ii] * u2
                                a4z = Tm[9, ii] * u0 + Tm[10, ii] * u1 + Tm[11, ii] * u2
                                skew_ok = abs(a4x * ex + a4y * ey + a4z * ez) <= tol
                                okm[ii] = okm[ii] & (off == off) & (skew_ok | (not is_rpu))
                                und[ii] = und[ii] | (off > tol)
                    # actuator ranges
                    if leg_act[k] == 1:
                        for q in range(actr.shape[0]):
                            lo = actr[q, 0]
                            hi = actr[q, 1]
                            for ii in range(nb):
                                okm[ii] = okm[ii] & (Q[k, ii] - lo >= 0.0) & (hi - Q[k, ii] >= 0.0)
                    # passive leg length ranges (length = actuator value for non-PUS legs)
                    for q in range(offs[0, k], offs[0, k + 1]):
                        lo = lenr[q, 1]
                        hi = lenr[q, 2]
                        if kind == 1 or kind >= 4:  # a link of fixed length
                            L = leg_f[k, 18]
                            ok_l = L - lo >= 0.0 and hi - L >= 0.0
                            if not ok_l:
                                for ii in range(nb):
                                    okm[ii] = 0
                        else:
                            for ii in range(nb):
                                okm[ii] = okm[ii] & (Q[k, ii] - lo >= 0.0) & (hi - Q[k, ii] >= 0.0)
                    # joint cone angles lo <= angle(u, v) <= hi, without arctan2 or sqrt:
                    # angle <= hi iff sin(hi) (u.v) - cos(hi) |u x v| >= 0 for hi in (0, pi),
                    # tested on squares with the signs handled (modes from _angle_modes)
                    for q in range(offs[1, k], offs[1, k + 1]):
                        end = int(cone[q, 1])
                        lo_mode = int(cone[q, 5])
                        hi_mode = int(cone[q, 6])
                        l1 = lo_mode == 1
                        l2 = lo_mode == 2
                        h0 = hi_mode == 0
                        h1 = hi_mode == 1
                        h2 = hi_mode == 2
                        sl2 = cone[q, 7]
                        cl2 = cone[q, 8]
                        sh2 = cone[q, 9]
                        ch2 = cone[q, 10]
                        q0 = leg_f[k, 12]
                        q1 = leg_f[k, 13]
                        q2 = leg_f[k, 14]
                        r0 = leg_f[k, 15]
                        r1 = leg_f[k, 16]
                        r2 = leg_f[k, 17]
                        plat = end == 1
                        sgn = -1.0 if plat else 1.0
                        if lo_mode == 0 and hi_mode == 1:  # the usual cone: hi < pi/2, no lower limit
                            # |w x v|^2 as |w|^2 - (w.v)^2 (v a unit vector: the reference
                            # directions are normalised, R orthonormal; at the limit the
                            # difference is ~3 eps / sin^2(hi) relative), and the platform's
                            # -w by the sign of the dot product: ~11 operations a pose less
                            if plat:
                                for ii in range(nb):
                                    wx = Sg[k, 3, ii] - Sg[k, 0, ii]
                                    wy = Sg[k, 4, ii] - Sg[k, 1, ii]
                                    wz = Sg[k, 5, ii] - Sg[k, 2, ii]
                                    vx = Tm[3, ii] * r0 + Tm[4, ii] * r1 + Tm[5, ii] * r2
                                    vy = Tm[6, ii] * r0 + Tm[7, ii] * r1 + Tm[8, ii] * r2
                                    vz = Tm[9, ii] * r0 + Tm[10, ii] * r1 + Tm[11, ii] * r2
                                    dp = wx * vx + wy * vy + wz * vz  # (-w).v = -dp
                                    d2 = dp * dp
                                    cr2 = (wx * wx + wy * wy + wz * wz) - d2
                                    okm[ii] = okm[ii] & (dp <= 0.0) & (sh2 * d2 >= ch2 * cr2)
                            else:
                                for ii in range(nb):
                                    wx = Sg[k, 3, ii] - Sg[k, 0, ii]
                                    wy = Sg[k, 4, ii] - Sg[k, 1, ii]
                                    wz = Sg[k, 5, ii] - Sg[k, 2, ii]
                                    dot = wx * q0 + wy * q1 + wz * q2
                                    d2 = dot * dot
                                    cr2 = (wx * wx + wy * wy + wz * wz) - d2
                                    okm[ii] = okm[ii] & (dot >= 0.0) & (sh2 * d2 >= ch2 * cr2)
                            continue
                        for ii in range(nb):
                            wx = sgn * (Sg[k, 3, ii] - Sg[k, 0, ii])
                            wy = sgn * (Sg[k, 4, ii] - Sg[k, 1, ii])
                            wz = sgn * (Sg[k, 5, ii] - Sg[k, 2, ii])
                            if plat:
                                vx = Tm[3, ii] * r0 + Tm[4, ii] * r1 + Tm[5, ii] * r2
                                vy = Tm[6, ii] * r0 + Tm[7, ii] * r1 + Tm[8, ii] * r2
                                vz = Tm[9, ii] * r0 + Tm[10, ii] * r1 + Tm[11, ii] * r2
                            else:
                                vx = q0
                                vy = q1
                                vz = q2
                            dot = wx * vx + wy * vy + wz * vz
                            cx = wy * vz - wz * vy
                            cy = wz * vx - wx * vz
                            cz = wx * vy - wy * vx
                            cr2 = cx * cx + cy * cy + cz * cz
                            d2 = dot * dot
                            ok_hi = h0 | (h1 & (dot >= 0.0) & (sh2 * d2 >= ch2 * cr2)) | (
                                h2 & ((dot >= 0.0) | (ch2 * cr2 >= sh2 * d2)))
                            ok_lo = (not (l1 or l2)) | (l1 & ((dot <= 0.0) | (cl2 * cr2 >= sl2 * d2))) | (
                                l2 & (dot <= 0.0) & (sl2 * d2 >= cl2 * cr2))
                            okm[ii] = okm[ii] & ok_hi & ok_lo
                    # leg axis against a base or platform axis: arccos(n.a) <= hi as n.a >= cos(hi)
                    for q in range(offs[3, k], offs[3, k + 1]):
                        ax = axang[q, 1]
                        ay = axang[q, 2]
                        az = axang[q, 3]
                        in_plat = axang[q, 4] == 1.0
                        ch = axang[q, 7]
                        for ii in range(nb):
                            if in_plat:
                                vx = Tm[3, ii] * ax + Tm[4, ii] * ay + Tm[5, ii] * az
                                vy = Tm[6, ii] * ax + Tm[7, ii] * ay + Tm[8, ii] * az
                                vz = Tm[9, ii] * ax + Tm[10, ii] * ay + Tm[11, ii] * az
                            else:
                                vx = ax
                                vy = ay
                                vz = az
                            wx = Sg[k, 3, ii] - Sg[k, 0, ii]
                            wy = Sg[k, 4, ii] - Sg[k, 1, ii]
                            wz = Sg[k, 5, ii] - Sg[k, 2, ii]
                            ln = leg_f[k, 18] if (kind == 1 or kind >= 4) else Q[k, ii]
                            okm[ii] = okm[ii] & (wx * vx + wy * vy + wz * vz >= ch * ln)
                    # signed revolute angle (atan2: not vectorised)
                    for q in range(offs[2, k], offs[2, k + 1]):
                        for ii in range(nb):
                            if okm[ii]:
                                wx = Sg[k, 3, ii] - Sg[k, 0, ii]
                                wy = Sg[k, 4, ii] - Sg[k, 1, ii]
                                wz = Sg[k, 5, ii] - Sg[k, 2, ii]
                                ang = math.atan2(wx * rang[q, 4] + wy * rang[q, 5] + wz * rang[q, 6],
                                                 wx * rang[q, 1] + wy * rang[q, 2] + wz * rang[q, 3])
                                okm[ii] = (ang - rang[q, 7] >= 0.0) and (rang[q, 8] - ang >= 0.0)
                # 3. expression margins (the rest of the program), >= 0 (NaN fails)
                if expr.shape[0] > 0 and _any(okm, nb):
                    _run(ins, n_pose, ins.shape[0], Rg, Sc, nb)
                    for q in range(expr.shape[0]):
                        r = expr[q, 0]
                        for ii in range(nb):
                            okm[ii] = okm[ii] & (Rg[r, ii] >= 0.0)
                # 4. leg interference, last: segment-segment distance (spatial.segment_distance,
                # branch-free) compared squared
                for q in range(pair.shape[0]):
                    if not _any(okm, nb):
                        break
                    ka = int(pair[q, 0])
                    kb = int(pair[q, 1])
                    Dq = pair[q, 2]
                    D2 = pair[q, 4]
                    # The two segments projected on the pair's direction (pu, a unit vector):
                    # intervals more than D apart (by a relative 1e-9: the projections are
                    # rounded) prove the distance >= D; only if some feasible pose of the
                    # sub-block is not settled so (NaN included) is more computed. One
                    # direction chosen for the pair settles what the three axes' bounding
                    # boxes did and more, in half their operations (docs/performance.md).
                    ux = pu[q, 0]
                    uy = pu[q, 1]
                    uz = pu[q, 2]
                    thr = Dq * (1.0 + 1e-9) if Dq > 0.0 else Dq
                    need = 0
                    for ii in range(nb):
                        a0 = Sg[ka, 0, ii] * ux + Sg[ka, 1, ii] * uy + Sg[ka, 2, ii] * uz
                        a1 = Sg[ka, 3, ii] * ux + Sg[ka, 4, ii] * uy + Sg[ka, 5, ii] * uz
                        b0 = Sg[kb, 0, ii] * ux + Sg[kb, 1, ii] * uy + Sg[kb, 2, ii] * uz
                        b1_ = Sg[kb, 3, ii] * ux + Sg[kb, 4, ii] * uy + Sg[kb, 5, ii] * uz
                        a_lo = a0 if a0 < a1 else a1
                        a_hi = a1 if a0 < a1 else a0
                        b_lo = b0 if b0 < b1_ else b1_
                        b_hi = b1_ if b0 < b1_ else b0
                        g1 = b_lo - a_hi
                        g2 = a_lo - b_hi
                        g = g1 if g1 > g2 else g2
                        pend[ii] = okm[ii] & (not (g >= thr))
                        need |= pend[ii]
                    if not need:
                        continue
                    # The distance of the two lines bounds the segments' from below too: a
                    # pose whose lines are clearly (by a relative 1e-9) at least D apart, and
                    # not nearly parallel (|d1 x d2|^2 > 1e-6 |d1|^2 |d2|^2, so that the cross
                    # product is accurate), is settled without the segment distance. Where
                    # the boxes overlap, the legs are often skew and far apart along their
                    # common normal (a third of the work of the segment distance, no division).
                    need = 0
                    for ii in range(nb):
                        d1x = Sg[ka, 3, ii] - Sg[ka, 0, ii]
                        d1y = Sg[ka, 4, ii] - Sg[ka, 1, ii]
                        d1z = Sg[ka, 5, ii] - Sg[ka, 2, ii]
                        d2x = Sg[kb, 3, ii] - Sg[kb, 0, ii]
                        d2y = Sg[kb, 4, ii] - Sg[kb, 1, ii]
                        d2z = Sg[kb, 5, ii] - Sg[kb, 2, ii]
                        rx = Sg[ka, 0, ii] - Sg[kb, 0, ii]
                        ry = Sg[ka, 1, ii] - Sg[kb, 1, ii]
                        rz = Sg[ka, 2, ii] - Sg[kb, 2, ii]
                        cx = d1y * d2z - d1z * d2y
                        cy = d1z * d2x - d1x * d2z
                        cz = d1x * d2y - d1y * d2x
                        cc = cx * cx + cy * cy + cz * cz
                        aa = d1x * d1x + d1y * d1y + d1z * d1z
                        ee = d2x * d2x + d2y * d2y + d2z * d2z
                        rc = rx * cx + ry * cy + rz * cz
                        apart = (cc > 1e-6 * (aa * ee)) & (rc * rc > D2 * cc * (1.0 + 1e-9))
                        pend[ii] = pend[ii] & (not apart)
                        need |= pend[ii]
                    if not need:
                        continue
                    # two passes: the general case branch-free for the whole sub-block (SIMD;
                    # the selects discard what a (nearly) parallel pair computes), then the
                    # (nearly) parallel pairs, if any, one by one
                    par = False
                    for ii in range(nb):
                        p1x = Sg[ka, 0, ii]
                        p1y = Sg[ka, 1, ii]
                        p1z = Sg[ka, 2, ii]
                        p2x = Sg[kb, 0, ii]
                        p2y = Sg[kb, 1, ii]
                        p2z = Sg[kb, 2, ii]
                        d1x = Sg[ka, 3, ii] - p1x
                        d1y = Sg[ka, 4, ii] - p1y
                        d1z = Sg[ka, 5, ii] - p1z
                        d2x = Sg[kb, 3, ii] - p2x
                        d2y = Sg[kb, 4, ii] - p2y
                        d2z = Sg[kb, 5, ii] - p2z
                        rx = p1x - p2x
                        ry = p1y - p2y
                        rz = p1z - p2z
                        a = d1x * d1x + d1y * d1y + d1z * d1z
                        e = d2x * d2x + d2y * d2y + d2z * d2z
                        f = d2x * rx + d2y * ry + d2z * rz
                        c = d1x * rx + d1y * ry + d1z * rz
                        b = d1x * d2x + d1y * d2y + d1z * d2z
                        denom = a * e - b * b
                        ae = a * e
                        general = denom > 1e-12 * (ae if ae > 1e-300 else 1e-300)
                        s = _clip01((b * f - c * e) / denom)
                        t = (b * s + f) / e
                        t = t if e > 1e-300 else 0.0
                        s_lo = _clip01(-c / a)
                        s_lo = s_lo if a > 1e-300 else 0.0
                        s_hi = _clip01((b - c) / a)
                        s_hi = s_hi if a > 1e-300 else 0.0
                        s = s_lo if t < 0.0 else (s_hi if t > 1.0 else s)
                        t = _clip01(t)
                        cx = (p1x + s * d1x) - (p2x + t * d2x)
                        cy = (p1y + s * d1y) - (p2y + t * d2y)
                        cz = (p1z + s * d1z) - (p2z + t * d2z)
                        dist2 = cx * cx + cy * cy + cz * cz
                        okm[ii] = okm[ii] & ((dist2 >= D2) | (not general))
                        par |= not general
                    if par:
                        for ii in range(nb):
                            p1x = Sg[ka, 0, ii]
                            p1y = Sg[ka, 1, ii]
                            p1z = Sg[ka, 2, ii]
                            p2x = Sg[kb, 0, ii]
                            p2y = Sg[kb, 1, ii]
                            p2z = Sg[kb, 2, ii]
                            d1x = Sg[ka, 3, ii] - p1x
                            d1y = Sg[ka, 4, ii] - p1y
                            d1z = Sg[ka, 5, ii] - p1z
                            d2x = Sg[kb, 3, ii] - p2x
                            d2y = Sg[kb, 4, ii] - p2y
                            d2z = Sg[kb, 5, ii] - p2z
                            a = d1x * d1x + d1y * d1y + d1z * d1z
                            e = d2x * d2x + d2y * d2y + d2z * d2z
                            b = d1x * d2x + d1y * d2y + d1z * d2z
                            denom = a * e - b * b
                            if not denom > 1e-12 * max(a * e, 1e-300):
                                dist2 = _parallel_seg2(p1x, p1y, p1z, d1x, d1y, d1z, a, p2x, p2y, p2z, d2x, d2y,
                                                       d2z, e)
                                okm[ii] = okm[ii] & (dist2 >= D2)
                # the answers through the output's data pointer (no negative-index tests);
                # a sub-block not compacted (lane[ii] == ii) as one straight loop
                op = _data(outv)
                if nb < nb0:  # compacted: lanes not listed are infeasible
                    for ii in range(nb0):
                        op[j0 + ii] = 0
                    for ii in range(nb):
                        op[j0 + lane[ii]] = okm[ii]
                else:
                    for ii in range(nb):
                        op[j0 + ii] = okm[ii]
                for ii in range(nb):
                    n_amb += okm[ii] & und[ii]
                if ext.shape[0] > 0:
                    for c in range(3):
                        lo = ext[blk, c]
                        hi = ext[blk, 3 + c]
                        for ii in range(nb):
                            v = Tm[c, ii]
                            f = okm[ii] != 0
                            lo = v if (f and v < lo) else lo
                            hi = v if (f and v > hi) else hi
                        ext[blk, c] = lo
                        ext[blk, 3 + c] = hi
            amb[blk] = n_amb

    @njit(**_jit_inline)
    def _nmin(a, b):
        """np.minimum for scalars (NaN propagates)."""
        if a != a or b != b:
            return np.nan
        return a if a <= b else b

    @njit(**_jit_inline)
    def _upd(M, i, ci, m):
        """M[i, ci] = np.minimum(M[i, ci], m)."""
        if m < M[i, ci] or m != m:
            M[i, ci] = m

    @njit(**_jit)
    def _margins_kernel(X, ins, consts, cbase, n_reg, n_pose, pose_regs, valid_regs, plim, loop, expr, tol, leg_kind,
                        leg_act,
                        leg_f, coord, actr, lenr, cone, rang, axang, pair, offs, block, M, amb, claim, b1):
        """All constraint margins with NumPy's formulas (arctan2, arccos, sqrt), no early
        exit -- Mechanism.constraint_margins. The program runs per sub-block; the rest per
        pose."""
        N = X.shape[0]
        nl = leg_kind.shape[0]
        nc = M.shape[1]
        nocoord = np.zeros((0, 4))
        seg = np.empty((nl, 6))
        lens = np.empty(nl)
        qv = np.empty(nl)
        nvec = np.empty((nl, 3))
        Rg = np.empty((n_reg, SUB))
        _fill_consts(Rg, consts, cbase)
        Sc = np.empty((2, SUB))
        Tm = np.empty((12, SUB))
        okm = np.empty(SUB, dtype=np.uint8)
        while True:
            blk = _claim(claim)
            if blk >= b1:
                break
            n_amb = 0
            i1 = min(N, (blk + 1) * block)
            for j0 in range(blk * block, i1, SUB):
              nb = min(SUB, i1 - j0)
              _pose_prog(X, j0, nb, nocoord, okm, Rg, Sc, Tm, ins, n_pose, pose_regs, valid_regs, plim, loop)
              _run(ins, n_pose, ins.shape[0], Rg, Sc, nb)
              for ii in range(nb):
                i = j0 + ii
                reach = okm[ii] != 0
                T = (Tm[0, ii], Tm[1, ii], Tm[2, ii], Tm[3, ii], Tm[4, ii], Tm[5, ii], Tm[6, ii], Tm[7, ii],
                     Tm[8, ii], Tm[9, ii], Tm[10, ii], Tm[11, ii])
                undecided = False
                if reach:
                    for k in range(nl):
                        st, q_act, length, ux, uy, uz, ax_, ay_, az_ = _leg(k, leg_kind[k], leg_f, T, tol)
                        if st == 1:
                            reach = False
                            break
                        if st == 2:
                            undecided = True
                        lens[k] = length
                        qv[k] = q_act
                        seg[k, 0] = ux
                        seg[k, 1] = uy
                        seg[k, 2] = uz
                        seg[k, 3] = ax_
                        seg[k, 4] = ay_
                        seg[k, 5] = az_
                        # unit leg direction as the legs compute it
                        wx = ax_ - ux
                        wy = ay_ - uy
                        wz = az_ - uz
                        if leg_kind[k] != 1 and leg_kind[k] < 4:  # not a link of fixed length
                            length = math.sqrt(wx * wx + wy * wy + wz * wz)
                        nvec[k, 0] = wx / length
                        nvec[k, 1] = wy / length
                        nvec[k, 2] = wz / length
                if not reach:
                    for j in range(nc):
                        M[i, j] = -np.inf
                    continue
                if undecided:
                    n_amb += 1
                for j in range(nc):
                    M[i, j] = np.inf
                for q in range(coord.shape[0]):
                    x = X[i, int(coord[q, 0])]
                    _upd(M, i, int(coord[q, 3]), _nmin(x - coord[q, 1], coord[q, 2] - x))
                for k in range(nl):
                    if leg_act[k] == 1:
                        for q in range(actr.shape[0]):
                            _upd(M, i, int(actr[q, 2]), _nmin(qv[k] - actr[q, 0], actr[q, 1] - qv[k]))
                for q in range(lenr.shape[0]):
                    ln = lens[int(lenr[q, 0])]
                    _upd(M, i, int(lenr[q, 3]), _nmin(ln - lenr[q, 1], lenr[q, 2] - ln))
                for q in range(cone.shape[0]):
                    k = int(cone[q, 0])
                    u0, u1, u2, v0, v1, v2 = _cone_uv(k, int(cone[q, 1]), leg_f, T, nvec[k, 0], nvec[k, 1], nvec[k, 2])
                    cx = u1 * v2 - u2 * v1
                    cy = u2 * v0 - u0 * v2
                    cz = u0 * v1 - u1 * v0
                    ang = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), u0 * v0 + u1 * v1 + u2 * v2)
                    _upd(M, i, int(cone[q, 4]), _nmin(ang - cone[q, 2], cone[q, 3] - ang))
                for q in range(rang.shape[0]):
                    k = int(rang[q, 0])
                    ang = math.atan2(nvec[k, 0] * rang[q, 4] + nvec[k, 1] * rang[q, 5] + nvec[k, 2] * rang[q, 6],
                                     nvec[k, 0] * rang[q, 1] + nvec[k, 1] * rang[q, 2] + nvec[k, 2] * rang[q, 3])
                    _upd(M, i, int(rang[q, 9]), _nmin(ang - rang[q, 7], rang[q, 8] - ang))
                for q in range(axang.shape[0]):
                    k = int(axang[q, 0])
                    if axang[q, 4] == 1.0:
                        bx, by, bz = _rot(T, axang[q, 1], axang[q, 2], axang[q, 3])
                    else:
                        bx = axang[q, 1]
                        by = axang[q, 2]
                        bz = axang[q, 3]
                    c = nvec[k, 0] * bx + nvec[k, 1] * by + nvec[k, 2] * bz
                    _upd(M, i, int(axang[q, 6]), axang[q, 5] - math.acos(_clip1(c)))
                for q in range(expr.shape[0]):
                    _upd(M, i, expr[q, 1], Rg[expr[q, 0], ii])
                # interference: min distance over the pairs, minus the diameter
                for q in range(pair.shape[0]):
                    d = math.sqrt(_seg_dist2(seg, int(pair[q, 0]), int(pair[q, 1])))
                    _upd(M, i, int(pair[q, 3]), d - pair[q, 2])
                for j in range(nc):
                    if M[i, j] != M[i, j]:  # NaN (undefined) -> -inf; an unbounded limit stays inf
                        M[i, j] = -np.inf
            amb[blk] = n_amb


def _array(dtype: str, ndim: int, readonly: bool = False):
    """The numba type of a C-contiguous array of ``dtype`` ("f8", "i8", "b1")."""
    dt = {"f8": _nbt.float64, "i8": _nbt.int64, "b1": _nbt.boolean}[dtype]
    return _nbt.Array(dt, ndim, "C", readonly=readonly)


def signatures() -> dict:
    """{kernel name: (dispatcher, argument types)} of this module's kernels: the one
    specialisation each is called with (``tests/engine/test_engine_warmup.py`` checks it against
    what a real evaluation compiles), so that it can be compiled ahead, in another process
    (:mod:`parasynth.engine.warmup`)."""
    if not HAVE_NUMBA:
        return {}
    f1, f2, f3 = _array("f8", 1), _array("f8", 2), _array("f8", 3)
    i1, i2, b1 = _array("i8", 1), _array("i8", 2), _array("b1", 1)
    i8, f8 = _nbt.int64, _nbt.float64
    X = _array("f8", 2, readonly=True)
    prog = (X, i2, f1, i8, i8, i8, i1, i1, f1, i8)  # poses, ins, consts, cbase, n_reg, n_pose, regs, plim, the
    # pose loop's address
    plan = (i2, f8, i1, i1) + (f2,) * 8 + (i2,)  # expr, tol, leg_kind, leg_act, leg_f .. pair, offs
    return {
        "_pose_kernel": (_pose_kernel, prog + (i2, i8, b1, f2, f2, f3, i1, i8)),
        "_feasible_kernel": (_feasible_kernel, prog + plan + (i8, b1, i1, f2, i1, i8)),
        "_margins_kernel": (_margins_kernel, prog + plan + (i8, f2, i1, i1, i8)),
        "_spin_done": (_spin_done, (i1, i8)),
        "_crew_spin": (_crew_spin, (i1, i8, i1, i8, i1, i8)),
        "_crew_serve": (_crew_serve, (i1, i8, i1, i8, i1, i8, i1, i1, i1)),
        "_cancel_tickets": (_cancel_tickets, (i1, i8)),
        "_tickets_done": (_tickets_done, (i1, i8, i8, i8, i8)),
        "_feasible_batch": (_feasible_batch,
                            prog + plan + (i8, b1, i1, f2, i1, i8) + (i8, i8, i1, i1, i1) + (i1, i8, i1)),
    }
