"""The compiled inverse kinematics of chain limbs (:class:`parasynth.model.chains.ChainLeg`):
the same Levenberg-Marquardt solve as the NumPy reference (``ChainLeg.inverse``), one pose at
a time in a numba kernel, for a chain given as data (``ChainLeg.chain_arrays``: per freedom its
kind, home axis and home point; the anchor's home position, the platform anchor, the length
scale, the actuated freedom). One specialisation serves every chain limb: a new joint string,
new axes or a new design is new data, not a new compile.

Per pose: from the home configuration (q = 0), or from the coordinates of the chain's closed form
where it has one (``ChainLeg.chain_arrays()["closed"]``; ``_rrps_form``, ``_planar_form`` and
``_spu_form``, as ``model.chains.closed_form_solve``; a pose without a solution in the home
pose's working mode is out of reach, its residual infinite), the anchor frame by the product of
exponentials, the error ``e = ((target - position) / L, log(R Rc^T))``, its largest component
``r``; while ``r >= IK_TOL`` (and finite), at most ``IK_ITERATIONS`` trials: the step
``(J^T J + mu I) dq = J^T e`` with ``mu = lam (1 + trace(J^T J) / n)`` (J: the joint twists at
the anchor, position rows divided by L), scaled to at most 0.5 per coordinate, taken only where
it lowers ``|e|^2``; ``lam`` starts at 1e-12 and follows Nielsen's rule
(``model.chains.damping_factor`` after a taken step, not below 1e-12; times 2, 4, 8, ... after
successive refused ones); the pose stops stalled (a least-squares minimum off the limb's reach)
when a taken step gained no more than ``IK_STALL`` of the error or ``lam`` exceeds
1e6. The reference solves the normal equations by LU (``np.linalg.solve``), this kernel by
Cholesky (they are symmetric positive definite with the damping): the iterates agree to
rounding, the converged coordinates to ~1e-12, and a pose whose residual ends within rounding
of the reachability threshold (``1e3 * IK_TOL``) may be told apart differently (the agreement
test allows those only). The joint angles (coordinates and cone angles) come from
``ChainLeg.joint_angles`` at the solved coordinates, as in the reference.

The closure (``ChainLeg.closure_solve``, the least-squares reach whose error on the home
constraint directions is the limb's closure equations): :func:`closure_solve` runs the
reference's Gauss-Newton (``mu = 1e-14 (1 + trace)``, steps scaled to 0.5, a pose leaving once
its step falls to 1e-10) one pose at a time in ``_closure_kernel``, from the reference's
branch-following warm start (``ChainLeg.closure_start``, stored back with ``closure_store`` on
the same limb, so that compiled and NumPy solves continue each other's branch); Cholesky
instead of LU for the normal equations, so the errors agree to rounding (1e-12 in the tests,
near home where the solve converges). :func:`closure_residuals` is
:func:`parasynth.model.parasitic.closure_residuals` with it (the structures' motion rule calls
it through :func:`parasynth.engine.closure_residuals`).

Where it is used: :func:`solve` gives the :class:`~parasynth.model.legs.LegState` that
``ChainLeg.solve`` gives, with the joint coordinates, current axes, points and the residual in
``extra`` (so the constraint wrenches and joint twists of the NumPy reference apply unchanged);
:func:`feasible` and :func:`margins` evaluate a mechanism with chain limbs as
``Mechanism.is_feasible`` / ``constraint_margins`` do, with every chain limb solved here
(the closed-form legs by their own ``solve``, the constraints by their NumPy margins); :func:`solve_arrays` gives the
index kernels their configurations (:mod:`parasynth.engine.indices`, ``_chain_rows_kernel``).
The kernels are compiled at their first call only (a study without chain limbs never compiles
them), and cached on disk like the others (``precompile`` kinds ``chains`` and
``chain_closure``).
"""

from __future__ import annotations

import math

import numpy as np

from ..model import parasitic
from ..model.chains import CLOSURE_ITERATIONS, IK_ITERATIONS, IK_STALL, IK_TOL, ChainLeg
from ..model.constraints import LegLengthRange, PoseContext, feasible_rows, leg_gate, state_rows
from ..model.legs import LegState, solve_geometry
from ..model.spatial import unit
from . import core
from .core import HAVE_NUMBA, Unsupported

__all__ = ["covers", "chain_legs", "context", "solve", "solve_arrays", "feasible", "margins", "signatures",
           "closure_solve", "closure_residuals", "REACH_FACTOR", "closes_on_chains", "pose_batch", "axial_reach",
           "trailing_reach", "cone_reach", "reach_gate", "needs_angles"]

#: A pose is reachable when the solve's residual is below ``REACH_FACTOR * IK_TOL`` (as
#: ``ChainLeg.solve``).
REACH_FACTOR = 1e3
#: A chain limb's solve costs ~2 us a pose on one core (1.8-2.4 us measured for the eight chain
#: limb types, ``benchmarks/structures.py --chains``): ~60 poses of the cheapest program kernel
#: (:func:`parasynth.engine.core.program_work`), so a batch is spread over threads from ~140
#: poses up.
CHAIN_WORK = 2000.0 / core.REFERENCE_NS

