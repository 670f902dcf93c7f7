"""Rotations, Euler conventions, twists and wrenches, vectorised over poses.

Conventions used everywhere in parasynth
----------------------------------------
* Frames: the base frame is fixed; every vector returned by the library is expressed in it.
* A **twist** of the platform is ``t = (v_P, omega)``: the velocity of the platform reference
  point ``P`` and the angular velocity, both in the base frame (shape ``(..., 6)``).
* A **wrench** is ``w = (f, m_P)``: a force and its moment about the same point ``P``.
  With this ordering the power of a wrench on a twist is the plain dot product ``w @ t``,
  which is the reciprocal product of screw theory (2021 paper, eq. (3)): a wrench is
  reciprocal to a twist (does no work on it) when ``w @ t == 0``.
* Angles are radians; lengths are metres.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "R_NAMES",
    "rot_x",
    "rot_y",
    "rot_z",
    "cross",
    "rot_axis",
    "euler_to_matrix",
    "euler_rate_map",
    "EULER_CONVENTIONS",
    "skew",
    "unit",
    "revolute_twist",
    "prismatic_twist",
    "force_wrench",
    "couple_wrench",
    "reciprocal_basis",
    "canonical_wrenches",
    "null_space",
    "null_direction",
    "segment_distance",
]

#: Names of the rotation-matrix entries R11 .. R33 (row-major), as task parametrisations and
#: expressions use them: one definition for the descriptions and the engine.
R_NAMES = tuple(f"R{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))


def _as_angle_array(a) -> np.ndarray:
    return np.asarray(a, dtype=float)


def _rot(a, i: int, j: int) -> np.ndarray:
    """Rotation matrices ``a.shape + (3, 3)`` about the axis other than ``i`` and ``j`` (i < j),
    written entry by entry (not stacked: a few vectors cost a fifth as much)."""
    a = _as_angle_array(a)
    c, s = np.cos(a), np.sin(a)
    M = np.zeros(a.shape + (3, 3), dtype=c.dtype)
    k = 3 - i - j
    M[..., k, k] = 1.0
    M[..., i, i] = c
    M[..., j, j] = c
    M[..., i, j] = -s
    M[..., j, i] = s
    return M


def rot_x(a) -> np.ndarray:
    """Rotation matrices about the x axis, shape ``a.shape + (3, 3)``."""
    return _rot(a, 1, 2)


def rot_y(a) -> np.ndarray:
    """Rotation matrices about the y axis, shape ``a.shape + (3, 3)``."""
    return _rot(a, 2, 0)


def rot_z(a) -> np.ndarray:
    """Rotation matrices about the z axis, shape ``a.shape + (3, 3)``."""
    return _rot(a, 0, 1)


def cross(a, b) -> np.ndarray:
    """``np.cross(a, b)`` of float 3-vectors along the last axis (broadcast): the same products
    and differences in the same order, so the same bits, without np.cross's axis handling (a
    fifth of its time on a few vectors)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype=float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out


_ROT = {"x": rot_x, "y": rot_y, "z": rot_z}
_AXIS = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}


def rot_axis(axis: np.ndarray, angle) -> np.ndarray:
    """Rodrigues rotation about unit ``axis`` (shape (3,) or (..., 3)) by ``angle``."""
    axis = unit(np.asarray(axis, dtype=float))
    angle = _as_angle_array(angle)[..., None, None]
    K = skew(axis)
    eye = np.eye(3)
    return eye + np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K)


#: Named Euler conventions. Each is a sequence of rotation axes; the matrix is the product
#: ``R = R_a1(q1) @ R_a2(q2) @ R_a3(q3)`` (rotations about the current, moving axes), so the
#: angle order of the tuple is the order of the letters.
#:
#: * ``"zyz"``  -- grinding robot (2022 paper), eq. (2): ``R = Rz(alpha) Ry(beta) Rz(gamma)``.
#: * ``"yzx"``  -- 2T2R paper (2018), eq. (1): its "x-z-y" rotation composes to
#:   ``R = Ry(theta) Rz(phi) Rx(psi)`` (checked entry by entry against eq. (1)); angles
#:   are given in the order (theta, phi, psi).
#: * ``"yx"``   -- 5-DOF paper (2021), eq. (7) with gamma = 0: ``R = Ry(beta) Rx(alpha)``;
#:   angles in the order (beta, alpha).
#: * ``"yxy"``  -- the 5-PUS/UPU model's limb-consistent form of eq. (7) (see its docstring).
#: * ``"xyz"``, ``"zyx"``, ``"zxz"`` -- the usual sequences, for user models.
EULER_CONVENTIONS = {
    "zyz": "zyz",
    "yzx": "yzx",
    "yx": "yx",
    "xyz": "xyz",
    "zyx": "zyx",
    "zxz": "zxz",
    "yxy": "yxy",
}


