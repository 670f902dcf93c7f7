"""Pose accuracy of a parallel mechanism: first-order error bounds and Monte Carlo.

Error model
-----------
The platform pose is fixed by the closure equations of its legs, one per row of
``mech.wrench_matrix``::

    h(pose, legs) = [ actuator values ; constraint residuals ] = [ q ; h_c0 ]

* actuated rows: the leg's inverse kinematics (``leg.solve``) gives the actuator value (leg
  length or slider position, m);
* constraint rows (signed residuals, zero at a consistent pose): an RPS or PRS leg keeps its
  sphere in the plane normal to its revolute axis, ``(A - B) . r``; an RPU leg keeps its
  universal joint in that plane and its platform axis normal to ``r``, ``(A - B) . r`` and
  ``(R u) . r``; a UPU leg keeps the twist of its two cross axes about the leg line at its
  design value, ``atan2((c_b x c_p) . n, c_b . c_p)`` with ``c_b = unit(u_b x n)``,
  ``c_p = unit(R u_p x n)``.

Error sources, each independent and zero-mean:

* **actuator errors** ``dq_i`` in ``[-actuator_tolerance, +actuator_tolerance]`` (resolution or
  repeatability of each drive);
* **manufacturing errors** of every leg's geometry, independently per leg: each coordinate of
  the base and platform anchor points in ``[-anchor_tolerance, +anchor_tolerance]``, the length
  of fixed-length links (PUS, PRS) in ``[-link_tolerance, +link_tolerance]``, and the direction of
  every joint axis (``u_axis``, ``slider_axis``, ``r_axis``, ``u_platform_axis``) tilted about two
  axes normal to it by angles in ``[-axis_tolerance, +axis_tolerance]``;
* **joint clearances** of spherical and universal joints: the joint centre is displaced
  anywhere in a ball of radius ``spherical_clearance`` (S) or ``universal_clearance`` (U), the
  radial gap of the joint (the clearance is taken up in whatever direction the error lands;
  R and P joints are taken as exact).

The commanded actuator values are the nominal inverse kinematics ``q``. The actual pose
``pose (+) t``, with ``t = (dp, dtheta)`` (m, rad: the displacement of the platform point P and
the rotation vector, ``R' = exp([dtheta]) R``), satisfies ``h(pose (+) t, legs + de) = [q + dq;
h_c0]``. To first order ``G_t t + G_e de = [dq; 0]`` with ``G_t = dh/dt`` and ``G_e = dh/de``
(central finite differences of the closure residuals), hence ``t = S e`` with the sensitivity
matrix ``S = G_t^+ [E_q, -G_e]`` (N, 6, n_sources).

* **first order, worst case**: ``|t_k| <= b_k = sum_j |S_kj| tol_j + sum_g c_g ||S_k,g||`` (box
  tolerances, ball clearances); the reported position (orientation) error is ``||b[:3]||``
  (``||b[3:]||``), which bounds ``||dp||`` (``||dtheta||``) for every admissible error to first
  order;
* **first order, covariance**: ``S diag(sigma^2) S^T`` with ``sigma^2 = tol^2 / 3`` (uniform in the
  box) and ``c^2 / 5`` per coordinate (uniform in the ball);
* **Monte Carlo**: errors sampled uniformly in the box and the balls, the perturbed closure solved
  for ``t`` by a chord Newton iteration (``G_t^+`` fixed), the largest sampled ``||dp||``
  (``||dtheta||``) reported.

Assumptions: rigid links, errors small enough for the linearisation (Monte Carlo checks it),
the closure Jacobian ``G_t`` of rank 6 (an under-actuated mechanism, e.g. the 4-UPS/1-RPS, has an
uncontrolled freedom whose error is not defined: ``ValueError``), poses near a singularity give
large (and at the singularity ``inf``) errors. With more closure rows than 6 (redundant
constraints) the least-squares solution is used. A leg type without the ``accuracy`` capability
(:data:`parasynth.model.legs.CAPABILITIES`) is refused by name (``LegCapabilityError``, a ``ValueError``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..model.legs import require
from ..model.spatial import rot_axis, unit
from ..common.units import parse_quantity

__all__ = [
    "TOLERANCE_SETTINGS",
    "ErrorSources",
    "closure_residuals",
    "error_sources",
    "sensitivity",
    "pose_error_bound",
    "pose_error_covariance",
    "pose_error_monte_carlo",
    "actuator_pose_error",
    "parameter_sensitivity",
    "sensitivity_ranking",
]

#: Tolerance settings and their quantity kinds (for study files).
TOLERANCE_SETTINGS = {
    "actuator_tolerance": "length",
    "anchor_tolerance": "length",
    "link_tolerance": "length",
    "axis_tolerance": "angle",
    "spherical_clearance": "length",
    "universal_clearance": "length",
}
#: Tolerances are SI numbers, or strings with their unit ("0.02 mm", "0.05 deg").

_AXIS_FIELDS = ("u_axis", "slider_axis", "r_axis", "u_platform_axis")


def _check_tolerances(tol: dict) -> dict:
    unknown = sorted(set(tol) - set(TOLERANCE_SETTINGS))
    if unknown:
        raise ValueError(f"unknown tolerance setting(s) {unknown}; allowed: {', '.join(TOLERANCE_SETTINGS)}")
    out = {}
    for k in TOLERANCE_SETTINGS:
        v = tol.get(k, 0.0)
        if isinstance(v, str):  # a quantity with its unit, e.g. "0.02 mm", "0.05 deg"
            v = parse_quantity(v, TOLERANCE_SETTINGS[k], field=k)
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"{k} must be a tolerance in SI units (m or rad), got {v!r}") from None
        if not math.isfinite(v) or v < 0:
            raise ValueError(f"{k} must be a finite tolerance >= 0 (0: source ignored), got {v!r}")
        out[k] = v
    if not any(out.values()):
        raise ValueError(f"give at least one positive tolerance among {', '.join(TOLERANCE_SETTINGS)}")
    return out


# -- closure residuals ----------------------------------------------------------------------------
def _leg_residual(leg, p, R) -> np.ndarray:
    """Closure residuals (N, r) of one leg, rows as in ``mech.wrench_matrix`` for this leg:
    (actuator value if actuated), then the constraint residuals the leg type declares
    (``leg.constraint_residuals``); a leg type without the ``accuracy`` capability is refused."""
    require(leg, "accuracy")
    A = leg.platform_points(p, R)
    out = [leg.actuator_value(A, p, R)] if leg.is_actuated else []
    out += leg.constraint_residuals(A, R)
    return np.stack(out, axis=-1) if out else np.zeros(p.shape[:1] + (0,))


def closure_residuals(mech, p, R, legs=None) -> np.ndarray:
    """Closure residuals (N, m) of all legs at platform poses ``(p, R)``; ``legs`` replaces
    ``mech.legs`` (e.g. perturbed copies)."""
    return np.concatenate([_leg_residual(leg, p, R) for leg in (legs or mech.legs)], axis=-1)


def _rows_per_leg(mech):
    n = []
    for leg in mech.legs:
        n.append(int(leg.is_actuated) + len(leg.constraint_rows))
    return n


def _actuated_row_mask(mech):
    mask = []
    for leg, n in zip(mech.legs, _rows_per_leg(mech)):
        mask += [leg.is_actuated] + [False] * (n - 1) if leg.is_actuated else [False] * n
    return np.array(mask, bool)


def _compose(p, R, t):
    """Pose (+) twist: p + dp, exp([dtheta]) R."""
    dth = t[..., 3:]
    ang = np.linalg.norm(dth, axis=-1)
    axis = np.where(ang[..., None] > 0, dth / np.where(ang > 0, ang, 1.0)[..., None], [1.0, 0, 0])
    return p + t[..., :3], rot_axis(axis, ang) @ R


# -- error sources --------------------------------------------------------------------------------
@dataclass(frozen=True)
class ErrorSources:
    """The scalar error sources of a mechanism (columns of the sensitivity matrix).

    ``names``: e.g. ``"L1.platform.x"``, ``"L2.link_length"``, ``"q3"``; ``kind``: "actuator",
    "anchor", "link", "axis", "spherical_clearance", "universal_clearance"; ``leg``: leg
    index (-1 for actuators, which are indexed by ``index``); ``group``: id shared by the three
    coordinates of one clearance ball (-1 for box sources)."""

    names: tuple
    kind: tuple
    leg: tuple
    index: tuple
    group: tuple

    def __len__(self):
        return len(self.names)


def _base_joint(leg):
    for c in leg.joints:
        if c != "P":
            return c
    return ""


def error_sources(mech) -> ErrorSources:
    """Every scalar error source of ``mech`` (actuators, leg geometry, joint clearances)."""
    names, kind, legi, idx, group = [], [], [], [], []
    g = 0
    for i, a in enumerate(mech.actuators):
        names.append(a), kind.append("actuator"), legi.append(-1), idx.append(i), group.append(-1)
    for li, leg in enumerate(mech.legs):
        for end in ("base", "platform"):
            for c, ax in enumerate("xyz"):
                names.append(f"{leg.name}.{end}.{ax}"), kind.append("anchor"), legi.append(li)
                idx.append((end, c)), group.append(-1)
        if hasattr(leg, "link_length"):
            names.append(f"{leg.name}.link_length"), kind.append("link"), legi.append(li)
            idx.append(("link_length", 0)), group.append(-1)
        for f in _AXIS_FIELDS:
            if hasattr(leg, f):
                # A PRS revolute axis stays normal to its slider: one tilt about the slider axis
                # (its other tilt is a tilt of the slider-revolute assembly, under slider_axis).
                for c in ((0,) if _coupled_axes(leg) and f == "r_axis" else (0, 1)):
                    names.append(f"{leg.name}.{f}.tilt{c + 1}"), kind.append("axis"), legi.append(li)
                    idx.append((f, c)), group.append(-1)
        for end, letter in (("base", _base_joint(leg)), ("platform", leg.joints[-1])):
            if letter in ("S", "U"):
                k = "spherical_clearance" if letter == "S" else "universal_clearance"
                for c, ax in enumerate("xyz"):
                    names.append(f"{leg.name}.{letter}_{end}.gap_{ax}"), kind.append(k), legi.append(li)
                    idx.append((end, c)), group.append(g)
                g += 1
    return ErrorSources(tuple(names), tuple(kind), tuple(legi), tuple(idx), tuple(group))


def _cross3(a, b):
    # one pair of 3-vectors: np.cross costs ten times more at this size (draws of robust measures)
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _unit3(a):
    return a / math.sqrt(float(a @ a))


def _rot3(k, ang):
    """Rodrigues rotation matrix about the unit 3-vector ``k`` by ``ang`` (as ``rot_axis``)."""
    x, y, z = float(k[0]), float(k[1]), float(k[2])
    c, s = math.cos(ang), math.sin(ang)
    C = 1.0 - c
    return np.array([[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
                     [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
                     [z * x * C - y * s, z * y * C + x * s, c + z * z * C]])


def _tilt_basis(a):
    a = _unit3(np.asarray(a, dtype=float))
    helper = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 1.0, 0])
    b1 = _unit3(_cross3(a, helper))
    return b1, _cross3(a, b1)


def _coupled_axes(leg) -> bool:
    """A leg whose revolute axis is carried normal to its slider axis (PRS)."""
    return hasattr(leg, "slider_axis") and hasattr(leg, "r_axis")


def _tilt(a, c, delta):
    """Rotation matrix tilting the unit axis ``a`` by ``delta`` towards ``_tilt_basis(a)[c]``."""
    b = _tilt_basis(a)[c]
    return _rot3(_unit3(_cross3(np.asarray(a, dtype=float), b)), float(delta))


def _leg_changes(leg, items) -> dict:
    """New field values of ``leg`` for the errors ``items`` [(index, delta), ...] (anchor
    coordinates and link lengths added, axis tilts applied one after the other, each about
    the nominal axis' tilt basis; a PRS slider tilt turns its revolute axis with it)."""
    kw = {}
    for (what, c), delta in items:
        if what in ("base", "platform"):
            v = kw.setdefault(what, np.array(getattr(leg, what), dtype=float))
            v[c] += delta
        elif what == "link_length":
            kw[what] = kw.get(what, float(leg.link_length)) + delta
        else:
            a0 = _unit3(np.array(getattr(leg, what), dtype=float))
            if what == "r_axis" and _coupled_axes(leg):
                Q = _rot3(_unit3(np.array(kw.get("slider_axis", leg.slider_axis), dtype=float)), float(delta))
            else:
                Q = _tilt(a0, c, delta)
            kw[what] = Q @ kw.get(what, a0)
            if what == "slider_axis" and _coupled_axes(leg):
                kw["r_axis"] = Q @ kw.get("r_axis", _unit3(np.array(leg.r_axis, dtype=float)))
    return kw


def _leg_changes_batch(legs, items) -> dict:
    """:func:`_leg_changes` for ``k`` draws at once: ``legs`` the draws' nominal copies of one
    leg (k legs of one type, e.g. ``[leg] * k``), ``items`` [(index, deltas (k,)), ...]; the new
    field values stacked over the draws ((k, 3) vectors, (k,) link lengths), each draw's row
    the value :func:`_leg_changes` gives for that draw's leg and deltas (a zero delta changes
    nothing there either: a zero tilt is the identity)."""
    kw = {}
    leg = legs[0]
    same = all(g is leg for g in legs)

    def nominal(f, unit=False):
        if same:
            v = np.array(getattr(leg, f), dtype=float)
            v = np.tile(v, (len(legs), 1)) if v.ndim else np.full(len(legs), float(v))
        else:
            v = np.array([np.asarray(getattr(g, f), dtype=float) for g in legs])
        return v / np.linalg.norm(v, axis=-1, keepdims=True) if unit else v

    def current(f, unit=False):
        v = kw.get(f)
        return nominal(f, unit) if v is None else v

    for (what, c), deltas in items:
        deltas = np.asarray(deltas, dtype=float)
        if what in ("base", "platform"):
            v = kw.setdefault(what, current(what))
            v[:, c] += deltas
        elif what == "link_length":
            kw[what] = current(what) + deltas
        else:
            if what == "r_axis" and _coupled_axes(leg):
                Q = rot_axis(current("slider_axis", unit=True), deltas)
            else:  # about a0 x b_c, (b_1, b_2) the tilt basis of the nominal axis a0
                a0 = nominal(what, unit=True)
                helper = np.where((np.abs(a0[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
                b = np.cross(a0, helper)
                b /= np.linalg.norm(b, axis=-1, keepdims=True)
                if c == 1:
                    b = np.cross(a0, b)
                Q = rot_axis(np.cross(a0, b), deltas)
            kw[what] = np.einsum("kij,kj->ki", Q, current(what, unit=True))
            if what == "slider_axis" and _coupled_axes(leg):
                kw["r_axis"] = np.einsum("kij,kj->ki", Q, current("r_axis", unit=True))
    return kw


def _perturb_leg(leg, idx, delta):
    return dataclasses.replace(leg, **_leg_changes(leg, [(idx, delta)]))


def _steps(mech):
    return 1e-6 * mech.length_scale, 1e-6


def _pose_jacobian(mech, p, R):
    """G_t = dh/dt (N, m, 6) by central differences."""
    hl, ha = _steps(mech)
    N = p.shape[0]
    cols = []
    for k in range(6):
        t = np.zeros((N, 6))
        h = hl if k < 3 else ha
        t[:, k] = h
        hp = closure_residuals(mech, *_compose(p, R, t))
        hm = closure_residuals(mech, *_compose(p, R, -t))
        cols.append((hp - hm) / (2 * h))
    return np.stack(cols, axis=-1)


def _source_jacobian(mech, p, R, src: ErrorSources):
    """G_e = dh/de (N, m, n_sources); actuator columns are zero (they enter the right side)."""
    hl, ha = _steps(mech)
    N = p.shape[0]
    m = sum(_rows_per_leg(mech))
    G = np.zeros((N, m, len(src)))
    offsets = np.concatenate([[0], np.cumsum(_rows_per_leg(mech))])
    for j, (k, li, idx) in enumerate(zip(src.kind, src.leg, src.index)):
        if k == "actuator":
            continue
        leg = mech.legs[li]
        h = ha if k == "axis" else hl
        rp = _leg_residual(_perturb_leg(leg, idx, h), p, R)
        rm = _leg_residual(_perturb_leg(leg, idx, -h), p, R)
        G[:, offsets[li]:offsets[li + 1], j] = (rp - rm) / (2 * h)
    return G


def _pinv_rank6(Gt, mech, rtol=1e-8):
    """``G_t^+`` (N, 6, m) on the dimensionally homogeneous form of ``G_t`` (rotations and
    length rows scaled by the model's length scale); inf where its 6th singular value is below
    ``rtol`` times the largest (a singular pose: the finite differences resolve about 1e-10)."""
    N, m = Gt.shape[:2]
    if m < 6:
        raise ValueError(f"{mech.name}: {m} closure equations cannot fix the 6 pose coordinates "
                         f"(under-actuated mechanism: an uncontrolled freedom has no defined pose error)")
    L = mech.length_scale
    dc = np.array([1.0, 1.0, 1.0, 1.0 / L, 1.0 / L, 1.0 / L])
    dr = np.where(_length_rows(mech), 1.0 / L, 1.0)
    ok = np.all(np.isfinite(Gt), axis=(1, 2))
    Gs = np.where(ok[:, None, None], Gt, 0.0) * dr[None, :, None] * dc[None, None, :]
    s = np.linalg.svd(Gs, compute_uv=False)
    sing = s[:, 5] <= rtol * np.maximum(s[:, 0], 1e-300)
    Gi = np.full((N, 6, m), np.nan)
    good = ok & ~sing
    if good.any():
        Gi[good] = dc[None, :, None] * np.linalg.pinv(Gs[good]) * dr[None, None, :]
    Gi[ok & sing] = np.inf
    return Gi


def _length_rows(mech):
    """(m,) bool: closure rows in metres (actuators, plane offsets); the others are angles."""
    rows = []
    for leg in mech.legs:
        if leg.is_actuated:
            rows.append(leg.actuator_kind != "angle")  # a crank angle is an angle
        rows += [kind == "length" for kind in leg.constraint_rows]
    return np.array(rows, bool)


def sensitivity(mech, X):
    """Sensitivity matrices ``S`` (N, 6, n_sources) of the pose error twist ``(dp, dtheta)`` to
    every error source of :func:`error_sources` at poses ``X`` (N, n_task), and the sources.
    Rows at unreachable poses are NaN, at singular poses inf."""
    Xa, _ = mech._poses(X)
    p, R = mech.pose(Xa)
    src = error_sources(mech)
    Gt = _pose_jacobian(mech, p, R)
    Gi = _pinv_rank6(Gt, mech)
    Ge = _source_jacobian(mech, p, R, src)
    act_rows = np.flatnonzero(_actuated_row_mask(mech))
    for j, (k, i) in enumerate(zip(src.kind, src.index)):
        if k == "actuator":
            Ge[:, act_rows[i], j] = -1.0
    sing = np.any(np.isinf(Gi), axis=(1, 2))
    with np.errstate(invalid="ignore"):
        S = -np.einsum("nim,nmj->nij", np.where(sing[:, None, None], 0.0, Gi), Ge)
    S[sing] = np.inf
    reach = mech.inverse_kinematics(Xa).reachable
    S[~reach] = np.nan
    return S, src


def _tolerance_vector(src: ErrorSources, tol: dict) -> np.ndarray:
    key = {"actuator": "actuator_tolerance", "anchor": "anchor_tolerance", "link": "link_tolerance",
           "axis": "axis_tolerance", "spherical_clearance": "spherical_clearance",
           "universal_clearance": "universal_clearance"}
    return np.array([tol[key[k]] for k in src.kind])


def pose_error_bound(mech, X, **tolerances) -> np.ndarray:
    """First-order worst-case bound ``b`` (N, 6) on ``|dp_k|`` (m) and ``|dtheta_k|`` (rad) for
    every admissible error (see the module docstring). Tolerances in SI (m, rad)."""
    tol = _check_tolerances(tolerances)
    S, src = sensitivity(mech, X)
    return _bound(S, src, tol)


def _bound(S, src, tol):
    tv = _tolerance_vector(src, tol)
    grp = np.array(src.group)
    box = (grp < 0) & (tv > 0)  # sources without a tolerance are left out (no inf * 0 at singular poses)
    b = np.einsum("nij,j->ni", np.abs(S[..., box]), tv[box])
    for g in np.unique(grp[(grp >= 0) & (tv > 0)]):
        cols = np.flatnonzero(grp == g)
        b = b + tv[cols[0]] * np.linalg.norm(S[..., cols], axis=-1)
    return b


def pose_error_covariance(mech, X, **tolerances) -> np.ndarray:
    """First-order covariance (N, 6, 6) of ``(dp, dtheta)`` for errors uniform in the tolerance
    box (variance tol^2/3) and clearance balls (c^2/5 per coordinate)."""
    tol = _check_tolerances(tolerances)
    S, src = sensitivity(mech, X)
    return _covariance(S, src, tol)


def _covariance(S, src, tol):
    tv = _tolerance_vector(src, tol)
    var = np.where(np.array(src.group) < 0, tv ** 2 / 3.0, tv ** 2 / 5.0)
    on = var > 0
    return np.einsum("nij,j,nkj->nik", S[..., on], var[on], S[..., on])


def _sample_errors(src: ErrorSources, tol: dict, M: int, rng) -> np.ndarray:
    tv = _tolerance_vector(src, tol)
    grp = np.array(src.group)
    e = rng.uniform(-1.0, 1.0, size=(M, len(src))) * tv
    for g in np.unique(grp[grp >= 0]):
        cols = np.flatnonzero(grp == g)
        d = rng.normal(size=(M, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        r = tv[cols[0]] * rng.uniform(0.0, 1.0, size=M) ** (1.0 / 3.0)
        e[:, cols] = d * r[:, None]
    return e


def _perturbed_legs(mech, src, e):
    """Copies of the legs with the errors ``e`` applied (one ``dataclasses.replace`` per leg)."""
    items = {}
    for j, (k, li, idx) in enumerate(zip(src.kind, src.leg, src.index)):
        if k != "actuator" and e[j] != 0.0:
            items.setdefault(li, []).append((idx, e[j]))
    legs = list(mech.legs)
    for li, it in items.items():
        legs[li] = dataclasses.replace(legs[li], **_leg_changes(legs[li], it))
    return legs


def pose_error_monte_carlo(mech, X, samples: int = 200, seed: int = 0, max_iter: int = 20,
                           errors=None, **tolerances):
    """Monte Carlo pose errors: ``(t, e)`` with ``t`` (samples, N, 6) the exact pose error twists
    (m, rad) solving the perturbed closure equations and ``e`` (samples, n_sources) the sampled
    errors (uniform in the tolerance box and the clearance balls; or the given ``errors``)."""
    tol = _check_tolerances(tolerances)
    Xa, _ = mech._poses(X)
    p, R = mech.pose(Xa)
    src = error_sources(mech)
    Gi = _pinv_rank6(_pose_jacobian(mech, p, R), mech)
    h0 = closure_residuals(mech, p, R)
    rng = np.random.default_rng(seed)
    E = np.asarray(errors, dtype=float) if errors is not None else _sample_errors(src, tol, int(samples), rng)
    act_rows = np.flatnonzero(_actuated_row_mask(mech))
    act_idx = [i for k, i in zip(src.kind, src.index) if k == "actuator"]
    act_cols = [j for j, k in enumerate(src.kind) if k == "actuator"]
    scale = np.where(_length_rows(mech), mech.length_scale, 1.0)
    out = np.full((E.shape[0], Xa.shape[0], 6), np.nan)
    for s in range(E.shape[0]):
        legs = _perturbed_legs(mech, src, E[s])
        target = h0.copy()
        target[:, act_rows[act_idx]] += E[s, act_cols]
        t = np.zeros((Xa.shape[0], 6))
        for _ in range(max_iter):
            r = closure_residuals(mech, *_compose(p, R, t), legs=legs) - target
            with np.errstate(invalid="ignore"):
                t = t - np.einsum("nim,nm->ni", Gi, r)
            if np.all(~np.isfinite(r) | (np.abs(r) <= 1e-14 * scale)):
                break
        out[s] = t
    return out, E


def actuator_pose_error(mech, X, dq) -> np.ndarray:
    """First-order pose error twists (N, 6) for actuator errors ``dq`` (N, n_act) or (n_act,)
    (m), from the closure sensitivity (equal to ``twist_map @ J^{-1} dq`` for a square
    actuator Jacobian)."""
    S, src = sensitivity(mech, X)
    cols = [j for j, k in enumerate(src.kind) if k == "actuator"]
    dq = np.broadcast_to(np.asarray(dq, dtype=float), (S.shape[0], len(cols)))
    return np.einsum("nij,nj->ni", S[..., cols], dq)


# -- design-parameter sensitivity and ranking -----------------------------------------------------
def _param_elements(mech):
    """(field, index path, kind, value) for every scalar element of the length/angle
    parameters of ``mech.params``."""
    units = dict(getattr(type(mech.params), "UNITS", {}))
    out = []
    for f in dataclasses.fields(mech.params):
        kind = units.get(f.name)
        if kind not in ("length", "angle"):
            continue
        v = getattr(mech.params, f.name)
        if isinstance(v, bool) or v is None:
            continue
        a = np.asarray(v, dtype=float) if not isinstance(v, str) else None
        if a is None:
            continue
        for ix in np.ndindex(a.shape):
            out.append((f.name, ix, kind, a))
    return out


def _with_element(mech, name, ix, arr, delta):
    a = np.array(arr, dtype=float)
    a[ix] += delta
    if a.ndim == 0:
        val = float(a)
    elif a.ndim == 1:
        val = tuple(float(x) for x in a)
    else:
        val = tuple(tuple(float(x) for x in row) for row in a)
    return mech.with_params(**{name: val})


def _pose_twist_diff(p1, R1, p0, R0):
    """Small twist (dp, dtheta) from pose 0 to pose 1."""
    dR = R1 @ np.swapaxes(R0, -1, -2)
    w = 0.5 * np.stack([dR[..., 2, 1] - dR[..., 1, 2], dR[..., 0, 2] - dR[..., 2, 0],
                        dR[..., 1, 0] - dR[..., 0, 1]], -1)
    return np.concatenate([p1 - p0, w], -1)


def parameter_sensitivity(mech, X):
    """Sensitivity (N, 6, n) of the pose error twist to every scalar element of the mechanism's
    design parameters with a length or angle unit (``dataclasses.fields(mech.params)``, e.g.
    ``link_length``, ``slider_radius``, ``hinge_points[2][0]``), the actuators held at their
    nominal values; and the element names. A design parameter is one value shared by every leg
    it describes (a common, systematic error); limits and diameters have zero sensitivity.

    First order, by central differences: ``dX = -J^{-1} dIK/dpi`` at fixed actuators, then
    ``t = T dX + dpose/dpi``. Needs a square actuator Jacobian (``ValueError`` otherwise)."""
    Xa, _ = mech._poses(X)
    if mech.n_actuators != mech.n_task:
        raise ValueError(f"{mech.name}: parameter_sensitivity needs as many actuators as task coordinates "
                         f"({mech.n_actuators} vs {mech.n_task})")
    J = mech.jacobian(Xa)
    T = mech.twist_map(Xa)
    Ji = np.linalg.inv(np.where(np.isfinite(J), J, 0.0))
    p0, R0 = mech.pose(Xa)
    hl, ha = _steps(mech)
    cols, names = [], []
    for name, ix, kind, arr in _param_elements(mech):
        h = hl if kind == "length" else ha
        res = []
        for sgn in (1, -1):
            m2 = _with_element(mech, name, ix, arr, sgn * h)
            q2 = m2.inverse_kinematics(Xa).actuators
            p2, R2 = m2.pose(Xa)
            res.append((q2, _pose_twist_diff(p2, R2, p0, R0)))
        dq = (res[0][0] - res[1][0]) / (2 * h)
        dpose = (res[0][1] - res[1][1]) / (2 * h)
        dX = -np.einsum("nij,nj->ni", Ji, dq)
        cols.append(np.einsum("nij,nj->ni", T, dX) + dpose)
        names.append(name + "".join(f"[{i}]" for i in ix))
    return np.stack(cols, axis=-1), names


def sensitivity_ranking(mech, X, level: str = "sources", quantile: float = 1.0, **tolerances) -> list[dict]:
    """Which dimension drives the pose error most: a list of ``{"name", "kind", "position",
    "orientation"}`` sorted by decreasing ``position`` (m), the worst-case first-order position
    error (norm of the component bounds) caused by that group alone, at the ``quantile`` over
    the poses ``X`` (default the largest).

    ``level="sources"``: the error sources of :func:`error_sources` grouped by kind (actuators,
    base anchors, platform anchors, link lengths, joint axes, S and U clearances), with the given
    tolerances; ``level="parameters"``: each design parameter of ``mech.params`` with a length or
    angle unit (all its elements), with ``anchor_tolerance`` for lengths and ``axis_tolerance``
    for angles (see :func:`parameter_sensitivity`)."""
    tol = _check_tolerances(tolerances)
    groups = {}
    if level == "sources":
        S, src = sensitivity(mech, X)
        tv = _tolerance_vector(src, tol)
        for j, (k, idx) in enumerate(zip(src.kind, src.index)):
            label = (f"{idx[0]} anchors" if k == "anchor" else
                     {"axis": "joint axes", "link": "link lengths", "actuator": "actuators"}.get(k, k))
            groups.setdefault(label, ([], k))[0].append(j)
        rows = []
        for label, (cols, k) in groups.items():
            sub = ErrorSources(*(tuple(getattr(src, f)[c] for c in cols) for f in
                                 ("names", "kind", "leg", "index", "group")))
            b = _bound(S[..., cols], sub, tol)
            rows.append(_rank_row(label, k, b, quantile, tv[cols]))
    elif level == "parameters":
        S, names = parameter_sensitivity(mech, X)
        kinds = {e[0]: e[2] for e in _param_elements(mech)}
        for j, nm in enumerate(names):
            groups.setdefault(nm.split("[")[0], []).append(j)
        rows = []
        for field, cols in groups.items():
            t = tol["anchor_tolerance"] if kinds[field] == "length" else tol["axis_tolerance"]
            b = np.einsum("nij->ni", np.abs(S[..., cols])) * t
            rows.append(_rank_row(field, kinds[field], b, quantile, np.array([t])))
    else:
        raise ValueError(f"level must be 'sources' or 'parameters', got {level!r}")
    rows.sort(key=lambda r: -r["position"] if np.isfinite(r["position"]) else -np.inf)
    return rows


def _rank_row(label, kind, b, quantile, tv):
    pe = np.linalg.norm(b[:, :3], axis=-1)
    oe = np.linalg.norm(b[:, 3:], axis=-1)
    pe, oe = pe[np.isfinite(pe)], oe[np.isfinite(oe)]
    return {"name": label, "kind": kind,
            "position": float(np.quantile(pe, quantile)) if pe.size and np.any(tv > 0) else 0.0,
            "orientation": float(np.quantile(oe, quantile)) if oe.size and np.any(tv > 0) else 0.0}