if HAVE_NUMBA:  # pragma: no branch
    from numba import njit

    _jit = dict(cache=True, nogil=True, error_model="numpy", boundscheck=False)

    @njit(**_jit)
    def _rotation(ax, ay, az, angle):
        """The rotation (row-major 9-tuple) through ``angle`` about the axis (ax, ay, az):
        Rodrigues about the unit axis, R = I + s K + (1 - c) K K, K = skew(u)
        (spatial.rot_axis normalises it again)."""
        nn = math.sqrt(ax * ax + ay * ay + az * az)
        ux = ax / nn
        uy = ay / nn
        uz = az / nn
        s = math.sin(angle)
        c1 = 1.0 - math.cos(angle)
        return (1.0 + c1 * (-uz * uz - uy * uy), -s * uz + c1 * (uy * ux), s * uy + c1 * (uz * ux),
                s * uz + c1 * (ux * uy), 1.0 + c1 * (-uz * uz - ux * ux), -s * ux + c1 * (uz * uy),
                -s * uy + c1 * (ux * uz), s * ux + c1 * (uy * uz), 1.0 + c1 * (-uy * uy - ux * ux))

    @njit(**_jit)
    def _forward(q, kinds, axes, points, home, Rg, tg, axw, ptw, pos):
        """The anchor frame (``pos``, ``Rg``) and the freedoms' current axes and points at the
        joint coordinates ``q`` (product of exponentials, as ``ChainLeg.forward``). The running
        frame is kept in local scalars, not in ``Rg`` and ``tg`` (written once at the end), so
        that the stores to ``axw`` and ``ptw`` do not make the compiler reload it (171 -> 151 ns
        for a five-freedom chain); the arithmetic is the same, operation for operation."""
        n = kinds.shape[0]
        g00, g01, g02, g10, g11, g12, g20, g21, g22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
        t0, t1, t2 = 0.0, 0.0, 0.0
        for m in range(n):
            a0 = axes[m, 0]
            a1 = axes[m, 1]
            a2 = axes[m, 2]
            ax = g00 * a0 + g01 * a1 + g02 * a2
            ay = g10 * a0 + g11 * a1 + g12 * a2
            az = g20 * a0 + g21 * a1 + g22 * a2
            axw[m, 0] = ax
            axw[m, 1] = ay
            axw[m, 2] = az
            qm = q[m]
            if kinds[m] == 1:
                ptw[m, 0] = np.nan
                ptw[m, 1] = np.nan
                ptw[m, 2] = np.nan
                t0 += ax * qm
                t1 += ay * qm
                t2 += az * qm
                continue
            c0 = points[m, 0]
            c1 = points[m, 1]
            c2 = points[m, 2]
            cx = g00 * c0 + g01 * c1 + g02 * c2 + t0
            cy = g10 * c0 + g11 * c1 + g12 * c2 + t1
            cz = g20 * c0 + g21 * c1 + g22 * c2 + t2
            ptw[m, 0] = cx
            ptw[m, 1] = cy
            ptw[m, 2] = cz
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rotation(ax, ay, az, qm)
            dx = t0 - cx
            dy = t1 - cy
            dz = t2 - cz
            t0 = r00 * dx + r01 * dy + r02 * dz + cx
            t1 = r10 * dx + r11 * dy + r12 * dz + cy
            t2 = r20 * dx + r21 * dy + r22 * dz + cz
            g00, g10, g20 = r00 * g00 + r01 * g10 + r02 * g20, r10 * g00 + r11 * g10 + r12 * g20, \
                r20 * g00 + r21 * g10 + r22 * g20
            g01, g11, g21 = r00 * g01 + r01 * g11 + r02 * g21, r10 * g01 + r11 * g11 + r12 * g21, \
                r20 * g01 + r21 * g11 + r22 * g21
            g02, g12, g22 = r00 * g02 + r01 * g12 + r02 * g22, r10 * g02 + r11 * g12 + r12 * g22, \
                r20 * g02 + r21 * g12 + r22 * g22
        Rg[0, 0] = g00
        Rg[0, 1] = g01
        Rg[0, 2] = g02
        Rg[1, 0] = g10
        Rg[1, 1] = g11
        Rg[1, 2] = g12
        Rg[2, 0] = g20
        Rg[2, 1] = g21
        Rg[2, 2] = g22
        tg[0] = t0
        tg[1] = t1
        tg[2] = t2
        pos[0] = g00 * home[0] + g01 * home[1] + g02 * home[2] + t0
        pos[1] = g10 * home[0] + g11 * home[1] + g12 * home[2] + t1
        pos[2] = g20 * home[0] + g21 * home[1] + g22 * home[2] + t2

    @njit(**_jit)
    def _frames(q, kinds, axes, FR, i):
        """``FR[i, m]``: the orientation of the body before freedom m at the joint coordinates
        ``q`` (and ``FR[i, n]`` after the last), the rotations of :func:`_forward` (as
        ``ChainLeg._forward``'s frames, which the joint cones read)."""
        n = kinds.shape[0]
        for a in range(3):
            for b in range(3):
                FR[i, 0, a, b] = 1.0 if a == b else 0.0
        for m in range(n):
            if kinds[m] == 1:
                for a in range(3):
                    for b in range(3):
                        FR[i, m + 1, a, b] = FR[i, m, a, b]
                continue
            ax = FR[i, m, 0, 0] * axes[m, 0] + FR[i, m, 0, 1] * axes[m, 1] + FR[i, m, 0, 2] * axes[m, 2]
            ay = FR[i, m, 1, 0] * axes[m, 0] + FR[i, m, 1, 1] * axes[m, 1] + FR[i, m, 1, 2] * axes[m, 2]
            az = FR[i, m, 2, 0] * axes[m, 0] + FR[i, m, 2, 1] * axes[m, 1] + FR[i, m, 2, 2] * axes[m, 2]
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rotation(ax, ay, az, q[m])
            for b in range(3):
                g0 = FR[i, m, 0, b]
                g1 = FR[i, m, 1, b]
                g2 = FR[i, m, 2, b]
                FR[i, m + 1, 0, b] = r00 * g0 + r01 * g1 + r02 * g2
                FR[i, m + 1, 1, b] = r10 * g0 + r11 * g1 + r12 * g2
                FR[i, m + 1, 2, b] = r20 * g0 + r21 * g1 + r22 * g2

    @njit(**_jit)
    def _error(R, tx, ty, tz, Rg, pos, L, e):
        """The solve's error ``e`` (6,): ((target - position) / L, log(R Rc^T)); returns the
        squared error and its largest component (NaN when not finite)."""
        e[0] = (tx - pos[0]) / L
        e[1] = (ty - pos[1]) / L
        e[2] = (tz - pos[2]) / L
        m00 = R[0, 0] * Rg[0, 0] + R[0, 1] * Rg[0, 1] + R[0, 2] * Rg[0, 2]
        m11 = R[1, 0] * Rg[1, 0] + R[1, 1] * Rg[1, 1] + R[1, 2] * Rg[1, 2]
        m22 = R[2, 0] * Rg[2, 0] + R[2, 1] * Rg[2, 1] + R[2, 2] * Rg[2, 2]
        m21 = R[2, 0] * Rg[1, 0] + R[2, 1] * Rg[1, 1] + R[2, 2] * Rg[1, 2]
        m12 = R[1, 0] * Rg[2, 0] + R[1, 1] * Rg[2, 1] + R[1, 2] * Rg[2, 2]
        m02 = R[0, 0] * Rg[2, 0] + R[0, 1] * Rg[2, 1] + R[0, 2] * Rg[2, 2]
        m20 = R[2, 0] * Rg[0, 0] + R[2, 1] * Rg[0, 1] + R[2, 2] * Rg[0, 2]
        m10 = R[1, 0] * Rg[0, 0] + R[1, 1] * Rg[0, 1] + R[1, 2] * Rg[0, 2]
        m01 = R[0, 0] * Rg[1, 0] + R[0, 1] * Rg[1, 1] + R[0, 2] * Rg[1, 2]
        vx = 0.5 * (m21 - m12)
        vy = 0.5 * (m02 - m20)
        vz = 0.5 * (m10 - m01)
        sn = math.sqrt(vx * vx + vy * vy + vz * vz)
        cs = 0.5 * (m00 + m11 + m22 - 1.0)
        th = math.atan2(sn, cs)
        f = th / (sn if sn > 1e-300 else 1e-300) if sn > 1e-12 else 1.0
        e[3] = vx * f
        e[4] = vy * f
        e[5] = vz * f
        r = 0.0
        c = 0.0
        bad = False
        for k in range(6):
            a = abs(e[k])
            c += e[k] * e[k]
            if a != a:
                bad = True
            elif a > r:
                r = a
        if bad:
            return np.nan, np.nan
        return c, r

    @njit(**_jit)
    def _normal_equations(n, kinds, axw, ptw, pos, L, e, J, A, b):
        """The joint twists at the anchor as the columns of J (6, n) (a prismatic freedom (a, 0),
        a revolute one (a x (pos - c), a); position rows divided by L), the lower triangle of
        A = J^T J and b = J^T e; returns the trace of A."""
        for m in range(n):
            ax = axw[m, 0]
            ay = axw[m, 1]
            az = axw[m, 2]
            if kinds[m] == 1:
                J[0, m] = ax / L
                J[1, m] = ay / L
                J[2, m] = az / L
                J[3, m] = 0.0
                J[4, m] = 0.0
                J[5, m] = 0.0
            else:
                rx = pos[0] - ptw[m, 0]
                ry = pos[1] - ptw[m, 1]
                rz = pos[2] - ptw[m, 2]
                J[0, m] = (ay * rz - az * ry) / L
                J[1, m] = (az * rx - ax * rz) / L
                J[2, m] = (ax * ry - ay * rx) / L
                J[3, m] = ax
                J[4, m] = ay
                J[5, m] = az
        tr = 0.0
        for a in range(n):
            for c in range(a + 1):  # the lower triangle: all that the Cholesky solve reads
                s = 0.0
                for k in range(6):
                    s += J[k, a] * J[k, c]
                A[a, c] = s
            tr += A[a, a]
            s = 0.0
            for k in range(6):
                s += J[k, a] * e[k]
            b[a] = s
        return tr

    @njit(**_jit)
    def _cholesky_solve(n, A, b, Lc, dq):
        """dq solving A dq = b (A symmetric positive definite, damped by the caller; its lower
        triangle read): Cholesky A = Lc Lc^T, then the two triangular solves."""
        for a in range(n):
            for c in range(a + 1):
                s = A[a, c]
                for k in range(c):
                    s -= Lc[a, k] * Lc[c, k]
                if a == c:
                    Lc[a, a] = math.sqrt(s) if s > 0.0 else 1e-300
                else:
                    Lc[a, c] = s / Lc[c, c]
        for a in range(n):
            s = b[a]
            for k in range(a):
                s -= Lc[a, k] * dq[k]
            dq[a] = s / Lc[a, a]
        for a in range(n - 1, -1, -1):
            s = dq[a]
            for k in range(a + 1, n):
                s -= Lc[k, a] * dq[k]
            dq[a] = s / Lc[a, a]

    @njit(**_jit)
    def _damping_factor(gain, pred):
        """What the damping is multiplied by after a taken step (Nielsen's rule, as
        ``model.chains.damping_factor``): ``max(1/3, 1 - (2 rho - 1)^3)`` with ``rho`` the
        decrease obtained over the decrease the linear model predicted (1 where it predicted
        none)."""
        rho = gain / pred if pred > 0.0 else 1.0
        f = 1.0 - (2.0 * rho - 1.0) ** 3
        return f if f > 1.0 / 3.0 else 1.0 / 3.0

    @njit(**_jit)
    def _rrps_form(cf, tx, ty, tz, R, q):
        """``q`` (6,): the closed form ``"RRP-S"`` (``model.chains.closed_form_solve``, one pose;
        ``cf`` its constants) reaching the anchor position (tx, ty, tz) with orientation ``R``."""
        Ax, Ay, Az = cf[1], cf[2], cf[3]
        a1x, a1y, a1z = cf[4], cf[5], cf[6]
        a2x, a2y, a2z = cf[7], cf[8], cf[9]
        cx, cy, cz = cf[10], cf[11], cf[12]
        ux, uy, uz = cf[13], cf[14], cf[15]
        k, b, rho0 = cf[16], cf[17], cf[18]
        wx = tx - Ax
        wy = ty - Ay
        wz = tz - Az
        th1 = math.atan2(k * (wx * a2x + wy * a2y + wz * a2z), -k * (wx * cx + wy * cy + wz * cz))
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rotation(a1x, a1y, a1z, th1)
        # R1^T w - b u
        rx = r00 * wx + r10 * wy + r20 * wz - b * ux
        ry = r01 * wx + r11 * wy + r21 * wz - b * uy
        rz = r02 * wx + r12 * wy + r22 * wz - b * uz
        th2 = math.atan2((uy * rz - uz * ry) * a2x + (uz * rx - ux * rz) * a2y + (ux * ry - uy * rx) * a2z,
                         rx * ux + ry * uy + rz * uz)
        # T = R1^T R, then M = R2^T T: the entries of M needed (columns 0, 1 and 2 of T)
        s00, s01, s02, s10, s11, s12, s20, s21, s22 = _rotation(a2x, a2y, a2z, th2)
        t00 = r00 * R[0, 0] + r10 * R[1, 0] + r20 * R[2, 0]
        t10 = r01 * R[0, 0] + r11 * R[1, 0] + r21 * R[2, 0]
        t20 = r02 * R[0, 0] + r12 * R[1, 0] + r22 * R[2, 0]
        t01 = r00 * R[0, 1] + r10 * R[1, 1] + r20 * R[2, 1]
        t11 = r01 * R[0, 1] + r11 * R[1, 1] + r21 * R[2, 1]
        t21 = r02 * R[0, 1] + r12 * R[1, 1] + r22 * R[2, 1]
        t02 = r00 * R[0, 2] + r10 * R[1, 2] + r20 * R[2, 2]
        t12 = r01 * R[0, 2] + r11 * R[1, 2] + r21 * R[2, 2]
        t22 = r02 * R[0, 2] + r12 * R[1, 2] + r22 * R[2, 2]
        m00 = s00 * t00 + s10 * t10 + s20 * t20
        m01 = s00 * t01 + s10 * t11 + s20 * t21
        m02 = s00 * t02 + s10 * t12 + s20 * t22
        m12 = s01 * t02 + s11 * t12 + s21 * t22
        m22 = s02 * t02 + s12 * t12 + s22 * t22
        q[0] = th1
        q[1] = th2
        q[2] = math.sqrt(rx * rx + ry * ry + rz * rz) - rho0
        q[3] = math.atan2(-m12, m22)
        q[4] = math.atan2(m02, math.hypot(m12, m22))
        q[5] = math.atan2(-m01, m00)

    @njit(**_jit)
    def _wrap(x):
        """An angle into [-pi, pi) (``model.chains._wrap``)."""
        return x - 2.0 * np.pi * math.floor((x + np.pi) / (2.0 * np.pi))

    @njit(**_jit)
    def _planar_form(cf, tx, ty, tz, R, q):
        """``q`` (5,): the closed forms ``"RR-UR"`` and ``"PR-UR"`` (``model.chains._planar_solve``,
        one pose); False (``q`` untouched) where the pose has no solution."""
        ax, ay, az = cf[1], cf[2], cf[3]
        bx, by, bz = cf[4], cf[5], cf[6]
        nx, ny, nz = cf[7], cf[8], cf[9]
        cx, cy, cz = cf[10], cf[11], cf[12]
        vx_, vy_, vz_ = cf[13], cf[14], cf[15]
        # R a, R b, R n
        rax = R[0, 0] * ax + R[0, 1] * ay + R[0, 2] * az
        ray = R[1, 0] * ax + R[1, 1] * ay + R[1, 2] * az
        raz = R[2, 0] * ax + R[2, 1] * ay + R[2, 2] * az
        rbx = R[0, 0] * bx + R[0, 1] * by + R[0, 2] * bz
        rby = R[1, 0] * bx + R[1, 1] * by + R[1, 2] * bz
        rbz = R[2, 0] * bx + R[2, 1] * by + R[2, 2] * bz
        rnx = R[0, 0] * nx + R[0, 1] * ny + R[0, 2] * nz
        rny = R[1, 0] * nx + R[1, 1] * ny + R[1, 2] * nz
        rnz = R[2, 0] * nx + R[2, 1] * ny + R[2, 2] * nz
        phi = math.atan2(rbx * nx + rby * ny + rbz * nz, rbx * bx + rby * by + rbz * bz)
        psi = math.atan2(rnx * ax + rny * ay + rnz * az, rax * ax + ray * ay + raz * az)
        va = vx_ * ax + vy_ * ay + vz_ * az
        vn = vx_ * nx + vy_ * ny + vz_ * nz
        rv = math.hypot(va, vn)
        h = (tx - cx) * ax + (ty - cy) * ay + (tz - cz) * az
        if not abs(h) <= rv:
            return False
        dl = math.acos(h / rv)
        th4 = _wrap(math.atan2(vn, va) - dl if vn >= 0.0 else math.atan2(vn, va) + dl)
        # w = Rot(a, phi) Rot(b, th4) v; c = target - w
        b00, b01, b02, b10, b11, b12, b20, b21, b22 = _rotation(bx, by, bz, th4)
        w0 = b00 * vx_ + b01 * vy_ + b02 * vz_
        w1 = b10 * vx_ + b11 * vy_ + b12 * vz_
        w2 = b20 * vx_ + b21 * vy_ + b22 * vz_
        a00, a01, a02, a10, a11, a12, a20, a21, a22 = _rotation(ax, ay, az, phi)
        px = tx - (a00 * w0 + a01 * w1 + a02 * w2)
        py = ty - (a10 * w0 + a11 * w1 + a12 * w2)
        pz = tz - (a20 * w0 + a21 * w1 + a22 * w2)
        f0x, f0y, f0z = cf[16], cf[17], cf[18]
        f1x, f1y, f1z = cf[19], cf[20], cf[21]
        if cf[0] == 2.0:
            u1b = (f1x - f0x) * bx + (f1y - f0y) * by + (f1z - f0z) * bz
            u1n = (f1x - f0x) * nx + (f1y - f0y) * ny + (f1z - f0z) * nz
            u2b = (cx - f1x) * bx + (cy - f1y) * by + (cz - f1z) * bz
            u2n = (cx - f1x) * nx + (cy - f1y) * ny + (cz - f1z) * nz
            db = (px - f0x) * bx + (py - f0y) * by + (pz - f0z) * bz
            dn = (px - f0x) * nx + (py - f0y) * ny + (pz - f0z) * nz
            uu1 = u1b * u1b + u1n * u1n
            uu2 = u2b * u2b + u2n * u2n
            m = 0.5 * ((db * db + dn * dn) - uu1 - uu2)
            g0 = math.atan2(u1b * u2n - u1n * u2b, u1b * u2b + u1n * u2n)
            cosv = m / math.sqrt(uu1 * uu2)
            if not abs(cosv) <= 1.0:
                return False
            ac = math.acos(cosv)
            th2 = _wrap((ac if g0 >= 0.0 else -ac) - g0)
            c2 = math.cos(th2)
            s2 = math.sin(th2)
            sx = u1b + c2 * u2b - s2 * u2n
            sy = u1n + s2 * u2b + c2 * u2n
            th1 = math.atan2(sx * dn - sy * db, sx * db + sy * dn)
            q[0] = th1
            q[1] = th2
            q[2] = _wrap(phi - th1 - th2)
        else:
            u2b = (cx - f1x) * bx + (cy - f1y) * by + (cz - f1z) * bz
            u2n = (cx - f1x) * nx + (cy - f1y) * ny + (cz - f1z) * nz
            eb = f0x * bx + f0y * by + f0z * bz
            en = f0x * nx + f0y * ny + f0z * nz
            gb = (px - f1x) * bx + (py - f1y) * by + (pz - f1z) * bz
            gn = (px - f1x) * nx + (py - f1y) * ny + (pz - f1z) * nz
            ge = gb * eb + gn * en
            disc = ge * ge - (gb * gb + gn * gn) + (u2b * u2b + u2n * u2n)
            if not disc >= 0.0:
                return False
            sq = math.sqrt(disc)
            s = ge - sq if u2b * eb + u2n * en >= 0.0 else ge + sq
            rx = gb - s * eb
            ry = gn - s * en
            th1 = math.atan2(u2b * ry - u2n * rx, u2b * rx + u2n * ry)
            q[0] = s
            q[1] = th1
            q[2] = _wrap(phi - th1)
        q[3] = th4
        q[4] = _wrap(psi - th4)
        return True

    @njit(**_jit)
    def _spu_form(cf, tx, ty, tz, R, q):
        """``q`` (6,): the closed form ``"SP-U"`` (``model.chains._spu_solve``, one pose); False
        (``q`` untouched) where the pose has no solution in the home pose's working mode."""
        wx, wy, wz = tx - cf[1], ty - cf[2], tz - cf[3]
        ux, uy, uz = cf[4], cf[5], cf[6]
        t0, t1, t2 = cf[7], cf[8], cf[9]
        n0, n1, n2 = cf[10], cf[11], cf[12]
        f0, f1, f2 = cf[13], cf[14], cf[15]
        rho = math.sqrt(wx * wx + wy * wy + wz * wz)
        mx, my, mz = wx / rho, wy / rho, wz / rho
        kx = R[0, 0] * mx + R[1, 0] * my + R[2, 0] * mz  # R^T m
        ky = R[0, 1] * mx + R[1, 1] * my + R[2, 1] * mz
        kz = R[0, 2] * mx + R[1, 2] * my + R[2, 2] * mz
        kt = kx * t0 + ky * t1 + kz * t2
        kf = kx * f0 + ky * f1 + kz * f2
        ut = ux * t0 + uy * t1 + uz * t2
        uf = ux * f0 + uy * f1 + uz * f2
        cosv = ut / math.hypot(kt, kf)
        if not abs(cosv) <= 1.0:
            return False
        dl = math.acos(cosv)
        beta = math.atan2(kf, kt)
        q5 = _wrap(beta - dl if uf >= 0.0 else beta + dl)
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rotation(n0, n1, n2, q5)
        vx = r00 * kx + r01 * ky + r02 * kz
        vy = r10 * kx + r11 * ky + r12 * kz
        vz = r20 * kx + r21 * ky + r22 * kz
        vt = vx * t0 + vy * t1 + vz * t2
        upx, upy, upz = ux - ut * t0, uy - ut * t1, uz - ut * t2
        vpx, vpy, vpz = vx - vt * t0, vy - vt * t1, vz - vt * t2
        q4 = -math.atan2((upy * vpz - upz * vpy) * t0 + (upz * vpx - upx * vpz) * t1 + (upx * vpy - upy * vpx) * t2,
                         vpx * upx + vpy * upy + vpz * upz)
        # Rs = R Rot(n2, -q5) Rot(t, -q4): Rot(a, -x) is Rot(a, x) transposed
        s00, s01, s02, s10, s11, s12, s20, s21, s22 = _rotation(t0, t1, t2, q4)
        # a = Rot(t, q4) Rot(n2, q5), so Rot(n2, -q5) Rot(t, -q4) = a^T
        a00 = s00 * r00 + s01 * r10 + s02 * r20
        a01 = s00 * r01 + s01 * r11 + s02 * r21
        a02 = s00 * r02 + s01 * r12 + s02 * r22
        a10 = s10 * r00 + s11 * r10 + s12 * r20
        a11 = s10 * r01 + s11 * r11 + s12 * r21
        a12 = s10 * r02 + s11 * r12 + s12 * r22
        a20 = s20 * r00 + s21 * r10 + s22 * r20
        a21 = s20 * r01 + s21 * r11 + s22 * r21
        a22 = s20 * r02 + s21 * r12 + s22 * r22
        # Rs = R a^T: the entries the x-y-z angles read
        m00 = R[0, 0] * a00 + R[0, 1] * a01 + R[0, 2] * a02
        m01 = R[0, 0] * a10 + R[0, 1] * a11 + R[0, 2] * a12
        m02 = R[0, 0] * a20 + R[0, 1] * a21 + R[0, 2] * a22
        m12 = R[1, 0] * a20 + R[1, 1] * a21 + R[1, 2] * a22
        m22 = R[2, 0] * a20 + R[2, 1] * a21 + R[2, 2] * a22
        q[0] = math.atan2(-m12, m22)
        q[1] = math.atan2(m02, math.hypot(m12, m22))
        q[2] = math.atan2(-m01, m00)
        q[3] = rho - cf[16]
        q[4] = q4
        q[5] = q5
        return True

    @njit(**_jit)
    def _chain_kernel(P, Rm, kinds, axes, points, home, plat, L, n_iter, tol, stall, cf, Q, res, POS, AXW, PTW, FR,
                      i0, i1):
        """Poses ``i0 .. i1 - 1``: joint coordinates ``Q``, residual ``res``, anchor position
        ``POS``, the freedoms' axes ``AXW`` and points ``PTW`` at the solution and, if ``FR`` has
        rows (N, n + 1, 3, 3), the orientation of the body before each freedom (:func:`_frames`). The
        reference's Levenberg-Marquardt: a trial step is taken only where it lowers the squared
        error; the damping follows Nielsen's rule (:func:`_damping_factor` after a taken step, not
        below 1e-12; times 2, 4, 8, ... after successive refused ones); a pose stops when reached,
        stalled (a taken step gained no more than ``stall`` of the error, or the damping exceeds 1e6)
        or after ``n_iter`` trials. With the constants ``cf`` of a closed form (non-empty,
        ``model.chains.closed_form_constants``) the solve starts from its coordinates (where they
        reach, no step is taken), else from home."""
        n = kinds.shape[0]
        q = np.zeros(n)
        qt = np.zeros(n)
        Rg = np.empty((3, 3))
        tg = np.empty(3)
        pos = np.empty(3)
        axw = np.empty((n, 3))
        ptw = np.empty((n, 3))
        Rgt = np.empty((3, 3))
        post = np.empty(3)
        axt = np.empty((n, 3))
        ptt = np.empty((n, 3))
        e = np.empty(6)
        et = np.empty(6)
        J = np.empty((6, n))
        A = np.empty((n, n))
        b = np.empty(n)
        dq = np.empty(n)
        Lc = np.empty((n, n))
        d0 = np.empty(n)
        for i in range(i0, i1):
            R = Rm[i]
            tx = P[i, 0] + R[0, 0] * plat[0] + R[0, 1] * plat[1] + R[0, 2] * plat[2]
            ty = P[i, 1] + R[1, 0] * plat[0] + R[1, 1] * plat[1] + R[1, 2] * plat[2]
            tz = P[i, 2] + R[2, 0] * plat[0] + R[2, 1] * plat[1] + R[2, 2] * plat[2]
            finite = tx == tx and ty == ty and tz == tz
            for a in range(3):
                for c in range(3):
                    finite = finite and R[a, c] == R[a, c]
            closed = True  # False: no solution in the home pose's working mode (out of reach, not solved)
            if cf.shape[0] > 0 and finite:
                if cf[0] == 1.0:
                    _rrps_form(cf, tx, ty, tz, R, q)
                elif cf[0] == 4.0:
                    closed = _spu_form(cf, tx, ty, tz, R, q)
                else:
                    closed = _planar_form(cf, tx, ty, tz, R, q)
            if not closed or cf.shape[0] == 0 or not finite:
                for m in range(n):
                    q[m] = 0.0
            _forward(q, kinds, axes, points, home, Rg, tg, axw, ptw, pos)
            cost, r = _error(R, tx, ty, tz, Rg, pos, L, e)
            if not closed:
                r = np.inf
                n_it = 0
            else:
                n_it = n_iter
            lam = 1e-12
            nu = 2.0
            fresh = True  # the normal equations are those of the current coordinates
            tr = 0.0
            for it in range(n_it):
                if not (r >= tol):  # reached, or not finite
                    break
                # joint twists at the anchor: P (a, 0), R (a x (pos - c), a); position rows / L.
                # After a refused step the coordinates are unchanged, and so are J^T J and J^T e:
                # only the damping on the diagonal is new.
                if fresh:
                    tr = _normal_equations(n, kinds, axw, ptw, pos, L, e, J, A, b)
                    for a in range(n):
                        d0[a] = A[a, a]
                mu = lam * (1.0 + tr / n)
                for a in range(n):
                    A[a, a] = d0[a] + mu
                _cholesky_solve(n, A, b, Lc, dq)
                step = 0.0
                for a in range(n):
                    if abs(dq[a]) > step:
                        step = abs(dq[a])
                fac = 0.5 / (step if step > 1e-300 else 1e-300)
                fac = fac if fac < 1.0 else 1.0
                for a in range(n):
                    qt[a] = q[a] + dq[a] * fac
                _forward(qt, kinds, axes, points, home, Rgt, tg, axt, ptt, post)
                ct, rt = _error(R, tx, ty, tz, Rgt, post, L, et)
                ok = (ct == ct) and ct < cost
                gain = cost - ct if ok else 0.0
                fresh = ok
                if ok:  # the trial becomes the current state (the buffers exchanged, not copied)
                    # the decrease the linear model predicted for the step s = fac dq:
                    # |e|^2 - |e - J s|^2 = 2 s.b - s^T (J^T J) s (its lower triangle and d0)
                    sb = 0.0
                    sas = 0.0
                    for a in range(n):
                        sa = dq[a] * fac
                        sb += sa * b[a]
                        sas += d0[a] * sa * sa
                        for c in range(a):
                            sas += 2.0 * A[a, c] * sa * (dq[c] * fac)
                    pred = 2.0 * sb - sas
                    lam = lam * _damping_factor(gain, pred)
                    lam = lam if lam > 1e-12 else 1e-12
                    nu = 2.0
                    cost = ct
                    r = rt
                    q, qt = qt, q
                    axw, axt = axt, axw
                    ptw, ptt = ptt, ptw
                    e, et = et, e
                    pos, post = post, pos
                else:
                    lam = lam * nu
                    nu = nu * 2.0
                if (ok and gain <= stall * (cost + gain)) or lam > 1e6:
                    break
            res[i] = r
            for m in range(n):
                Q[i, m] = q[m]
                for a in range(3):
                    AXW[i, m, a] = axw[m, a]
                    PTW[i, m, a] = ptw[m, a]
            for a in range(3):
                POS[i, a] = pos[a]
            if FR.shape[0] > 0:
                _frames(q, kinds, axes, FR, i)


    @njit(**_jit)
    def _closure_kernel(T, Rm, kinds, axes, points, home, L, n_iter, Q, E, i0, i1):
        """Poses ``i0 .. i1 - 1`` of the closure's least-squares reach (``ChainLeg.closure_solve``):
        from the joint coordinates ``Q`` (the warm start, overwritten by the solution), at most
        ``n_iter`` Gauss-Newton steps ``(J^T J + mu I) dq = J^T e``, ``mu = 1e-14 (1 + trace(J^T
        J))``, each scaled to at most 0.5 per coordinate; a pose whose step fell to 1e-10 or below
        (or is not finite) stops after it. ``E`` (N, 6): the error at the last coordinates (the
        anchor's position / L and the rotation vector of ``R Rc^T``), NaN for a pose that is not
        finite."""
        n = kinds.shape[0]
        q = np.empty(n)
        Rg = np.empty((3, 3))
        tg = np.empty(3)
        pos = np.empty(3)
        axw = np.empty((n, 3))
        ptw = np.empty((n, 3))
        e = np.empty(6)
        J = np.empty((6, n))
        A = np.empty((n, n))
        b = np.empty(n)
        dq = np.empty(n)
        Lc = np.empty((n, n))
        for i in range(i0, i1):
            R = Rm[i]
            tx = T[i, 0]
            ty = T[i, 1]
            tz = T[i, 2]
            finite = math.isfinite(tx) and math.isfinite(ty) and math.isfinite(tz)
            for a in range(3):
                for c in range(3):
                    if not math.isfinite(R[a, c]):
                        finite = False
            if not finite:
                for k in range(6):
                    E[i, k] = np.nan
                continue
            for m in range(n):
                q[m] = Q[i, m]
            for it in range(n_iter + 1):
                _forward(q, kinds, axes, points, home, Rg, tg, axw, ptw, pos)
                _error(R, tx, ty, tz, Rg, pos, L, e)
                if it == n_iter:
                    break
                tr = _normal_equations(n, kinds, axw, ptw, pos, L, e, J, A, b)
                mu = 1e-14 * (1.0 + tr)
                for a in range(n):
                    A[a, a] += mu
                _cholesky_solve(n, A, b, Lc, dq)
                step = 0.0
                for a in range(n):
                    d = abs(dq[a])
                    if d != d:
                        step = np.nan
                        break
                    if d > step:
                        step = d
                if step != step:
                    for a in range(n):
                        q[a] = np.nan
                else:
                    fac = 0.5 / (step if step > 1e-300 else 1e-300)
                    fac = fac if fac < 1.0 else 1.0
                    for a in range(n):
                        q[a] += dq[a] * fac
                if not (step > 1e-10):  # converged (or not finite): the error at the last step, then stop
                    _forward(q, kinds, axes, points, home, Rg, tg, axw, ptw, pos)
                    _error(R, tx, ty, tz, Rg, pos, L, e)
                    break
            for m in range(n):
                Q[i, m] = q[m]
            for k in range(6):
                E[i, k] = e[k]


