"""Fused compiled feasibility kernels (numba), with the NumPy path as the reference.

:meth:`Mechanism.is_feasible` evaluates a pose batch stage by stage -- the pose, every leg's
inverse kinematics, then each constraint over the whole batch -- with (N,)-, (N, 3)- and
(N, 3, 3)-sized temporaries at every step. Here the same test is one compiled pass
(``numba.njit(parallel=True)``, float64, no fastmath): ``prange`` over blocks of poses, and
within a block, sub-blocks of ``SUB`` poses whose intermediate values (rotation, joint centres,
actuator values, a feasibility mask) live in small per-block scratch arrays that stay in the
L1 cache. Per sub-block: the platform pose (a vectorisable sin/cos, Cephes' algorithm, within
~2e-16 of libm), then leg by leg its inverse kinematics and that leg's checks (actuator
range, passive length, joint cone angles, leg-axis angles), each a straight loop over the
sub-block with the leg's geometry and limits as loop invariants -- the compiler vectorises
these loops (SIMD across poses) -- then the pose-level checks and, last, the most expensive
one, leg interference: for each listed pair, a bounding-box test settles the poses whose
segments are at least a diameter apart along an axis, and only if a feasible pose remains
unsettled is the segment-segment distance computed for the sub-block. Cheapest checks come
first and a sub-block stops at the first leg or pair after which none of its poses is still
feasible (early exit per sub-block rather than per pose: branch-free SIMD over 64 poses is
faster than scalar per-pose exits). Nothing of size N is allocated but the result.

Entry points
------------
* :func:`feasible_fast` ``(mech, X)`` -> (N,) bool, ``mech.is_feasible(X)``;
* :func:`margins_fast` ``(mech, X)`` -> {constraint name: (N,) margin}, as
  ``mech.constraint_margins(X)`` (a per-pose scalar kernel without early exit, with NumPy's
  formulas; -inf where a leg cannot reach the pose);
* :func:`kernel_available` ``(mech)`` -> whether a compiled kernel covers ``mech``.

They fall back silently to the NumPy methods when numba is not importable (or the
environment variable ``PARASYNTH_NO_NUMBA`` is set), when the model has no kernel, or when
its legs or constraints include anything the kernel does not implement: nothing is guessed.

Coverage: the models ``5pus_upu`` (both platforms), ``2rpu_2sps`` (coupled and uncoupled)
and ``4ups_1rps``. The kernel is generic in the geometry: at every call it reads the legs'
types, anchors, slider axes, link lengths, branches, revolute and universal-joint axes, the
neutral directions ``base_ref``/``platform_ref``, and every limit from ``mech.constraints``,
so parameter changes are reflected without recompiling. Only the task-space parametrisation
(each model's ``_pose`` and ``pose_valid``) is compiled in; it is compared with
``mech.pose``/``mech.pose_valid`` on a few poses when a mechanism is first seen and the NumPy
path is used if they differ (a model whose convention changed). Supported constraints:
:class:`ActuatorRange`, :class:`LegLengthRange`, :class:`CoordinateRange`,
:class:`JointAngleLimit` on cone angles (``*_base_cone``, ``*_platform_cone``) and on the
revolute angle ``R_base`` of RPS/RPU legs, :class:`LegAxisAngle`, :class:`LegInterference`
and the grinding robot's centre-axis angle.

Agreement with the NumPy path
-----------------------------
The kernel evaluates the same conditions, but not always in the same arithmetic form: to keep
``arctan2``/``arccos``/``sqrt`` out of the loops, a cone limit ``angle(u, v) <= hi`` is tested
as ``sin(hi) (u.v) - cos(hi) |u x v| >= 0`` (on squares, signs handled), ``arccos(c) <= hi``
as ``c >= cos(hi)`` and a distance limit ``d >= D`` as ``d^2 >= D^2``; the 5pus_upu rotation
takes cos/sin of its auxiliary angle algebraically; the kernel's sin/cos may differ from
NumPy's by an ulp; sums may associate differently. The booleans therefore agree exactly except at
poses within rounding of a boundary. The contract, tested in ``tests/test_kernels.py``:
``feasible_fast`` and ``is_feasible`` may disagree only at poses whose NumPy feasibility
margin -- the smallest of the legs' reachability margins (PUS discriminant
``L^2 - d_perp^2`` in m^2, leg length, RPS/RPU off-plane tolerance) and the constraint
margins -- is within 1e-12 of zero. (At poses found by bisection on the boundary they do
disagree, in either direction; on random poses never.) :func:`margins_fast` agrees with
``constraint_margins`` to ~1e-15, except where rounding is amplified: by ``arccos`` near 0
and pi (up to ~1e-8 rad) and by the square root of a PUS discriminant near the reach limit.

RPS/RPU legs accept an off-plane error up to ``GEOM_TOL * max(1, leg length)``. The kernel
decides reachability itself whenever the off-plane error is at most ``GEOM_TOL`` (in the
built-in models it is exactly 0) and otherwise hands the whole batch to NumPy.
"""

from __future__ import annotations

import math
import os
import weakref

import numpy as np

from .constraints import (ActuatorRange, CoordinateRange, JointAngleLimit, LegAxisAngle, LegInterference,
                          LegLengthRange)
from .legs import GEOM_TOL, PUS, RPS, RPU, SPS, UPS, UPU

