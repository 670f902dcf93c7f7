"""Measures of a design on a task (:class:`parasynth.model.task.Task`), and path continuity.

Every task measure of one design reads one :class:`TaskEvaluation`, built once per
(mechanism, task, pose constraints, engine) and kept while the mechanism lives: the platform
poses, their feasibility, the pose-wise indices, the static forces, the path and its inverse
dynamics are each computed once, on first use, vectorised over the poses (the compiled
engine's batch calls for feasibility, singularity margin, LTI and condition number).

Definitions (docs/tasks.md has the details):

* ``task_coverage``: share of the required poses that are feasible (reachable, every selected
  pose constraint met) and meet the task's floors, in [0, 1].
* ``task_margin_min``, ``task_lti_min``: smallest singularity margin (the mechanism's
  ``singularity_margin``) and local transmission index over the feasible poses;
  ``task_condition_max``: largest condition number of the actuator Jacobian ``d q / d X`` in
  SI units (columns of lengths per m, of angles per rad; *not* made homogeneous by a length
  scale, so its value depends on the units: SI), over the feasible poses.
* ``task_stiffness_min``: smallest translational stiffness (N/m) at the tool point over the
  feasible poses: ``1 / lambda_max`` of the compliance of the tool point's translation under a
  force at it (stiffness model of :mod:`parasynth.measures.stiffness`).
* ``task_position_error_max``: largest first-order worst-case position error (m) of the tool
  point over the feasible poses, ``||b||`` of the per-axis bounds (tolerances of
  :mod:`parasynth.measures.accuracy`).
* ``task_actuator_force_max``: largest ``|F_i|`` (N, or N m for a crank) balancing the
  task's wrench at the tool point and the payload's weight, massless legs, at the feasible
  poses; with ``wrench_signs`` the worst sign combination of the wrench's components; with a
  trajectory also the inverse dynamics of the payload (its mass and inertia on the platform,
  legs massless) at every path sample (:func:`parasynth.measures.dynamics.inverse_dynamics`).
* ``task_actuator_speed_max``: largest ``|dq_i/dt|`` along the path;
  ``task_actuator_power_max``: ``max_i |F_i| * max_i |dq_i/dt|`` over the path (a bound on the
  power of one actuator, W for linear actuators).
* ``envelope_clearance``: smallest clearance (m) of every body to the installation space at
  the feasible poses and path samples (negative: outside).
* ``installed_height``: the extent (m) along ``W``'s z of every body at every feasible pose;
  ``total_stroke``: sum over the actuators of the range of each actuator over the feasible
  poses and path samples (m, or rad for cranks); ``moving_mass``: legs as solid rods and the
  platform as a solid disc of ``density`` (kg).

Measures over poses return their worst value when no pose is feasible: 0 for a measure to
maximise (-inf for ``envelope_clearance``), inf for one to minimise.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from ..common.units import actuator_unit_kind, actuators_summary
from .accuracy import TOLERANCE_SETTINGS, _bound, _check_tolerances, sensitivity
from .dynamics import InertiaModel, LegInertia, PlatformInertia, RigidBody, _equivalent, _leg_bodies, _motion
from .. import engine
from .indices import WrenchSystem, _scale_wrench, leg_wrench_arrays, local_condition_number, local_transmission_index
from .measure_spec import Setting
from .objectives import COMMON_PARAMS, grinding_decoupling_ratio, grinding_max_force, register
from .objectives import get as get_measure
from .stiffness import STIFFNESS_SETTINGS, compliance, stiffness_matrix
from .usable import _orientation, sign_rule
from ..model.legs import PUS, RUS, SPS, UPS, LegState
from ..model.mechanism import ForwardKinematicsError
from ..model.task import Payload, Task, TaskError, _cross

__all__ = ["TaskEvaluation", "task_evaluation", "Continuity", "path_continuity", "assembly_mode_checked",
           "ASSEMBLY_MODE_SKIPPED", "static_task_forces", "leg_inertia",
           "task_measures", "TASK_MEASURES"]


# ---------------------------------------------------------------------------------------------
# forces: one pseudo-inverse, many loads
# ---------------------------------------------------------------------------------------------
def _balance_matrix(ws, L: float, rtol: float = 1e-10):
    """(G, ok): ``x = G @ w_scaled`` solves ``M x + w = 0`` in the least-squares sense as
    :func:`parasynth.measures.indices.static_forces` does (rows scaled, columns normalised,
    minimum norm), for any load ``w`` (the scaled load is ``w`` with moments / L)."""
    M = ws.matrix()
    ok = ws.reachable & np.all(np.isfinite(M), axis=(1, 2))
    Ms = np.swapaxes(_scale_wrench(np.swapaxes(np.where(ok[:, None, None], M, 0.0), 1, 2), L), 1, 2)
    cn = np.linalg.norm(Ms, axis=1)
    cn = np.where(cn > 0, cn, 1.0)
    U, s, Vt = np.linalg.svd(Ms / cn[:, None, :], full_matrices=False)
    keep = s > rtol * np.maximum(s[:, :1], 1e-300)
    sinv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    G = -np.einsum("nkj,nk,nik->nji", Vt, sinv, U) / cn[:, :, None]  # (N, k, 6)
    return G, ok


def _line_legs(mech):
    """``(base anchors (n, 3), platform anchors (n, 3))`` when every leg is an actuated SPS or
    UPS leg (their wrench is a unit force along the line of the anchors, no constraint wrench,
    rate scale 1, the state reachable where the anchors differ), else None."""
    legs = mech.legs
    if not legs or not all(type(leg) in (SPS, UPS) and leg.is_actuated for leg in legs):
        return None
    return (np.array([np.asarray(leg.base, dtype=float) for leg in legs]),
            np.array([np.asarray(leg.platform, dtype=float) for leg in legs]))


def _line_wrench_system(Xa, valid, p, R, base, plat) -> WrenchSystem:
    """The wrench system of SPS/UPS legs (:func:`_line_legs`) for all legs at once: the
    arithmetic of the legs' ``solve`` and ``actuation_wrench`` (the anchors rotated by one matrix
    product for all legs, so the values agree with the leg-by-leg ones to rounding), on arrays
    (N, 3, n_legs) whose components are contiguous per pose."""
    N, n = Xa.shape[0], base.shape[0]
    # few large temporaries: on a busy machine fresh memory costs more than the arithmetic
    r = R @ plat.T  # (N, 3, n): R a_i, the anchors relative to P
    A3 = r + p[:, :, None]  # the anchors in B
    u = A3 - base.T[None]
    length = np.sqrt(u[:, 0] * u[:, 0] + u[:, 1] * u[:, 1] + u[:, 2] * u[:, 2])  # (N, n)
    pos = length > 0
    np.divide(u, length[:, None, :], out=u, where=pos[:, None, :])  # unit leg directions
    if not pos.all():
        np.copyto(u, 0.0, where=~pos[:, None, :])
    # the actuation wrench (u, r x u), as force_wrench
    act = np.empty((N, n, 6))
    act[..., :3] = np.swapaxes(u, 1, 2)
    act[..., 3] = r[:, 1] * u[:, 2] - r[:, 2] * u[:, 1]
    act[..., 4] = r[:, 2] * u[:, 0] - r[:, 0] * u[:, 2]
    act[..., 5] = r[:, 0] * u[:, 1] - r[:, 1] * u[:, 0]
    reachable = valid & np.all(pos, axis=1)
    A, U = np.swapaxes(A3, 1, 2), np.swapaxes(u, 1, 2)  # (N, n, 3) views
    B = np.broadcast_to(base, A.shape)
    states = [LegState(length[:, i], pos[:, i], B[:, i], A[:, i], U[:, i], length[:, i]) for i in range(n)]
    S = np.ones((N, n))
    anchors = A
    C = np.zeros((N, 0, 6))
    if not reachable.all():
        anchors = A.copy()
        for arr in (act, S, anchors, C):
            arr[~reachable] = np.nan
    return WrenchSystem(Xa, reachable, act, S, C, anchors, p, R, states, False)


def _wrench_system(mech, X, engine_name: str = "compiled") -> WrenchSystem:
    """:func:`parasynth.measures.indices.wrench_system` without the passive joint angles (the
    wrenches do not need them) and with the platform poses from the engine's pose batch; for
    SPS/UPS legs computed for all legs at once (:func:`_line_wrench_system`)."""
    Xa, _ = mech._poses(X)
    valid, p, R, _ = engine.pose_batch(mech, Xa, engine=engine_name)
    lines = _line_legs(mech)
    if lines is not None:
        return _line_wrench_system(Xa, valid, p, R, *lines)
    states = [leg.solve(p, R, joint_angles=False) for leg in mech.legs]
    reachable = valid & np.logical_and.reduce([st.reachable for st in states])
    A, S, anchors, C = leg_wrench_arrays(mech, states, p, reachable)
    return WrenchSystem(Xa, reachable, A, S, C, anchors, p, R, states, False)


def static_task_forces(mech, X, loads, L=None, ws=None):
    """Generalised actuator forces (N, m, n_act) balancing each of the loads (N, m, 6) (wrenches
    about the platform point in the base frame) at poses ``X``, massless legs; NaN where
    unreachable. The least squares of :func:`parasynth.measures.indices.static_forces` (a
    square, regular system: its one solution, by LU)."""
    ws = _wrench_system(mech, X) if ws is None else ws
    Ls = float(mech.length_scale if L is None else L)
    w = _scale_wrench(np.asarray(loads, dtype=float), Ls)
    F = _solve_square(ws, w, Ls)
    if F is None:
        G, ok = _balance_matrix(ws, Ls)
        F = np.einsum("nkj,nmj->nmk", G[:, :ws.n_act, :], w)
        F[~ok] = np.nan
    return F


def _solve_square(ws, w, L):
    """Actuator forces (N, m, n_act) from ``M x = -w`` by LU where the wrench system is square
    and regular at every pose (None otherwise: the least squares decides)."""
    if ws.actuation.shape[1] + ws.constraint.shape[1] != 6 or not np.all(ws.reachable):
        return None
    # the columns of M as rows (N, k, 6): generalised actuator wrenches, then constraints
    if ws.constraint.shape[1]:
        with np.errstate(divide="ignore", invalid="ignore"):
            Wt = np.concatenate([ws.actuation / ws.rate_scale[..., None], ws.constraint], axis=1)
    elif np.all(ws.rate_scale == 1.0):  # moments / L in the same pass (dividing by 1 is exact)
        Wt = ws.actuation / np.array([1.0, 1.0, 1.0, L, L, L])
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            Wt = ws.actuation / ws.rate_scale[..., None]
    if not np.all(np.isfinite(Wt)):
        return None
    if ws.constraint.shape[1] or not np.all(ws.rate_scale == 1.0):
        Wt[..., 3:] /= L
    cn = Wt[..., 0] * Wt[..., 0]  # the column norms, summed in order
    for j in range(1, 6):
        cn += Wt[..., j] * Wt[..., j]
    cn = np.sqrt(cn)
    if np.any(cn <= 0):
        return None
    Wt /= cn[..., None]
    Mn = np.swapaxes(Wt, 1, 2)
    try:
        y = np.linalg.solve(Mn, -np.swapaxes(w, 1, 2))  # (N, k, m)
    except np.linalg.LinAlgError:
        return None
    # near a singularity (unknowns beyond 1e9 of the load) the least squares, which drops
    # singular values below 1e-10, decides
    scale = max(1.0, float(np.max(np.abs(w))))
    if not np.all(np.isfinite(y)) or float(np.max(np.abs(y))) > 1e9 * scale:
        return None
    x = y / cn[:, :, None]
    return np.swapaxes(x[:, :ws.n_act, :], 1, 2)


def _load_columns(task: Task, mech, X, R=None):
    """Loads at P (N, 1 + m, 6): the payload's weight (with the constant part of the wrench
    unless signs are asked for), then one column per wrench component taken with both signs.
    ``R``: the platform orientations at ``X`` when known."""
    if R is None:
        _, R = mech.pose(X)
    N = X.shape[0]
    pl = task.payload
    g = task.gravity_vector()
    f = pl.mass * np.broadcast_to(g, (N, 3))
    rc = R @ np.array(pl.com)
    base = np.concatenate([f, _cross(rc, f)], axis=1)
    cols = [base]
    w = task.wrench_components(R)
    if w is not None:
        r = R @ np.array(task.tool.offset)
        wp = np.concatenate([w[:, :3], w[:, 3:] + _cross(r, w[:, :3])], axis=1)
        if task.wrench_signs:
            for k in range(6):
                wk = np.zeros_like(w)
                wk[:, k] = w[:, k]
                if np.any(wk):
                    cols.append(np.concatenate([wk[:, :3], wk[:, 3:] + _cross(r, wk[:, :3])], axis=1))
        else:
            cols[0] = base + wp
    return np.stack(cols, axis=1)


def _payload_load(pl, ok, R, t, acc, g):
    """The equivalent load (N, 6) about P of the payload alone (massless legs): the one of
    :func:`parasynth.measures.dynamics.equivalent_load`, weight minus mass times acceleration of
    the centre of mass and minus the rate of angular momentum, the same arithmetic; NaN where
    not ``ok``."""
    v, w = t[:, :3], t[:, 3:]
    a, al = acc[:, :3], acc[:, 3:]
    rc = R @ np.asarray(pl.com)
    ac = a + _cross(al, rc) + _cross(w, _cross(w, rc))
    Iw = R @ pl.tensor @ np.swapaxes(R, 1, 2)
    F = pl.mass * (g - ac)
    Tq = -(np.einsum("nij,nj->ni", Iw, al) + _cross(w, np.einsum("nij,nj->ni", Iw, w)))
    weq = np.concatenate([F, _cross(rc, F) + Tq], axis=1)
    weq[~ok] = np.nan
    return weq


def _worst(F):
    """|F| worst over the sign columns: |F_0| + sum_k |F_k| (N, n_act)."""
    return np.abs(F[:, 0]) + np.sum(np.abs(F[:, 1:]), axis=1)


# ---------------------------------------------------------------------------------------------
# continuity along the path
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Continuity:
    """Whether a path is followed: ``first_break`` (index of the first sample that breaks it,
    None when none does), ``reason`` ("infeasible", "floor", "singularity", "assembly mode"
    or ""), ``rule``: how a singularity is detected ("sign": the oriented singularity
    function changes sign; else the margin floor, in words)."""

    first_break: int | None
    reason: str
    rule: str

    @property
    def ok(self) -> bool:
        return self.first_break is None


#: Why :func:`path_continuity` skips the assembly-mode check of an under-actuated mechanism.
ASSEMBLY_MODE_SKIPPED = "assembly mode not checked (fewer actuators than freedoms)"


def assembly_mode_checked(mech) -> bool:
    """Whether :func:`path_continuity` checks the assembly mode on ``mech``: not for an
    under-actuated mechanism (fewer actuators than task freedoms, e.g. the 4-UPS/1-RPS with 4
    actuators and 5 freedoms), whose actuators do not fix the pose (forward kinematics has a
    family of solutions, so there is no assembly mode to keep)."""
    return mech.n_actuators >= mech.n_task


def path_continuity(mech, X, feasible=None, floor: float = 1e-3, substeps: int | None = None,
                    tol: float | None = None, margin=None, floors_ok=None, max_step: float = 0.05) -> Continuity:
    """The first sample of the ordered path ``X`` (K, d) that the robot cannot reach from the
    previous one: an infeasible sample (``feasible`` (K,) bool, default reachable), a sample
    where the task's floors fail (``floors_ok`` (K,) bool, reason "floor"), a singularity
    crossed (where the wrench system is square: the oriented singularity function of
    :meth:`Mechanism.singularity_function`, its constraint basis oriented continuously along the
    path as :func:`parasynth.measures.usable.oriented_determinant` does, changes sign between
    samples; otherwise the singularity margin falls below ``floor``), or a change of assembly
    mode: forward kinematics continued from the previous sample's pose (Newton steps on the
    inverse kinematics, every transition at once) through ``substeps`` equal steps of the
    actuators (default: enough for steps of at most ``max_step`` times the length scale, or
    ``max_step`` rad, at least 1) does not return the inverse kinematics' pose within ``tol``
    (default 1e-6 of the length scale for lengths, 1e-6 rad for angles). For an under-actuated
    mechanism (fewer actuators than task freedoms) the actuators do not determine the pose and
    the assembly-mode check is skipped (``rule`` says so)."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    K = len(X)
    q_all = _actuators(mech, X)
    reach = np.all(np.isfinite(q_all), axis=1)
    ok = reach if feasible is None else (np.asarray(feasible, bool) & reach)
    rule = sign_rule(mech)
    bad = np.zeros(K, bool)
    reason = np.full(K, "", dtype=object)

    def flag(mask, why):
        new = mask & ~bad
        bad[new] = True
        reason[new] = why

    flag(~ok, "infeasible")
    if floors_ok is not None:
        flag(~np.asarray(floors_ok, bool), "floor")
    if rule is None:
        det, V = mech.singularity_function(X)
        if V.shape[1]:
            o = np.ones(K)
            o[1:] = _orientation(V[:-1], V[1:])  # b's basis against a's, for every neighbouring pair
            o = np.where(np.isfinite(o), np.sign(o), 1.0)
            det = det * np.cumprod(o)
        cross = np.zeros(K, bool)
        cross[1:] = (np.sign(det[1:]) != np.sign(det[:-1])) | (det[1:] == 0)
        flag(cross, "singularity")
        rule_txt = "sign"
    else:
        m = mech.singularity_margin(X) if margin is None else margin
        flag(~(m >= floor), "singularity")
        rule_txt = rule
    first = int(np.argmax(bad)) if bad.any() else K
    n = first - 1  # transitions 0 -> 1, ..., n-1 -> n are between good samples
    if not assembly_mode_checked(mech):
        n = 0
        rule_txt += "; " + ASSEMBLY_MODE_SKIPPED
    if n > 0:
        q = q_all
        L = mech.length_scale
        ang_act = np.array([mech.actuator_kinds[a] == "angle" for a in mech.actuators])
        qs = np.where(ang_act, 1.0, L)
        if substeps is None:
            substeps = int(np.clip(np.ceil(np.max(np.abs(np.diff(q[:n + 1], axis=0)) / qs) / max_step), 1, 100))
        lin = np.array([c not in mech.angular_coordinates for c in mech.task_coordinates])
        tl = np.where(lin, 1e-6 * L, 1e-6) if tol is None else np.full(mech.n_task, float(tol))
        Xc = _continue(mech, X[:n], q[:n], q[1:n + 1], int(substeps), qs)
        # where the chord steps have not converged (near a singularity), the damped forward
        # kinematics from the previous sample decides
        with np.errstate(invalid="ignore"):
            res = np.max(np.abs(_actuators(mech, Xc) - q[1:n + 1]) / qs, axis=1)
        slow = np.flatnonzero(~(res <= 1e-10))
        for _ in range(4):  # samples it refuses are not reached (NaN), the others solved again
            if not slow.size:
                break
            try:
                Xc[slow] = mech.forward_kinematics(q[1:n + 1][slow], guess=X[:n][slow])
                break
            except ForwardKinematicsError as e:
                failed = slow[e.indices[e.indices < slow.size]]
                Xc[failed] = np.nan
                slow = np.setdiff1d(slow, failed)
        else:
            Xc[slow] = np.nan
        far = ~np.all(np.abs(Xc - X[1:n + 1]) <= tl, axis=1)
        new = np.zeros(K, bool)
        new[1:n + 1] = far
        flag(new, "assembly mode")
    if not bad.any():
        return Continuity(None, "", rule_txt)
    i = int(np.argmax(bad))
    return Continuity(i, str(reason[i]), rule_txt)