def _array(dtype, ndim):
    from numba import types as nbt

    return nbt.Array({"f8": nbt.float64, "i8": nbt.int64}[dtype], ndim, "C")


def signatures() -> dict:
    """{kernel name: (dispatcher, argument types)}: the one specialisation of the chain kernel."""
    if not HAVE_NUMBA:
        return {}
    from numba import types as nbt

    f1, f2, f3, f4, i1 = _array("f8", 1), _array("f8", 2), _array("f8", 3), _array("f8", 4), _array("i8", 1)
    sig = (f2, f3, i1, f2, f2, f1, f1, nbt.float64, nbt.int64, nbt.float64, nbt.float64, f1, f2, f1, f2, f3, f3, f4,
           nbt.int64, nbt.int64)
    csig = (f2, f3, i1, f2, f2, f1, nbt.float64, nbt.int64, f2, f2, nbt.int64, nbt.int64)
    return {"_chain_kernel": (_chain_kernel, sig), "_closure_kernel": (_closure_kernel, csig)}


def _c(a, dtype=np.float64):
    return np.require(a, dtype=dtype, requirements=["C", "W"])


def solve_arrays(leg: ChainLeg, p, R, frames: bool = False) -> dict:
    """The compiled solve of ``leg`` at platform poses ``p`` (N, 3), ``R`` (N, 3, 3):
    ``{"q" (N, n), "residual" (N,), "position" (N, 3), "axes" (N, n, 3), "points" (N, n, 3; NaN
    for a prismatic freedom)}``, with ``frames`` also ``"frames"`` (N, n + 1, 3, 3): the
    orientation of the body before each freedom and after the last."""
    d = leg.chain_arrays()
    P = _c(np.atleast_2d(np.asarray(p, float)))
    Rm = _c(np.asarray(R, float).reshape(-1, 3, 3))
    kept = leg.__dict__.get("_kept_solve")
    if kept is not None and not frames and kept[0].shape == P.shape and np.array_equal(kept[0], P) \
            and np.array_equal(kept[1], Rm):
        return dict(kept[2])
    N, n = P.shape[0], d["kinds"].shape[0]
    Q = np.empty((N, n))
    res = np.empty(N)
    POS = np.empty((N, 3))
    AXW = np.empty((N, n, 3))
    PTW = np.empty((N, n, 3))
    FR = np.empty((N if frames else 0, n + 1, 3, 3))
    args = (P, Rm, _c(d["kinds"], np.int64), _c(d["axes"]), _c(d["points"]), _c(d["home"]), _c(d["platform"]),
            float(d["length"]), int(IK_ITERATIONS), float(IK_TOL), float(IK_STALL), _c(d["closed"]), Q, res, POS, AXW,
            PTW, FR)
    core._timed_blocks("chain", lambda block, b0, b1: _chain_kernel(*args, b0 * block, min(N, b1 * block)), N,
                       N * CHAIN_WORK)
    out = {"q": Q, "residual": res, "position": POS, "axes": AXW, "points": PTW}
    if frames:
        out["frames"] = FR
    return out