__all__ = ["HAVE_NUMBA", "feasible_fast", "margins_fast", "kernel_available", "KernelPlan", "build_plan"]

try:  # pragma: no cover - depends on the environment
    if os.environ.get("PARASYNTH_NO_NUMBA", "").strip() not in ("", "0"):
        raise ImportError("disabled by PARASYNTH_NO_NUMBA")
    from numba import njit, prange

    HAVE_NUMBA = True
except Exception:  # ImportError, or a broken numba/llvmlite install
    HAVE_NUMBA = False

# Leg kinds in the kernel.
_FREE, _PUS, _RPS, _RPU = 0, 1, 2, 3
# Pose parametrisations in the kernel.
_POSE_YXY, _POSE_2T2R_COUPLED, _POSE_2T2R, _POSE_ZYZ = 0, 1, 2, 3

# Leg float-array layout (leg_f columns).
_B, _A, _AX, _AX2, _BREF, _PREF, _LEN, _BRANCH = 0, 3, 6, 9, 12, 15, 18, 19
_NLF = 20

#: Cone-angle keys of each leg class: (base end, platform end).
_CONE_KEYS = {
    SPS: ("S_base_cone", "S_platform_cone"),
    UPS: ("U_base_cone", "S_platform_cone"),
    PUS: ("U_base_cone", "S_platform_cone"),
    RPS: ("R_base_cone", "S_platform_cone"),
    RPU: ("R_base_cone", "U_platform_cone"),
    UPU: ("U_base_cone", "U_platform_cone"),
}

#: Poses per parallel work item (one scratch allocation per work item).
BLOCK = 4096


class _Unsupported(Exception):
    """The mechanism uses something the kernel does not implement (use NumPy)."""


# ---------------------------------------------------------------------------------------------
# Plan: the mechanism's geometry and constraints packed into arrays for the kernel.
# ---------------------------------------------------------------------------------------------
class KernelPlan:
    """Arrays describing one mechanism for the kernels (built by :func:`build_plan`).

    Check tables (float64, one row per elementary check; integer fields stored as floats):

    * ``coord``  (col, lo, hi, ci): CoordinateRange
    * ``actr``   (lo, hi, ci): ActuatorRange over all actuated legs
    * ``lenr``   (leg, lo, hi, ci): LegLengthRange
    * ``cone``   (leg, end, lo, hi, ci, lo_mode, hi_mode, sin^2 lo, cos^2 lo, sin^2 hi, cos^2 hi)
    * ``rang``   (leg, r0[3], b[3], lo, hi, ci): signed revolute angle atan2(n.b, n.r0)
    * ``axang``  (leg, axis[3], frame, hi, ci, cos hi): LegAxisAngle
    * ``centre`` (hi, ci, cos hi): angle between platform y and the centre's position vector
    * ``pair``   (leg i, leg j, D, ci, D^2 or -1): LegInterference

    ``ci`` is the column of the constraint in ``names`` (the order of ``mech.constraints``).
    The per-leg tables (lenr, cone, rang, axang) are sorted by leg; ``offs`` (4, n_legs + 1)
    holds each leg's row range in them (rows 0..3: lenr, cone, rang, axang). Leg geometry
    ``leg_f`` (n_legs, 20): base anchor, platform anchor, slider/revolute axis, RPU platform
    axis, base_ref, platform_ref, link length, branch.
    """

    def __init__(self, pose_code, pose_f, leg_kind, leg_act, leg_f, names, tables):
        self.pose_code = int(pose_code)
        self.pose_f = pose_f
        self.leg_kind = leg_kind
        self.leg_act = leg_act
        self.leg_f = leg_f
        self.names = tuple(names)
        self.tables = tables  # dict name -> (k, m) float64

    def args(self):
        t = self.tables
        return (self.pose_code, self.pose_f, GEOM_TOL, self.leg_kind, self.leg_act, self.leg_f, t["coord"],
                t["actr"], t["lenr"], t["cone"], t["rang"], t["axang"], t["centre"], t["pair"], t["offs"])


def _table(rows, width):
    a = np.asarray(rows, dtype=np.float64).reshape(-1, width) if rows else np.zeros((0, width))
    return np.ascontiguousarray(a)


def _pose_code(mech) -> int:
    """The compiled parametrisation of ``mech``'s model (exact class only)."""
    from .mechanisms.pus_upu_5dof import PUSUPU5
    from .mechanisms.rpu_sps_2t2r import RPU2SPS2
    from .mechanisms.ups_rps_grinding import UPSRPSGrinding

    t = type(mech)
    if t is PUSUPU5:
        return _POSE_YXY
    if t is RPU2SPS2:
        return _POSE_2T2R_COUPLED if mech.params.coupled else _POSE_2T2R
    if t is UPSRPSGrinding:
        return _POSE_ZYZ
    raise _Unsupported(f"no kernel for model {t.__name__}")


def _pose_params(mech, code: int) -> np.ndarray:
    """Model parameters the compiled parametrisation needs (float64 array)."""
    if code == _POSE_YXY:
        return np.array([float(mech.params.upu_base_z)])
    return np.zeros(1)


