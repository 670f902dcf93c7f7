"""Rigid-body inverse dynamics of a parallel mechanism along a trajectory, and the grinding
robot's force-decoupling study (2022 paper, Section 4).

Model
-----
* The platform is one rigid body (mass, centre of mass in the platform frame, inertia tensor
  about the centre of mass in the platform frame).
* Each leg is two rigid bodies on its line (the 2022 paper's simplification, Section 4.1-4.4):
  the **cylinder** hinged at the base joint, its centre of mass ``offset`` from the base joint
  centre towards the platform, and the **rod** hinged at the platform joint, its centre of mass
  ``offset`` from the platform joint centre towards the base. Both turn with the leg; the rod
  also slides along it. For a slider leg (PUS) the "cylinder" is the slider carriage (it only
  translates along the slider axis; ``offset`` and inertia unused) and the "rod" is the link.
  Joints are massless and frictionless. Legs not listed in the inertia model are massless.
* Leg angular velocity: the swing ``n x n'`` plus the spin about the leg that its base joint
  imposes -- none for a revolute base joint (RPS, RPU: the leg turns about the revolute axis),
  the one that keeps the angular velocity in the span of the universal joint's axes for a
  U joint (UPS, UPU, and the link of a PUS leg on its slider's U joint), none for a spherical
  base joint (SPS: the spin about the leg is a local freedom with no dynamics of its own; its
  transverse inertia is taken as the mean of the two given values). The 2022 paper's eq.
  (25) neglects the U-joint spin; with its nearly axisymmetric leg bodies the difference is
  small.
* Leg body frames (for the principal inertias ``(I1, I2, I3)``): ``e3 = n`` (base to
  platform), ``e2`` a transverse axis fixed in the leg -- the revolute axis (RPS, RPU) or the
  universal joint's cross axis ``unit(a1 x n)`` (UPS, UPU, PUS link; ``a1`` the axis fixed to
  the base or slider) -- and ``e1 = e2 x e3``.

Method (virtual work)
---------------------
Every body's velocity is a linear function of the platform twist ``t = (v_P, omega)`` (a leg's
motion depends only on the velocity of its platform anchor ``A``), so the applied-minus-
inertial load of every body -- ``(m (g - a_c), -(I eps + omega x I omega))`` at its centre of
mass -- has an equivalent wrench on the platform with the same virtual power for every twist
(its Jacobian transpose). Summed with the platform's own load and the external wrench this is
the **equivalent load** ``w_eq``; actuator forces ``F`` and constraint reactions ``lambda`` then
solve exactly the static problem of :func:`parasynth.measures.indices.static_forces`::

    sum_i F_i a_i / s_i + sum_j lambda_j c_j + w_eq = 0

(least squares with the unbalanced residual when the wrench system cannot balance it, e.g.
the under-actuated 4-UPS/1-RPS). Hence, along any motion, ``sum_i F_i q_i' = dT/dt - P_gravity
- P_external + residual . t`` (``T`` the kinetic energy), which the tests check against finite
differences. Reactions along a leg's constraint that the leg's own weight or inertia produce
out of its plane of motion (RPS, RPU) are assigned to its base joint (they are statically
indeterminate between its two ends); ``lambda`` is what the platform receives.

Platform accelerations ``(a_P, alpha) = d/dt (T(X) X')`` use the model's ``twist_map`` and a
fourth-order central difference of it along ``X'`` for ``T'``.

Units SI throughout; frames as in :mod:`parasynth.model.spatial`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .indices import (StaticForces, _as_poses, _lstsq_balance, _pack, default_gravity, point_force_wrench,
                      wrench_system)
from ..model.legs import PUS, RPS, RPU, SPS, UPS, UPU, LegCapabilityError, require, unsupported_message
from ..mechanisms import load_mechanism

__all__ = [
    "RigidBody",
    "LegInertia",
    "PlatformInertia",
    "InertiaModel",
    "grinding_inertia",
    "GRINDING_INERTIA",
    "platform_motion",
    "equivalent_load",
    "inverse_dynamics",
    "kinetic_energy",
    "grinding_trajectory",
    "grinding_lift_trajectory",
    "TrajectoryForces",
    "DecouplingResult",
    "force_decoupling",
]


def _nonneg(name: str, v) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {v!r}") from None
    if not np.isfinite(x) or x < 0:
        raise ValueError(f"{name} must be finite and >= 0, got {v!r}")
    return x


@dataclass(frozen=True)
class RigidBody:
    """A leg body: ``mass`` (kg), principal moments ``inertia = (I1, I2, I3)`` (kg m^2) about
    its centre of mass along the leg body frame (``e3`` along the leg, see the module
    docstring) and the ``offset`` (m) of its centre of mass along the leg (from the base joint
    for a cylinder, from the platform joint for a rod)."""

    mass: float = 0.0
    inertia: tuple = (0.0, 0.0, 0.0)
    offset: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "mass", _nonneg("mass", self.mass))
        I = np.asarray(self.inertia, dtype=float)
        if I.shape != (3,):
            raise ValueError(f"inertia must be three principal moments (kg m^2), got {self.inertia!r}")
        object.__setattr__(self, "inertia", tuple(_nonneg("inertia", v) for v in I))
        try:
            off = float(self.offset)
        except (TypeError, ValueError):
            raise ValueError(f"offset must be a length in m, got {self.offset!r}") from None
        if not np.isfinite(off):
            raise ValueError(f"offset must be finite, got {self.offset!r}")
        object.__setattr__(self, "offset", off)


@dataclass(frozen=True)
class LegInertia:
    """The two bodies of a leg: ``cylinder`` (hinged at the base joint) and ``rod`` (hinged at
    the platform joint)."""

    cylinder: RigidBody = field(default_factory=RigidBody)
    rod: RigidBody = field(default_factory=RigidBody)


@dataclass(frozen=True)
class PlatformInertia:
    """The moving platform with everything it carries: ``mass`` (kg), centre of mass ``com``
    (platform frame, m) and ``inertia`` about the centre of mass in the platform frame
    (kg m^2; three principal moments along the platform axes or a 3x3 tensor)."""

    mass: float = 0.0
    com: tuple = (0.0, 0.0, 0.0)
    inertia: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "mass", _nonneg("platform mass", self.mass))
        c = np.asarray(self.com, dtype=float)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise ValueError(f"platform com must be a finite 3-vector (m), got {self.com!r}")
        object.__setattr__(self, "com", tuple(c))
        I = np.asarray(self.inertia, dtype=float)
        if I.shape == (3,):
            I = np.diag([_nonneg("platform inertia", v) for v in I])
        if I.shape != (3, 3) or not np.all(np.isfinite(I)) or not np.allclose(I, I.T):
            raise ValueError("platform inertia must be 3 principal moments or a symmetric 3x3 tensor (kg m^2), "
                             f"got {self.inertia!r}")
        object.__setattr__(self, "inertia", tuple(map(tuple, I)))

    @property
    def tensor(self) -> np.ndarray:
        return np.array(self.inertia, dtype=float)


@dataclass(frozen=True)
class InertiaModel:
    """Inertia of a mechanism: the ``platform`` and ``legs`` {leg name: LegInertia}; legs not
    named are massless."""

    platform: PlatformInertia = field(default_factory=PlatformInertia)
    legs: dict = field(default_factory=dict)

    def check(self, mech) -> None:
        names = {leg.name for leg in mech.legs}
        unknown = sorted(set(self.legs) - names)
        if unknown:
            raise ValueError(f"inertia model names unknown leg(s) {unknown}; {mech.name} has legs {sorted(names)}")


def grinding_inertia(rps_rod_mass: float = 0.255) -> InertiaModel:
    """Inertia of the 4-UPS/1-RPS grinding robot from the 2022 paper's Table 3.

    * Platform (with fixture): ``m_B`` = 3.593 kg; ``I_BX, I_BY, I_BZ`` = 3.30e-3, 17.79e-3,
      16.28e-3 kg m^2 about the platform axes (y is the disc's normal in this model: the
      largest moment is about it, as for a disc). Centre of mass at the platform centre (the
      paper applies the platform's inertia force and weight at B_o, eqs. (46)-(48)).
    * Driving legs L1-L4 (UPS). Cylinder: ``m_ui`` = 1.458 kg, centre of mass ``l_u1`` =
      0.063 m from the universal joint; inertias ``I_uiX, I_uiY, I_uiZ`` = 15.34e-3, 14.92e-3,
      0.72e-3 in the frame of eq. (54), ``(n x u, n x (n x u), n)``, whose first two axes
      coincide (up to sign) with this module's ``(e1, e2)`` when the leg is along Y. Rod:
      ``m_ri`` = 0.255 kg, centre of mass ``l_r2`` = 0.155 m from the sphere (the paper's
      ``l_ri``, eqs. (31)-(32)); 1.95e-3, 1.95e-3, 0.013e-3.
    * Constraining branch L5 (RPS). Cylinder: ``m_c1`` = 1.311 kg; ``I_c1X, I_c1Y, I_c1Z`` =
      8.94e-3, 0.67e-3, 9.34e-3 in the DH frame 1 (z1 = revolute axis, y1 along the branch,
      since its smallest moment is about y1), i.e. ``(I1, I2, I3)`` = (8.94e-3, 9.34e-3,
      0.67e-3) here (``e2`` = revolute axis, ``e3`` = leg). Centre of mass ``l_c1`` = 0.133 m
      **assumed** from the revolute axis. Rod: inertias 1.14e-3, 1.14e-3, 0.011e-3 (axial
      smallest); centre of mass ``l_c2`` = 0.198 m **assumed** from the sphere (like
      ``l_ri``); its mass ``m_c2`` is **not given** in Table 3: ``rps_rod_mass`` (default
      0.255 kg, the driving rods' value).
    """
    drive = LegInertia(RigidBody(1.458, (15.34e-3, 14.92e-3, 0.72e-3), 0.063),
                       RigidBody(0.255, (1.95e-3, 1.95e-3, 0.013e-3), 0.155))
    rps = LegInertia(RigidBody(1.311, (8.94e-3, 9.34e-3, 0.67e-3), 0.133),
                     RigidBody(rps_rod_mass, (1.14e-3, 1.14e-3, 0.011e-3), 0.198))
    return InertiaModel(PlatformInertia(3.593, (0.0, 0.0, 0.0), (3.30e-3, 17.79e-3, 16.28e-3)),
                        {"L1": drive, "L2": drive, "L3": drive, "L4": drive, "L5": rps})


#: Table 3 of the 2022 paper (see :func:`grinding_inertia` for the mapping and assumptions).
GRINDING_INERTIA = grinding_inertia()


# ---------------------------------------------------------------------------------------------
# Kinematics of the platform and of the leg bodies
# ---------------------------------------------------------------------------------------------
def _traj_arrays(mech, X, Xd, Xdd=None):
    Xa, single = _as_poses(mech, X)
    N = Xa.shape[0]
    out = [Xa]
    for name, a in (("Xd", Xd), ("Xdd", Xdd)):
        if a is None:
            out.append(None)
            continue
        a = np.asarray(a, dtype=float)
        if a.ndim == 1:
            a = a[None, :]
        if a.ndim == 2 and a.shape[0] == 1 and N > 1:
            a = np.broadcast_to(a, (N, a.shape[1]))
        if a.shape != (N, mech.n_task) or not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite with the shape of X ({N}, {mech.n_task}); got {np.shape(a)}")
        out.append(np.array(a))
    return (*out, single)


def platform_motion(mech, X, Xd, Xdd):
    """Platform twist ``(v_P, omega)`` and acceleration ``(a_P, alpha)`` (N, 6) each, for task
    coordinates, rates and second derivatives. ``a_P`` is the acceleration of the point ``P``
    and ``alpha`` the angular acceleration, ``d/dt (T(X) X') = T X'' + (dT/dX . X') X'``, the
    last term by a fourth-order central difference of ``mech.twist_map`` along ``X'``."""
    Xa, Xd, Xdd, single = _traj_arrays(mech, X, Xd, Xdd)
    T = mech.twist_map(Xa)
    t = np.einsum("nij,nj->ni", T, Xd)
    acc = np.einsum("nij,nj->ni", T, Xdd)
    scale = np.array([mech.length_scale if c not in mech.angular_coordinates else 1.0 for c in mech.task_coordinates])
    speed = np.linalg.norm(Xd / scale, axis=1)
    moving = speed > 0
    if np.any(moving):
        h = np.where(moving, 1e-3 / np.where(moving, speed, 1.0), 0.0)[:, None]
        dT = (-mech.twist_map(Xa + 2 * h * Xd) + 8 * mech.twist_map(Xa + h * Xd)
              - 8 * mech.twist_map(Xa - h * Xd) + mech.twist_map(Xa - 2 * h * Xd))
        dT = dT / np.where(moving, 12 * h[:, 0], 1.0)[:, None, None]
        acc = acc + np.where(moving[:, None], np.einsum("nij,nj->ni", dT, Xd), 0.0)
    return (t[0], acc[0]) if single else (t, acc)


def _axis_kind(leg):
    require(leg, "dynamics")
    if isinstance(leg, (UPS, UPU, PUS)):
        return "U", np.asarray(leg.u_axis, dtype=float)
    if isinstance(leg, (RPS, RPU)):
        return "R", np.asarray(leg.r_axis, dtype=float)
    if isinstance(leg, SPS):
        return "S", None
    raise LegCapabilityError(unsupported_message(leg, "dynamics"))  # pragma: no cover - required first


def _skew(v):
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2)


def _dot(a, b):
    return np.sum(a * b, axis=-1)


@dataclass
class _Body:
    mass: float
    com: np.ndarray  # (N, 3)
    v: np.ndarray  # (N, 3)
    a: np.ndarray  # (N, 3)
    vmap: np.ndarray  # (N, 3, 3): v = vmap @ v_A
    omega: np.ndarray | None = None  # (N, 3)
    eps: np.ndarray | None = None
    wmap: np.ndarray | None = None  # (N, 3, 3): omega = wmap @ v_A
    I: np.ndarray | None = None  # (N, 3, 3) base frame


def _leg_bodies(leg, st, vA, aA, li: LegInertia) -> list[_Body]:
    """The leg's bodies with their velocities, accelerations and velocity maps from ``v_A``."""
    kind, a1 = _axis_kind(leg)
    n = st.direction
    N = n.shape[0]
    eye = np.broadcast_to(np.eye(3), (N, 3, 3))
    nn = n[:, :, None] * n[:, None, :]
    B, A = st.base_point, st.platform_point
    if isinstance(leg, PUS):
        e = np.broadcast_to(np.asarray(leg.slider_axis, dtype=float), (N, 3))
        Lk = float(leg.link_length)
        ne = _dot(n, e)
        Nd = (eye - e[:, :, None] * n[:, None, :] / ne[:, None, None]) / Lk
        ndot = np.einsum("nij,nj->ni", Nd, vA)
        sdot = _dot(n, vA) / ne
        sdd = (_dot(n, aA) + Lk * _dot(ndot, ndot)) / ne
        ndd = (aA - sdd[:, None] * e) / Lk
    else:
        l = st.length
        P = eye - nn
        if kind == "R":
            P = P - np.outer(a1, a1)
        Nd = P / l[:, None, None]
        ndot = np.einsum("nij,nj->ni", Nd, vA)
        ldot = _dot(n, vA)
        ldd = _dot(n, aA) + l * _dot(ndot, ndot)
        ndd = (aA - ldd[:, None] * n - 2 * ldot[:, None] * ndot) / l[:, None]
    # Angular velocity and acceleration of the leg.
    nx = _skew(n)
    omega = np.cross(n, ndot)
    eps = np.cross(n, ndd)
    Wm = nx @ Nd
    if kind == "U":
        k = n @ a1
        m = omega @ a1
        one = 1.0 - k * k
        s = k * m / one
        kd = ndot @ a1
        md = eps @ a1
        sd = ((kd * m + k * md) * one + 2 * k * k * kd * m) / one**2
        omega = omega + s[:, None] * n
        eps = eps + sd[:, None] * n + s[:, None] * ndot
        Wm = Wm + (k / one)[:, None, None] * n[:, :, None] * (a1 @ Wm)[:, None, :]
    # Body frames and inertia tensors (base frame).
    def tensor(I3):
        I3 = np.asarray(I3, dtype=float)
        if kind == "S":
            It = 0.5 * (I3[0] + I3[1])
            return It * (eye - nn) + I3[2] * nn
        e2 = np.cross(a1, n) if kind == "U" else np.broadcast_to(a1, (N, 3))
        e2 = e2 / np.linalg.norm(e2, axis=-1, keepdims=True)
        e1 = np.cross(e2, n)
        E = np.stack([e1, e2, n], axis=-1)  # columns
        return E @ np.diag(I3) @ np.swapaxes(E, 1, 2)

    bodies = []
    cyl, rod = li.cylinder, li.rod
    if isinstance(leg, PUS):
        if cyl.mass > 0:
            vmap = e[:, :, None] * (n / ne[:, None])[:, None, :]
            bodies.append(_Body(cyl.mass, B.copy(), sdot[:, None] * e, sdd[:, None] * e, vmap))
    elif cyl.mass > 0 or any(cyl.inertia):
        d = cyl.offset
        bodies.append(_Body(cyl.mass, B + d * n, d * ndot, d * ndd, d * Nd, omega, eps, Wm, tensor(cyl.inertia)))
    if rod.mass > 0 or any(rod.inertia):
        d = rod.offset
        # A revolute-jointed leg moves in its plane: the out-of-plane part of v_A (zero in any
        # real motion) is dropped so that its out-of-plane loads stay with its base joint.
        vmap = eye - np.outer(a1, a1) if kind == "R" else eye
        bodies.append(_Body(rod.mass, A - d * n, vA - d * ndot, aA - d * ndd, vmap - d * Nd, omega, eps, Wm,
                            tensor(rod.inertia)))
    return bodies


def _motion(mech, X, Xd, Xdd, inertia: InertiaModel):
    Xa, Xd, Xdd, single = _traj_arrays(mech, X, Xd, Xdd)
    inertia.check(mech)
    ws = wrench_system(mech, Xa)
    ok = ws.reachable
    Xs = np.where(ok[:, None], Xa, mech.home)
    Xds = np.where(ok[:, None], Xd, 0.0)
    Xdds = np.where(ok[:, None], Xdd, 0.0) if Xdd is not None else np.zeros_like(Xds)
    t, acc = platform_motion(mech, Xs, Xds, Xdds)
    if ok.all():  # every pose reachable: the wrench system's leg states are those of Xs
        states, p, R = ws.states, ws.p, ws.R
    else:
        _, states, p = mech.leg_states(Xs)
        _, R = mech.pose(Xs)
    v, w = t[:, :3], t[:, 3:]
    a, al = acc[:, :3], acc[:, 3:]
    legs = []
    for leg, st in zip(mech.legs, states):
        li = inertia.legs.get(leg.name)
        if li is None:
            continue
        r = st.platform_point - p
        vA = v + np.cross(w, r)
        aA = a + np.cross(al, r) + np.cross(w, np.cross(w, r))
        legs.append((leg, st, r, _leg_bodies(leg, st, vA, aA, li)))
    return Xa, single, ok, ws, p, R, t, acc, legs


def kinetic_energy(mech, X, Xd, inertia: InertiaModel) -> np.ndarray:
    """Kinetic energy (J, (N,)) of the platform and the leg bodies at poses ``X`` moving at
    task rates ``Xd``. NaN where unreachable."""
    Xa, single, ok, ws, p, R, t, acc, legs = _motion(mech, X, Xd, None, inertia)
    v, w = t[:, :3], t[:, 3:]
    pl = inertia.platform
    rc = R @ np.asarray(pl.com)
    vc = v + np.cross(w, rc)
    Iw = R @ pl.tensor @ np.swapaxes(R, 1, 2)
    T = 0.5 * pl.mass * _dot(vc, vc) + 0.5 * np.einsum("ni,nij,nj->n", w, Iw, w)
    for _, _, _, bodies in legs:
        for b in bodies:
            T = T + 0.5 * b.mass * _dot(b.v, b.v)
            if b.omega is not None:
                T = T + 0.5 * np.einsum("ni,nij,nj->n", b.omega, b.I, b.omega)
    T = np.where(ok, T, np.nan)
    return T[0] if single else T


def equivalent_load(mech, X, Xd, Xdd, inertia: InertiaModel, gravity=None, external=None) -> np.ndarray:
    """The equivalent load on the platform (N, 6), ``(f, m_P)`` about ``P``: the external wrench
    plus the applied-minus-inertial loads (weight minus mass times acceleration, and minus the
    rate of angular momentum) of the platform and of every leg body, carried to the platform
    by virtual work. Balancing it is the inverse-dynamics problem (see the module docstring).
    ``gravity``: vector (m/s^2), default :func:`parasynth.measures.indices.default_gravity`;
    ``external``: wrench (6,) or (N, 6) on the platform about ``P``."""
    Xa, single, ok, ws, p, R, t, acc, legs = _motion(mech, X, Xd, Xdd, inertia)
    weq = _equivalent(mech, Xa, ok, p, R, t, acc, legs, inertia, gravity, external)
    return weq[0] if single else weq


def _equivalent(mech, Xa, ok, p, R, t, acc, legs, inertia, gravity, external):
    N = Xa.shape[0]
    g = default_gravity(mech) if gravity is None else np.asarray(gravity, dtype=float)
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise ValueError(f"gravity must be a finite 3-vector (m/s^2), got {gravity!r}")
    v, w = t[:, :3], t[:, 3:]
    a, al = acc[:, :3], acc[:, 3:]
    pl = inertia.platform
    rc = R @ np.asarray(pl.com)
    ac = a + np.cross(al, rc) + np.cross(w, np.cross(w, rc))
    Iw = R @ pl.tensor @ np.swapaxes(R, 1, 2)
    F = pl.mass * (g - ac)
    Tq = -(np.einsum("nij,nj->ni", Iw, al) + np.cross(w, np.einsum("nij,nj->ni", Iw, w)))
    weq = np.concatenate([F, np.cross(rc, F) + Tq], axis=1)
    for leg, st, r, bodies in legs:
        fA = np.zeros((N, 3))
        for b in bodies:
            Fb = b.mass * (g - b.a)
            fA += np.einsum("nji,nj->ni", b.vmap, Fb)
            if b.omega is not None:
                Tb = -(np.einsum("nij,nj->ni", b.I, b.eps) + np.cross(b.omega, np.einsum("nij,nj->ni", b.I, b.omega)))
                fA += np.einsum("nji,nj->ni", b.wmap, Tb)
        weq += np.concatenate([fA, np.cross(r, fA)], axis=1)
    if external is not None:
        ext = np.asarray(external, dtype=float)
        ext = np.broadcast_to(ext, (N, 6)) if ext.shape == (6,) else ext
        if ext.shape != (N, 6) or not np.all(np.isfinite(ext)):
            raise ValueError(f"external must be a finite wrench (6,) or ({N}, 6); got {np.shape(external)}")
        weq = weq + ext
    weq[~ok] = np.nan
    return weq


def inverse_dynamics(mech, X, Xd, Xdd, inertia: InertiaModel, gravity=None, external=None,
                     length: float | None = None) -> StaticForces:
    """Actuator forces and constraint reactions along a trajectory (inverse dynamics).

    ``X``, ``Xd``, ``Xdd``: task coordinates and their first and second time derivatives
    (N, n_task), SI. ``inertia``: :class:`InertiaModel` (e.g. :data:`GRINDING_INERTIA`).
    ``gravity``: vector (m/s^2, base frame), default
    :func:`parasynth.measures.indices.default_gravity` (``-Y`` for the grinding robot, ``-Z``
    otherwise). ``external``: wrench on the platform about ``P`` (6,) or (N, 6), e.g. a
    grinding force from :func:`parasynth.measures.indices.point_force_wrench`.

    Returns :class:`parasynth.measures.indices.StaticForces` (``actuator``: generalised actuator forces,
    N, positive pushing; ``constraint``: reactions of the unit constraint wrenches;
    ``residual``: the part of the equivalent load the wrench system cannot balance, zero for
    a controlled mechanism off singularities; ``balanced``), solved as in
    :func:`parasynth.measures.indices.static_forces` with the equivalent load of
    :func:`equivalent_load`.
    """
    Xa, single, ok, ws, p, R, t, acc, legs = _motion(mech, X, Xd, Xdd, inertia)
    weq = _equivalent(mech, Xa, ok, p, R, t, acc, legs, inertia, gravity, external)
    L = float(mech.length_scale if length is None else length)
    x, res, bal, _ = _lstsq_balance(ws, np.where(ok[:, None], weq, 0.0), L)
    ws.single = single
    return _pack(ws, x, res, bal)


# ---------------------------------------------------------------------------------------------
# The grinding robot's trajectories and force-decoupling study (2022 paper, Section 4.5)
# ---------------------------------------------------------------------------------------------
def grinding_trajectory(t, y0: float = 0.45, beta: float = -np.pi / 12, alpha: float = 0.0, gamma: float = 0.0):
    """Hypothesis 1's motion, eqs. (66)-(68), as task coordinates ``(x, y, alpha, beta,
    gamma)`` of the ``4ups_1rps`` model and their first and second derivatives, (N, 5) each.

    * 0 <= t <= 5 s: ``X = 0.002 t^2``; 5 < t <= 10 s: ``X = 0.1 - 0.002 (t - 10)^2``;
      ``Y = 0.45`` (a straight line along X, accelerating at 4 mm/s^2 then decelerating);
    * 10 < t <= 50 s: ``X = 0.1 cos(pi (t - 10)/20)``, ``Y = 0.1 sin(pi (t - 10)/20) + 0.45``
      (one full circle of radius 0.1 m about (0, 0.45) m in 40 s);
    * ``beta = -pi/12`` throughout (eq. (68)); ``alpha = gamma = 0`` (not stated; taken as zero).
      ``alpha``, ``beta``, ``gamma`` set the constant attitude, so other readings of eq. (68)
      can be run, e.g. ``beta=0, alpha=-pi/12``.

    (X, Y) are read as the platform centre (the paper applies the motion "to the moving
    platform"). ``y0`` is the 0.45 m of the equations.

    **What beta = -15 deg does.** The model's frame is the paper's: eq. (1), the DH chain of
    the RPS branch, equals the model's pose, with ``alpha = -(theta1 + theta3)``,
    ``beta = theta4``, ``gamma = theta5`` (eq. (3)), and the disc's normal is the platform's
    y axis (eqs. (9)-(10): ``n_mi = (0, 1, 0)``, grinding point ``(0, y_T, 0)``). In
    ``R = Rz(alpha) Ry(beta) Rz(gamma)`` the normal is
    ``R (0, 1, 0) = Rz(alpha) (-c(beta) s(gamma), c(gamma), s(beta) s(gamma))``: with
    ``gamma = 0`` it is ``Rz(alpha) (0, 1, 0)`` whatever ``beta`` (eq. (1)'s second column is
    ``(s theta13, c theta13, 0)`` when ``theta5 = 0``, free of ``theta4``). So ``beta`` alone
    turns the platform about its own normal, ``alpha`` tilts it within the plane of motion
    (about Z, like the revolute angle ``theta1``), and ``beta`` tilts the normal out of that
    plane only together with ``gamma``. Eq. (68) as printed is therefore a -15 deg spin about
    the disc axis, and that is the default.
    A spin is the same as a common offset of the sphere angles, which the paper does not give
    (the model assumes -45, 45, 135, 225 deg): the spun path equals the level path with
    ``platform_angles`` -30, 60, 150, 240 deg. docs/reproduction.md compares the readings
    with the paper's forces.

    Along this path the model's limits are exceeded in places
    (``d2`` reaches 0.60 m > ``d2_max`` = 0.55 m at the top of the circle, and the legs
    lengthen to 0.730 m > ``l_max`` = 0.68 m; 61 % of the path is feasible);
    :func:`force_decoupling` reports the smallest margins. The equations have a velocity jump at t = 10 s (``Y'`` goes from 0 to 15.7 mm/s),
    which the paper notices as a sudden change of the forces; here each instant is evaluated
    on its own branch (t = 10 s on the linear one).
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if np.any(t < 0) or np.any(t > 50) or not np.all(np.isfinite(t)):
        raise ValueError("t must lie in [0, 50] s (eqs. (66)-(68))")
    X = np.zeros((t.size, 5))
    Xd = np.zeros_like(X)
    Xdd = np.zeros_like(X)
    a = t <= 5
    b = (t > 5) & (t <= 10)
    c = t > 10
    X[a, 0], Xd[a, 0], Xdd[a, 0] = 0.002 * t[a] ** 2, 0.004 * t[a], 0.004
    X[b, 0], Xd[b, 0], Xdd[b, 0] = 0.1 - 0.002 * (t[b] - 10) ** 2, -0.004 * (t[b] - 10), -0.004
    X[~c, 1] = y0
    w = np.pi / 20
    u = w * (t[c] - 10)
    X[c, 0], X[c, 1] = 0.1 * np.cos(u), 0.1 * np.sin(u) + y0
    Xd[c, 0], Xd[c, 1] = -0.1 * w * np.sin(u), 0.1 * w * np.cos(u)
    Xdd[c, 0], Xdd[c, 1] = -0.1 * w**2 * np.cos(u), -0.1 * w**2 * np.sin(u)
    X[:, 2], X[:, 3], X[:, 4] = alpha, beta, gamma
    return X, Xd, Xdd


def grinding_lift_trajectory(t, x0: float = 0.0, y0: float = 0.45, accel: float = 0.002):
    """Hypotheses 2 and 3's motion: the platform moves along +Y, accelerating uniformly at
    ``accel`` (the paper's 2 mm/s^2) for 5 s and decelerating for 5 s (0 <= t <= 10 s, 50 mm
    in all), level (``alpha = beta = gamma = 0``). The start point is not stated: ``(x0, y0)``
    default to the start of eq. (66), (0, 0.45) m."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if np.any(t < 0) or np.any(t > 10) or not np.all(np.isfinite(t)):
        raise ValueError("t must lie in [0, 10] s")
    X = np.zeros((t.size, 5))
    Xd = np.zeros_like(X)
    Xdd = np.zeros_like(X)
    a = t <= 5
    X[:, 0] = x0
    X[a, 1], Xd[a, 1], Xdd[a, 1] = y0 + 0.5 * accel * t[a] ** 2, accel * t[a], accel
    b = ~a
    X[b, 1] = y0 + accel * 25.0 - 0.5 * accel * (t[b] - 10) ** 2
    Xd[b, 1], Xdd[b, 1] = -accel * (t[b] - 10), -accel
    return X, Xd, Xdd


@dataclass
class TrajectoryForces:
    """Forces along a trajectory: times ``t`` (N,), poses ``X``, driving forces ``actuator``
    (N, n_act, N), constraint reactions ``constraint`` (N, n_c), unbalanced ``residual``
    (N, 6), ``balanced`` (N,), the grinding force ``load`` (N) it was computed with, and the
    smallest constraint margin of the model along the path {name: min margin}."""

    t: np.ndarray
    X: np.ndarray
    actuator: np.ndarray
    constraint: np.ndarray
    residual: np.ndarray
    balanced: np.ndarray
    load: float
    min_margins: dict


@dataclass
class DecouplingResult:
    """The force-decoupling study (see :func:`force_decoupling`)."""

    gravity_only: TrajectoryForces  # hypothesis 1: eqs. (66)-(68), no grinding force
    loaded: dict  # {force: TrajectoryForces}: the same path with the grinding force
    lift: dict  # {force: TrajectoryForces}: hypotheses 2/3 (0 N as the reference)
    load_point: tuple
    direction: tuple

    def summary(self) -> dict:
        """The decoupling claim as numbers.

        ``h1_min``, ``h1_max`` (N) and the times at which they occur (driving forces under
        gravity only along eqs. (66)-(68)); for every grinding force ``F``:
        ``drive_change[F]`` the largest change of any driving force against the gravity-only
        case on the same path, ``constraint_share[F]`` the fraction of ``F`` taken by the
        constraining branch (``-delta lambda / F`` of its unit Z force; 1 = fully decoupled);
        ``drive_change_30_50`` the largest driving-force change from the first to the last
        grinding force (paper: about 2 N), on the eqs. (66)-(68) path and on the lift path;
        ``max_residual`` the largest unbalanced force (N) in any case."""
        h1 = self.gravity_only
        A = h1.actuator
        out = {
            "h1_min": float(np.nanmin(A)), "h1_max": float(np.nanmax(A)),
            "h1_t_min": float(h1.t[np.unravel_index(np.nanargmin(A), A.shape)[0]]),
            "h1_t_max": float(h1.t[np.unravel_index(np.nanargmax(A), A.shape)[0]]),
            "h1_leg_ranges": {f"L{i + 1}": (float(np.nanmin(A[:, i])), float(np.nanmax(A[:, i])))
                              for i in range(A.shape[1])},
        }
        for key, cases, ref in (("path", self.loaded, h1), ("lift", self.lift, self.lift.get(0.0))):
            change, share = {}, {}
            for F, tf in cases.items():
                if F == 0.0 or ref is None:
                    continue
                change[F] = float(np.nanmax(np.abs(tf.actuator - ref.actuator)))
                share[F] = float(np.nanmedian(-(tf.constraint[:, 0] - ref.constraint[:, 0]) / F))
            out[f"drive_change_{key}"] = change
            out[f"constraint_share_{key}"] = share
            Fs = sorted(F for F in cases if F != 0.0)
            if len(Fs) >= 2:
                out[f"drive_change_{key}_{Fs[0]:g}_{Fs[-1]:g}"] = float(
                    np.nanmax(np.abs(cases[Fs[-1]].actuator - cases[Fs[0]].actuator)))
        allres = [h1] + list(self.loaded.values()) + list(self.lift.values())
        out["max_residual"] = float(max(np.nanmax(np.linalg.norm(tf.residual[:, :3], axis=1)) for tf in allres))
        out["max_residual_moment"] = float(max(np.nanmax(np.linalg.norm(tf.residual[:, 3:], axis=1)) for tf in allres))
        return out


def force_decoupling(mech=None, inertia: InertiaModel | None = None, grinding_forces=(30.0, 50.0),
                     dt: float = 0.1, load_point=(0.0, 0.0, 0.0), direction=(0.0, 0.0, 1.0),
                     gravity=None, y0: float = 0.45, attitude=(0.0, -np.pi / 12, 0.0)) -> DecouplingResult:
    """Run the 2022 paper's hypotheses 1-3 on the ``4ups_1rps`` model (Section 4.5).

    * Hypothesis 1: gravity only, motion of eqs. (66)-(68) (:func:`grinding_trajectory`),
      at the constant z-y-z ``attitude`` ``(alpha, beta, gamma)``, default eq. (68) as printed
      (``beta = -pi/12``, a spin about the disc axis; see :func:`grinding_trajectory`).
    * Hypotheses 2 and 3: a constant grinding force of 30 N and 50 N (``grinding_forces``)
      along ``direction`` (base frame, default +Z, the constant-force actuator's axis) with
      zero moment about the platform centre (the paper: "the torque of that external force is
      always n_k = 0"), during the level lift of :func:`grinding_lift_trajectory`; the
      gravity-only lift is computed as their reference. The same forces are also applied along
      the eqs. (66)-(68) path (``loaded``), the cleanest comparison with hypothesis 1.
    * ``load_point`` (platform frame, m): where the force acts; the default (platform centre)
      is the paper's; ``(0, y_T, 0)`` puts it at the grinding point of eq. (10), which adds the
      moment of the force about the centre.

    Gravity along ``-Y`` (the model's vertical) unless ``gravity`` is given; inertia
    :data:`GRINDING_INERTIA` unless given; samples every ``dt`` seconds.
    """
    mech = mech or load_mechanism("4ups_1rps")
    if mech.name != "4ups_1rps":
        raise ValueError(f"force_decoupling is the grinding robot's study (4ups_1rps); got {mech.name!r}")
    inertia = inertia or GRINDING_INERTIA
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    forces = [float(F) for F in grinding_forces]

    def run(t, traj, F):
        X, Xd, Xdd = traj
        ext = point_force_wrench(mech, X, F * d, load_point) if F else None
        sf = inverse_dynamics(mech, X, Xd, Xdd, inertia, gravity=gravity, external=ext)
        margins = {k: float(np.min(v)) for k, v in mech.constraint_margins(X).items()}
        return TrajectoryForces(t, X, sf.actuator, sf.constraint, sf.residual, sf.balanced, F, margins)

    t1 = np.round(np.arange(0.0, 50.0 + 1e-9, dt), 12)
    att = np.asarray(attitude, dtype=float)
    if att.shape != (3,) or not np.all(np.isfinite(att)):
        raise ValueError(f"attitude must be three finite z-y-z angles (alpha, beta, gamma) in rad, got {attitude!r}")
    a, b, c = (float(v) for v in att)
    path = grinding_trajectory(t1, y0=y0, alpha=a, beta=b, gamma=c)
    t2 = np.round(np.arange(0.0, 10.0 + 1e-9, dt), 12)
    lift = grinding_lift_trajectory(t2, y0=y0)
    h1 = run(t1, path, 0.0)
    loaded = {F: run(t1, path, F) for F in forces}
    lifted = {F: run(t2, lift, F) for F in [0.0] + forces}
    return DecouplingResult(h1, loaded, lifted, tuple(map(float, load_point)), tuple(map(float, d)))
