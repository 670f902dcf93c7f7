"""Parasitic (dependent) pose coordinates solved on the legs' closure equations: the NumPy
reference.

A leg whose joints leave the platform fewer than six freedoms can follow a pose only if the
pose satisfies its *closure equations*: scalar functions of the platform pose that vanish where
the leg assembles. A mechanism whose task coordinates are only some of the pose coordinates
(``z, alpha, beta`` of a 3-RPS) states the others (``x, y, gamma``) as *unknowns* found by a
Gauss-Newton solve of all legs' closure equations at each pose (docs/structures.md, "Parasitic
motion").

Closure equations of the leg models of :mod:`parasynth.model.legs` (``A`` the platform anchor,
``B`` the base anchor, ``n`` the unit leg direction, lengths divided by the length scale ``L``):

* RPS, PRS: the sphere lies in the plane of the revolute joint, ``(A - B) . r_axis / L = 0``;
* RPU: the same, and the platform axis of the universal joint is normal to the revolute axis,
  ``(R u_platform_axis) . r_axis = 0``;
* UPU: the two cross axes of the universal joints (normal to the leg) are parallel, i.e. the
  base axis, the leg and the platform axis are coplanar, ``det(u_axis, n, R u_platform_axis) =
  0`` (the assumption of Tsai's 3-UPU: both intermediate axes fixed parallel on the leg);
* SPS, UPS, PUS, RUS: none (six-freedom chains);
* a limb from a joint string (:class:`parasynth.model.chains.ChainLeg`): one per constraint
  wrench of the limb at its home pose, the error of the chain's least-squares reach of the
  platform anchor frame (its forward kinematics against the anchor's position and the platform's
  orientation) on the directions of those wrenches (``ChainLeg.closure_residuals``; compiled in
  :func:`parasynth.engine.chains.closure_residuals`).

:func:`closure_residuals` evaluates them; :func:`gauss_newton` solves a batch of square or
over-determined systems with a numerical Jacobian; :func:`implicit_gradient` gives the
derivative of the solved unknowns with respect to the task coordinates (implicit function
theorem), so that twist maps and Jacobians follow the solved motion.
"""

from __future__ import annotations

import numpy as np

from .spatial import cross, dot_rows, rotate_rows

__all__ = ["CLOSURE_COUNTS", "closure_count", "closure_residuals", "closure_geometry", "closure_jacobian", "GEOMETRY_WIDTH", "gauss_newton", "implicit_gradient",
           "ParasiticError", "SOLVE_KEY", "SOLVE_TOL", "SOLVE_ITERATIONS", "HOME_ITERATIONS"]

#: The entry of a described mechanism's parameter environment that holds its task.solve data
#: (length scale, home solution, scales of the unknowns, :func:`closure_geometry`): the compiled
#: solve's parameter slots. Not a name an expression can use.
SOLVE_KEY = "__solve__"
#: Closure equations per leg type (see the module docstring).
CLOSURE_COUNTS = {"SPS": 0, "UPS": 0, "PUS": 0, "RUS": 0, "RPS": 1, "PRS": 1, "RPU": 2, "UPU": 1}
#: Convergence tolerance on the largest scaled residual (dimensionless).
SOLVE_TOL = 1e-12
#: Gauss-Newton iterations at a pose (from the home solution); the compiled solve unrolls as many
#: (engine/parasitic.py), so that both accept the same poses.
SOLVE_ITERATIONS = 12
#: Iterations of the home solve (from task.solve.start or a structure's nominal home).
HOME_ITERATIONS = 60


class ParasiticError(ValueError):
    """A leg whose closure equations are not known, or a system that cannot be solved."""


def _is_chain(leg) -> bool:
    """A limb that states its own closure equations (a chain limb of :mod:`parasynth.model.chains`)."""
    return callable(getattr(leg, "closure_residuals", None)) and hasattr(leg, "n_closure")


def closure_count(leg) -> int:
    """Number of closure equations of ``leg`` (by its joint string; a chain limb says)."""
    if _is_chain(leg):
        return int(leg.n_closure)
    try:
        return CLOSURE_COUNTS[leg.joints]
    except KeyError:
        raise ParasiticError(f"leg {leg.name}: no closure equations for leg type {leg.joints!r}; known: "
                             f"{', '.join(CLOSURE_COUNTS)}") from None


#: Numbers per leg in :func:`closure_geometry`.
GEOMETRY_WIDTH = 12


