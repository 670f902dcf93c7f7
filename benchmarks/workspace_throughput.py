"""Workspace throughput: feasible-pose evaluations per second, per model.

Three ways of deciding whether poses are feasible (reachable by every leg and inside every
constraint the model declares: actuator strokes, joint angles, leg interference, ...):

(a) ``numpy``  -- ``mech.is_feasible(X, engine="numpy")`` on large chunks (the vectorised
    reference path);
(b) ``kernel`` -- ``mech.is_feasible(X)``: the compiled engine (``parasynth.engine``), timed
    after a warm-up call so that JIT compilation is excluded, on chunks of 2**20 poses;
(c) ``loop``   -- a naive per-pose loop written like a paper's brute-force workspace search:
    one pose at a time, plain Python/NumPy on 3-vectors (rotation matrix, inverse kinematics
    of each leg, each limit in turn, pairwise segment distances), measured in the same run on
    a small sample. Models without a hand-written loop use the library one pose at a time
    (``is_feasible`` with NumPy on a single pose), the per-pose loop a user would write.

Besides the rate on the box (which depends on the feasible fraction: infeasible poses exit
early), the **worst case** is measured: the compiled engine on poses that are all feasible
(feasible samples of the box, repeated), where every check of every leg runs.

The poses are uniform in a task box around each model's workspace (printed, with the
feasible fraction: early rejection makes the rate depend on it). Each model runs in its own
process so that ``peak_rss_mb`` (``resource.getrusage``) is that model's peak. The run ends
with exactly one line per model::

    <model> poses_per_s=<float> ratio_vs_loop=<float> peak_rss_mb=<float>

    <model> poses_per_s=<float> ratio_vs_loop=<float> peak_rss_mb=<float> worst_case_poses_per_s=<float>
    <model> worst_case_ratio_vs_numpy=<float>

where ``poses_per_s`` is the rate of the fastest path, ``ratio_vs_loop`` its ratio to the
loop measured in the same run, and ``worst_case_ratio_vs_numpy`` the worst-case compiled rate
over the NumPy path's rate on the same all-feasible poses.

``--figures`` instead measures, in one process and alternately with the anchor
(``benchmarks/anchor.py``: a fused ``prange`` kernel of a simplified 5-PUS/UPU, every pose
feasible, f64), the engine's time on 1 and 2 threads per batch size (the ratio 1-thread /
2-thread time of both, and the CPU time 2 threads / 1 thread: the hand-off's cost; threads
from ``core.PARALLEL_MIN`` up whether they pay now or not, ``core.ADAPTIVE = False``), then
each figure of issue 29 with its ratio to the anchor (threads while they pay, as in a run)::

    threads_ratio n=<int> engine=<float> anchor=<float> engine_vs_anchor_1_thread=<float> (target ...)
    threads_after_idle n=<int> one_thread_ms=<f> two_threads_ms=<f> ratio=<f> ratio_crew_not_kept_apart=<f>
    figure worst_case_feasibility poses_per_s=<f> anchor_poses_per_s=<f> ratio_vs_anchor=<f>
    figure workspace_volume_1e5 ms=<f> anchor_ms=<f> time_vs_anchor=<f>
    figure described_6pus_2^17 ms=<f> anchor_ms=<f> per_pose_time_vs_anchor=<f>

``--big-workspace 1e8`` instead runs ``parasynth.workspace`` with that many Sobol samples on
``5pus_upu`` in a fresh process and prints its time and peak memory
(``workspace_samples=<n> seconds=<f> peak_rss_mb=<f>``).

Usage::

    python benchmarks/workspace_throughput.py                    # ~2e7 kernel poses per model
    python benchmarks/workspace_throughput.py --seconds 3        # time-boxed per path
    python benchmarks/workspace_throughput.py --n 5e6 --models 5pus_upu
    python benchmarks/workspace_throughput.py --big-workspace 1e8
    python benchmarks/workspace_throughput.py --figures      # beside the anchor

Not part of the test suite.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import math
import multiprocessing as mp
import os
import resource
import sys
import time

import numpy as np

#: Task boxes (lo, hi), SI, around each model's workspace: with the default parameters 35-50%
#: of the poses are feasible (printed; early rejection makes the rate depend on it).
BOXES = {
    "5pus_upu": ([-0.06, -0.06, -0.10, -0.35, -0.35], [0.06, 0.06, 0.08, 0.35, 0.35]),
    "2rpu_2sps": ([0.62, -0.55, -0.5], [0.94, 0.55, 0.5]),
    "4ups_1rps": ([-0.2, 0.36, -0.4, 0.0, -0.4], [0.2, 0.5, 0.4, 0.4, 0.4]),
    "gough_stewart_6ups": ([-0.15, -0.15, 0.45, -0.25, -0.25, -0.5], [0.15, 0.15, 0.8, 0.25, 0.25, 0.5]),
    "3rps": ([0.3, -0.5, -0.5], [0.7, 0.5, 0.5]),
    "3prs": ([-0.2, -0.5, -0.5], [0.25, 0.5, 0.5]),
}

KERNEL_CHUNK = 2**20
NUMPY_CHUNK = 2**17


# ---------------------------------------------------------------------------------------------
# (c) The naive loop: one pose at a time on 3-vectors, like a paper's brute-force search.
# ---------------------------------------------------------------------------------------------
def rot_x(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def angle(u, v):
    """Angle between two vectors (rad)."""
    c = np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v))
    return math.acos(min(1.0, max(-1.0, c)))


def segment_distance(p1, q1, p2, q2):
    """Closest distance of segments [p1, q1], [p2, q2] (Ericson, Real-Time Collision
    Detection, 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = np.dot(d1, d1), np.dot(d2, d2), np.dot(d2, r)
    eps = 1e-300
    if a <= eps and e <= eps:
        return np.linalg.norm(r)
    if a <= eps:
        s, t = 0.0, min(max(f / e, 0.0), 1.0)
    else:
        c = np.dot(d1, r)
        if e <= eps:
            t, s = 0.0, min(max(-c / a, 0.0), 1.0)
        else:
            b = np.dot(d1, d2)
            denom = a * e - b * b
            s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > 1e-12 * a * e else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t, s = 0.0, min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t, s = 1.0, min(max((b - c) / a, 0.0), 1.0)
    return np.linalg.norm((p1 + d1 * s) - (p2 + d2 * t))


def loop_5pus_upu(mech, X):
    P = mech.params
    pus, upu = mech.legs[:5], mech.legs[5]
    out = np.zeros(len(X), dtype=bool)
    for i, (x, y, z, alpha, beta) in enumerate(X):
        dx, dz = x, z - P.upu_base_z
        if dx * dx + dz * dz <= 1e-12:
            continue
        q1 = math.atan2(dx, dz)
        R = rot_y(q1) @ rot_x(alpha) @ rot_y(beta - q1)
        p = np.array([x, y, z])
        if np.linalg.norm(p + R @ upu.platform - upu.base) == 0.0:
            continue
        segs, ok = [], True
        for leg in pus:
            S = p + R @ leg.platform
            d = S - leg.base
            de = np.dot(d, leg.slider_axis)
            disc = leg.link_length**2 - (np.dot(d, d) - de**2)
            if disc < 0:  # sphere out of reach of the link
                ok = False
                break
            s = de + leg.branch * math.sqrt(disc)
            if not P.slider_min <= s <= P.slider_max:
                ok = False
                break
            U = leg.base + s * leg.slider_axis
            n = (S - U) / leg.link_length
            if angle(n, leg.base_ref) > P.ujoint_max or angle(-n, R @ leg.platform_ref) > P.sphere_max:
                ok = False
                break
            segs.append((U, S))
        if not ok:
            continue
        for a in range(5):
            for b in range(a + 1, 5):
                if segment_distance(*segs[a], *segs[b]) < P.link_diameter:
                    ok = False
                    break
            if not ok:
                break
        out[i] = ok
    return out


def loop_2rpu_2sps(mech, X):
    P = mech.params
    out = np.zeros(len(X), dtype=bool)
    for i, row in enumerate(X):
        if P.coupled:
            z, psi, th = row
            if abs(math.cos(th)) <= 1e-9:
                continue
            x = z * math.tan(th)
        else:
            x, z, psi, th = row
        if abs(psi) > P.psi_max or abs(th) > P.theta_max:
            continue
        R = rot_y(th) @ rot_x(psi)
        p = np.array([x, 0.0, z])
        segs, ok = [], True
        for leg in mech.legs:
            A = p + R @ leg.platform
            d = A - leg.base
            q = np.linalg.norm(d)
            if hasattr(leg, "r_axis"):  # RPU: leg in the plane normal to r_axis
                if abs(np.dot(d, leg.r_axis)) > 1e-9 or abs(np.dot(R @ leg.u_platform_axis, leg.r_axis)) > 1e-9:
                    ok = False
                    break
            if not P.q_min <= q <= P.q_max:
                ok = False
                break
            segs.append((leg.base, A))
        if not ok:
            continue
        for a in range(4):
            for b in range(a + 1, 4):
                if segment_distance(*segs[a], *segs[b]) < P.leg_diameter:
                    ok = False
                    break
            if not ok:
                break
        out[i] = ok
    return out


def loop_4ups_1rps(mech, X):
    P = mech.params
    drive, rps = mech.legs[:4], mech.legs[4]
    # revolute-angle frame of the constraining branch (theta1 = 0 at home)
    a1 = rps.r_axis
    r0 = rps.base_ref - np.dot(rps.base_ref, a1) * a1
    r0 = r0 / np.linalg.norm(r0)
    b0 = np.cross(a1, r0)
    Y = np.array([0.0, 1.0, 0.0])
    out = np.zeros(len(X), dtype=bool)
    for i, (x, y, al, be, ga) in enumerate(X):
        R = rot_z(al) @ rot_y(be) @ rot_z(ga)
        p = np.array([x, y, 0.0])
        segs, ok = [], True
        for leg in drive:
            A = p + R @ leg.platform
            L = A - leg.base
            l = np.linalg.norm(L)
            if not P.l_min <= l <= P.l_max:
                ok = False
                break
            if angle(L, R @ Y) > P.sphere_max or angle(L, Y) > P.ujoint_max:
                ok = False
                break
            segs.append((leg.base, A))
        if not ok:
            continue
        d = p - rps.base  # constraining branch: plane, stroke d2, revolute angle theta1
        d2 = np.linalg.norm(d)
        if abs(np.dot(d, rps.r_axis)) > 1e-9 or not P.d2_min <= d2 <= P.d2_max:
            continue
        n = d / d2
        if abs(math.atan2(np.dot(n, b0), np.dot(n, r0))) > P.theta1_max:
            continue
        if angle(p, R @ Y) > P.sphere_max:
            continue
        for a, b in ((0, 1), (1, 2), (2, 3), (3, 0)):
            if segment_distance(*segs[a], *segs[b]) < P.leg_diameter:
                ok = False
                break
        out[i] = ok
    return out


def loop_library(mech, X):
    """One pose at a time through the library's NumPy path."""
    return np.array([bool(mech.is_feasible(x, engine="numpy")) for x in X])


LOOPS = {"5pus_upu": loop_5pus_upu, "2rpu_2sps": loop_2rpu_2sps, "4ups_1rps": loop_4ups_1rps}


# ---------------------------------------------------------------------------------------------
# Measurement
# ---------------------------------------------------------------------------------------------
def _peak_rss_mb() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return r / 1024.0 if sys.platform != "darwin" else r / 2**20


def _timed_chunks(fn, sampler, chunk, total, seconds):
    """Run fn on fresh chunks of poses; time only fn. Stops after ``total`` poses or, with
    ``seconds``, once that much time has been spent in fn. Returns (poses, seconds,
    feasible count, cpu seconds)."""
    done = feas = 0
    t_fn = cpu = 0.0
    while True:
        n = chunk if seconds else min(chunk, total - done)
        if n <= 0:
            break
        X = sampler(n)
        c0, t0 = time.process_time(), time.perf_counter()
        ok = fn(X)
        t_fn += time.perf_counter() - t0
        cpu += time.process_time() - c0
        done += n
        feas += int(np.count_nonzero(ok))
        if seconds and t_fn >= seconds:
            break
    return done, t_fn, feas, cpu


def run_model(name: str, opts: dict) -> dict:
    import numba

    from parasynth.engine import kernels
    from parasynth import load_mechanism

    mech = load_mechanism(name)
    lo, hi = (np.asarray(b, dtype=float) for b in BOXES[name])
    rng = np.random.default_rng(opts["seed"])

    def sampler(n):
        return rng.uniform(lo, hi, size=(n, lo.size))

    res = {"model": name, "box": (lo.tolist(), hi.tolist()), "kernel": kernels.kernel_available(mech),
           "threads": numba.get_num_threads() if kernels.HAVE_NUMBA else 0}
    seconds = opts["seconds"]

    # (c) naive loop, small sample; checked against the reference
    Xl = sampler(opts["loop_n"])
    loop = LOOPS.get(name, loop_library)
    t0 = time.perf_counter()
    ok_loop = loop(mech, Xl)
    t_loop = time.perf_counter() - t0
    if seconds:  # time-boxed: continue until `seconds`
        n_more = 0
        while t_loop < seconds:
            Xm = sampler(200)
            t0 = time.perf_counter()
            loop(mech, Xm)
            t_loop += time.perf_counter() - t0
            n_more += 200
        n_loop = len(Xl) + n_more
    else:
        n_loop = len(Xl)
    ref = mech.is_feasible(Xl, engine="numpy")
    res["loop"] = dict(n=n_loop, rate=n_loop / t_loop, agree=int(np.count_nonzero(ok_loop == ref)), checked=len(Xl))

    # (a) vectorised NumPy, large chunks
    numpy_path = lambda X: mech.is_feasible(X, engine="numpy")  # noqa: E731
    n_np, t_np, f_np, c_np = _timed_chunks(numpy_path, sampler, opts["numpy_chunk"], opts["numpy_n"], seconds)
    res["numpy"] = dict(n=n_np, rate=n_np / t_np, feasible=f_np / n_np, cpu_per_wall=c_np / t_np)

    # (b) fused kernel: warm-up (JIT compile or cache load) excluded, then the big run
    Xw = sampler(4096)
    t0 = time.perf_counter()
    ok_w = kernels.feasible_fast(mech, Xw)
    res["warmup_s"] = time.perf_counter() - t0
    ref_w = mech.is_feasible(Xw, engine="numpy")
    res["kernel_agree"] = (int(np.count_nonzero(ok_w == ref_w)), len(Xw))
    n_k, t_k, f_k, c_k = _timed_chunks(lambda X: kernels.feasible_fast(mech, X), sampler, opts["chunk"],
                                       opts["n"], seconds)
    res["fused"] = dict(n=n_k, rate=n_k / t_k, feasible=f_k / n_k, cpu_per_wall=c_k / t_k)

    # worst case: every pose feasible (feasible samples of the box, repeated)
    Xs = sampler(2**17)
    feas = Xs[numpy_path(Xs)]
    if len(feas):
        Xf = np.ascontiguousarray(np.resize(feas, (opts["chunk"], lo.size)))
        assert np.all(kernels.feasible_fast(mech, Xf))
        reps = max(1, opts["n"] // len(Xf)) if not seconds else None
        t_w, n_w = 0.0, 0
        while True:
            t0 = time.perf_counter()
            kernels.feasible_fast(mech, Xf)
            t_w += time.perf_counter() - t0
            n_w += len(Xf)
            if (seconds and t_w >= seconds) or (not seconds and n_w >= reps * len(Xf)):
                break
        Xn = Xf[: opts["numpy_chunk"]]
        t0 = time.perf_counter()
        numpy_path(Xn)
        np_rate = len(Xn) / (time.perf_counter() - t0)
        res["worst"] = dict(rate=n_w / t_w, numpy_rate=np_rate, distinct=len(feas))
    else:
        res["worst"] = dict(rate=float("nan"), numpy_rate=float("nan"), distinct=0)
    res["peak_rss_mb"] = _peak_rss_mb()
    return res


def run_big_workspace(n: int, name: str = "5pus_upu") -> dict:
    """parasynth.workspace with n Sobol samples: time and peak memory (this process)."""
    import parasynth

    mech = parasynth.load_mechanism(name)
    parasynth.workspace(mech, n=4096)  # warm-up (compilation or cache load)
    t0 = time.perf_counter()
    ws = parasynth.workspace(mech, n=n, progress=False)
    return dict(n=ws.n_samples, seconds=time.perf_counter() - t0, peak_rss_mb=_peak_rss_mb(),
                fraction=ws.fraction, rss_before=None)


# ---------------------------------------------------------------------------------------------
# The figures of the engine beside the anchor (benchmarks/anchor.py), measured in one process
# ---------------------------------------------------------------------------------------------
THREAD_SIZES = (4096, 8192, 10_000, 16384, 100_000, 2**17, 2**20)


def _best(fn, repeats=7, min_time=0.05):
    """Best wall time (s) of one call of ``fn`` (each repeat ``min_time`` long at least), and
    the CPU time (s, all threads) of that repeat's calls."""
    t0 = time.perf_counter()
    fn()
    one = max(time.perf_counter() - t0, 1e-6)
    reps = max(1, int(min_time / one))
    best, cpu = math.inf, math.inf
    for _ in range(repeats):
        c0, t0 = time.process_time(), time.perf_counter()
        for _ in range(reps):
            fn()
        dt = (time.perf_counter() - t0) / reps
        if dt < best:
            best, cpu = dt, (time.process_time() - c0) / reps
    return best, cpu


def _thread_row(n, mech, kernels, anchor, set_threads, rounds=15, min_time=0.02):
    """The engine's and the anchor's batch of ``n`` all-feasible poses on one thread and on two,
    the four ways taken in turn within each round (this machine's speed drifts by tens of per
    cent within minutes: ways timed one after another would compare two machines): per way the
    best round's time per call (s) and CPU time per call, and per pair the median over the
    rounds of the one-thread time over the two-thread time."""
    import numba

    X = anchor.feasible_poses(n)
    ways = {}
    for t in (1, 2):
        def eng(t=t):
            set_threads(t)
            kernels.feasible_fast(mech, X)

        def anc(t=t):
            numba.set_num_threads(min(t, numba.config.NUMBA_NUM_THREADS))
            anchor.run(X)

        ways[f"engine{t}"], ways[f"anchor{t}"] = eng, anc
    reps = {}
    for k, fn in ways.items():  # warm, and the calls a round needs for min_time
        fn()
        t0 = time.perf_counter()
        fn()
        reps[k] = max(1, int(min_time / max(time.perf_counter() - t0, 1e-6)))
    wall = {k: [] for k in ways}
    cpu = {k: [] for k in ways}
    for _ in range(rounds):
        for k, fn in ways.items():
            c0, t0 = time.process_time(), time.perf_counter()
            for _ in range(reps[k]):
                fn()
            wall[k].append((time.perf_counter() - t0) / reps[k])
            cpu[k].append((time.process_time() - c0) / reps[k])
    set_threads(None)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    row = {"n": n}
    for k in ways:
        i = int(np.argmin(wall[k]))
        row[k] = (wall[k][i], cpu[k][i])
    for who in ("engine", "anchor"):
        row[f"{who}_paired"] = float(np.median(np.array(wall[f"{who}1"]) / np.array(wall[f"{who}2"])))
    return row


def _after_idle(core, kernels, mech, anchor, set_threads, sizes=(8192, 16384), rounds=25, calls=12):
    """Batches after an idle millisecond (the calling thread asleep, as between a study's
    evaluations that wait for a file or a database): the median time on one thread and on two,
    with the crew kept off the calling thread's CPU (``core.APART``) and without, interleaved
    round by round so that the three share the machine's state."""
    import os as _os

    out = []
    cpus = _os.sched_getaffinity(0) if hasattr(_os, "sched_getaffinity") else None
    apart0 = core.APART
    for n in sizes:
        X = anchor.feasible_poses(n)
        t = {"one": [], "apart": [], "together": []}
        for _ in range(rounds):
            for way in t:
                set_threads(1 if way == "one" else 2)
                if way != "one":
                    core.APART = apart0 and way == "apart"
                    if way == "together" and cpus is not None:
                        for th, _w in core._CREW.members:
                            _os.sched_setaffinity(th.native_id, cpus)
                        core._CREW.apart_from = None
                for _ in range(calls):
                    time.sleep(0.001)
                    t0 = time.perf_counter()
                    kernels.feasible_fast(mech, X)
                    t[way].append(time.perf_counter() - t0)
        core.APART = apart0
        set_threads(None)
        out.append({"n": n, "apart_available": apart0, **{k: float(np.median(v)) for k, v in t.items()}})
    return out


def run_figures(opts: dict) -> dict:
    """The engine's figures and the anchor's, alternately in this process: the thread ratio per
    batch size, the worst-case feasibility rate (2e6 all-feasible poses), ``workspace_volume``
    of 1e5 Sobol samples on a new design each call and the workspace of a described 6-PUS on
    2**17 samples."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import anchor
    import numba

    from parasynth import load_mechanism
    from parasynth.engine import core, kernels
    from parasynth.measures import objectives
    from parasynth.measures.workspace import workspace

    res = {"load_before": os.getloadavg(), "threads_available": int(numba.config.NUMBA_NUM_THREADS),
           "anchor_disagree": anchor.check()}
    mech = load_mechanism("5pus_upu")
    n_max = int(numba.config.NUMBA_NUM_THREADS)

    def set_threads(t):  # core.set_threads; an older engine read numba's count alone
        if hasattr(core, "set_threads"):
            core.set_threads(t)
        else:
            numba.config.NUMBA_NUM_THREADS = n_max if t is None else t

    rows = []
    adaptive = getattr(core, "ADAPTIVE", None)
    if adaptive is not None:  # the table compares the two ways, whichever pays now
        core.ADAPTIVE = False
    for n in opts["sizes"]:
        rows.append(_thread_row(n, mech, kernels, anchor, set_threads))
    res["threads"] = rows
    res["idle"] = _after_idle(core, kernels, mech, anchor, set_threads) if hasattr(core, "APART") else []
    if adaptive is not None:  # the figures below as a run has them: threads while they pay
        core.ADAPTIVE = adaptive
    # worst-case feasibility, 2e6 poses, both threads
    n = 2_000_000
    X = anchor.feasible_poses(n)
    assert kernels.feasible_fast(mech, X).all()
    res["worst"] = dict(n=n, engine=_best(lambda: kernels.feasible_fast(mech, X), repeats=5)[0],
                        anchor=anchor.anchor_seconds(n, 2, repeats=5))
    # workspace_volume of 1e5 Sobol samples, a new design (a new mechanism object) each call
    designs = [load_mechanism("5pus_upu", link_length=0.19 + 0.0005 * i) for i in range(400)]
    it = iter(range(10**9))
    ranges = designs[0].default_ranges()

    def one_volume():
        m = designs[next(it) % len(designs)]
        objectives._CACHE.clear()
        objectives.workspace_volume(m, n=100_000, ranges=ranges)

    res["volume"] = dict(engine=_best(one_volume)[0], anchor=anchor.anchor_seconds(100_000, 2))
    # a described 6-PUS, 2**17 samples
    hexa = load_mechanism("hexapod_6pus")
    hx = [load_mechanism("hexapod_6pus", link_length=0.68 + 0.0005 * i) for i in range(100)]
    it6 = iter(range(10**9))
    workspace(hexa, n=4096, keep_points=False, progress=False)
    res["hexapod"] = dict(engine=_best(lambda: workspace(hx[next(it6) % len(hx)], n=2**17, keep_points=False,
                                                         progress=False), repeats=5)[0],
                          anchor=anchor.anchor_seconds(2**17, 2, repeats=5))
    res["load_after"] = os.getloadavg()
    return res


def print_figures(r: dict) -> None:
    la, lb = r["load_before"], r["load_after"]
    print(f"load average (1 min) {la[0]:.2f} before, {lb[0]:.2f} after; numba threads available "
          f"{r['threads_available']}; anchor = benchmarks/anchor.py (fused, prange, every pose feasible, f64; "
          f"{r['anchor_disagree']} disagreements with NumPy on 4096 poses)")
    print("thread table: best round of each way, the four ways in turn each round; 'paired': the median "
          "over rounds of one thread's time over two threads'")
    print(f"{'poses':>9s} {'engine 1 thr':>13s} {'engine 2 thr':>13s} {'2/1 thr':>8s} {'paired':>7s} {'cpu 2/1':>8s} "
          f"{'anchor 1 thr':>13s} {'anchor 2 thr':>13s} {'2/1 thr':>8s} {'paired':>7s} {'engine/anchor':>14s} "
          f"{'(1 thr)':>8s}")
    for row in r["threads"]:
        e1, c1 = row["engine1"]
        e2, c2 = row["engine2"]
        a1, a2 = row["anchor1"][0], row["anchor2"][0]
        print(f"{row['n']:9d} {e1 * 1e3:11.3f}ms {e2 * 1e3:11.3f}ms {e1 / e2:8.2f} {row.get('engine_paired', e1 / e2):7.2f} "
              f"{c2 / c1:8.2f} {a1 * 1e3:11.3f}ms {a2 * 1e3:11.3f}ms {a1 / a2:8.2f} "
              f"{row.get('anchor_paired', a1 / a2):7.2f} {e2 / a2:14.2f} {e1 / a1:8.2f}")
    for row in r["threads"]:
        tgt = "(target >= 1.8 from ~1e4 poses, idle machine)" if row["n"] >= 8192 else "(serial below 8192 poses)"
        print(f"threads_ratio n={row['n']} engine={row['engine1'][0] / row['engine2'][0]:.3g} "
              f"engine_paired={row.get('engine_paired', float('nan')):.3g} "
              f"anchor={row['anchor1'][0] / row['anchor2'][0]:.3g} "
              f"engine_vs_anchor_1_thread={row['anchor1'][0] / row['engine1'][0]:.3g} {tgt}")
    for row in r.get("idle", []):
        print(f"threads_after_idle n={row['n']} one_thread_ms={row['one'] * 1e3:.3f} "
              f"two_threads_ms={row['apart'] * 1e3:.3f} ratio={row['one'] / row['apart']:.3g} "
              f"ratio_crew_not_kept_apart={row['one'] / row['together']:.3g}"
              + ("" if row["apart_available"] else " (crew not kept apart here: not Linux)"))
    w = r["worst"]
    print(f"figure worst_case_feasibility poses_per_s={w['n'] / w['engine']:.4g} "
          f"anchor_poses_per_s={w['n'] / w['anchor']:.4g} ratio_vs_anchor={w['anchor'] / w['engine']:.3g} "
          f"(target >= 5e7 and >= 2.7)")
    v = r["volume"]
    print(f"figure workspace_volume_1e5 ms={v['engine'] * 1e3:.3f} anchor_ms={v['anchor'] * 1e3:.3f} "
          f"time_vs_anchor={v['engine'] / v['anchor']:.3g} (target <= 1.0 and <= 5 ms)")
    h = r["hexapod"]
    print(f"figure described_6pus_2^17 ms={h['engine'] * 1e3:.3f} anchor_ms={h['anchor'] * 1e3:.3f} "
          f"per_pose_time_vs_anchor={h['engine'] / h['anchor']:.3g} (target <= 2)")


def _run_isolated(name, opts):
    """Run one model in a fresh process (its own peak RSS)."""
    with cf.ProcessPoolExecutor(max_workers=1, mp_context=mp.get_context("spawn")) as ex:
        return ex.submit(run_model, name, opts).result()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", nargs="+", default=list(BOXES), choices=list(BOXES),
                    help="models to run (default: all)")
    ap.add_argument("--n", type=float, default=20 * KERNEL_CHUNK,
                    help="poses for the fused kernel (default 20*2**20 ~ 2.1e7); NumPy gets n/20, at least 2**17")
    ap.add_argument("--seconds", type=float, default=None,
                    help="instead of --n: time spent in each path (loop, NumPy, kernel) per model")
    ap.add_argument("--loop-n", type=int, default=1000, help="poses for the naive loop (default 1000)")
    ap.add_argument("--chunk", type=int, default=KERNEL_CHUNK, help="kernel chunk (default 2**20)")
    ap.add_argument("--numpy-chunk", type=int, default=NUMPY_CHUNK, help="NumPy chunk (default 2**17)")
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--in-process", action="store_true", help="run all models in this process")
    ap.add_argument("--big-workspace", type=float, default=None, metavar="N",
                    help="only run parasynth.workspace on 5pus_upu with N Sobol samples (e.g. 1e8): time, memory")
    ap.add_argument("--figures", action="store_true",
                    help="only the figures of the engine beside the anchor (benchmarks/anchor.py) in one process: "
                         "the 2-thread/1-thread ratio per batch size, worst-case feasibility, workspace_volume "
                         "of 1e5 samples, a described 6-PUS on 2**17 samples")
    ap.add_argument("--sizes", type=float, nargs="+", default=list(THREAD_SIZES),
                    help="batch sizes of the thread table of --figures")
    args = ap.parse_args(argv)
    if args.figures:
        print_figures(run_figures({"sizes": [int(x) for x in args.sizes]}))
        return
    if args.big_workspace:
        with cf.ProcessPoolExecutor(max_workers=1, mp_context=mp.get_context("spawn")) as ex:
            r = ex.submit(run_big_workspace, int(args.big_workspace)).result()
        print(f"workspace_samples={r['n']} seconds={r['seconds']:.6g} peak_rss_mb={r['peak_rss_mb']:.6g} "
              f"fraction={r['fraction']:.4g}")
        return
    n = int(args.n)
    opts = dict(n=n, numpy_n=max(NUMPY_CHUNK, n // 20), seconds=args.seconds, loop_n=args.loop_n,
                chunk=args.chunk, numpy_chunk=args.numpy_chunk, seed=args.seed)

    results = []
    for name in args.models:
        r = run_model(name, opts) if args.in_process else _run_isolated(name, opts)
        results.append(r)

    print(f"cores: {os.cpu_count()}, numba threads: {results[0]['threads']}; poses uniform in the task boxes below")
    hdr = f"{'model':18s} {'path':7s} {'poses':>10s} {'poses/s':>12s} {'x loop':>9s} {'feasible':>9s} {'cpu/wall':>9s}"
    print(hdr)
    print("-" * len(hdr))
    for r in results:
        lr = r["loop"]["rate"]
        print(f"{r['model']:18s} {'loop':7s} {r['loop']['n']:10d} {lr:12.4g} {1.0:9.1f} {'':>9s} {'':>9s}")
        for path in ("numpy", "fused"):
            d = r[path]
            print(f"{r['model']:18s} {path:7s} {d['n']:10d} {d['rate']:12.4g} {d['rate'] / lr:9.1f} "
                  f"{d['feasible']:9.3f} {d['cpu_per_wall']:9.2f}")
    print()
    for r in results:
        print(f"{r['model']}: box lo={r['box'][0]} hi={r['box'][1]}; kernel available: {r['kernel']}; "
              f"warm-up {r['warmup_s']:.2f} s; loop agrees with is_feasible on {r['loop']['agree']}/"
              f"{r['loop']['checked']} poses, kernel on {r['kernel_agree'][0]}/{r['kernel_agree'][1]}")
    print()
    for r in results:
        w = r["worst"]
        print(f"{r['model']}: worst case (all {w['distinct']} distinct feasible poses repeated): compiled "
              f"{w['rate']:.4g} poses/s, NumPy {w['numpy_rate']:.4g} poses/s")
    print()
    for r in results:
        best = max(r["numpy"]["rate"], r["fused"]["rate"])
        w = r["worst"]
        print(f"{r['model']} poses_per_s={best:.6g} ratio_vs_loop={best / r['loop']['rate']:.6g} "
              f"peak_rss_mb={r['peak_rss_mb']:.6g} worst_case_poses_per_s={w['rate']:.6g}")
        print(f"{r['model']} worst_case_ratio_vs_numpy={w['rate'] / w['numpy_rate']:.6g}")


if __name__ == "__main__":
    main()
