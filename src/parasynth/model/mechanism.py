"""The generic parallel mechanism: a base, a platform and legs.

Everything here is derived from the legs: inverse kinematics is each leg's own, the
actuator-rate Jacobian stacks the legs' actuation rows, the wrench system stacks actuation and
constraint wrenches (the 2018 paper's overall Jacobian J0), the singularity margin is its
smallest normalised singular value, forward kinematics is a damped Newton solve of the
inverse kinematics, and mobility is the screw-theory rank of the legs' constraint wrenches.

A concrete model supplies only its legs and its task-space parametrisation:

* ``pose(X) -> (p, R)``: platform reference point (N, 3) and orientation (N, 3, 3) for task
  coordinates ``X`` (N, n_task), including any dependent coordinates;
* ``twist_map(X)``: the matrix (N, 6, n_task) mapping task-coordinate rates to the platform
  twist ``(v_P, omega)``.

This is the NumPy model: it never imports the compiled engine. The methods that have a compiled
path (``is_feasible``, ``constraint_margins``, ``singularity_margin``,
``structural_constraint_rank``) take ``engine="compiled"`` (default) or ``"numpy"``; here they
are the NumPy reference, and "compiled" on a model class written in Python runs them on NumPy
with one :class:`EngineFallbackWarning` per class. Described mechanisms
(:class:`~parasynth.mechanisms.description.DescribedMechanism`) override them to run on
:mod:`parasynth.engine`.
"""

from __future__ import annotations

import copy
import dataclasses
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .constraints import Constraint, PoseContext, feasible_rows
from .legs import JOINT_DOF, Leg, LegState, solve_geometry
from .spatial import reciprocal_basis
from ..common.validation import check_engine, check_names, check_pose_array, is_real_number, mask_huge_poses

__all__ = ["Mechanism", "IKResult", "Mobility", "ForwardKinematicsError", "EngineFallbackWarning"]


class EngineFallbackWarning(UserWarning):
    """The compiled engine does not cover a mechanism; NumPy evaluates it (the message says why).
    Also :class:`parasynth.engine.EngineFallbackWarning`."""


class ForwardKinematicsError(RuntimeError):
    """Forward kinematics failed: no convergence, inconsistent actuator values, or actuators
    that do not determine the pose. ``indices`` lists the failing samples."""

    def __init__(self, message: str, indices=None, residual=None):
        super().__init__(message)
        self.indices = np.asarray(indices if indices is not None else [], dtype=int)
        self.residual = residual


@dataclass
class IKResult:
    """Inverse kinematics of N poses.

    ``actuators`` (N, n_act): leg lengths (m) for UPS/SPS/RPU/RPS legs, slider positions (m)
    for PUS and PRS legs, crank angles (rad) for RUS legs, NaN where the pose is not
    reachable; ``reachable`` (N,) bool;
    ``passive_angles``: {"<leg>.<joint angle>": (N,) rad}; ``legs``: the per-leg states
    (joint centres, leg directions, lengths). For a single pose given as shape (n,), arrays
    lose their leading axis.
    """

    actuators: np.ndarray
    reachable: np.ndarray
    passive_angles: dict[str, np.ndarray]
    legs: list[LegState] = field(repr=False)
    actuator_names: tuple[str, ...] = ()

    @property
    def n_reachable(self) -> int:
        return int(np.count_nonzero(self.reachable))


@dataclass(frozen=True)
class Mobility:
    """Mobility of a mechanism at a pose.

    ``dof``: freedoms of the platform from screw theory (6 - rank of the legs' constraint
    wrenches); ``type``: e.g. "2T2R" (translational and rotational dimensions of the twist
    space); ``n_actuators``; ``controlled``: do the actuators determine every freedom (the
    actuation and constraint wrenches together have rank 6)?; ``gruebler``: the plain
    Grübler-Kutzbach count 6(n - g - 1) + sum f_i; ``gruebler_corrected``: the same plus
    redundant constraints minus local freedoms (the 2018 paper's eq. (2));
    ``constraint_rank``; ``redundant_constraints``; ``local_dof``; ``twist_basis`` (dof, 6):
    the platform's instantaneous freedoms; ``uncontrolled_twists`` (k, 6): freedoms the
    actuators do not see at the analysed pose (empty when controlled there);
    ``singular_at_pose``: the analysed pose is a singularity although the actuators control
    every freedom at generic poses nearby (``controlled`` always describes the generic case,
    whether or not a pose is given).
    """

    dof: int
    type: str
    n_actuators: int
    controlled: bool
    gruebler: int
    gruebler_corrected: int
    constraint_rank: int
    redundant_constraints: int
    local_dof: int
    n_links: int
    n_joints: int
    sum_joint_dof: int
    twist_basis: np.ndarray = field(repr=False)
    uncontrolled_twists: np.ndarray = field(repr=False)
    singular_at_pose: bool = False

    def summary(self) -> str:
        ctrl = "yes" if self.controlled else f"no ({len(self.uncontrolled_twists)} uncontrolled freedom(s))"
        if self.singular_at_pose:
            ctrl += f" (but singular at this pose: {len(self.uncontrolled_twists)} freedom(s) uncontrolled here)"
        return (
            f"screw theory: {self.dof} DOF ({self.type}), constraint rank {self.constraint_rank}; "
            f"Grübler-Kutzbach: 6({self.n_links}-{self.n_joints}-1)+{self.sum_joint_dof} = {self.gruebler}"
            f" (+{self.redundant_constraints} redundant -{self.local_dof} local = {self.gruebler_corrected}); "
            f"{self.n_actuators} actuators, controlled: {ctrl}"
        )


