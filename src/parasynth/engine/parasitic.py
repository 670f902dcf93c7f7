"""The compiled solve of ``task.solve``: the dependent pose coordinates as nodes of the pose
program (:mod:`parasynth.engine.program`), the same Gauss-Newton solve of the legs' closure
equations as the NumPy reference :mod:`parasynth.model.parasitic`.

The program is straight-line code, so the solve is unrolled: from the home solution (parameter
slots, so that one program serves every design of a description), :data:`ITERATIONS` damped
Gauss-Newton steps, each with the closure residuals and their exact Jacobian (forward-mode
derivatives of the residual graph with respect to the unknowns, then the unknowns of the step
substituted), the step from the normal equations by a Cholesky factorisation, limited to half a
scale per unknown as in the reference. A pose is valid only if the last residuals are within
``10 * SOLVE_TOL`` (the reference's test; beyond it the NumPy path gives NaN). The twist map
takes the derivative of the unknowns by the implicit function theorem at the solution,
``dU/dX = -(J_U^T J_U)^-1 J_U^T J_X`` (seeded into the program's forward-mode derivatives), not
through the unrolled iterations.

Assumptions, the reference's: the closure equations of :mod:`parasynth.model.parasitic` (RPS,
PRS, RPU, UPU), their Jacobian in the unknowns of full column rank at the solution (a
structure's rule chooses the dependent coordinates so); both take :data:`ITERATIONS` steps from home
at most (the reference stops early where converged, after one more step); a pose converging only
later is unreachable on both paths, up to rounding at the tolerance. The program's check against
the reference (``core._check_program``) refuses the compiled path where they disagree on its
probe poses.

This module builds graph nodes only; it imports nothing of the engine (the graph and its
derivative class are passed in).
"""

from __future__ import annotations

from ..model.parasitic import CLOSURE_COUNTS, GEOMETRY_WIDTH, SOLVE_ITERATIONS, SOLVE_TOL

__all__ = ["ITERATIONS", "solve_nodes"]

#: Unrolled Gauss-Newton steps of the compiled solve (the reference's budget at a pose).
ITERATIONS = SOLVE_ITERATIONS


def _p(g, key, q):
    return g.param((key, (q,)))


def _dot(g, a, b):
    acc = g.mul(a[0], b[0])
    for u, v in zip(a[1:], b[1:]):
        acc = g.add(acc, g.mul(u, v))
    return acc


def _matvec(g, R, v):
    return [_dot(g, R[i], v) for i in range(3)]


def _cross(g, a, b):
    return [g.sub(g.mul(a[1], b[2]), g.mul(a[2], b[1])), g.sub(g.mul(a[2], b[0]), g.mul(a[0], b[2])),
            g.sub(g.mul(a[0], b[1]), g.mul(a[1], b[0]))]


def residual_nodes(g, joints, key, off, pos, R, L):
    """The closure residual nodes of legs of types ``joints`` (the geometry in parameter slots
    ``key`` from ``off``, :func:`parasynth.model.parasitic.closure_geometry`) at the pose nodes
    ``pos`` (3) and ``R`` (3x3)."""
    out = []
    for k, j in enumerate(joints):
        n = CLOSURE_COUNTS[j]
        if n == 0:
            continue
        o = off + k * GEOMETRY_WIDTH
        base = [_p(g, key, o + i) for i in range(3)]
        plat = [_p(g, key, o + 3 + i) for i in range(3)]
        a1 = [_p(g, key, o + 6 + i) for i in range(3)]
        a2 = [_p(g, key, o + 9 + i) for i in range(3)]
        A = [g.add(pos[i], x) for i, x in enumerate(_matvec(g, R, plat))]
        d = [g.sub(A[i], base[i]) for i in range(3)]
        if j in ("RPS", "PRS", "RPU"):
            out.append(g.div(_dot(g, d, a1), L))
            if j == "RPU":
                out.append(_dot(g, _matvec(g, R, a2), a1))
        elif j == "UPU":
            a4 = _matvec(g, R, a2)
            out.append(g.div(_dot(g, _cross(g, a1, d), a4), g.op("sqrt", _dot(g, d, d))))
        else:  # pragma: no cover (CLOSURE_COUNTS names the types with equations)
            raise ValueError(f"closure equations of {j}")
    return out


class _Subst:
    """Nodes of the graph with the placeholder inputs replaced (memoised per substitution)."""

    def __init__(self, g, mapping: dict):
        self.g, self.map, self.memo = g, mapping, {}

    def __call__(self, i):
        r = self.memo.get(i)
        if r is not None:
            return r
        if i in self.map:
            r = self.map[i]
        else:
            t = self.g.nodes[i]
            if t[0] in ("c", "x", "p"):
                r = i
            else:
                memo = self.memo
                args = tuple([memo[a] if a in memo else self(a) for a in t[1:]])  # (the call only when new)
                r = i if args == t[1:] else self.g.op(t[0], *args)
        self.memo[i] = r
        return r


