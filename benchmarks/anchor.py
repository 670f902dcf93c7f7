"""The anchor: a bare fused feasibility kernel of a simplified 5-PUS/UPU, the baseline the
engine's benchmarks quote their figures against (measured in the same run, so that the ratio
holds on a machine shared with other work).

Written the way a hand-tuned kernel for one mechanism would be: one ``numba.prange`` over the
poses (``parallel=True``, 256 poses to a work item: the angles' sines and cosines in a
vectorised loop, the rest scalar), float64, every check fused in one loop body -- the
UPU-constrained rotation, the five PUS legs' inverse kinematics, stroke, U-joint and S-joint
cone angles; the ten pairwise link distances (Ericson's segment distance) only with
``pairs=ALL_PAIRS`` (the simplified anchor leaves them out; the engine checks them). It is
timed on poses that are all feasible, so every check of every leg runs for every pose (no
early exit). It does less than the engine (no interpreter, no described expressions, no other
leg kinds, no interference by default, no margins).

``anchor_seconds(n, threads)`` is the best time of one call on ``n`` such poses with ``threads``
numba threads; ``check()`` verifies the kernel against the library's NumPy reference.

Used by ``workspace_throughput.py`` and ``study_throughput.py``; not part of the test suite.
"""

from __future__ import annotations

import math
import os
import time

# OpenMP threads that sleep when idle: spinning threads on a machine shared with other work
# (the numba threading layer here is OpenMP) make a prange kernel many times slower.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # noqa: E402
import numpy as np
from numba import njit, prange  # noqa: E402

from parasynth.engine.core import _sincos  # the engine's vectorisable (sin, cos), as a tuned kernel would have

#: The task box of the 5-PUS/UPU (x, y, z, alpha, beta), SI, as in workspace_throughput.py.
BOX = ([-0.06, -0.06, -0.10, -0.35, -0.35], [0.06, 0.06, 0.08, 0.35, 0.35])


@njit(inline="always")
def _clamp01(v):
    return 0.0 if v < 0.0 else (1.0 if v > 1.0 else v)


@njit(inline="always")
def _seg_d2(U, S, i, j):
    """Squared distance of the segments U[i]-S[i] and U[j]-S[j] (Ericson 5.1.9)."""
    d1x, d1y, d1z = S[i, 0] - U[i, 0], S[i, 1] - U[i, 1], S[i, 2] - U[i, 2]
    d2x, d2y, d2z = S[j, 0] - U[j, 0], S[j, 1] - U[j, 1], S[j, 2] - U[j, 2]
    rx, ry, rz = U[i, 0] - U[j, 0], U[i, 1] - U[j, 1], U[i, 2] - U[j, 2]
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    c = d1x * rx + d1y * ry + d1z * rz
    b = d1x * d2x + d1y * d2y + d1z * d2z
    den = a * e - b * b
    s = _clamp01((b * f - c * e) / den) if den > 1e-12 * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = _clamp01(-c / a)
    elif t > 1.0:
        t = 1.0
        s = _clamp01((b - c) / a)
    wx = rx + d1x * s - d2x * t
    wy = ry + d1y * s - d2y * t
    wz = rz + d1z * s - d2z * t
    return wx * wx + wy * wy + wz * wz


@njit(parallel=True, fastmath=False, cache=True)
def anchor_kernel(X, base, plat, axis, bref, pref, branch, L, smin, smax, cu, cs, dmin2, zu, pairs, out):
    n = X.shape[0]
    nblk = (n + 255) // 256
    for blk in prange(nblk):  # the poses, 256 to a work item (its scratch allocated once)
        U = np.empty((5, 3))
        S = np.empty((5, 3))
        T = np.empty((4, 256))
        i0, i1 = blk * 256, min(n, blk * 256 + 256)
        for i in range(i0, i1):  # the angles' sines and cosines, a vectorised loop
            T[0, i - i0], T[1, i - i0] = _sincos(X[i, 3])
            T[2, i - i0], T[3, i - i0] = _sincos(X[i, 4])
        for i in range(i0, i1):
            x, y, z = X[i, 0], X[i, 1], X[i, 2]
            # the UPU's first angle q1 = atan2(x, z - zu); cos/sin(be - q1) by the sum formulas
            h = math.sqrt(x * x + (z - zu) * (z - zu))
            c1, s1 = (z - zu) / h, x / h
            sa, ca, sb, cb = T[0, i - i0], T[1, i - i0], T[2, i - i0], T[3, i - i0]
            c2, s2 = cb * c1 + sb * s1, sb * c1 - cb * s1
            # R = Ry(q1) Rx(al) Ry(be - q1)
            a00, a01, a02 = c1, s1 * sa, s1 * ca
            a10, a11, a12 = 0.0, ca, -sa
            a20, a21, a22 = -s1, c1 * sa, c1 * ca
            r00, r01, r02 = a00 * c2 - a02 * s2, a01, a00 * s2 + a02 * c2
            r10, r11, r12 = a10 * c2 - a12 * s2, a11, a10 * s2 + a12 * c2
            r20, r21, r22 = a20 * c2 - a22 * s2, a21, a20 * s2 + a22 * c2
            ok = True
            for k in range(5):
                px, py, pz = plat[k, 0], plat[k, 1], plat[k, 2]
                sx = x + r00 * px + r01 * py + r02 * pz
                sy = y + r10 * px + r11 * py + r12 * pz
                sz = z + r20 * px + r21 * py + r22 * pz
                dx, dy, dz = sx - base[k, 0], sy - base[k, 1], sz - base[k, 2]
                de = dx * axis[k, 0] + dy * axis[k, 1] + dz * axis[k, 2]
                disc = L * L - (dx * dx + dy * dy + dz * dz - de * de)
                if disc < 0.0:
                    ok = False
                s = de + branch[k] * math.sqrt(max(disc, 0.0))
                if s < smin or s > smax:
                    ok = False
                ux, uy, uz = base[k, 0] + s * axis[k, 0], base[k, 1] + s * axis[k, 1], base[k, 2] + s * axis[k, 2]
                U[k, 0], U[k, 1], U[k, 2] = ux, uy, uz
                S[k, 0], S[k, 1], S[k, 2] = sx, sy, sz
                nx, ny, nz = (sx - ux) / L, (sy - uy) / L, (sz - uz) / L
                if nx * bref[k, 0] + ny * bref[k, 1] + nz * bref[k, 2] < cu:
                    ok = False
                qx = r00 * pref[k, 0] + r01 * pref[k, 1] + r02 * pref[k, 2]
                qy = r10 * pref[k, 0] + r11 * pref[k, 1] + r12 * pref[k, 2]
                qz = r20 * pref[k, 0] + r21 * pref[k, 1] + r22 * pref[k, 2]
                if -(nx * qx + ny * qy + nz * qz) < cs:
                    ok = False
            for q in range(pairs.shape[0]):
                if _seg_d2(U, S, pairs[q, 0], pairs[q, 1]) < dmin2:
                    ok = False
            out[i] = ok


