"""Fused compiled feasibility kernels (numba), with the NumPy path as the reference.

:meth:`Mechanism.is_feasible` evaluates a pose batch stage by stage: the pose, every leg's
inverse kinematics, then each constraint over the whole batch, with (N,)- and (N, 3)-sized
temporaries at every step. Here the same test is one compiled pass over the poses
(``numba.njit(parallel=True)``, ``prange`` over blocks of poses): per pose the rotation,
each leg's inverse kinematics and every declared constraint are evaluated on scalars, the
cheapest checks first, and the pose is rejected at the first violated one. Nothing of size N
is allocated except the result.

Entry points
------------
* :func:`feasible_fast` ``(mech, X)`` -> (N,) bool, the same as ``mech.is_feasible(X)``.
* :func:`margins_fast` ``(mech, X)`` -> {constraint name: (N,) margins}, the same as
  ``mech.constraint_margins(X)`` (all constraints, no early exit; -inf where unreachable).
* :func:`kernel_available` ``(mech)`` -> whether a kernel covers this mechanism.

Both fall back silently to the NumPy methods when numba is not importable (or the
environment variable ``PARASYNTH_NO_NUMBA`` is set), when the model has no kernel, or when
its legs or constraints include something the kernel does not implement (then nothing is
guessed: the NumPy path decides).

Coverage: the models ``5pus_upu``, ``2rpu_2sps`` (coupled and uncoupled) and ``4ups_1rps``.
The kernel is generic in the geometry: it reads, at every call, the legs' anchors, slider
axes, link lengths, branches, revolute and universal-joint axes, the neutral directions
``base_ref``/``platform_ref`` and all limits from the mechanism and its ``constraints`` dict,
so any parameter change is reflected. Only the task-space parametrisation (the model's
``pose``) is compiled in, and it is checked against ``mech.pose`` on a few poses before use.
Supported constraints: :class:`ActuatorRange`, :class:`LegLengthRange`,
:class:`CoordinateRange`, :class:`JointAngleLimit` on the cone angles (``*_base_cone``,
``*_platform_cone``) and the revolute angle ``R_base``, :class:`LegAxisAngle`,
:class:`LegInterference` and the grinding robot's centre-axis angle.

Agreement with the NumPy path
-----------------------------
The kernel evaluates the same formulas in float64 without fastmath, but not always in the
same arithmetic form: to avoid ``arctan2``/``arccos``/``sqrt`` in the boolean kernel, an
angle limit ``angle(u, v) <= hi`` is tested as ``sin(hi) (u.v) - cos(hi) |u x v| >= 0``
(squared, sign-aware), ``arccos(c) <= hi`` as ``c >= cos(hi)``, and a distance limit
``d >= D`` as ``d^2 >= D^2``; also libm and NumPy's own ``sin``/``cos`` may differ by an ulp,
and NumPy's matrix products may sum in another order. Results therefore agree exactly except
at poses within rounding of a constraint boundary: the documented (and tested) contract is
that ``feasible_fast`` and ``is_feasible`` can disagree only at poses where the NumPy
feasibility margin -- the smallest of the leg reachability margins (the PUS discriminant
``L^2 - d_perp^2``, m^2) and the constraint margins -- is within 1e-12 of zero.
:func:`margins_fast` uses the NumPy formulas (``arctan2``, ``arccos``, ``sqrt``) and agrees with
``constraint_margins`` to a few ulps.

One NumPy behaviour is batch dependent: RPS/RPU legs accept an off-plane error up to
``GEOM_TOL * max(1, largest leg length in the batch)``. The kernel decides reachability
itself whenever that does not matter (off-plane error <= GEOM_TOL, always the case in the
built-in models, where it is exactly 0) and otherwise hands the whole batch to NumPy.
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
_POSE_YX, _POSE_2T2R_COUPLED, _POSE_2T2R, _POSE_ZYZ = 0, 1, 2, 3

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

#: Poses per parallel work item (one scratch allocation per block).
BLOCK = 1024


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
    """

    def __init__(self, pose_code, leg_kind, leg_act, leg_f, names, tables):
        self.pose_code = int(pose_code)
        self.leg_kind = leg_kind
        self.leg_act = leg_act
        self.leg_f = leg_f
        self.names = tuple(names)
        self.tables = tables  # dict name -> (k, m) float64

    def args(self):
        t = self.tables
        return (self.pose_code, self.leg_kind, self.leg_act, self.leg_f, t["coord"], t["actr"], t["lenr"],
                t["cone"], t["rang"], t["axang"], t["centre"], t["pair"])


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
        return _POSE_YX
    if t is RPU2SPS2:
        return _POSE_2T2R_COUPLED if mech.params.coupled else _POSE_2T2R
    if t is UPSRPSGrinding:
        return _POSE_ZYZ
    raise _Unsupported(f"no kernel for model {t.__name__}")


