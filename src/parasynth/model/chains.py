"""Limbs defined by their joint string: a serial chain of R, P, U and S joints with the actuated
joint marked and the relations of its axes, solved by a numerical inverse kinematics, from a
closed form where the limb's geometry has one (the NumPy reference; docs/structures.md, "Limbs
from joint strings").

A limb is written as its joints from base to platform, the actuated joint followed by ``*``
(``"RP*UR"``: revolute, actuated prismatic, universal, revolute), or as the plain string with the
index of the actuated joint (``parse_chain("RPUR", actuated=1)``); ``actuated=None`` with no
marker is a passive limb only when ``passive=True`` is said. The axes of its freedoms, in chain
order (R: one axis; P: its direction; U: two axes, the second normal to the first; S: none, its
three freedoms are free), are given by *relations*:

* ``"parallel:REF"`` or just ``"REF"``: the axis is parallel to REF;
* ``"normal:REF"``: the axis is normal to REF; an axis normal to two references is along their
  cross product; an axis normal to one reference only is also taken normal to the limb's line
  (the usual cross axis of a universal joint), or, if REF is along the limb, normal to the base
  normal;

with REF one of ``prev`` (the previous rotational axis of the chain: of an R or U joint, not a
prismatic direction), ``axisK`` (the chain's axis number K, counted from 0, an earlier one),
``base_normal`` (the base's z axis),
``radial`` and ``tangent`` (of the limb's base anchor on its circle), ``limb`` (the line from
the base anchor to the platform anchor at the home pose) and the fixed axes ``x``, ``y``, ``z``.
Several relations of one axis are joined with ``&`` (``"normal:prev&normal:limb"``). Relations
that contradict each other (parallel and normal to the same reference, parallel to two
references that are never parallel, ...) are refused with one line naming the axis.

Geometry (an assumption, stated here and as parameters): at the home pose the joint centres of
the rotational joints (R, U, S) lie on the line from the base anchor to the platform anchor, at
the fractions ``stations`` of its length (default: evenly spread from 0 to 1 over the rotational
joints; a prismatic joint has no centre, it moves everything after it along its direction), each
moved off that line by its entry of ``offsets`` (a fraction of the line's length, in [-1, 1],
default 0: the *elbow*), along the direction normal to the joint's first axis and to the line
(``axis x limb``; the base normal stands for a spherical joint's axis; the anchor's radial
direction where that cross product vanishes). Without an elbow, parallel revolute axes through
points of one line are a stretched planar chain, singular (the RRUR's three x axes, the RUU's
crank along its link). The chain's forward kinematics is the product of exponentials of its
joint twists from this home configuration; its inverse kinematics at a platform pose is a
Levenberg-Marquardt solve of the anchor frame's position and orientation over the joint
coordinates, started at the home configuration (the branch of the home pose), or at the
coordinates of a closed form where the chain's geometry has one (:func:`closed_form_constants`:
then no step is taken where they reach). A pose is
reachable when the solve's residual is below 1000 :data:`IK_TOL`; a limb of fewer than six
freedoms reaches only the poses its constraints allow. The actuator value is the actuated
joint's coordinate from home (a prismatic joint between two joint centres adds their home
distance, so that it reads as the limb's length).

Each universal or spherical joint has a cone angle, ``<letter><joint index>_cone``: the angle
between its link as the body after it carries it and as the body before it carries it (the link
to the next joint centre or to the platform anchor; for the joint at the platform anchor, the
link arriving from the previous centre or the base anchor), also named ``U_base_cone`` /
``S_base_cone`` for the joint at the base anchor and ``U_platform_cone`` / ``S_platform_cone``
for the one at the platform anchor -- the rule of the hand-written legs' cone angles.

Closure equations (:mod:`parasynth.model.parasitic`): a limb with ``c`` constraint wrenches at
its home pose states ``c`` equations, the error of the chain's least-squares reach of the
platform anchor frame (:meth:`ChainLeg.closure_solve`) on those home constraint directions
(:meth:`ChainLeg.closure_residuals`): zero exactly where the chain assembles, smooth near home.
Out of the limb's reach (a stretched chain) the error is positional and its projection may
vanish; such a pose is refused by the inverse kinematics, not by the closure.

The chain's constraint wrenches are the wrenches reciprocal to its joint twists at the solved
configuration (an SVD), so the mobility of a structure follows from them as for the hand-written
leg types. The engine solves chain limbs with compiled kernels of the same solves
(:mod:`parasynth.engine.chains`, from :meth:`ChainLeg.chain_arrays`): the inverse kinematics
for feasibility and constraint margins, the closure's least-squares reach (with the warm start
of :meth:`ChainLeg.closure_start`) for the structures' motion rule, and, from the solved
configuration, the joint twists, constraint wrenches and actuation wrench of the pose-wise index
kernels (:mod:`parasynth.engine.indices`); so a chain limb declares ``compiled=True``. Every
other capability but ``stiffness`` and ``passive`` is off, so the other parts refuse it by name
(:func:`parasynth.model.legs.require`).
"""

from __future__ import annotations

import functools

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .legs import JOINT_DOF, LEG_TYPES, Leg, LegCapabilities, LegState, _vec3
from .spatial import cross, null_space, unit

__all__ = ["ChainError", "ChainSpec", "ChainLeg", "parse_chain", "JOINT_LETTERS", "REFERENCES", "RELATIONS",
           "IK_TOL", "IK_ITERATIONS", "IK_STALL", "CLOSURE_ITERATIONS", "chain_class", "CLOSED_FORMS",
           "closed_form_constants", "closed_form_solve"]

#: The joint letters a joint string may hold, with their freedoms.
JOINT_LETTERS = {"R": "revolute", "P": "prismatic", "U": "universal", "S": "spherical"}
#: The references an axis relation may name.
REFERENCES = ("prev", "base_normal", "radial", "tangent", "limb", "x", "y", "z", "axisK")
#: The relations an axis may have to a reference.
RELATIONS = ("parallel", "normal")
#: Largest residual of a reached pose (position / length scale and orientation in rad).
IK_TOL = 1e-9
#: Gauss-Newton iterations of the inverse kinematics.
IK_ITERATIONS = 60
#: A pose of the inverse kinematics stops stalled after a taken step that lowered the squared
#: error by no more than this fraction of it (a least-squares minimum off the limb's reach,
#: approached linearly; MINPACK's ``ftol``). With Nielsen's damping, 1e-12 and 1e-6 told the
#: same poses reached over 82,000 poses of five chain limb types (42,000 reached), 1e-6 in a
#: fifth fewer trials; 1e-3 lost four.
IK_STALL = 1e-6
#: Gauss-Newton iterations of the least-squares reach of the closure equations.
CLOSURE_ITERATIONS = 40
#: The axes of each joint letter that take a relation (S: none).
_AXES_PER_JOINT = {"R": 1, "P": 1, "U": 2, "S": 0}
#: References always normal to each other (at every anchor), and always the same direction.
_ALWAYS_NORMAL = {frozenset(p) for p in (("radial", "tangent"), ("radial", "base_normal"), ("tangent", "base_normal"),
                                         ("x", "y"), ("y", "z"), ("x", "z"), ("radial", "z"), ("tangent", "z"))}
_SAME = {frozenset(("z", "base_normal"))}
_ALLOWED = (f"relations {', '.join(RELATIONS)} (written 'parallel:REF', 'normal:REF' or 'REF', joined with '&') "
            f"to REF in {', '.join(REFERENCES)}")