def solve(leg: ChainLeg, p, R, joint_angles: bool = True, arrays: bool = False):
    """``leg.solve(p, R)`` with the compiled inverse kinematics: the same
    :class:`~parasynth.model.legs.LegState` (actuator, reachability, end points, direction,
    length, joint angles; ``extra`` q, axes, points, residual as lists per freedom; with
    ``arrays``, also the compiled solve's arrays, :func:`solve_arrays`)."""
    out = solve_arrays(leg, p, R, frames=joint_angles and leg.has_cones)
    d = leg.chain_arrays()
    q, res = out["q"], out["residual"]
    reachable = res < REACH_FACTOR * IK_TOL
    kinds = d["kinds"]
    axes = [out["axes"][:, m, :] for m in range(len(kinds))]
    points = [None if kinds[m] == 1 else out["points"][:, m, :] for m in range(len(kinds))]
    first = next((c for c in points if c is not None), None)
    A = out["position"]
    B = np.broadcast_to(leg.base, A.shape).copy() if first is None else first
    nvec = unit(A - B)
    length = np.linalg.norm(A - B, axis=-1)
    act = np.full(len(q), np.nan) if d["actuated"] < 0 else q[:, d["actuated"]] + d["act_home"]
    act = np.where(reachable, act, np.nan)
    frames = [out["frames"][:, m] for m in range(len(kinds) + 1)] if "frames" in out else None
    angles = leg.joint_angles(q, reachable, frames) if joint_angles else {}
    st = LegState(act, reachable, B, A, nvec, length, angles)
    st.extra.update({"q": q, "axes": axes, "points": points, "residual": res})
    if arrays:
        st.extra["arrays"] = out
    return st


