"""Cartesian stiffness of a parallel mechanism from its wrench system.

The platform is held by the unit wrenches of ``mech.wrench_matrix``: the actuation wrench of
every actuated leg (a force along the leg line) and the constraint wrenches of the legs that
constrain (RPS, RPU, UPU, PRS). Each row ``w_j`` is carried by a spring of stiffness ``k_j``
(N/m for a force, N m/rad for a couple) whose deformation is the leg's own displacement along
that wrench, ``w_j . t`` for a small platform twist ``t = (dp, dtheta)``. The restoring wrench
is ``sum_j k_j w_j (w_j . t)``, so the Cartesian stiffness matrix is::

    K = W^T diag(k) W            (6 x 6, twist (v_P, omega) -> wrench (f, m_P) about P)

(Gosselin 1990 for the actuated legs; the constraint wrenches of lower-mobility limbs as in
Pashkevich, Chablat & Wenger's VJM model reduced to one spring per reciprocal wrench, so that a
lower-mobility mechanism gets a full 6 x 6 matrix). Legs are massless, joints ideal (no
clearance, rigid bearings); the matrix is that of the unloaded pose: the geometric stiffening or
softening of a preloaded mechanism (the term in the derivative of W under load) is neglected.

Where the values come from, per value and per leg (first that applies):

1. an explicit setting (a keyword of :func:`stiffness_matrix`, a measure setting of a study):
   ``axial_stiffness``, ``actuator_stiffness``, ``constraint_force_stiffness``,
   ``constraint_couple_stiffness``; for the estimate ``diameter``, ``constraint_diameter``,
   ``youngs_modulus``, ``shear_modulus``;
2. the value the mechanism description declares for the leg in its ``stiffness:`` section
   (keys ``axial``, ``actuator``, ``constraint_force``, ``constraint_couple``, and for the
   estimate ``diameter``, ``youngs_modulus``, ``shear_modulus``; usually parameters with units
   such as ``leg_stiffness: 2e7 N/m``, so that they can be study design variables), available
   as ``mech.declared_stiffness`` ({leg name: {key: SI value}});
3. the geometric estimate below (rod diameter: the model parameter ``leg_diameter`` or
   ``link_diameter``; steel moduli); the drive: rigid.

An estimate input given by a setting or the description (e.g. ``diameter``) only matters for
the values that neither a setting nor the description gives.

The geometric estimate is that of a solid steel rod of the leg's diameter ``d`` and its length
``L`` at the pose (base joint centre to platform joint centre)::

    axial (actuated legs, along the leg line):   k = E A / L,         A = pi d^2 / 4
    constraint force, lateral to the leg:        k = 3 E I / L^3,     I = pi d^4 / 64
                                  (a cantilever clamped at the base joint, force at the tip)
    constraint couple, bending the leg:          k = E I / L
    constraint couple about the leg axis:        k = G J / L,         J = pi d^4 / 32

A force or couple at an angle to the leg combines the two compliances by the squared direction
cosines. E = 210 GPa and G = 80.8 GPa (structural steel, nu = 0.3). An actuator drive
(``actuator_stiffness``, the screw or slider's own stiffness along its coordinate, default
rigid) acts in series with the leg: the line compliance is ``1/k_leg + s^2/k_actuator`` with
``s`` the leg's transmission factor (1 for telescopic legs, ``n . e`` for a slider leg).

Policy for singular matrices (an uncontrolled freedom, e.g. the under-actuated 4-UPS/1-RPS, or a
pose near a singularity): eigenvalues of the dimensionally homogeneous matrix (moments divided by
the model's length scale) below ``rtol`` times the largest count as zero. A load that does work on
such a freedom is not carried: its deflection is ``inf`` and the stiffness along it is ``0``. A
load that does no work on it is carried elastically and gets finite values from the
pseudo-inverse. Unreachable poses give NaN.
"""

from __future__ import annotations

import math

import numpy as np

from ..common.units import parse_quantity
from ..model.legs import require

__all__ = [
    "STEEL_E",
    "STEEL_G",
    "stiffness_matrix",
    "compliance",
    "deflection",
    "point_deflection",
    "stiffness_along",
    "part_stiffness",
    "STIFFNESS_SETTINGS",
]

#: Young's modulus of structural steel (Pa), the default material of the legs.
STEEL_E = 210e9
#: Shear modulus of structural steel (Pa): E / (2 (1 + nu)) with nu = 0.3.
STEEL_G = STEEL_E / (2 * 1.3)