def damping_factor(gain, pred):
    """What the inverse kinematics' damping is multiplied by after a taken step (Nielsen's
    rule, H. B. Nielsen 1999, "Damping parameter in Marquardt's method"):
    ``max(1/3, 1 - (2 rho - 1)^3)``, ``rho`` the decrease of the squared error obtained over
    the decrease the linear model predicted (1 where it predicted none). A step as good as
    predicted divides the damping by three; a poor one keeps it or doubles it, so that a pose
    that needs a large damping (far from its limb's reach) keeps it instead of losing it after
    every taken step and climbing back through refused ones (the tenfold rule did: a fifth to two
    fifths of the trials of a pose out of reach were refused)."""
    gain = np.asarray(gain, dtype=float)
    pred = np.asarray(pred, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(pred > 0.0, gain / np.where(pred > 0.0, pred, 1.0), 1.0)
    return np.maximum(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)


#: The closed forms of a chain limb's inverse kinematics, by the code its constants start with
#: (:func:`closed_form_constants`).
CLOSED_FORMS = {1: "RRP-S", 2: "RR-UR", 3: "PR-UR", 4: "SP-U"}
#: Relative tolerance of the geometry a closed form assumes (normal axes, centres on a line).
CLOSED_FORM_TOL = 1e-9


def closed_form_constants(kinds, axes, points, home, L) -> np.ndarray:
    """The constants of the closed-form inverse kinematics of a chain given as data (per freedom
    its kind, 0 revolute or 1 prismatic, home axis and home point; the anchor at home; the length
    scale), or an empty array where its geometry has none (the numerical solve then works alone).
    The constants start with the form's code (:data:`CLOSED_FORMS`): ``"RRP-S"``
    (:func:`_rrps_constants`), ``"RR-UR"`` and ``"PR-UR"`` (:func:`_planar_constants`),
    ``"SP-U"`` (:func:`_spu_constants`). Each form gives the solution in the working mode of the
    home pose (:func:`closed_form_solve`)."""
    kinds = np.asarray(kinds)
    axes = np.asarray(axes, float)
    points = np.asarray(points, float)
    home = np.asarray(home, float)
    pattern = tuple(int(k) for k in kinds)
    if pattern == (0, 0, 1, 0, 0, 0):
        return _rrps_constants(axes, points, home, L)
    if pattern == (0, 0, 0, 1, 0, 0):
        return _spu_constants(axes, points, home, L)
    if len(pattern) == 5:
        return _planar_constants(kinds, axes, points, home, L)
    return np.zeros(0)


def _rrps_constants(axes, points, home, L) -> np.ndarray:
    """The constants of the form ``"RRP-S"`` (code 1), or an empty array: two revolutes, a slider
    and a spherical joint at the anchor (its three freedoms about x, y, z through the anchor), the
    first revolute's axis ``a1`` through ``A``, the second's ``a2`` normal to it and to the
    slider's direction ``u``, and the second revolute's centre and the anchor on the slider's line
    through ``A`` (the RRPS of the vocabulary; an elbow offset breaks it). The anchor ``w = target
    - A`` is then ``R1 (b u + rho R2 u)``: ``R1^T w`` is normal to ``a2``, which gives the first
    angle (two solutions, ``pi`` apart: the one of the home pose), the second angle and ``rho``
    (> 0, the home pose's side) follow in the plane normal to ``a2``, and the spherical joint's
    angles are the x-y-z angles of ``(R1 R2)^T R`` with the middle one within +-pi/2. Constants:
    the code, A, a1, a2, a1 x a2, u, the sign that puts the home pose at the first angle 0, ``b``
    (the second centre's distance from A along u) and the anchor's home distance from the second
    centre."""
    tol = CLOSED_FORM_TOL
    if not (_near(axes[3:], np.eye(3), tol) and _near(points[3:], home, tol * L)):
        return np.zeros(0)
    A, a1, B, a2, u = points[0], axes[0], points[1], axes[1], axes[2]
    c12 = cross(a1, a2)
    if abs(a1 @ a2) > tol or abs(a2 @ u) > tol or abs(u @ c12) < 1e-6:
        return np.zeros(0)
    if np.linalg.norm(cross(B - A, u)) > tol * L or np.linalg.norm(cross(home - B, u)) > tol * L:
        return np.zeros(0)
    k = -1.0 if u @ c12 > 0 else 1.0
    return np.concatenate([[1.0], A, a1, a2, c12, u, [k, (B - A) @ u, (home - B) @ u]])


def _free_arrays(free) -> tuple:
    """A chain's freedoms ``(kind, home axis, home point)`` as arrays: kinds (n,) int64 (0
    revolute, 1 prismatic), axes (n, 3), points (n, 3; zeros for a prismatic freedom)."""
    n = len(free)
    kinds = np.array([1 if k == "P" else 0 for k, _, _ in free], dtype=np.int64)
    axes = np.array([a for _, a, _ in free], dtype=float).reshape(n, 3)
    points = np.array([np.zeros(3) if c is None else c for _, _, c in free], dtype=float).reshape(n, 3)
    return kinds, axes, points


def _near(a, b, tol: float) -> bool:
    """Whether ``a`` and ``b`` differ by at most ``tol`` in every entry (``np.allclose`` with
    ``rtol=0`` for the few entries of a limb's geometry, a tenth of its time)."""
    return float(np.max(np.abs(np.asarray(a, float) - b))) <= tol


def _planar_constants(kinds, axes, points, home, L) -> np.ndarray:
    """The constants of the forms ``"RR-UR"`` (code 2) and ``"PR-UR"`` (code 3) (see
    :func:`closed_form_constants`), or an empty array: a revolute about ``a`` (or a slider along
    ``e`` normal to ``a``), a revolute about ``a``, a universal joint (``a``, then ``b`` normal to
    it) and a revolute about ``b`` at the anchor -- the RRUR and PRUR of the vocabulary. Then the
    rotations about ``a`` sum to the platform's angle ``phi`` about ``a`` and those about ``b`` to
    its angle ``psi`` about ``b`` (``R = Rot(a, phi) Rot(b, psi)``); the universal joint's
    centre keeps its component along ``a``, which gives its second angle ``t4`` (the home pose's
    side of ``b``), hence the centre ``c = target - Rot(a, phi) Rot(b, t4) v``; and the planar
    chain before it reaches ``c`` in the plane normal to ``a``: two links with the elbow on its
    home side, or the slider's root with the link pointing along the slider as at home. Constants:
    the code, a, b, a x b, the universal joint's home centre ``c0``, ``v = anchor - c0``, then the
    first revolute's centre and the elbow (RR) or the slider's direction and the revolute's
    centre (PR)."""
    tol = CLOSED_FORM_TOL
    if not all(k == 0 for k in kinds[1:]) or kinds[0] not in (0, 1):
        return np.zeros(0)
    a, b = axes[1], axes[3]
    if not (_near(axes[2], a, tol) and _near(axes[4], b, tol)
            and abs(a @ b) <= tol):
        return np.zeros(0)
    if (kinds[0] == 0 and not _near(axes[0], a, tol)) or (kinds[0] == 1 and abs(axes[0] @ a) > tol):
        return np.zeros(0)
    c0 = points[2]
    if not (_near(points[3], c0, tol * L) and _near(points[4], home, tol * L)):
        return np.zeros(0)
    n = cross(a, b)
    v = home - c0

    def flat(x):  # the length of a vector's part normal to a
        return float(np.hypot(x @ b, x @ n))

    first, second = (points[0], points[1]) if kinds[0] == 0 else (axes[0], points[1])
    links = [second - first, c0 - second] if kinds[0] == 0 else [c0 - second]
    if flat(v) < 1e-9 * L or any(flat(x) < 1e-9 * L for x in links):
        return np.zeros(0)
    return np.concatenate([[2.0 if kinds[0] == 0 else 3.0], a, b, n, c0, v, first, second])


def _spu_constants(axes, points, home, L) -> np.ndarray:
    """The constants of the form ``"SP-U"`` (code 4), or an empty array: a spherical joint at
    ``A`` (its freedoms about x, y, z), a slider along ``u`` from ``A`` through the anchor, a
    universal joint at the anchor (``t``, then ``n2`` normal to it and to ``u``) -- the SPU of the
    vocabulary. The anchor is ``A + rho Rs u`` (``Rs`` the spherical joint's rotation): ``rho =
    |target - A|`` (> 0, the home side) and ``Rs u`` its direction ``m``; the platform's rotation
    is ``Rs Rot(t, q4) Rot(n2, q5)``, so ``Rot(t, -q4) u = Rot(n2, q5) R^T m``: the components
    along ``t`` give ``q5`` (two roots: the one keeping the link on its home side of the plane of
    ``t`` and ``n2``), the rest ``q4``, and the spherical joint's angles are the x-y-z angles of
    ``R Rot(n2, -q5) Rot(t, -q4)``. Constants: the code, A, u, t, n2, t x n2, the anchor's home
    distance from A."""
    tol = CLOSED_FORM_TOL
    A, u, t, n2 = points[0], axes[3], axes[4], axes[5]
    if not (_near(axes[:3], np.eye(3), tol) and _near(points[1:3], A, tol * L)
            and _near(points[4:], home, tol * L)):
        return np.zeros(0)
    if abs(t @ n2) > tol or abs(u @ n2) > tol or np.linalg.norm(cross(t, u)) < 1e-6:
        return np.zeros(0)
    if np.linalg.norm(cross(home - A, u)) > tol * L or (home - A) @ u <= 0.0:
        return np.zeros(0)
    return np.concatenate([[4.0], A, u, t, n2, cross(t, n2), [(home - A) @ u]])


def _spu_solve(cf, target, R) -> np.ndarray:
    """:func:`closed_form_solve` of the form ``"SP-U"`` (N, 6); NaN rows for the poses without
    a solution in the home pose's working mode."""
    A, u, t, n2, f = (cf[1 + 3 * i:4 + 3 * i] for i in range(5))
    rho0 = cf[16]
    w = np.asarray(target, float) - A
    rho = np.linalg.norm(w, axis=1)
    m = w / rho[:, None]
    k = np.einsum("nji,nj->ni", R, m)  # R^T m
    kt, kf = k @ t, k @ f
    ut, uf = float(u @ t), float(u @ f)
    with np.errstate(invalid="ignore"):
        dl = np.arccos(ut / np.hypot(kt, kf))
    beta = np.arctan2(kf, kt)
    q5 = _wrap(beta - dl if uf >= 0.0 else beta + dl)
    v = np.einsum("nij,nj->ni", _rot_rows(n2, q5), k)
    up = u - ut * t  # the parts normal to t
    vp = v - (v @ t)[:, None] * t
    q4 = -np.arctan2(cross(up, vp) @ t, vp @ up)
    Rs = R @ _rot_rows(n2, -q5) @ _rot_rows(t, -q4)
    q0 = np.arctan2(-Rs[:, 1, 2], Rs[:, 2, 2])
    q1 = np.arctan2(Rs[:, 0, 2], np.hypot(Rs[:, 1, 2], Rs[:, 2, 2]))
    q2 = np.arctan2(-Rs[:, 0, 1], Rs[:, 0, 0])
    return np.stack([q0, q1, q2, rho - rho0, q4, q5], axis=1)


def _wrap(x):
    """Angles into [-pi, pi)."""
    return x - 2.0 * np.pi * np.floor((x + np.pi) / (2.0 * np.pi))


def _planar_solve(cf, target, R) -> np.ndarray:
    """:func:`closed_form_solve` of the forms ``"RR-UR"`` and ``"PR-UR"`` (N, 5); NaN rows for
    the poses without a solution in the home pose's working mode."""
    a, b, n, c0, v, f0, f1 = (cf[1 + 3 * i:4 + 3 * i] for i in range(7))
    t = np.asarray(target, float)
    Ra, Rb, Rn = R @ a, R @ b, R @ n  # R's columns in the frame (a, b, n): RF[i, j] = f_i . R f_j
    phi = np.arctan2(Rb @ n, Rb @ b)
    psi = np.arctan2(Rn @ a, Ra @ a)
    vx, vz = float(v @ a), float(v @ n)
    rv = math.hypot(vx, vz)
    h = (t - c0) @ a
    with np.errstate(invalid="ignore"):
        dl = np.arccos(h / rv)
    th4 = _wrap(math.atan2(vz, vx) - dl if vz >= 0.0 else math.atan2(vz, vx) + dl)
    w = np.einsum("nij,j->ni", _rot_rows(a, phi) @ _rot_rows(b, th4), v)
    c = t - w
    q = np.empty((t.shape[0], 5))
    if cf[0] == 2.0:  # two revolutes: A (f0), the elbow (f1)
        u1 = np.array([(f1 - f0) @ b, (f1 - f0) @ n])
        u2 = np.array([(c0 - f1) @ b, (c0 - f1) @ n])
        dd = np.stack([(c - f0) @ b, (c - f0) @ n], -1)
        m = 0.5 * (np.einsum("ni,ni->n", dd, dd) - u1 @ u1 - u2 @ u2)
        g0 = math.atan2(u1[0] * u2[1] - u1[1] * u2[0], u1 @ u2)
        with np.errstate(invalid="ignore"):
            ac = np.arccos(m / math.sqrt((u1 @ u1) * (u2 @ u2)))
        th2 = _wrap((ac if g0 >= 0.0 else -ac) - g0)
        sx = u1[0] + np.cos(th2) * u2[0] - np.sin(th2) * u2[1]
        sy = u1[1] + np.sin(th2) * u2[0] + np.cos(th2) * u2[1]
        th1 = np.arctan2(sx * dd[:, 1] - sy * dd[:, 0], sx * dd[:, 0] + sy * dd[:, 1])
        q[:, 0], q[:, 1], q[:, 2] = th1, th2, _wrap(phi - th1 - th2)
    else:  # a slider along e (f0), the revolute's centre (f1)
        u2 = np.array([(c0 - f1) @ b, (c0 - f1) @ n])
        e2 = np.array([f0 @ b, f0 @ n])
        g = np.stack([(c - f1) @ b, (c - f1) @ n], -1)
        ge = g @ e2
        with np.errstate(invalid="ignore"):
            sq = np.sqrt(ge * ge - np.einsum("ni,ni->n", g, g) + u2 @ u2)
        s = ge - sq if u2 @ e2 >= 0.0 else ge + sq
        rx, ry = g[:, 0] - s * e2[0], g[:, 1] - s * e2[1]
        th1 = np.arctan2(u2[0] * ry - u2[1] * rx, u2[0] * rx + u2[1] * ry)
        q[:, 0], q[:, 1], q[:, 2] = s, th1, _wrap(phi - th1)
    q[:, 3], q[:, 4] = th4, _wrap(psi - th4)
    return q


def _rot_rows(a, t) -> np.ndarray:
    """Rotations (N, 3, 3) through the angles ``t`` (N,) about the unit axis ``a`` (Rodrigues)."""
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    t = np.asarray(t, float)[:, None, None]
    return np.eye(3) + np.sin(t) * K + (1.0 - np.cos(t)) * (K @ K)


def closed_form_solve(cf, target, R) -> np.ndarray:
    """Joint coordinates (N, n) of the closed form with constants ``cf``
    (:func:`closed_form_constants`) reaching the anchor positions ``target`` (N, 3) with the
    platform orientations ``R`` (N, 3, 3), in the working mode of the home pose; NaN rows where
    it has no solution there (the pose is out of the limb's reach in that mode)."""
    return {1.0: _rrps_solve, 4.0: _spu_solve}.get(float(cf[0]), _planar_solve)(cf, target, R)


def _rrps_solve(cf, target, R) -> np.ndarray:
    """:func:`closed_form_solve` of the form ``"RRP-S"`` (N, 6): every finite pose has a solution."""
    A, a1, a2, c12, u = cf[1:4], cf[4:7], cf[7:10], cf[10:13], cf[13:16]
    k, b, rho0 = cf[16], cf[17], cf[18]
    w = np.asarray(target, float) - A
    th1 = np.arctan2(k * (w @ a2), -k * (w @ c12))
    R1 = _rot_rows(a1, th1)
    r = np.einsum("nji,nj->ni", R1, w) - b * u
    th2 = np.arctan2(cross(u, r) @ a2, r @ u)
    M = np.einsum("nji,njk->nik", _rot_rows(a2, th2), np.einsum("nji,njk->nik", R1, R))
    q3 = np.arctan2(-M[:, 1, 2], M[:, 2, 2])
    q4 = np.arctan2(M[:, 0, 2], np.hypot(M[:, 1, 2], M[:, 2, 2]))
    q5 = np.arctan2(-M[:, 0, 1], M[:, 0, 0])
    return np.stack([th1, th2, np.linalg.norm(r, axis=1) - rho0, q3, q4, q5], axis=1)


@functools.lru_cache(maxsize=256)
def _parsed(chain, axes, stations, offsets, passive: bool) -> ChainSpec:
    """:func:`parse_chain` of hashable arguments (tuples or None), kept: a ``ChainSpec`` is frozen,
    and a study builds the same limbs for every design (a ``ChainError`` is raised each time)."""
    return parse_chain(chain, axes=None if axes is None else list(axes), passive=passive,
                       stations=None if stations is None else list(stations),
                       offsets=None if offsets is None else list(offsets))


class ChainError(ValueError):
    """A joint string, an actuated joint or axis relations that are not allowed; the message
    says what is wrong and what is allowed."""


def _fmt(x) -> str:
    return repr(x) if isinstance(x, str) else f"{x!r} ({type(x).__name__})"


@dataclass(frozen=True)
class ChainSpec:
    """A parsed limb: ``joints`` (the letters, base to platform), ``actuated`` (index of the
    actuated joint, None for a passive limb), ``relations`` (per axis of the chain, a tuple of
    (relation, reference) pairs), ``stations`` (home fractions of the rotational joints'
    centres along the limb, None: evenly spread), ``kinds`` (the joint letter of each axis) and
    ``offsets`` (home offsets of the rotational joints' centres off the anchor line, fractions
    of its length, None: all on the line)."""

    joints: str
    actuated: int | None
    relations: tuple
    stations: tuple | None = None
    kinds: tuple = ()
    offsets: tuple | None = None

    @property
    def name(self) -> str:
        """The joint string with the actuated joint marked (``RP*UR``)."""
        return "".join(j + ("*" if i == self.actuated else "") for i, j in enumerate(self.joints))

    @property
    def n_dof(self) -> int:
        return sum(JOINT_DOF[j] for j in self.joints)

    @property
    def n_axes(self) -> int:
        return sum(_AXES_PER_JOINT[j] for j in self.joints)


def _parse_relation(raw, where: str) -> tuple:
    if not isinstance(raw, str) or not raw.strip():
        raise ChainError(f"{where}: expected a relation string, got {_fmt(raw)}; allowed: {_ALLOWED}")
    out = []
    for part in raw.split("&"):
        part = part.strip()
        rel, _, ref = part.partition(":") if ":" in part else ("parallel", "", part)
        rel, ref = rel.strip(), ref.strip()
        if rel not in RELATIONS:
            raise ChainError(f"{where}: unknown relation {rel!r} in {raw!r}; allowed: {_ALLOWED}")
        if ref not in REFERENCES[:-1] and not (ref.startswith("axis") and ref[4:].isdigit()):
            raise ChainError(f"{where}: unknown reference {ref!r} in {raw!r}; allowed: {_ALLOWED}")
        out.append((rel, ref))
    return tuple(out)


def _check_symbolic(rels: tuple, where: str) -> None:
    """Contradictions that hold at every anchor and pose."""
    par = [r for k, r in rels if k == "parallel"]
    nor = [r for k, r in rels if k == "normal"]
    for r in par:
        if r in nor:
            raise ChainError(f"{where}: parallel and normal to {r!r} at once contradict each other; an axis is "
                             f"either parallel or normal to a reference ({_ALLOWED})")
    for a in par:
        for b in par:
            if a != b and frozenset((a, b)) in _ALWAYS_NORMAL:
                raise ChainError(f"{where}: parallel to {a!r} and to {b!r} contradict each other (they are normal); "
                                 f"give one parallel reference ({_ALLOWED})")
        for b in nor:
            if frozenset((a, b)) in _SAME:
                raise ChainError(f"{where}: parallel to {a!r} and normal to {b!r} contradict each other (the same "
                                 f"direction); {_ALLOWED}")


def parse_chain(spec, actuated=None, axes=None, *, passive: bool = False, stations=None, offsets=None) -> ChainSpec:
    """Parse a limb: ``spec`` its joint string (``"RP*UR"``, or ``"RPUR"`` with ``actuated``, the
    index of the actuated joint), ``axes`` the relations of its axes in chain order (a list of
    strings, one per axis: R and P one each, U two, S none; None: the defaults, first rotational
    axis ``tangent``, a prismatic joint ``limb``, every later rotational axis ``parallel:prev``
    except a universal joint's second axis ``normal:prev``), ``passive`` True for a limb without
    an actuator, ``stations`` the home fractions of the rotational joints' centres along the
    limb, ``offsets`` the home offsets of the rotational joints' centres off the anchor line
    (fractions of its length, each in [-1, 1]; the elbow of an R-R or R-U link, see the module
    docstring). :class:`ChainError` (one line: what is wrong, what is allowed) otherwise."""
    if not isinstance(spec, str) or not spec.strip():
        raise ChainError(f"joint string must be a non-empty string of {', '.join(JOINT_LETTERS)} (the actuated joint "
                         f"followed by '*', e.g. 'RP*UR'), got {_fmt(spec)}")
    s = spec.strip()
    letters, marks = [], []
    for ch in s:
        if ch == "*":
            if not letters:
                raise ChainError(f"joint string {s!r}: '*' must follow the joint it marks as actuated, e.g. 'RP*UR'")
            marks.append(len(letters) - 1)
        elif ch.upper() in JOINT_LETTERS and ch.isalpha():
            letters.append(ch.upper())
        else:
            raise ChainError(f"joint string {s!r}: unknown joint letter {ch!r}; allowed: "
                             f"{', '.join(f'{k} ({v})' for k, v in JOINT_LETTERS.items())}, the actuated one "
                             f"followed by '*'")
    joints = "".join(letters)
    if len(marks) != len(set(marks)):
        raise ChainError(f"joint string {s!r}: a joint is marked '*' twice; mark exactly one actuated joint")
    if actuated is not None:
        if isinstance(actuated, bool) or not isinstance(actuated, (int, np.integer)) \
                or not 0 <= int(actuated) < len(joints):
            raise ChainError(f"actuated must be the index (0 to {len(joints) - 1}) of a joint of {joints!r}, got "
                             f"{_fmt(actuated)}")
        marks = sorted(set(marks) | {int(actuated)})
    if len(marks) > 1:
        raise ChainError(f"joint string {s!r}: {len(marks)} actuated joints ({', '.join(str(m) for m in marks)}); a "
                         f"limb has exactly one actuated joint (or none with passive=True)")
    if not isinstance(passive, (bool, np.bool_)):
        raise ChainError(f"passive must be True or False, got {_fmt(passive)}")
    if not marks and not passive:
        raise ChainError(f"joint string {s!r}: no actuated joint; mark one with '*' (e.g. 'RP*UR') or give actuated=, "
                         f"or say passive=True for a constraining limb")
    if marks and passive:
        raise ChainError(f"joint string {s!r}: passive=True but joint {marks[0]} is marked actuated; give one or "
                         f"the other")
    act = marks[0] if marks else None
    if act is not None and joints[act] not in "RP":
        raise ChainError(f"joint string {s!r}: the actuated joint {act} is a {JOINT_LETTERS[joints[act]]} joint; "
                         f"only a revolute (R) or prismatic (P) joint can be actuated")
    n_dof = sum(JOINT_DOF[j] for j in joints)
    if n_dof > 6 + 1 or n_dof < 1:
        raise ChainError(f"joint string {s!r}: {n_dof} joint freedoms; a limb has 1 to 7 (six freedoms and at most "
                         f"an idle spin)")
    n_axes = sum(_AXES_PER_JOINT[j] for j in joints)
    if axes is None:
        axes, first = [], True
        for j in joints:
            if j == "P":
                axes.append("limb")
            elif j in "RU":
                axes.append("tangent" if first else "parallel:prev")
                first = False
                if j == "U":
                    axes.append("normal:prev")
    if not isinstance(axes, (list, tuple)):
        raise ChainError(f"axes must be a list of {n_axes} relation strings (one per axis of {joints}), got {_fmt(axes)}")
    if len(axes) != n_axes:
        raise ChainError(f"axes: {joints} has {n_axes} axes (R, P one each, U two, S none), {len(axes)} relations "
                         f"given")
    rels = []
    kinds = [j for j in joints for _ in range(_AXES_PER_JOINT[j])]
    k = 0
    for i, j in enumerate(joints):
        for m in range(_AXES_PER_JOINT[j]):
            where = f"axes[{k}] (joint {i} {j}{'' if j != 'U' else ' axis ' + str(m + 1)})"
            r = _parse_relation(axes[k], where)
            rot_before = [kk for kk in range(k) if kinds[kk] != "P"]
            if any(ref == "prev" for _, ref in r) and not rot_before:
                raise ChainError(f"{where}: no rotational axis comes before it to be 'prev'; "
                                 f"{_ALLOWED.replace('prev, ', '')}")
            for _, ref in r:
                if ref.startswith("axis") and int(ref[4:]) >= k:
                    raise ChainError(f"{where}: {ref!r} is not an earlier axis (axes 0 to {k - 1} come before it)")
            _check_symbolic(r, where)
            if j == "U" and m == 1 and ("parallel", "prev") in r:
                raise ChainError(f"{where}: a universal joint's second axis is normal to its first, not parallel; "
                                 f"give 'normal:prev' (with another normal reference to fix it)")
            rels.append(r)
            k += 1
    n_rot = sum(1 for j in joints if j in "RUS")
    if stations is not None:
        if not isinstance(stations, (list, tuple)) or len(stations) != n_rot or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and 0.0 <= v <= 1.0 for v in stations):
            raise ChainError(f"stations must be {n_rot} numbers in [0, 1] (the home fractions along the limb of its "
                             f"rotational joints' centres, non-decreasing), got {_fmt(stations)}")
        if any(b < a for a, b in zip(stations, stations[1:])):
            raise ChainError(f"stations must be non-decreasing (joint centres in chain order along the limb), got "
                             f"{list(stations)}")
        stations = tuple(float(v) for v in stations)
    if offsets is not None:
        if not isinstance(offsets, (list, tuple)) or len(offsets) != n_rot or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and -1.0 <= v <= 1.0
                for v in offsets):
            raise ChainError(f"offsets must be {n_rot} numbers in [-1, 1] (the home offsets of its rotational joints' "
                             f"centres off the anchor line, as fractions of the limb's length), got {_fmt(offsets)}")
        offsets = tuple(float(v) for v in offsets) if any(offsets) else None
    spec_ = ChainSpec(joints, act, tuple(rels), stations, tuple(kinds), offsets)
    # the relations at a generic anchor: contradictions that depend on the previous axes
    _resolve_axes(spec_, np.array([math.cos(0.7), math.sin(0.7), 0.0]), np.array([-math.sin(0.7), math.cos(0.7), 0.0]),
                  unit(np.array([-0.31, 0.17, 0.93])))
    return spec_


