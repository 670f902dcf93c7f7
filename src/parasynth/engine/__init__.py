"""The evaluation engine: feasibility, constraint margins and poses of batches of poses,
compiled from what a mechanism description declares, with the NumPy methods of
:class:`~parasynth.mechanism.Mechanism` as the reference.

Entry points (``engine="compiled"`` is the default everywhere; ``"numpy"`` the reference):

* :func:`feasible` ``(mech, X, names=None, engine=...)`` -> (N,) bool, as
  ``Mechanism.is_feasible``;
* :func:`margins` ``(mech, X, names=None, engine=...)`` -> {name: (N,)}, as
  ``Mechanism.constraint_margins``;
* :func:`pose_batch` ``(mech, X, twist=False)`` -> ``(valid (N,), p (N, 3), R (N, 3, 3), T)``
  with T (N, 6, n_task) the twist map when ``twist`` (else None), as ``mech.pose_valid``,
  ``mech.pose``, ``mech.twist_map`` (p, R, T are those of the home pose where not valid,
  like the NumPy methods evaluated on home-substituted poses -- here they are simply not
  meaningful: use ``valid``);
* :func:`available` ``(mech, names=None)`` and :func:`reason` ``(mech, names=None)``: whether
  the compiled path covers ``mech`` and, if not, why;
* :func:`warm_up` ``(work, progress=..., stop=...)``: run ``work`` (one design, or
  :func:`exercise` of a mechanism) on a compiling thread, saying "compiling the evaluation
  engine (once per installation) ..." only when numba actually compiles, and staying
  interruptible (see :mod:`parasynth.engine.warmup`);
* :func:`reference` (a context manager): inside it every entry point evaluates with the NumPy
  reference, ``engine="compiled"`` requests included -- for work too small to repay compiling
  (``parasynth validate``).

How it works: :mod:`parasynth.engine.program` translates the task parametrisation and the
expression margins into a register program (parameters as a constants vector, so one program
serves every design of a description); :mod:`parasynth.engine.core` holds the plans (leg
geometry and limits as arrays, read for every mechanism) and the numba kernels that interpret
the program per sub-block of poses and run the legs' inverse kinematics and checks.

Anything the compiled path does not handle -- a model class that is not a description, a leg
or constraint type it does not know, an expression construct it cannot translate, a
translation that does not reproduce ``mech.pose`` on probe poses, numba missing (or
``PARASYNTH_NO_NUMBA`` set) -- runs on NumPy, and says so once per mechanism kind and reason
(a :class:`EngineFallbackWarning` naming the construct, also logged on the
``parasynth.engine`` logger). The answer is never a different one silently.
"""

from __future__ import annotations

import contextlib
import contextvars

import numpy as np

from . import core
from .core import BLOCK, HAVE_NUMBA, SUB, EngineFallbackWarning, KernelPlan, Unsupported, warn_fallback
from .warmup import COMPILING, WarmUp, exercise, warm_up

__all__ = ["HAVE_NUMBA", "ENGINES", "EngineFallbackWarning", "feasible", "margins", "pose_batch", "available",
           "reason", "check_engine", "plan", "warm_up", "exercise", "WarmUp", "COMPILING", "reference"]

ENGINES = ("compiled", "numpy")


_FORCED: contextvars.ContextVar = contextvars.ContextVar("parasynth_engine_forced", default=None)


def check_engine(engine, arg: str = "engine") -> str:
    """Validate an engine name ("compiled" or "numpy") and return the engine to use: "numpy"
    inside :func:`reference`."""
    if not isinstance(engine, str) or engine.lower() not in ENGINES:
        raise ValueError(f"{arg} must be one of {', '.join(ENGINES)}; got {engine!r}")
    return _FORCED.get() or engine.lower()


@contextlib.contextmanager
def reference():
    """Within the block (this thread or task), every engine entry point -- feasibility,
    margins, poses, the pose-wise indices -- evaluates with the NumPy reference, whatever
    ``engine`` it is asked for: nothing is compiled. For a handful of evaluations (checking a
    study file) that should not wait for a cold compile; the answers agree with the compiled
    path to ~1e-12 (see the agreement contracts)."""
    token = _FORCED.set("numpy")
    try:
        yield
    finally:
        _FORCED.reset(token)