def _sequence(convention: str, angles, check_count: bool = True):
    """The axis sequence of a named Euler convention and the angles as a float array; a one-line
    error for an unknown convention or (``check_count``) a wrong number of angles."""
    seq = EULER_CONVENTIONS.get(convention)
    if seq is None:
        raise ValueError(
            f"unknown Euler convention {convention!r}; allowed: {sorted(EULER_CONVENTIONS)}"
        )
    angles = np.asarray(angles, dtype=float)
    if check_count and angles.shape[-1] != len(seq):
        raise ValueError(
            f"convention {convention!r} takes {len(seq)} angles, got shape {angles.shape}"
        )
    return seq, angles


def euler_to_matrix(convention: str, angles) -> np.ndarray:
    """Rotation matrices for ``angles`` (shape (..., k)) in a named convention."""
    seq, angles = _sequence(convention, angles)
    R = _ROT[seq[0]](angles[..., 0])
    for k, ax in enumerate(seq[1:], start=1):
        R = R @ _ROT[ax](angles[..., k])
    return R


def euler_rate_map(convention: str, angles) -> np.ndarray:
    """Matrix ``E`` with ``omega = E @ angle_rates`` (base frame), shape (..., 3, k).

    For ``R = R1(q1) R2(q2) R3(q3)`` the angular velocity is
    ``omega = e1 q1' + R1 e2 q2' + R1 R2 e3 q3'``.
    """
    seq, angles = _sequence(convention, angles, check_count=False)
    cols = []
    R = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3))
    for k, ax in enumerate(seq):
        cols.append(R @ _AXIS[ax])
        R = R @ _ROT[ax](angles[..., k])
    return np.stack(cols, axis=-1)


def euler_matrix_and_rate(convention: str, angles, rate: bool = True):
    """``(euler_to_matrix(convention, angles), euler_rate_map(convention, angles))`` -- the
    same operations on the same per-axis rotations, each computed once (the rate map is None
    with ``rate=False``)."""
    seq, angles = _sequence(convention, angles)
    mats = [_ROT[ax](angles[..., k]) for k, ax in enumerate(seq)]
    R = mats[0]
    for M in mats[1:]:
        R = R @ M
    if not rate:
        return R, None
    cols = []
    Q = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3))
    for ax, M in zip(seq, mats):
        cols.append(Q @ _AXIS[ax])
        Q = Q @ M
    return R, np.stack(cols, axis=-1)