def _actuators(mech, X) -> np.ndarray:
    """Actuator values (N, n_act) of poses ``X`` (the inverse kinematics without passive joint
    angles), NaN where unreachable or where the parametrisation is undefined."""
    Xa, _ = mech._poses(X)
    valid = mech.pose_valid(Xa)
    with np.errstate(all="ignore"):
        p, R = mech.pose(np.where(valid[:, None], Xa, mech.home))
    states = [leg.solve(p, R, joint_angles=False) for leg in mech.legs]
    ok = valid & np.logical_and.reduce([st.reachable for st in states])
    q = np.stack([st.actuator for leg, st in zip(mech.legs, states) if leg.is_actuated], axis=-1)
    return np.where(ok[:, None], q, np.nan)


def _continue(mech, X0, q0, q1, substeps: int, qs, steps: int = 1, final: int = 4) -> np.ndarray:
    """Poses reached from ``X0`` (M, d) when the actuators move from ``q0`` to ``q1`` (M, n_act)
    in ``substeps`` equal steps, each followed by chord-Newton steps on the inverse kinematics
    (the actuator Jacobian once per sub-step; ``steps`` iterations, ``final`` after the last);
    NaN where a step leaves the reachable set."""
    X = X0.copy()
    for j in range(1, substeps + 1):
        qt = q0 + (j / substeps) * (q1 - q0)
        J = mech.jacobian(X)
        okJ = np.all(np.isfinite(J), axis=(1, 2))
        Jp = np.linalg.pinv(np.where(okJ[:, None, None], J / qs[None, :, None], 0.0), rcond=1e-12)
        for _ in range(final if j == substeps else steps):
            r = (_actuators(mech, X) - qt) / qs
            ok = okJ & np.all(np.isfinite(r), axis=1)
            X = np.where(ok[:, None], X - np.einsum("nij,nj->ni", Jp, np.where(ok[:, None], r, 0.0)), np.nan)
    return X