#: Settings of :func:`stiffness_matrix` and their quantity kinds (for study files).
STIFFNESS_SETTINGS = {
    "axial_stiffness": "stiffness",
    "actuator_stiffness": "stiffness",
    "constraint_force_stiffness": "stiffness",
    "constraint_couple_stiffness": "rotational_stiffness",
    "diameter": "length",
    "constraint_diameter": "length",
    "youngs_modulus": "pressure",
    "shear_modulus": "pressure",
}

#: Relative eigenvalue threshold below which a stiffness matrix counts as singular.
RTOL = 1e-9


def _positive(name, value, allow_inf=False):
    if isinstance(value, str):  # a quantity with its unit, e.g. "2e7 N/m"
        value = parse_quantity(value, STIFFNESS_SETTINGS.get(name.split("[")[0], "dimensionless"), field=name)
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number (SI), got {value!r}") from None
    if not (v > 0) or math.isnan(v) or (math.isinf(v) and not allow_inf):
        allowed = "a positive value (inf allowed: rigid)" if allow_inf else "a finite positive value"
        raise ValueError(f"{name} must be {allowed}, got {value!r}")
    return v


def _per_row(name, value, n, allow_inf=False):
    """A scalar or a sequence of ``n`` positive values -> array (n,) (None passes)."""
    if value is None:
        return None
    if np.ndim(value) == 0:
        return np.full(n, _positive(name, value, allow_inf))
    vals = list(value)
    if len(vals) != n:
        raise ValueError(f"{name} must be one value or {n} values (one per row), got {len(vals)}")
    return np.array([_positive(f"{name}[{i}]", v, allow_inf) for i, v in enumerate(vals)])


def _model_diameter(mech):
    for f in ("leg_diameter", "link_diameter"):
        v = getattr(mech.params, f, None)
        if v is not None and float(v) > 0:
            return float(v)
    return None


def _declared(mech) -> dict:
    """{leg name: {key: SI value}} of the description's ``stiffness:`` section (empty if none)."""
    return getattr(mech, "declared_stiffness", None) or {}


