"""Compiled closure equations of legs at explicit poses: the mechanism as built.

:func:`parasynth.measures.accuracy.closure_residuals` (NumPy) gives the closure residuals ``h(p, R)`` of
a set of legs: per leg its actuator value (when actuated: the leg length, or the slider position
of a fixed-length link) and its constraint residuals (the sphere's offset from an RPS or PRS
leg's revolute plane; for an RPU leg that offset and the platform axis' component along the
revolute axis; for a UPU leg the twist angle between its two cross axes). Here the same
residuals run in one compiled pass over a batch of rows, each row a pose and one draw of leg
geometry (the draws of a robust measure, :mod:`parasynth.measures.robustness`):

* :func:`prep` ``(plan, p, R, draw)``: the residuals ``h0`` at poses ``(p, R)``, their pose
  Jacobian by central differences (steps ``1e-6 L`` and ``1e-6`` rad, as
  ``accuracy._pose_jacobian``) and whether every leg reaches the pose (the reachability rules
  of the legs' ``solve``);
* :func:`solve` ``(plan, p0, R0, Gi, h0, ok, dq, scale, src, draw)``: chord Newton from the
  nominal poses ``(p0, R0)[src]`` on the closure ``h(p, R) = h0[src] + dq[draw]`` of each row's
  draw of the legs (``Gi``: the chord matrix, the inverse of the closure Jacobian at the nominal
  pose), row by row until every residual is within ``1e-12 scale``: the actual platform poses
  and whether they converged (and every leg reaches them).

A pose is composed with a twist ``t`` as ``accuracy._compose`` does: ``p + t[:3]`` and
``exp([t[3:]]) R``. ``tests/measures/test_robust.py`` checks both entry points against the NumPy
residuals and iteration.

Leg types: SPS, UPS, PUS, RPS, RPU, UPU, PRS (``_Unsupported`` for others, and for a leg class
overriding the methods the kernels reproduce, as :mod:`parasynth.engine.indices`).
"""

from __future__ import annotations

import math

import numpy as np

from ..model.legs import GEOM_TOL, require
from .core import HAVE_NUMBA, _array
from .indices import _NC, _PRS, _PUS, _RPS, _RPU, _SPS, _UPS, _UPU, _check_legs, _legs_plan, _Unsupported

if HAVE_NUMBA:
    from numba import njit
    from numba import types as _nbt

__all__ = ["plan", "prep", "solve", "signatures", "ClosurePlan"]



class ClosurePlan:
    """The legs of ``d`` draws packed into arrays: ``code``, ``act`` (per leg), ``geo``
    (d, legs, 5, 3), ``sc`` (d, legs, 3) as :func:`parasynth.engine.indices._legs_plan` lays
    out one draw, and ``m`` closure rows."""

    __slots__ = ("code", "act", "geo", "sc", "m")

    def __init__(self, code, act, geo, sc):
        self.code, self.act = code, act
        self.geo = np.ascontiguousarray(geo, dtype=float)
        self.sc = np.ascontiguousarray(sc, dtype=float)
        self.m = int(act.sum() + sum(_NC[int(c)] for c in code))

    @property
    def draws(self) -> int:
        return self.geo.shape[0]


#: Geometry slots of :func:`parasynth.engine.indices._legs_plan` per leg type.
_SLOTS = {_SPS: (), _UPS: ("u_axis",), _PUS: ("slider_axis", "u_axis"), _RPS: ("r_axis",),
          _RPU: ("r_axis", "u_platform_axis"), _UPU: ("u_axis", "u_platform_axis"), _PRS: ("slider_axis", "r_axis")}