def _geometry():
    from parasynth import load_mechanism

    mech = load_mechanism("5pus_upu")
    P = mech.params
    pus = mech.legs[:5]
    st = lambda f: np.ascontiguousarray([f(leg) for leg in pus], dtype=float)  # noqa: E731
    bref = st(lambda g: g.base_ref / np.linalg.norm(g.base_ref))
    pref = st(lambda g: g.platform_ref / np.linalg.norm(g.platform_ref))
    args = (st(lambda g: g.base), st(lambda g: g.platform), st(lambda g: g.slider_axis), bref, pref,
            st(lambda g: g.branch), float(pus[0].link_length), float(P.slider_min), float(P.slider_max),
            math.cos(P.ujoint_max), math.cos(P.sphere_max), float(P.link_diameter) ** 2, float(P.upu_base_z))
    return mech, args


_CACHE: dict = {}


def feasible_poses(n: int, seed: int = 2024) -> np.ndarray:
    """``n`` poses of the task box that are all feasible (feasible samples repeated)."""
    mech, _ = _setup()
    rng = np.random.default_rng(seed)
    lo, hi = (np.asarray(b) for b in BOX)
    Xs = rng.uniform(lo, hi, size=(2**15, 5))
    feas = Xs[mech.is_feasible(Xs, engine="numpy")]
    return np.ascontiguousarray(np.resize(feas, (n, 5)))


def _setup():
    if "geo" not in _CACHE:
        _CACHE["geo"] = _geometry()
    return _CACHE["geo"]


#: The link pairs whose distance the anchor checks: none by default (the simplified anchor,
#: ~110-120 ns per pose on one core here, as the anchor of issue 29: 10.9 ms for 1e5 poses);
#: ``ALL_PAIRS`` adds the ten segment distances (~2x the time per pose).
PAIRS = np.zeros((0, 2), dtype=np.int64)
ALL_PAIRS = np.array([(a, b) for a in range(5) for b in range(a + 1, 5)], dtype=np.int64)


def run(X: np.ndarray, pairs: np.ndarray = PAIRS) -> np.ndarray:
    _, args = _setup()
    out = np.empty(X.shape[0], dtype=np.bool_)
    anchor_kernel(X, *args, pairs, out)
    return out


def check(n: int = 4096) -> int:
    """Poses (of ``n`` uniform in the box) where the anchor with every check (``ALL_PAIRS``) and
    the library's NumPy reference disagree (0 expected but for poses within rounding of a limit)."""
    mech, _ = _setup()
    rng = np.random.default_rng(7)
    lo, hi = (np.asarray(b) for b in BOX)
    X = rng.uniform(lo, hi, size=(n, 5))
    return int(np.count_nonzero(run(X, ALL_PAIRS) != mech.is_feasible(X, engine="numpy")))


def anchor_seconds(n: int, threads: int, repeats: int = 7, min_time: float = 0.05) -> float:
    """Best time (s) of one anchor call on ``n`` all-feasible poses on ``threads`` threads."""
    X = feasible_poses(n)
    prev = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        out = run(X)
        assert out.all(), "the anchor's poses must all be feasible"
        reps = max(1, int(min_time / max(_time_once(X), 1e-6)))
        best = math.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            for _ in range(reps):
                run(X)
            best = min(best, (time.perf_counter() - t0) / reps)
        return best
    finally:
        numba.set_num_threads(prev)


def _time_once(X):
    t0 = time.perf_counter()
    run(X)
    return time.perf_counter() - t0


if __name__ == "__main__":
    print("disagreements with the NumPy reference on 4096 poses:", check())
    for n in (8192, 100_000, 2**17, 2_000_000):
        t1, t2 = anchor_seconds(n, 1), anchor_seconds(n, 2)
        print(f"anchor n={n}: 1 thread {t1 * 1e3:.3f} ms, 2 threads {t2 * 1e3:.3f} ms, {n / t2:.3g} poses/s")