def closure_solve(leg: ChainLeg, p, R, iterations: int = CLOSURE_ITERATIONS):
    """``leg.closure_solve(p, R, iterations)`` by the compiled kernel: the joint coordinates (N,
    n) of the chain's least-squares reach of the platform poses and the remaining error (N, 6),
    with the reference's branch-following warm start (``ChainLeg.closure_start`` and
    ``closure_store``: the same cache on the limb, so both solves continue each other's
    branch)."""
    target, Rm, q = leg.closure_start(p, R)
    d = leg.chain_arrays()
    N = q.shape[0]
    Q = _c(q)
    E = np.empty((N, 6))
    T = _c(target)
    Rm = _c(Rm)
    args = (T, Rm, _c(d["kinds"], np.int64), _c(d["axes"]), _c(d["points"]), _c(d["home"]), float(d["length"]),
            int(iterations), Q, E)
    core._timed_blocks("chain_closure", lambda block, b0, b1: _closure_kernel(*args, b0 * block, min(N, b1 * block)),
                       N, N * CHAIN_WORK)
    leg.closure_store(target, Rm, Q)
    return Q, E


def _closure_of(leg, p, R) -> list:
    """A chain limb's closure equations (``ChainLeg.closure_residuals``) by :func:`closure_solve`."""
    if not leg.n_closure:
        return []
    _, e = closure_solve(leg, p, R)
    r = e @ leg._closure_dirs
    return [r[:, k] for k in range(r.shape[1])]


def closure_residuals(legs, p, R, L: float) -> np.ndarray:
    """:func:`parasynth.model.parasitic.closure_residuals` (N, k) with the chain limbs' closure
    equations by the compiled solve (the NumPy reference without numba)."""
    if not HAVE_NUMBA:
        return parasitic.closure_residuals(legs, p, R, L)
    return parasitic.closure_residuals(legs, p, R, L, chain=_closure_of)


# ---------------------------------------------------------------------------------------------
# mechanisms with chain limbs: Mechanism.is_feasible / constraint_margins, chain limbs compiled
# ---------------------------------------------------------------------------------------------
def chain_legs(mech) -> list:
    """The chain limbs of ``mech``."""
    return [leg for leg in getattr(mech, "legs", ()) if isinstance(leg, ChainLeg)]


def covers(mech) -> bool:
    """Whether :func:`feasible` and :func:`margins` apply: numba is there and ``mech`` has a
    chain limb (its other legs are solved by their own ``solve``)."""
    return HAVE_NUMBA and bool(chain_legs(mech))


def _poses(mech, Xa):
    """(valid, p, R) of task poses ``Xa``: the description's compiled pose program where it
    covers ``mech``, else the NumPy methods on home-substituted poses (as ``pose_context``)."""
    if core._is_described(mech):
        try:
            prog, consts = core.program_constants(mech, {}, False)
            valid, p, R, _ = core.run_pose(prog, consts, Xa, False)
            return valid, np.asarray(p, float), np.asarray(R, float)
        except (Unsupported, KeyError, IndexError, TypeError, ValueError, AttributeError):
            pass
    if closes_on_chains(mech):  # the unknowns by the compiled closure
        valid, p, R, _ = pose_batch(mech, Xa)
        return valid, p, R
    with np.errstate(all="ignore"):
        valid = mech.pose_valid(Xa)
        Xs = np.where(valid[:, None], Xa, mech.home)
        p, R = mech._pose(Xs)
    return valid, np.asarray(p, float), np.asarray(R, float)