def _pose_numpy(code: int, X: np.ndarray):
    """The compiled parametrisations in NumPy (used to verify them against ``mech.pose``)."""
    N = X.shape[0]
    p = np.zeros((N, 3))
    R = np.zeros((N, 3, 3))
    if code == _POSE_YX:
        p[:] = X[:, :3]
        al, be = X[:, 3], X[:, 4]
        ca, sa, cb, sb = np.cos(al), np.sin(al), np.cos(be), np.sin(be)
        R[:] = np.stack([cb, sb * sa, sb * ca, 0 * ca, ca, -sa, -sb, cb * sa, cb * ca], -1).reshape(N, 3, 3)
    elif code in (_POSE_2T2R_COUPLED, _POSE_2T2R):
        if code == _POSE_2T2R_COUPLED:
            z, psi, th = X[:, 0], X[:, 1], X[:, 2]
            x = z * np.tan(th)
        else:
            x, z, psi, th = X[:, 0], X[:, 1], X[:, 2], X[:, 3]
        p[:, 0], p[:, 2] = x, z
        c, s, cp, sp = np.cos(th), np.sin(th), np.cos(psi), np.sin(psi)
        R[:] = np.stack([c, s * sp, s * cp, 0 * c, cp, -sp, -s, c * sp, c * cp], -1).reshape(N, 3, 3)
    else:
        p[:, 0], p[:, 1] = X[:, 0], X[:, 1]
        ca, sa = np.cos(X[:, 2]), np.sin(X[:, 2])
        cb, sb = np.cos(X[:, 3]), np.sin(X[:, 3])
        cg, sg = np.cos(X[:, 4]), np.sin(X[:, 4])
        m00, m01, m02 = ca * cb, -sa, ca * sb
        m10, m11, m12 = sa * cb, ca, sa * sb
        m20, m21, m22 = -sb, 0 * ca, cb
        R[:] = np.stack([m00 * cg + m01 * sg, m00 * -sg + m01 * cg, m02,
                         m10 * cg + m11 * sg, m10 * -sg + m11 * cg, m12,
                         m20 * cg + m21 * sg, m20 * -sg + m21 * cg, m22], -1).reshape(N, 3, 3)
    return p, R


def _check_pose_code(mech, code: int) -> None:
    """Compare the compiled parametrisation with ``mech.pose`` (guards against a model whose
    convention changed since the kernel was written)."""
    rng = np.random.default_rng(7)
    n = mech.n_task
    X = mech.home + rng.uniform(-0.3, 0.3, size=(16, n))
    X = np.vstack([mech.home, X])
    valid = mech.pose_valid(X)
    p0, R0 = mech.pose(X[valid])
    p1, R1 = _pose_numpy(code, X[valid])
    if not (np.allclose(p0, p1, rtol=0, atol=1e-12) and np.allclose(R0, R1, rtol=0, atol=1e-12)):
        raise _Unsupported(f"{mech.name}: compiled pose parametrisation does not match mech.pose")