def plan(leg_sets, fields=None) -> ClosurePlan:
    """The :class:`ClosurePlan` of ``leg_sets`` (a list of draws, each a sequence of legs of the
    same types in the same order; ``fields``: per leg {field: (draws, ...) values}, the draws'
    geometry already stacked). Raises ``_Unsupported`` when a leg has no compiled closure."""
    leg_sets = list(leg_sets)
    first = leg_sets[0]
    _check_legs(first)
    for leg in first:  # the leg type declares whether the closure as built is compiled for it
        require(leg, "closure", _Unsupported)
    for legs in leg_sets:
        if len(legs) != len(first) or any(type(a) is not type(b) for a, b in zip(legs, first)):
            raise _Unsupported("the draws' legs differ in type or number")
    code, act, geo0, sc0, _ = _legs_plan(first)
    nd = len(leg_sets)
    if fields is None:
        geo = np.empty((nd, len(first), 5, 3))
        sc = np.empty((nd, len(first), 3))
        for d, legs in enumerate(leg_sets):
            _, _, geo[d], sc[d], _ = _legs_plan(legs)
        return ClosurePlan(code, act, geo, sc)
    geo = np.repeat(geo0[None], nd, axis=0)
    sc = np.repeat(sc0[None], nd, axis=0)
    for j, leg in enumerate(first):
        fl = fields[j]
        for slot, name in enumerate(("base", "platform") + _SLOTS[int(code[j])]):
            geo[:, j, slot] = fl[name]
        if int(code[j]) in (_PUS, _PRS):
            sc[:, j, 0] = fl["link_length"]
    return ClosurePlan(code, act, geo, sc)


def prep(cp: ClosurePlan, p, R, length_scale: float, draw=None, jacobian: bool = True):
    """(h0 (N, m), Gt (N, m, 6) or None, reach (N,)) at poses ``(p, R)``, row ``i`` with the legs
    of draw ``draw[i]`` (default: draw 0 for every row); the Jacobian (position steps
    ``1e-6 length_scale``) only with ``jacobian``."""
    p = np.ascontiguousarray(p, dtype=float)
    R = np.ascontiguousarray(R, dtype=float)
    n = p.shape[0]
    draw = np.zeros(n, np.int64) if draw is None else np.ascontiguousarray(draw, dtype=np.int64)
    h0 = np.empty((n, cp.m))
    Gt = np.empty((n if jacobian else 0, cp.m, 6))
    reach = np.empty(n, np.bool_)
    _prep_kernel(p, R, draw, cp.code, cp.act, cp.geo, cp.sc, 1e-6 * float(length_scale), 1e-6, h0, Gt, reach)
    return h0, (Gt if jacobian else None), reach


def solve(cp: ClosurePlan, p0, R0, Gi, h0, ok, dq, scale, src, draw, max_iter: int = 20):
    """(converged (N,), p (N, 3), R (N, 3, 3)): chord Newton per row (module documentation)."""
    src = np.ascontiguousarray(src, dtype=np.int64)
    draw = np.ascontiguousarray(draw, dtype=np.int64)
    n = src.shape[0]
    conv = np.empty(n, np.bool_)
    p = np.empty((n, 3))
    R = np.empty((n, 3, 3))
    dq = np.ascontiguousarray(dq, dtype=float).reshape(cp.draws, cp.m)
    _solve_kernel(np.ascontiguousarray(p0, dtype=float), np.ascontiguousarray(R0, dtype=float),
                  np.ascontiguousarray(Gi, dtype=float), np.ascontiguousarray(h0, dtype=float),
                  np.ascontiguousarray(ok, dtype=np.bool_), dq, np.ascontiguousarray(scale, dtype=float),
                  src, draw, cp.code, cp.act, cp.geo, cp.sc, int(max_iter), conv, p, R)
    return conv, p, R