def closes_on_chains(mech) -> bool:
    """Whether ``mech`` is a description whose ``task.solve`` closes on chain limbs (a 3-RUU, a
    4-RPUR/RPS), with numba: its pose program cannot hold their closure, :func:`pose_batch`
    poses it."""
    task = getattr(getattr(mech, "description", None), "task", None)
    return (HAVE_NUMBA and getattr(task, "solve", None) is not None
            and any(isinstance(leg, ChainLeg) for leg in getattr(mech, "_solve_legs", ())))


def pose_batch(mech, Xa, twist: bool = False):
    """``(valid, p, R, T)`` of poses ``Xa`` (N, n_task), as :func:`parasynth.engine.pose_batch`,
    of a description whose ``task.solve`` closes on chain limbs (:func:`closes_on_chains`): the
    unknowns by the model's Gauss-Newton with the chain limbs' closure by the compiled solve
    (:func:`_offer_unknowns`, ~1e-14 from the NumPy closure's), and so the derivatives of the
    unknowns in the twist map (the implicit function theorem's closure Jacobians); the pose and
    the twist map from them by the description's expressions. The model keeps its own solve
    (the reference never sees these unknowns)."""
    kept = mech._solve_cache
    try:
        with np.errstate(all="ignore"):
            _offer_unknowns(mech, Xa)
            valid = np.asarray(mech.pose_valid(Xa), dtype=bool)
            Xs = np.where(valid[:, None], Xa, mech.home)
            _offer_unknowns(mech, Xs)
            p, R = mech._pose(Xs)
            T = mech._twist_map(Xs, chain=_closure_of) if twist else None
    finally:
        mech._solve_cache = kept
    return valid, np.asarray(p, dtype=float), np.asarray(R, dtype=float), T


def _offer_unknowns(mech, X) -> None:
    """Let the NumPy model of a description whose ``task.solve`` closes on chain limbs
    (:func:`closes_on_chains`: the pose program cannot hold their solve) solve the unknowns at
    ``X`` with the chain limbs' closure equations by the compiled solve (the same Gauss-Newton,
    ~1e-14 from the NumPy closure's), when it asks for them. The NumPy engine (``engine="numpy"``,
    the reference) keeps the NumPy closure: only this compiled path offers it, and
    :func:`pose_batch` puts the model's own cache back after."""
    Xc = np.array(X, dtype=float)
    mech.use_solved_unknowns(Xc, lambda: mech.solve_unknowns(Xc, chain=_closure_of), partial=True)


def context(mech, X, gate=(), raw: dict | None = None, live: list | None = None, angles: bool = True) -> PoseContext:
    """``mech.pose_context(X)`` with the chain limbs solved by the compiled kernel. With
    constraints ``gate`` (a feasibility test's), a chain limb is solved only at the poses where
    no leg before it breaks one of them alone (:func:`parasynth.model.constraints.leg_gate`:
    a stroke, a joint angle out of its range); elsewhere it is left unreachable, which those
    poses are not feasible anyway. ``raw``: filled with {leg index: (the poses it was solved
    at, the compiled solve's arrays there)}. ``live``: a list, then given the poses every leg
    reached (indices into X), and the context is of those poses alone (no chain state is
    expanded to every pose: a feasibility test needs no other). ``angles=False``: the legs'
    states without their passive joint angles, for constraints none of which reads them
    (``Constraint.reads_angles``; :func:`needs_angles`)."""
    Xa, _ = mech._poses(X)
    Xa = np.ascontiguousarray(Xa, dtype=np.float64)
    valid, p, R = _poses(mech, Xa)
    # the pose of an invalid parametrisation is the home pose's (as the NumPy path)
    if not valid.all():
        _, ph, Rh = _poses(mech, np.ascontiguousarray(mech.home[None, :], dtype=np.float64))
        p = np.where(valid[:, None], p, ph)
        R = np.where(valid[:, None, None], R, Rh)
    # the closed-form legs at every pose, then each chain limb only at the poses every leg before
    # it reaches (a pose another leg misses is infeasible whatever the chain's state there: the
    # solve of a pose out of reach, up to its stall, is the costly one)
    N = p.shape[0]
    states = [None if isinstance(leg, ChainLeg) else (leg.solve(p, R) if angles else solve_geometry(leg, p, R))
              for leg in mech.legs]
    alive = valid.copy()
    for leg, st in zip(mech.legs, states):
        if st is not None:
            alive &= st.reachable
            ok = leg_gate(gate, leg, st)
            if ok is not None:
                alive &= ok
    for k, leg in enumerate(mech.legs):
        if states[k] is None:
            idx = np.flatnonzero(alive)  # the gates read only the poses still alive
            pa, Ra = (p, R) if idx.size == N else (p[idx], R[idx])
            # a limb solved by its closed form tells an unreached pose at once, without a numerical
            # solve to save: its reach tests would only cost (~0.7 ms a limb at 8192 poses)
            reach = None if leg.closed_form is not None else reach_gate(leg, pa, Ra)
            for ok in (_length_gate(gate, leg, pa, Ra), reach):
                if ok is not None:
                    alive[idx] &= ok
            idx = np.flatnonzero(alive)
            keep = raw is not None
            st = solve(leg, p[idx], R[idx], angles, keep) if idx.size < N else solve(leg, p, R, angles, keep)
            if keep:
                raw[k] = (idx, st.extra.pop("arrays"))
            if live is not None:
                states[k] = (idx, st)
                alive[idx] &= st.reachable
            else:
                states[k] = st if idx.size == N else _expand(leg, st, idx, p, R)
                alive &= states[k].reachable
            ok = leg_gate(gate, leg, st)
            if ok is not None:
                if idx.size == N:
                    alive &= ok
                else:
                    alive[idx] &= ok
    if live is not None:  # the context of the poses every leg reached
        L = np.flatnonzero(alive)
        live.append(L)
        rows = []
        for st in states:
            if isinstance(st, tuple):
                idx, st = st
                rows.append(state_rows(st, np.searchsorted(idx, L), idx.size))
            else:
                rows.append(state_rows(st, L, N))
        act = np.stack([st.actuator for leg, st in zip(mech.legs, rows) if leg.is_actuated], axis=-1)
        return PoseContext(Xa[L], p[L], R[L], list(mech.legs), rows, np.ones(L.size, bool), act, mech)
    reachable = valid & np.logical_and.reduce([st.reachable for st in states])
    act = np.stack([st.actuator for leg, st in zip(mech.legs, states) if leg.is_actuated], axis=-1)
    return PoseContext(Xa, p, R, list(mech.legs), states, reachable, act, mech)


def _length_gate(gate, leg: ChainLeg, p, R):
    """Before a chain limb is solved: False at the poses where its length (first joint centre
    to platform anchor, as its state gives it) is outside a :class:`LegLengthRange` of
    ``gate`` on it by more than a reached pose's error can explain, None when no such
    range names it or its first joint is prismatic (whose centre moves with the slider).

    The first joint's centre is fixed (it turns about itself); the anchor of a reached pose is
    within ``REACH_FACTOR * IK_TOL`` of the limb's length scale of the target on each axis, so
    its length within sqrt(3) of that of the target's: the slack is ten times it."""
    cs = [c for c in gate if type(c) is LegLengthRange and leg.name in c.legs]
    if not cs:
        return None
    d = leg.chain_arrays()
    if d["kinds"][0] != 0:
        return None
    A = p + np.einsum("nij,j->ni", R, np.asarray(leg.platform, float))
    ln = np.linalg.norm(A - d["points"][0], axis=-1)
    slack = 10.0 * REACH_FACTOR * IK_TOL * d["length"]
    ok = np.ones(ln.shape, bool)
    for c in cs:
        ok &= (ln >= c.lo - slack) & (ln <= c.hi + slack)
    return ok


#: Axes within this of parallel (cross product of unit axes) or of normal (dot product) count as
#: such for :func:`axial_reach` (the relations build them exactly, to rounding).
AXIAL_TOL = 1e-9


def _distinct(points) -> list:
    """``points`` without the repeats of the one before (a universal joint's two freedoms share
    their centre): the joint centres of a chain, in order."""
    out = []
    for q in points:
        if not out or not np.array_equal(q, out[-1]):
            out.append(q)
    return out


def _leading(leg: ChainLeg):
    """``(chain arrays, unit axes, a, k)``: the first revolute's unit axis ``a`` (None without a
    revolute) and the number ``k`` of leading freedoms that are revolutes parallel to it or
    prismatics normal to it."""
    d = leg.chain_arrays()
    kinds = d["kinds"]
    unit_axes = [ax / math.sqrt(float(ax @ ax)) for ax in d["axes"]]
    a = next((u for u, kind in zip(unit_axes, kinds) if kind == 0), None)
    k = 0
    while a is not None and k < len(kinds) and (
            (kinds[k] == 0 and float(np.linalg.norm(np.cross(unit_axes[k], a))) <= AXIAL_TOL)
            or (kinds[k] == 1 and abs(float(unit_axes[k] @ a)) <= AXIAL_TOL)):
        k += 1
    return d, unit_axes, a, k