# ---------------------------------------------------------------------------------------------
# the evaluation of one design on one task
# ---------------------------------------------------------------------------------------------
_EVALS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _rod(mass: float, length: float, radius: float, offset: float) -> RigidBody:
    """A solid round rod: principal moments about its centre of mass, transverse
    ``m (3 r^2 + L^2) / 12`` twice and axial ``m r^2 / 2``."""
    t = mass * (3.0 * radius * radius + length * length) / 12.0
    return RigidBody(mass, (t, t, 0.5 * mass * radius * radius), offset)


def leg_inertia(mech, task: Task, lengths=None) -> InertiaModel:
    """The payload on the platform and the legs as solid rods of the task's ``leg_density``
    and leg diameter (``task.space.leg_diameter``, else the mechanism's ``leg_diameter``), as
    ``moving_mass`` models them: a telescopic (SPS, UPS) leg its longest length over the task
    (``lengths`` {leg name: m}; default the longest over the required poses it reaches) in two
    halves, a cylinder hinged at the base joint and a rod hinged at the platform joint, each
    half as long with its centre of mass at its middle (a quarter of the longest length from
    its joint); a PUS leg its link, a rod hinged at the platform joint (the carriage
    massless). The joints and actuators themselves are massless (an assumption: their masses
    depend on the hardware). Other legs (RUS cranks) are refused naming the key."""
    pl = task.payload
    platform = PlatformInertia(pl.mass, pl.com, pl.tensor)
    rho = float(task.leg_density)
    if rho <= 0:
        return InertiaModel(platform)
    d = task._leg_diameter(mech)
    if not d > 0:
        raise TaskError(f"{task.where}.loads.leg_density: the legs need a diameter (task.space.leg_diameter or the "
                        f"mechanism's leg_diameter parameter)")
    area, r = np.pi * d * d / 4.0, 0.5 * d
    if lengths is None and any(type(leg) in (SPS, UPS) for leg in mech.legs):
        ev = task_evaluation(mech, task._copy(trajectory=None))
        Y = ev.Xf if len(ev.Xf) else mech.home[None, :]
        _, states, _ = mech.leg_states(Y)
        lengths = {leg.name: float(np.nanmax(st.length)) for leg, st in zip(mech.legs, states)}
    legs = {}
    for leg in mech.legs:
        if type(leg) in (SPS, UPS):
            half = 0.5 * lengths[leg.name]
            body = _rod(rho * area * half, half, r, 0.5 * half)
            legs[leg.name] = LegInertia(cylinder=body, rod=body)
        elif type(leg) is PUS:
            Lk = float(leg.link_length)
            legs[leg.name] = LegInertia(rod=_rod(rho * area * Lk, Lk, r, 0.5 * Lk))
        else:
            raise TaskError(f"{task.where}.loads.leg_density: leg masses are modelled for SPS, UPS and PUS legs; "
                            f"{mech.name} has {type(leg).__name__} legs (give 0: massless legs)")
    return InertiaModel(platform, legs)