def closure_geometry(legs) -> np.ndarray:
    """The legs' closure geometry as one flat array, per leg (in order) its base anchor, platform
    anchor (platform frame), first axis and second axis (12 numbers; the axes are ``r_axis`` and
    ``u_platform_axis`` of RPS, PRS and RPU, ``u_axis`` and ``u_platform_axis`` of UPU, zeros
    where a leg has none, and for a chain limb, whose closure the compiled solve reads from the
    limb itself): what the compiled solve reads (:mod:`parasynth.engine.parasitic`)."""
    rows = []
    for leg in legs:
        closure_count(leg)
        if _is_chain(leg):
            rows.append(np.concatenate([leg.base, leg.platform, np.zeros(6)]))
            continue
        a1 = getattr(leg, "u_axis" if leg.joints == "UPU" else "r_axis", None)
        a2 = getattr(leg, "u_platform_axis", None)
        z = np.zeros(3)
        rows.append(np.concatenate([leg.base, leg.platform, z if a1 is None else a1, z if a2 is None else a2]))
    return np.concatenate(rows) if rows else np.zeros(0)


def _leg_residuals(leg, p, R, L, chain=None):
    if _is_chain(leg):
        return leg.closure_residuals(p, R, L) if chain is None else chain(leg, p, R)
    A = leg.platform_points(p, R)
    j = leg.joints
    if j in ("RPS", "RPU"):
        out = [dot_rows(A - leg.base, leg.r_axis) / L]
        if j == "RPU":
            out.append(dot_rows(rotate_rows(R, leg.u_platform_axis), leg.r_axis))
        return out
    if j == "PRS":
        return [dot_rows(A - leg.base, leg.r_axis) / L]
    if j == "UPU":
        d = A - leg.base
        # a zero-length UPU (the platform anchor on its base joint) has no direction: its
        # residual is NaN there (0/0) and the pose not valid, as in the compiled pose program
        n = d / np.linalg.norm(d, axis=-1, keepdims=True)
        a4 = rotate_rows(R, leg.u_platform_axis)
        return [np.einsum("ij,ij->i", cross(np.broadcast_to(leg.u_axis, n.shape), n), a4)]
    if closure_count(leg) == 0:
        return []
    raise ParasiticError(f"leg {leg.name}: closure equations of {j!r} are not implemented")  # pragma: no cover


def closure_residuals(legs, p, R, L: float, chain=None) -> np.ndarray:
    """The closure equations of every leg at poses ``p`` (N, 3), ``R`` (N, 3, 3): (N, k),
    dimensionless (lengths divided by ``L``). ``chain(leg, p, R)``: the closure equations of a
    chain limb (a list of (N,) arrays) by another solve than the limb's own
    (``parasynth.engine.chains.closure_residuals`` passes the compiled one)."""
    p = np.asarray(p, dtype=float)
    cols = []
    for leg in legs:
        cols += _leg_residuals(leg, p, R, float(L), chain)
    if not cols:
        return np.zeros((p.shape[0], 0))
    return np.stack(cols, axis=-1)


def _jacobian(fun, X, U, F0, h):
    """dF/dU (N, k, m) by central differences of step ``h`` (m,), all 2m perturbed systems in one
    call of ``fun``."""
    N, m = U.shape
    E = np.concatenate([np.diag(h), -np.diag(h)])  # (2m, m)
    Up = (U[None, :, :] + E[:, None, :]).reshape(2 * m * N, m)
    Xp = np.broadcast_to(X[None], (2 * m,) + X.shape).reshape((2 * m * N,) + X.shape[1:])
    Fp = fun(Xp, Up).reshape(2 * m, N, -1)
    return np.moveaxis((Fp[:m] - Fp[m:]) / (2.0 * h[:, None, None]), 0, -1)