def _resolve_axes(spec: ChainSpec, radial, tangent, limb, who: str = "") -> list[np.ndarray]:
    """The home directions of the chain's axes at an anchor (its radial and tangent directions,
    the limb's home line); :class:`ChainError` where relations contradict."""
    fixed = {"base_normal": np.array([0.0, 0.0, 1.0]), "radial": np.asarray(radial, float),
             "tangent": np.asarray(tangent, float), "limb": np.asarray(limb, float), "x": np.eye(3)[0],
             "y": np.eye(3)[1], "z": np.eye(3)[2]}
    out = []
    tol = 1e-9
    for k, rels in enumerate(spec.relations):
        where = f"{who}axes[{k}]"
        prev = [out[kk] for kk in range(k) if spec.kinds[kk] != "P"]
        vec = {ref: (prev[-1] if ref == "prev" else out[int(ref[4:])] if ref.startswith("axis") else fixed[ref])
               for _, ref in rels}
        par = [vec[r] for kind, r in rels if kind == "parallel"]
        nor = [vec[r] for kind, r in rels if kind == "normal"]
        for v in par + nor:
            if _norm3(v) < tol:
                raise ChainError(f"{where}: a reference direction is undefined at this anchor (radial or tangent of an "
                                 f"anchor on the centre); give x, y, z or base_normal")
        if par:
            a = unit(par[0])
        elif len(nor) >= 2 and np.linalg.norm(cross(nor[0], nor[1])) > 1e-6:
            a = unit(cross(nor[0], nor[1]))
        else:
            c = cross(nor[0], fixed["limb"])
            if np.linalg.norm(c) < 1e-6:
                c = cross(nor[0], fixed["base_normal"])
            if np.linalg.norm(c) < 1e-6:
                c = cross(nor[0], fixed["x"])
            a = unit(c)
        for (kind, r) in rels:
            if not _holds(kind, a, vec[r]):
                names = [f"{kind}:{r}" for kind, r in rels]
                raise ChainError(f"{where}: relations {' & '.join(names)} contradict each other here ({kind} to {r!r} "
                                 f"cannot hold with the others); {_ALLOWED}")
        out.append(a)
    return out