def _leg_loads(mech, inertia: InertiaModel, states, p, twist, accel) -> list:
    """The leg bodies of :func:`parasynth.measures.dynamics._equivalent` from the platform's
    twist and acceleration (N, 6) and the legs' states (as ``_motion`` builds them)."""
    v, w = twist[:, :3], twist[:, 3:]
    a, al = accel[:, :3], accel[:, 3:]
    out = []
    for leg, st in zip(mech.legs, states):
        li = inertia.legs.get(leg.name)
        if li is None:
            continue
        r = st.platform_point - p
        vA = v + _cross(w, r)
        aA = a + _cross(al, r) + _cross(w, _cross(w, r))
        out.append((leg, st, r, _leg_bodies(leg, st, vA, aA, li)))
    return out


def task_evaluation(mech, task: Task, constraints=None, engine: str = "compiled") -> "TaskEvaluation":
    """The cached :class:`TaskEvaluation` of ``mech`` on ``task``."""
    if not isinstance(task, Task):
        raise TaskError(f"task: give a parasynth.Task, got {type(task).__name__}")
    per = _EVALS.setdefault(mech, {})
    key = (id(task), None if constraints is None else tuple(constraints), engine)
    ev = per.get(key)
    if ev is None or ev.task is not task:
        if len(per) > 16:
            per.clear()
        ev = per[key] = TaskEvaluation(mech, task, constraints, engine)
    return ev