def _trailing_group(unit_axes, kinds, first: int) -> int:
    """The first freedom ``j >= first`` from which every freedom up to the last is a revolute
    parallel to the last one's axis."""
    b = unit_axes[-1]
    j = len(kinds) - 1
    while j - 1 >= first and kinds[j - 1] == 0 and float(np.linalg.norm(np.cross(unit_axes[j - 1], b))) <= AXIAL_TOL:
        j -= 1
    return j


def _reach_tests(leg: ChainLeg):
    """``(axial, trailing, cone)``: the data of :func:`axial_reach`, :func:`trailing_reach` and
    :func:`cone_reach` of ``leg``, read from its chain in one pass; each None where the chain has
    not that test."""
    d, unit_axes, a, k = _leading(leg)
    kinds, pts, home = d["kinds"], d["points"], d["home"]
    n = len(kinds)
    if a is not None and k == 1 and n > 2 and kinds[0] == 0 and kinds[1] == 1 and not (kinds[2:] == 1).any():
        return None, None, _cone(d, unit_axes)
    if a is None or k == 0 or k == n or (kinds[k:] == 1).any():
        return None, None, None
    c = pts[k]
    trail = _distinct([pts[m] for m in range(k, n)] + [home])
    reach = sum(float(np.linalg.norm(q1 - q0)) for q0, q1 in zip(trail, trail[1:]))
    axial = (a, float(a @ c), reach, 10.0 * REACH_FACTOR * IK_TOL * d["length"])
    b = unit_axes[n - 1]
    j = _trailing_group(unit_axes, kinds, k)
    pris = [m for m in range(k) if kinds[m] == 1]
    revs = [m for m in range(k) if kinds[m] == 0]
    dvec = unit_axes[pris[0]] if pris else None
    if j != k or not revs or (pris and max(pris) > min(revs)) or (  # other axes between the groups; a slider after a turn
            dvec is not None and any(float(np.linalg.norm(np.cross(unit_axes[m], dvec))) > AXIAL_TOL for m in pris)):
        return axial, None, None
    lead = _distinct([pts[m] for m in revs] + [c])
    rho = sum(float(np.linalg.norm((q1 - q0) - float((q1 - q0) @ a) * a)) for q0, q1 in zip(lead, lead[1:]))
    w = None if dvec is None else np.cross(a, dvec) / float(np.linalg.norm(np.cross(a, dvec)))
    return axial, {"a": a, "h": axial[1], "b": b, "kb": float(b @ (home - c)), "ell": reach, "rho": rho,
                   "c1": lead[0], "w": w, "length": float(d["length"])}, None


def _cone(d: dict, unit_axes) -> dict | None:
    """The data of :func:`cone_reach` of a chain that starts with a revolute and a prismatic
    joint (checked by the caller, with only revolutes after them), or None where it has not
    that form."""
    kinds, pts, home = d["kinds"], d["points"], d["home"]
    n = len(kinds)
    a, e, o, c = unit_axes[0], unit_axes[1], pts[0], pts[2]

    def normal(v):  # the part of v normal to a
        return v - float(v @ a) * a

    v0, en = c - o, normal(e)
    if float(np.linalg.norm(en)) <= AXIAL_TOL or float(np.linalg.norm(np.cross(normal(v0), en))) > AXIAL_TOL * d["length"]:
        return None  # the slider's line along a (a cylinder) or missing the axis (a hyperboloid): no test
    j = _trailing_group(unit_axes, kinds, 2)
    if any(not np.array_equal(pts[m], c) for m in range(2, j)):
        return None  # a freedom between the slider and the trailing revolutes that moves c
    s = -float(normal(v0) @ en) / float(en @ en)
    trail = _distinct([pts[m] for m in range(2, n)] + [home])
    ell = sum(float(np.linalg.norm(q1 - q0)) for q0, q1 in zip(trail, trail[1:]))
    b = unit_axes[n - 1]
    kb = float(b @ (home - c))
    return {"a": a, "apex": o + float(a @ (v0 + s * e)) * a, "cos": float(a @ e), "sin": float(np.linalg.norm(en)),
            "b": b, "kb": kb, "ell": ell, "rho": math.sqrt(max(ell * ell - kb * kb, 0.0)),
            "length": float(d["length"])}


def axial_reach(leg: ChainLeg):
    """The reach test of a chain limb (:func:`reach_gate`): ``(a, h, reach, slack)``, or None
    where the chain has none.

    The chain's leading freedoms, from the base, while each is a revolute about an axis parallel
    to ``a`` (the first revolute's axis) or a prismatic along a direction normal to it, keep the
    component along ``a`` of every point after them: a turn about an axis parallel to ``a``
    and a shift normal to it do not change it. So the first joint centre after them, ``c``, has
    ``a . c = h`` (its home value) at every configuration. When the freedoms after it are all
    revolute, the links between their joint centres and the anchor are rigid, so the anchor is
    within ``reach`` (their lengths' sum) of ``c`` and ``|a . A - h| <= reach`` wherever the
    chain reaches ``A``. The 5-RRUR's limbs (their x axes up to the universal joint's second
    axis) and the 5-PRUR's (the vertical slider normal to x) have it; a chain whose prismatic
    joint follows a revolute off its normal (the RPUR's slider along the limb: :func:`cone_reach`)
    or comes later has none."""
    return _reach_tests(leg)[0]


#: The least sine of the angle between the leading axis and the trailing one for the line test of
#: :func:`trailing_reach` (nearly parallel axes: the two planes' line is ill-conditioned).
LINE_SIN_MIN = 0.1


def trailing_reach(leg: ChainLeg):
    """The second reach test of a chain limb (:func:`reach_gate`), for a chain of three parts: the
    leading freedoms of :func:`axial_reach` (prismatics normal to ``a`` all before the revolutes
    parallel to it, the prismatics along one direction ``d``), then, from the first joint centre
    ``c`` after them, only revolutes parallel to the last one's axis ``b`` up to the anchor (the
    RRUR's and PRUR's universal joint's second axis and last revolute, both along the platform's
    y). A dict of the test's data, or None where the chain has not that form.

    At a configuration reaching the anchor ``A`` with the platform's rotation ``R``:

    * ``a . c = h`` (:func:`axial_reach`);
    * the trailing revolutes turn about axes parallel to ``b_w = R b`` (the last axis is fixed in
      the platform), through ``c`` and points after it, so ``b_w . (A - c) = kb`` (its home value)
      and ``|A - c| <= ell`` (the rigid links after ``c``);
    * the leading revolutes turn ``c`` about axes parallel to ``a`` from the first one's centre
      ``c1`` shifted by the prismatics along ``d``: its component along ``w = a x d`` stays within
      ``rho`` (the links' lengths normal to ``a``) of ``w . c1``; without a prismatic its
      distance from the line through ``c1`` along ``a`` is at most ``rho``.

    So ``c`` lies on the line of the two planes, within ``ell`` of ``A`` and in that slab (or
    cylinder): where the segment of the line within ``ell`` of ``A`` misses it, no configuration
    reaches the pose."""
    return _reach_tests(leg)[1]


def _trailing_gate(t: dict, A, R):
    """:func:`trailing_reach`'s test at anchors ``A`` (N, 3) and rotations ``R`` (N, 3, 3): False
    where the segment of the planes' line within ``ell`` of ``A`` misses the leading part's slab
    (or cylinder) by more than a reached pose's error can explain; True where the leading and
    trailing axes are within ``LINE_SIN_MIN`` of parallel (no test). A reached pose's anchor and
    rotation are within ``REACH_FACTOR * IK_TOL`` (of the length scale, in rad) of the target's on
    each axis, so its line is within that times the lengths involved (the links', the anchor's
    distance from the origin) over the sine of the axes' angle of the target's: the slack is ten
    times it."""
    a, h, kb, ell, rho, c1, w = t["a"], t["h"], t["kb"], t["ell"], t["rho"], t["c1"], t["w"]
    bw = R @ t["b"]
    cr = np.cross(a, bw)
    sn = np.linalg.norm(cr, axis=1)
    line = sn >= LINE_SIN_MIN
    tl = cr / np.where(line, sn, 1.0)[:, None]
    eps = 10.0 * REACH_FACTOR * IK_TOL
    slack = eps * (t["length"] + ell + rho + np.linalg.norm(A, axis=1)) / np.where(line, sn, 1.0) + eps * t["length"]
    # the line {a . c = h, bw . c = bw . A - kb}: its point c0 = alpha a + beta bw
    g = bw @ a
    r2 = np.einsum("ij,ij->i", bw, A) - kb
    den = np.where(line, 1.0 - g * g, 1.0)
    c0 = ((h - g * r2) / den)[:, None] * a + ((r2 - g * h) / den)[:, None] * bw
    # its segment within ell of A: tau in [tc - dl, tc + dl]
    tc = np.einsum("ij,ij->i", tl, A - c0)
    off = A - c0 - tc[:, None] * tl
    e = ell + slack
    disc = e * e - np.einsum("ij,ij->i", off, off)
    dl = np.sqrt(np.maximum(disc, 0.0))
    lo, hi = tc - dl, tc + dl
    r = rho + slack
    if w is not None:  # the slab |w . c - w . c1| <= rho
        wt, wc, w0 = tl @ w, c0 @ w, float(w @ c1)
        flat = np.abs(wt) < 1e-12
        wt_ = np.where(flat, 1.0, wt)
        t1, t2 = (w0 - r - wc) / wt_, (w0 + r - wc) / wt_
        meets = np.where(flat, np.abs(wc - w0) <= r, np.maximum(lo, np.minimum(t1, t2)) <= np.minimum(hi, np.maximum(t1, t2)))
    else:  # the cylinder |(c - c1) normal to a| <= rho (the line is normal to a)
        q = c0 - c1
        q = q - (q @ a)[:, None] * a
        B = np.einsum("ij,ij->i", q, tl)
        D = B * B - (np.einsum("ij,ij->i", q, q) - r * r)
        sq = np.sqrt(np.maximum(D, 0.0))
        meets = (D >= 0.0) & (np.maximum(lo, -B - sq) <= np.minimum(hi, -B + sq))
    return ~line | ((disc >= 0.0) & meets)


