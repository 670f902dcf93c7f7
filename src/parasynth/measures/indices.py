"""Performance indices and static forces of a mechanism, vectorised over poses.

Every function takes the mechanism first and poses ``X`` of shape (N, n_task) (or one pose of
shape (n_task,)), SI units. Twists are ``(v_P, omega)`` and wrenches ``(f, m_P)`` about the
platform reference point ``P`` in the base frame (see :mod:`parasynth.model.spatial`); the power
of a wrench on a twist is ``w @ t``. Poses the legs cannot reach give NaN in per-pose
results and are counted (never averaged) in summaries.

Contents
--------
* Transmission: :func:`pressure_angle_indices` (the 2018 paper's eq. (36), model
  ``2rpu_2sps`` only); :func:`transmission_indices`, :func:`input_transmission_index`,
  :func:`output_transmission_index`, :func:`local_transmission_index` (Wang, Liu, Wang &
  Gosselin's motion/force transmission indices, generalised to lower-mobility and
  under-actuated mechanisms); :func:`good_transmission_fraction` and
  :func:`good_transmission_volume` over a given set of workspace poses.
* Conditioning: :func:`local_condition_number` of a dimensionally homogeneous Jacobian and
  :func:`global_conditioning_index` (Gosselin & Angeles) with its sampling error.
* Singularity: :func:`singularity_margin_stats`.
* Statics: :func:`static_forces` (actuator forces and constraint reactions for an external
  wrench, least squares with the unbalanced residual when the wrench system cannot balance
  it), :func:`min_max_forces`, :func:`wrench_capability`, and the load helpers
  :func:`gravity_wrench`, :func:`point_force_wrench`, :func:`default_gravity`.

Dimensional homogeneity
-----------------------
Wherever forces and moments (or velocities and angular velocities) are compared, moments are
divided by a characteristic length ``L`` and angular velocities multiplied by it -- by default
``mech.length_scale``. The reciprocal product is unchanged by this scaling
(``f.v + m.omega = f.v + (m/L).(L omega)``), so every reciprocity (null-space) computation is
exact; only least-squares choices (which solution of an indeterminate system, how an
unbalanced residual is measured) depend on ``L``, and each function says where.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field

import numpy as np

from .. import engine as _engine


__all__ = [
    "PressureAngleIndices",
    "pressure_angle_indices",
    "TransmissionIndices",
    "transmission_indices",
    "input_transmission_index",
    "output_transmission_index",
    "local_transmission_index",
    "FractionEstimate",
    "good_transmission_fraction",
    "good_transmission_volume",
    "local_condition_number",
    "GlobalIndex",
    "global_conditioning_index",
    "MarginStats",
    "singularity_margin_stats",
    "StaticForces",
    "static_forces",
    "min_max_forces",
    "wrench_capability",
    "default_gravity",
    "gravity_wrench",
    "point_force_wrench",
    "wrench_system",
    "WrenchSystem",
]

#: Standard gravity (m/s^2).
G0 = 9.80665


# ---------------------------------------------------------------------------------------------
# The wrench system at N poses (built from the legs' public methods)
# ---------------------------------------------------------------------------------------------
@dataclass
class WrenchSystem:
    """Actuation and constraint wrenches at N poses, as the legs define them.

    ``actuation`` (N, n_act, 6): unit force along each actuated leg's transmission line
    (through its platform anchor), in actuator order. ``rate_scale`` (N, n_act): the legs'
    transmission factor, ``actuator_rate = actuation @ twist / rate_scale`` (1 for telescopic
    legs, ``n . e`` for a slider). ``constraint`` (N, n_c, 6): every leg's constraint wrenches
    (unit forces or unit couples). ``anchors`` (N, n_act, 3): platform anchors of the
    actuated legs. ``reachable`` (N,). ``p`` (N, 3), ``R`` (N, 3, 3): platform pose.
    ``states``: per-leg states (all legs). Rows of unreachable poses are NaN.
    """

    X: np.ndarray
    reachable: np.ndarray
    actuation: np.ndarray
    rate_scale: np.ndarray
    constraint: np.ndarray
    anchors: np.ndarray
    p: np.ndarray
    R: np.ndarray
    states: list = field(repr=False)
    single: bool = False

    @property
    def n_act(self) -> int:
        return self.actuation.shape[1]

    def matrix(self) -> np.ndarray:
        """Columns of the equilibrium equations, (N, 6, n_act + n_c): the wrench a unit
        *generalised* actuator force applies (``actuation / rate_scale``), then the unit
        constraint wrenches. ``M @ [F; lambda]`` is the wrench the legs apply on the platform."""
        with np.errstate(divide="ignore", invalid="ignore"):
            A = self.actuation / self.rate_scale[..., None]
        return np.swapaxes(np.concatenate([A, self.constraint], axis=1), 1, 2)


def _as_poses(mech, X) -> tuple[np.ndarray, bool]:
    """Poses as a float array (N, n_task) and whether a single pose (n_task,) was given."""
    return mech._poses(X)


def wrench_system(mech, X) -> WrenchSystem:
    """The actuation and constraint wrenches of ``mech`` at poses ``X`` (see
    :class:`WrenchSystem`). The same rows as ``mech.wrench_matrix`` (which stacks them), plus
    the transmission factors and anchors the indices need."""
    Xa, single = _as_poses(mech, X)
    _, states, p = mech.leg_states(Xa)
    valid = mech.pose_valid(Xa)
    _, R = mech.pose(np.where(valid[:, None], Xa, mech.home))
    reachable = np.logical_and.reduce([st.reachable for st in states])
    A, S, anchors, C = leg_wrench_arrays(mech, states, p, reachable)
    return WrenchSystem(Xa, reachable, A, S, C, anchors, p, R, states, single)


def leg_wrench_arrays(mech, states, p, reachable) -> tuple:
    """The legs' wrenches stacked over the poses from their solved ``states`` and platform
    points ``p`` (N, 3): unit actuation wrenches ``A`` (N, n_act, 6), transmission scales ``S``
    (N, n_act), platform anchors (N, n_act, 3) and constraint wrenches ``C`` (N, k, 6), NaN
    where ``reachable`` (N,) is False."""
    A, S, anchors, C = [], [], [], []
    for leg, st in zip(mech.legs, states):
        if leg.is_actuated:
            w, s = leg.actuation_wrench(st, p)
            A.append(w)
            S.append(np.broadcast_to(s, st.length.shape))
            anchors.append(st.platform_point)
        C.append(leg.constraint_wrenches(st, p))
    N = p.shape[0]
    A = np.stack(A, axis=1) if A else np.zeros((N, 0, 6))
    S = np.stack(S, axis=1).astype(float) if S else np.zeros((N, 0))
    anchors = np.stack(anchors, axis=1) if anchors else np.zeros((N, 0, 3))
    C = np.concatenate(C, axis=1) if C else np.zeros((N, 0, 6))
    bad = ~reachable
    for arr in (A, S, anchors, C):
        arr[bad] = np.nan
    return A, S, anchors, C


def _scale_wrench(W: np.ndarray, L: float) -> np.ndarray:
    W = np.array(W, dtype=float, copy=True)
    W[..., 3:] /= L
    return W


def _null_basis(M: np.ndarray, rtol: float) -> tuple[np.ndarray, np.ndarray]:
    """Batched null space of rows M (N, m, 6): right singular vectors Vt (N, 6, 6) and the
    rank (N,); rows ``Vt[k, rank[k]:]`` span the null space."""
    N, m, _ = M.shape
    if m < 6:
        M = np.concatenate([M, np.zeros((N, 6 - m, 6))], axis=1)
    _, s, Vt = np.linalg.svd(M)
    rank = np.sum(s > rtol * np.maximum(s[:, :1], 1e-300), axis=1)
    return Vt, rank


def _out(a: np.ndarray, single: bool):
    return a[0] if single else a


# ---------------------------------------------------------------------------------------------
# Pressure-angle indices of the 2018 paper (2-RPU&2-SPS)
# ---------------------------------------------------------------------------------------------
@dataclass
class PressureAngleIndices:
    """Eq. (36) of the 2018 paper at N poses: ``lambda1 = cos(alpha)`` (RPU limbs 2 and 4),
    ``lambda2 = cos(beta)`` (SPS limbs 1 and 3); ``alpha``, ``beta`` in rad (acute angles).
    ``definition`` says which angle was used (see :func:`pressure_angle_indices`)."""

    lambda1: np.ndarray
    lambda2: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    definition: str


def pressure_angle_indices(mech, X, definition: str = "paper", engine: str = "compiled") -> PressureAngleIndices:
    """Transmission indices ``lambda1 = cos(alpha)``, ``lambda2 = cos(beta)`` of the 2018 paper
    (Section 7, eq. (36)) for the ``2rpu_2sps`` model.

    The paper defines, for the RPU limbs, the acute angle ``alpha_i`` "between the force
    ``w2`` (``w4``) generated at the same point of the two RPU limbs and the velocity
    ``Q w4`` (``-Q w2``) of point A" -- the pressure angle at the limbs' common point when the
    other limb's actuator is locked -- and then says "``alpha`` is the angle between ``w2``
    and ``w4``", which is what eq. (36) uses; likewise ``beta`` for the SPS limbs ``w1``, ``w3``
    (``w_i`` is the unit vector of limb ``i``, base to platform). The two readings differ: a
    locked RPU limb turns about its base revolute axis, so the common point moves normal to
    that limb in the plane of the RPU limbs and the pressure angle is the complement of the
    angle between the limbs.

    ``definition="paper"`` (default): ``alpha`` = acute angle between the limb lines,
    ``lambda1 = |w2 . w4|``, ``lambda2 = |w1 . w3|``. This is what the paper computed: it
    reproduces every trend it reports for Figures 13-14 (both indices grow with z and with
    theta over 10-50 deg; lambda1 does not depend on psi; lambda2 is largest at psi = 0 and
    falls with |psi|), whereas the pressure-angle reading reverses the z and theta trends.

    ``definition="pressure"``: ``alpha`` = acute angle between the force of one limb and the
    velocity of the common point with the other limb locked (normal to the locked limb),
    ``lambda1 = sqrt(1 - (w2 . w4)^2) = |w2 x w4|``, and likewise for the SPS limbs. (The SPS
    limbs are coplanar exactly when x = z tan(theta), the coupled model; for skew limbs this
    is the sine of the angle between their directions.)

    ``engine="compiled"`` (default) takes the leg directions from the compiled kernels of
    :mod:`parasynth.engine.indices`, ``engine="numpy"`` from the legs' NumPy inverse
    kinematics (the same directions to rounding).

    Raises ``ValueError`` for any model other than ``2rpu_2sps`` or an unknown definition.
    """
    if getattr(mech, "name", None) != "2rpu_2sps":
        raise ValueError(
            f"pressure_angle_indices is defined for the 2rpu_2sps model (2018 paper, eq. (36)); "
            f"got {getattr(mech, 'name', mech)!r}. Use local_transmission_index for any mechanism."
        )
    if definition not in ("paper", "pressure"):
        raise ValueError(f"definition must be 'paper' or 'pressure', got {definition!r}")
    Xa, single = _as_poses(mech, X)
    if _engine.use_compiled(mech, engine, "pressure_angle_indices"):
        dirs, reachable = _engine.leg_directions(mech, Xa)
        w = {leg.name: dirs[:, k] for k, leg in enumerate(mech.legs)}
    else:
        _, states, _ = mech.leg_states(Xa)
        reachable = np.logical_and.reduce([st.reachable for st in states])
        w = {leg.name: st.direction for leg, st in zip(mech.legs, states)}
    c_rpu = np.abs(np.sum(w["L2"] * w["L4"], -1))
    c_sps = np.abs(np.sum(w["L1"] * w["L3"], -1))
    s_rpu = np.linalg.norm(np.cross(w["L2"], w["L4"]), axis=-1)
    s_sps = np.linalg.norm(np.cross(w["L1"], w["L3"]), axis=-1)
    if definition == "paper":
        alpha, beta = np.arctan2(s_rpu, c_rpu), np.arctan2(s_sps, c_sps)
    else:
        alpha, beta = np.arctan2(c_rpu, s_rpu), np.arctan2(c_sps, s_sps)
    alpha = np.where(reachable, alpha, np.nan)
    beta = np.where(reachable, beta, np.nan)
    lam1, lam2 = np.cos(alpha), np.cos(beta)
    return PressureAngleIndices(*(_out(a, single) for a in (lam1, lam2, alpha, beta)), definition)


# ---------------------------------------------------------------------------------------------
# Motion/force transmission (Wang, Liu, Wang & Gosselin 2010)
# ---------------------------------------------------------------------------------------------
@dataclass
class TransmissionIndices:
    """Motion/force transmission indices at N poses.

    ``input`` (N, n_act), ``output`` (N, n_act): per actuated leg; ``lti`` (N,): the local
    transmission index, the smallest of all of them; ``uncontrolled`` (N,) int: the number of
    platform freedoms no actuator drives (0 for a controlled mechanism off singularities);
    ``output_twists`` (N, n_act, 6): the output twist ``(v_P, omega)`` used for each leg,
    scaled so that its transmission wrench does unit power on it. NaN where unreachable."""

    input: np.ndarray
    output: np.ndarray
    lti: np.ndarray
    uncontrolled: np.ndarray
    output_twists: np.ndarray = field(repr=False)


def transmission_indices(mech, X, rtol: float = 1e-9) -> TransmissionIndices:
    """Input, output and local transmission indices (Wang, Liu, Wang & Gosselin, Mech. Mach.
    Theory 45 (2010) 1462-1476), for mechanisms of any mobility.

    For actuated leg ``i`` the transmission wrench ``$_Ti`` is its actuation wrench: the unit
    force along the leg's transmission line through its platform anchor ``A_i`` (the wrench
    reciprocal to all its passive joints; the legs supply it).

    * **Input index** ``|$_Ti . $_Ii| / max``: ``$_Ii`` is the unit twist of the actuated
      prismatic joint (a translation along ``e_i``), so the index is ``|n_i . e_i|``, the
      cosine between the transmitted force and the actuator's motion: 1 for telescopic legs,
      the leg's ``rate_scale`` for a slider (PUS).
    * **Output index** ``|$_Ti . $_Oi| / max``: ``$_Oi`` is the platform twist when every
      other actuator is locked, i.e. reciprocal to every other transmission wrench and every
      constraint wrench. For a force wrench through ``A_i`` the power is ``f_i . v_Ai``
      (``v_Ai`` the velocity of ``A_i`` under ``$_Oi``) and its maximum over the force
      direction is ``|f_i| |v_Ai| = |f_i| sqrt(h_O^2 + r^2)`` (``h_O`` the pitch of ``$_Oi``,
      ``r`` the distance of ``A_i`` from its axis, per unit angular speed) -- the paper's
      normalisation -- so the output index is the cosine of the pressure angle at the anchor,
      ``|f_i . v_Ai| / (|f_i| |v_Ai|)``: frame-invariant, independent of ``L`` and of the
      task parametrisation.
    * ``LTI = min_i min(input_i, output_i)``.

    **Lower mobility and under-actuation.** Constraint wrenches are among the wrenches the
    output twist must be reciprocal to, so a lower-mobility mechanism's output twists stay
    in its twist space. When the actuators and constraints together have rank ``r < 6`` (the
    4-UPS/1-RPS robot: 4 + 1 = 5) locking the other actuators leaves a ``7 - r``-dimensional
    set of twists; it always contains the ``6 - r`` *uncontrolled* twists (reciprocal to every
    actuation and constraint wrench), on which leg ``i`` does no work. We take ``$_Oi`` as the
    twist of that set with the largest output index, i.e. the leg's own driven motion with the
    uncontrolled freedoms chosen to minimise the anchor velocity: the index then measures how
    well leg ``i`` transmits into the freedoms the actuators control, and it reduces to the
    usual definition when ``r = 6``. Closed form: with a basis ``B`` of the set, ``b = B^T $_Ti``
    and ``G = B^T V^T V B`` (``V`` maps a twist to ``v_Ai``), the index is
    ``sqrt(b^T G^+ b)`` (Cauchy-Schwarz). At an exact singularity of a controlled mechanism
    the same rule applies (the set grows), and legs whose wrench depends on the others get 0.

    Ranks use ``rtol`` on singular values of the wrench rows made homogeneous with
    ``mech.length_scale``.
    """
    ws = wrench_system(mech, X)
    L = float(mech.length_scale)
    N, na = ws.actuation.shape[:2]
    ok = ws.reachable & np.all(np.isfinite(ws.actuation), axis=(1, 2)) & np.all(np.isfinite(ws.constraint), axis=(1, 2))
    As = _scale_wrench(np.where(ok[:, None, None], ws.actuation, 0.0), L)
    Cs = _scale_wrench(np.where(ok[:, None, None], ws.constraint, 0.0), L)
    anchors = np.where(ok[:, None, None], ws.anchors, 0.0)
    rel = anchors - ws.p[:, None, :]  # A_i - P
    # Uncontrolled twists (scaled coordinates t_s = (v, L omega)).
    Vt_all, rank_all = _null_basis(np.concatenate([As, Cs], axis=1), rtol)
    n_unc = 6 - rank_all
    out = np.full((N, na), np.nan)
    twists = np.full((N, na, 6), np.nan)
    eye = np.eye(3)
    for i in range(na):
        others = np.concatenate([np.delete(As, i, axis=1), Cs], axis=1)
        Vt, rank = _null_basis(others, rtol)
        # V_s maps a scaled twist to the anchor velocity: v_A = v - (A - P) x omega
        #   = [I, -[r]x / L] t_s.
        r = rel[:, i]
        Vs = np.concatenate([np.broadcast_to(eye, (N, 3, 3)), -_skew(r) / L], axis=2)  # (N,3,6)
        g = As[:, i]  # wrench in scaled coordinates: power = g . t_s
        fnorm = np.linalg.norm(g[:, :3], axis=-1)
        for d in np.unique(6 - rank[ok]):
            idx = np.flatnonzero(ok & (6 - rank == d))
            if d == 0:
                out[idx, i] = 0.0
                continue
            B = np.swapaxes(Vt[idx, 6 - d:, :], 1, 2)  # (G, 6, d)
            b = np.einsum("gkd,gk->gd", B, g[idx])
            VB = Vs[idx] @ B  # (G, 3, d)
            Gm = np.swapaxes(VB, 1, 2) @ VB
            Gp = np.linalg.pinv(Gm, rcond=1e-12, hermitian=True)
            c = np.einsum("gde,ge->gd", Gp, b)
            val = np.einsum("gd,gd->g", b, c)
            out[idx, i] = np.minimum(np.sqrt(np.maximum(val, 0.0)) / np.maximum(fnorm[idx], 1e-300), 1.0)
            t_s = np.einsum("gkd,gd->gk", B, c)
            pw = np.einsum("gk,gk->g", g[idx], t_s)
            t_s = t_s / np.where(np.abs(pw) > 1e-300, pw, 1.0)[:, None]
            t_s[:, 3:] /= L
            twists[idx, i] = t_s
    with np.errstate(invalid="ignore"):
        inp = np.abs(ws.rate_scale)
    inp = np.where(ok[:, None], np.minimum(inp, 1.0), np.nan)
    out = np.where(ok[:, None], out, np.nan)
    lti = np.where(ok, np.min(np.concatenate([inp, out], axis=1), axis=1) if na else np.nan, np.nan)
    n_unc = np.where(ok, n_unc, -1)
    s = ws.single
    return TransmissionIndices(_out(inp, s), _out(out, s), _out(lti, s), _out(n_unc, s), _out(twists, s))


def _skew(v: np.ndarray) -> np.ndarray:
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2)


def input_transmission_index(mech, X) -> np.ndarray:
    """Input transmission index of every actuated leg, (N, n_act): ``|n_i . e_i|`` (see
    :func:`transmission_indices`); 1 for telescopic legs. NaN where unreachable."""
    ws = wrench_system(mech, X)
    v = np.where(ws.reachable[:, None], np.minimum(np.abs(ws.rate_scale), 1.0), np.nan)
    return _out(v, ws.single)


def output_transmission_index(mech, X, rtol: float = 1e-9, engine: str = "compiled") -> np.ndarray:
    """Output transmission index of every actuated leg, (N, n_act) (see
    :func:`transmission_indices`). ``engine`` as in :func:`local_transmission_index`."""
    if _engine.use_compiled(mech, engine, "output_transmission_index"):
        return _engine.transmission(mech, X, rtol)[1]
    return transmission_indices(mech, X, rtol).output


def local_transmission_index(mech, X, rtol: float = 1e-9, engine: str = "compiled") -> np.ndarray:
    """Local transmission index LTI (N,): the smallest input and output transmission index
    over the actuated legs, in [0, 1] (1 = every force transmitted along the motion it
    drives, 0 = a singularity). See :func:`transmission_indices` for the definitions and the
    treatment of lower-mobility and under-actuated mechanisms. NaN where unreachable.

    ``engine="compiled"`` (default): the compiled kernels of :mod:`parasynth.engine.indices`
    (the same definitions, agreeing with the NumPy path to 1e-9; NumPy with the reason logged
    once for a mechanism they do not cover); ``engine="numpy"``: :func:`transmission_indices`."""
    if _engine.use_compiled(mech, engine, "local_transmission_index"):
        return _engine.transmission(mech, X, rtol)[2]
    return transmission_indices(mech, X, rtol).lti


@dataclass
class FractionEstimate:
    """A Monte Carlo fraction ``value`` with its binomial standard error ``stderr`` over
    ``n`` usable samples; ``n_excluded`` samples were unreachable (not counted)."""

    value: float
    stderr: float
    n: int
    n_excluded: int


def good_transmission_fraction(mech, X, threshold: float = 0.7, index=None) -> FractionEstimate:
    """Fraction of the given workspace poses whose transmission index is at least
    ``threshold`` (default 0.7, the usual good-transmission bound, i.e. pressure angles within
    about 45.6 deg), with its binomial standard error.

    ``X`` is a plain array of poses, typically the feasible samples of a workspace; poses the
    legs cannot reach are excluded and counted. ``index`` is a function ``(mech, X) -> (N,)``,
    default :func:`local_transmission_index`.
    """
    if not np.isfinite(threshold):
        raise ValueError(f"threshold must be a finite number, got {threshold!r}")
    Xa, _ = _as_poses(mech, X)
    idx = np.asarray((index or local_transmission_index)(mech, Xa), dtype=float)
    ok = np.isfinite(idx)
    n = int(np.count_nonzero(ok))
    if n == 0:
        return FractionEstimate(float("nan"), float("nan"), 0, int(idx.size))
    p = float(np.mean(idx[ok] >= threshold))
    return FractionEstimate(p, float(np.sqrt(p * (1 - p) / n)), n, int(idx.size - n))


def good_transmission_volume(mech, X, workspace_volume: float, threshold: float = 0.7,
                             workspace_volume_stderr: float = 0.0, index=None) -> tuple[float, float]:
    """Volume of the good-transmission workspace, ``fraction * workspace_volume``, and its
    standard error (independent errors of the fraction and of the volume combined to first
    order). ``X``: poses sampled uniformly in the workspace (whose volume, in the task
    coordinates' units, comes from the workspace analysis)."""
    fr = good_transmission_fraction(mech, X, threshold, index)
    V = float(workspace_volume)
    err = float(np.hypot(fr.stderr * V, fr.value * float(workspace_volume_stderr)))
    return fr.value * V, err


# ---------------------------------------------------------------------------------------------
# Conditioning
# ---------------------------------------------------------------------------------------------
def local_condition_number(mech, X, length: float | None = None, space: str = "task",
                           engine: str = "compiled") -> np.ndarray:
    """Condition number (N,) >= 1 of a dimensionally homogeneous actuator Jacobian.

    ``space="task"`` (default): ``J = mech.jacobian(X)`` (actuator rates per task-coordinate
    rate) with the columns of angular coordinates divided by ``length`` (default
    ``mech.length_scale``), so that every entry is dimensionless:
    ``q' = J_lin x' + (J_ang / L)(L theta')``. Euler-angle rates are not angular velocities, so
    this number depends on the parametrisation away from poses where the rate map is
    orthonormal.

    ``space="twist"``: the actuation rows ``(n_i, (A_i - P) x n_i) / rate_scale`` with moments
    divided by ``L``, restricted to an orthonormal basis (in the scaled metric ``(v, L omega)``)
    of the mechanism's twist space (the twists reciprocal to all its constraint wrenches). This
    one is independent of the task parametrisation.

    For a non-square Jacobian the ratio of the largest to the smallest of its
    ``min(rows, columns)`` singular values is returned. ``inf`` at singularities, NaN where
    unreachable. An isotropic pose gives exactly 1.

    ``engine="compiled"`` (default) evaluates ``space="task"`` with the compiled kernels of
    :mod:`parasynth.engine.indices` (relative agreement 1e-9 with the NumPy path; NumPy with
    the reason logged once where they do not apply, including ``space="twist"``);
    ``engine="numpy"``: the NumPy reference.
    """
    L = float(mech.length_scale if length is None else length)
    if not np.isfinite(L) or L <= 0:
        raise ValueError(f"length must be a positive length in m, got {length!r}")
    if space not in ("task", "twist"):
        raise ValueError(f"space must be 'task' or 'twist', got {space!r}")
    if space == "twist" and engine == "compiled":
        _engine.warn_fallback("local_condition_number", mech, "space='twist' has no compiled form")
        engine = "numpy"
    if _engine.use_compiled(mech, engine, "local_condition_number"):
        return _engine.condition_number(mech, X, L)
    if space == "task":
        Xa, single = _as_poses(mech, X)
        J = np.array(mech.jacobian(Xa), dtype=float, copy=True)
        ang = [k for k, c in enumerate(mech.task_coordinates) if c in mech.angular_coordinates]
        J[:, :, ang] /= L
        kappa = _kappa(J)
    elif space == "twist":
        ws = wrench_system(mech, X)
        single = ws.single
        ok = ws.reachable & np.all(np.isfinite(ws.constraint), axis=(1, 2))
        with np.errstate(divide="ignore", invalid="ignore"):
            A = _scale_wrench(ws.actuation / ws.rate_scale[..., None], L)
        Cs = _scale_wrench(np.where(ok[:, None, None], ws.constraint, 0.0), L)
        Vt, rank = _null_basis(Cs, 1e-9)
        kappa = np.full(A.shape[0], np.nan)
        for d in np.unique(6 - rank[ok]):
            idx = np.flatnonzero(ok & (6 - rank == d))
            B = np.swapaxes(Vt[idx, 6 - d:, :], 1, 2)  # (G, 6, d), orthonormal basis
            kappa[idx] = _kappa(A[idx] @ B)
    else:
        raise ValueError(f"space must be 'task' or 'twist', got {space!r}")
    return _out(kappa, single)


def _kappa(J: np.ndarray) -> np.ndarray:
    """Condition numbers of a stack of matrices (G, m, n) over their min(m, n) singular
    values; inf when singular, NaN when not finite."""
    finite = np.all(np.isfinite(J), axis=(1, 2))
    if J.shape[1] == 0 or J.shape[2] == 0:
        return np.where(finite, np.inf, np.nan)
    s = np.linalg.svd(np.where(finite[:, None, None], J, 0.0), compute_uv=False)
    m = min(J.shape[1], J.shape[2])
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(s[:, m - 1] > 1e-14 * s[:, 0], s[:, 0] / s[:, m - 1], np.inf)
    return np.where(finite, kappa, np.nan)


@dataclass
class GlobalIndex:
    """A workspace average ``value`` of a local index with its Monte Carlo standard error
    ``stderr`` over ``n`` usable poses; ``n_excluded`` poses were unreachable."""

    value: float
    stderr: float
    n: int
    n_excluded: int


def global_conditioning_index(mech, X, length: float | None = None, space: str = "task",
                              engine: str = "compiled") -> GlobalIndex:
    """Global conditioning index (Gosselin & Angeles 1991): the workspace average of the
    inverse condition number, ``GCI = int (1/kappa) dW / int dW``.

    ``X`` are poses sampled uniformly in the workspace (a plain array; sampling is the
    caller's). The Monte Carlo estimate is the sample mean of ``1/kappa`` (0 at
    singularities) and its standard error ``std / sqrt(n)``. Unreachable poses are excluded
    and counted. ``length``, ``space`` and ``engine`` as in :func:`local_condition_number`.
    """
    kappa = np.atleast_1d(local_condition_number(mech, X, length, space, engine))
    ok = ~np.isnan(kappa)
    n = int(np.count_nonzero(ok))
    if n == 0:
        return GlobalIndex(float("nan"), float("nan"), 0, int(kappa.size))
    inv = 1.0 / kappa[ok]
    se = float(np.std(inv, ddof=1) / np.sqrt(n)) if n > 1 else float("nan")
    return GlobalIndex(float(np.mean(inv)), se, n, int(kappa.size - n))


# ---------------------------------------------------------------------------------------------
# Singularity margin
# ---------------------------------------------------------------------------------------------
@dataclass
class MarginStats:
    """Statistics of ``mech.singularity_margin`` over reachable poses: ``min``, ``mean``,
    ``max``, ``percentiles`` {q: value}, ``argmin`` (index into the given poses), ``n`` used,
    ``n_unreachable``."""

    min: float
    mean: float
    max: float
    percentiles: dict
    argmin: int
    n: int
    n_unreachable: int


def singularity_margin_stats(mech, X, percentiles=(1, 5, 25, 50, 75, 95), engine: str = "compiled") -> MarginStats:
    """Summary of the singularity margin (smallest normalised singular value of the wrench
    system, :meth:`Mechanism.singularity_margin`, ``engine`` as there) over the poses ``X``;
    unreachable poses are ignored and counted."""
    m = np.atleast_1d(mech.singularity_margin(np.atleast_2d(np.asarray(X, dtype=float)), engine=engine))
    ok = np.isfinite(m)
    n = int(np.count_nonzero(ok))
    if n == 0:
        nan = float("nan")
        return MarginStats(nan, nan, nan, {q: nan for q in percentiles}, -1, 0, int(m.size))
    v = m[ok]
    pct = {q: float(np.percentile(v, q)) for q in percentiles}
    idx = np.flatnonzero(ok)[int(np.argmin(v))]
    return MarginStats(float(v.min()), float(v.mean()), float(v.max()), pct, int(idx), n, int(m.size - n))


# ---------------------------------------------------------------------------------------------
# Loads
# ---------------------------------------------------------------------------------------------
def default_gravity(mech) -> np.ndarray:
    """Gravity vector (m/s^2, base frame) for a model: ``mech.gravity`` if the model defines
    one; (0, -g, 0) for the grinding robot ``4ups_1rps`` (Y is its vertical: the legs run
    along Y and carry the weight, Section 4 of the 2022 paper); (0, 0, -g) otherwise."""
    g = getattr(mech, "gravity", None)
    if g is not None:
        return np.asarray(g, dtype=float)
    if getattr(mech, "name", None) == "4ups_1rps":
        return np.array([0.0, -G0, 0.0])
    return np.array([0.0, 0.0, -G0])


def point_force_wrench(mech, X, force, point=(0.0, 0.0, 0.0), pose=None) -> np.ndarray:
    """Wrench (N, 6) at ``P`` (base frame) of a force ``force`` (3,) or (N, 3), base frame, N,
    applied at ``point`` given in the platform frame (m). ``pose``: ``mech.pose`` at the poses
    ``X``, where the caller has it (two loads at the same poses pose the platform once)."""
    Xa, single = _as_poses(mech, X)
    _, R = mech.pose(Xa) if pose is None else pose
    f = np.broadcast_to(np.asarray(force, dtype=float), (Xa.shape[0], 3))
    r = R @ np.asarray(point, dtype=float)
    w = np.concatenate([f, np.cross(r, f)], axis=-1)
    return _out(w, single)


def gravity_wrench(mech, X, mass: float, com=(0.0, 0.0, 0.0), g=None, pose=None) -> np.ndarray:
    """Wrench (N, 6) at ``P`` of the weight of a body of ``mass`` (kg) carried by the
    platform, centre of mass ``com`` in the platform frame (m); ``g`` the gravity vector
    (default :func:`default_gravity`); ``pose`` as in :func:`point_force_wrench`."""
    gv = default_gravity(mech) if g is None else np.asarray(g, dtype=float)
    return point_force_wrench(mech, X, float(mass) * gv, com, pose=pose)


# ---------------------------------------------------------------------------------------------
# Static forces
# ---------------------------------------------------------------------------------------------
@dataclass
class StaticForces:
    """Forces balancing a load at N poses.

    ``actuator`` (N, n_act): generalised actuator forces, power-conjugate to the actuator
    coordinates (N for leg lengths and sliders): ``actuator @ q' = power delivered``; positive
    = the actuator pushes the platform away from the base along its coordinate. ``line``
    (N, n_act): the force each actuated leg transmits along its line (equal to ``actuator``
    for telescopic legs, ``actuator / (n.e)`` for a slider). ``constraint`` (N, n_c): the
    intensities of the unit constraint wrenches (N for forces, N m for couples) in the order
    of ``mech.wrench_matrix``'s constraint rows. ``residual`` (N, 6): the net wrench left on
    the platform, ``W^T [line; constraint] + w_load`` -- zero when the load is balanced.
    ``balanced`` (N,) bool. NaN/False where unreachable.
    """

    actuator: np.ndarray
    constraint: np.ndarray
    residual: np.ndarray
    balanced: np.ndarray
    line: np.ndarray


def _load_array(wrench, N: int) -> np.ndarray:
    w = np.asarray(wrench, dtype=float)
    if w.shape == (6,):
        w = np.broadcast_to(w, (N, 6))
    if w.shape != (N, 6):
        raise ValueError(f"wrench must have shape (6,) or ({N}, 6) as (f, m_P) in N and N m; got {np.shape(wrench)}")
    if not np.all(np.isfinite(w)):
        raise ValueError("wrench must be finite")
    return w


#: A square system whose Frobenius condition bound ``|A|_F |A^-1|_F`` (at least the 2-norm
#: condition number) is at most this is solved by its inverse in :func:`_lstsq_balance`: every
#: singular value is then above ``rtol`` (1e-10) of the largest, so the SVD's minimum-norm
#: solution is that unique solution.
_DIRECT_COND = 1e9


def _lstsq_balance(ws: WrenchSystem, w: np.ndarray, L: float, rtol: float = 1e-10, btol: float = 1e-8):
    """Least-squares [F; lambda] with M x + w ~ 0, M = ws.matrix(); rows scaled (moments / L)
    and columns normalised; minimum norm in the normalised unknowns (singular values below
    ``rtol`` of the largest dropped). A square system (as many actuators and constraint
    wrenches as six) that is well conditioned (:data:`_DIRECT_COND`) is solved by its inverse,
    the others by the SVD: the same solution to rounding, a fifth of the time."""
    M = ws.matrix()
    N, _, k = M.shape
    ok = ws.reachable & np.all(np.isfinite(M), axis=(1, 2))
    Ms = _scale_wrench(np.swapaxes(np.where(ok[:, None, None], M, 0.0), 1, 2), L)  # (N, k, 6) rows
    Ms = np.swapaxes(Ms, 1, 2)  # (N, 6, k)
    bs = -_scale_wrench(w, L)
    cn = np.linalg.norm(Ms, axis=1)  # (N, k)
    cn = np.where(cn > 0, cn, 1.0)
    Mn = Ms / cn[:, None, :]
    y = np.empty((N, k))
    svd = np.ones(N, dtype=bool)
    if k == 6 and N:
        Mi = np.where(ok[:, None, None], Mn, np.eye(6))  # the unreachable rows stay NaN below
        try:
            inv = np.linalg.inv(Mi)
        except np.linalg.LinAlgError:  # an exactly singular system among them: all by the SVD
            inv = None
        if inv is not None:
            with np.errstate(invalid="ignore", over="ignore"):
                bound = np.linalg.norm(Mi, axis=(1, 2)) * np.linalg.norm(inv, axis=(1, 2))
            direct = np.isfinite(bound) & (bound <= _DIRECT_COND)
            y[direct] = np.einsum("nij,nj->ni", inv[direct], bs[direct])
            svd = ~direct
    if svd.any():
        U, s, Vt = np.linalg.svd(Mn[svd], full_matrices=False)
        keep = s > rtol * np.maximum(s[:, :1], 1e-300)
        sinv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
        y[svd] = np.einsum("nkj,nk,nik,ni->nj", Vt, sinv, U, bs[svd])
    x = y / cn
    res_s = np.einsum("nik,nk->ni", Ms, x) - bs  # scaled net wrench
    scale = np.linalg.norm(bs, axis=1) + np.linalg.norm(Ms * np.abs(x)[:, None, :], axis=(1, 2))
    balanced = ok & (np.linalg.norm(res_s, axis=1) <= btol * np.maximum(scale, 1e-300))
    res = res_s.copy()
    res[:, 3:] *= L
    x[~ok] = np.nan
    res[~ok] = np.nan
    return x, res, balanced, ok


def _pack(ws: WrenchSystem, x, res, balanced) -> StaticForces:
    na = ws.n_act
    F = x[:, :na]
    with np.errstate(divide="ignore", invalid="ignore"):
        line = F / ws.rate_scale
    s = ws.single
    return StaticForces(_out(F, s), _out(x[:, na:], s), _out(res, s), _out(balanced, s), _out(line, s))


def static_forces(mech, X, wrench, length: float | None = None) -> StaticForces:
    """Actuator forces and constraint reactions that hold the platform against an external
    wrench, with massless legs.

    ``wrench``: the external load on the platform, ``(f, m_P)`` about ``P`` in the base frame
    (N and N m), shape (6,) or (N, 6) -- e.g. ``gravity_wrench(mech, X, m, com)`` or
    ``point_force_wrench``. Equilibrium of the platform::

        sum_i F_i a_i / s_i + sum_j lambda_j c_j + w_load = 0,   i.e.  W^T [line; lambda] = -w_load

    with ``a_i`` the unit actuation wrenches and ``c_j`` the unit constraint wrenches (the rows
    ``W`` of ``mech.wrench_matrix``), ``s_i`` the legs' transmission factors and
    ``F_i = s_i line_i`` the generalised actuator forces.

    Solved in the least-squares sense with moments divided by ``length`` (default
    ``mech.length_scale``) and unknowns normalised to unit columns: exact when the system
    balances the load; when constraint reactions are statically indeterminate (e.g. the two
    RPU legs' parallel constraint forces of ``2rpu_2sps``) the minimum-norm split is
    returned; when the load has a component the wrench system cannot produce (the
    under-actuated ``4ups_1rps`` for a load doing work on its uncontrolled freedom) the
    least-squares forces are returned with the unbalanced ``residual`` and ``balanced=False``.
    """
    ws = wrench_system(mech, X)
    L = float(mech.length_scale if length is None else length)
    w = _load_array(wrench, ws.X.shape[0])
    x, res, bal, _ = _lstsq_balance(ws, w, L)
    return _pack(ws, x, res, bal)


def _limits(force_limits, na: int) -> np.ndarray:
    lim = np.broadcast_to(np.asarray(force_limits, dtype=float), (na,)).copy()
    if not np.all(np.isfinite(lim)) or np.any(lim <= 0):
        raise ValueError(f"force_limits must be positive finite forces (N), one or {na}; got {force_limits!r}")
    return lim


def min_max_forces(mech, X, wrench, weights=None, length: float | None = None) -> StaticForces:
    """The actuator force distribution that balances a load with the smallest largest
    actuator force, ``minimise max_i |F_i| / weight_i`` subject to equilibrium (a linear
    programme per pose, cvxpy).

    Useful where actuation is redundant (more actuators than freedoms) or constraint
    reactions are indeterminate; for a determinate system it returns the unique solution.
    Equilibrium is imposed on the part of the load the wrench system can balance: the
    unbalanced least-squares residual of :func:`static_forces` is kept (and reported), so an
    under-actuated model still gets the best distribution for the balanceable part.
    ``weights`` (n_act,) default 1 (e.g. the actuators' force ratings).
    """
    import cvxpy as cp  # lazy: cvxpy takes seconds to import; only the LP/QP force measures need it

    ws = wrench_system(mech, X)
    L = float(mech.length_scale if length is None else length)
    N = ws.X.shape[0]
    w = _load_array(wrench, N)
    x_ls, res, bal, ok = _lstsq_balance(ws, w, L)
    na = ws.n_act
    wt = np.ones(na) if weights is None else _limits(weights, na)
    M = ws.matrix()
    k = M.shape[2]
    Mp = cp.Parameter((6, k))
    bp = cp.Parameter(6)
    tolp = cp.Parameter(nonneg=True)
    x = cp.Variable(k)
    t = cp.Variable()
    cons = [cp.abs(Mp @ x - bp) <= tolp, cp.abs(cp.multiply(1.0 / wt, x[:na])) <= t]
    prob = cp.Problem(cp.Minimize(t), cons)
    solver = _lp_solver()
    out = np.full((N, k), np.nan)
    for n in range(N):
        if not ok[n]:
            continue
        Ms = M[n].copy()
        Ms[3:] /= L
        target = Ms @ x_ls[n]  # the balanceable part, exactly as least squares found it
        Mp.value, bp.value = Ms, target
        tolp.value = 1e-9 * max(1.0, float(np.max(np.abs(target))))
        status = _solve(prob, solver)
        if status in ("optimal", "optimal_inaccurate") and x.value is not None:
            out[n] = x.value
        else:  # fall back on the least-squares solution
            out[n] = x_ls[n]
    return _pack(ws, out, res, bal)


def wrench_capability(mech, X, directions, force_limits, gravity_wrench=None,
                      length: float | None = None, cap: float = 1e9) -> np.ndarray:
    """Largest load along each direction the actuators can hold within their force limits.

    For each pose and each direction ``d`` (rows of ``directions``: wrenches (6,) as
    ``(f, m_P)`` about ``P``, or forces (3,) through ``P``; not normalised) returns the largest
    scalar ``s`` such that the load ``s d + w_g`` (``w_g`` = ``gravity_wrench``, (6,) or (N, 6),
    default none) is balanced by ``|F_i| <= force_limits_i`` (generalised actuator forces, N)
    and arbitrary constraint reactions (the joints are assumed strong enough). A linear
    programme per pose solved with cvxpy (one parametrised problem reused for all poses; all
    directions of a pose in one solve, since they are independent).

    Returns (N, n_dir). ``inf`` where the constraints alone take the direction (e.g. a force
    along Z through the centre of the grinding robot); NaN where no ``s`` balances the load
    (e.g. gravity exceeds the limits, or an under-actuated model cannot balance it at all); a
    negative value means the weight must be relieved by pulling against ``d``. Equilibrium is
    imposed to 1e-9 of the force limits (moments divided by ``length``, default
    ``mech.length_scale``), so a direction the wrench system cannot produce gets (about) 0.
    """
    import cvxpy as cp  # lazy: cvxpy takes seconds to import; only the LP/QP force measures need it

    ws = wrench_system(mech, X)
    L = float(mech.length_scale if length is None else length)
    N = ws.X.shape[0]
    na = ws.n_act
    lim = _limits(force_limits, na)
    D = np.atleast_2d(np.asarray(directions, dtype=float))
    if D.shape[1] == 3:
        D = np.concatenate([D, np.zeros_like(D)], axis=1)
    if D.ndim != 2 or D.shape[1] != 6 or not np.all(np.isfinite(D)):
        raise ValueError("directions must be finite rows of 6 (wrench) or 3 (force through P); "
                         f"got shape {np.shape(directions)}")
    nd = D.shape[0]
    Wg = np.zeros((N, 6)) if gravity_wrench is None else _load_array(gravity_wrench, N)
    Ds = _scale_wrench(D, L).T  # (6, nd)
    M = ws.matrix()
    k = M.shape[2]
    Mp = cp.Parameter((6, k))
    Dp = cp.Parameter((6, nd))
    Gp = cp.Parameter((6, nd))
    tol = 1e-9 * float(np.max(lim))
    xv = cp.Variable((k, nd))
    sv = cp.Variable(nd)
    lim_col = lim[:, None]
    cons = [cp.abs(Mp @ xv + Dp @ cp.diag(sv) + Gp) <= tol,
            cp.abs(xv[:na, :]) <= np.repeat(lim_col, nd, axis=1),
            sv <= cap]
    prob = cp.Problem(cp.Maximize(cp.sum(sv)), cons)
    single_x = cp.Variable(k)
    single_s = cp.Variable()
    Mp1, dp1, gp1 = cp.Parameter((6, k)), cp.Parameter(6), cp.Parameter(6)
    prob1 = cp.Problem(cp.Maximize(single_s), [cp.abs(Mp1 @ single_x + single_s * dp1 + gp1) <= tol,
                                               cp.abs(single_x[:na]) <= lim, single_s <= cap])
    solver = _lp_solver()
    out = np.full((N, nd), np.nan)
    for n in range(N):
        if not (ws.reachable[n] and np.all(np.isfinite(M[n]))):
            continue
        Ms = M[n].copy()
        Ms[3:] /= L
        g = Wg[n].copy()
        g[3:] /= L
        Mp.value, Dp.value, Gp.value = Ms, Ds, np.repeat(g[:, None], nd, axis=1)
        status = _solve(prob, solver)
        if status in ("optimal", "optimal_inaccurate"):
            out[n] = sv.value
            continue
        for j in range(nd):  # one direction may be infeasible: solve them one by one
            Mp1.value, dp1.value, gp1.value = Ms, Ds[:, j], g
            if _solve(prob1, solver) in ("optimal", "optimal_inaccurate"):
                out[n, j] = float(single_s.value)
    out = np.where(out >= cap * (1 - 1e-6), np.inf, out)
    return _out(out, ws.single)


_HIGHS_BANNER_DONE = False


def _solve(prob, kw) -> str:
    """Solve a cvxpy problem; returns its status ("solver_error" if the solver raised).

    HiGHS prints a banner on the process's standard output (at C level) the first time it
    runs; that first solve runs with file descriptor 1 pointed at the null device."""
    import cvxpy as cp  # lazy: as in min_max_forces

    global _HIGHS_BANNER_DONE
    quiet = kw.get("solver") == cp.HIGHS and not _HIGHS_BANNER_DONE
    opts = dict(kw)
    if opts.get("solver") == cp.HIGHS:
        opts["output_flag"] = False
    try:
        if quiet:
            _HIGHS_BANNER_DONE = True
            with _stdout_to_devnull():
                prob.solve(**opts)
        else:
            prob.solve(**opts)
    except cp.SolverError:
        return "solver_error"
    return prob.status


class _stdout_to_devnull:
    """Point file descriptor 1 at os.devnull for the duration (C-level output)."""

    def __enter__(self):
        self._saved = None
        try:
            sys.stdout.flush()
            self._saved = os.dup(1)
            self._null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(self._null, 1)
        except (OSError, ValueError, AttributeError):  # no real fd 1: leave it alone
            self._saved = None
        return self

    def __exit__(self, *exc):
        if self._saved is not None:
            os.dup2(self._saved, 1)
            os.close(self._saved)
            os.close(self._null)
        return False


def _lp_solver():
    import cvxpy as cp  # lazy: as in min_max_forces

    return {"solver": cp.HIGHS} if "HIGHS" in cp.installed_solvers() else {}