class TaskEvaluation:
    """Everything the task measures read, each computed once on first use (see the module
    documentation)."""

    def __init__(self, mech, task: Task, constraints=None, engine: str = "compiled"):
        self.mech, self.task, self.constraints, self.engine = mech, task, constraints, engine
        self._c = {}

    def _get(self, name, fn):
        if name not in self._c:
            self._c[name] = fn()
        return self._c[name]

    # poses
    @property
    def X(self) -> np.ndarray:
        return self._get("X", lambda: self.task.platform_poses(self.mech))

    @property
    def feasible(self) -> np.ndarray:
        return self._get("feasible", lambda: np.asarray(
            self.mech.is_feasible(self.X, names=self.constraints, engine=self.engine), bool))

    @property
    def Xf(self) -> np.ndarray:
        return self.X[self.feasible]

    @property
    def margin(self) -> np.ndarray:
        return self._get("margin", lambda: self._on_feasible(
            lambda Y: self.mech.singularity_margin(Y, engine=self.engine)))

    @property
    def condition(self) -> np.ndarray:
        return self._get("condition", lambda: self._on_feasible(
            lambda Y: local_condition_number(self.mech, Y, length=1.0, engine=self.engine)))

    @property
    def lti(self) -> np.ndarray:
        return self._get("lti", lambda: self._on_feasible(
            lambda Y: local_transmission_index(self.mech, Y, engine=self.engine)))

    def _on_feasible(self, fn):
        out = np.full(len(self.X), np.nan)
        f = self.feasible
        if f.any():
            out[f] = fn(self.X[f])
        return out

    @property
    def covered(self) -> np.ndarray:
        """(N,) bool: feasible and every floor met."""
        def f():
            ok = self.feasible.copy()
            fl = self.task.floors
            if "singularity_margin" in fl:
                ok &= self.margin >= fl["singularity_margin"]
            if "condition" in fl:
                ok &= self.condition <= fl["condition"]
            if "lti" in fl:
                ok &= self.lti >= fl["lti"]
            return ok
        return self._get("covered", f)

    # forces
    @property
    def static_forces(self) -> np.ndarray:
        """Worst |F| (N_feasible, n_act) at the feasible poses."""
        def f():
            Y = self.Xf
            if not len(Y):
                return np.zeros((0, self.mech.n_actuators))
            task = self.task
            if task.wrench is not None and task.wrench.ndim == 2:  # per pose: those of the feasible poses
                task = task._copy(wrench=task.wrench[self.feasible])
            ws = _wrench_system(self.mech, Y, self.engine)
            loads = _load_columns(task, self.mech, Y, ws.R)
            if task.leg_density > 0:  # the legs' weight, at rest
                inertia = self.inertia
                z = np.zeros((len(Y), 6))
                legs = _leg_loads(self.mech, inertia, ws.states, ws.p, z, z)
                g = task.gravity_vector()
                loads = loads.copy()
                loads[:, 0] += _equivalent(self.mech, Y, ws.reachable, ws.p, ws.R, z, z, legs,
                                           InertiaModel(PlatformInertia(), inertia.legs), g, None)
            return _worst(static_task_forces(self.mech, Y, loads, ws=ws))
        return self._get("static", f)

    @property
    def inertia(self) -> InertiaModel:
        """The payload and the legs' rods (:func:`leg_inertia`; massless legs by default)."""
        def f():
            lengths = None
            if self.task.leg_density > 0 and any(type(leg) in (SPS, UPS) for leg in self.mech.legs):
                Y = self.Xf if len(self.Xf) else self.mech.home[None, :]
                _, states, _ = self.mech.leg_states(Y)
                lengths = {leg.name: float(np.nanmax(st.length)) for leg, st in zip(self.mech.legs, states)}
            return leg_inertia(self.mech, self.task, lengths)
        return self._get("inertia", f)

    @property
    def path(self):
        return self._get("path", lambda: self.task.path(self.mech))

    @property
    def path_feasible(self) -> np.ndarray:
        return self._get("path_feasible", lambda: np.asarray(
            self.mech.is_feasible(self.path.X, names=self.constraints, engine=self.engine), bool))

    def _need_path(self, what):
        if self.task.trajectory is None:
            raise TaskError(f"task.trajectory: {what} needs a trajectory (motion limits or timed poses)")
        return self.path

    def _dynamics(self):
        """Worst |F| and |dq/dt| (K, n_act) at the path samples (NaN where infeasible): the
        inverse dynamics of :mod:`parasynth.measures.dynamics` (the payload's mass and inertia
        on the platform, massless legs, the equivalent load of every sample) with the wrench
        (its sign combinations with ``wrench_signs``), one wrench system and one
        pseudo-inverse for every load; the rates from the same wrench system and twists."""
        def f():
            pa = self._need_path("inverse dynamics")
            mech, task = self.mech, self.task
            ok = self.path_feasible
            X = pa.X[ok]
            F_out = np.full((len(pa.X), mech.n_actuators), np.nan)
            q_out = np.full((len(pa.X), mech.n_actuators), np.nan)
            if not len(X):
                return F_out, q_out
            pl = task.payload
            inertia = self.inertia
            if pa.twist is not None:  # the platform's motion from the path
                ws = _wrench_system(mech, X, self.engine)
                Xa, okr, p, R, t, acc = X, ws.reachable, ws.p, ws.R, pa.twist[ok], pa.accel[ok]
                legs = _leg_loads(mech, inertia, ws.states, p, t, acc) if inertia.legs else []
            else:
                Xa, _, okr, ws, p, R, t, acc, legs = _motion(mech, X, pa.Xd[ok], pa.Xdd[ok], inertia)
            if legs:
                weq = _equivalent(mech, Xa, okr, p, R, t, acc, legs, inertia, task.gravity_vector(), None)
            else:
                weq = _payload_load(pl, okr, R, t, acc, task.gravity_vector())
            cols = [weq]
            if task.wrench is not None:
                Tw = task._copy(payload=Payload())
                if task.wrench.ndim == 2:  # per pose: the wrench of each segment's start pose
                    seg = pa.samples.segment[ok] if pa.samples is not None else np.zeros(len(X), int)
                    Tw = Tw._copy(wrench=task.wrench[seg])
                wc = _load_columns(Tw, mech, X, R)
                cols = [weq + wc[:, 0]] + [wc[:, k] for k in range(1, wc.shape[1])]
            F = static_task_forces(mech, X, np.stack(cols, axis=1), ws=ws)
            F_out[ok] = _worst(F)
            with np.errstate(invalid="ignore", divide="ignore"):
                q_out[ok] = np.abs(np.einsum("nkj,nj->nk", ws.actuation, t) / ws.rate_scale)
            return F_out, q_out
        return self._get("dynamics", f)

    @property
    def wrench_path_forces(self) -> np.ndarray:
        """Worst |F| (K, n_act) at the path samples that the task's wrench alone causes (its sign
        combinations with ``wrench_signs``; NaN where infeasible): by linearity, the change of
        the actuator forces when the wrench is applied on top of the payload's dynamics."""
        def f():
            pa = self._need_path("the forces of the wrench along the path")
            task, mech = self.task, self.mech
            if task.wrench is None:
                raise TaskError(f"{task.where}.loads.wrench: needed (the forces it causes along the path)")
            ok = self.path_feasible
            X = pa.X[ok]
            out = np.full((len(pa.X), mech.n_actuators), np.nan)
            if not len(X):
                return out
            ws = _wrench_system(mech, X, self.engine)
            Tw = task._copy(payload=Payload())
            if task.wrench.ndim == 2:  # per pose: the wrench of each segment's start pose
                seg = pa.samples.segment[ok] if pa.samples is not None else np.zeros(len(X), int)
                Tw = Tw._copy(wrench=task.wrench[seg])
            out[ok] = _worst(static_task_forces(mech, X, _load_columns(Tw, mech, X, ws.R), ws=ws))
            return out
        return self._get("wrench_path", f)

    @property
    def dynamic_forces(self) -> np.ndarray:
        """Worst |F| (K, n_act) at the path samples (NaN where infeasible)."""
        return self._dynamics()[0]

    @property
    def actuator_rates(self) -> np.ndarray:
        """|dq_i/dt| (K, n_act) along the path (NaN where infeasible)."""
        return self._dynamics()[1]

    # geometry
    @property
    def clearance(self) -> np.ndarray:
        """Clearance (m) of every body to the installation space at the feasible poses, then the
        feasible path samples. SPS/UPS legs: :meth:`Task.line_clearance` on the platform poses
        of the engine's pose batch (the legs are not solved); other legs: the legs' states
        (:meth:`Task.space_clearance`)."""
        def f():
            sets = [self.Xf]
            if self.task.trajectory is not None:
                sets.append(self.path.X[self.path_feasible])
            lines = _line_legs(self.mech) is not None
            out = []
            for Y in sets:
                if not len(Y):
                    out.append(np.zeros(0))
                elif lines:
                    _, p, R, _ = engine.pose_batch(self.mech, Y, engine=self.engine)
                    out.append(self.task.line_clearance(self.mech, p, R))
                else:
                    out.append(self.task.space_clearance(self.mech, Y))
            return np.concatenate(out)
        return self._get("clearance", f)

    def continuity(self, floor: float = 1e-3, substeps: int | None = None) -> Continuity:
        """:func:`path_continuity` along the path (or the poses in their order without one),
        with the task's floors applied to every sample."""
        def f():
            if self.task.trajectory is None:
                return path_continuity(self.mech, self.X, self.feasible, floor=floor, substeps=substeps,
                                       floors_ok=self.covered | ~self.feasible)
            X, feas = self.path.X, self.path_feasible
            return path_continuity(self.mech, X, feas, floor=floor, substeps=substeps,
                                   floors_ok=_floors_ok(self, X, feas))
        return self._get(("continuity", floor, substeps), f)