def _normal_solve(g, J, F):
    """Nodes of ``z`` with ``(J^T J + mu I) z = J^T F`` (J: k x m nodes, F: k nodes, or k x c for
    several right-hand sides) by Cholesky; m small."""
    m = len(J[0])
    cols = F if isinstance(F[0], list) else [[f] for f in F]
    c = len(cols[0])
    A = [[_dot(g, [row[i] for row in J], [row[j] for row in J]) for j in range(m)] for i in range(m)]
    # Levenberg-Marquardt's tiny damping, 1e-12 of the mean diagonal: a rank-deficient J (a
    # degenerate pose, dependent equations) gives a finite step, nearly the reference's
    # minimum-norm one; a full-rank J a step unchanged to ~1e-12
    tr = A[0][0]
    for i in range(1, m):
        tr = g.add(tr, A[i][i])
    mu = g.add(g.mul(tr, g.const(1e-12 / m)), g.const(1e-300))
    A = [[g.add(A[i][j], mu) if i == j else A[i][j] for j in range(m)] for i in range(m)]
    B = [[_dot(g, [row[i] for row in J], [r[q] for r in cols]) for q in range(c)] for i in range(m)]
    Lc = [[None] * m for _ in range(m)]
    for i in range(m):
        for j in range(i + 1):
            s = A[i][j]
            for k in range(j):
                s = g.sub(s, g.mul(Lc[i][k], Lc[j][k]))
            Lc[i][j] = g.op("sqrt", s) if i == j else g.div(s, Lc[j][j])
    Y = [[None] * c for _ in range(m)]
    for q in range(c):
        for i in range(m):
            s = B[i][q]
            for k in range(i):
                s = g.sub(s, g.mul(Lc[i][k], Y[k][q]))
            Y[i][q] = g.div(s, Lc[i][i])
    Z = [[None] * c for _ in range(m)]
    for q in range(c):
        for i in reversed(range(m)):
            s = Y[i][q]
            for k in range(i + 1, m):
                s = g.sub(s, g.mul(Lc[k][i], Z[k][q]))
            Z[i][q] = g.div(s, Lc[i][i])
    return Z if isinstance(F[0], list) else [z[0] for z in Z]


def solve_nodes(g, diff_cls, joints, key, n, m, pose_of):
    """The unrolled solve. ``pose_of(unknown nodes)`` builds the pose nodes ``(pos, R)`` with the
    unknowns given; ``n`` task coordinates (inputs ``x(0..n-1)``), ``m`` unknowns; the slots of
    ``key``: length scale, home solution (m), scales (m), then the legs' geometry.

    Returns ``(U, chain, valid, seed)``: the solution nodes (m), the iterates (to emit in order,
    which keeps the emitter's recursion shallow), the validity node (residuals within
    tolerance) and ``{(U_i, j): dU_i/dX_j}`` to seed the forward-mode derivatives."""
    L = _p(g, key, 0)
    U0 = [_p(g, key, 1 + i) for i in range(m)]
    us = [_p(g, key, 1 + m + i) for i in range(m)]
    off = 1 + 2 * m
    ph = [g.x(n + i) for i in range(m)]  # placeholders, all substituted below
    pos, R = pose_of(ph)
    F = residual_nodes(g, joints, key, off, pos, R, L)
    if len(F) < m:
        raise ValueError(f"{len(F)} closure equation(s) for {m} unknowns")
    d = diff_cls(g)
    JU = [[g.mul(d(f, n + i), us[i]) for i in range(m)] for f in F]  # in scaled unknowns
    JX = [[d(f, j) for j in range(n)] for f in F]
    half, tiny, one = g.const(0.5), g.const(1e-300), g.const(1.0)
    U, chain = list(U0), []
    for _ in range(ITERATIONS):
        sb = _Subst(g, dict(zip(ph, U)))
        Fk = [sb(f) for f in F]
        Jk = [[sb(x) for x in row] for row in JU]
        dz = _normal_solve(g, Jk, Fk)
        big = g.op("abs", dz[0])
        for z in dz[1:]:
            big = g.op("max", big, g.op("abs", z))
        fac = g.op("min", one, g.div(half, g.op("max", big, tiny)))
        U = [g.sub(u, g.mul(g.mul(z, fac), s)) for u, z, s in zip(U, dz, us)]
        chain.append(U)
    sb = _Subst(g, dict(zip(ph, U)))
    Ff = [sb(f) for f in F]
    worst = g.op("abs", Ff[0])
    for f in Ff[1:]:
        worst = g.op("max", worst, g.op("abs", f))
    valid = g.op("le", worst, g.const(10.0 * SOLVE_TOL))
    seed = {}
    if n:
        Jf = [[sb(x) for x in row] for row in JU]
        Xf = [[sb(x) for x in row] for row in JX]
        G = _normal_solve(g, Jf, Xf)  # (m, n) in scaled unknowns: dU_s/dX = -G
        for i in range(m):
            for j in range(n):
                seed[(U[i], j)] = g.neg(g.mul(G[i][j], us[i]))
    return U, chain, valid, seed