if HAVE_NUMBA:
    _jit = dict(nogil=True, error_model="numpy", fastmath=False, cache=True)

    @njit(**_jit)
    def _unit(x, y, z):
        n = math.sqrt(x * x + y * y + z * z)
        return x / n, y / n, z / n

    @njit(**_jit)
    def _residual(px, py, pz, R, d, code, act, geo, sc, out):
        """Closure residuals (m,) of draw ``d`` at pose (p, R) into ``out``; whether every leg
        reaches the pose (as the legs' ``solve``)."""
        reach = True
        k = 0
        for j in range(code.shape[0]):
            t = code[j]
            qx, qy, qz = geo[d, j, 1, 0], geo[d, j, 1, 1], geo[d, j, 1, 2]
            ax = px + R[0, 0] * qx + R[0, 1] * qy + R[0, 2] * qz
            ay = py + R[1, 0] * qx + R[1, 1] * qy + R[1, 2] * qz
            az = pz + R[2, 0] * qx + R[2, 1] * qy + R[2, 2] * qz
            dx, dy, dz = ax - geo[d, j, 0, 0], ay - geo[d, j, 0, 1], az - geo[d, j, 0, 2]
            e0, e1, e2 = geo[d, j, 2, 0], geo[d, j, 2, 1], geo[d, j, 2, 2]
            length = math.sqrt(dx * dx + dy * dy + dz * dz)
            if t == _PUS or t == _PRS:
                Ll = sc[d, j, 0]
                de = dx * e0 + dy * e1 + dz * e2
                disc = Ll * Ll - (dx * dx + dy * dy + dz * dz - de * de)
                if not disc >= 0.0:
                    reach = False
                if act[j]:
                    out[k] = de + sc[d, j, 1] * math.sqrt(disc) if disc >= 0.0 else np.nan
                    k += 1
                if t == _PRS:
                    f0, f1, f2 = geo[d, j, 3, 0], geo[d, j, 3, 1], geo[d, j, 3, 2]
                    off = dx * f0 + dy * f1 + dz * f2
                    if not abs(off) <= GEOM_TOL * max(1.0, Ll):
                        reach = False
                    out[k] = off
                    k += 1
                continue
            if not (length > 0.0 and length < np.inf):
                reach = False
            if act[j]:
                out[k] = length
                k += 1
            if t == _RPS or t == _RPU:
                off = dx * e0 + dy * e1 + dz * e2
                if not abs(off) <= GEOM_TOL * max(1.0, length):
                    reach = False
                out[k] = off
                k += 1
            if t == _RPU or t == _UPU:
                ux, uy, uz = geo[d, j, 3, 0], geo[d, j, 3, 1], geo[d, j, 3, 2]
                a4x = R[0, 0] * ux + R[0, 1] * uy + R[0, 2] * uz
                a4y = R[1, 0] * ux + R[1, 1] * uy + R[1, 2] * uz
                a4z = R[2, 0] * ux + R[2, 1] * uy + R[2, 2] * uz
                if t == _RPU:
                    s = a4x * e0 + a4y * e1 + a4z * e2
                    if not abs(s) <= GEOM_TOL:
                        reach = False
                    out[k] = s
                else:  # the twist angle between the cross axes: atan2((cb x cp) . n, cb . cp)
                    nx, ny, nz = dx / length, dy / length, dz / length
                    bx, by, bz = _unit(e1 * nz - e2 * ny, e2 * nx - e0 * nz, e0 * ny - e1 * nx)
                    cx, cy, cz = _unit(a4y * nz - a4z * ny, a4z * nx - a4x * nz, a4x * ny - a4y * nx)
                    sx, sy, sz = by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx
                    out[k] = math.atan2(sx * nx + sy * ny + sz * nz, bx * cx + by * cy + bz * cz)
                k += 1
        return reach

    @njit(**_jit)
    def _compose(p0, R0, s, t, R):
        """p0[s] + t[:3] and exp([t[3:]]) R0[s] (into R), as ``accuracy._compose``."""
        wx, wy, wz = t[3], t[4], t[5]
        ang = math.sqrt(wx * wx + wy * wy + wz * wz)
        if ang > 0.0:
            x, y, z = wx / ang, wy / ang, wz / ang
        else:
            x, y, z = 1.0, 0.0, 0.0
        sn, cs = math.sin(ang), math.cos(ang)
        C = 1.0 - cs
        # I + sin K + (1 - cos) K^2 (rot_axis), K the cross-product matrix of the unit axis
        q00, q01, q02 = 1.0 - C * (y * y + z * z), C * x * y - sn * z, C * x * z + sn * y
        q10, q11, q12 = C * x * y + sn * z, 1.0 - C * (x * x + z * z), C * y * z - sn * x
        q20, q21, q22 = C * x * z - sn * y, C * y * z + sn * x, 1.0 - C * (x * x + y * y)
        for c in range(3):
            r0, r1, r2 = R0[s, 0, c], R0[s, 1, c], R0[s, 2, c]
            R[0, c] = q00 * r0 + q01 * r1 + q02 * r2
            R[1, c] = q10 * r0 + q11 * r1 + q12 * r2
            R[2, c] = q20 * r0 + q21 * r1 + q22 * r2
        return p0[s, 0] + t[0], p0[s, 1] + t[1], p0[s, 2] + t[2]

    @njit(**_jit)
    def _prep_kernel(p, R, draw, code, act, geo, sc, hl, ha, h0, Gt, reach):
        m = h0.shape[1]
        t = np.zeros(6)
        Rt = np.empty((3, 3))
        hp = np.empty(m)
        hm = np.empty(m)
        for i in range(p.shape[0]):
            d = draw[i]
            reach[i] = _residual(p[i, 0], p[i, 1], p[i, 2], R[i], d, code, act, geo, sc, h0[i])
            if Gt.shape[0] == 0:  # residuals and reachability only
                continue
            for c in range(6):
                h = hl if c < 3 else ha
                t[:] = 0.0
                t[c] = h
                px, py, pz = _compose(p, R, i, t, Rt)
                _residual(px, py, pz, Rt, d, code, act, geo, sc, hp)
                t[c] = -h
                px, py, pz = _compose(p, R, i, t, Rt)
                _residual(px, py, pz, Rt, d, code, act, geo, sc, hm)
                for q in range(m):
                    Gt[i, q, c] = (hp[q] - hm[q]) / (2.0 * h)

    @njit(**_jit)
    def _solve_kernel(p0, R0, Gi, h0, ok, dq, scale, src, draw, code, act, geo, sc, max_iter, conv, p, R):
        m = h0.shape[1]
        t = np.zeros(6)
        r = np.empty(m)
        for i in range(src.shape[0]):
            s, d = src[i], draw[i]
            t[:] = 0.0
            done = False
            reach = False
            px, py, pz = _compose(p0, R0, s, t, R[i])
            if ok[s]:
                for _ in range(max_iter):
                    px, py, pz = _compose(p0, R0, s, t, R[i])
                    reach = _residual(px, py, pz, R[i], d, code, act, geo, sc, r)
                    done = True
                    for q in range(m):
                        r[q] -= h0[s, q] + dq[d, q]
                        if not abs(r[q]) <= 1e-12 * scale[q]:
                            done = False
                    if done:
                        break
                    for a in range(6):
                        acc = 0.0
                        for q in range(m):
                            if math.isfinite(r[q]):
                                acc += Gi[s, a, q] * r[q]
                        t[a] -= acc
                if not done:
                    px, py, pz = _compose(p0, R0, s, t, R[i])
            conv[i] = done and reach
            p[i, 0], p[i, 1], p[i, 2] = px, py, pz

else:  # pragma: no cover - numba missing: the callers run the NumPy closure
    def _prep_kernel(*args):
        raise _Unsupported("numba is not available")

    def _solve_kernel(*args):
        raise _Unsupported("numba is not available")


def signatures() -> dict:
    """{kernel name: (dispatcher, argument types)}, as :func:`parasynth.engine.core.signatures`."""
    if not HAVE_NUMBA:
        return {}
    f1, f2, f3, f4 = _array("f8", 1), _array("f8", 2), _array("f8", 3), _array("f8", 4)
    i1, b1 = _array("i8", 1), _array("b1", 1)
    i8, f8 = _nbt.int64, _nbt.float64
    return {
        "_prep_kernel": (_prep_kernel, (f2, f3, i1, i1, i1, f4, f3, f8, f8, f2, f3, b1)),
        "_solve_kernel": (_solve_kernel, (f2, f3, f3, f2, b1, f2, f1, i1, i1, i1, i1, f4, f3, i8, b1, f2, f3)),
    }