def _angle_modes(lo: float, hi: float):
    """Encode cone-angle bounds [lo, hi] (rad, angle in [0, pi]) for the boolean test."""
    if not (np.isfinite(hi) or hi == np.inf) or np.isnan(lo) or np.isnan(hi):
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
    _check_pose_code(mech, code)
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
            if c.frame not in ("base", "platform"):
                raise _Unsupported(f"LegAxisAngle frame {c.frame!r}")
            a = np.asarray(c.axis, dtype=float)
            a = a / np.linalg.norm(a)
            for n in c.legs:
                rows["axang"].append((index[n], *a, 1.0 if c.frame == "platform" else 0.0, c.hi, ci,
                                      _cos_limit(float(c.hi))))
        elif t is LegInterference:
            D = float(c.diameter)
            for a_, b_ in c._pairs(names):
                rows["pair"].append((index[a_], index[b_], D, ci, D * D if D > 0 else -1.0))
        elif t.__name__ == "_CentreAxisAngle" and t.__module__.endswith("ups_rps_grinding") and code == _POSE_ZYZ:
            rows["centre"].append((c.hi, ci, _cos_limit(float(c.hi))))
        else:
            raise _Unsupported(f"constraint type {t.__name__}")
    widths = {"coord": 4, "actr": 3, "lenr": 4, "cone": 11, "rang": 10, "axang": 8, "centre": 3, "pair": 5}
    tables = {k: _table(v, widths[k]) for k, v in rows.items()}
    return KernelPlan(code, kind, act, np.ascontiguousarray(F), [c.name for c in cons], tables)


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
    except (_Unsupported, KeyError, AttributeError, ImportError):
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

    @njit(**_jit_inline)
    def _pose(code, X, i, P):
        """Platform position P[0:3] and rotation P[3:12] (row-major) of pose X[i]; False if
        the parametrisation is not defined there (Mechanism.pose_valid)."""
        for j in range(X.shape[1]):
            if not math.isfinite(X[i, j]):
                return False
        if code == 0:  # 5pus_upu: p = X[:3], R = Ry(beta) Rx(alpha)
            ca = math.cos(X[i, 3])
            sa = math.sin(X[i, 3])
            cb = math.cos(X[i, 4])
            sb = math.sin(X[i, 4])
            P[0] = X[i, 0]
            P[1] = X[i, 1]
            P[2] = X[i, 2]
            P[3] = cb
            P[4] = sb * sa
            P[5] = sb * ca
            P[6] = 0.0
            P[7] = ca
            P[8] = -sa
            P[9] = -sb
            P[10] = cb * sa
            P[11] = cb * ca
            return True
        if code == 1 or code == 2:  # 2rpu_2sps: p = (x, 0, z), R = Ry(theta) Rz(0) Rx(psi)
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
                return False
            s = math.sin(th)
            cp = math.cos(psi)
            sp = math.sin(psi)
            P[0] = z * math.tan(th) if code == 1 else X[i, 0]
            P[1] = 0.0
            P[2] = z
            P[3] = c
            P[4] = s * sp
            P[5] = s * cp
            P[6] = 0.0
            P[7] = cp
            P[8] = -sp
            P[9] = -s
            P[10] = c * sp
            P[11] = c * cp
            return True
        # code 3, 4ups_1rps: p = (x, y, 0), R = Rz(alpha) Ry(beta) Rz(gamma)
        ca = math.cos(X[i, 2])
        sa = math.sin(X[i, 2])
        cb = math.cos(X[i, 3])
        sb = math.sin(X[i, 3])
        cg = math.cos(X[i, 4])
        sg = math.sin(X[i, 4])
        m00 = ca * cb
        m10 = sa * cb
        P[0] = X[i, 0]
        P[1] = X[i, 1]
        P[2] = 0.0
        P[3] = m00 * cg - sa * sg
        P[4] = m00 * -sg - sa * cg
        P[5] = ca * sb
        P[6] = m10 * cg + ca * sg
        P[7] = m10 * -sg + ca * cg
        P[8] = sa * sb
        P[9] = -sb * cg
        P[10] = -sb * -sg
        P[11] = cb
        return True

    @njit(**_jit_inline)
    def _leg(k, kind, leg_f, P, seg):
        """Inverse kinematics of leg k: seg[k] = (base joint centre, platform joint centre),
        returns (status, actuator value, length): status 0 reachable, 1 unreachable,
        2 undecidable here (batch-dependent RPS/RPU tolerance)."""
        a0 = leg_f[k, 3]
        a1 = leg_f[k, 4]
        a2 = leg_f[k, 5]
        Ax = P[0] + (P[3] * a0 + P[4] * a1 + P[5] * a2)
        Ay = P[1] + (P[6] * a0 + P[7] * a1 + P[8] * a2)
        Az = P[2] + (P[9] * a0 + P[10] * a1 + P[11] * a2)
        seg[k, 3] = Ax
        seg[k, 4] = Ay
        seg[k, 5] = Az
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
                return 1, 0.0, L
            s = de + leg_f[k, 19] * math.sqrt(disc)
            seg[k, 0] = bx + s * ex
            seg[k, 1] = by + s * ey
            seg[k, 2] = bz + s * ez
            return 0, s, L
        seg[k, 0] = bx
        seg[k, 1] = by
        seg[k, 2] = bz
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        if not length > 0.0:
            return 1, length, length
        if kind == 0:
            return 0, length, length
        rx = leg_f[k, 6]
        ry = leg_f[k, 7]
        rz = leg_f[k, 8]
        if kind == 3:  # RPU: platform axis must be normal to the revolute axis
            ux = leg_f[k, 9]
            uy = leg_f[k, 10]
            uz = leg_f[k, 11]
            a4x = P[3] * ux + P[4] * uy + P[5] * uz
            a4y = P[6] * ux + P[7] * uy + P[8] * uz
            a4z = P[9] * ux + P[10] * uy + P[11] * uz
            if not abs(a4x * rx + a4y * ry + a4z * rz) <= 1e-9:
                return 1, length, length
        off = abs(dx * rx + dy * ry + dz * rz)
        if off <= 1e-9:
            return 0, length, length
        if not off == off:
            return 1, length, length
        return 2, length, length

    @njit(**_jit_inline)
    def _cone_vectors(leg, end, leg_f, P, seg):
        """(u, v) whose angle is the cone angle of ``end`` (0 base, 1 platform) of ``leg``:
        base: (leg vector, base_ref); platform: (-leg vector, R @ platform_ref)."""
        wx = seg[leg, 3] - seg[leg, 0]
        wy = seg[leg, 4] - seg[leg, 1]
        wz = seg[leg, 5] - seg[leg, 2]
        if end == 0:
            return wx, wy, wz, leg_f[leg, 12], leg_f[leg, 13], leg_f[leg, 14]
        r0 = leg_f[leg, 15]
        r1 = leg_f[leg, 16]
        r2 = leg_f[leg, 17]
        vx = P[3] * r0 + P[4] * r1 + P[5] * r2
        vy = P[6] * r0 + P[7] * r1 + P[8] * r2
        vz = P[9] * r0 + P[10] * r1 + P[11] * r2
        return -wx, -wy, -wz, vx, vy, vz

    @njit(**_jit_inline)
    def _seg_dist2(seg, i, j):
        """Squared distance between segments seg[i] and seg[j] (spatial.segment_distance)."""
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
            s = 0.0
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
    def _cone_ok(ux, uy, uz, vx, vy, vz, lo_mode, hi_mode, sl2, cl2, sh2, ch2):
        """lo <= angle(u, v) <= hi without arctan2: angle <= hi iff
        sin(hi) (u.v) - cos(hi) |u x v| >= 0 (hi in (0, pi)); likewise for lo."""
        dot = ux * vx + uy * vy + uz * vz
        cx = uy * vz - uz * vy
        cy = uz * vx - ux * vz
        cz = ux * vy - uy * vx
        cr2 = cx * cx + cy * cy + cz * cz
        d2 = dot * dot
        if hi_mode == 1:
            if not (dot >= 0.0 and sh2 * d2 >= ch2 * cr2):
                return False
        elif hi_mode == 2:
            if not (dot >= 0.0 or ch2 * cr2 >= sh2 * d2):
                return False
        if lo_mode == 1:
            if not (dot <= 0.0 or cl2 * cr2 >= sl2 * d2):
                return False
        elif lo_mode == 2:
            if not (dot <= 0.0 and sl2 * d2 >= cl2 * cr2):
                return False
        return True

    @njit(parallel=True, **_jit)
    def _feasible_kernel(X, code, leg_kind, leg_act, leg_f, coord, actr, lenr, cone, rang, axang, centre,
                         pair, block, out, amb):
        N = X.shape[0]
        nl = leg_kind.shape[0]
        nblk = (N + block - 1) // block
        for blk in prange(nblk):
            P = np.empty(12)
            seg = np.empty((nl, 6))
            lens = np.empty(nl)
            n_amb = 0
            i1 = min(N, (blk + 1) * block)
            for i in range(blk * block, i1):
                ok = True
                # 1. task-coordinate ranges (no kinematics needed)
                for q in range(coord.shape[0]):
                    x = X[i, int(coord[q, 0])]
                    if not (x - coord[q, 1] >= 0.0 and coord[q, 2] - x >= 0.0):
                        ok = False
                        break
                if ok:
                    ok = _pose(code, X, i, P)
                # 2. legs: reachability and actuator ranges, leg by leg
                undecided = False
                if ok:
                    for k in range(nl):
                        st, q_act, length = _leg(k, leg_kind[k], leg_f, P, seg)
                        lens[k] = length
                        if st == 1:
                            ok = False
                            break
                        if st == 2:
                            undecided = True
                        if leg_act[k] == 1:
                            for q in range(actr.shape[0]):
                                if not (q_act - actr[q, 0] >= 0.0 and actr[q, 1] - q_act >= 0.0):
                                    ok = False
                                    break
                            if not ok:
                                break
                # 3. passive leg lengths
                if ok:
                    for q in range(lenr.shape[0]):
                        ln = lens[int(lenr[q, 0])]
                        if not (ln - lenr[q, 1] >= 0.0 and lenr[q, 2] - ln >= 0.0):
                            ok = False
                            break
                # 4. cone angles of the passive joints
                if ok:
                    for q in range(cone.shape[0]):
                        ux, uy, uz, vx, vy, vz = _cone_vectors(int(cone[q, 0]), int(cone[q, 1]), leg_f, P, seg)
                        if not _cone_ok(ux, uy, uz, vx, vy, vz, int(cone[q, 5]), int(cone[q, 6]),
                                        cone[q, 7], cone[q, 8], cone[q, 9], cone[q, 10]):
                            ok = False
                            break
                # 5. leg axis against a base or platform axis: arccos(n.a) <= hi
                if ok:
                    for q in range(axang.shape[0]):
                        k = int(axang[q, 0])
                        wx = seg[k, 3] - seg[k, 0]
                        wy = seg[k, 4] - seg[k, 1]
                        wz = seg[k, 5] - seg[k, 2]
                        ax = axang[q, 1]
                        ay = axang[q, 2]
                        az = axang[q, 3]
                        if axang[q, 4] == 1.0:
                            bx = P[3] * ax + P[4] * ay + P[5] * az
                            by = P[6] * ax + P[7] * ay + P[8] * az
                            bz = P[9] * ax + P[10] * ay + P[11] * az
                        else:
                            bx = ax
                            by = ay
                            bz = az
                        if not (wx * bx + wy * by + wz * bz >= axang[q, 7] * lens[k]):
                            ok = False
                            break
                # 6. platform y axis against the centre's position vector
                if ok:
                    for q in range(centre.shape[0]):
                        nrm = math.sqrt(P[0] * P[0] + P[1] * P[1] + P[2] * P[2])
                        c = (P[0] / nrm) * P[4] + (P[1] / nrm) * P[7] + (P[2] / nrm) * P[10]
                        if not (min(max(c, -1.0), 1.0) >= centre[q, 2]):
                            ok = False
                            break
                # 7. signed revolute angles (atan2 on the leg vector)
                if ok:
                    for q in range(rang.shape[0]):
                        k = int(rang[q, 0])
                        wx = seg[k, 3] - seg[k, 0]
                        wy = seg[k, 4] - seg[k, 1]
                        wz = seg[k, 5] - seg[k, 2]
                        ang = math.atan2(wx * rang[q, 4] + wy * rang[q, 5] + wz * rang[q, 6],
                                         wx * rang[q, 1] + wy * rang[q, 2] + wz * rang[q, 3])
                        if not (ang - rang[q, 7] >= 0.0 and rang[q, 8] - ang >= 0.0):
                            ok = False
                            break
                # 8. leg interference (most expensive, last)
                if ok:
                    for q in range(pair.shape[0]):
                        if not (_seg_dist2(seg, int(pair[q, 0]), int(pair[q, 1])) >= pair[q, 4]):
                            ok = False
                            break
                if ok and undecided:
                    n_amb += 1
                out[i] = ok
            amb[blk] = n_amb

    @njit(**_jit_inline)
    def _upd(M, i, ci, m):
        if m < M[i, ci] or m != m:
            M[i, ci] = m

    @njit(parallel=True, **_jit)
    def _margins_kernel(X, code, leg_kind, leg_act, leg_f, coord, actr, lenr, cone, rang, axang, centre,
                        pair, block, M, amb):
        """All constraint margins, NumPy's formulas, no early exit (constraint_margins)."""
        N = X.shape[0]
        nl = leg_kind.shape[0]
        nc = M.shape[1]
        nblk = (N + block - 1) // block
        for blk in prange(nblk):
            P = np.empty(12)
            seg = np.empty((nl, 6))
            lens = np.empty(nl)
            qv = np.empty(nl)
            nvec = np.empty((nl, 3))
            n_amb = 0
            i1 = min(N, (blk + 1) * block)
            for i in range(blk * block, i1):
                reach = _pose(code, X, i, P)
                undecided = False
                if reach:
                    for k in range(nl):
                        st, q_act, length = _leg(k, leg_kind[k], leg_f, P, seg)
                        lens[k] = length
                        qv[k] = q_act
                        if st == 1:
                            reach = False
                            break
                        if st == 2:
                            undecided = True
                        # unit leg direction as the legs compute it
                        wx = seg[k, 3] - seg[k, 0]
                        wy = seg[k, 4] - seg[k, 1]
                        wz = seg[k, 5] - seg[k, 2]
                        if leg_kind[k] == 1:
                            nvec[k, 0] = wx / length
                            nvec[k, 1] = wy / length
                            nvec[k, 2] = wz / length
                        else:
                            nn = math.sqrt(wx * wx + wy * wy + wz * wz)
                            nvec[k, 0] = wx / nn
                            nvec[k, 1] = wy / nn
                            nvec[k, 2] = wz / nn
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
                    _upd(M, i, int(coord[q, 3]), min(x - coord[q, 1], coord[q, 2] - x))
                for k in range(nl):
                    if leg_act[k] == 1:
                        for q in range(actr.shape[0]):
                            _upd(M, i, int(actr[q, 2]), min(qv[k] - actr[q, 0], actr[q, 1] - qv[k]))
                for q in range(lenr.shape[0]):
                    ln = lens[int(lenr[q, 0])]
                    _upd(M, i, int(lenr[q, 3]), min(ln - lenr[q, 1], lenr[q, 2] - ln))
                for q in range(cone.shape[0]):
                    k = int(cone[q, 0])
                    ux = nvec[k, 0]
                    uy = nvec[k, 1]
                    uz = nvec[k, 2]
                    if int(cone[q, 1]) == 0:
                        vx = leg_f[k, 12]
                        vy = leg_f[k, 13]
                        vz = leg_f[k, 14]
                    else:
                        ux = -ux
                        uy = -uy
                        uz = -uz
                        r0 = leg_f[k, 15]
                        r1 = leg_f[k, 16]
                        r2 = leg_f[k, 17]
                        vx = P[3] * r0 + P[4] * r1 + P[5] * r2
                        vy = P[6] * r0 + P[7] * r1 + P[8] * r2
                        vz = P[9] * r0 + P[10] * r1 + P[11] * r2
                    cx = uy * vz - uz * vy
                    cy = uz * vx - ux * vz
                    cz = ux * vy - uy * vx
                    ang = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ux * vx + uy * vy + uz * vz)
                    _upd(M, i, int(cone[q, 4]), min(ang - cone[q, 2], cone[q, 3] - ang))
                for q in range(rang.shape[0]):
                    k = int(rang[q, 0])
                    ang = math.atan2(nvec[k, 0] * rang[q, 4] + nvec[k, 1] * rang[q, 5] + nvec[k, 2] * rang[q, 6],
                                     nvec[k, 0] * rang[q, 1] + nvec[k, 1] * rang[q, 2] + nvec[k, 2] * rang[q, 3])
                    _upd(M, i, int(rang[q, 9]), min(ang - rang[q, 7], rang[q, 8] - ang))
                for q in range(axang.shape[0]):
                    k = int(axang[q, 0])
                    ax = axang[q, 1]
                    ay = axang[q, 2]
                    az = axang[q, 3]
                    if axang[q, 4] == 1.0:
                        bx = P[3] * ax + P[4] * ay + P[5] * az
                        by = P[6] * ax + P[7] * ay + P[8] * az
                        bz = P[9] * ax + P[10] * ay + P[11] * az
                    else:
                        bx = ax
                        by = ay
                        bz = az
                    c = nvec[k, 0] * bx + nvec[k, 1] * by + nvec[k, 2] * bz
                    _upd(M, i, int(axang[q, 6]), axang[q, 5] - math.acos(min(max(c, -1.0), 1.0)))
                for q in range(centre.shape[0]):
                    nrm = math.sqrt(P[0] * P[0] + P[1] * P[1] + P[2] * P[2])
                    c = (P[0] / nrm) * P[4] + (P[1] / nrm) * P[7] + (P[2] / nrm) * P[10]
                    _upd(M, i, int(centre[q, 1]), centre[q, 0] - math.acos(min(max(c, -1.0), 1.0)))
                # interference: min distance per constraint, then minus the diameter
                for q in range(pair.shape[0]):
                    ci = int(pair[q, 3])
                    d = math.sqrt(_seg_dist2(seg, int(pair[q, 0]), int(pair[q, 1])))
                    _upd(M, i, ci, d - pair[q, 2])
                for j in range(nc):
                    if not math.isfinite(M[i, j]):
                        M[i, j] = -np.inf
            amb[blk] = n_amb