# ---------------------------------------------------------------------------------------------
# plans: one record per mechanism object (core.record_of), one plan per constraint selection
# ---------------------------------------------------------------------------------------------
def _selection(mech, names):
    return mech._select(names)


def _warn(mech, why: str, what: str = "is_feasible/constraint_margins") -> None:
    warn_fallback(what, mech, why, stacklevel=5)


def plan(mech, names=None):
    """(KernelPlan or None, reason or None) for ``mech`` and the constraints ``names``."""
    if not HAVE_NUMBA:
        return None, "numba (not importable, or disabled by PARASYNTH_NO_NUMBA)"
    cons = _selection(mech, names)
    key = tuple(id(c) for c in cons)
    legs = tuple(id(leg) for leg in mech.legs)
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


def _compiled_plan(mech, names, engine):
    if check_engine(engine) == "numpy":
        return None
    p, why = plan(mech, names)
    if p is None:
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


def feasible(mech, X, names=None, engine: str = "compiled"):
    """(N,) bool: reachable and every selected constraint satisfied at poses ``X`` -- the
    answer of ``mech.is_feasible(X, names, engine="numpy")`` (see the agreement contract in
    :mod:`parasynth.engine.core`). A single pose (n_task,) gives a scalar bool."""
    p = _compiled_plan(mech, names, engine)
    if p is None:
        return mech._is_feasible_numpy(X, names)
    Xc, single = _kernel_poses(mech, X)
    out, amb = core.run_feasible(p, Xc)
    if amb:  # batch-dependent RPS/RPU reachability: NumPy decides
        return mech._is_feasible_numpy(X, names)
    return out[0] if single else out


def margins(mech, X, names=None, engine: str = "compiled") -> dict:
    """{constraint name: (N,) margin} as ``mech.constraint_margins(X, names, engine="numpy")``
    (-inf where a leg cannot reach the pose or a margin is undefined)."""
    p = _compiled_plan(mech, names, engine)
    if p is None:
        return mech._constraint_margins_numpy(X, names)
    Xc, single = _kernel_poses(mech, X)
    M, amb = core.run_margins(p, Xc)
    if amb:
        return mech._constraint_margins_numpy(X, names)
    return {n: (M[0, j] if single else M[:, j]) for j, n in enumerate(p.names)}


def pose_batch(mech, X, twist: bool = False, engine: str = "compiled"):
    """``(valid, p, R, T)`` of poses X (N, n_task): validity of the parametrisation (as
    ``mech.pose_valid``), platform positions (N, 3), rotations (N, 3, 3) and, with ``twist``,
    the twist map (N, 6, n_task) (as ``mech.twist_map``; else None). Entries of invalid
    poses are unspecified."""
    Xa, _ = mech._poses(X)
    prog = None
    if check_engine(engine) == "compiled":
        if not HAVE_NUMBA:
            _warn(mech, "numba (not importable, or disabled by PARASYNTH_NO_NUMBA)", "pose_batch")
        elif not core._is_described(mech):
            _warn(mech, f"the model class {type(mech).__name__} (not a mechanism description)", "pose_batch")
        else:
            try:
                prog = core.program_for(mech, {}, twist)
                consts = prog.constants(mech._penv)
            except (Unsupported, KeyError, IndexError, TypeError, ValueError) as e:
                _warn(mech, str(e), "pose_batch")
                prog = None
    if prog is not None:
        ok, P, R, T = core.run_pose(prog, consts, Xa, twist)
        return ok, P, R, T
    with np.errstate(all="ignore"):
        valid = mech.pose_valid(Xa)
        Xs = np.where(valid[:, None], Xa, mech.home)
        P, R = mech.pose(Xs)
        T = mech.twist_map(Xs) if twist else None
    return valid, np.asarray(P, dtype=float), np.asarray(R, dtype=float), T