def _check_pose_code(mech, code: int, pose_f: np.ndarray) -> None:
    """Compare the compiled parametrisation (validity, p, R) with ``mech.pose_valid`` and
    ``mech.pose`` on deterministic poses around ``home``: guards against a model whose
    convention changed since the kernel was written (then NumPy is used)."""
    rng = np.random.default_rng(7)
    n = mech.n_task
    X = mech.home + rng.uniform(-0.4, 0.4, size=(32, n))
    X = np.vstack([mech.home, X, np.zeros((1, n))])
    if code == _POSE_YXY:  # the parametrisation's singular line x = 0, z = upu_base_z
        X[-1, 2] = pose_f[0]
    valid = mech.pose_valid(X)
    p0, R0 = mech.pose(X[valid])
    for simd in (False, True):
        ok, p1, R1 = _pose_batch(np.ascontiguousarray(X), code, pose_f, simd)
        if not np.array_equal(ok, valid):
            raise _Unsupported(f"{mech.name}: compiled pose validity does not match mech.pose_valid")
        if not (np.allclose(p0, p1[valid], rtol=0, atol=1e-12)
                and np.allclose(R0, R1[valid].reshape(-1, 3, 3), rtol=0, atol=1e-12)):
            raise _Unsupported(f"{mech.name}: compiled pose parametrisation does not match mech.pose")


def _angle_modes(lo: float, hi: float):
    """Encode cone-angle bounds [lo, hi] (rad, angle in [0, pi]) for the boolean test."""
    if np.isnan(lo) or np.isnan(hi):
        raise _Unsupported("NaN angle limit")
    if hi <= 0 or lo >= np.pi:
        raise _Unsupported("degenerate cone-angle limit")
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
        raise _Unsupported("NaN angle limit")
    if hi >= np.pi:
        return -np.inf
    if hi < 0:
        return np.inf
    return math.cos(hi)


def _revolute_frame(r_axis: np.ndarray, ref: np.ndarray):
    """r0 and b of legs._u_angles (same operations), for the signed revolute angle."""
    from .spatial import unit

    a1 = r_axis
    r0 = unit(ref - np.dot(ref, a1) * a1)
    if not np.any(r0):
        r0 = unit(np.cross(a1, [1.0, 0, 0]) if abs(a1[0]) < 0.9 else np.cross(a1, [0, 1.0, 0]))
    b = np.cross(a1, r0)
    return r0, b


def build_plan(mech) -> KernelPlan:
    """Pack ``mech`` for the kernels; raises ``_Unsupported`` if it cannot be represented."""
    code = _pose_code(mech)
    pose_f = _pose_params(mech, code)
    _check_pose_code(mech, code, pose_f)
    legs = list(mech.legs)
    nl = len(legs)
    names = [leg.name for leg in legs]
    index = {n: i for i, n in enumerate(names)}
    kind = np.zeros(nl, dtype=np.int64)
    act = np.zeros(nl, dtype=np.int64)
    F = np.zeros((nl, _NLF))
    for i, leg in enumerate(legs):
        t = type(leg)
        if t in (SPS, UPS, UPU):
            kind[i] = _FREE
        elif t is PUS:
            kind[i] = _PUS
            F[i, _AX:_AX + 3] = leg.slider_axis
            F[i, _LEN] = float(leg.link_length)
            F[i, _BRANCH] = float(leg.branch)
        elif t is RPS:
            kind[i] = _RPS
            F[i, _AX:_AX + 3] = leg.r_axis
        elif t is RPU:
            kind[i] = _RPU
            F[i, _AX:_AX + 3] = leg.r_axis
            F[i, _AX2:_AX2 + 3] = leg.u_platform_axis
        else:
            raise _Unsupported(f"leg type {t.__name__}")
        act[i] = 1 if leg.is_actuated else 0
        F[i, _B:_B + 3] = leg.base
        F[i, _A:_A + 3] = leg.platform
        F[i, _BREF:_BREF + 3] = leg.base_ref
        F[i, _PREF:_PREF + 3] = leg.platform_ref

    # Angle keys each leg actually reports (checked, not assumed).
    p, R = mech.pose(mech.home[None, :])
    keys = [set(leg.solve(p, R).angles) for leg in legs]

    rows = {k: [] for k in ("coord", "actr", "lenr", "cone", "rang", "axang", "centre", "pair")}
    cons = list(mech.constraints.values())
    for ci, c in enumerate(cons):
        t = type(c)
        if t is ActuatorRange:
            if not act.any():
                raise _Unsupported("ActuatorRange without actuators (NumPy raises)")
            rows["actr"].append((c.lo, c.hi, ci))
        elif t is CoordinateRange:
            if not 0 <= c.index < mech.n_task:
                raise _Unsupported("coordinate index out of range")
            rows["coord"].append((c.index, c.lo, c.hi, ci))
        elif t is LegLengthRange:
            if not c.legs:
                raise _Unsupported("LegLengthRange without legs")
            for n in c.legs:
                rows["lenr"].append((index[n], c.lo, c.hi, ci))
        elif t is JointAngleLimit:
            sel = [i for i, leg in enumerate(legs) if (not c.legs or leg.name in c.legs) and c.key in keys[i]]
            if not sel:
                raise _Unsupported("JointAngleLimit matching no leg (NumPy raises)")
            for i in sel:
                ckeys = _CONE_KEYS[type(legs[i])]
                if c.key in ckeys:
                    end = ckeys.index(c.key)
                    rows["cone"].append((i, end, c.lo, c.hi, ci) + _angle_modes(float(c.lo), float(c.hi)))
                elif c.key == "R_base" and kind[i] in (_RPS, _RPU):
                    r0, b = _revolute_frame(legs[i].r_axis, legs[i].base_ref)
                    rows["rang"].append((i, *r0, *b, c.lo, c.hi, ci))
                else:
                    raise _Unsupported(f"joint angle {c.key!r} of leg {legs[i].name}")
        elif t is LegAxisAngle:
            if c.frame not in ("base", "platform") or not c.legs:
                raise _Unsupported(f"LegAxisAngle frame {c.frame!r} or no legs")
            a = np.asarray(c.axis, dtype=float)
            a = a / np.linalg.norm(a)
            for n in c.legs:
                rows["axang"].append((index[n], *a, 1.0 if c.frame == "platform" else 0.0, c.hi, ci,
                                      _cos_limit(float(c.hi))))
        elif t is LegInterference:
            D = float(c.diameter)
            if not c._pairs(names):
                raise _Unsupported("LegInterference without pairs (NumPy raises)")
            for a_, b_ in c._pairs(names):
                rows["pair"].append((index[a_], index[b_], D, ci, D * D if D > 0 else -1.0))
        elif t.__name__ == "_CentreAxisAngle" and t.__module__.endswith("ups_rps_grinding") and code == _POSE_ZYZ:
            rows["centre"].append((c.hi, ci, _cos_limit(float(c.hi))))
        else:
            raise _Unsupported(f"constraint type {t.__name__}")
    widths = {"coord": 4, "actr": 3, "lenr": 4, "cone": 11, "rang": 10, "axang": 8, "centre": 3, "pair": 5}
    # Per-leg checks sorted by leg, with offsets, so the boolean kernel runs them right after
    # that leg's inverse kinematics (early rejection).
    for k in ("lenr", "cone", "rang", "axang"):
        rows[k] = sorted(rows[k], key=lambda r: r[0])
    tables = {k: _table(v, widths[k]) for k, v in rows.items()}
    offs = np.zeros((4, nl + 1), dtype=np.int64)
    for j, k in enumerate(("lenr", "cone", "rang", "axang")):
        legs_of = tables[k][:, 0].astype(np.int64)
        offs[j] = np.searchsorted(legs_of, np.arange(nl + 1), side="left")
    tables["offs"] = offs
    plan = KernelPlan(code, pose_f, kind, act, np.ascontiguousarray(F), [c.name for c in cons], tables)
    return plan