def _norm3(v) -> float:
    """The length of a 3-vector, in Python floats (a test's, not a result's)."""
    x, y, z = (float(c) for c in v)
    return math.sqrt(x * x + y * y + z * z)


def _holds(kind: str, a, v) -> bool:
    """Whether the unit axis ``a`` is parallel (``kind == "parallel"``: the cross product with the
    unit ``v`` within 1e-6) or normal (the dot product within 1e-6) to the direction ``v``; in
    Python floats, a tenth of NumPy's time on 3-vectors (the answer of a tolerance this far above
    rounding does not depend on the last bits). A zero ``v`` holds either relation."""
    ax, ay, az = (float(c) for c in a)
    vx, vy, vz = (float(c) for c in v)
    n = math.sqrt(vx * vx + vy * vy + vz * vz)
    if not n > 0.0:
        return True
    vx, vy, vz = vx / n, vy / n, vz / n
    if kind == "parallel":
        cx, cy, cz = ay * vz - az * vy, az * vx - ax * vz, ax * vy - ay * vx
        return not math.sqrt(cx * cx + cy * cy + cz * cz) > 1e-6
    return not abs(ax * vx + ay * vy + az * vz) > 1e-6


def _log_rot(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) of rotation matrices (N, 3, 3)."""
    v = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], -1)
    s = np.linalg.norm(v, axis=-1)
    c = 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0)
    th = np.arctan2(s, c)
    f = np.where(s > 1e-12, th / np.maximum(s, 1e-300), 1.0)
    return v * f[:, None]


def _skew3(a) -> np.ndarray:
    """The cross-product matrix of a 3-vector."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _elbow_direction(axis, limb, radial) -> np.ndarray:
    """The direction of a joint centre's offset off the anchor line: normal to the joint's
    first axis and to the limb (``axis x limb``; the base normal stands for a spherical joint's
    axis), else the radial direction, else x."""
    for v in (cross(axis, limb), np.asarray(radial, float), np.eye(3)[0]):
        if np.linalg.norm(v) > 1e-6:
            return unit(np.asarray(v, float))
    return np.eye(3)[0]  # pragma: no cover


