"""Feasibility, constraint margins and poses of pose batches on the compiled kernels, behind the
entry points of :mod:`parasynth.engine` (which loads this module at the first compiled
evaluation: it imports :mod:`parasynth.engine.core` and with it numba).

Plans live in the engine's one record of each mechanism object (:func:`core.record_of`), one per
constraint selection. Where the kernels do not cover a mechanism (see :mod:`parasynth.engine`),
the mechanism's NumPy reference answers and :func:`core.warn_fallback` -- the engine's one
fallback policy -- says why with an :class:`~parasynth.model.mechanism.EngineFallbackWarning`, once
per entry point, model class and reason.
"""

from __future__ import annotations

import numpy as np

from . import chains, core
from .core import HAVE_NUMBA, Unsupported, warn_fallback

__all__ = ["feasible", "feasible_extents", "margins", "compiled_pose_batch", "compiled_unknowns", "available", "reason",
           "plan"]

# ---------------------------------------------------------------------------------------------
# plans: one record per mechanism object (core.record_of), one plan per constraint selection
# ---------------------------------------------------------------------------------------------
def _selection(mech, names):
    return mech._select(names)


def _warn(mech, why: str, what: str = "is_feasible/constraint_margins") -> None:
    warn_fallback(what, mech, why, stacklevel=6)


def plan(mech, names=None):
    """(KernelPlan or None, reason or None) for ``mech`` and the constraints ``names``."""
    if not HAVE_NUMBA:
        return None, "numba (not importable, or disabled by PARASYNTH_NO_NUMBA)"
    cons = _selection(mech, names)
    key = tuple(map(id, cons))
    legs = tuple(map(id, mech.legs))
    per = core.record_of(mech).setdefault("feasibility", {})
    hit = per.get(key)
    if hit is not None and hit[0] == legs and hit[1] is mech.constraints and hit[2] == key:
        return hit[3], hit[4]
    try:
        p, why = core.build_plan(mech, cons), None
    except Unsupported as e:
        p, why = None, str(e)
    except (KeyError, AttributeError, ImportError, ValueError, TypeError, IndexError) as e:
        p, why = None, f"this mechanism ({type(e).__name__}: {e})"
    per[key] = (legs, mech.constraints, key, p, why, cons)  # cons kept alive: ids stay unique
    return p, why


def available(mech, names=None) -> bool:
    """Whether the compiled path covers ``mech`` (with the constraints ``names``)."""
    return plan(mech, names)[0] is not None


def reason(mech, names=None) -> str | None:
    """Why the compiled path does not cover ``mech`` (None if it does)."""
    return plan(mech, names)[1]


def _compiled_plan(mech, names):
    p, why = plan(mech, names)
    if p is None and not chains.covers(mech):
        _warn(mech, why)
    return p


# ---------------------------------------------------------------------------------------------
# entry points
# ---------------------------------------------------------------------------------------------
def _kernel_poses(mech, X):
    """(contiguous float64 (N, n_task), single) for the kernels: ``mech._poses`` without its
    NumPy pass that masks huge lengths as NaN -- the kernels test every coordinate against
    its limit (``Program.pose_limit``, the same magnitude), with the same outcome, and a
    serial pass over the whole batch would cost a third of the parallel kernel's time. Input
    that is not a float batch of the right shape goes through ``mech._poses`` (and its errors)."""
    if isinstance(X, np.ndarray) and X.dtype == np.float64 and X.ndim in (1, 2) and X.shape[-1] == mech.n_task:
        single = X.ndim == 1
        Xa = X[None, :] if single else X
        return np.ascontiguousarray(Xa), single
    Xa, single = mech._poses(X)
    return np.ascontiguousarray(Xa, dtype=np.float64), single


def feasible(mech, X, names=None, floor_margin=None):
    """(N,) bool: reachable and every selected constraint satisfied at poses ``X`` -- the
    answer of ``mech.is_feasible(X, names, engine="numpy")`` (see the agreement contract in
    :mod:`parasynth.engine.core`). A single pose (n_task,) gives a scalar bool.
    ``floor_margin(mech, X)``: the singularity margin (the compiled index kernel), with which
    the plan's singularity-margin floors are applied to the poses the kernel accepts."""
    p = _compiled_plan(mech, names)
    if p is None:  # chain limbs: their compiled inverse kinematics, the rest as the reference
        return chains.feasible(mech, X, names) if chains.covers(mech) else mech._is_feasible_numpy(X, names)
    Xc, single = _kernel_poses(mech, X)
    out, amb = core.run_feasible(p, Xc)
    if amb:  # batch-dependent RPS/RPU reachability: NumPy decides
        return mech._is_feasible_numpy(X, names)
    if p.floors:
        sel = np.flatnonzero(out)
        if sel.size:
            floor = max(f for _, f in p.floors)
            with np.errstate(invalid="ignore"):
                out[sel] = np.asarray(floor_margin(mech, Xc[sel])) >= floor  # NaN: not feasible
    return out[0] if single else out