def gauss_newton(fun, X, U0, scale, tol: float = SOLVE_TOL, iterations: int = SOLVE_ITERATIONS):
    """Solve ``fun(X, U) = 0`` for the unknowns ``U`` (N, m) from ``U0`` at each row of ``X``.

    ``fun(X, U)`` returns (N, k) residuals, k >= m (a consistent over-determined system is
    solved in the least-squares sense); ``scale`` (m,) is each unknown's magnitude (the length
    scale for lengths, 1 for angles), used for the difference steps and to limit each step to
    half a scale (a damped Newton); a row whose residuals are within ``tol`` takes one more step
    (to the rounding floor). Returns ``(U, converged)``; rows that do not converge to ``tol`` are
    NaN and ``converged`` False."""
    X = np.asarray(X, dtype=float)
    U = np.array(np.broadcast_to(U0, (X.shape[0], len(scale))), dtype=float)
    scale = np.asarray(scale, dtype=float)
    h = 1e-7 * scale
    done = np.zeros(X.shape[0], dtype=bool)
    if U.shape[1] == 0:
        return U, np.ones(X.shape[0], dtype=bool)
    with np.errstate(all="ignore"):
        for _ in range(iterations):
            act = np.flatnonzero(~done)
            if not act.size:
                break
            Xa, Ua = X[act], U[act]
            F = fun(Xa, Ua)
            # a row within tol takes this one more step (to the rounding floor: the compiled solve
            # iterates on, and the two agree to rounding) and is then done
            done[act[np.all(np.abs(F) <= tol, axis=-1)]] = True
            J = _jacobian(fun, Xa, Ua, F, h) * scale  # in scaled unknowns
            step = np.full(Ua.shape, np.nan)
            good = np.all(np.isfinite(J), axis=(1, 2)) & np.all(np.isfinite(F), axis=1)
            if np.any(good):
                # least squares, minimum-norm step (pinv: k > m, k < m and dependent equations alike;
                # a row that does not converge is NaN at the end)
                Jg, Fg = J[good], F[good]
                dz = -np.einsum("nij,nj->ni", np.linalg.pinv(Jg, rcond=1e-10), Fg)
                big = np.max(np.abs(dz), axis=-1, keepdims=True)
                step[good] = dz * np.minimum(1.0, 0.5 / np.maximum(big, 1e-300))
            U[act] = Ua + step * scale
        F = fun(X, U)
        done = np.all(np.abs(F) <= tol * 10.0, axis=-1) & np.all(np.isfinite(U), axis=-1)
    U[~done] = np.nan
    return U, done


def _stencil(fun, X, U, which, h):
    """d fun / d (X or U) (N, k, n) by the five-point central difference of step ``h`` (n,)
    (truncation ~h^4, rounding ~eps/h: ~1e-13 with h = 1e-3 of the scale)."""
    V = X if which == "x" else U
    N, n = V.shape
    E = np.concatenate([np.diag(h) * c for c in (-2.0, -1.0, 1.0, 2.0)])  # (4n, n)
    Vp = (V[None] + E[:, None, :]).reshape(4 * n * N, n)
    other = U if which == "x" else X
    Op = np.broadcast_to(other[None], (4 * n,) + other.shape).reshape((4 * n * N,) + other.shape[1:])
    F = (fun(Vp, Op) if which == "x" else fun(Op, Vp)).reshape(4, n, N, -1)
    D = (F[0] - 8.0 * F[1] + 8.0 * F[2] - F[3]) / (12.0 * h[:, None, None])  # (n, N, k)
    return np.moveaxis(D, 0, -1)


def closure_jacobian(fun, X, U, uscale) -> np.ndarray:
    """d fun / d U (N, k, m) in scaled unknowns (five-point differences, steps 1e-3 of ``uscale``)."""
    uscale = np.asarray(uscale, dtype=float)
    with np.errstate(all="ignore"):
        return _stencil(fun, np.asarray(X, dtype=float), U, "u", 1e-3 * uscale) * uscale


def implicit_gradient(fun, X, U, xscale, uscale) -> np.ndarray:
    """dU/dX (N, m, n) of the solution ``U`` of ``fun(X, U) = 0``: ``-pinv(F_U) F_X`` with both
    Jacobians by five-point central differences (steps 1e-3 of ``xscale`` (n,) and ``uscale``
    (m,))."""
    X = np.asarray(X, dtype=float)
    N, n = X.shape
    m = U.shape[1]
    if m == 0:
        return np.zeros((N, 0, n))
    with np.errstate(all="ignore"):
        FU = _stencil(fun, X, U, "u", 1e-3 * np.asarray(uscale, dtype=float))
        FX = _stencil(fun, X, U, "x", 1e-3 * np.asarray(xscale, dtype=float))
        ok = np.all(np.isfinite(FU), axis=(1, 2)) & np.all(np.isfinite(FX), axis=(1, 2))
        G = np.full((N, m, n), np.nan)
        if np.any(ok):
            G[ok] = -np.linalg.pinv(FU[ok]) @ FX[ok]
    return G