def _angle_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (rad) between the rows of ``a`` and ``b`` (N, 3)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.einsum("ij,ij->i", a, b))


def _cone_links(spec: ChainSpec, centres, joint_of, base, A0, L) -> tuple:
    """Per universal or spherical joint: its angle keys, the indices of the freedoms before and
    after it (:meth:`ChainLeg._forward`'s frames) and the home direction of the link that its
    cone angle follows: the link to the next joint centre (or to the platform anchor), or, for
    the joint at the platform anchor, the link arriving from the previous joint centre (or the
    base anchor)."""
    out = []
    rot = [i for i, j in enumerate(spec.joints) if j in "RUS"]
    tol = 1e-9 * L
    for i, j in enumerate(spec.joints):
        if j not in "US":
            continue
        c = centres[i]
        later = [centres[k] for k in rot if k > i and np.linalg.norm(centres[k] - c) > tol]
        if later:
            link = later[0] - c
        elif np.linalg.norm(A0 - c) > tol:
            link = A0 - c
        else:
            earlier = [centres[k] for k in rot if k < i and np.linalg.norm(centres[k] - c) > tol]
            link = c - (earlier[-1] if earlier else base)
        if np.linalg.norm(link) <= tol:  # pragma: no cover (a limb of one joint at its own base)
            continue
        keys = [f"{j}{i}_cone"]
        if i == rot[0] and np.linalg.norm(c - base) <= tol:
            keys.append(f"{j}_base_cone")
        if i == rot[-1] and np.linalg.norm(c - A0) <= tol:
            keys.append(f"{j}_platform_cone")
        m0 = joint_of.index(i)
        m1 = len(joint_of) - joint_of[::-1].index(i)
        out.append((tuple(keys), m0, m1, unit(link)))
    return tuple(out)