def _row_stiffness(mech, states, p, stiff):
    """Per-row spring stiffness (N, k) in the row order of ``mech.wrench_matrix``.

    Per value: the keyword ``stiff[...]`` if given, else the description's declared value for
    the leg, else the geometric estimate (whose rod diameter and moduli follow the same order)."""
    decl = _declared(mech)
    E_kw = _positive("youngs_modulus", stiff["youngs_modulus"]) if stiff.get("youngs_modulus") is not None else None
    G_kw = _positive("shear_modulus", stiff["shear_modulus"]) if stiff.get("shear_modulus") is not None else None
    d_kw = _positive("diameter", stiff["diameter"]) if stiff.get("diameter") is not None else None
    dc_kw = (_positive("constraint_diameter", stiff["constraint_diameter"])
             if stiff.get("constraint_diameter") is not None else None)
    d_model = _model_diameter(mech)

    def material(leg):
        dl = decl.get(leg.name, {})
        E = E_kw if E_kw is not None else dl.get("youngs_modulus", STEEL_E)
        G = G_kw if G_kw is not None else dl.get("shear_modulus", STEEL_G)
        d = d_kw if d_kw is not None else dl.get("diameter", d_model)
        return E, G, d

    legs = mech.legs
    act_legs = [(leg, st) for leg, st in zip(legs, states) if leg.is_actuated]
    na = len(act_legs)
    k_ax = _per_row("axial_stiffness", stiff.get("axial_stiffness"), na)
    k_dr = _per_row("actuator_stiffness", stiff.get("actuator_stiffness"), na, allow_inf=True)
    N = p.shape[0]
    cols = []
    for i, (leg, st) in enumerate(act_legs):
        L = st.length
        dl = decl.get(leg.name, {})
        if k_ax is not None:
            kl = np.full(N, k_ax[i])
        elif "axial" in dl:
            kl = np.full(N, dl["axial"])
        else:
            E, _, d = material(leg)
            if d is None:
                raise ValueError(
                    f"{mech.name}: no leg diameter to estimate the axial stiffness of leg {leg.name} from (the model "
                    f"has no leg_diameter/link_diameter parameter and its description no stiffness for the leg); "
                    f"give axial_stiffness (N/m) or diameter (m)")
            kl = E * (math.pi * d * d / 4) / L
        kd = k_dr[i] if k_dr is not None else dl.get("actuator", math.inf)
        _, s = leg.actuation_wrench(st, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            comp = 1.0 / kl + (s * s) / kd
        cols.append(1.0 / comp)
    # Constraint rows.
    crow = []  # (leg, state, wrench rows (N, c, 6))
    for leg, st in zip(legs, states):
        C = leg.constraint_wrenches(st, p)
        if C.shape[1]:
            crow.append((leg, st, C))
    kf_user = stiff.get("constraint_force_stiffness")
    kc_user = stiff.get("constraint_couple_stiffness")
    all_rows = [(leg, st, C[:, j]) for leg, st, C in crow for j in range(C.shape[1])]
    kf = _per_row("constraint_force_stiffness", kf_user, len(all_rows)) if kf_user is not None else None
    kc = _per_row("constraint_couple_stiffness", kc_user, len(all_rows)) if kc_user is not None else None
    for j, (leg, st, w) in enumerate(all_rows):
        L = st.length
        n = st.direction
        dl = decl.get(leg.name, {})
        kf_j = kf[j] if kf is not None else dl.get("constraint_force")
        kc_j = kc[j] if kc is not None else dl.get("constraint_couple")
        E, G, d = material(leg)
        dc = dc_kw if dc_kw is not None else d
        f, m = w[:, :3], w[:, 3:]
        fn = np.linalg.norm(f, axis=-1)
        is_force = fn > 1e-12
        need_default = (kf_j is None and np.any(is_force)) or (kc_j is None and np.any(~is_force))
        if need_default and dc is None:
            raise ValueError(
                f"{mech.name}: no leg diameter to estimate the stiffness of leg {leg.name}'s constraint wrench from; "
                f"give constraint_force_stiffness (N/m), constraint_couple_stiffness (N*m/rad) or diameter (m)")
        comp_f = comp_m = np.full(N, np.nan)
        if need_default:
            A = math.pi * dc * dc / 4
            I = math.pi * dc ** 4 / 64
            J = 2 * I
            with np.errstate(divide="ignore", invalid="ignore"):
                cf = np.sum(unit_rows(f) * n, -1) ** 2
                comp_f = cf * L / (E * A) + (1 - cf) * L ** 3 / (3 * E * I)
                cm = np.sum(unit_rows(m) * n, -1) ** 2
                comp_m = cm * L / (G * J) + (1 - cm) * L / (E * I)
        kforce = np.full(N, kf_j) if kf_j is not None else 1.0 / comp_f
        kcouple = np.full(N, kc_j) if kc_j is not None else 1.0 / comp_m
        cols.append(np.where(is_force, kforce, kcouple))
    return np.stack(cols, axis=1) if cols else np.zeros((N, 0))


def unit_rows(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(n > 0, v / np.where(n > 0, n, 1.0), 0.0)


def stiffness_matrix(mech, X, **stiffness) -> np.ndarray:
    """Cartesian stiffness matrices (N, 6, 6) of ``mech`` at poses ``X`` (or (6, 6) for one pose).

    In the twist/wrench convention of ``mech.wrench_matrix``: ``K @ (v_P, omega)`` is the wrench
    ``(f, m_P)`` (N, N m about the platform point P, base frame) that holds a small displacement
    (m, rad); blocks ``K[:3, :3]`` in N/m, ``K[3:, 3:]`` in N m/rad, off-diagonal in N. SI units.
    ``K = W^T diag(k) W`` over the actuation rows and the constraint rows of ``W``.

    Settings (SI; all optional, defaults from the leg geometry, see the module docstring):
    ``axial_stiffness`` (N/m; one value or one per actuated leg) along the leg lines,
    ``actuator_stiffness`` (N/m, default inf: rigid drive) in series along the actuator
    coordinate, ``constraint_force_stiffness`` (N/m) and ``constraint_couple_stiffness``
    (N m/rad; one value or one per constraint row), ``diameter`` and ``constraint_diameter``
    (m, the steel rod of the estimates; default the model's ``leg_diameter`` or
    ``link_diameter``), ``youngs_modulus`` and ``shear_modulus`` (Pa). A setting given here
    beats the value the description declares for a leg (``stiffness:`` section,
    ``mech.declared_stiffness``), which beats the geometric estimate. Values may also be
    strings with their unit (``"2e7 N/m"``, ``"300 N*m/rad"``, ``"35 mm"``, ``"210 GPa"``). Zero,
    negative or non-finite values raise ``ValueError`` naming the setting. Unreachable poses
    give NaN.
    """
    unknown = sorted(set(stiffness) - set(STIFFNESS_SETTINGS))
    if unknown:
        raise ValueError(f"stiffness_matrix: unknown setting(s) {unknown}; allowed: {', '.join(STIFFNESS_SETTINGS)}")
    for leg in mech.legs:
        require(leg, "stiffness")
    Xa, single = mech._poses(X)
    _, states, p = mech.leg_states(Xa)
    W = mech.wrench_matrix(Xa)
    k = _row_stiffness(mech, states, p, stiffness)
    ok = np.all(np.isfinite(W), axis=(1, 2)) & np.all(np.isfinite(k), axis=1)
    Ws = np.where(ok[:, None, None], W, 0.0)
    ks = np.where(ok[:, None], k, 0.0)
    K = np.einsum("nki,nk,nkj->nij", Ws, ks, Ws)
    K = 0.5 * (K + np.swapaxes(K, 1, 2))
    K[~ok] = np.nan
    return K[0] if single else K


def _scale(L):
    return np.array([1.0, 1.0, 1.0, 1.0 / L, 1.0 / L, 1.0 / L])


def compliance(K, length_scale: float, rtol: float = RTOL):
    """Pseudo-inverse compliance of stiffness matrices ``K`` (N, 6, 6) and their null twists.

    Works on the homogeneous matrix ``S K S`` (``S = diag(1, 1, 1, 1/L, 1/L, 1/L)``);
    eigenvalues below ``rtol`` times the largest count as zero. Returns ``(C, Z)``: ``C``
    (N, 6, 6) maps a wrench to a twist on the carried subspace, ``Z`` (N, 6, 6) the orthogonal
    projector (in the scaled space) onto the null space (zero when K is regular). NaN rows stay
    NaN."""
    K = np.asarray(K, dtype=float)
    single = K.ndim == 2
    K = K[None] if single else K
    S = _scale(float(length_scale))
    ok = np.all(np.isfinite(K), axis=(1, 2))
    Ks = np.where(ok[:, None, None], K, 0.0) * S[None, :, None] * S[None, None, :]
    lam, V = np.linalg.eigh(Ks)
    lmax = np.maximum(lam[:, -1:], 1e-300)
    regular = lam > rtol * lmax
    inv = np.where(regular, 1.0 / np.where(regular, lam, 1.0), 0.0)
    Cs = np.einsum("nik,nk,njk->nij", V, inv, V)
    Zs = np.einsum("nik,nk,njk->nij", V, (~regular).astype(float), V)
    C = Cs * S[None, :, None] * S[None, None, :]
    C[~ok] = np.nan
    Zs[~ok] = np.nan
    return (C[0], Zs[0]) if single else (C, Zs)


def _unbalanced(Z, w, L, tol=1e-7):
    """(N,) bool: the wrench ``w`` (N, 6) does work on a null twist of K (relative size > tol)."""
    ws = w * _scale(L)
    proj = np.einsum("nij,nj->ni", Z, ws)
    return np.linalg.norm(proj, axis=-1) > tol * np.maximum(np.linalg.norm(ws, axis=-1), 1e-300)


def deflection(mech, X, wrench, **stiffness) -> np.ndarray:
    """Small displacement twist (N, 6) ``(dp, dtheta)`` of the platform (m, rad; ``dp`` of P)
    under an external wrench ``(f, m_P)`` (6,) or (N, 6) on it: ``K t = w``. Rows are ``inf``
    where the wrench does work on a freedom the mechanism does not stiffen (a singular K), NaN
    where the pose is unreachable."""
    Xa, single = mech._poses(X)
    K = stiffness_matrix(mech, Xa, **stiffness)
    w = np.broadcast_to(np.asarray(wrench, dtype=float), (Xa.shape[0], 6))
    C, Z = compliance(K, mech.length_scale)
    t = np.einsum("nij,nj->ni", C, w)
    bad = _unbalanced(Z, w, mech.length_scale)
    t[bad] = np.inf
    return t[0] if single else t


def _check_point(mech, point):
    r = np.asarray(point if point is not None else (0.0, 0.0, 0.0), dtype=float)
    if r.shape != (3,) or not np.all(np.isfinite(r)):
        raise ValueError(f"point must be 3 finite coordinates (m, platform frame), got {point!r}")
    reach = 10 * mech.length_scale
    if np.linalg.norm(r) > reach:
        raise ValueError(
            f"point {r.tolist()} m is {np.linalg.norm(r):.3g} m from the platform reference point, more than 10 "
            f"length scales ({reach:.3g} m) of {mech.name}: outside the platform frame's reach (units? give m)")
    return r


def _check_direction(direction, name="direction"):
    d = np.asarray(direction, dtype=float)
    if d.shape != (3,) or not np.all(np.isfinite(d)):
        raise ValueError(f"{name} must be 3 finite components, got {direction!r}")
    n = np.linalg.norm(d)
    if n < 1e-12:
        raise ValueError(f"{name} must be a non-zero vector, got {direction!r}")
    return d / n


def point_deflection(mech, X, force=(0.0, 0.0, 0.0), moment=(0.0, 0.0, 0.0), point=(0.0, 0.0, 0.0),
                     **stiffness) -> np.ndarray:
    """Displacement (N, 3) (m, base frame) of the platform point ``point`` (platform frame, m)
    under a force ``force`` (N, base frame) applied at that point and a couple ``moment``
    (N m, base frame). ``inf`` where the load is not carried (see the module docstring)."""
    Xa, single = mech._poses(X)
    r = _check_point(mech, point)
    _, R = mech.pose(Xa)
    rb = R @ r
    f = np.broadcast_to(np.asarray(force, dtype=float), (Xa.shape[0], 3))
    m = np.broadcast_to(np.asarray(moment, dtype=float), (Xa.shape[0], 3))
    w = np.concatenate([f, np.cross(rb, f) + m], axis=-1)
    t = deflection(mech, Xa, w, **stiffness)
    with np.errstate(invalid="ignore"):
        u = t[:, :3] + np.cross(t[:, 3:], rb)
    u[np.any(np.isinf(t), axis=1)] = np.inf
    return u[0] if single else u


def stiffness_along(mech, X, direction=(0.0, 0.0, 1.0), point=(0.0, 0.0, 0.0), frame: str = "base",
                    **stiffness) -> np.ndarray:
    """Stiffness (N, ) (N/m) of the platform point ``point`` (platform frame, m) along
    ``direction`` (``frame`` "base" or "platform"): the force along the direction divided by the
    displacement of the point along it, ``1 / (w^T C w)`` for the unit wrench ``w`` of that
    force. 0 where such a force is not carried (singular K), NaN where unreachable."""
    if frame not in ("base", "platform"):
        raise ValueError(f"frame must be 'base' or 'platform', got {frame!r}")
    Xa, single = mech._poses(X)
    d = _check_direction(direction)
    r = _check_point(mech, point)
    _, R = mech.pose(Xa)
    rb = R @ r
    db = R @ d if frame == "platform" else np.broadcast_to(d, rb.shape)
    w = np.concatenate([db, np.cross(rb, db)], axis=-1)
    K = stiffness_matrix(mech, Xa, **stiffness)
    C, Z = compliance(K, mech.length_scale)
    c = np.einsum("ni,nij,nj->n", w, C, w)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = 1.0 / c
    k[_unbalanced(Z, w, mech.length_scale)] = 0.0
    k[~np.isfinite(c)] = np.nan
    return k[0] if single else k


def part_stiffness(mech, X, part: str = "translational", **stiffness) -> np.ndarray:
    """Smallest translational (N/m) or rotational (N m/rad) stiffness at poses ``X`` (N,).

    Translational: the smallest ratio of a pure force at P to the displacement of P along it,
    the rotations left free: ``1 / lambda_max(C_tt)`` with ``C_tt`` the force-to-translation
    block of the compliance. Rotational: ``1 / lambda_max(C_rr)`` for pure couples. 0 where some
    force (couple) does work on a freedom K does not stiffen; NaN where unreachable."""
    if part not in ("translational", "rotational"):
        raise ValueError(f"part must be 'translational' or 'rotational', got {part!r}")
    Xa, single = mech._poses(X)
    K = stiffness_matrix(mech, Xa, **stiffness)
    C, Z = compliance(K, mech.length_scale)
    sl = slice(0, 3) if part == "translational" else slice(3, 6)
    ok = np.all(np.isfinite(C), axis=(1, 2))
    Cb = np.where(ok[:, None, None], C[:, sl, sl], 0.0)
    lam = np.linalg.eigvalsh(Cb)[:, -1]
    with np.errstate(divide="ignore"):
        k = np.where(lam > 0, 1.0 / np.where(lam > 0, lam, 1.0), 0.0)
    # A null twist of K with a component in this part means some pure force/couple is not carried.
    Zb = np.where(ok[:, None, None], Z[:, sl, sl], 0.0)
    k[np.linalg.norm(Zb, axis=(1, 2)) > 1e-7] = 0.0
    k[~ok] = np.nan
    return k[0] if single else k