def _floors_ok(ev, X, feas) -> np.ndarray:
    """(K,) bool: the task's floors hold at the feasible samples ``X`` (True elsewhere)."""
    ok = np.ones(len(X), bool)
    fl = ev.task.floors
    if not fl or not feas.any():
        return ok
    Y, sub = X[feas], np.ones(int(feas.sum()), bool)
    with np.errstate(invalid="ignore"):
        if "singularity_margin" in fl:
            sub &= ev.mech.singularity_margin(Y, engine=ev.engine) >= fl["singularity_margin"]
        if "condition" in fl:
            sub &= local_condition_number(ev.mech, Y, length=1.0, engine=ev.engine) <= fl["condition"]
        if "lti" in fl:
            sub &= local_transmission_index(ev.mech, Y, engine=ev.engine) >= fl["lti"]
    ok[feas] = sub
    return ok


# ---------------------------------------------------------------------------------------------
# the registered measures
# ---------------------------------------------------------------------------------------------
_TASK = Setting("task", doc="the task (parasynth.Task)")
_BASE = {"task": _TASK, **COMMON_PARAMS}


def _ev(mech, task, kw):
    if task is None:
        raise TaskError("task: required (a parasynth.Task)")
    return task_evaluation(mech, task, kw.get("constraints"), kw.get("engine", "compiled"))


def _max(v, empty=np.inf):
    v = np.asarray(v, dtype=float)
    v = v[~np.isnan(v)]
    return float(np.max(v)) if v.size else empty


def _min(v, empty=0.0):
    v = np.asarray(v, dtype=float)
    v = v[~np.isnan(v)]
    return float(np.min(v)) if v.size else empty


def _one_actuator_unit(mech, name: str) -> None:
    """Refuse measure ``name`` on a mechanism with both linear actuators and cranks: its largest
    actuator force (speed) would compare N with N*m (m/s with rad/s)."""
    actuator_unit_kind("actuator_force", actuators_summary(mech.actuator_kinds.values()), name)


@register("task_coverage", unit="1", sense="maximize", settings=_BASE, cost="cheap")
def task_coverage(mech, task=None, **kw) -> float:
    """Share of the task's required poses that are feasible and meet its floors, in [0, 1]."""
    ev = _ev(mech, task, kw)
    return float(np.mean(ev.covered))


@register("task_margin_min", unit="1", sense="maximize", settings=_BASE, cost="cheap")
def task_margin_min(mech, task=None, **kw) -> float:
    """Smallest singularity margin over the task's feasible poses (0 if none)."""
    return _min(_ev(mech, task, kw).margin)


@register("task_condition_max", unit="1", sense="minimize", settings=_BASE, cost="cheap")
def task_condition_max(mech, task=None, **kw) -> float:
    """Largest condition number of the actuator Jacobian in SI units (not homogenised) over
    the task's feasible poses (inf if none)."""
    return _max(_ev(mech, task, kw).condition)


@register("task_lti_min", unit="1", sense="maximize", settings=_BASE, cost="cheap")
def task_lti_min(mech, task=None, **kw) -> float:
    """Smallest local transmission index over the task's feasible poses (0 if none)."""
    return _min(_ev(mech, task, kw).lti)


@register("task_stiffness_min", unit="N/m", kind="stiffness", sense="maximize", cost="cheap",
          settings={**_BASE, **{k: Setting(kind) for k, kind in STIFFNESS_SETTINGS.items()}})
def task_stiffness_min(mech, task=None, **kw) -> float:
    """Smallest translational stiffness (N/m) at the tool point over the task's feasible poses:
    1 / lambda_max of the tool point's translational compliance (0 if none)."""
    ev = _ev(mech, task, kw)
    stiff = {k: v for k, v in kw.items() if k in STIFFNESS_SETTINGS and v is not None}
    Y = ev.Xf
    if not len(Y):
        return 0.0
    K = stiffness_matrix(mech, Y, **stiff)
    C, Z = compliance(K, mech.length_scale)
    _, R = mech.pose(Y)
    r = R @ np.array(task.tool.offset)
    # displacement of the tool point: dp - r x dtheta; force f at it: (f, r x f) at P
    A = np.zeros((len(Y), 3, 6))
    A[:, :, :3] = np.eye(3)
    A[:, :, 3:] = -_skew(r)
    CT = A @ C @ np.swapaxes(A, 1, 2)
    ok = np.all(np.isfinite(CT), axis=(1, 2))
    lam = np.linalg.eigvalsh(np.where(ok[:, None, None], CT, 0.0))[:, -1]
    with np.errstate(divide="ignore"):
        k = np.where(lam > 0, 1.0 / np.where(lam > 0, lam, 1.0), 0.0)
    ZT = A @ np.where(np.isfinite(Z), Z, 0.0) @ np.swapaxes(A, 1, 2)
    k[np.linalg.norm(ZT, axis=(1, 2)) > 1e-7] = 0.0
    k[~ok] = np.nan
    return _min(k)