_PLANS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _plan(mech):
    """Cached plan of ``mech`` (None if unsupported). The cache entry is reused only while the
    mechanism's legs and constraint objects are the same objects."""
    if not HAVE_NUMBA:
        return None
    try:
        cons = tuple(mech.constraints.values())
    except Exception:
        return None
    key_legs = tuple(id(leg) for leg in mech.legs)
    key_cons = tuple(id(c) for c in cons)
    try:
        hit = _PLANS.get(mech)
    except TypeError:
        hit = None
    if hit is not None and hit[0] == key_legs and hit[1] == key_cons and hit[2] is mech.constraints:
        return hit[3]
    try:
        plan = build_plan(mech)
    except (_Unsupported, KeyError, AttributeError, ImportError, ValueError, TypeError):
        plan = None
    try:
        _PLANS[mech] = (key_legs, key_cons, mech.constraints, plan, cons, tuple(mech.legs))
    except TypeError:
        pass
    return plan


def kernel_available(mech) -> bool:
    """Whether :func:`feasible_fast` runs a compiled kernel for ``mech``."""
    return _plan(mech) is not None


# ---------------------------------------------------------------------------------------------
# Public entry points
# ---------------------------------------------------------------------------------------------
def feasible_fast(mech, X) -> np.ndarray:
    """(N,) bool: reachable and every constraint of ``mech`` satisfied at poses ``X`` (N, n_task)
    -- ``mech.is_feasible(X)`` computed by the fused kernel when one covers ``mech``, else by
    ``mech.is_feasible`` itself. A single pose (n_task,) gives a scalar bool."""
    plan = _plan(mech)
    if plan is None:
        return mech.is_feasible(X)
    Xa, single = mech._poses(X)
    Xc = np.ascontiguousarray(Xa, dtype=np.float64)
    out = np.empty(Xc.shape[0], dtype=np.bool_)
    nblk = (Xc.shape[0] + BLOCK - 1) // BLOCK
    amb = np.zeros(max(nblk, 1), dtype=np.int64)
    _feasible_kernel(Xc, *plan.args(), BLOCK, out, amb)
    if amb.any():  # batch-dependent RPS/RPU reachability: let NumPy decide
        return mech.is_feasible(X)
    return out[0] if single else out


def margins_fast(mech, X) -> dict:
    """{constraint name: (N,) margin} for all constraints, as ``mech.constraint_margins(X)``
    (-inf where a leg cannot reach the pose or a margin is not finite), by the compiled kernel
    when one covers ``mech``."""
    plan = _plan(mech)
    if plan is None:
        return mech.constraint_margins(X)
    Xa, single = mech._poses(X)
    Xc = np.ascontiguousarray(Xa, dtype=np.float64)
    M = np.empty((Xc.shape[0], len(plan.names)))
    nblk = (Xc.shape[0] + BLOCK - 1) // BLOCK
    amb = np.zeros(max(nblk, 1), dtype=np.int64)
    _margins_kernel(Xc, *plan.args(), BLOCK, M, amb)
    if amb.any():
        return mech.constraint_margins(X)
    return {n: (M[0, j] if single else M[:, j]) for j, n in enumerate(plan.names)}