@dataclass(frozen=True)
class ChainLeg(Leg):
    """A limb of any joint string (:func:`parse_chain`), solved numerically.

    ``chain``: the joint string with the actuated joint marked (``"RP*UR"``) or a passive one;
    ``axes``: the relations of its axes (None: the defaults of :func:`parse_chain`); ``passive``:
    no actuator; ``stations``: home fractions of the rotational joints' centres; ``home_point``:
    the platform anchor's position (base frame) at the home pose, level platform (None: the
    platform anchor raised by ``home_height`` above the base plane); ``radial`` and ``tangent``:
    the base anchor's directions (None: from the anchor's angle about z); ``offsets``: home
    offsets of the rotational joints' centres off the anchor line (fractions of its length, the
    elbows; None: on the line); ``closed``: False solves the limb numerically even where its
    geometry has a closed form (:attr:`closed_form`; to compare the two)."""

    chain: str = "RP*UR"
    axes: tuple | None = None
    passive: bool = False
    stations: tuple | None = None
    home_point: np.ndarray | None = None
    home_height: float = 0.4
    radial: np.ndarray | None = None
    tangent: np.ndarray | None = None
    offsets: tuple | None = None
    closed: bool = True

    joints: ClassVar[str] = "chain"
    actuated: ClassVar[int | None] = None
    capabilities: ClassVar[LegCapabilities] = LegCapabilities(compiled=True, stiffness=True, passive=True)
    #: The joint-angle keys of the universal or spherical joint at the base and at the platform
    #: anchor (None: a revolute or prismatic end joint), set per joint string by :func:`chain_class`.
    cone_keys: ClassVar[tuple] = (None, None)
    #: What a mechanism description gives a chain limb: its anchor's directions and the height of
    #: its home configuration (the structures give ``radial``, ``tangent`` and ``height``).
    description_options: ClassVar[dict | None] = {"radial": "axis_base", "tangent": "axis_base",
                                                   "home_height": "length"}

    def __post_init__(self):
        super().__post_init__()
        chain = self.chain.replace("*", "") if self.passive and isinstance(self.chain, str) else self.chain
        opts = [None if v is None else tuple(v) for v in (self.axes, self.stations, self.offsets)]
        try:
            try:  # a study builds the same limbs for every design: their parse is kept
                spec = _parsed(chain, *opts, bool(self.passive))
            except TypeError:  # something unhashable: parsed (and refused) as given, not kept
                spec = _parsed.__wrapped__(chain, *opts, bool(self.passive))
        except ChainError as e:
            raise ChainError(f"leg {self.name}: {e}") from None
        A0 = (self.platform + np.array([0.0, 0.0, float(self.home_height)]) if self.home_point is None
              else _vec3(f"leg {self.name}: home_point", self.home_point))
        d = A0 - self.base
        L = float(np.linalg.norm(d))
        if L <= 0:
            raise ChainError(f"leg {self.name}: the home platform anchor coincides with the base anchor")
        rad = self.radial
        if rad is None:
            rad = np.array([self.base[0], self.base[1], 0.0])
            rad = rad / np.linalg.norm(rad) if np.linalg.norm(rad) > 1e-12 else np.zeros(3)
        tan = self.tangent if self.tangent is not None else cross([0.0, 0.0, 1.0], rad)
        axes = _resolve_axes(spec, rad, tan, d / L, who=f"leg {self.name}: ")
        n_rot = sum(1 for j in spec.joints if j in "RUS")
        st = spec.stations or tuple(np.linspace(0.0, 1.0, n_rot)) if n_rot > 1 else (spec.stations or (1.0,))
        # the freedoms as (kind, axis, point) at home
        free, joint_of, k, r = [], [], 0, 0
        centres = []
        for i, j in enumerate(spec.joints):
            if j == "P":
                free.append(("P", axes[k], None))
                joint_of.append(i)
                k += 1
                centres.append(None)
                continue
            c = self.base + st[r] * d
            if j == "S":
                dirs = list(np.eye(3))
            else:
                dirs = axes[k:k + _AXES_PER_JOINT[j]]
                k += _AXES_PER_JOINT[j]
            if spec.offsets is not None and spec.offsets[r]:
                c = c + spec.offsets[r] * L * _elbow_direction(dirs[0] if j != "S" else np.eye(3)[2], d / L, rad)
            r += 1
            centres.append(c)
            for a in dirs:
                free.append(("R", np.asarray(a, float), c))
                joint_of.append(i)
        act_free = None if spec.actuated is None else joint_of.index(spec.actuated)
        act_home = 0.0
        if spec.actuated is not None and spec.joints[spec.actuated] == "P":
            before = [c for c in centres[:spec.actuated] if c is not None]
            after = [c for c in centres[spec.actuated + 1:] if c is not None]
            if before and after:
                act_home = float(abs((after[0] - before[-1]) @ free[act_free][1]))
        object.__setattr__(self, "_spec", spec)
        object.__setattr__(self, "_free", tuple(free))
        # each revolute freedom's cross-product matrix K and K @ K (Rodrigues, :meth:`_forward`)
        object.__setattr__(self, "_skews", tuple(None if kind == "P" else (_skew3(a), _skew3(a) @ _skew3(a))
                                                 for kind, a, _ in free))
        Z = np.zeros((3, 3))
        object.__setattr__(self, "_poe", (np.stack([Z if sk is None else sk[0] for sk in self._skews]),
                                          np.stack([Z if sk is None else sk[1] for sk in self._skews]),
                                          np.stack([np.zeros(3) if c is None else c for _, _, c in free])))
        object.__setattr__(self, "_joint_of", tuple(joint_of))
        object.__setattr__(self, "_act", act_free)
        object.__setattr__(self, "_act_home", act_home)
        object.__setattr__(self, "_home", A0)
        object.__setattr__(self, "_L", L)
        object.__setattr__(self, "_cones", _cone_links(spec, centres, joint_of, self.base, A0, L))
        object.__setattr__(self, "_closed", closed_form_constants(*_free_arrays(free), A0, L) if self.closed
                           else np.zeros(0))
        # the closure directions: the left null space of the scaled joint twists at home (the
        # constraint wrenches' directions there), onto which the closure residual is projected;
        # the twists from the home axes and points (those of forward(q = 0), the same numbers)
        J = self._twists_at([a[None] for _, a, _ in free], [None if c is None else c[None] for _, _, c in free],
                            A0[None])[0].T.copy()
        J[:3] /= L
        U, sv, _ = np.linalg.svd(J)
        rank = int(np.sum(sv > 1e-9 * max(sv[0], 1e-300))) if len(sv) else 0
        object.__setattr__(self, "_closure_dirs", U[:, rank:].copy())
        object.__setattr__(self, "_closure_cache", {})  # {rows: (targets, orientations, q)}: closure_solve

    # -- structure ---------------------------------------------------------------------------
    @property
    def spec(self) -> ChainSpec:
        return self._spec

    @property
    def n_joint_dof(self) -> int:
        return len(self._free)

    @property
    def is_actuated(self) -> bool:
        return self._spec.actuated is not None

    @property
    def actuator_kind(self) -> str:
        return _actuator_kind(self._spec)

    @property
    def closed_form(self) -> str | None:
        """The name of the closed form of this limb's inverse kinematics (:data:`CLOSED_FORMS`;
        from its geometry: :func:`closed_form_constants`), or None: solved numerically alone."""
        return CLOSED_FORMS[int(self._closed[0])] if self._closed.size else None

    def chain_arrays(self) -> dict:
        """The chain as data, for a compiled solve (:mod:`parasynth.engine.chains`): ``kinds``
        (n,) int64 per freedom (0 revolute, 1 prismatic), ``axes`` (n, 3) and ``points`` (n, 3,
        zeros for a prismatic freedom) at home, ``home`` and ``platform`` (the anchor at home,
        base frame; the platform anchor, platform frame), ``length`` (the scale of the solve's
        position residual), ``actuated`` (the actuated freedom, -1 for none), ``act_home``,
        ``joint_of`` (n,) the joint of each freedom and ``closed`` the constants of its closed
        form (:func:`closed_form_constants`; empty: none)."""
        kinds, axes, points = _free_arrays(self._free)
        return {"kinds": kinds, "axes": axes, "points": points, "home": np.array(self._home, float),
                "platform": np.array(self.platform, float), "length": float(self._L),
                "actuated": -1 if self._act is None else int(self._act), "act_home": float(self._act_home),
                "joint_of": np.array(self._joint_of, dtype=np.int64), "closed": self._closed}

    # -- kinematics --------------------------------------------------------------------------
    def forward(self, q: np.ndarray):
        """The anchor frame (position (N, 3), orientation (N, 3, 3)) and the freedoms' current
        axes and points at joint coordinates ``q`` (N, n) from home (product of exponentials)."""
        return self._forward(q)[:4]

    def _forward(self, q: np.ndarray):
        """:meth:`forward` and the orientation (N, 3, 3) of the body before each freedom (and
        after the last). The product of exponentials of the home joint twists: each revolute
        freedom turns what follows it about its home axis through its home point (Rodrigues with
        the axis' constant cross-product matrix), each prismatic one shifts it along its home
        direction, composed from the base."""
        q = np.atleast_2d(np.asarray(q, float))
        N = q.shape[0]
        Rg = np.broadcast_to(np.eye(3), (N, 3, 3)).copy()
        tg = np.zeros((N, 3))
        axes, points, frames = [], [], []
        # every freedom's exponential at once: Rodrigues rotations (N, n, 3, 3) about the home axes,
        # and their shifts (I - Rm) c (N, n, 3) (a prismatic freedom's rows unused)
        K, K2, C = self._poe
        Rm_all = np.eye(3) + np.sin(q)[..., None, None] * K + (1.0 - np.cos(q))[..., None, None] * K2
        tm_all = C - (Rm_all @ C[..., None])[..., 0]
        for m, (kind, a, c) in enumerate(self._free):
            frames.append(Rg)
            aw = Rg @ a
            axes.append(aw)
            if kind == "P":
                points.append(None)
                tg = tg + aw * q[:, m:m + 1]
                continue
            points.append(Rg @ c + tg)
            tg = tg + (Rg @ tm_all[:, m, :, None])[..., 0]
            Rg = Rg @ Rm_all[:, m]
        pos = Rg @ self._home + tg
        frames.append(Rg)
        return pos, Rg, axes, points, frames

    def _twists_at(self, axes, points, ref):
        """The joint twists (N, n, 6), (v at ``ref``, w), of the freedoms with the current
        ``axes`` and ``points``."""
        N = np.shape(axes[0])[0] if axes else np.shape(ref)[0]
        T = np.zeros((N, len(self._free), 6))
        for m, ((kind, _, _), a, c) in enumerate(zip(self._free, axes, points)):
            if kind == "P":
                T[:, m, :3] = a
            else:
                d = ref - c
                T[:, m, 0] = a[:, 1] * d[:, 2] - a[:, 2] * d[:, 1]
                T[:, m, 1] = a[:, 2] * d[:, 0] - a[:, 0] * d[:, 2]
                T[:, m, 2] = a[:, 0] * d[:, 1] - a[:, 1] * d[:, 0]
                T[:, m, 3:] = a
        return T

    def _error(self, q, target, R):
        """The frame at ``q`` and its error against ``(target, R)`` (position / home length, rotation
        vector)."""
        pos, Rc, axes, points = self.forward(q)
        e = np.concatenate([(target - pos) / self._L, _log_rot(R @ np.transpose(Rc, (0, 2, 1)))], axis=1)
        return e, pos, axes, points

    def inverse(self, p, R, q0=None, closed: bool = True):
        """Joint coordinates (N, n) reaching the platform poses ``(p, R)`` and the residual (N,)
        of the solve (position / length scale, orientation in rad): the closed form where the
        limb has one (:attr:`closed_form`; not with ``closed=False``), then Levenberg-Marquardt
        on the anchor frame's error from there (from the home configuration without a closed
        form, or from ``q0``), which takes no step where the closed form reached. A step is taken only where it lowers
        the squared error; the damping follows Nielsen's rule (:func:`damping_factor` after a
        taken step, not below 1e-12; doubled, then quadrupled, ... after refused ones); a pose
        leaves the batch when reached (residual below :data:`IK_TOL`) or stalled (a
        least-squares minimum off the limb's reach: a taken step lowered the squared error by no
        more than :data:`IK_STALL` of it, or the damping exceeds 1e6)."""
        p = np.atleast_2d(np.asarray(p, float))
        R = np.asarray(R, float).reshape(-1, 3, 3)
        N, n = p.shape[0], len(self._free)
        target = p + np.einsum("nij,j->ni", R, self.platform)
        if q0 is not None:
            q = np.array(q0, float)
        elif closed and self._closed.size:
            q = closed_form_solve(self._closed, target, R)
        else:
            q = np.zeros((N, n))
        # a pose the closed form has no solution for is out of reach in the home pose's working mode:
        # not solved (its coordinates those of home, its residual infinite)
        finite = np.isfinite(target).all(axis=1) & np.isfinite(R).all(axis=(1, 2))
        out = ~np.isfinite(q).all(axis=1) & finite
        q[out | ~finite] = 0.0
        L = self._L
        e, pos, axes, points = self._error(q, target, R)
        res = np.max(np.abs(e), axis=1)
        res[out] = np.inf
        cost = np.einsum("ij,ij->i", e, e)
        lam = np.full(N, 1e-12)
        nu = np.full(N, 2.0)
        act = np.flatnonzero((res >= IK_TOL) & np.isfinite(res))
        for _ in range(IK_ITERATIONS):
            if not act.size:
                break
            J = self._twists_at([a[act] for a in axes], [None if c is None else c[act] for c in points],
                                pos[act]).transpose(0, 2, 1)  # (k, 6, n)
            J[:, :3, :] /= L
            JTJ = np.einsum("nki,nkj->nij", J, J)
            mu = lam[act] * (1.0 + np.einsum("nii->n", JTJ) / n)
            g = np.einsum("nki,nk->ni", J, e[act])
            dq = np.linalg.solve(JTJ + mu[:, None, None] * np.eye(n), g[..., None])[..., 0]
            step = np.max(np.abs(dq), axis=1, keepdims=True)
            dq *= np.minimum(1.0, 0.5 / np.maximum(step, 1e-300))
            # the decrease the linear model predicts for the step: |e|^2 - |e - J dq|^2
            pred = 2.0 * np.einsum("ni,ni->n", dq, g) - np.einsum("ni,nij,nj->n", dq, JTJ, dq)
            qt = q[act] + dq
            et, post, axt, ptt = self._error(qt, target[act], R[act])
            ct = np.einsum("ij,ij->i", et, et)
            ok = np.isfinite(ct) & (ct < cost[act])
            gain = np.where(ok, cost[act] - ct, 0.0)
            acc = act[ok]
            q[acc], e[acc], pos[acc], cost[acc] = qt[ok], et[ok], post[ok], ct[ok]
            for a, b in zip(axes, axt):
                a[acc] = b[ok]
            for a, b in zip(points, ptt):
                if a is not None:
                    a[acc] = b[ok]
            lam[act] = np.where(ok, np.maximum(lam[act] * damping_factor(gain, pred), 1e-12), lam[act] * nu[act])
            nu[act] = np.where(ok, 2.0, nu[act] * 2.0)
            res[act] = np.max(np.abs(e[act]), axis=1)
            stalled = (ok & (gain <= IK_STALL * (cost[act] + gain))) | (lam[act] > 1e6)
            act = act[(res[act] >= IK_TOL) & ~stalled]
        return q, res

    def solve(self, p, R, joint_angles: bool = True):
        p = np.atleast_2d(np.asarray(p, float))
        R = np.asarray(R, float).reshape(-1, 3, 3)
        q, res = self.inverse(p, R)
        pos, Rc, axes, points, frames = self._forward(q)
        reachable = res < 1e3 * IK_TOL
        first = next((c for c in points if c is not None), None)
        B = np.broadcast_to(self.base, pos.shape).copy() if first is None else first
        A = pos
        n = unit(A - B)
        length = np.linalg.norm(A - B, axis=-1)
        act = np.full(len(q), np.nan) if self._act is None else q[:, self._act] + self._act_home
        act = np.where(reachable, act, np.nan)
        angles = self.joint_angles(q, reachable, frames) if joint_angles else {}
        st = LegState(act, reachable, B, A, n, length, angles)
        st.extra.update({"q": q, "axes": axes, "points": points, "residual": res})
        return st

    @property
    def has_cones(self) -> bool:
        """Whether :meth:`joint_angles` gives the cone angle of a universal or spherical joint
        (which needs the bodies' orientations, ``frames``)."""
        return bool(self._cones)

    def joint_angles(self, q, reachable, frames=None) -> dict:
        """The passive angles at joint coordinates ``q`` (N, n): each freedom's coordinate from
        home (``<letter><joint>_<freedom>``) and the cone angle of every universal or spherical
        joint whose links are given (``_cones``: the link's direction carried by the body after
        the joint against the body before it), NaN where not ``reachable``. ``frames``: the
        bodies' orientations of :meth:`_forward` at ``q`` when already computed."""
        q = np.atleast_2d(np.asarray(q, float))
        angles = {f"{self._spec.joints[j]}{j}_{m}": q[:, m] for m, j in enumerate(self._joint_of)}
        if self._cones and frames is None:
            frames = self._forward(q)[4]
        for keys, m0, m1, link in self._cones:
            cone = np.where(reachable, _angle_rows(frames[m1] @ link, frames[m0] @ link), np.nan)
            for key in keys:
                angles[key] = cone
        return angles

    # -- closure equations (model/parasitic.py) ------------------------------------------------
    @property
    def n_closure(self) -> int:
        """Number of closure equations: the constraint wrenches of the limb at its home pose."""
        return int(self._closure_dirs.shape[1])

    def closure_solve(self, p, R, iterations: int = CLOSURE_ITERATIONS):
        """The joint coordinates (N, n) of the chain's least-squares reach of the platform poses
        ``(p, R)`` (Gauss-Newton from home, to the rounding floor) and the remaining error (N, 6):
        the anchor position (divided by the limb's home length) and the rotation vector of the
        platform orientation against the chain's end orientation.

        A row starts from the last solution of a batch of the same size or of a size that divides
        it (rows in the same order, as the perturbed poses of a finite-difference Jacobian) when
        its pose is within 0.05 (position / home length, rotation in rad) of that row's, else from
        home: the solve follows the branch of the nearby poses it came from."""
        target, R, q = self.closure_start(p, R)
        N, n = q.shape
        err = np.full((N, 6), np.nan)
        act = np.flatnonzero(np.all(np.isfinite(target), axis=1) & np.all(np.isfinite(R), axis=(1, 2)))
        L = self._L
        for it in range(iterations + 1):
            if not act.size:
                break
            pos, Rc, axes, points = self.forward(q[act])
            e = np.concatenate([(target[act] - pos) / L, _log_rot(R[act] @ np.transpose(Rc, (0, 2, 1)))], axis=1)
            err[act] = e
            if it == iterations:
                break
            J = self._twists_at(axes, points, pos).transpose(0, 2, 1)  # (k, 6, n)
            J[:, :3, :] /= L
            JTJ = np.einsum("nki,nkj->nij", J, J)
            mu = 1e-14 * (1.0 + np.einsum("nii->n", JTJ))
            dq = np.linalg.solve(JTJ + mu[:, None, None] * np.eye(n), np.einsum("nki,nk->ni", J, e)[..., None])[..., 0]
            step = np.max(np.abs(dq), axis=1)
            dq *= np.minimum(1.0, 0.5 / np.maximum(step, 1e-300))[:, None]
            q[act] += dq
            # a row whose step fell below 1e-10 (the next, quadratically convergent, one would be at the
            # rounding floor) takes its error once more, then leaves
            keep = np.isfinite(step) & (step > 1e-10)
            done = act[~keep]
            if done.size:
                pos, Rc, _, _ = self.forward(q[done])
                err[done] = np.concatenate([(target[done] - pos) / L,
                                            _log_rot(R[done] @ np.transpose(Rc, (0, 2, 1)))], axis=1)
            act = act[keep]
        self.closure_store(target, R, q)
        return q, err

    def closure_start(self, p, R):
        """``(target, R, q0)`` of :meth:`closure_solve` at platform poses ``(p, R)``: the anchor
        targets (N, 3), the orientations (N, 3, 3) and the starting joint coordinates (N, n),
        the last solution of a batch of the same size or of a size that divides it where its
        pose is within 0.05 of this row's (the branch-following warm start), else home (zeros).
        Shared with the compiled solve (:func:`parasynth.engine.chains.closure_solve`)."""
        p = np.atleast_2d(np.asarray(p, float))
        R = np.asarray(R, float).reshape(-1, 3, 3)
        N, n = p.shape[0], len(self._free)
        target = p + np.einsum("nij,j->ni", R, self.platform)
        q = np.zeros((N, n))
        cache = self._closure_cache
        M = next((M for M in sorted(cache, reverse=True) if N % M == 0), None)
        if M is not None:
            t0, R0, q0 = (np.tile(v, (N // M,) + (1,) * (v.ndim - 1)) for v in cache[M])
            with np.errstate(invalid="ignore"):
                near = (np.max(np.abs(target - t0), axis=1) / self._L < 0.05) & \
                    (np.linalg.norm(_log_rot(R @ np.transpose(R0, (0, 2, 1))), axis=1) < 0.05) & \
                    np.all(np.isfinite(q0), axis=1)
            q[near] = q0[near]
        return target, R, q

    def closure_store(self, target, R, q) -> None:
        """Keep the solution ``q`` of a batch (the warm start of the next batch of its size or a
        multiple of it; at most four batch sizes kept)."""
        cache = self._closure_cache
        N = q.shape[0]
        if len(cache) >= 4 and N not in cache:
            cache.pop(next(iter(cache)))
        cache[N] = (target, R, q.copy())

    def closure_residuals(self, p, R, L: float | None = None) -> list[np.ndarray]:
        """The closure equations (:attr:`n_closure` arrays (N,)) at platform poses ``(p, R)``:
        the error of the chain's least-squares reach (:meth:`closure_solve`) on the directions of
        its constraint wrenches at home. Zero exactly where the chain assembles (its error
        vanishes), smooth in the pose near home; dimensionless (positions by the limb's home
        length: ``L`` is not used, it is the signature of the closure equations)."""
        if not self.n_closure:
            return []
        _, e = self.closure_solve(p, R)
        r = e @ self._closure_dirs
        return [r[:, k] for k in range(r.shape[1])]

    def joint_twists(self, st, P):
        return self._twists_at(st.extra["axes"], st.extra["points"], np.broadcast_to(P, st.platform_point.shape))

    def actuator_value(self, A, p, R):
        return self.solve(p, R).actuator

    def constraint_wrenches(self, st, P):
        """The wrenches reciprocal to every joint twist (unit force, or unit couple)."""
        T = self.joint_twists(st, P)
        L = self._L
        Ts = T.copy()
        Ts[..., 3:] *= L
        Vt, rank = null_space(Ts)
        c = 6 - int(np.max(rank)) if len(rank) else 0
        W = Vt[:, 6 - c:].copy() if c else np.zeros((T.shape[0], 0, 6))
        if c:
            W[..., 3:] *= L
            f = np.linalg.norm(W[..., :3], axis=-1)
            m = np.linalg.norm(W[..., 3:], axis=-1)
            couple = f <= 1e-9 * np.maximum(m / L, 1e-300)
            W[couple, :3] = 0.0
            W = W / np.where(couple, m, f)[..., None]
        return W

    def actuation_wrench(self, st, P):
        """The wrench reciprocal to every passive joint twist and not to the actuated one (and
        orthogonal to the constraint wrenches), as a unit force or couple; ``rate_scale`` its
        power on the actuated joint's unit twist."""
        if self._act is None:
            raise ChainError(f"leg {self.name}: a passive limb has no actuation wrench")
        T = self.joint_twists(st, P)
        L = self._L
        Ts = T.copy()
        Ts[..., 3:] *= L
        passive = np.delete(Ts, self._act, axis=1)
        C = self.constraint_wrenches(st, P).copy()
        C[..., 3:] /= L  # scaled like the twists' dual
        out = np.zeros((T.shape[0], 6))
        for i in range(T.shape[0]):
            # the wrenches reciprocal to the passive twists, less the constraint wrenches
            _, s, V = np.linalg.svd(np.vstack([passive[i], np.zeros((1, 6))]))
            rk = int(np.sum(s > 1e-9 * max(s[0], 1e-300)))
            ns = V[rk:]
            if C.shape[1]:
                Q, _ = np.linalg.qr(C[i].T)
                ns = ns - (ns @ Q) @ Q.T
            w = ns[int(np.argmax(np.linalg.norm(ns, axis=1)))]
            w = np.concatenate([w[:3], w[3:] * L])
            f, m = np.linalg.norm(w[:3]), np.linalg.norm(w[3:])
            out[i] = w / (f if f > 1e-9 * m / L else m)
        rate = np.einsum("ij,ij->i", out, T[:, self._act])
        sign = np.where(rate < 0, -1.0, 1.0)
        return out * sign[:, None], rate * sign


def _actuator_kind(spec: ChainSpec) -> str:
    """``slider`` (an actuated prismatic first joint), ``length`` (a prismatic joint further up
    the chain), ``angle`` (a revolute joint) or ``none`` (a passive limb)."""
    if spec.actuated is None:
        return "none"
    if spec.joints[spec.actuated] == "R":
        return "angle"
    return "slider" if spec.actuated == 0 else "length"


def chain_class(spec: str, *, axes=None, passive: bool = False, stations=None, offsets=None, capabilities=None,
                doc: str = "") -> type:
    """A leg type of its own (a subclass of :class:`ChainLeg`) for a joint string: its
    ``joints`` are the plain letters (``"RPUR"``), its defaults the given axis relations,
    stations and offsets, and it declares its own ``capabilities`` (default: those of
    :class:`ChainLeg`)."""
    s = parse_chain(spec, axes=axes, passive=passive, stations=stations, offsets=offsets)
    caps = capabilities or ChainLeg.capabilities
    ns = {"joints": s.joints, "actuated": s.actuated, "capabilities": caps, "actuator_kind": _actuator_kind(s), "__doc__": doc or f"The {s.name} limb.",
          "__annotations__": {"chain": str, "axes": "tuple | None", "passive": bool, "stations": "tuple | None",
                              "offsets": "tuple | None"}}
    ns.update(chain=spec if "*" in spec or passive else s.name, axes=None if axes is None else tuple(axes),
              passive=passive, stations=None if stations is None else tuple(stations),
              offsets=None if offsets is None else tuple(offsets))
    cls = type(s.joints, (ChainLeg,), ns)
    cls.__module__ = __name__
    cls = dataclass(frozen=True)(cls)
    cls.constraint_rows, cls.cone_keys = _constraint_kinds(cls)
    return cls


def _constraint_kinds(cls) -> tuple[tuple[str, ...], tuple]:
    """The kinds of the constraint wrenches of a chain limb type at a generic anchor and pose
    (``angle`` for a couple, ``length`` for a force: its ``constraint_rows``) and its
    ``cone_keys``: the angle keys of its universal or spherical joint at the base anchor and at
    the platform anchor (``U_base_cone``, ``S_platform_cone``, ...; None where the end joint is
    a revolute or a prismatic joint, or sits off the anchor)."""
    leg = cls("generic", base=[0.3 * math.cos(0.4), 0.3 * math.sin(0.4), 0.0], platform=[0.15, 0.02, 0.0])
    p, R = np.array([[0.0, 0.0, 0.4]]), np.eye(3)[None]
    W = leg.constraint_wrenches(leg.solve(p, R), p)[0]
    keys = [k for ks, _, _, _ in leg._cones for k in ks]
    ends = (next((k for k in keys if k.endswith("_base_cone")), None),
            next((k for k in keys if k.endswith("_platform_cone")), None))
    return tuple("angle" if np.linalg.norm(w[:3]) < 1e-9 else "length" for w in W), ends


def register_chain(spec: str, **kw) -> type:
    """:func:`chain_class` added to :data:`parasynth.model.legs.LEG_TYPES` under its joint
    letters (a hand-written leg type of the same letters is not replaced: :class:`ChainError`)."""
    cls = chain_class(spec, **kw)
    old = LEG_TYPES.get(cls.joints)
    if old is not None and not issubclass(old, ChainLeg):
        raise ChainError(f"joint string {spec!r}: {cls.joints} is a hand-written leg type already; its chain limb "
                         f"would replace a closed form")
    LEG_TYPES[cls.joints] = cls
    return cls


#: The chain limbs of the vocabulary (docs/structures.md, "Limbs from joint strings"): their axes
#: as in the type synthesis of 3T2R mechanisms (Masouleh, Gosselin et al.): the base-side
#: revolute axes all along x, the platform-side ones along the platform's y, so that every limb
#: imposes the same couple about x x (R y) and the platform turns about x and the moving y.
_3T2R_AXES = ("x", "parallel:prev", "normal:prev&normal:base_normal", "parallel:prev")
RPUR = register_chain("RP*UR", axes=(_3T2R_AXES[0], "limb") + _3T2R_AXES[1:], stations=(0.0, 0.8, 1.0),
                      capabilities=LegCapabilities(compiled=True, stiffness=True),
                      doc="revolute (x), actuated prismatic along the limb, universal (x, then y), revolute (the "
                          "platform's y): one constraint couple about x x (R y) -- the limb of the 5-RPUR")
PRUR = register_chain("P*RUR", axes=("base_normal",) + _3T2R_AXES, stations=(0.0, 0.3, 1.0),
                      capabilities=LegCapabilities(compiled=True, stiffness=True),
                      doc="actuated slider along the base normal, revolute (x), universal (x, then y), revolute "
                          "(the platform's y): one constraint couple about x x (R y) -- the limb of the 5-PRUR")
SPU = register_chain("SP*U", axes=("limb", "tangent", "normal:prev&normal:limb"),
                     capabilities=LegCapabilities(compiled=True, stiffness=True),
                     doc="spherical, actuated prismatic, universal (the platform's tangent, then normal to it and the "
                         "limb): six freedoms -- the inversion of the UPS, the limb of the 6-SPU")
RRPS = register_chain("RRP*S", axes=("tangent", "normal:prev&normal:limb", "limb"), stations=(0.0, 0.1, 1.0),
                      capabilities=LegCapabilities(compiled=True, stiffness=True),
                      doc="revolute (tangent) at the base anchor, revolute normal to it and the limb a tenth of the "
                          "limb further (an offset universal joint), actuated prismatic, spherical: six freedoms -- "
                          "the limb of a 6-RRPS")
RRUR = register_chain("R*RUR", axes=("x",) + _3T2R_AXES, stations=(0.0, 0.4, 0.8, 1.0), offsets=(0.0, 0.3, 0.0, 0.0),
                      capabilities=LegCapabilities(compiled=True, stiffness=True),
                      doc="actuated revolute (x) at the base anchor, revolute (x) at an elbow (station 0.4, offset 0.3 "
                          "of the limb's length normal to x and the limb), universal (x, then the platform's y), "
                          "revolute (the platform's y): one constraint couple about x x (R y) -- the limb of the "
                          "5-RRUR (Masouleh, Gosselin et al.); without the elbow its three parallel x axes would meet "
                          "the limb's line in a row, a singular planar R-R-R")
RUU = register_chain("R*UU", axes=("tangent", "parallel:prev", "normal:prev&normal:limb", "parallel:prev", "axis0"),
                     stations=(0.0, 0.3, 1.0), offsets=(0.0, 0.25, 0.0), capabilities=LegCapabilities(compiled=True, stiffness=True),
                     doc="actuated crank (revolute, tangent) at the base anchor, universal at the crank's end (station "
                         "0.3, offset 0.25 of the limb's length normal to the tangent and the limb; its first axis "
                         "tangent, its second normal to it and the limb), universal at the platform anchor (its first "
                         "axis parallel to that second axis, its second tangent): one constraint couple normal to the "
                         "tangent and the intermediate axis -- the limb of the translational 3-RUU (Kong and Gosselin, "
                         "Type Synthesis of Parallel Mechanisms, 2007; the Delta-like R-U-U)")
URPU = register_chain("URP*U", axes=("tangent", "normal:prev&normal:limb", "parallel:prev", "limb", "radial",
                                     "normal:prev&normal:limb"), stations=(0.0, 0.8, 1.0),
                      capabilities=LegCapabilities(compiled=True, stiffness=True),
                      doc="universal (tangent, then normal to it and the limb) at the base anchor, revolute parallel "
                          "to the universal joint's second axis four fifths of the limb up, actuated prismatic along "
                          "the limb (from the revolute to the platform), universal (radial, then normal to it and the limb) at the platform anchor: six "
                          "independent freedoms at every platform twist -- the limb of the 6-URPU (3T3R). Two axis "
                          "choices fail: with the platform's first axis tangent, the rotation axes span two directions "
                          "only (one constraint couple, five freedoms); with the revolute parallel to the tangent "
                          "instead, the limb loses a freedom when its platform anchor faces its base anchor (no "
                          "platform twist); with the revolute a fifth of the limb up, it is near a singularity (the "
                          "smallest singular value of its scaled twists 0.02 of the largest, against 0.09) and "
                          "reaches about half of the poses within 50 mm and 10 deg of home")
PRRS = register_chain("P*RRS", axes=("base_normal", "tangent", "normal:prev&normal:limb"), stations=(0.0, 0.1, 1.0),
                      capabilities=LegCapabilities(compiled=True, stiffness=True),
                      doc="actuated slider along the base normal, revolute (tangent) on the slider, revolute normal to "
                          "it and the limb a tenth of the limb further (an offset universal joint), link, spherical: "
                          "six freedoms -- the limb of the 6-PRRS (3T3R)")
__all__ += ["register_chain", "RPUR", "PRUR", "SPU", "RRPS", "RRUR", "RUU", "URPU", "PRRS"]