def _skew(v):
    z = np.zeros(v.shape[0])
    return np.stack([np.stack([z, -v[:, 2], v[:, 1]], -1), np.stack([v[:, 2], z, -v[:, 0]], -1),
                     np.stack([-v[:, 1], v[:, 0], z], -1)], -2)


@register("task_position_error_max", unit="m", kind="length", sense="minimize", cost="expensive",
          settings={**_BASE, **{k: Setting(kind, default=0.0, low=0.0) for k, kind in TOLERANCE_SETTINGS.items()}})
def task_position_error_max(mech, task=None, **kw) -> float:
    """Largest first-order worst-case position error (m) of the tool point over the task's
    feasible poses, ||b|| of the per-axis bounds for the given tolerances (inf if none)."""
    ev = _ev(mech, task, kw)
    tol = _check_tolerances({k: v for k, v in kw.items() if k in TOLERANCE_SETTINGS})
    Y = ev.Xf
    if not len(Y):
        return np.inf
    S, src = sensitivity(mech, Y)
    _, R = mech.pose(Y)
    r = R @ np.array(task.tool.offset)
    with np.errstate(invalid="ignore"):
        ST = S[:, :3] - np.einsum("nij,njk->nik", _skew(r), S[:, 3:])
    b = _bound(ST, src, tol)
    return _max(np.linalg.norm(b, axis=1))


@register("task_actuator_force_max", unit="N (N*m for cranks)", kind="actuator_force", sense="minimize",
          settings=_BASE, cost="cheap")
def task_actuator_force_max(mech, task=None, **kw) -> float:
    """Largest |actuator force| (N; N m for cranks) balancing the task's wrench at the tool
    point and the payload's weight at the feasible poses, massless legs; with a trajectory
    also the payload's inverse dynamics at every feasible path sample (inf if none)."""
    _one_actuator_unit(mech, "task_actuator_force_max")
    ev = _ev(mech, task, kw)
    v = _max(ev.static_forces, empty=-np.inf)
    if task.trajectory is not None:
        v = max(v, _max(ev.dynamic_forces, empty=-np.inf))
    return v if v > -np.inf else np.inf


@register("task_actuator_speed_max", unit="m/s (rad/s for cranks)", kind="actuator_speed", sense="minimize",
          settings=_BASE, cost="cheap")
def task_actuator_speed_max(mech, task=None, **kw) -> float:
    """Largest |dq_i/dt| along the task's path (m/s for linear actuators, rad/s for cranks)."""
    _one_actuator_unit(mech, "task_actuator_speed_max")
    return _max(_ev(mech, task, kw).actuator_rates)


@register("task_actuator_power_max", unit="W", kind="power", sense="minimize", settings=_BASE, cost="cheap")
def task_actuator_power_max(mech, task=None, **kw) -> float:
    """max_i |F_i| times max_i |dq_i/dt| over the task's path: a bound on one actuator's power
    (W: N times m/s, or N m times rad/s for cranks)."""
    _one_actuator_unit(mech, "task_actuator_power_max")
    ev = _ev(mech, task, kw)
    return _max(ev.dynamic_forces) * _max(ev.actuator_rates)


@register("envelope_clearance", unit="m", kind="length", sense="maximize", settings=_BASE, cost="cheap")
def envelope_clearance(mech, task=None, **kw) -> float:
    """Smallest clearance (m) of every body to the task's installation space at its feasible
    poses and path samples (negative: outside; -inf when nothing is feasible; inf without a
    space)."""
    ev = _ev(mech, task, kw)
    if task.space is None:
        return np.inf
    return _min(ev.clearance, empty=-np.inf)


@register("installed_height", unit="m", kind="length", sense="minimize", settings=_BASE, cost="cheap")
def installed_height(mech, task=None, **kw) -> float:
    """Extent (m) along the task frame's z of the base anchors, the legs' joint centres (a
    crank's tip) and the platform joints over the task's feasible poses (inf if none)."""
    ev = _ev(mech, task, kw)
    Y = ev.Xf
    if not len(Y):
        return np.inf
    _, states, _ = mech.leg_states(Y)
    fixed = np.broadcast_to(np.array([np.asarray(leg.base, dtype=float) for leg in mech.legs]),
                            (len(Y), len(mech.legs), 3))
    pts = np.concatenate([fixed, np.stack([st.base_point for st in states], 1),
                          np.stack([st.platform_point for st in states], 1)], axis=1)
    z = ((pts - task.placement.p) @ task.placement.R)[..., 2]
    return float(np.nanmax(z) - np.nanmin(z))


@register("total_stroke", unit="m", kind="length", sense="minimize", settings=_BASE, cost="cheap")
def total_stroke(mech, task=None, **kw) -> float:
    """Sum over the actuators of the range (max - min) of each actuator value over the task's
    feasible poses and path samples (m; rad for cranks, added as they are)."""
    ev = _ev(mech, task, kw)
    Y = ev.Xf
    if task.trajectory is not None:
        Y = np.concatenate([Y, ev.path.X[ev.path_feasible]])
    if not len(Y):
        return np.inf
    q = mech.inverse_kinematics(Y).actuators
    return float(np.sum(np.nanmax(q, axis=0) - np.nanmin(q, axis=0)))


@register("moving_mass", unit="kg", kind="mass", sense="minimize", cost="cheap",
          settings={**_BASE, "density": Setting("float", default=7850.0, low=0.0, doc="density (kg/m^3)"),
                    "leg_diameter": Setting("length", doc="leg rod diameter (default the task's or the model's)"),
                    "platform_thickness": Setting("length", default=0.02, doc="platform disc thickness")})
