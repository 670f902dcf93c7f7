"""Compiled pose-wise indices: singularity margin, local transmission index, condition number.

The NumPy reference builds the legs' wrench system for a whole batch of poses with (N, k, 6)
temporaries and then calls LAPACK on the stack. Here one compiled pass (``numba.njit``,
``nogil``, float64, no fastmath) takes the platform poses and, pose by pose, forms the
same wrench rows from the legs' geometry and runs small decompositions on them in scratch
arrays that stay in the L1 cache:

* the legs' **actuation wrenches** (a unit force along the leg's transmission line through its
  platform anchor, ``rate_scale`` = ``n . e`` for slider legs, ``n . (r_axis x (C - base))``
  for a RUS crank whose link leaves its tip ``C`` (:func:`parasynth.engine.core.crank_tip`),
  and 1 otherwise) and **constraint wrenches**, analytic wherever :mod:`parasynth.model.legs` is
  analytic (RPS and PRS: a force along the revolute axis through the sphere centre; RPU: that force and a couple about
  ``r_axis x R u_platform_axis``), and for UPU legs the numeric reciprocal of the five joint
  twists, as :meth:`parasynth.model.legs.UPU.constraint_wrenches` computes it (moments of the twists
  scaled by the batch-mean leg length, null direction, unit force or unit couple); the null
  direction comes from a Householder QR of the 6 x 5 twist matrix instead of an SVD (the
  direction is the same up to sign and rounding, and every index below is invariant to the
  sign of a constraint row);
* singular values by the **one-sided Jacobi** method (Hestenes), which computes small singular
  values to high relative accuracy -- no eigenvalues of Gram matrices. Column pairs are
  visited in round-robin order (consecutive rotations independent).

Transmission indices: each actuated leg's output twist spans the twists reciprocal to every
other row of the wrench system. When that system is square (n_act + n_c = 6) and well
conditioned (smallest singular value above 1e-6 of the largest) one SVD serves every leg: the
twist is the leg's column of the inverse, ``V S^-1 U^T e_i`` (by interlacing the other rows
then have rank 5 at the NumPy path's 1e-9 threshold, so the NumPy path finds the same
one-dimensional set); otherwise each leg gets the SVD of its other rows, as in NumPy.

Batches of at least :data:`PARALLEL_MIN` poses are spread over threads (ranges of chunks taken
by the calling thread and the engine's crew, :func:`parasynth.engine.core.over_blocks`); smaller ones serially, where starting
threads would cost more than it saves -- except for the singularity margin, whose ~3 us a pose
make a design's few hundred feasible poses worth two threads (ranges of poses, while
``core.TIMING`` finds that threads pay; see :func:`_kernel`).

Every function is generic over the leg types ``SPS, UPS, PUS, RPS, RPU, UPU, PRS, RUS`` and
chain limbs (:class:`parasynth.model.chains.ChainLeg`); nothing is written per model class. A
chain limb's rows come from its compiled inverse kinematics (:mod:`parasynth.engine.chains`):
``_chain_rows_kernel`` writes, per pose, its joint twists about the platform reference point,
its constraint wrenches (the right singular vectors of the smallest singular values of the
twists, moments scaled by the limb's length: one-sided Jacobi), its actuation wrench
(reciprocal to the passive twists, out of the constraint span, signed by its power on the
actuated twist) and direction into an array ``ext`` that every kernel reads at the limb's
offset, as ``ChainLeg.constraint_wrenches`` / ``actuation_wrench`` compute them (the basis of
several constraint wrenches is the SVD's, unique for the vocabulary's limbs, which have at most
one). The platform pose and the twist map come from the model's own
``pose``/``twist_map`` (vectorised NumPy), or, for a described mechanism, from its compiled
program (:func:`parasynth.engine.evaluate.compiled_pose_batch`).

Entry points (each ``(mech, X)`` with poses ``X`` (N, n_task), results as the NumPy methods):

* :func:`singularity_margin` -- :meth:`Mechanism.singularity_margin`;
* :func:`transmission` -- input/output indices and LTI of
  :func:`parasynth.measures.indices.transmission_indices`;
* :func:`local_transmission_index` -- its LTI;
* :func:`condition_number` -- :func:`parasynth.measures.indices.local_condition_number` in the task
  space;
* :func:`leg_directions` -- unit leg directions (the inputs of the pressure-angle indices);
* :func:`coverage` -- ``(True, "")`` or ``(False, reason)``: whether the kernels cover a
  mechanism (a leg type other than the seven above, a subclass that overrides a leg's or the
  mechanism's wrench methods, or numba unavailable are not covered).

Agreement with the NumPy reference (``tests/engine/test_engine_indices.py``): within 1e-9 absolute
for the margin and the transmission indices (values in [0, 1]) and 1e-9 relative for
condition numbers, over random poses of every shipped mechanism. Exactly as in NumPy, ranks
use relative thresholds on singular values, so poses within rounding of a threshold (an exact
singularity) may fall on either side.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.chains import IK_TOL, ChainLeg
from ..model.legs import GEOM_TOL, PRS, PUS, RPS, RPU, RUS, SPS, UPS, UPU, Leg, require
from ..model.mechanism import Mechanism
from .chains import REACH_FACTOR
from .chains import solve_arrays as chain_solve_arrays
from .evaluate import _kernel_poses, compiled_pose_batch

__all__ = [
    "HAVE_NUMBA",
    "coverage",
    "singularity_margin",
    "transmission",
    "local_transmission_index",
    "condition_number",
    "leg_directions",
    "constraint_rank",
    "warn_fallback",
]


# One decision (PARASYNTH_NO_NUMBA, a broken install), one fallback policy and warning
# (warn_fallback, said once per what, model class and reason) and one per-mechanism record of
# plans (record_of) for the whole engine.
from . import core
from .core import _WARNED, HAVE_NUMBA, _array, over_blocks, record_of, warn_fallback  # noqa: F401

#: A chain limb's rows (two one-sided Jacobi SVDs of its joint twists) cost ~2 us a pose on one
#: core (a 5-RPUR limb: 17 ms for 8192 poses), as its solve (``chains.CHAIN_WORK``): a batch is
#: spread over threads from a few hundred poses up.
CHAIN_ROWS_WORK = 2000.0 / core.REFERENCE_NS

if HAVE_NUMBA:
    from .core import _claim, crank_tip

if HAVE_NUMBA:
    from numba import njit
    from numba import types as _nbt

# Leg type codes in the kernels (_CHAIN: a chain limb of model/chains.py, its rows computed per
# pose by _chain_rows_kernel into the array ``ext``).
_SPS, _UPS, _PUS, _RPS, _RPU, _UPU, _PRS, _RUS, _CHAIN = 0, 1, 2, 3, 4, 5, 6, 7, 8
#: A chain limb's entries in ``ext`` from its offset: reachable (1/0), the unit actuation wrench
#: (6), its rate scale, the unit direction (3), the number of joint twists, the joint twists
#: (at most 7 x 6, about the platform reference point, SI), then its constraint wrenches (c x 6).
_EXT_A, _EXT_S, _EXT_D, _EXT_K, _EXT_T, _EXT_C = 1, 7, 8, 11, 12, 54
_CODES = {SPS: _SPS, UPS: _UPS, PUS: _PUS, RPS: _RPS, RPU: _RPU, UPU: _UPU, PRS: _PRS, RUS: _RUS}
#: Constraint rows of each leg type (as the leg type declares them: ``constraint_rows``).
_NC = {code: len(cls.constraint_rows) for cls, code in _CODES.items()}
# Methods whose NumPy definitions the kernels reproduce: a subclass overriding one of them is
# not covered.
_LEG_METHODS = ("solve", "actuation_wrench", "constraint_wrenches", "joint_twists", "platform_points")
_MECH_METHODS = ("leg_states", "_actuation_rows", "wrench_matrix", "normalized_wrench_system", "jacobian")

#: Poses per parallel work item.
CHUNK = 256

# ---------------------------------------------------------------------------------------------
# Plan: the legs packed into arrays
# ---------------------------------------------------------------------------------------------
class _Unsupported(Exception):
    pass


def _check_covered(mech) -> None:
    if not HAVE_NUMBA:
        raise _Unsupported("numba is not available")
    for m in _MECH_METHODS:
        if getattr(type(mech), m, None) is not getattr(Mechanism, m):
            raise _Unsupported(f"{type(mech).__name__} overrides Mechanism.{m}")
    if not mech.legs:
        raise _Unsupported("the mechanism has no legs")
    for leg in mech.legs:
        require(leg, "compiled", _Unsupported)
        cls = type(leg)
        if isinstance(leg, ChainLeg):
            _check_chain(leg)
            continue
        if cls not in _CODES:
            base = next((b for b in cls.__mro__[1:] if b in _CODES), None)
            if base is None:
                raise _Unsupported(f"leg {leg.name}: leg type {cls.__name__} ({cls.joints or '?'}) has no compiled "
                                   f"form (covered: {', '.join(c.__name__ for c in _CODES)})")
            for m in _LEG_METHODS:
                if getattr(cls, m) is not getattr(base, m):
                    raise _Unsupported(f"leg {leg.name}: {cls.__name__} overrides {base.__name__}.{m}")
    if mech.n_actuators == 0:
        raise _Unsupported("the mechanism has no actuated leg")


def _check_chain(leg) -> None:
    """``_Unsupported`` unless the chain limb ``leg`` is solved as :class:`ChainLeg` solves it
    (no overridden method) with at most seven freedoms (the kernels' scratch)."""
    for m in _LEG_METHODS + ("closure_solve", "inverse", "forward"):
        if getattr(type(leg), m) is not getattr(ChainLeg, m):
            raise _Unsupported(f"leg {leg.name}: {type(leg).__name__} overrides ChainLeg.{m}")
    if leg.n_joint_dof > 7:  # pragma: no cover (parse_chain allows at most seven)
        raise _Unsupported(f"leg {leg.name}: {leg.n_joint_dof} joint freedoms (the kernels take at most 7)")


#: Coverage by (mechanism class, (leg class, actuated) per leg): what decides it is structural.
_COVERAGE: dict = {}


def coverage(mech) -> tuple[bool, str]:
    """``(True, "")`` when the compiled indices cover ``mech``, else ``(False, reason)`` (kept
    per leg types, names and actuation, and in the engine's record of ``mech`` while its legs
    are the same object: a design asks it several times)."""
    rec = record_of(mech)
    kept = rec.get("coverage")
    if kept is not None and kept[0] is mech.legs:
        return kept[1]
    key = (type(mech), tuple((type(leg), leg.name, bool(leg.is_actuated)) for leg in mech.legs))
    hit = _COVERAGE.get(key)
    if hit is not None:
        rec["coverage"] = (mech.legs, hit)
    else:
        try:
            _check_covered(mech)
            hit = (True, "")
        except _Unsupported as e:
            hit = (False, str(e))
        if len(_COVERAGE) > 256:
            _COVERAGE.clear()
        _COVERAGE[key] = hit
    return hit


def _leg_code(leg: Leg) -> int:
    t = type(leg)
    c = _CODE_OF_TYPE.get(t)
    if c is not None:
        return c
    if isinstance(leg, ChainLeg):
        c = _CHAIN
    else:
        c = next((_CODES[cls] for cls in t.__mro__ if cls in _CODES), None)
        if c is None:
            raise _Unsupported(f"leg {leg.name}: no compiled form")  # pragma: no cover - checked before
    _CODE_OF_TYPE[t] = c
    return c


#: {leg type: its code}, as :func:`_leg_code` found it.
_CODE_OF_TYPE: dict = {}


def _code_info(code: np.ndarray) -> tuple[bool, tuple]:
    """``(any UPU leg, the chain limbs' indices)`` of the legs' codes (kept per codes: the
    designs of a study have the same)."""
    key = code.tobytes()
    hit = _CODE_INFO.get(key)
    if hit is None:
        hit = (bool(np.any(code == _UPU)), tuple(np.flatnonzero(code == _CHAIN).tolist()))
        if len(_CODE_INFO) > 256:
            _CODE_INFO.clear()
        _CODE_INFO[key] = hit
    return hit


_CODE_INFO: dict = {}


def _plan(mech):
    """Leg arrays of ``mech`` (kept in the engine's record of the mechanism, beside its
    feasibility plans, while its legs are the same object)."""
    rec = record_of(mech)
    plan = rec.get("indices")
    if plan is not None and plan[0] is mech.legs:
        return plan[1]
    ok, why = coverage(mech)
    if not ok:
        raise _Unsupported(why)
    plan = _legs_plan(mech.legs)
    rec["indices"] = (mech.legs, plan)
    return plan


def _check_legs(legs) -> None:
    """``_Unsupported`` unless every leg has a compiled form (as :func:`_check_covered`)."""
    if not HAVE_NUMBA:
        raise _Unsupported("numba is not available")
    for leg in legs:
        require(leg, "compiled", _Unsupported)
        cls = type(leg)
        if isinstance(leg, ChainLeg):
            _check_chain(leg)
            continue
        base = next((b for b in cls.__mro__ if b in _CODES), None)
        if base is None:
            raise _Unsupported(f"leg {leg.name}: leg type {cls.__name__} has no compiled form")
        if base is not cls and any(getattr(cls, m) is not getattr(base, m) for m in _LEG_METHODS):
            raise _Unsupported(f"leg {leg.name}: {cls.__name__} overrides {base.__name__}'s methods")


def _legs_plan(legs):
    """(code, act, geo, sc, nc): the legs packed into arrays (one geometry per leg)."""
    nl = len(legs)
    code, act = [], []
    geo = []  # base, platform, axis 1, axis 2, axis 3 per leg: one flat list of floats (one array made of it)
    sc = []  # link length, branch, crank length (a chain limb: its offset in ext, c), flat as geo
    zero = [0.0, 0.0, 0.0]
    nc = 0
    off = 0
    for leg in legs:
        c = _leg_code(leg)
        code.append(c)
        act.append(1 if leg.is_actuated else 0)
        geo += leg.base.tolist()
        geo += leg.platform.tolist()
        if c == _CHAIN:
            geo += zero * 3
            k = int(leg.n_closure)
            sc += (float(off), float(k), 0.0)
            off += _EXT_C + 6 * k
            nc += k
            continue
        nc += _NC[c]
        if c == _UPS:
            axes = (leg.u_axis.tolist(), zero, zero)
        elif c == _PUS:
            axes = (leg.slider_axis.tolist(), leg.u_axis.tolist(), zero)
        elif c == _RPS:
            axes = (leg.r_axis.tolist(), zero, zero)
        elif c == _RPU:
            axes = (leg.r_axis.tolist(), leg.u_platform_axis.tolist(), zero)
        elif c == _UPU:
            axes = (leg.u_axis.tolist(), leg.u_platform_axis.tolist(), zero)
        elif c == _PRS:
            axes = (leg.slider_axis.tolist(), leg.r_axis.tolist(), zero)
        elif c == _RUS:  # crank axis, the crank's zero direction c0 and r_axis x c0 (as RUS._crank)
            axes = (leg.r_axis.tolist(), leg.crank_direction.tolist(),
                    np.cross(leg.r_axis, leg.crank_direction).tolist())
        else:
            axes = (zero, zero, zero)
        for a in axes:
            geo += a
        if c in (_PUS, _PRS, _RUS):
            sc += (float(leg.link_length), float(leg.branch), float(getattr(leg, "crank_length", 0.0)))
        else:
            sc += (0.0, 0.0, 0.0)
    # NumPy reads a flat list several times faster than nested ones
    return (np.array(code, dtype=np.int64), np.array(act, dtype=np.int64),
            np.array(geo, dtype=np.float64).reshape(nl, 5, 3), np.array(sc, dtype=np.float64).reshape(nl, 3), int(nc))


def _chain_ext(legs, plan, p, R) -> np.ndarray:
    """The per-pose rows of the chain limbs among ``legs`` (N, width; (N, 0) without one): each
    chain limb solved by the compiled inverse kinematics (:func:`parasynth.engine.chains.solve_arrays`),
    its joint twists, constraint wrenches, actuation wrench and direction by
    ``_chain_rows_kernel`` at its offset (``sc[j, 0]``)."""
    code, _, _, sc, _ = plan
    N = p.shape[0]
    ch = _code_info(code)[1]
    if not ch:
        return np.empty((N, 0))
    width = int(max(sc[j, 0] + _EXT_C + 6 * sc[j, 1] for j in ch))
    ext = np.empty((N, width))
    for j in ch:
        leg = legs[j]
        out = chain_solve_arrays(leg, p, R)
        d = leg.chain_arrays()
        kinds = np.ascontiguousarray(d["kinds"], dtype=np.int64)
        rot = np.flatnonzero(kinds == 0)
        args = (p, out["axes"], out["points"], out["position"], out["residual"], REACH_FACTOR * IK_TOL, kinds,
                int(d["actuated"]), int(rot[0]) if rot.size else -1, np.ascontiguousarray(leg.base, dtype=float),
                int(sc[j, 1]), float(d["length"]), ext, int(sc[j, 0]))
        core._timed_blocks("chain_rows", lambda block, b0, b1: _chain_rows_kernel(*args, b0 * block,
                                                                                  min(N, b1 * block)),
                           N, N * CHAIN_ROWS_WORK)
    return ext


def _poses(mech, X, need_twist: bool):
    """(Xa, single, valid, p, R, T): poses, validity of the parametrisation, platform positions,
    rotations and (with ``need_twist``) twist maps, with invalid poses replaced by ``home`` (as
    ``Mechanism.leg_states`` does). From the compiled program of a described mechanism
    (:func:`parasynth.engine.evaluate.compiled_pose_batch`) where it covers the description, else
    from the model's NumPy ``pose_valid``/``_pose``/``_twist_map`` (model classes written in
    Python)."""
    compiled = None
    if getattr(mech, "description", None) is not None:  # a description: its pose is compiled too
        # the poses as the kernels take them (the program tests each coordinate against its
        # limit: no NumPy pass masking huge lengths first)
        Xa, single = _kernel_poses(mech, X)
        compiled = compiled_pose_batch(mech, Xa, twist=need_twist, masked=False)
    if compiled is not None:
        valid, p, R, T = compiled
        valid = np.asarray(valid, dtype=bool)
        T = T if need_twist else None
        if not valid.all():  # the home pose written into copies (the arrays stay the program's otherwise)
            p = np.array(p, dtype=float)
            R = np.array(R, dtype=float)
            T = np.array(T, dtype=float) if need_twist else None
            bad = ~valid
            p0, R0 = mech._pose(mech.home[None, :])
            p[bad], R[bad] = p0[0], R0[0]
            if need_twist:
                T[bad] = mech._twist_map(mech.home[None, :])[0]
    else:
        Xa, single = mech._poses(X)
        valid = np.asarray(mech.pose_valid(Xa), dtype=bool)
        Xs = np.where(valid[:, None], Xa, mech.home)
        p, R = mech._pose(Xs)
        T = mech._twist_map(Xs) if need_twist else None
    p = np.ascontiguousarray(p, dtype=float)
    R = np.ascontiguousarray(R, dtype=float)
    if T is not None:
        T = np.ascontiguousarray(T, dtype=float)
    return Xa, single, valid, p, R, T


def _upu_lengths(plan, p, R) -> np.ndarray:
    """Per leg, the length the NumPy UPU reciprocal scales moments with: the mean leg length
    over the batch (at least 1 mm), as :meth:`UPU.constraint_wrenches` (1 for other legs).
    Non-finite lengths (poses at infinity) are left out of the mean, where the NumPy mean
    would make every pose of the batch NaN."""
    code, _, geo, _, _ = plan
    if not _code_info(code)[0]:
        return np.ones(len(code))
    return _upu_mean_lengths(p, R, code, geo)


# ---------------------------------------------------------------------------------------------
# Kernels
# ---------------------------------------------------------------------------------------------
if HAVE_NUMBA:
    _jit = dict(nogil=True, error_model="numpy", fastmath=False, cache=True)
    _jit_inline = _jit

    #: Round-robin ordering of the 15 column pairs of six columns: five rounds of three
    #: disjoint pairs, so that consecutive rotations are independent and their square roots
    #: and divisions overlap in the processor.
    _PAIRS6 = np.array([[0, 1], [2, 5], [3, 4], [0, 2], [1, 3], [4, 5], [0, 3], [2, 4], [1, 5],
                        [0, 4], [3, 5], [1, 2], [0, 5], [1, 4], [2, 3]], dtype=np.int64)

    @njit(**_jit_inline)
    def _less_span(X, k, Qc, nq):
        """Row ``k`` of ``X`` less its components along the first ``nq`` rows of ``Qc``
        (orthonormal), in place (Gram-Schmidt); returns the squared length left."""
        for r2 in range(nq):
            dd = 0.0
            for q in range(6):
                dd += X[k, q] * Qc[r2, q]
            for q in range(6):
                X[k, q] -= dd * Qc[r2, q]
        nrm = 0.0
        for q in range(6):
            nrm += X[k, q] * X[k, q]
        return nrm

    @njit(**_jit)
    def _null_of_five(M, hv, beta, q):
        """A unit vector ``q`` (6,) orthogonal to the five rows of ``M`` (5, 6; overwritten): the
        last column of the complete Householder QR factorisation of ``M^T`` (``hv`` (5, 6),
        ``beta`` (5,): the reflections' vectors and ``2 / |v|^2``, scratch). Where ``M`` has rank
        five it spans the null space, as the right singular vector of the zero singular value
        does, up to sign (neither sign is meaningful); five reflections, no sweeps
        (:func:`parasynth.model.spatial.null_direction` is the same on NumPy)."""
        for k in range(5):
            nrm = 0.0
            for i in range(k, 6):
                nrm += M[k, i] * M[k, i]
            nrm = math.sqrt(nrm)
            if nrm == 0.0:
                beta[k] = 0.0
                continue
            alpha = -nrm if M[k, k] >= 0.0 else nrm
            for i in range(k, 6):
                hv[k, i] = M[k, i]
            hv[k, k] -= alpha
            vn = 0.0
            for i in range(k, 6):
                vn += hv[k, i] * hv[k, i]
            if vn == 0.0:
                beta[k] = 0.0
                continue
            beta[k] = 2.0 / vn
            for jj in range(k + 1, 5):
                d = 0.0
                for i in range(k, 6):
                    d += hv[k, i] * M[jj, i]
                d *= beta[k]
                for i in range(k, 6):
                    M[jj, i] -= d * hv[k, i]
        for i in range(6):
            q[i] = 0.0
        q[5] = 1.0
        for k in range(4, -1, -1):
            if beta[k] == 0.0:
                continue
            d = 0.0
            for i in range(k, 6):
                d += hv[k, i] * q[i]
            d *= beta[k]
            for i in range(k, 6):
                q[i] -= d * hv[k, i]

    @njit(**_jit)
    def _jacobi_sv(Mt, m, n, Vt, want_v, sv):
        """One-sided Jacobi (Hestenes) SVD of the m x n matrix whose columns are stored as the
        rows ``Mt[j, :m]`` (overwritten: column j becomes ``sigma_j u_j``). ``sv[:n]`` receives
        the singular values (unsorted); with ``want_v`` the rows ``Vt[j, :n]`` receive the right
        singular vectors (``v_j``, the columns of V with ``M_in V = M_out``). Returns the number
        of sweeps. Singular values come out with an absolute error of a few eps * ||M|| (small
        ones to high relative accuracy when the columns are well scaled)."""
        if want_v:
            for i in range(n):
                for j in range(n):
                    Vt[i, j] = 1.0 if i == j else 0.0
        tol2 = (4.0e-16 * max(m, 1)) ** 2
        fro = 0.0
        for j in range(n):
            a = 0.0
            for k in range(m):
                a += Mt[j, k] * Mt[j, k]
            sv[j] = a
            fro += a
        # Columns below eps * ||M||_F carry nothing beyond rounding: rotating against them
        # never converges (their direction is noise), so they are left alone.
        tiny = 1e-32 * fro
        sweeps = 0
        npair = 15 if n <= 6 else n * (n - 1) // 2
        for _sweep in range(60):
            sweeps += 1
            rotated = False
            i = 0
            j = 0
            for q in range(npair):
                if n <= 6:  # round-robin: consecutive rotations independent
                    i = _PAIRS6[q, 0]
                    j = _PAIRS6[q, 1]
                    if j >= n:
                        continue
                else:  # cyclic by rows
                    j += 1
                    if q == 0:
                        i, j = 0, 1
                    elif j >= n:
                        i += 1
                        j = i + 1
                a = sv[i]
                b = sv[j]
                if a <= tiny or b <= tiny:
                    continue
                g = 0.0
                for k in range(m):
                    g += Mt[i, k] * Mt[j, k]
                if g * g <= tol2 * (a * b):
                    continue
                rotated = True
                zeta = (b - a) / (2.0 * g)
                if zeta >= 0.0:
                    t = 1.0 / (zeta + math.sqrt(1.0 + zeta * zeta))
                else:
                    t = -1.0 / (-zeta + math.sqrt(1.0 + zeta * zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = c * t
                for k in range(m):
                    x = Mt[i, k]
                    y = Mt[j, k]
                    Mt[i, k] = c * x - s * y
                    Mt[j, k] = s * x + c * y
                if want_v:
                    for k in range(n):
                        x = Vt[i, k]
                        y = Vt[j, k]
                        Vt[i, k] = c * x - s * y
                        Vt[j, k] = s * x + c * y
                # updated squared norms; recomputed where the update cancels
                a2 = a - t * g
                b2 = b + t * g
                if a2 < 0.25 * a:
                    a2 = 0.0
                    for k in range(m):
                        a2 += Mt[i, k] * Mt[i, k]
                if b2 < 0.25 * b:
                    b2 = 0.0
                    for k in range(m):
                        b2 += Mt[j, k] * Mt[j, k]
                sv[i] = a2
                sv[j] = b2
            if not rotated:
                break
        for j in range(n):
            a = 0.0
            for k in range(m):
                a += Mt[j, k] * Mt[j, k]
            sv[j] = math.sqrt(a)
        return sweeps

    @njit(**_jit)
    def _sv_or_none(Mt, m, V, sv):
        """:func:`_jacobi_sv` of the ``m`` columns of ``Mt`` (6 rows) with its right singular
        vectors ``V``; with no column, zero singular values and the unit vectors. Returns the
        largest singular value."""
        if m > 0:
            _jacobi_sv(Mt, m, np.int64(6), V, np.int64(1), sv)
        else:
            for a in range(6):
                sv[a] = 0.0
                for q in range(6):
                    V[a, q] = 1.0 if a == q else 0.0
        smax = 0.0
        for q in range(6):
            smax = max(smax, sv[q])
        return smax

    @njit(**_jit)
    def _jacobi_sv6(Mt, n, sv):
        """:func:`_jacobi_sv` without V for at most six columns of length exactly 6 (the wrench
        systems of up to six rows): constant loop bounds, and the pairs in round-robin order."""
        tol2 = (4.0e-16 * 6) ** 2
        fro = 0.0
        for j in range(n):
            a = 0.0
            for k in range(6):
                a += Mt[j, k] * Mt[j, k]
            sv[j] = a
            fro += a
        tiny = 1e-32 * fro
        for _sweep in range(60):
            rotated = False
            for q in range(15):
                i = _PAIRS6[q, 0]
                j = _PAIRS6[q, 1]
                if j >= n:
                    continue
                a = sv[i]
                b = sv[j]
                if a <= tiny or b <= tiny:
                    continue
                g = 0.0
                for k in range(6):
                    g += Mt[i, k] * Mt[j, k]
                if g * g <= tol2 * (a * b):
                    continue
                rotated = True
                zeta = (b - a) / (2.0 * g)
                if zeta >= 0.0:
                    t = 1.0 / (zeta + math.sqrt(1.0 + zeta * zeta))
                else:
                    t = -1.0 / (-zeta + math.sqrt(1.0 + zeta * zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = c * t
                for k in range(6):
                    x = Mt[i, k]
                    y = Mt[j, k]
                    Mt[i, k] = c * x - s * y
                    Mt[j, k] = s * x + c * y
                a2 = a - t * g
                b2 = b + t * g
                if a2 < 0.25 * a:
                    a2 = 0.0
                    for k in range(6):
                        a2 += Mt[i, k] * Mt[i, k]
                if b2 < 0.25 * b:
                    b2 = 0.0
                    for k in range(6):
                        b2 += Mt[j, k] * Mt[j, k]
                sv[i] = a2
                sv[j] = b2
            if not rotated:
                break
        for j in range(n):
            a = 0.0
            for k in range(6):
                a += Mt[j, k] * Mt[j, k]
            sv[j] = math.sqrt(a)

    @njit(**_jit_inline)
    def _cross(a0, a1, a2, b0, b1, b2):
        return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0

    @njit(**_jit_inline)
    def _unit3(x, y, z):
        nrm = math.sqrt(x * x + y * y + z * z)
        if nrm > 0.0:
            return x / nrm, y / nrm, z / nrm
        return 0.0, 0.0, 0.0

    @njit(**_jit)
    def _upu_reciprocal(Tw, Lu, w):
        """Null direction of the 5 scaled twists (rows of ``Tw`` (5, 6)) by Householder QR of
        Tw^T; written to ``w`` (6,) as a wrench in SI (moment scaled back by ``Lu``), then
        made a unit force or, when its force vanishes, a unit couple."""
        M = np.empty((5, 6))
        for k in range(5):
            for i in range(6):
                M[k, i] = Tw[k, i]
        _null_of_five(M, np.empty((5, 6)), np.empty(5), w)
        for i in range(3, 6):
            w[i] *= Lu
        fn = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        mn = math.sqrt(w[3] * w[3] + w[4] * w[4] + w[5] * w[5])
        if fn <= 1e-9 * max(mn / Lu, 1e-300):
            w[0] = 0.0
            w[1] = 0.0
            w[2] = 0.0
            sc = mn
        else:
            sc = fn
        for i in range(6):
            w[i] /= sc

    @njit(**_jit_inline)
    def _rus_tip(dx, dy, dz, geo, sc, j):
        """The crank tip of RUS leg ``j`` relative to its base anchor, for the sphere at base + d,
        and whether the link reaches the sphere."""
        _, ct, st, ok = crank_tip(dx, dy, dz, geo[j, 3, 0], geo[j, 3, 1], geo[j, 3, 2], geo[j, 4, 0], geo[j, 4, 1],
                                  geo[j, 4, 2], sc[j, 2], sc[j, 0], sc[j, 1])
        h = sc[j, 2]
        return (h * (ct * geo[j, 3, 0] + st * geo[j, 4, 0]), h * (ct * geo[j, 3, 1] + st * geo[j, 4, 1]),
                h * (ct * geo[j, 3, 2] + st * geo[j, 4, 2]), ok)

    @njit(**_jit)
    def _legs(p, R, i, code, act, geo, sc, upuL, ext, A, scale, anchor, C, Tw, w):
        """The wrench system of pose ``i``: actuation rows ``A`` (n_act, 6), ``scale``
        (n_act,), platform anchors of the actuated legs ``anchor`` (n_act, 3) and constraint
        rows ``C`` (n_c, 6), all in SI about the platform reference point. Returns whether
        every leg reaches the pose."""
        px, py, pz = p[i, 0], p[i, 1], p[i, 2]
        reach = True
        ia = 0
        ic = 0
        for j in range(code.shape[0]):
            t = code[j]
            qx, qy, qz = geo[j, 1, 0], geo[j, 1, 1], geo[j, 1, 2]
            ax = px + R[i, 0, 0] * qx + R[i, 0, 1] * qy + R[i, 0, 2] * qz
            ay = py + R[i, 1, 0] * qx + R[i, 1, 1] * qy + R[i, 1, 2] * qz
            az = pz + R[i, 2, 0] * qx + R[i, 2, 1] * qy + R[i, 2, 2] * qz
            if t == _CHAIN:  # a chain limb: its rows at this pose from _chain_rows_kernel (ext)
                o = np.int64(sc[j, 0])
                if not ext[i, o] > 0.5:
                    reach = False
                if act[j]:
                    for q in range(6):
                        A[ia, q] = ext[i, o + 1 + q]
                    scale[ia] = ext[i, o + 7]
                    anchor[ia, 0], anchor[ia, 1], anchor[ia, 2] = ax, ay, az
                    ia += 1
                for r in range(np.int64(sc[j, 1])):
                    for q in range(6):
                        C[ic, q] = ext[i, o + _EXT_C + 6 * r + q]
                    ic += 1
                continue
            bx, by, bz = geo[j, 0, 0], geo[j, 0, 1], geo[j, 0, 2]
            dx, dy, dz = ax - bx, ay - by, az - bz
            e0, e1, e2 = geo[j, 2, 0], geo[j, 2, 1], geo[j, 2, 2]
            rs = 1.0
            if t == _PUS or t == _PRS:
                Ll = sc[j, 0]
                de = dx * e0 + dy * e1 + dz * e2
                perp2 = dx * dx + dy * dy + dz * dz - de * de
                disc = Ll * Ll - perp2
                if not disc >= 0.0:
                    reach = False
                    disc = 0.0
                if t == _PRS:
                    off = abs(dx * geo[j, 3, 0] + dy * geo[j, 3, 1] + dz * geo[j, 3, 2])
                    if not off <= GEOM_TOL * max(1.0, Ll):
                        reach = False
                s = de + sc[j, 1] * math.sqrt(disc)
                bx, by, bz = bx + s * e0, by + s * e1, bz + s * e2
                nx, ny, nz = (ax - bx) / Ll, (ay - by) / Ll, (az - bz) / Ll
                rs = nx * e0 + ny * e1 + nz * e2
            elif t == _RUS:
                Ll = sc[j, 0]
                cx, cy, cz, ok = _rus_tip(dx, dy, dz, geo, sc, j)
                reach = reach and ok
                nx, ny, nz = (ax - bx - cx) / Ll, (ay - by - cy) / Ll, (az - bz - cz) / Ll
                tx, ty, tz = _cross(e0, e1, e2, cx, cy, cz)
                rs = nx * tx + ny * ty + nz * tz
            else:
                length = math.sqrt(dx * dx + dy * dy + dz * dz)
                if not (length > 0.0 and length < np.inf):  # a pose at infinity: NaN, as NumPy ends
                    reach = False
                nx, ny, nz = _unit3(dx, dy, dz)
                if t == _RPS or t == _RPU:
                    off = abs(dx * e0 + dy * e1 + dz * e2)
                    if not off <= GEOM_TOL * max(1.0, length):
                        reach = False
            rx, ry, rz = ax - px, ay - py, az - pz
            if act[j]:
                mx, my, mz = _cross(rx, ry, rz, nx, ny, nz)
                A[ia, 0], A[ia, 1], A[ia, 2] = nx, ny, nz
                A[ia, 3], A[ia, 4], A[ia, 5] = mx, my, mz
                scale[ia] = rs
                anchor[ia, 0], anchor[ia, 1], anchor[ia, 2] = ax, ay, az
                ia += 1
            if t == _RPS or t == _PRS or t == _RPU:
                if t == _PRS:
                    fx, fy, fz = geo[j, 3, 0], geo[j, 3, 1], geo[j, 3, 2]
                else:
                    fx, fy, fz = e0, e1, e2
                mx, my, mz = _cross(rx, ry, rz, fx, fy, fz)
                C[ic, 0], C[ic, 1], C[ic, 2] = fx, fy, fz
                C[ic, 3], C[ic, 4], C[ic, 5] = mx, my, mz
                ic += 1
                if t == _RPU:
                    ux, uy, uz = geo[j, 3, 0], geo[j, 3, 1], geo[j, 3, 2]
                    a4x = R[i, 0, 0] * ux + R[i, 0, 1] * uy + R[i, 0, 2] * uz
                    a4y = R[i, 1, 0] * ux + R[i, 1, 1] * uy + R[i, 1, 2] * uz
                    a4z = R[i, 2, 0] * ux + R[i, 2, 1] * uy + R[i, 2, 2] * uz
                    if not abs(a4x * e0 + a4y * e1 + a4z * e2) <= GEOM_TOL:
                        reach = False
                    cx, cy, cz = _cross(e0, e1, e2, a4x, a4y, a4z)
                    cx, cy, cz = _unit3(cx, cy, cz)
                    C[ic, 0], C[ic, 1], C[ic, 2] = 0.0, 0.0, 0.0
                    C[ic, 3], C[ic, 4], C[ic, 5] = cx, cy, cz
                    ic += 1
            elif t == _UPU:
                Lu = upuL[j]
                ux, uy, uz = geo[j, 3, 0], geo[j, 3, 1], geo[j, 3, 2]
                a4x = R[i, 0, 0] * ux + R[i, 0, 1] * uy + R[i, 0, 2] * uz
                a4y = R[i, 1, 0] * ux + R[i, 1, 1] * uy + R[i, 1, 2] * uz
                a4z = R[i, 2, 0] * ux + R[i, 2, 1] * uy + R[i, 2, 2] * uz
                a2x, a2y, a2z = _cross(e0, e1, e2, nx, ny, nz)
                a2x, a2y, a2z = _unit3(a2x, a2y, a2z)
                a3x, a3y, a3z = _cross(a4x, a4y, a4z, nx, ny, nz)
                a3x, a3y, a3z = _unit3(a3x, a3y, a3z)
                # revolute twist (axis x (P - point), axis), angular part scaled by Lu
                bpx, bpy, bpz = px - bx, py - by, pz - bz
                apx, apy, apz = px - ax, py - ay, pz - az
                v0, v1, v2 = _cross(e0, e1, e2, bpx, bpy, bpz)
                Tw[0, 0], Tw[0, 1], Tw[0, 2], Tw[0, 3], Tw[0, 4], Tw[0, 5] = v0, v1, v2, e0 * Lu, e1 * Lu, e2 * Lu
                v0, v1, v2 = _cross(a2x, a2y, a2z, bpx, bpy, bpz)
                Tw[1, 0], Tw[1, 1], Tw[1, 2], Tw[1, 3], Tw[1, 4], Tw[1, 5] = v0, v1, v2, a2x * Lu, a2y * Lu, a2z * Lu
                Tw[2, 0], Tw[2, 1], Tw[2, 2], Tw[2, 3], Tw[2, 4], Tw[2, 5] = nx, ny, nz, 0.0, 0.0, 0.0
                v0, v1, v2 = _cross(a3x, a3y, a3z, apx, apy, apz)
                Tw[3, 0], Tw[3, 1], Tw[3, 2], Tw[3, 3], Tw[3, 4], Tw[3, 5] = v0, v1, v2, a3x * Lu, a3y * Lu, a3z * Lu
                v0, v1, v2 = _cross(a4x, a4y, a4z, apx, apy, apz)
                Tw[4, 0], Tw[4, 1], Tw[4, 2], Tw[4, 3], Tw[4, 4], Tw[4, 5] = v0, v1, v2, a4x * Lu, a4y * Lu, a4z * Lu
                _upu_reciprocal(Tw, Lu, w)
                for k in range(6):
                    C[ic, k] = w[k]
                ic += 1
        return reach

    @njit(**_jit)
    def _upu_mean_lengths(p, R, code, geo):
        out = np.ones(code.shape[0])
        N = p.shape[0]
        for j in range(code.shape[0]):
            if code[j] != _UPU:
                continue
            qx, qy, qz = geo[j, 1, 0], geo[j, 1, 1], geo[j, 1, 2]
            acc = 0.0
            cnt = 0
            for i in range(N):
                dx = p[i, 0] + R[i, 0, 0] * qx + R[i, 0, 1] * qy + R[i, 0, 2] * qz - geo[j, 0, 0]
                dy = p[i, 1] + R[i, 1, 0] * qx + R[i, 1, 1] * qy + R[i, 1, 2] * qz - geo[j, 0, 1]
                dz = p[i, 2] + R[i, 2, 0] * qx + R[i, 2, 1] * qy + R[i, 2, 2] * qz - geo[j, 0, 2]
                d = math.sqrt(dx * dx + dy * dy + dz * dz)
                if math.isfinite(d):  # a pose at infinity must not spoil the others
                    acc += d
                    cnt += 1
            out[j] = max(acc / max(cnt, 1), 1e-3)
        return out

    @njit(**_jit_inline)
    def _put_rev(Tw, k, a0, a1, a2, cx, cy, cz, px, py, pz, L):
        v0, v1, v2 = _cross(a0, a1, a2, px - cx, py - cy, pz - cz)
        Tw[k, 0], Tw[k, 1], Tw[k, 2] = v0, v1, v2
        Tw[k, 3], Tw[k, 4], Tw[k, 5] = a0 * L, a1 * L, a2 * L

    @njit(**_jit_inline)
    def _put_pri(Tw, k, d0, d1, d2):
        Tw[k, 0], Tw[k, 1], Tw[k, 2] = d0, d1, d2
        Tw[k, 3], Tw[k, 4], Tw[k, 5] = 0.0, 0.0, 0.0

    @njit(**_jit)
    def _joint_twists(p, R, i, j, code, geo, sc, ext, L, Tw):
        """The joint twists of leg ``j`` at pose ``i`` as rows of ``Tw`` (up to 7, about the
        platform reference point, angular parts multiplied by ``L``), in the order of the
        legs' ``joint_twists``; returns their number (0 when the leg cannot reach the pose)."""
        px, py, pz = p[i, 0], p[i, 1], p[i, 2]
        t = code[j]
        if t == _CHAIN:  # the chain's joint twists about p at the solved configuration (ext)
            o = np.int64(sc[j, 0])
            if not ext[i, o] > 0.5:
                return 0
            k = np.int64(ext[i, o + _EXT_K])
            for a in range(k):
                for q in range(6):
                    v = ext[i, o + _EXT_T + 6 * a + q]
                    Tw[a, q] = v * L if q >= 3 else v
            return k
        qx, qy, qz = geo[j, 1, 0], geo[j, 1, 1], geo[j, 1, 2]
        ax = px + R[i, 0, 0] * qx + R[i, 0, 1] * qy + R[i, 0, 2] * qz
        ay = py + R[i, 1, 0] * qx + R[i, 1, 1] * qy + R[i, 1, 2] * qz
        az = pz + R[i, 2, 0] * qx + R[i, 2, 1] * qy + R[i, 2, 2] * qz
        bx, by, bz = geo[j, 0, 0], geo[j, 0, 1], geo[j, 0, 2]
        e0, e1, e2 = geo[j, 2, 0], geo[j, 2, 1], geo[j, 2, 2]
        if t == _PUS or t == _PRS:
            Ll = sc[j, 0]
            dx, dy, dz = ax - bx, ay - by, az - bz
            de = dx * e0 + dy * e1 + dz * e2
            disc = Ll * Ll - (dx * dx + dy * dy + dz * dz - de * de)
            if not disc >= 0.0:
                return 0
            s = de + sc[j, 1] * math.sqrt(disc)
            bx, by, bz = bx + s * e0, by + s * e1, bz + s * e2
            nx, ny, nz = (ax - bx) / Ll, (ay - by) / Ll, (az - bz) / Ll
        elif t == _RUS:
            cx, cy, cz, ok = _rus_tip(ax - bx, ay - by, az - bz, geo, sc, j)
            if not ok:
                return 0
            cx, cy, cz = bx + cx, by + cy, bz + cz
            nx, ny, nz = (ax - cx) / sc[j, 0], (ay - cy) / sc[j, 0], (az - cz) / sc[j, 0]
        else:
            nx, ny, nz = _unit3(ax - bx, ay - by, az - bz)
        k = 0
        if t == _SPS:
            for q in range(3):
                _put_rev(Tw, k, 1.0 if q == 0 else 0.0, 1.0 if q == 1 else 0.0, 1.0 if q == 2 else 0.0,
                         bx, by, bz, px, py, pz, L)
                k += 1
        elif t == _UPS or t == _UPU:
            _put_rev(Tw, k, e0, e1, e2, bx, by, bz, px, py, pz, L)
            c0, c1, c2 = _cross(e0, e1, e2, nx, ny, nz)
            c0, c1, c2 = _unit3(c0, c1, c2)
            _put_rev(Tw, k + 1, c0, c1, c2, bx, by, bz, px, py, pz, L)
            k += 2
        elif t == _PUS:
            _put_pri(Tw, k, e0, e1, e2)
            u0, u1, u2 = geo[j, 3, 0], geo[j, 3, 1], geo[j, 3, 2]
            _put_rev(Tw, k + 1, u0, u1, u2, bx, by, bz, px, py, pz, L)
            c0, c1, c2 = _cross(u0, u1, u2, nx, ny, nz)
            c0, c1, c2 = _unit3(c0, c1, c2)
            _put_rev(Tw, k + 2, c0, c1, c2, bx, by, bz, px, py, pz, L)
            k += 3
        elif t == _PRS:
            _put_pri(Tw, k, e0, e1, e2)
            _put_rev(Tw, k + 1, geo[j, 3, 0], geo[j, 3, 1], geo[j, 3, 2], bx, by, bz, px, py, pz, L)
            k += 2
        elif t == _RPS or t == _RPU:
            _put_rev(Tw, k, e0, e1, e2, bx, by, bz, px, py, pz, L)
            k += 1
        elif t == _RUS:  # the crank at the base anchor, the universal joint at its tip
            _put_rev(Tw, k, e0, e1, e2, bx, by, bz, px, py, pz, L)
            _put_rev(Tw, k + 1, e0, e1, e2, cx, cy, cz, px, py, pz, L)
            c0, c1, c2 = _cross(e0, e1, e2, nx, ny, nz)
            c0, c1, c2 = _unit3(c0, c1, c2)
            _put_rev(Tw, k + 2, c0, c1, c2, cx, cy, cz, px, py, pz, L)
            k += 3
        if t == _SPS or t == _UPS or t == _RPS or t == _RPU or t == _UPU:
            _put_pri(Tw, k, nx, ny, nz)
            k += 1
        if t == _RPU:
            _put_rev(Tw, k, e0, e1, e2, ax, ay, az, px, py, pz, L)
            ux, uy, uz = geo[j, 3, 0], geo[j, 3, 1], geo[j, 3, 2]
            a4x = R[i, 0, 0] * ux + R[i, 0, 1] * uy + R[i, 0, 2] * uz
            a4y = R[i, 1, 0] * ux + R[i, 1, 1] * uy + R[i, 1, 2] * uz
            a4z = R[i, 2, 0] * ux + R[i, 2, 1] * uy + R[i, 2, 2] * uz
            _put_rev(Tw, k + 1, a4x, a4y, a4z, ax, ay, az, px, py, pz, L)
            k += 2
        elif t == _UPU:
            ux, uy, uz = geo[j, 3, 0], geo[j, 3, 1], geo[j, 3, 2]
            a4x = R[i, 0, 0] * ux + R[i, 0, 1] * uy + R[i, 0, 2] * uz
            a4y = R[i, 1, 0] * ux + R[i, 1, 1] * uy + R[i, 1, 2] * uz
            a4z = R[i, 2, 0] * ux + R[i, 2, 1] * uy + R[i, 2, 2] * uz
            c0, c1, c2 = _cross(a4x, a4y, a4z, nx, ny, nz)
            c0, c1, c2 = _unit3(c0, c1, c2)
            _put_rev(Tw, k, c0, c1, c2, ax, ay, az, px, py, pz, L)
            _put_rev(Tw, k + 1, a4x, a4y, a4z, ax, ay, az, px, py, pz, L)
            k += 2
        else:  # spherical joint at the platform anchor
            for q in range(3):
                _put_rev(Tw, k, 1.0 if q == 0 else 0.0, 1.0 if q == 1 else 0.0, 1.0 if q == 2 else 0.0,
                         ax, ay, az, px, py, pz, L)
                k += 1
        return k

    @njit(**_jit)
    def _constraint_rank_kernel(p, R, code, geo, sc, ext, L):
        """Rank of the union of the legs' reciprocal wrench spaces at pose 0 (scaled
        coordinates; per-leg rank tolerance 1e-9, union tolerance 1e-8, as ``mobility``).
        -1 when a leg cannot reach the pose."""
        nl = code.shape[0]
        Tw = np.empty((7, 6))
        Twt = np.empty((6, 7))
        V = np.empty((6, 6))
        sv = np.empty(7)
        U = np.empty((6, 6 * nl))
        nu = 0
        for j in range(nl):
            k = _joint_twists(p, R, 0, j, code, geo, sc, ext, L, Tw)
            if k == 0:
                return -1
            for a in range(k):
                for q in range(6):
                    Twt[q, a] = Tw[a, q]
            _jacobi_sv(Twt, k, np.int64(6), V, np.int64(1), sv)
            smax = 0.0
            for q in range(6):
                smax = max(smax, sv[q])
            for q in range(6):
                if not sv[q] > 1e-9 * max(smax, 1e-300):
                    for q2 in range(6):
                        U[q2, nu] = V[q, q2]
                    nu += 1
        if nu == 0:
            return 0
        # rank of the nu x 6 union: Jacobi on its columns (the 6 coordinates)
        Ut = np.empty((6, nu))
        for q in range(6):
            for a in range(nu):
                Ut[q, a] = U[q, a]
        sv2 = np.empty(6)
        _jacobi_sv(Ut, np.int64(nu), np.int64(6), V, np.int64(0), sv2)
        smax = 0.0
        for q in range(6):
            smax = max(smax, sv2[q])
        r = 0
        for q in range(6):
            if sv2[q] > 1e-8 * max(smax, 1e-300):
                r += 1
        return r

    @njit(**_jit)
    def _chain_rows_kernel(p, AXW, PTW, POS, res, tol, kinds, act, first, base, nc, Ll, ext, off, i0, i1):
        """A chain limb's rows at every pose, into ``ext[:, off:]`` (see ``_EXT_*``), from its
        solved configuration (``engine.chains.solve_arrays``: axes ``AXW``, points ``PTW``,
        anchor ``POS``, residual ``res``, reachable below ``tol``), as the NumPy reference
        (``ChainLeg.joint_twists``, ``constraint_wrenches``, ``actuation_wrench``): the joint
        twists about ``p``; the ``nc`` constraint wrenches, the null space of the twists with
        moments scaled by the limb's length ``Ll`` (one wrench: the null vector of the five
        twists by Householder, :func:`_null_of_five`; more: the right singular vectors of the
        smallest singular values, one-sided Jacobi), each a unit force or (when the force
        vanishes) a unit couple; the unit actuation wrench reciprocal to the passive twists, out
        of the span of the constraint wrenches (where those are five rows, their null vector;
        else the null space of the passive twists by Jacobi, the constraint span projected out),
        its power on the actuated twist (``rate``) made positive; the direction from
        the first rotational joint centre (``first``, or ``base``) to the anchor. Poses ``i0 ..
        i1 - 1``, each on its own (ranges of poses are spread over threads)."""
        n = kinds.shape[0]
        T = np.empty((max(n, 1), 6))
        Mt = np.empty((6, max(n, 1)))
        V = np.empty((6, 6))
        sv = np.empty(6)
        W = np.empty((max(nc, 1), 6))
        Qc = np.empty((max(nc, 1), 6))
        ns = np.empty((6, 6))
        order = np.empty(6, np.int64)
        w0 = np.empty(6)
        M5 = np.empty((max(n, 5), 6))
        hv = np.empty((5, 6))
        hb = np.empty(5)
        nv = np.empty(6)
        for i in range(i0, i1):
            ok = res[i] < tol
            ext[i, off] = 1.0 if ok else 0.0
            px, py, pz = p[i, 0], p[i, 1], p[i, 2]
            for m in range(n):
                ax, ay, az = AXW[i, m, 0], AXW[i, m, 1], AXW[i, m, 2]
                if kinds[m] == 1:
                    T[m, 0], T[m, 1], T[m, 2] = ax, ay, az
                    T[m, 3], T[m, 4], T[m, 5] = 0.0, 0.0, 0.0
                else:
                    v0, v1, v2 = _cross(ax, ay, az, px - PTW[i, m, 0], py - PTW[i, m, 1], pz - PTW[i, m, 2])
                    T[m, 0], T[m, 1], T[m, 2] = v0, v1, v2
                    T[m, 3], T[m, 4], T[m, 5] = ax, ay, az
            ext[i, off + _EXT_K] = n
            for m in range(n):
                for q in range(6):
                    ext[i, off + _EXT_T + 6 * m + q] = T[m, q]
            # direction
            if first >= 0:
                bx, by, bz = PTW[i, first, 0], PTW[i, first, 1], PTW[i, first, 2]
            else:
                bx, by, bz = base[0], base[1], base[2]
            d0, d1, d2 = _unit3(POS[i, 0] - bx, POS[i, 1] - by, POS[i, 2] - bz)
            ext[i, off + _EXT_D], ext[i, off + _EXT_D + 1], ext[i, off + _EXT_D + 2] = d0, d1, d2
            # constraint wrenches: null space of the scaled twists (columns: the six coordinates);
            # a limb without any (six freedoms) skips the decomposition, whose results only they read.
            # One (five freedoms): the null vector of the five scaled twists by Householder; more
            # (a basis of a larger null space, which any rotation of it spans too): the right
            # singular vectors of the smallest singular values, as the NumPy reference picks them
            if nc == 1 and n == 5:
                for m in range(5):
                    for q in range(6):
                        M5[m, q] = T[m, q] * Ll if q >= 3 else T[m, q]
                _null_of_five(M5, hv, hb, nv)
                for q in range(6):
                    W[0, q] = nv[q] * Ll if q >= 3 else nv[q]
            elif nc > 0:
                for m in range(n):
                    for q in range(6):
                        Mt[q, m] = T[m, q] * Ll if q >= 3 else T[m, q]
                _jacobi_sv(Mt, n, np.int64(6), V, np.int64(1), sv)
                # the six singular values in increasing order (insertion sort)
                for q in range(6):
                    order[q] = q
                for a in range(1, 6):
                    b = a
                    while b > 0 and sv[order[b]] < sv[order[b - 1]]:
                        tmp = order[b]
                        order[b] = order[b - 1]
                        order[b - 1] = tmp
                        b -= 1
                for r in range(nc):
                    q0 = order[r]
                    for q in range(6):
                        W[r, q] = V[q0, q] * Ll if q >= 3 else V[q0, q]
            for r in range(nc):
                f = math.sqrt(W[r, 0] ** 2 + W[r, 1] ** 2 + W[r, 2] ** 2)
                mm = math.sqrt(W[r, 3] ** 2 + W[r, 4] ** 2 + W[r, 5] ** 2)
                couple = f <= 1e-9 * max(mm / Ll, 1e-300)
                if couple:
                    W[r, 0], W[r, 1], W[r, 2] = 0.0, 0.0, 0.0
                nrm = mm if couple else f
                for q in range(6):
                    W[r, q] /= nrm
                    ext[i, off + _EXT_C + 6 * r + q] = W[r, q]
            if act < 0:
                for q in range(7):
                    ext[i, off + _EXT_A + q] = np.nan
                continue
            # orthonormal basis of the constraint wrenches, scaled as the twists' dual (Gram-Schmidt)
            nq = 0
            for r in range(nc):
                for q in range(6):
                    Qc[nq, q] = W[r, q] / Ll if q >= 3 else W[r, q]
                nrm = math.sqrt(_less_span(Qc, nq, Qc, nq))
                if nrm > 1e-12:
                    for q in range(6):
                        Qc[nq, q] /= nrm
                    nq += 1
            # actuation wrench: reciprocal to the passive twists (scaled), less the constraint span
            npas = n - 1
            c = 0
            for m in range(n):  # the passive twists, scaled, as rows
                if m == act:
                    continue
                for q in range(6):
                    M5[c, q] = T[m, q] * Ll if q >= 3 else T[m, q]
                c += 1
            if npas + nq == 5:
                # five rows, the passive twists and the constraint basis: their null vector (Householder)
                for r in range(nq):
                    for q in range(6):
                        M5[npas + r, q] = Qc[r, q]
                _null_of_five(M5, hv, hb, nv)
                for q in range(6):
                    w0[q] = nv[q] * Ll if q >= 3 else nv[q]
            else:
                # the null space of the passive twists (Jacobi), less the constraint span: its
                # longest remaining vector
                for c in range(npas):
                    for q in range(6):
                        Mt[q, c] = M5[c, q]
                smax = _sv_or_none(Mt, npas, V, sv)
                best = -1
                bestn = -1.0
                nn = 0
                for a in range(6):
                    if sv[a] > 1e-9 * max(smax, 1e-300):
                        continue
                    for q in range(6):
                        ns[nn, q] = V[a, q]
                    nrm = _less_span(ns, nn, Qc, nq)
                    if nrm > bestn:
                        bestn = nrm
                        best = nn
                    nn += 1
                if best < 0:
                    for q in range(7):
                        ext[i, off + _EXT_A + q] = np.nan
                    continue
                for q in range(6):
                    w0[q] = ns[best, q] * Ll if q >= 3 else ns[best, q]
            f = math.sqrt(w0[0] ** 2 + w0[1] ** 2 + w0[2] ** 2)
            mm = math.sqrt(w0[3] ** 2 + w0[4] ** 2 + w0[5] ** 2)
            nrm = f if f > 1e-9 * mm / Ll else mm
            rate = 0.0
            for q in range(6):
                w0[q] /= nrm
                rate += w0[q] * T[act, q]
            sgn = -1.0 if rate < 0.0 else 1.0
            for q in range(6):
                ext[i, off + _EXT_A + q] = w0[q] * sgn
            ext[i, off + _EXT_S] = rate * sgn

    @njit(**_jit_inline)
    def _legs_scratch(na, nc):
        """The scratch :func:`_legs` fills for one pose: the actuation rows (na, 6), their scales
        and anchors, the constraint rows (nc, 6), the joint twists (5, 6) and a wrench (6)."""
        return (np.empty((max(na, 1), 6)), np.empty(max(na, 1)), np.empty((max(na, 1), 3)),
                np.empty((max(nc, 1), 6)), np.empty((5, 6)), np.empty(6))

    def _margin_kernel(p, R, valid, code, act, geo, sc, upuL, ext, na, nc, rc, L, out, block, claim, nblk):
        """The singularity margin of poses (p, R) -> out, pose by pose; blocks of ``block``
        poses claimed from ``claim`` (every thread of a batch calls it once, see
        :func:`parasynth.engine.core._timed_claims`) until ``nblk``."""
        N = p.shape[0]
        rcu = min(rc, nc, 6) if nc > 0 else 0
        k = na + rcu
        kk = min(k, 6)
        A, scale, anchor, C, Tw, w = _legs_scratch(na, nc)
        Ct = np.empty((max(nc, 1), 6))
        svc = np.empty(max(nc, 1))
        Vd = np.empty((1, 1))
        M = np.empty((max(k, 6), max(k, 6)))
        sv = np.empty(max(k, 6))
        used = np.zeros(max(nc, 1), np.bool_)
        while True:
            c = _claim(claim)
            if c >= nblk:
                break
            for i in range(c * block, min(N, (c + 1) * block)):
                if not valid[i]:
                    out[i] = np.nan
                    continue
                if not _legs(p, R, i, code, act, geo, sc, upuL, ext, A, scale, anchor, C, Tw, w):
                    out[i] = np.nan
                    continue
                finite = True
                # actuation rows: moments / L, then unit norm
                for a in range(na):
                    for q in range(3, 6):
                        A[a, q] /= L
                    nrm = 0.0
                    for q in range(6):
                        nrm += A[a, q] * A[a, q]
                    nrm = math.sqrt(nrm)
                    for q in range(6):
                        A[a, q] /= nrm
                        if not math.isfinite(A[a, q]):
                            finite = False
                # constraint block: top rc principal directions weighted by relative sv
                if rcu > 0:
                    for r in range(nc):
                        for q in range(6):
                            v = C[r, q] / L if q >= 3 else C[r, q]
                            if not math.isfinite(v):
                                finite = False
                            Ct[r, q] = v
                if not finite:
                    out[i] = np.nan
                    continue
                if rcu > 0:
                    _jacobi_sv(Ct, np.int64(6), nc, Vd, np.int64(0), svc)
                    for r in range(nc):
                        used[r] = False
                    s0 = 0.0
                    for r in range(nc):
                        s0 = max(s0, svc[r])
                    s0 = max(s0, 1e-300)
                    for r in range(rcu):
                        best = -1
                        for q in range(nc):
                            if not used[q] and (best < 0 or svc[q] > svc[best]):
                                best = q
                        used[best] = True
                        for q in range(6):
                            Ct[best, q] /= s0
                        # row na + r of the system
                        if k > 6:
                            for q in range(6):
                                M[q, na + r] = Ct[best, q]
                        else:
                            for q in range(6):
                                M[na + r, q] = Ct[best, q]
                # Jacobi works on columns (stored as rows of M): the k x 6 system itself when
                # k > 6, its transpose (k columns of length 6) otherwise.
                if k > 6:
                    for a in range(na):
                        for q in range(6):
                            M[q, a] = A[a, q]
                    _jacobi_sv(M, k, np.int64(6), Vd, np.int64(0), sv)
                else:
                    for a in range(na):
                        for q in range(6):
                            M[a, q] = A[a, q]
                    _jacobi_sv6(M, k, sv)
                smin = np.inf
                for q in range(kk):
                    smin = min(smin, sv[q])
                out[i] = smin

    def _lti_kernel(p, R, valid, code, act, geo, sc, upuL, ext, na, nc, L, rtol, inp, outp, lti, c0, c1):
        N = p.shape[0]
        m = na - 1 + nc
        for c in range(c0, c1):
            A, scale, anchor, C, Tw, w = _legs_scratch(na, nc)
            O = np.empty((6, max(m, 1)))
            V = np.empty((6, 6))
            sv = np.empty(6)
            B = np.empty((6, 6))
            VB = np.empty((6, 3))
            P = np.empty((6, 6))
            svb = np.empty(6)
            bb = np.empty(6)
            WV = np.empty((6, 6))
            for i in range(c * CHUNK, min(N, (c + 1) * CHUNK)):
                ok = valid[i] and _legs(p, R, i, code, act, geo, sc, upuL, ext, A, scale, anchor, C, Tw, w)
                if ok:
                    for a in range(na):
                        for q in range(6):
                            if not math.isfinite(A[a, q]):
                                ok = False
                    for r in range(nc):
                        for q in range(6):
                            if not math.isfinite(C[r, q]):
                                ok = False
                if not ok:
                    for a in range(na):
                        inp[i, a] = np.nan
                        outp[i, a] = np.nan
                    lti[i] = np.nan
                    continue
                for a in range(na):
                    for q in range(3, 6):
                        A[a, q] /= L
                for r in range(nc):
                    for q in range(3, 6):
                        C[r, q] /= L
                # Square and well conditioned (sigma_min > 1e-6 sigma_max): every leg's set of
                # twists reciprocal to the other rows is one-dimensional (singular values
                # interlace, so the others keep rank 5 at the 1e-9 threshold), spanned by the
                # column of W^-1 = V S^-1 U^T of its row: one SVD for all legs.
                square = False
                if na + nc == 6:
                    for r in range(6):
                        for q in range(6):
                            WV[q, r] = A[r, q] if r < na else C[r - na, q]
                    _jacobi_sv(WV, np.int64(6), np.int64(6), V, np.int64(1), sv)
                    smax = 0.0
                    smin = np.inf
                    for q in range(6):
                        smax = max(smax, sv[q])
                        smin = min(smin, sv[q])
                    square = smin > 1e-6 * smax
                low = np.inf
                for a in range(na):
                    if square:
                        # t = sum_j v_j u_j[a] / sigma_j, with u_j[a] = WV[j, a] / sigma_j
                        for q in range(6):
                            tq = 0.0
                            for j in range(6):
                                tq += V[j, q] * (WV[j, a] / (sv[j] * sv[j]))
                            bb[q] = tq
                        rx = anchor[a, 0] - p[i, 0]
                        ry = anchor[a, 1] - p[i, 1]
                        rz = anchor[a, 2] - p[i, 2]
                        cx, cy, cz = _cross(rx, ry, rz, bb[3], bb[4], bb[5])
                        v0 = bb[0] - cx / L
                        v1 = bb[1] - cy / L
                        v2 = bb[2] - cz / L
                        g = v0 * v0 + v1 * v1 + v2 * v2
                        bt = 0.0
                        for q in range(6):
                            bt += A[a, q] * bb[q]
                        val = bt * bt / g if g > 0.0 else 0.0
                        fn = math.sqrt(A[a, 0] * A[a, 0] + A[a, 1] * A[a, 1] + A[a, 2] * A[a, 2])
                        o = min(math.sqrt(max(val, 0.0)) / max(fn, 1e-300), 1.0)
                        outp[i, a] = o
                        ii = min(abs(scale[a]), 1.0)
                        inp[i, a] = ii
                        low = min(low, o, ii)
                        continue
                    # rows: the other actuation wrenches and every constraint wrench
                    row = 0
                    for b in range(na):
                        if b != a:
                            for q in range(6):
                                O[q, row] = A[b, q]
                            row += 1
                    for r in range(nc):
                        for q in range(6):
                            O[q, row] = C[r, q]
                        row += 1
                    smax = _sv_or_none(O, m, V, sv)
                    thr = rtol * max(smax, 1e-300)
                    d = 0
                    for q in range(6):
                        if not sv[q] > thr:
                            for q2 in range(6):
                                B[q2, d] = V[q, q2]
                            d += 1
                    if d == 0:
                        val = 0.0
                    else:
                        rx = anchor[a, 0] - p[i, 0]
                        ry = anchor[a, 1] - p[i, 1]
                        rz = anchor[a, 2] - p[i, 2]
                        for e in range(d):
                            s_ = 0.0
                            for q in range(6):
                                s_ += B[q, e] * A[a, q]
                            bb[e] = s_
                            cx, cy, cz = _cross(rx, ry, rz, B[3, e], B[4, e], B[5, e])
                            VB[e, 0] = B[0, e] - cx / L
                            VB[e, 1] = B[1, e] - cy / L
                            VB[e, 2] = B[2, e] - cz / L
                        if d == 1:
                            g = VB[0, 0] * VB[0, 0] + VB[0, 1] * VB[0, 1] + VB[0, 2] * VB[0, 2]
                            val = bb[0] * bb[0] / g if g > 0.0 else 0.0
                        else:
                            _jacobi_sv(VB, np.int64(3), d, P, np.int64(1), svb)
                            s0 = 0.0
                            for e in range(d):
                                s0 = max(s0, svb[e])
                            val = 0.0
                            for e in range(d):
                                s2 = svb[e] * svb[e]
                                if s2 > 1e-12 * s0 * s0:
                                    pb = 0.0
                                    for e2 in range(d):
                                        pb += P[e, e2] * bb[e2]
                                    val += pb * pb / s2
                    fn = math.sqrt(A[a, 0] * A[a, 0] + A[a, 1] * A[a, 1] + A[a, 2] * A[a, 2])
                    o = min(math.sqrt(max(val, 0.0)) / max(fn, 1e-300), 1.0)
                    outp[i, a] = o
                    ii = min(abs(scale[a]), 1.0)
                    inp[i, a] = ii
                    low = min(low, o, ii)
                lti[i] = low

    def _kappa_kernel(p, R, valid, T, angcol, code, act, geo, sc, upuL, ext, na, nc, L, out, c0, c1):
        N = p.shape[0]
        nt = T.shape[2]
        mn = min(na, nt)
        for c in range(c0, c1):
            A, scale, anchor, C, Tw, w = _legs_scratch(na, nc)
            J = np.empty((max(na, nt), max(na, nt)))
            sv = np.empty(max(na, nt))
            Vd = np.empty((1, 1))
            for i in range(c * CHUNK, min(N, (c + 1) * CHUNK)):
                if not (valid[i] and _legs(p, R, i, code, act, geo, sc, upuL, ext, A, scale, anchor, C, Tw, w)):
                    out[i] = np.nan
                    continue
                finite = True
                for a in range(na):
                    for col in range(nt):
                        s_ = 0.0
                        for q in range(6):
                            s_ += (A[a, q] / scale[a]) * T[i, q, col]
                        if angcol[col]:
                            s_ /= L
                        if not math.isfinite(s_):
                            finite = False
                        if na >= nt:  # Jacobi on columns, stored as rows
                            J[col, a] = s_
                        else:
                            J[a, col] = s_
                if not finite:
                    out[i] = np.nan
                    continue
                if na >= nt:
                    _jacobi_sv(J, na, nt, Vd, np.int64(0), sv)
                else:
                    _jacobi_sv(J, nt, na, Vd, np.int64(0), sv)
                smax = 0.0
                smin = np.inf
                for q in range(mn):
                    smax = max(smax, sv[q])
                    smin = min(smin, sv[q])
                if smin > 1e-14 * smax:
                    out[i] = smax / smin
                else:
                    out[i] = np.inf

    def _dir_kernel(p, R, valid, code, act, geo, sc, upuL, ext, na, nc, dirs, reach, c0, c1):
        """Unit leg directions (N, n_legs, 3) base -> platform and reachability."""
        N = p.shape[0]
        nl = code.shape[0]
        for c in range(c0, c1):
            A, scale, anchor, C, Tw, w = _legs_scratch(na, nc)
            for i in range(c * CHUNK, min(N, (c + 1) * CHUNK)):
                reach[i] = valid[i] and _legs(p, R, i, code, act, geo, sc, upuL, ext, A, scale, anchor, C, Tw, w)
                for j in range(nl):
                    qx, qy, qz = geo[j, 1, 0], geo[j, 1, 1], geo[j, 1, 2]
                    ax = p[i, 0] + R[i, 0, 0] * qx + R[i, 0, 1] * qy + R[i, 0, 2] * qz
                    ay = p[i, 1] + R[i, 1, 0] * qx + R[i, 1, 1] * qy + R[i, 1, 2] * qz
                    az = p[i, 2] + R[i, 2, 0] * qx + R[i, 2, 1] * qy + R[i, 2, 2] * qz
                    bx, by, bz = geo[j, 0, 0], geo[j, 0, 1], geo[j, 0, 2]
                    t = code[j]
                    if t == _CHAIN:
                        o = np.int64(sc[j, 0])
                        dirs[i, j, 0] = ext[i, o + _EXT_D]
                        dirs[i, j, 1] = ext[i, o + _EXT_D + 1]
                        dirs[i, j, 2] = ext[i, o + _EXT_D + 2]
                    elif t == _PUS or t == _PRS:
                        e0, e1, e2 = geo[j, 2, 0], geo[j, 2, 1], geo[j, 2, 2]
                        Ll = sc[j, 0]
                        dx, dy, dz = ax - bx, ay - by, az - bz
                        de = dx * e0 + dy * e1 + dz * e2
                        disc = Ll * Ll - (dx * dx + dy * dy + dz * dz - de * de)
                        s = de + sc[j, 1] * math.sqrt(disc) if disc >= 0.0 else np.nan
                        bx, by, bz = bx + s * e0, by + s * e1, bz + s * e2
                        dirs[i, j, 0] = (ax - bx) / Ll
                        dirs[i, j, 1] = (ay - by) / Ll
                        dirs[i, j, 2] = (az - bz) / Ll
                    elif t == _RUS:
                        cx, cy, cz, ok = _rus_tip(ax - bx, ay - by, az - bz, geo, sc, j)
                        dirs[i, j, 0] = (ax - bx - cx) / sc[j, 0]
                        dirs[i, j, 1] = (ay - by - cy) / sc[j, 0]
                        dirs[i, j, 2] = (az - bz - cz) / sc[j, 0]
                    else:
                        ux, uy, uz = _unit3(ax - bx, ay - by, az - bz)
                        dirs[i, j, 0], dirs[i, j, 1], dirs[i, j, 2] = ux, uy, uz


    # Each kernel once, serial over a range of chunks (nogil): large batches are spread over
    # threads by core.over_blocks, one design's few thousand poses run on the calling thread
    # (studies parallelise over designs).
    _KERNELS = {}
    for _f in (_margin_kernel, _lti_kernel, _kappa_kernel, _dir_kernel):
        _KERNELS[_f.__name__] = njit(**_jit)(_f)

#: Batches of at least this many poses are spread over threads.
PARALLEL_MIN = 16384


#: Kernels that claim their blocks of poses themselves (:func:`core._timed_claims`), with their
#: CPU time per pose (ns, one core, 5-PUS/UPU, measured): a batch is spread over threads from
#: :data:`WORK_MIN_NS` of work (while that pays, ``core.TIMING``), in blocks of a few poses, so
#: one design's few hundred feasible poses of the singularity margin (~3 us a pose, the SVDs of
#: the wrench system) are shared by the threads, a late crew thread taking fewer.
_CLAIMING = {"_margin_kernel": 3000.0}
#: Work (ns of one core) from which a batch is spread over threads: about what 8192 poses of the
#: feasibility kernel take (``core.PARALLEL_MIN``).
WORK_MIN_NS = 4.0e5
#: Poses per block of a claiming kernel's parallel batch: at least this many.
MIN_BLOCK = 4


def _kernel(name: str, n: int):
    """``kernel(*args)`` for ``n`` poses: a claiming kernel (:data:`_CLAIMING`) over blocks its
    threads claim (:func:`core._timed_claims`; its work in poses of the feasibility kernel,
    ``n * cost * core.PARALLEL_MIN / WORK_MIN_NS``, decides whether threads pay), any other
    over all chunks of CHUNK poses, spread over threads when ``n >= PARALLEL_MIN``. Every pose
    is computed alone: the split never changes a result."""
    k = _KERNELS[name]
    cost = _CLAIMING.get(name)
    if cost is not None:
        work = n * cost * core.PARALLEL_MIN / WORK_MIN_NS

        def claimed(*args):
            core._timed_claims(name, lambda block, claim, nblk: k(*args, block, claim, nblk), n, work,
                               unit=MIN_BLOCK)

        return claimed
    nchunk = (n + CHUNK - 1) // CHUNK

    def run(*args):
        over_blocks(lambda c0, c1: k(*args, c0, c1), nchunk, n >= PARALLEL_MIN)

    return run


# ---------------------------------------------------------------------------------------------
# Entry points
# ---------------------------------------------------------------------------------------------
def _out(a, single):
    return a[0] if single else a


def singularity_margin(mech, X) -> np.ndarray:
    """Compiled :meth:`Mechanism.singularity_margin` (N,) (NaN where unreachable). Raises
    ``_Unsupported`` (an ``Exception``) when :func:`coverage` is False."""
    plan = _plan(mech)
    code, act, geo, sc, nc = plan
    Xa, single, valid, p, R, _ = _poses(mech, X, False)
    upuL = _upu_lengths(plan, p, R)
    out = np.empty(Xa.shape[0])
    kernel = _kernel("_margin_kernel", Xa.shape[0])
    kernel(p, R, valid, code, act, geo, sc, upuL, _chain_ext(mech.legs, plan, p, R), int(mech.n_actuators), nc,
           int(mech.constraint_rank),
           float(mech.length_scale), out)
    return _out(out, single)


def singularity_margin_at(legs, p, R, n_actuators: int, constraint_rank: int, length_scale: float) -> np.ndarray:
    """Compiled singularity margin (N,) of the legs ``legs`` at explicit platform poses ``p``
    (N, 3), ``R`` (N, 3, 3), NaN where a leg cannot reach: the margin of
    :meth:`Mechanism.singularity_margin_of_states` for a mechanism with these legs, its
    structural ``constraint_rank`` and ``length_scale`` (UPU moments scaled by the mean leg
    length over these poses). For poses that are not a parametrisation's, e.g. the actual
    poses of a mechanism as built (:mod:`parasynth.measures.robustness`). Raises ``_Unsupported`` (an
    ``Exception``) when a leg has no compiled form."""
    _check_legs(legs)
    plan = _legs_plan(legs)
    code, act, geo, sc, nc = plan
    p = np.ascontiguousarray(p, dtype=float)
    R = np.ascontiguousarray(R, dtype=float)
    n = p.shape[0]
    out = np.empty(n)
    if not n:
        return out
    upuL = _upu_lengths(plan, p, R)
    kernel = _kernel("_margin_kernel", n)
    kernel(p, R, np.ones(n, np.bool_), code, act, geo, sc, upuL, _chain_ext(legs, plan, p, R), int(n_actuators), nc,
           int(constraint_rank),
           float(length_scale), out)
    return out


def transmission(mech, X, rtol: float = 1e-9):
    """Compiled input (N, n_act), output (N, n_act) and local (N,) transmission indices of
    :func:`parasynth.measures.indices.transmission_indices`."""
    plan = _plan(mech)
    code, act, geo, sc, nc = plan
    Xa, single, valid, p, R, _ = _poses(mech, X, False)
    upuL = _upu_lengths(plan, p, R)
    N, na = Xa.shape[0], int(mech.n_actuators)
    inp, outp, lti = np.empty((N, na)), np.empty((N, na)), np.empty(N)
    kernel = _kernel("_lti_kernel", N)
    kernel(p, R, valid, code, act, geo, sc, upuL, _chain_ext(mech.legs, plan, p, R), na, nc, float(mech.length_scale),
           float(rtol), inp, outp, lti)
    return _out(inp, single), _out(outp, single), _out(lti, single)


def local_transmission_index(mech, X, rtol: float = 1e-9) -> np.ndarray:
    """Compiled LTI (N,) of :func:`parasynth.measures.indices.local_transmission_index`."""
    return transmission(mech, X, rtol)[2]


def condition_number(mech, X, length: float | None = None) -> np.ndarray:
    """Compiled :func:`parasynth.measures.indices.local_condition_number` in the task space (N,):
    the Jacobian ``mech.jacobian(X)`` with angular-coordinate columns divided by ``length``
    (default ``mech.length_scale``); ``inf`` when singular, NaN where unreachable."""
    plan = _plan(mech)
    code, act, geo, sc, nc = plan
    L = float(mech.length_scale if length is None else length)
    Xa, single, valid, p, R, T = _poses(mech, X, True)
    upuL = _upu_lengths(plan, p, R)
    angcol = np.array([c in mech.angular_coordinates for c in mech.task_coordinates], dtype=np.bool_)
    out = np.empty(Xa.shape[0])
    kernel = _kernel("_kappa_kernel", Xa.shape[0])
    kernel(p, R, valid, T, angcol, code, act, geo, sc, upuL, _chain_ext(mech.legs, plan, p, R), int(mech.n_actuators),
           nc, L, out)
    return _out(out, single)


def constraint_rank(mech, X=None) -> int:
    """Compiled :meth:`Mechanism.structural_constraint_rank` at pose ``X`` (default ``home``):
    the rank of the union of the legs' reciprocal wrench spaces (null spaces of their joint
    twists). Raises ``ValueError`` when a leg cannot reach the pose."""
    plan = _plan(mech)
    code, act, geo, sc, nc = plan
    X0 = mech.home if X is None else np.asarray(X, dtype=float)
    home = mech.home_platform_pose() if X is None and hasattr(mech, "home_platform_pose") else None
    if home is not None:  # the pose the NumPy reference takes, computed when the mechanism was built
        (p, R), valid = home, (True,)
    else:
        Xa, _, valid, p, R, _ = _poses(mech, X0[None, :], False)
    r = -1
    if valid[0]:
        r = int(_constraint_rank_kernel(p, R, code, geo, sc, _chain_ext(mech.legs, plan, p, R),
                                        float(mech.length_scale)))
    if r < 0:
        raise ValueError(f"{mech.name}: pose {X0.tolist()} is not reachable")
    return r


def leg_directions(mech, X) -> tuple[np.ndarray, np.ndarray]:
    """Unit leg directions base -> platform (N, n_legs, 3) (the legs' ``direction``) and
    reachability (N,)."""
    plan = _plan(mech)
    code, act, geo, sc, nc = plan
    Xa, single, valid, p, R, _ = _poses(mech, X, False)
    upuL = np.ones(len(code))
    N = Xa.shape[0]
    dirs, reach = np.empty((N, len(code), 3)), np.empty(N, np.bool_)
    _kernel("_dir_kernel", N)(p, R, valid, code, act, geo, sc, upuL, _chain_ext(mech.legs, plan, p, R),
                              int(mech.n_actuators), nc, dirs, reach)
    return _out(dirs, single), _out(reach, single)


def signatures() -> dict:
    """{kernel name: (dispatcher, argument types)} of the index kernels, as
    :func:`parasynth.engine.core.signatures`."""
    if not HAVE_NUMBA:
        return {}
    f1, f2, f3 = _array("f8", 1), _array("f8", 2), _array("f8", 3)
    i1, b1 = _array("i8", 1), _array("b1", 1)
    i8, f8 = _nbt.int64, _nbt.float64
    legs = (i1, i1, f3, f2, f1, f2, i8, i8)  # code, act, geo, sc, upuL, ext, na, nc
    return {
        "_upu_mean_lengths": (_upu_mean_lengths, (f2, f3, i1, f3)),
        "_constraint_rank_kernel": (_constraint_rank_kernel, (f2, f3, i1, f3, f2, f2, f8)),
        "_chain_rows_kernel": (_chain_rows_kernel, (f2, f3, f3, f2, f1, f8, i1, i8, i8, f1, i8, f8, f2, i8, i8, i8)),
        "_margin_kernel": (_KERNELS["_margin_kernel"], (f2, f3, b1) + legs + (i8, f8, f1, i8, i1, i8)),
        "_lti_kernel": (_KERNELS["_lti_kernel"], (f2, f3, b1) + legs + (f8, f8, f2, f2, f1, i8, i8)),
        "_kappa_kernel": (_KERNELS["_kappa_kernel"], (f2, f3, b1, f3, b1) + legs + (f8, f1, i8, i8)),
        "_dir_kernel": (_KERNELS["_dir_kernel"], (f2, f3, b1) + legs + (f3, b1, i8, i8)),
    }