# ---------------------------------------------------------------------------------------------
# Kernels
# ---------------------------------------------------------------------------------------------
if HAVE_NUMBA:
    _jit = dict(nogil=True, error_model="numpy", fastmath=False, cache=True)
    _jit_inline = dict(_jit, inline="always")

    # The pose travels as a tuple T = (px, py, pz, R00, R01, R02, R10, ..., R22) so that it
    # stays in registers (values stored in scratch arrays would be reloaded after every store,
    # since the compiler cannot prove the arrays do not alias).

    @njit(**_jit_inline)
    def _pose(code, pose_f, X, i):
        """(valid, T) for pose X[i]; valid is False where the parametrisation is not defined
        (the model's ``pose_valid``)."""
        z12 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        for j in range(X.shape[1]):
            if not math.isfinite(X[i, j]):
                return False, z12
        if code == 0:
            # 5pus_upu: p = X[:3]; R = Ry(q1) Rx(alpha) Ry(beta - q1) with
            # q1 = atan2(x, z - upu_base_z); cos q1, sin q1 and cos/sin(beta - q1) taken
            # algebraically (equal to NumPy's arctan2/cos/sin to rounding).
            dx = X[i, 0]
            dz = X[i, 2] - pose_f[0]
            r2 = dx * dx + dz * dz
            if not r2 > 1e-12:
                return False, z12
            r = math.sqrt(r2)
            c1 = dz / r
            s1 = dx / r
            ca = math.cos(X[i, 3])
            sa = math.sin(X[i, 3])
            cb = math.cos(X[i, 4])
            sb = math.sin(X[i, 4])
            cg = cb * c1 + sb * s1  # cos(beta - q1)
            sg = sb * c1 - cb * s1  # sin(beta - q1)
            m02 = s1 * ca
            m22 = c1 * ca
            return True, (X[i, 0], X[i, 1], X[i, 2],
                          c1 * cg - m02 * sg, s1 * sa, c1 * sg + m02 * cg,
                          sa * sg, ca, -sa * cg,
                          -s1 * cg - m22 * sg, c1 * sa, -s1 * sg + m22 * cg)
        if code == 1 or code == 2:
            # 2rpu_2sps: p = (x, 0, z), R = Ry(theta) Rz(0) Rx(psi); coupled: x = z tan(theta)
            if code == 1:
                z = X[i, 0]
                psi = X[i, 1]
                th = X[i, 2]
            else:
                z = X[i, 1]
                psi = X[i, 2]
                th = X[i, 3]
            c = math.cos(th)
            if not abs(c) > 1e-9:
                return False, z12
            s = math.sin(th)
            cp = math.cos(psi)
            sp = math.sin(psi)
            x = z * math.tan(th) if code == 1 else X[i, 0]
            return True, (x, 0.0, z, c, s * sp, s * cp, 0.0, cp, -sp, -s, c * sp, c * cp)
        # code 3, 4ups_1rps: p = (x, y, 0), R = Rz(alpha) Ry(beta) Rz(gamma)
        ca = math.cos(X[i, 2])
        sa = math.sin(X[i, 2])
        cb = math.cos(X[i, 3])
        sb = math.sin(X[i, 3])
        cg = math.cos(X[i, 4])
        sg = math.sin(X[i, 4])
        m00 = ca * cb
        m10 = sa * cb
        return True, (X[i, 0], X[i, 1], 0.0,
                      m00 * cg - sa * sg, m00 * -sg - sa * cg, ca * sb,
                      m10 * cg + ca * sg, m10 * -sg + ca * cg, sa * sb,
                      -sb * cg, -sb * -sg, cb)

    @njit(**_jit_inline)
    def _rot(T, x, y, z):
        """R @ (x, y, z)."""
        return (T[3] * x + T[4] * y + T[5] * z,
                T[6] * x + T[7] * y + T[8] * z,
                T[9] * x + T[10] * y + T[11] * z)

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
        if kind == 1:  # PUS: slider along e through base, link of length L
            ex = leg_f[k, 6]
            ey = leg_f[k, 7]
            ez = leg_f[k, 8]
            L = leg_f[k, 18]
            de = dx * ex + dy * ey + dz * ez
            disc = L * L - ((dx * dx + dy * dy + dz * dz) - de * de)
            if not disc >= 0.0:
                return 1, 0.0, L, bx, by, bz, Ax, Ay, Az
            s = de + leg_f[k, 19] * math.sqrt(disc)
            return 0, s, L, bx + s * ex, by + s * ey, bz + s * ez, Ax, Ay, Az
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

    #: Poses per SIMD sub-block (the scratch of one sub-block stays in the L1 cache).
    SUB = 64

    @njit(**_jit_inline)
    def _clip01(x):
        return min(max(x, 0.0), 1.0)

    @njit(**_jit_inline)
    def _any(m, nb):
        r = False
        for ii in range(nb):
            r |= m[ii] != 0
        return r

    # Vectorisable sin/cos (Cephes sin.c: reduction by pi/4 in three parts, degree-6
    # polynomials; absolute error <= ~2.2e-16, i.e. within an ulp or two of libm) for the
    # SIMD pose stage; arguments beyond 1e6 rad are recomputed with libm.
    _FOPI = 1.27323954473516268615
    _DP1 = 7.85398125648498535156e-1
    _DP2 = 3.77489470793079817668e-8
    _DP3 = 2.69515142907905952645e-15
    _S0, _S1, _S2, _S3, _S4, _S5 = (1.58962301576546568060e-10, -2.50507477628578072866e-8,
                                    2.75573136213857245213e-6, -1.98412698295895385996e-4,
                                    8.33333333332211858878e-3, -1.66666666666666307295e-1)
    _C0, _C1, _C2, _C3, _C4, _C5 = (-1.13585365213876817300e-11, 2.08757008419747316778e-9,
                                    -2.75573141792967388112e-7, 2.48015872888517045348e-5,
                                    -1.38888888888730564116e-3, 4.16666666666665929218e-2)
    _BIG_ANGLE = 1e6

    @njit(**_jit_inline)
    def _sincos(x):
        ax = abs(x)
        y = math.floor(ax * _FOPI)
        y = y + (y - 2.0 * math.floor(y * 0.5))  # next even octant
        j = y - 8.0 * math.floor(y * 0.125)  # octant mod 8: 0, 2, 4 or 6
        z = ((ax - y * _DP1) - y * _DP2) - y * _DP3
        zz = z * z
        ps = z + z * zz * (((((_S0 * zz + _S1) * zz + _S2) * zz + _S3) * zz + _S4) * zz + _S5)
        pc = 1.0 - 0.5 * zz + zz * zz * (((((_C0 * zz + _C1) * zz + _C2) * zz + _C3) * zz + _C4) * zz + _C5)
        swap = (j == 2.0) | (j == 6.0)
        s = pc if swap else ps
        c = ps if swap else pc
        s = -s if (j >= 4.0) != (x < 0.0) else s
        c = -c if (j == 2.0) | (j == 4.0) else c
        return s, c

    @njit(**_jit_inline)
    def _sincos_rows(Xs, col, row, nb, Sn, Cs):
        """Sn[row], Cs[row] = sin, cos of Xs[col] over a sub-block."""
        for ii in range(nb):
            s, c = _sincos(Xs[col, ii])
            Sn[row, ii] = s
            Cs[row, ii] = c
        for ii in range(nb):
            x = Xs[col, ii]
            if abs(x) > _BIG_ANGLE:
                Sn[row, ii] = math.sin(x)
                Cs[row, ii] = math.cos(x)

    @njit(**_jit_inline)
    def _pose_block(code, pose_f, X, j0, nb, coord, okm, Xs, Sn, Cs, Tm):
        """The SIMD form of _pose for poses X[j0:j0+nb]: okm (validity and coordinate
        ranges) and Tm (12, nb) = (p, R row-major)."""
        nt = X.shape[1]
        for ii in range(nb):  # copy to SoA; finiteness; task-coordinate ranges
            i = j0 + ii
            v = True
            for j in range(nt):
                v = v and math.isfinite(X[i, j])
            for q in range(coord.shape[0]):
                x = X[i, int(coord[q, 0])]
                v = v and (x - coord[q, 1] >= 0.0 and coord[q, 2] - x >= 0.0)
            okm[ii] = v
            for j in range(nt):
                Xs[j, ii] = X[i, j] if v else 0.0
        if code == 0:  # 5pus_upu, see _pose
            _sincos_rows(Xs, 3, 0, nb, Sn, Cs)
            _sincos_rows(Xs, 4, 1, nb, Sn, Cs)
            zb = pose_f[0]
            for ii in range(nb):
                dx = Xs[0, ii]
                dz = Xs[2, ii] - zb
                r2 = dx * dx + dz * dz
                okm[ii] = okm[ii] & (r2 > 1e-12)
                r = math.sqrt(r2)
                c1 = dz / r
                s1 = dx / r
                sa = Sn[0, ii]
                ca = Cs[0, ii]
                sb = Sn[1, ii]
                cb = Cs[1, ii]
                cg = cb * c1 + sb * s1
                sg = sb * c1 - cb * s1
                m02 = s1 * ca
                m22 = c1 * ca
                Tm[0, ii] = dx
                Tm[1, ii] = Xs[1, ii]
                Tm[2, ii] = Xs[2, ii]
                Tm[3, ii] = c1 * cg - m02 * sg
                Tm[4, ii] = s1 * sa
                Tm[5, ii] = c1 * sg + m02 * cg
                Tm[6, ii] = sa * sg
                Tm[7, ii] = ca
                Tm[8, ii] = -sa * cg
                Tm[9, ii] = -s1 * cg - m22 * sg
                Tm[10, ii] = c1 * sa
                Tm[11, ii] = -s1 * sg + m22 * cg
        elif code == 1 or code == 2:  # 2rpu_2sps, see _pose
            off = 0 if code == 1 else 1
            _sincos_rows(Xs, 2 + off, 0, nb, Sn, Cs)  # theta
            _sincos_rows(Xs, 1 + off, 1, nb, Sn, Cs)  # psi
            coupled = code == 1
            for ii in range(nb):
                s = Sn[0, ii]
                c = Cs[0, ii]
                sp = Sn[1, ii]
                cp = Cs[1, ii]
                okm[ii] = okm[ii] & (abs(c) > 1e-9)
                z = Xs[off, ii]
                Tm[0, ii] = z * (s / c) if coupled else Xs[0, ii]
                Tm[1, ii] = 0.0
                Tm[2, ii] = z
                Tm[3, ii] = c
                Tm[4, ii] = s * sp
                Tm[5, ii] = s * cp
                Tm[6, ii] = 0.0
                Tm[7, ii] = cp
                Tm[8, ii] = -sp
                Tm[9, ii] = -s
                Tm[10, ii] = c * sp
                Tm[11, ii] = c * cp
        else:  # 4ups_1rps, see _pose
            _sincos_rows(Xs, 2, 0, nb, Sn, Cs)
            _sincos_rows(Xs, 3, 1, nb, Sn, Cs)
            _sincos_rows(Xs, 4, 2, nb, Sn, Cs)
            for ii in range(nb):
                sa = Sn[0, ii]
                ca = Cs[0, ii]
                sb = Sn[1, ii]
                cb = Cs[1, ii]
                sg = Sn[2, ii]
                cg = Cs[2, ii]
                m00 = ca * cb
                m10 = sa * cb
                Tm[0, ii] = Xs[0, ii]
                Tm[1, ii] = Xs[1, ii]
                Tm[2, ii] = 0.0
                Tm[3, ii] = m00 * cg - sa * sg
                Tm[4, ii] = m00 * -sg - sa * cg
                Tm[5, ii] = ca * sb
                Tm[6, ii] = m10 * cg + ca * sg
                Tm[7, ii] = m10 * -sg + ca * cg
                Tm[8, ii] = sa * sb
                Tm[9, ii] = -sb * cg
                Tm[10, ii] = -sb * -sg
                Tm[11, ii] = cb

    @njit(**_jit)
    def _pose_batch(X, code, pose_f, simd):
        """Validity, positions and row-major rotations of poses X by the compiled pose
        (``simd``: the SIMD stage of the boolean kernel, else the scalar _pose)."""
        N = X.shape[0]
        ok = np.zeros(N, dtype=np.bool_)
        p = np.zeros((N, 3))
        R = np.zeros((N, 9))
        if simd:
            nt = X.shape[1]
            okm = np.empty(SUB, dtype=np.uint8)
            Xs = np.empty((nt, SUB))
            Sn = np.empty((3, SUB))
            Cs = np.empty((3, SUB))
            Tm = np.empty((12, SUB))
            coord = np.zeros((0, 4))
            for j0 in range(0, N, SUB):
                nb = min(SUB, N - j0)
                _pose_block(code, pose_f, X, j0, nb, coord, okm, Xs, Sn, Cs, Tm)
                for ii in range(nb):
                    if okm[ii]:
                        ok[j0 + ii] = True
                        for j in range(3):
                            p[j0 + ii, j] = Tm[j, ii]
                        for j in range(9):
                            R[j0 + ii, j] = Tm[3 + j, ii]
            return ok, p, R
        for i in range(N):
            v, T = _pose(code, pose_f, X, i)
            if v:
                ok[i] = True
                for j in range(3):
                    p[i, j] = T[j]
                for j in range(9):
                    R[i, j] = T[3 + j]
        return ok, p, R

    @njit(parallel=True, **_jit)
    def _feasible_kernel(X, code, pose_f, tol, leg_kind, leg_act, leg_f, coord, actr, lenr, cone, rang, axang,
                         centre, pair, offs, block, out, amb):
        """Boolean feasibility of poses X (N, n_task) -> out (N,), amb[block] = number of
        poses whose RPS/RPU reachability NumPy decides batch-dependently.

        Work items (prange) are blocks of ``block`` poses, processed in sub-blocks of SUB
        poses laid out structure-of-arrays: the pose (_pose_block), then leg by leg and check
        by check a straight loop over the sub-block that the compiler vectorises (the leg
        geometry and limits are loop invariants). A sub-block stops as soon as none of its
        poses is feasible; interference, the most expensive check, comes last (see the
        module docstring)."""
        N = X.shape[0]
        nl = leg_kind.shape[0]
        nblk = (N + block - 1) // block
        for blk in prange(nblk):
            Tm = np.empty((12, SUB))
            Xs = np.empty((X.shape[1], SUB))
            Sn = np.empty((3, SUB))
            Cs = np.empty((3, SUB))
            okm = np.empty(SUB, dtype=np.uint8)
            und = np.empty(SUB, dtype=np.uint8)
            Sg = np.empty((nl, 6, SUB))
            Q = np.empty((nl, SUB))
            n_amb = 0
            i1 = min(N, (blk + 1) * block)
            for j0 in range(blk * block, i1, SUB):
                nb = min(SUB, i1 - j0)
                # 1. task-coordinate ranges and the pose (SIMD, own sin/cos)
                _pose_block(code, pose_f, X, j0, nb, coord, okm, Xs, Sn, Cs, Tm)
                for ii in range(nb):
                    und[ii] = 0
                # 2. leg by leg: inverse kinematics, then that leg's checks
                for k in range(nl):
                    if not _any(okm, nb):
                        break
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
                    if kind == 1:  # PUS: slider along e through base, link of length L
                        L = leg_f[k, 18]
                        br = leg_f[k, 19]
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
                            okm[ii] = okm[ii] & (disc >= 0.0)
                            Q[k, ii] = s
                            Sg[k, 0, ii] = bx + s * ex
                            Sg[k, 1, ii] = by + s * ey
                            Sg[k, 2, ii] = bz + s * ez
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
                        if kind == 1:
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
                            ln = leg_f[k, 18] if kind == 1 else Q[k, ii]
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
                # 3. platform y axis against the position vector of the platform centre
                for q in range(centre.shape[0]):
                    ch = centre[q, 2]
                    for ii in range(nb):
                        px = Tm[0, ii]
                        py = Tm[1, ii]
                        pz = Tm[2, ii]
                        nrm = math.sqrt(px * px + py * py + pz * pz)
                        c = (px / nrm) * Tm[4, ii] + (py / nrm) * Tm[7, ii] + (pz / nrm) * Tm[10, ii]
                        c = 1.0 if c > 1.0 else c
                        c = -1.0 if c < -1.0 else c
                        okm[ii] = okm[ii] & (c >= ch)
                # 4. leg interference, last: segment-segment distance (spatial.segment_distance,
                # branch-free) compared squared
                for q in range(pair.shape[0]):
                    if not _any(okm, nb):
                        break
                    ka = int(pair[q, 0])
                    kb = int(pair[q, 1])
                    Dq = pair[q, 2]
                    D2 = pair[q, 4]
                    # Bounding boxes at least D apart along an axis prove the distance >= D
                    # (exactly: the distance is at least that gap); only if some feasible pose
                    # of the sub-block is not settled so is the distance computed.
                    need = 0
                    for ii in range(nb):
                        gap = -1.0
                        for c in range(3):
                            u = Sg[ka, c, ii]
                            v = Sg[ka, 3 + c, ii]
                            a_lo = u if u < v else v
                            a_hi = v if u < v else u
                            u = Sg[kb, c, ii]
                            v = Sg[kb, 3 + c, ii]
                            b_lo = u if u < v else v
                            b_hi = v if u < v else u
                            g1 = b_lo - a_hi
                            g2 = a_lo - b_hi
                            g = g1 if g1 > g2 else g2
                            gap = g if g > gap else gap
                        need |= okm[ii] & (gap < Dq)
                    if not need:
                        continue
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
                        if denom > 1e-12 * max(a * e, 1e-300):
                            s = _clip01((b * f - c * e) / denom)
                            t = (b * s + f) / e if e > 1e-300 else 0.0
                            s_lo = _clip01(-c / a) if a > 1e-300 else 0.0
                            s_hi = _clip01((b - c) / a) if a > 1e-300 else 0.0
                            s = s_lo if t < 0.0 else (s_hi if t > 1.0 else s)
                            t = _clip01(t)
                            cx = (p1x + s * d1x) - (p2x + t * d2x)
                            cy = (p1y + s * d1y) - (p2y + t * d2y)
                            cz = (p1z + s * d1z) - (p2z + t * d2z)
                            dist2 = cx * cx + cy * cy + cz * cz
                        else:
                            dist2 = _parallel_seg2(p1x, p1y, p1z, d1x, d1y, d1z, a, p2x, p2y, p2z, d2x, d2y, d2z, e)
                        okm[ii] = okm[ii] & (dist2 >= D2)
                for ii in range(nb):
                    out[j0 + ii] = okm[ii] != 0
                    n_amb += okm[ii] & und[ii]
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

    @njit(parallel=True, **_jit)
    def _margins_kernel(X, code, pose_f, tol, leg_kind, leg_act, leg_f, coord, actr, lenr, cone, rang, axang,
                        centre, pair, offs, block, M, amb):
        """All constraint margins with NumPy's formulas (arctan2, arccos, sqrt), no early
        exit -- Mechanism.constraint_margins."""
        N = X.shape[0]
        nl = leg_kind.shape[0]
        nc = M.shape[1]
        nblk = (N + block - 1) // block
        for blk in prange(nblk):
            seg = np.empty((nl, 6))
            lens = np.empty(nl)
            qv = np.empty(nl)
            nvec = np.empty((nl, 3))
            n_amb = 0
            i1 = min(N, (blk + 1) * block)
            for i in range(blk * block, i1):
                reach, T = _pose(code, pose_f, X, i)
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
                        if leg_kind[k] != 1:
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
                for q in range(centre.shape[0]):
                    nrm = math.sqrt(T[0] * T[0] + T[1] * T[1] + T[2] * T[2])
                    c = (T[0] / nrm) * T[4] + (T[1] / nrm) * T[7] + (T[2] / nrm) * T[10]
                    _upd(M, i, int(centre[q, 1]), centre[q, 0] - math.acos(_clip1(c)))
                # interference: min distance over the pairs, minus the diameter
                for q in range(pair.shape[0]):
                    d = math.sqrt(_seg_dist2(seg, int(pair[q, 0]), int(pair[q, 1])))
                    _upd(M, i, int(pair[q, 3]), d - pair[q, 2])
                for j in range(nc):
                    if not math.isfinite(M[i, j]):
                        M[i, j] = -np.inf
            amb[blk] = n_amb