def moving_mass(mech, task=None, density: float = 7850.0, leg_diameter=None, platform_thickness: float = 0.02,
                **kw) -> float:
    """Mass (kg) of the moving parts: every leg a solid rod of ``leg_diameter`` (telescopic
    legs at their longest length over the task's feasible poses; PUS legs their link; RUS legs
    crank and link) and the platform a solid disc through its farthest anchor, of
    ``platform_thickness``, all of ``density`` (default steel, 7850 kg/m^3). The payload is not
    included."""
    ev = _ev(mech, task, kw)
    d = task._leg_diameter(mech) if leg_diameter is None else float(leg_diameter)
    Y = ev.Xf if len(ev.Xf) else mech.home[None, :]
    _, states, _ = mech.leg_states(Y)
    length = 0.0
    for leg, st in zip(mech.legs, states):
        if isinstance(leg, RUS):
            length += float(leg.crank_length) + float(leg.link_length)
        elif isinstance(leg, PUS):
            length += float(leg.link_length)
        else:
            length += float(np.nanmax(st.length))
    rod = density * np.pi * d * d / 4.0 * length
    anchors = np.array([np.asarray(leg.platform, dtype=float) for leg in mech.legs])
    rad = float(np.max(np.linalg.norm(anchors[:, :2], axis=1)))
    disc = density * np.pi * rad * rad * float(platform_thickness)
    return float(rod + disc)


@register("task_path_followed", unit="1", sense="maximize", cost="expensive",
          settings={**_BASE, "floor": Setting("float", default=1e-3, low=0.0, high=1.0,
                                              doc="singularity-margin floor where no sign rule applies")})
def task_path_followed(mech, task=None, floor: float = 1e-3, **kw) -> float:
    """Share of the path (of its samples; of the required poses in their order without a
    trajectory) that the robot follows before the first sample breaking continuity
    (infeasible, a floor, a singularity crossed, a change of assembly mode): 1 when it follows
    all of it (:func:`path_continuity`)."""
    ev = _ev(mech, task, kw)
    c = ev.continuity(floor=floor)
    n = len(ev.path.X) if task.trajectory is not None else len(ev.X)
    return 1.0 if c.first_break is None else c.first_break / n


# -- the trajectory measures: a task's path, or the grinding path of the 2022 paper ----------------
_GRINDING = ("dt", "grinding_force", "load_point")
_TRAJECTORY_SETTINGS = {
    **_BASE,
    "dt": Setting("float", low=1e-9, doc="time step of the grinding path (s; without a task, default 0.25)"),
    "grinding_force": Setting("force", doc="grinding force along Z (without a task, default 50 N)"),
    "load_point": Setting("str", choices=("grinding_point", "centre"),
                          doc="where the grinding force acts (without a task, default grinding_point)"),
}


def _grinding_settings(name, mech, task, dt, grinding_force, load_point) -> dict:
    """The settings of the built-in grinding path (without a task), or a one-line error."""
    given = [k for k, v in zip(_GRINDING, (dt, grinding_force, load_point)) if v is not None]
    if task is not None:
        if given:
            raise TaskError(f"{name}: {', '.join(given)} set(s) the built-in grinding path; with a task its "
                            "trajectory and loads give the motion and the force (leave them out)")
        return {}
    if mech.name not in get_measure(name).without_task:
        raise TaskError(f"task: {name} needs a task with a trajectory on {mech.name!r} (without one it follows "
                        f"the 2022 paper's grinding path, on {', '.join(get_measure(name).without_task)} only)")
    return {"dt": 0.25 if dt is None else float(dt),
            "grinding_force": 50.0 if grinding_force is None else float(grinding_force),
            "load_point": "grinding_point" if load_point is None else load_point}


def _wrench_force_norm(task) -> float:
    w = np.atleast_2d(task.wrench)
    f = float(np.max(np.linalg.norm(w[:, :3], axis=1)))
    if not f > 0:
        raise TaskError(f"{task.where}.loads.wrench: force_decoupling_ratio needs a wrench with a force (the "
                        "ratio is per newton of it)")
    return f


@register("max_force_trajectory", unit="N (N*m for cranks)", kind="actuator_force", sense="minimize",
          settings=_TRAJECTORY_SETTINGS, without_task=("4ups_1rps",))
def max_force_trajectory(mech, task=None, dt=None, grinding_force=None, load_point=None, **kw) -> float:
    """Largest |actuator force| (N; N m for cranks) along a path. With a ``task`` (any
    mechanism): at every feasible sample of its trajectory, the inverse dynamics of its payload
    (mass and inertia on the platform, massless legs) with its wrench at the tool point and the
    payload's weight (inf when no sample is feasible). Without a task (``4ups_1rps`` only): the
    2022 paper's trajectory, eqs. (66)-(68), with the Table 3 inertias of platform **and legs**,
    gravity and the grinding force (N) along Z at the grinding point (``load_point``) or the
    platform centre; ``dt``, ``grinding_force`` and ``load_point`` belong to that case."""
    _one_actuator_unit(mech, "max_force_trajectory")
    g = _grinding_settings("max_force_trajectory", mech, task, dt, grinding_force, load_point)
    if task is None:
        return grinding_max_force(mech, **g)
    return _max(_ev(mech, task, kw).dynamic_forces)


@register("force_decoupling_ratio", unit="1", sense="minimize", settings=_TRAJECTORY_SETTINGS,
          without_task=("4ups_1rps",))
def force_decoupling_ratio(mech, task=None, dt=None, grinding_force=None, load_point=None, **kw) -> float:
    """How much of a process force reaches the actuators: the largest change of an actuator force
    along the path when the wrench is applied, divided by the magnitude of its force (0 = fully
    decoupled). With a ``task`` (any mechanism): its trajectory's feasible samples and its wrench
    (the worst sign combination with ``signs``; a per-pose wrench divided by its largest force);
    by linearity the change is the forces of the wrench alone, whatever the payload. Without a
    task (``4ups_1rps`` only): the 2022 paper's path and grinding force (eqs. (66)-(68), the
    paper's claim: 0)."""
    g = _grinding_settings("force_decoupling_ratio", mech, task, dt, grinding_force, load_point)
    if task is None:
        return grinding_decoupling_ratio(mech, **g)
    ev = _ev(mech, task, kw)
    return _max(ev.wrench_path_forces) / _wrench_force_norm(task)


#: The task measures, in the order of docs/tasks.md.
TASK_MEASURES = ("task_coverage", "task_margin_min", "task_condition_max", "task_lti_min", "task_stiffness_min",
                 "task_position_error_max", "task_actuator_force_max", "task_actuator_speed_max",
                 "task_actuator_power_max", "envelope_clearance", "installed_height", "total_stroke", "moving_mass",
                 "task_path_followed")


def task_measures(mech, task: Task, names=TASK_MEASURES, **settings) -> dict:
    """{name: value} of several task measures on one evaluation; each takes the ``settings``
    it declares (the path measures are skipped without a trajectory, the position error
    without a tolerance)."""
    out = {}
    for n in names:
        if task.trajectory is None and n in ("task_actuator_speed_max", "task_actuator_power_max"):
            continue
        own = {k: v for k, v in settings.items() if k in get_measure(n).params}
        if n == "task_position_error_max" and not any(own.get(k) for k in TOLERANCE_SETTINGS):
            continue  # no tolerance, no error
        out[n] = get_measure(n)(mech, task=task, **own)
    return out