def cone_reach(leg: ChainLeg):
    """The reach test of a chain limb that starts with a revolute and a slider not normal to its
    axis (:func:`reach_gate`; the RPUR's slider along the limb): a dict of the test's data, or
    None where the chain has not the form below.

    The first revolute turns about the axis ``a`` through its centre ``o``; the slider's line,
    which meets that axis, turns with it. So the first joint centre after the slider, ``c``, lies
    on a cone of revolution about the axis (its apex where the line meets the axis, its half-angle
    that of the slider to ``a``; both nappes: the slider is not bounded in the solve). Every
    freedom after the slider is a revolute: those before the trailing revolutes (all parallel to
    the last axis ``b``, fixed in the platform) turn about axes through ``c``. At a configuration
    reaching the anchor ``A`` with the platform's rotation ``R``, as in :func:`trailing_reach`,
    ``b_w . (A - c) = kb`` (``b_w = R b``, ``kb`` its home value) and ``|A - c| <= ell`` (the
    rigid links after ``c``): ``c`` is within ``rho = sqrt(ell^2 - kb^2)`` of
    ``A - kb b_w``. Where that point is further than ``rho`` from the cone, no configuration
    reaches the pose."""
    return _reach_tests(leg)[2]


def _cone_gate(t: dict, A, R):
    """:func:`cone_reach`'s test at anchors ``A`` (N, 3) and rotations ``R`` (N, 3, 3): False where
    ``A - kb R b`` is further from the cone than ``rho`` by more than a reached pose's error can
    explain (its anchor within ``REACH_FACTOR * IK_TOL`` of the length scale of the target's on
    each axis, its rotation within that in rad: the point moves by at most that times the length
    scale plus ``|kb|``; the distance to a fixed cone moves by no more): the slack is ten times
    it, with the trailing reach added."""
    a = t["a"]
    X = A - t["kb"] * (R @ t["b"]) - t["apex"]
    z = X @ a  # the point in the cone's meridian half-plane: along the axis, from the axis
    r = np.sqrt(np.maximum(np.einsum("ij,ij->i", X, X) - z * z, 0.0))
    cs, sn = t["cos"], t["sin"]
    dist = np.full(z.shape, np.inf)
    for vz in (cs, -cs):  # the two nappes' generators (vz, sn) in that half-plane
        along = z * vz + r * sn
        dist = np.minimum(dist, np.where(along >= 0.0, np.abs(z * sn - r * vz), np.hypot(z, r)))
    slack = 10.0 * REACH_FACTOR * IK_TOL * (t["length"] + abs(t["kb"]) + t["ell"])
    return dist <= t["rho"] + slack


def reach_gate(leg: ChainLeg, p, R):
    """Before a chain limb is solved: False at the poses its chain cannot reach, by the tests of
    :func:`axial_reach` (the anchor's component along the leading axis further from that of the
    first joint centre after the leading freedoms than the rest of the chain reaches) and of
    :func:`trailing_reach` (that joint centre on the line of two planes, within reach of the
    anchor and of the leading part), each by more than a reached pose's error can explain (the
    solve's anchor is within ``REACH_FACTOR * IK_TOL`` of the length scale of the target on each
    axis, its rotation within that in rad: the slack is ten times it); None where the chain has
    no such test. A pose it refuses is one the solve does not reach, so the answers do not
    change; the solve of a pose out of reach, run to its stall, costs three to five times that
    of a reached one (a 5-RRUR's limbs: 12-25 us against 4-5 us a pose). In
    ``structures_3t2r``'s box, with rotations, the two refuse all the unreached poses of a 5-RRUR's
    first limb and 0.7-0.95 of a 5-PRUR's (the first test alone: 0.83 and 0-0.4). A chain that
    starts with a revolute and a slider off its normal (RPUR) has the test of :func:`cone_reach`
    instead: 0.65-0.95 of a 5-RPUR limb's unreached poses in that box. :func:`context` asks it
    only of a limb solved numerically (``ChainLeg.closed_form`` None, or ``closed=False``): a
    closed form finds a pose out of reach at once."""
    t, tr, cn = _reach_tests(leg)
    if t is None and cn is None:
        return None
    A = p + np.einsum("nij,j->ni", R, np.asarray(leg.platform, float))
    if cn is not None:
        return _cone_gate(cn, A, np.asarray(R, float))
    a, h, reach, slack = t
    ok = np.abs(A @ a - h) <= reach + slack
    if tr is not None:
        ok &= _trailing_gate(tr, A, np.asarray(R, float))
    return ok


def _expand(leg: ChainLeg, st: LegState, idx, p, R) -> LegState:
    """The state ``st`` of a chain limb solved at the poses ``idx`` of (p, R), as a state of all
    N poses: the others unreachable (actuator, angles, joint coordinates NaN; the platform
    anchor where the platform puts it)."""
    N = p.shape[0]

    def full(a):
        out = np.full((N,) + np.shape(a)[1:], np.nan)
        out[idx] = a
        return out

    reach = np.zeros(N, bool)
    reach[idx] = st.reachable
    A = p + np.einsum("nij,j->ni", R, leg.platform)
    A[idx] = st.platform_point
    out = LegState(full(st.actuator), reach, full(st.base_point), A, full(st.direction), full(st.length),
                   {k: full(v) for k, v in st.angles.items()})
    out.extra.update({"q": full(st.extra["q"]), "residual": full(st.extra["residual"]),
                      "axes": [full(a) for a in st.extra["axes"]],
                      "points": [None if c is None else full(c) for c in st.extra["points"]]})
    return out


def feasible(mech, X, names=None):
    """``mech._is_feasible_numpy(X, names)`` with the chain limbs solved by the kernel: the
    constraints evaluated at the poses every leg reached (:func:`context` with ``live``), but
    for the joint-angle limits that hold at every reached pose (``JointAngleLimit.vacuous``:
    a cone angle up to 180 deg), which would only ask for the angles."""
    Xa, single = mech._poses(X)
    cons = [c for c in mech._select(names) if not getattr(c, "vacuous", False)]
    raw, live = {}, []
    ctx = context(mech, X, gate=cons, raw=raw, live=live, angles=needs_angles(cons))
    L = live[0]
    ok = np.zeros(Xa.shape[0], bool)
    ok[L] = feasible_rows(ctx, cons)
    _keep_solves(mech, ctx, ok[L], L, raw)
    return ok[0] if single else ok


def needs_angles(cons) -> bool:
    """Whether a margin of the constraints ``cons`` reads the legs' passive joint angles
    (``Constraint.reads_angles``; a constraint class that does not say is taken to): without
    them a closed-form leg's NumPy solve takes about half the time (an RPU at 8192 poses) and a
    chain limb's solve keeps no frames."""
    return any(getattr(c, "reads_angles", True) for c in cons)


def _keep_solves(mech, ctx, ok, L, raw) -> None:
    """Keep on each chain limb its compiled solve at the feasible poses ``ok`` of ``ctx`` (the
    context of the poses ``L``; the platform poses and the arrays, one set a limb): the
    measures then evaluate the wrench-system indices there (the singularity margin over the
    workspace), and :func:`solve_arrays` at exactly those platform poses returns them instead
    of solving again (a pose's solve depends on its pose alone)."""
    F = L[ok]
    for k, (idx, out) in raw.items():
        leg = mech.legs[k]
        pos = np.searchsorted(idx, F)
        if F.size and not (pos.max() < idx.size and np.array_equal(idx[pos], F)):
            object.__setattr__(leg, "_kept_solve", None)  # (cannot happen: a feasible pose was solved)
            continue
        kept = {key: np.ascontiguousarray(v[pos]) for key, v in out.items() if key != "frames"}
        object.__setattr__(leg, "_kept_solve", (np.ascontiguousarray(ctx.p[ok]), np.ascontiguousarray(ctx.R[ok]),
                                                kept))


def margins(mech, X, names=None) -> dict:
    """``mech._constraint_margins_numpy(X, names)`` with the chain limbs solved by the kernel."""
    _, single = mech._poses(X)
    cons = mech._select(names)
    ctx = context(mech, X, angles=needs_angles(cons))
    out = {}
    with np.errstate(invalid="ignore"):
        for c in cons:
            m = np.asarray(c.margin(ctx), dtype=float)
            m = np.where(ctx.reachable & ~np.isnan(m), m, -np.inf)
            out[c.name] = m[0] if single else m
    return out