_FALLBACK_WARNED: set = set()


def _numpy_only(mech, engine) -> None:
    """Validate ``engine`` ("compiled" or "numpy"; ``ValueError`` otherwise) for a method of a
    model class without a compiled path: "compiled" says once per class, as an
    :class:`EngineFallbackWarning`, that NumPy evaluates it."""
    if check_engine(engine) == "numpy" or type(mech) in _FALLBACK_WARNED:
        return
    _FALLBACK_WARNED.add(type(mech))
    msg = (f"{getattr(mech, 'name', type(mech).__name__)}: the compiled engine does not cover the model class "
           f"{type(mech).__name__} (not a mechanism description); evaluated with NumPy")
    warnings.warn(msg, EngineFallbackWarning, stacklevel=3)


def _rank(A: np.ndarray, rtol: float = 1e-8) -> int:
    if A.size == 0:
        return 0
    s = np.linalg.svd(A, compute_uv=False)
    return int(np.sum(s > rtol * max(s[0], 1e-300)))


class Mechanism:
    """A parallel mechanism built from legs. Subclasses define ``pose`` and ``twist_map``.

    Attributes
    ----------
    name: registry name of the model.
    params: the frozen parameter dataclass (SI units).
    task_coordinates: names of the independent pose coordinates (papers' symbols).
    actuators: names of the actuated joint variables.
    home: a reachable reference pose (task coordinates, SI).
    legs: the legs, base to platform.
    length_scale: characteristic length (m) used to make wrenches dimensionally
        homogeneous (moments divided by it) in margins and conditioning.
    """

    name: str = "mechanism"
    task_coordinates: tuple[str, ...] = ()
    angular_coordinates: frozenset[str] = frozenset()

    def __init__(self, params: Any, legs: list[Leg], home, length_scale: float):
        self.params = params
        self.home = np.asarray(home, dtype=float)
        self.length_scale = float(length_scale)
        self.legs = tuple(self._neutral_refs(legs))
        prefix = {"length": "q", "slider": "s", "angle": "t"}
        self.actuators = tuple(f"{prefix.get(leg.actuator_kind, 's')}{i + 1}"
                               for i, leg in enumerate(self.legs) if leg.is_actuated)
        #: {actuator name: "length" | "slider" | "angle"} (angles in rad, the others in m).
        self.actuator_kinds = dict(zip(self.actuators, (leg.actuator_kind for leg in self.legs if leg.is_actuated)))
        self._constraint_rank: int | None = None

    # -- parametrisation (subclass) -------------------------------------------------------------
    def default_ranges(self) -> dict:
        """A task box {coordinate: (lo, hi)} (SI) that contains the model's workspace; used
        when an analysis is not given explicit ranges."""
        return {}

    def _pose(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
        raise NotImplementedError

    def _twist_map(self, X: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def pose(self, X) -> tuple[np.ndarray, np.ndarray]:
        """Platform reference point (N, 3) and orientation (N, 3, 3) in the base frame for task
        coordinates ``X`` (N, n_task) or (n_task,), including dependent coordinates."""
        Xa, single = self._poses(X)
        p, R = self._pose(Xa)
        return (p[0], R[0]) if single else (p, R)

    def twist_map(self, X) -> np.ndarray:
        """Matrix (N, 6, n_task) mapping task-coordinate rates to the platform twist
        ``(v_P, omega)`` in the base frame."""
        Xa, single = self._poses(X)
        T = self._twist_map(Xa)
        return T[0] if single else T

    def pose_valid(self, X: np.ndarray) -> np.ndarray:
        """Poses at which the parametrisation itself is defined (e.g. tan(theta) finite)."""
        return np.all(np.isfinite(X), axis=-1)

    # -- helpers ---------------------------------------------------------------------------------
    @property
    def n_task(self) -> int:
        return len(self.task_coordinates)

    @property
    def n_actuators(self) -> int:
        return len(self.actuators)

    @property
    def actuated_legs(self) -> tuple[Leg, ...]:
        return tuple(leg for leg in self.legs if leg.is_actuated)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} task={self.task_coordinates} actuators={self.actuators}>"

    def _poses(self, X) -> tuple[np.ndarray, bool]:
        # Real numbers only (strings, booleans, complex refused); lengths beyond 1e6 m masked as NaN.
        X0 = check_pose_array(f"{self.name}: poses", X)
        X0 = mask_huge_poses(X0, [c not in self.angular_coordinates for c in self.task_coordinates])
        single = X0.ndim == 1
        X = X0[None, :] if single else X0
        if X.ndim != 2 or X.shape[1] != self.n_task:
            raise ValueError(
                f"{self.name}: poses must have shape (N, {self.n_task}) or ({self.n_task},) "
                f"with columns {self.task_coordinates}; got shape {X0.shape}"
            )
        return X, single

    def _neutral_refs(self, legs: list[Leg]) -> list[Leg]:
        """Set each leg's neutral joint directions to its direction at the home pose."""
        p, R = self._pose(self.home[None, :])
        out = []
        for leg in legs:
            st = solve_geometry(leg, p, R)
            n = st.direction[0]
            if not np.all(np.isfinite(n)) or not np.any(n):
                raise ValueError(f"{self.name}: home pose {self.home.tolist()} is not reachable by leg {leg.name}")
            out.append(leg.with_neutral(n, R[0].T @ (-n)))
        return out

    def leg_states(self, X) -> tuple[np.ndarray, list[LegState], np.ndarray]:
        """Task poses (N, n), per-leg states and the platform reference points (N, 3)."""
        Xa, _ = self._poses(X)
        valid = self.pose_valid(Xa)
        Xs = np.where(valid[:, None], Xa, self.home)
        p, R = self._pose(Xs)
        states = [leg.solve(p, R) for leg in self.legs]
        for st in states:
            st.reachable = st.reachable & valid
        return Xa, states, p

    # -- kinematics ------------------------------------------------------------------------------
    def inverse_kinematics(self, X) -> IKResult:
        """Actuator values, reachability and passive joint angles for poses ``X``.

        ``X`` has shape (N, n_task) (or (n_task,) for one pose), columns
        ``task_coordinates``, SI units. Unreachable poses (including NaN coordinates) are
        masked in ``.reachable`` and their actuator values are NaN.
        """
        Xa, single = self._poses(X)
        _, states, _ = self.leg_states(Xa)
        reachable = np.logical_and.reduce([st.reachable for st in states])
        act = np.stack([st.actuator for leg, st in zip(self.legs, states) if leg.is_actuated], axis=-1)
        act = np.where(reachable[:, None], act, np.nan)
        passive = {}
        for leg, st in zip(self.legs, states):
            for k, v in st.angles.items():
                passive[f"{leg.name}.{k}"] = np.where(reachable, v, np.nan)
        if single:
            act, reachable = act[0], reachable[0]
            passive = {k: v[0] for k, v in passive.items()}
        return IKResult(act, reachable, passive, states, self.actuators)

    def _actuation_rows(self, states, p) -> tuple[np.ndarray, np.ndarray]:
        rows, scales = [], []
        for leg, st in zip(self.legs, states):
            if leg.is_actuated:
                w, s = leg.actuation_wrench(st, p)
                rows.append(w)
                scales.append(s)
        return np.stack(rows, axis=1), np.stack(scales, axis=1)

    def jacobian(self, X) -> np.ndarray:
        """Actuator-rate Jacobian d(actuators)/d(task coordinates), shape (N, n_act, n_task).

        Built from the legs: each actuator rate is the power of its leg's unit actuation
        wrench on the platform twist, divided by the leg's transmission scale (1 for
        telescopic legs, n.e for a slider); the twist follows from ``twist_map``. Rows of
        unreachable poses are NaN."""
        Xa, single = self._poses(X)
        _, states, p = self.leg_states(Xa)
        reachable = np.logical_and.reduce([st.reachable for st in states])
        W, scale = self._actuation_rows(states, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            rows = W / scale[..., None]
        J = rows @ self._twist_map(np.where(reachable[:, None], Xa, self.home))
        J[~reachable] = np.nan
        return J[0] if single else J

    def wrench_matrix(self, X) -> np.ndarray:
        """The overall wrench system at each pose, shape (N, k, 6).

        Rows: first the unit actuation wrench of every actuated leg (in actuator order),
        then the constraint wrenches of every leg (unit forces or unit couples), each as
        (f, m_P) about the platform reference point in the base frame. This is the 2018
        paper's J0 = [J_a; J_c] written as wrenches. Rows of unreachable poses are NaN."""
        Xa, single = self._poses(X)
        _, states, p = self.leg_states(Xa)
        reachable = np.logical_and.reduce([st.reachable for st in states])
        W = self._wrench_of_states(states, p, reachable)
        return W[0] if single else W

    def _wrench_of_states(self, states, p, reachable) -> np.ndarray:
        A, _ = self._actuation_rows(states, p)
        C = [leg.constraint_wrenches(st, p) for leg, st in zip(self.legs, states)]
        W = np.concatenate([A] + C, axis=1)
        W[~reachable] = np.nan
        return W

    @property
    def constraint_rank(self) -> int:
        """Rank of the legs' constraint wrench system at the home pose (structural), computed
        once per instance by :meth:`structural_constraint_rank`."""
        if self._constraint_rank is None:
            self._constraint_rank = self.structural_constraint_rank()
        return self._constraint_rank

    def structural_constraint_rank(self, X=None, engine: str = "compiled") -> int:
        """``mobility(X).constraint_rank`` (default pose ``home``) without the rest of the
        mobility analysis: every leg's reciprocal wrench space is the null space of its joint
        twists (moments scaled by ``length_scale``, rank tolerance 1e-9 as in
        :func:`parasynth.model.spatial.reciprocal_basis`), and the rank of their union is taken with
        the tolerance of :meth:`mobility` (1e-8). One batched SVD over the legs instead of
        per-leg canonical bases, so that the per-design cost of the singularity margin stays
        small; the same span, so the same rank. ``engine`` as in :meth:`singularity_margin`."""
        _numpy_only(self, engine)
        X0 = self.home if X is None else np.asarray(X, dtype=float)
        _, states, p = self.leg_states(X0[None, :])
        if not all(st.reachable[0] for st in states):
            raise ValueError(f"{self.name}: pose {X0.tolist()} is not reachable")
        L = self.length_scale
        w = np.r_[np.ones(3), np.full(3, L)]
        T = np.zeros((len(self.legs), 6, 6))
        for k, (leg, st) in enumerate(zip(self.legs, states)):
            t = leg.joint_twists(st, p)[0] * w
            if t.shape[0] > 6:  # more than six joint freedoms: six rows spanning the same space
                _, sv, vt = np.linalg.svd(t, full_matrices=False)
                t = sv[:, None] * vt
            T[k, : t.shape[0]] = t
        _, s, Vt = np.linalg.svd(T)
        rank = np.sum(s > 1e-9 * np.maximum(s[:, :1], 1e-300), axis=1)
        rows = [Vt[k, rank[k]:] for k in range(len(self.legs))]
        C = np.concatenate(rows, axis=0) if rows else np.zeros((0, 6))
        return _rank(C)

    def normalized_wrench_system(self, X) -> np.ndarray:
        """Dimensionally homogeneous wrench system used by :meth:`singularity_margin`.

        Moments are divided by ``length_scale``; actuation rows are scaled to unit norm; the
        constraint block is replaced by its ``constraint_rank`` principal directions weighted
        by their singular values relative to the largest (so that a loss of constraint rank
        shows as a small row). Shape (N, n_act + constraint_rank, 6)."""
        W = self.wrench_matrix(np.atleast_2d(np.asarray(X, dtype=float)))
        return self._normalized(W, self.constraint_rank)

    def _normalized(self, W, rc: int) -> np.ndarray:
        W = W.copy()
        W[..., 3:] /= self.length_scale
        na = self.n_actuators
        A = W[:, :na]
        A = A / np.linalg.norm(A, axis=-1, keepdims=True)
        C = W[:, na:]
        if rc and C.shape[1]:
            ok = np.all(np.isfinite(C), axis=(1, 2))
            Cs = np.where(ok[:, None, None], C, 0.0)
            _, s, Vt = np.linalg.svd(Cs, full_matrices=False)
            rel = s[:, :rc] / np.maximum(s[:, :1], 1e-300)
            Cn = rel[..., None] * Vt[:, :rc]
            Cn[~ok] = np.nan
        else:
            Cn = np.zeros((W.shape[0], 0, 6))
        return np.concatenate([A, Cn], axis=1)

    @staticmethod
    def _margin_of(M: np.ndarray) -> np.ndarray:
        ok = np.all(np.isfinite(M), axis=(1, 2))
        s = np.linalg.svd(np.where(ok[:, None, None], M, 0.0), compute_uv=False)
        k = min(M.shape[1], 6)
        return np.where(ok, s[:, k - 1], np.nan)

    def singularity_margin(self, X, engine: str = "compiled") -> np.ndarray:
        """Smallest singular value of the normalised wrench system, (N,) (0 = singular).

        Of the (n_act + constraint_rank) x 6 normalised system the min(rows, 6)-th singular
        value is returned, so for an under-actuated mechanism it measures the independence
        of the wrenches it has. NaN for unreachable poses.

        ``engine="compiled"`` (default): a described mechanism evaluates it with the compiled
        kernels of :mod:`parasynth.engine.indices` (agreeing with the NumPy path to 1e-9); a
        mechanism they do not cover (a leg type of its own, an overridden wrench method, no
        numba) and a model class written in Python run on NumPy, saying so once.
        ``engine="numpy"``: the NumPy reference (this method)."""
        _numpy_only(self, engine)
        Xa, single = self._poses(X)
        out = self._margin_of(self.normalized_wrench_system(Xa))
        return out[0] if single else out

    def singularity_margin_of_states(self, states, p, reachable) -> np.ndarray:
        """The NumPy :meth:`singularity_margin` (N,) from legs' states already solved (a
        :class:`~parasynth.model.constraints.PoseContext`'s), NaN where ``reachable`` is False.
        The structural constraint rank comes from the NumPy reference when not yet known."""
        if self._constraint_rank is None:
            self._constraint_rank = Mechanism.structural_constraint_rank(self, engine="numpy")
        return self._margin_of(self._normalized(self._wrench_of_states(states, p, reachable), self._constraint_rank))

    def singularity_function(self, X) -> tuple[np.ndarray, np.ndarray]:
        """The determinant whose change of sign marks a singularity, and the constraint basis
        it depends on: ``(det (N,), basis (N, constraint_rank, 6))``, NaN where unreachable.

        The square, dimensionally homogeneous wrench system ``M = [A; V]`` (moments divided
        by ``length_scale``): ``A`` the unit actuation wrenches, each multiplied by the sign of
        its leg's transmission scale (so that the rows are those of the actuator Jacobian in
        wrench form, as :meth:`jacobian` uses them), and ``V`` an orthonormal basis of the
        legs' constraint wrenches (their ``constraint_rank`` principal directions). ``det M``
        vanishes exactly where the margin does. The actuation rows are continuous in the
        pose; the basis ``V`` is defined only up to its orientation (as the legs' numeric
        constraint wrenches are: a UPU leg's sign is arbitrary), so the sign of ``det M`` is
        meaningful only relative to an orientation of ``V`` carried continuously along a
        path: between two neighbouring poses a and b the singularity function keeps its
        sign when ``det M_a * det M_b * det(V_a V_b^T) > 0`` (``det(V_a V_b^T)`` is the
        orientation of b's basis relative to a's; see :mod:`parasynth.measures.usable`). With no
        constraint rows (a 6-UPS) it is ``det A``, which has the sign of the actuator
        Jacobian's determinant up to the twist map's (a coordinate factor, not the mechanism).

        Only for a square system, ``n_actuators + constraint_rank == 6``; ``ValueError``
        otherwise (an under-actuated or redundantly actuated mechanism has no determinant:
        the rank of a k x 6 system, k != 6, drops on a set of codimension >= 2, which does
        not split a region, so :mod:`parasynth.measures.usable` uses the margin alone there)."""
        rc = self.constraint_rank
        if self.n_actuators + rc != 6:
            raise ValueError(f"{self.name}: the singularity function needs a square wrench system; "
                             f"{self.n_actuators} actuators + constraint rank {rc} = {self.n_actuators + rc} rows, "
                             f"not 6")
        Xa, single = self._poses(X)
        _, states, p = self.leg_states(Xa)
        reachable = np.logical_and.reduce([st.reachable for st in states])
        W = self._wrench_of_states(states, p, reachable)
        _, scale = self._actuation_rows(states, p)
        na = self.n_actuators
        with np.errstate(invalid="ignore"):
            W[:, :na] *= np.sign(scale)[..., None]
        M = self._normalized(W, rc)
        V = M[:, na:].copy()
        if rc:
            V /= np.linalg.norm(V, axis=-1, keepdims=True)
            M[:, na:] = V
        ok = np.all(np.isfinite(M), axis=(1, 2))
        det = np.where(ok, np.linalg.det(np.where(ok[:, None, None], M, 0.0)), np.nan)
        return (det[0], V[0]) if single else (det, V)

    # -- forward kinematics ----------------------------------------------------------------------
    def forward_kinematics(self, actuators, guess=None, fixed: dict | None = None,
                           tol: float = 1e-12, max_iter: int = 200,
                           residual_tol: float = 1e-6) -> np.ndarray:
        """Task coordinates for actuator values, by damped Gauss-Newton on the inverse
        kinematics (Levenberg-Marquardt, batched over samples).

        ``actuators``: (N, n_act) or (n_act,), SI. ``guess``: starting pose(s), default
        ``home`` (the solution found is the assembly mode nearest the guess). ``fixed``:
        {coordinate: value} to hold coordinates fixed when the actuators alone do not
        determine the pose (under-actuated models). Raises :class:`ForwardKinematicsError`
        when a sample does not converge, when the actuator values are inconsistent with any
        pose of the model (over-determined models) or when the actuators do not determine the
        pose there (a singular Jacobian); raises ``ValueError`` for bad shapes, unknown fixed
        coordinates, or when fewer actuators than free coordinates remain.

        ``tol`` is the relative convergence tolerance of the actuator residual; a solution is
        accepted when the residual is below ``residual_tol`` (m, default 1 um): with more
        actuators than free coordinates, actuator values rounded as in a paper's table are
        slightly inconsistent and cannot be met exactly.
        """
        q = check_pose_array(f"{self.name}: actuators", actuators)
        single = q.ndim == 1
        q = np.atleast_2d(q)
        if q.shape[1] != self.n_actuators:
            raise ValueError(
                f"{self.name}: actuators must have shape (N, {self.n_actuators}) or "
                f"({self.n_actuators},) for {self.actuators}; got {np.shape(actuators)}"
            )
        if not np.all(np.isfinite(q)):
            raise ValueError(f"{self.name}: actuator values must be finite")
        fixed = dict(fixed or {})
        unknown = set(fixed) - set(self.task_coordinates)
        if unknown:
            raise ValueError(
                f"{self.name}: unknown fixed coordinate(s) {sorted(unknown)}; allowed: {self.task_coordinates}"
            )
        free = [i for i, c in enumerate(self.task_coordinates) if c not in fixed]
        if self.n_actuators < len(free):
            raise ValueError(
                f"{self.name}: {self.n_actuators} actuators cannot determine {len(free)} task "
                f"coordinates {tuple(self.task_coordinates[i] for i in free)}; pass "
                f"fixed={{...}} for {len(free) - self.n_actuators} of them"
            )
        N = q.shape[0]
        if guess is None:
            X = np.tile(self.home, (N, 1))
        else:
            X, _ = self._poses(guess)
            X = np.broadcast_to(X, (N, self.n_task)).copy()
        for k, v in fixed.items():
            X[:, self.task_coordinates.index(k)] = float(v)
        qscale = max(float(np.max(np.abs(q))), self.length_scale)

        def residual(Xc):
            r = self.inverse_kinematics(Xc).actuators - q
            cost = np.sum(r * r, axis=1)
            return r, np.where(np.isfinite(cost), cost, np.inf)

        r, cost = residual(X)
        if np.any(~np.isfinite(cost)):
            bad = np.flatnonzero(~np.isfinite(cost))
            raise ForwardKinematicsError(
                f"{self.name}: the starting pose is not reachable for samples {bad.tolist()}; pass a reachable guess",
                bad,
            )
        lam = np.full(N, 1e-3)
        done = np.zeros(N, bool)
        for _ in range(max_iter):
            J = self.jacobian(X)[:, :, free]
            JtJ = np.einsum("nki,nkj->nij", J, J)
            g = np.einsum("nki,nk->ni", J, r)
            D = np.einsum("nii->ni", JtJ) + 1e-12
            H = JtJ + lam[:, None, None] * np.eye(len(free)) * D[:, None, :]
            step = -np.linalg.solve(H, g[..., None])[..., 0]
            Xn = X.copy()
            Xn[:, free] += np.where(done[:, None], 0.0, step)
            rn, costn = residual(Xn)
            better = (costn < cost) & ~done
            X[better], r[better], cost[better] = Xn[better], rn[better], costn[better]
            lam = np.where(better, np.maximum(lam / 5, 1e-12), np.minimum(lam * 10, 1e12))
            small_step = np.linalg.norm(step, axis=1) <= 1e-15 * (1 + np.linalg.norm(X[:, free], axis=1))
            done |= (np.sqrt(cost) <= tol * qscale) | (small_step & better) | (lam >= 1e12)
            if np.all(done):
                break
        res = np.sqrt(cost)
        failed = np.flatnonzero(~(res <= residual_tol))
        if failed.size:
            over = self.n_actuators > len(free)
            why = (" (more actuators than free coordinates: the values may be inconsistent with any pose of this model)"
                   if over else "")
            raise ForwardKinematicsError(
                f"{self.name}: forward kinematics did not converge for samples {failed[:10].tolist()}"
                f"{'...' if failed.size > 10 else ''}; residual up to {res[failed].max():.3g} m{why}. "
                f"Try a guess closer to the expected assembly mode.",
                failed, res,
            )
        J = self.jacobian(X)[:, :, free]
        s = np.linalg.svd(J, compute_uv=False)
        sing = np.flatnonzero(s[:, -1] <= 1e-9 * np.maximum(s[:, 0], 1e-300))
        if sing.size:
            raise ForwardKinematicsError(
                f"{self.name}: the actuators do not determine the pose at samples {sing[:10].tolist()} "
                f"(the actuator Jacobian with respect to the free coordinates is singular there: a "
                f"singularity of the mechanism, or of the parametrisation, e.g. z-y-z angles at beta = 0, "
                f"where holding one more coordinate in `fixed` helps)",
                sing, res,
            )
        return X[0] if single else X

    # -- mobility ---------------------------------------------------------------------------------
    def mobility(self, X=None) -> Mobility:
        """Screw-theory mobility at pose ``X`` (default ``home``) beside the Grübler-Kutzbach
        count. The constraint wrenches are recomputed here numerically as the reciprocal
        complement of every leg's joint twists, independently of the legs' analytic
        constraint wrenches."""
        X0 = self.home if X is None else np.asarray(X, dtype=float)
        Xa, states, p = self.leg_states(X0[None, :])
        if not all(st.reachable[0] for st in states):
            raise ValueError(f"{self.name}: pose {X0.tolist()} is not reachable")
        L = self.length_scale
        C_rows, per_leg = [], 0
        for leg, st in zip(self.legs, states):
            T = leg.joint_twists(st, p)
            Cl = reciprocal_basis(T, L)[0]
            per_leg += Cl.shape[0]
            C_rows.append(Cl)
        C = np.concatenate(C_rows, axis=0) if C_rows else np.zeros((0, 6))
        Cs = C.copy()
        Cs[:, 3:] /= L
        rc = _rank(Cs)
        dof = 6 - rc
        # Twist space: twists t with C t = 0. Work with scaled twists t' = (v, L w).
        if rc:
            _, s, Vt = np.linalg.svd(np.vstack([Cs, np.zeros((6, 6))]))
            Tb = Vt[rc:].copy()
        else:
            Tb = np.eye(6)
        Tb[:, 3:] /= L  # back to (v, w)
        # Rows of the twist basis are unit vectors in the scaled space: an absolute tolerance
        # (a relative one would count a numerically zero rotational block as full rank).
        n_rot = int(np.sum(np.linalg.svd(Tb[:, 3:] * L, compute_uv=False) > 1e-8)) if dof else 0
        n_trans = dof - n_rot
        A, _ = self._actuation_rows(states, p)
        A = A[0].copy()
        A[:, 3:] /= L
        AC = np.vstack([A, Cs])
        controlled_here = _rank(AC) == 6
        controlled = controlled_here
        if not controlled_here:
            controlled = self._controlled_near(X0)
        # Freedoms not seen by actuators: twists in the twist space annihilated by A.
        if controlled_here:
            unc = np.zeros((0, 6))
        else:
            _, s, Vt = np.linalg.svd(np.vstack([AC, np.zeros((6, 6))]))
            r_ac = _rank(AC)
            unc = Vt[r_ac:].copy()
            unc[:, 3:] /= L
        n_links = 2 + sum(leg.n_links for leg in self.legs)
        n_joints = sum(len(leg.joints) for leg in self.legs)
        sum_f = sum(leg.n_joint_dof for leg in self.legs)
        gk = 6 * (n_links - n_joints - 1) + sum_f
        redundant = per_leg - rc
        local = sum(leg.local_dof for leg in self.legs)
        return Mobility(
            dof=dof,
            type=f"{n_trans}T{n_rot}R",
            n_actuators=self.n_actuators,
            controlled=bool(controlled),
            gruebler=gk,
            gruebler_corrected=gk + redundant - local,
            constraint_rank=rc,
            redundant_constraints=redundant,
            local_dof=local,
            n_links=n_links,
            n_joints=n_joints,
            sum_joint_dof=sum_f,
            twist_basis=Tb,
            uncontrolled_twists=unc,
            singular_at_pose=bool(controlled and not controlled_here),
        )

    def _controlled_near(self, X0: np.ndarray) -> bool:
        """Whether the wrench system has rank 6 at a few deterministic perturbations of X0
        (distinguishes a singular reference pose from structural under-actuation)."""
        rng = np.random.default_rng(12345)
        step = np.where([c in self.angular_coordinates for c in self.task_coordinates], 0.05,
                        0.02 * self.length_scale)
        # the five poses in one batch (the same draws as five in turn: one double each)
        X = X0 + step * rng.uniform(-1, 1, size=(5,) + X0.shape)
        for W in self.wrench_matrix(X):
            if not np.all(np.isfinite(W)):
                continue
            W = W.copy()
            W[:, 3:] /= self.length_scale
            if _rank(W) == 6:
                return True
        return False

    # -- constraints ------------------------------------------------------------------------------
    def build_constraints(self) -> list:
        """The model's constraints (subclasses override; limits come from ``params``)."""
        return []

    @property
    def constraints(self) -> dict:
        """{name: Constraint} declared by the model, in evaluation order."""
        if getattr(self, "_constraints", None) is None:
            cons = self.build_constraints()
            names = [c.name for c in cons]
            dup = {n for n in names if names.count(n) > 1}
            if dup:
                raise ValueError(f"{self.name}: duplicate constraint names {sorted(dup)}")
            self._constraints = {c.name: c for c in cons}
        return self._constraints

    #: Pose constraints added to the model's own by :meth:`with_constraints` (in order).
    added_constraints: tuple = ()

    def with_constraints(self, *constraints) -> "Mechanism":
        """A copy of this mechanism whose pose constraints are the model's plus ``constraints``
        (:class:`~parasynth.model.constraints.Constraint` objects with new names), e.g. a floor on
        the singularity margin that a study adds (``evaluation.constraints``). The copy is
        a new object (the engine keeps its own record of it); the original is unchanged."""
        for c in constraints:
            if not isinstance(c, Constraint):
                raise ValueError(f"{self.name}: with_constraints takes Constraint objects, got {c!r}")
        names = list(self.constraints) + [c.name for c in constraints]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"{self.name}: duplicate constraint names {dup}; give the added constraint another name")
        new = copy.copy(self)
        new._constraints = {**self.constraints, **{c.name: c for c in constraints}}
        new.added_constraints = tuple(self.added_constraints) + tuple(constraints)
        return new

    def pose_context(self, X):
        """Inverse kinematics of poses ``X`` packed for constraint evaluation."""
        Xa, _ = self._poses(X)
        valid = self.pose_valid(Xa)
        Xs = np.where(valid[:, None], Xa, self.home)
        p, R = self._pose(Xs)
        states = [leg.solve(p, R) for leg in self.legs]
        reachable = valid & np.logical_and.reduce([st.reachable for st in states])
        act = np.stack([st.actuator for leg, st in zip(self.legs, states) if leg.is_actuated], axis=-1)
        return PoseContext(Xa, p, R, list(self.legs), states, reachable, act, self)

    def _select(self, names):
        names = check_names("names", names)
        if names is None:
            return list(self.constraints.values())
        unknown = [n for n in names if n not in self.constraints]
        if unknown:
            raise ValueError(
                f"{self.name}: unknown constraint(s) {unknown}; valid: {', '.join(self.constraints) or '(none)'}"
            )
        return [self.constraints[n] for n in names]

    def constraint_margins(self, X, names=None, engine: str = "compiled") -> dict[str, np.ndarray]:
        """{constraint name: margins (N,)}, >= 0 where satisfied, in each constraint's unit
        (``self.constraints[name].unit``). Poses the legs cannot reach get -inf in every
        margin (never NaN). ``names`` selects a subset. ``engine``: "compiled" (default: a
        described mechanism runs on the compiled engine, :mod:`parasynth.engine`, falling back to
        NumPy with a warning where it does not cover the mechanism; a model class written in
        Python runs on NumPy, saying so once) or "numpy" (the reference)."""
        _numpy_only(self, engine)
        return self._constraint_margins_numpy(X, names)

    def _constraint_margins_numpy(self, X, names=None) -> dict[str, np.ndarray]:
        """The NumPy reference of :meth:`constraint_margins`."""
        Xa, single = self._poses(X)
        cons = self._select(names)
        ctx = self.pose_context(Xa)
        out = {}
        with np.errstate(invalid="ignore"):
            for c in cons:
                m = np.asarray(c.margin(ctx), dtype=float)
                # Unreachable poses (and undefined margins) are -inf; an unbounded limit stays +inf.
                m = np.where(ctx.reachable & ~np.isnan(m), m, -np.inf)
                out[c.name] = m[0] if single else m
        return out

    def is_feasible(self, X, names=None, engine: str = "compiled") -> np.ndarray:
        """(N,) bool: reachable and every selected constraint margin >= 0. ``engine``:
        "compiled" (default, see :meth:`constraint_margins`) or "numpy" (the reference)."""
        _numpy_only(self, engine)
        return self._is_feasible_numpy(X, names)

    def _is_feasible_numpy(self, X, names=None) -> np.ndarray:
        """The NumPy reference of :meth:`is_feasible`."""
        Xa, single = self._poses(X)
        cons = self._select(names)
        ok = feasible_rows(self.pose_context(Xa), cons)
        return ok[0] if single else ok

    # -- sampling helpers ---------------------------------------------------------------------------
    def with_params(self, **changes) -> "Mechanism":
        """A new mechanism of the same model with some parameters changed."""
        new = type(self)(dataclasses.replace(self.params, **changes))
        return new.with_constraints(*self.added_constraints) if self.added_constraints else new


def check_length(field_name: str, value, allow_zero: bool = False) -> float:
    """Validate a length parameter (m): finite and positive (or >= 0)."""
    if not is_real_number(value):  # True is not 1 m, "0.2" is not 0.2 m
        raise ValueError(f"{field_name} must be a length in m (a number), got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{field_name} must be a length in m (a number), got {value!r}") from None
    if not np.isfinite(v) or (v < 0 if allow_zero else v <= 0):
        what = "non-negative" if allow_zero else "positive"
        raise ValueError(f"{field_name} must be a finite, {what} length in m, got {value!r}")
    return v


def check_finite(field_name: str, value) -> float:
    if not is_real_number(value):
        raise ValueError(f"{field_name} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{field_name} must be a number, got {value!r}") from None
    if not np.isfinite(v):
        raise ValueError(f"{field_name} must be finite, got {value!r}")
    return v


def check_points(field_name: str, value, n: int, dim: int) -> tuple:
    try:
        a = np.asarray(value, dtype=float) if not isinstance(value, str) else None
    except (TypeError, ValueError):  # ragged or non-numeric: report it against the field
        a = None
    if a is None or a.shape != (n, dim):
        raise ValueError(f"{field_name} must be {n} points of {dim} coordinates (m), got {value!r}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{field_name} must be finite, got {value!r}")
    return tuple(tuple(float(c) for c in row) for row in a)


def check_angles(field_name: str, value, n: int) -> tuple:
    """Validate a list of ``n`` finite angles (rad)."""
    try:
        a = np.asarray(value, dtype=float) if not isinstance(value, str) else None
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != (n,):
        raise ValueError(f"{field_name} must be a list of {n} angles (rad), got {value!r}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{field_name} must be finite, got {value!r}")
    return tuple(float(x) for x in a)