def feasible_extents(mech, X, names=None):
    """``(ok (N,) bool, lo (3,), hi (3,))``: :func:`feasible` of poses ``X`` (N, n_task) and the
    least and greatest platform position over the feasible ones, from one kernel pass (the
    positions ``compiled_pose_batch`` gives; +inf / -inf when none is feasible). None -- the
    caller then asks :func:`feasible` and the poses apart -- where that pass does not give the
    whole answer: no plan, a singularity-margin floor (applied after the kernel), or
    reachability NumPy decides for the batch."""
    p, _ = plan(mech, names)
    if p is None or p.floors or not (isinstance(X, np.ndarray) and X.ndim == 2):
        return None
    Xc, _ = _kernel_poses(mech, X)
    out, amb, lo, hi = core.run_feasible(p, Xc, extents=True)
    if amb:
        return None
    return out, lo, hi


def margins(mech, X, names=None, floor_margin=None) -> dict:
    """{constraint name: (N,) margin} as ``mech.constraint_margins(X, names, engine="numpy")``
    (-inf where a leg cannot reach the pose or a margin is undefined); the singularity-margin
    floors' columns from ``floor_margin`` (see :func:`feasible`)."""
    p = _compiled_plan(mech, names)
    if p is None:
        return chains.margins(mech, X, names) if chains.covers(mech) else mech._constraint_margins_numpy(X, names)
    Xc, single = _kernel_poses(mech, X)
    M, amb = core.run_margins(p, Xc)
    if amb:
        return mech._constraint_margins_numpy(X, names)
    if p.floors:
        # the kernel leaves a floor's column at +inf where the pose is reachable, -inf elsewhere
        reach = np.flatnonzero(np.isposinf(M[:, p.floors[0][0]]))
        if reach.size:
            sm = np.asarray(floor_margin(mech, Xc[reach]), dtype=float)
            for ci, floor in p.floors:
                M[reach, ci] = np.where(np.isnan(sm), -np.inf, sm - floor)
    return {n: (M[0, j] if single else M[:, j]) for j, n in enumerate(p.names)}


def compiled_unknowns(mech, Xa):
    """``(valid, U)`` of poses ``Xa``: the solved unknowns of the description's ``task.solve``
    from its compiled program (as ``mech.solved_unknowns``), or None when the program does not
    cover ``mech`` or it solves nothing."""
    if not HAVE_NUMBA or not core._is_described(mech) or getattr(mech.description.task, "solve", None) is None:
        return None
    try:
        prog, consts = core.program_constants(mech, {}, False, unknowns=True)
    except (Unsupported, KeyError, IndexError, TypeError, ValueError, AttributeError):
        return None
    if prog.unknown_regs is None:
        return None
    return core.run_unknowns(prog, consts, Xa)


def compiled_pose_batch(mech, Xa, twist: bool = False, masked: bool = True):
    """``(valid, p, R, T)`` of poses ``Xa`` (N, n_task) from the description's compiled program
    (as :func:`parasynth.engine.pose_batch`) -- for a motion closing on chain limbs, which the
    program cannot hold, from the chain limbs' compiled closure (:func:`chains.pose_batch`) --
    or None, having said why once, when neither covers ``mech`` (the caller then evaluates the
    NumPy methods). ``masked=False``: ``Xa`` did not go through ``mech._poses`` (its huge
    lengths are not NaN yet): the program tests every coordinate against its limit, the
    chain limbs' closure is given the masked poses."""
    if not HAVE_NUMBA:
        _warn(mech, "numba (not importable, or disabled by PARASYNTH_NO_NUMBA)", "pose_batch")
        return None
    if not core._is_described(mech):
        _warn(mech, f"the model class {type(mech).__name__} (not a mechanism description)", "pose_batch")
        return None
    try:
        prog, consts = core.program_constants(mech, {}, twist)
    except (Unsupported, KeyError, IndexError, TypeError, ValueError, AttributeError) as e:
        if chains.closes_on_chains(mech):  # the closure's solve compiled, the pose from its unknowns
            return chains.pose_batch(mech, Xa if masked else mech._poses(Xa)[0], twist)
        _warn(mech, str(e), "pose_batch")
        return None
    return core.run_pose(prog, consts, Xa, twist)