def skew(v) -> np.ndarray:
    """Skew-symmetric cross-product matrices, ``skew(a) @ b == cross(a, b)``."""
    v = np.asarray(v, dtype=float)
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack(
        [np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2
    )


def unit(v, axis: int = -1) -> np.ndarray:
    """Normalise vectors along ``axis``; zero vectors stay zero (no NaN)."""
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v, axis=axis, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def revolute_twist(axis, point, ref) -> np.ndarray:
    """Unit twist of a rotation about ``axis`` through ``point``, taken at ``ref``: (v_ref, w)."""
    axis = np.asarray(axis, dtype=float)
    v = cross(axis, np.asarray(ref, dtype=float) - np.asarray(point, dtype=float))
    return np.concatenate(np.broadcast_arrays(v, axis), axis=-1)


def prismatic_twist(direction) -> np.ndarray:
    """Unit twist of a translation along ``direction``: (d, 0)."""
    d = np.asarray(direction, dtype=float)
    return np.concatenate([d, np.zeros_like(d)], axis=-1)


def force_wrench(direction, point, ref) -> np.ndarray:
    """Wrench of a unit force along ``direction`` acting on the line through ``point``,
    expressed at ``ref``: (f, (point - ref) x f)."""
    f = np.asarray(direction, dtype=float)
    m = cross(np.asarray(point, dtype=float) - np.asarray(ref, dtype=float), f)
    return np.concatenate(np.broadcast_arrays(f, m), axis=-1)


def couple_wrench(direction) -> np.ndarray:
    """Wrench of a unit couple about ``direction``: (0, n)."""
    n = np.asarray(direction, dtype=float)
    return np.concatenate([np.zeros_like(n), n], axis=-1)


def null_space(A: np.ndarray, rtol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Batched null space of ``A`` (shape (N, m, 6)).

    Returns ``(basis, rank)`` where ``basis`` has shape (N, 6, 6): the right singular vectors
    ordered from the largest singular value to the smallest, and ``rank`` (N,) the numerical
    rank. Rows ``basis[i, rank[i]:]`` span the null space of ``A[i]``.
    """
    A = np.asarray(A, dtype=float)
    N, m, n = A.shape
    if m < n:
        A = np.concatenate([A, np.zeros((N, n - m, n))], axis=1)
    _, s, Vt = np.linalg.svd(A)
    scale = np.maximum(s[:, :1], 1e-300)
    rank = np.sum(s > rtol * scale, axis=1)
    return Vt, rank


def null_direction(A: np.ndarray) -> np.ndarray:
    """A unit vector (N, 6) orthogonal to the five rows of each ``A`` (N, 5, 6): the last column
    of the complete QR factorisation of ``A^T`` (a quarter of the time of the SVD in
    :func:`null_space` for these sizes). Where ``A`` has rank five it spans the null space, to
    rounding, as the SVD's last right singular vector does (up to sign: neither sign is
    meaningful); where the rank is lower it is one direction of the null space; NaN rows give
    NaN."""
    A = np.asarray(A, dtype=float)
    Q, _ = np.linalg.qr(np.swapaxes(A, -1, -2), mode="complete")
    return Q[..., -1]


def reciprocal_basis(twists: np.ndarray, length: float, rtol: float = 1e-9) -> list[np.ndarray]:
    """Wrenches reciprocal to every twist in ``twists`` (shape (N, k, 6)), per pose.

    The moment part is scaled by ``length`` before the SVD so that forces and couples are
    compared in the same units. Returns a list (one entry per pose) of arrays (c_i, 6) of
    canonical wrenches (see :func:`canonical_wrenches`).
    """
    twists = np.asarray(twists, dtype=float)
    # A wrench w = (f, m) is reciprocal to t = (v, w_ang) when f.v + m.w_ang = 0. With
    # m = m_s * L and the twist angular part scaled the same way, the problem is a plain
    # orthogonal complement in a dimensionally homogeneous space.
    scaled = twists.copy()
    scaled[..., 3:] *= length
    Vt, rank = null_space(scaled, rtol)
    out = []
    for i in range(twists.shape[0]):
        basis = Vt[i, rank[i]:].copy()
        basis[:, 3:] *= length  # back to (f, m) in SI
        out.append(canonical_wrenches(basis, length))
    return out


def canonical_wrenches(basis: np.ndarray, length: float, tol: float = 1e-9) -> np.ndarray:
    """A physically readable basis of a wrench subspace.

    Pure couples (wrenches with zero force) are separated first and returned as unit
    couples; the remaining directions are returned as unit forces whose moments are
    orthogonal to the couple subspace (so a duplicate of the same line is not split).
    """
    basis = np.atleast_2d(np.asarray(basis, dtype=float))
    if basis.size == 0:
        return np.zeros((0, 6))
    F = basis[:, :3]
    # Combinations c with c @ F == 0 are pure couples.
    _, s, Vt = np.linalg.svd(F.T)  # F.T: (3, c)
    c = basis.shape[0]
    s_full = np.zeros(c)
    s_full[: s.size] = s
    smax = max(np.max(np.linalg.norm(basis, axis=1)), 1e-300)
    couple_mask = s_full <= tol * smax
    couples = Vt[couple_mask] @ basis
    forces = Vt[~couple_mask] @ basis
    rows = []
    if couples.shape[0]:
        cq, _ = np.linalg.qr(couples[:, 3:].T)
        for k in range(couples.shape[0]):
            rows.append(np.concatenate([np.zeros(3), cq[:, k]]))
    couple_dirs = np.array([r[3:] for r in rows]) if rows else np.zeros((0, 3))
    if forces.shape[0]:
        # Remove couple components from the force wrenches' moments, then orthonormalise the
        # force parts and rescale to unit force.
        if couple_dirs.shape[0]:
            forces[:, 3:] -= (forces[:, 3:] @ couple_dirs.T) @ couple_dirs
        q, r = np.linalg.qr(forces[:, :3].T)
        # Express the forces in the orthonormal force basis: forces = R^T Q^T ...
        coeff = np.linalg.solve(r.T, np.eye(r.shape[0]))  # (k, k)
        fw = coeff @ forces
        for k in range(fw.shape[0]):
            n = np.linalg.norm(fw[k, :3])
            rows.append(fw[k] / n)
    return np.array(rows)


def segment_distance(p1, q1, p2, q2) -> np.ndarray:
    """Minimum distance between segments [p1, q1] and [p2, q2], vectorised over leading axes.

    Closest points of two segments (Ericson, *Real-Time Collision Detection*, 5.1.9), with
    the degenerate cases (segments of zero length, parallel segments) handled as there.
    """
    p1, q1, p2, q2 = (np.asarray(a, dtype=float) for a in (p1, q1, p2, q2))
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.sum(d1 * d1, -1)
    e = np.sum(d2 * d2, -1)
    f = np.sum(d2 * r, -1)
    c = np.sum(d1 * r, -1)
    b = np.sum(d1 * d2, -1)
    eps = 1e-300
    a_pt, e_pt = a <= eps, e <= eps
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        # General case: s from the infinite lines (0 when parallel), then t, then clamp.
        s = np.where(denom > 1e-12 * np.maximum(a * e, eps), np.clip((b * f - c * e) / denom, 0, 1), 0.0)
        t = np.where(e_pt, 0.0, (b * s + f) / e)
        s = np.where(~e_pt & (t < 0), np.where(a_pt, 0.0, np.clip(-c / a, 0, 1)), s)
        s = np.where(~e_pt & (t > 1), np.where(a_pt, 0.0, np.clip((b - c) / a, 0, 1)), s)
        t = np.clip(t, 0, 1)
        # Second segment a point: closest point of the first to it.
        s = np.where(e_pt & ~a_pt, np.clip(-c / a, 0, 1), s)
        # First segment a point: closest point of the second to it.
        t = np.where(a_pt & ~e_pt, np.clip(f / e, 0, 1), t)
        s = np.where(a_pt, 0.0, s)
        t = np.where(a_pt & e_pt, 0.0, t)
    c1 = p1 + s[..., None] * d1
    c2 = p2 + t[..., None] * d2
    d = np.linalg.norm(c1 - c2, axis=-1)
    # For (nearly) parallel segments the closest pair involves an endpoint: the distances of
    # the four endpoints to the other segment bound the minimum exactly there.
    ends = np.minimum(np.minimum(_point_segment(p1, p2, d2, e), _point_segment(q1, p2, d2, e)),
                      np.minimum(_point_segment(p2, p1, d1, a), _point_segment(q2, p1, d1, a)))
    return np.minimum(d, ends)


def _point_segment(x, p, d, dd) -> np.ndarray:
    """Distance from points ``x`` to segments ``p + u d`` (u in [0, 1]), ``dd = d . d``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(dd > 1e-300, np.clip(np.sum((x - p) * d, -1) / dd, 0, 1), 0.0)
    return np.linalg.norm(x - p - u[..., None] * d, axis=-1)


def dot_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products (N,) of ``a`` (N, 3) with ``b`` (3,) or (N, 3)."""
    b = np.asarray(b)
    return a @ b if b.ndim == 1 else np.einsum("ij,ij->i", a, b)


def rotate_rows(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R @ v`` per row: R (N, 3, 3) applied to ``v`` (3,) or to the rows of ``v`` (N, 3)."""
    v = np.asarray(v)
    return R @ v if v.ndim == 1 else np.einsum("nij,nj->ni", R, v)

