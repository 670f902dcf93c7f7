""":class:`DescribedMechanism`: the :class:`~parasynth.model.mechanism.Mechanism` of a description
(pose and twist map from the task expressions, construction checks, mobility with
consistency checks). Its feasibility, constraint margins, singularity margin and constraint
rank run on the compiled engine (:mod:`parasynth.engine`) by default: the NumPy model
above which the engine sits has only the NumPy reference.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass

import numpy as np

from ... import engine as _engine
from ...model.legs import solve_geometry
from ...model.mechanism import Mechanism, Mobility
from ...model.parasitic import (HOME_ITERATIONS, SOLVE_KEY, ParasiticError, closure_count, closure_geometry, closure_jacobian,
                                closure_residuals, gauss_newton, implicit_gradient)
from ...model.spatial import euler_matrix_and_rate, reciprocal_basis, rot_axis, skew
from ...common.units import UNIT_KINDS
from .errors import DescriptionError, DescriptionWarning
from .expressions import R_NAMES, _Dual, _grad, _val
from .parameters import _param_env, values_key
from .schema import Description


def _columns(values, N: int) -> np.ndarray:
    """The values of expressions (scalars or (N,) arrays, or their duals' values) as the
    columns of an (N, k) float array: what ``np.stack`` of each broadcast to (N,) gives,
    converted to float, with one allocation and no broadcast views (a pose expression is
    evaluated ~25 times a design of a structure with solved coordinates)."""
    out = np.empty((N, len(values)))
    for j, v in enumerate(values):
        out[:, j] = _val(v)
    return out


@dataclass(frozen=True)
class DescribedMobility(Mobility):
    """:class:`~parasynth.model.mechanism.Mobility` of a described mechanism with the findings of
    its consistency checks: ``issues`` (messages, each also issued as a
    :class:`DescriptionWarning`), ``under_actuated`` (the actuators do not control every
    freedom) and ``consistent`` (the task parametrisation agrees with what the legs allow)."""

    issues: tuple = ()
    under_actuated: bool = False
    consistent: bool = True

    def summary(self) -> str:
        s = super().summary()
        if self.issues:
            s += "\nissues:\n  " + "\n  ".join(self.issues)
        return s


class DescribedMechanism(Mechanism):
    """A mechanism built from a :class:`Description`. Subclasses are made by
    :func:`description_class`; instantiate them with a ``Params`` object (SI) or nothing for the
    description's defaults.

    With variants, ``self.description`` is the description resolved for the instance's
    choices (cached per choice on the class), and ``task_coordinates`` /
    ``angular_coordinates`` are the instance's; the class attributes are the defaults'."""

    description: Description
    Params: type

    #: {variant name: Variant} of the description (empty without variants).
    variants: dict = {}

    def __init__(self, params=None):
        P = self.Params() if params is None else params
        if not isinstance(P, self.Params):
            raise ValueError(f"{self.name}: params must be a {self.Params.__name__} (use {self.name}.Params(...) or "
                             f"load_mechanism(..., **params))")
        if self.variants:
            # The resolved description of this instance's variant choice (parsed once, cached).
            d = self._description_for({k: getattr(P, k) for k in self.variants})
            self.description = d
            self.task_coordinates = d.task.names
            ang = d.__dict__.get("_angular_coordinates")  # one frozenset per resolved description
            if ang is None:
                ang = d._angular_coordinates = frozenset(c for c, k in d.task.coords if k == "angle")
            self.angular_coordinates = ang
        else:
            d = self.description
        self.params = P
        kept = P.__dict__.get("_env")  # the environment the parameters' checks used, as a copy of its own
        self._penv = dict(kept[1]) if kept is not None and kept[0] is d.params else _param_env(P, d.params)
        try:
            legs, home, L = d.build_geometry(self._penv)
        except DescriptionError as e:
            raise DescriptionError(f"{self.name}: {e}") from None
        try:
            #: {leg name: {key: SI value}} declared by the description's ``stiffness:`` section
            #: (see :mod:`.stiffness`); :func:`parasynth.stiffness_matrix` uses them.
            self.declared_stiffness = d.stiffness.values(self._penv)
        except DescriptionError as e:
            raise DescriptionError(f"{self.name}: {e}") from None
        self.home = np.asarray(home, dtype=float)
        self._solve_cache = None
        if d.task.solve is not None:
            self._init_solve(d.task.solve, legs, L)
        self._check_pose_expressions(self.home)
        try:
            super().__init__(P, legs, home, L)  # solves the legs at home (_neutral_refs)
        except DescriptionError:
            raise
        except ValueError as e:
            raise DescriptionError(f"{self.name}: task.home: {e}") from None
        # Evaluating every margin at home catches constraints the description cannot build
        # (unknown joint angle keys, ...): a property of the resolved description, checked once.
        self._check_constraints(margins=not getattr(d, "_margins_checked", False))
        d._margins_checked = True

    @classmethod
    def _description_for(cls, selection: dict) -> Description:
        """The description resolved for a variant selection (see :func:`description_class`)."""
        return cls.description

    def _output(self, spec, X):
        """Evaluate the output ``spec`` (:mod:`.outputs`) at poses X."""
        Xa, single = self._poses(X)
        p, R = self._pose(Xa)
        env = self._task_env(Xa)
        for k, nm in enumerate(("px", "py", "pz")):
            env[nm] = p[:, k]
        for nm in R_NAMES:
            env[nm] = R[:, int(nm[1]) - 1, int(nm[2]) - 1]
        N = Xa.shape[0]
        with np.errstate(all="ignore"):
            vals = [np.broadcast_to(np.asarray(e(env), dtype=float), (N,)) for e in spec.exprs]
        out = np.stack(vals, -1) if spec.vector else vals[0].copy()
        return out[0] if single else out

    # -- solved (parasitic) coordinates: task.solve ------------------------------------------------
    def _init_solve(self, solve, legs, L):
        """Solve the unknowns of ``task.solve`` at home (from ``task.solve.start``); the home
        solution starts the solve at every other pose."""
        self._solve_legs, self._solve_L = legs, float(L)
        ang = set(self.angular_coordinates)
        self._solve_xscale = np.array([1.0 if c in ang else L for c in self.task_coordinates])
        self._solve_uscale = np.array([1.0 if k == "angle" else L for _, k in solve.coords])
        self._solve_U0 = np.array([s(self._penv) for s in solve.start], dtype=float)
        m = len(solve.names)
        try:
            k = sum(closure_count(leg) for leg in legs)
        except ParasiticError as e:
            raise DescriptionError(f"{self.name}: task.solve: {e}") from None
        if k < m:
            raise DescriptionError(f"{self.name}: task.solve.unknowns: {m} unknowns ({', '.join(solve.names)}) but the "
                                   f"legs give {k} closure equation(s); allowed: at most {k} unknowns")
        U, ok = gauss_newton(self._closure, self.home[None, :], self._solve_U0, self._solve_uscale,
                             iterations=HOME_ITERATIONS)
        if not ok[0]:
            raise DescriptionError(f"{self.name}: task.solve: the legs' closure equations have no solution near "
                                   f"task.solve.start at the home pose {self.home.tolist()}")
        self._solve_U0 = U[0]
        FU = np.linalg.svd(closure_jacobian(self._closure, self.home[None, :], U, self._solve_uscale)[0],
                           compute_uv=False)
        rank = int(np.sum(FU > 1e-8 * max(FU[0], 1e-300)))
        if rank < m:
            raise DescriptionError(f"{self.name}: task.solve.unknowns: the closure equations fix only {rank} of the "
                                   f"{m} unknowns ({', '.join(solve.names)}) at the home pose; name as unknowns the "
                                   f"coordinates the legs' constraints determine")
        # what the compiled solve reads as parameter slots (engine/parasitic.py): the length scale,
        # the home solution, the unknowns' scales and the legs' closure geometry
        self._penv = dict(self._penv)
        self._penv[SOLVE_KEY] = np.concatenate([[float(L)], self._solve_U0, self._solve_uscale,
                                                closure_geometry(legs)])

    def _closure(self, X, U, chain=None):
        """The legs' closure residuals (N, k) at task coordinates X with the unknowns U
        (``chain``: as in :func:`parasynth.model.parasitic.closure_residuals`)."""
        p, R, _, _ = self._pose_eval(X, False, U=U)
        return closure_residuals(self._solve_legs, p, R, self._solve_L, chain)

    def solve_unknowns(self, X, chain=None) -> np.ndarray:
        """The unknowns of ``task.solve`` (N, m) at task coordinates X by the Gauss-Newton
        solve of :meth:`solved_unknowns` (NaN where it does not converge), not kept;
        ``chain(leg, p, R)`` gives the closure equations of chain limbs by another solve than
        their own (the compiled one: :mod:`parasynth.engine.chains`)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if self.description.task.solve is None:
            return np.zeros((X.shape[0], 0))
        U, _ = gauss_newton(lambda X, U: self._closure(X, U, chain), X, self._solve_U0, self._solve_uscale)
        return U

    def solved_unknowns(self, X) -> np.ndarray:
        """The unknowns of ``task.solve`` (N, m) at task coordinates X (N, n_task) (SI; NaN where
        the solve does not converge); (N, 0) without ``task.solve``."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if self.description.task.solve is None:
            return np.zeros((X.shape[0], 0))
        c = self._solve_cache
        if c is not None and c[0].shape == X.shape and np.array_equal(c[0], X, equal_nan=True):
            if not callable(c[1]):
                return c[1]
            U = c[1]()  # unknowns offered by use_solved_unknowns, computed at their first use
            if U is not None and U.shape == (X.shape[0], len(self._solve_uscale)) and \
                    (c[2] or np.all(np.isfinite(U))):
                self._solve_cache = (c[0], U)
                return U
        U = self.solve_unknowns(X)
        self._solve_cache = (X.copy(), U)
        return U

    def use_solved_unknowns(self, X, U, partial: bool = False) -> None:
        """Take ``U`` (N, m) as the unknowns of ``task.solve`` at poses X (N, n_task) from now
        until other poses are asked for (``solved_unknowns`` keeps one set): a measure that
        evaluates the NumPy model at poses whose unknowns the compiled engine solved
        (:func:`parasynth.engine.solved_unknowns`) spares the NumPy solve. ``U`` must be a
        solution of the closure equations at X (finite, every row), or a function giving it
        (or None), called when the NumPy model first asks for the unknowns at X: where it
        gives none, or not finite ones, the NumPy solve runs as without it. With ``partial``
        (a function only) its NaN rows are taken as poses where the solve does not converge,
        as the NumPy solve marks them (the chain limbs' closure solved by the compiled solve,
        :mod:`parasynth.engine.chains`)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if callable(U):
            if self.description.task.solve is None:
                raise ValueError(f"{self.name}: no task.solve, no unknowns")
            self._solve_cache = (X.copy(), U, bool(partial))
            return
        if partial:
            raise ValueError(f"{self.name}: partial unknowns are given by a function")
        U = np.asarray(U, dtype=float)
        if self.description.task.solve is None or U.shape != (X.shape[0], len(self._solve_uscale)):
            raise ValueError(f"{self.name}: unknowns of shape {U.shape} for {X.shape[0]} poses and "
                             f"{len(getattr(self, '_solve_uscale', ()))} unknowns")
        if not np.all(np.isfinite(U)):
            raise ValueError(f"{self.name}: unknowns that are not finite")
        self._solve_cache = (X.copy(), U.copy())

    # -- pose ------------------------------------------------------------------------------------
    def _task_env(self, X, dual: bool = False, U=None, chain=None) -> dict:
        """Parameters, task coordinates, solved unknowns (``task.solve``; given as ``U`` (N, m),
        or solved) and defined names for poses X (N, n_task); ``chain``: the chain limbs'
        closure for the unknowns' derivatives, as in :meth:`solve_unknowns`."""
        env = dict(self._penv)
        N, n = X.shape
        if dual:
            eye = np.eye(n)
            for j, c in enumerate(self.task_coordinates):
                env[c] = _Dual(X[:, j], np.broadcast_to(eye[j], (N, n)))
        else:
            for j, c in enumerate(self.task_coordinates):
                env[c] = X[:, j]
        solve = self.description.task.solve
        if solve is not None:
            if U is None:
                U = self.solved_unknowns(X)
            if dual:
                G = implicit_gradient(lambda Xq, Uq: self._closure(Xq, Uq, chain), X, U, self._solve_xscale,
                                      self._solve_uscale)
                for j, c in enumerate(solve.names):
                    env[c] = _Dual(U[:, j], G[:, j, :])
            else:
                for j, c in enumerate(solve.names):
                    env[c] = U[:, j]
        with np.errstate(all="ignore"):
            for name, e in self.description.task.defines:
                env[name] = e(env, dual)
        return env

    def _rotation(self, a: np.ndarray, rate: bool = True):
        """R (N, 3, 3) and E (N, 3, k) with omega = E @ angle rates, for angles a (N, k) (E
        may be None with ``rate=False``)."""
        t = self.description.task
        N = a.shape[0]
        if t.convention is not None:
            return euler_matrix_and_rate(t.convention, a, rate)
        if not t.rot_axes:
            return np.broadcast_to(np.eye(3), (N, 3, 3)).copy(), np.zeros((N, 3, 0))
        R = np.broadcast_to(np.eye(3), (N, 3, 3))
        cols = []
        for k, ax in enumerate(t.rot_axes):
            cols.append(R @ ax)
            R = R @ rot_axis(ax, a[:, k])
        return R, np.stack(cols, axis=-1)

    def _pose_eval(self, X, dual: bool, U=None, chain=None):
        t = self.description.task
        N, n = X.shape
        env = self._task_env(X, dual, U, chain)
        with np.errstate(all="ignore"):
            angs = [e(env, dual) for e in t.angles]
            a = _columns(angs, N)
            R, E = self._rotation(a, rate=dual)
            W = None
            if dual:
                da = (np.stack([np.broadcast_to(_grad(v), (N, n)) for v in angs], 1) if angs
                      else np.zeros((N, 0, n)))
                W = E @ da  # (N, 3, n): angular velocity per unit coordinate rate
            if t.position_uses_R:
                if dual:
                    # dR/dX_t = skew(omega_t) R, omega_t = W[:, :, t]
                    dR = np.einsum("ntij,njk->nikt", skew(np.moveaxis(W, -1, 1)), R)
                for nm in R_NAMES:
                    i, j = int(nm[1]) - 1, int(nm[2]) - 1
                    env[nm] = _Dual(R[:, i, j], dR[:, i, j, :]) if dual else R[:, i, j]
            pos = [e(env, dual) for e in t.position]
            p = _columns(pos, N)
            dp = np.stack([np.broadcast_to(_grad(v), (N, n)) for v in pos], 1) if dual else None
        return p, np.ascontiguousarray(R, dtype=float), dp, W

    def _pose(self, X):
        p, R, _, _ = self._pose_eval(X, False)
        return p, R

    def _twist_map(self, X, chain=None):
        _, _, dp, W = self._pose_eval(X, True, chain=chain)
        T = np.zeros((X.shape[0], 6, self.n_task))
        T[:, :3] = dp
        T[:, 3:] = W
        return T

    def pose_valid(self, X):
        ok = np.all(np.isfinite(X), axis=-1)
        Xs = np.where(ok[:, None], X, self.home)
        t = self.description.task
        if t.valid:
            env = self._task_env(Xs)
            with np.errstate(all="ignore"):
                for c in t.valid:
                    ok = ok & np.broadcast_to(np.asarray(c(env), dtype=bool), ok.shape)
        p, R = self._pose(Xs)
        return ok & np.all(np.isfinite(p), axis=-1) & np.all(np.isfinite(R), axis=(-1, -2))

    def default_ranges(self) -> dict:
        out = {}
        for c, (lo, hi) in self.description.task.ranges.items():
            out[c] = (lo(self._penv), hi(self._penv))
        return out

    def build_constraints(self):
        # Every constraint a value of the parameters it reads (all types but expression and
        # leg_axis_angle): the whole list kept per those values, as each constraint is.
        d = self.description
        names = d.__dict__.get("_constraint_inputs", False)
        if names is False:
            parts = [c.inputs() for c in d.constraints]
            names = d._constraint_inputs = (None if any(p is None for p in parts)
                                            else tuple(sorted({n for p in parts for n in p})))
        key = values_key(self._penv, names) if names is not None else None
        if key is None:
            return [c.build(self) for c in d.constraints]
        memo = d.__dict__.setdefault("_constraints_built", {})
        hit = memo.get(key)
        if hit is None:
            hit = tuple(c.build(self) for c in d.constraints)
            if len(memo) >= 64:
                memo.clear()
            memo[key] = hit
        return list(hit)

    # -- construction checks ---------------------------------------------------------------------
    def _home_pose_key(self, home):
        """The inputs of the pose expressions at ``home``: the home pose and the values of the
        parameters the task's expressions name (exactly, as bytes); None with ``task.solve``
        (the solved unknowns depend on the legs). Designs that change only the legs' geometry
        share it, and with it the checked home pose."""
        d = self.description
        t = d.task
        if t.solve is not None:
            return None
        names = d.__dict__.get("_pose_param_names")
        if names is None:
            used = set()
            for e in [e for _, e in t.defines] + list(t.angles) + list(t.position) + list(t.valid):
                used |= set(e.names)
            names = d._pose_param_names = tuple(sorted(n for n in used if n in {q.name for q in d.params}))
        penv = self._penv
        return (id(d), np.asarray(home, dtype=float).tobytes(),
                tuple(np.asarray(penv[n], dtype=float).tobytes() for n in names))

    def _check_pose_expressions(self, home):
        key = self._home_pose_key(home)
        memo = type(self).__dict__.get("_HOME_POSES")
        if memo is None:
            memo = {}
            type.__setattr__(type(self), "_HOME_POSES", memo)
        hit = memo.get(key) if key is not None else None
        if hit is not None and hit[0] is self.description:
            self._home_pose = (hit[1].copy(), hit[2].copy())  # checked before: finite, valid
            return
        X = home[None, :]
        try:
            p, R, dp, W = self._pose_eval(X, True)
        except DescriptionError as e:
            raise DescriptionError(f"{self.name}: {e}") from None
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(R)) and np.all(np.isfinite(dp))
                and np.all(np.isfinite(W))):
            raise DescriptionError(f"{self.name}: task.home: the pose expressions are not finite at the home pose "
                                   f"{home.tolist()}")
        valid = self.description.task.valid
        if valid:
            env = self._task_env(X)
            with np.errstate(all="ignore"):
                ok = all(bool(np.all(c(env))) for c in valid)
            if not ok:
                raise DescriptionError(f"{self.name}: task.home: the home pose {home.tolist()} fails task.valid")
        self._home_pose = (p, R)  # reused by _neutral_refs
        if key is not None:
            if len(memo) >= 64:
                memo.clear()
            memo[key] = (self.description, p.copy(), R.copy())

    def _neutral_refs(self, legs):
        """Each leg's neutral joint directions: its direction at home (as
        :meth:`Mechanism._neutral_refs`), after checking that every leg reaches home. ``legs``
        are the ones :meth:`Description.build_geometry` built for this mechanism: most are given
        their directions in place."""
        p, R = self.__dict__.pop("_home_pose", None) or self._pose(self.home[None, :])
        self._home_platform_pose = (self.home.copy(), p, R)
        out = []
        pf, Rf = p[0].tolist(), R[0].ravel().tolist()
        units = []  # (index in out, the two unit directions as floats) of the legs done in floats
        for leg in legs:
            # the direction in Python floats where the leg type computes it so (a dozen NumPy
            # calls less per leg), else, or to say why the leg does not reach home, its solve
            try:
                hd = leg.home_direction(pf, Rf)
            except (ValueError, OverflowError, ZeroDivisionError):
                hd = None
            if hd is not None and hd is not NotImplemented:
                x, y, z = hd
                if math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and (x or y or z):
                    nx, ny, nz = -x, -y, -z
                    pr = (Rf[0] * nx + Rf[3] * ny + Rf[6] * nz, Rf[1] * nx + Rf[4] * ny + Rf[7] * nz,
                          Rf[2] * nx + Rf[5] * ny + Rf[8] * nz)
                    # each made a unit vector as _unit_xyz makes it (one division per entry),
                    # all of them then one array whose rows the legs keep
                    nb, npf = math.sqrt(x * x + y * y + z * z), math.sqrt(pr[0] * pr[0] + pr[1] * pr[1] + pr[2] * pr[2])
                    if nb > 0 and npf > 0:
                        units.append((len(out), (x / nb, y / nb, z / nb), (pr[0] / npf, pr[1] / npf, pr[2] / npf)))
                        out.append(leg)
                    else:  # (a direction too small to square: _unit_xyz says so)
                        out.append(leg.with_unit_neutral(hd, pr))
                    continue
            with np.errstate(all="ignore"):
                st = solve_geometry(leg, p, R)
            n = st.direction[0]
            x, y, z = n.tolist()  # three floats: Python's tests cost a tenth of NumPy's reductions
            if not (st.reachable[0] and math.isfinite(x) and math.isfinite(y) and math.isfinite(z)) \
                    or not (x or y or z):
                why = ""
                if not np.isfinite(st.actuator[0]) and leg.actuator_kind == "angle":  # a crank
                    why = " (its platform anchor is out of the link's reach from every crank position)"
                elif not np.isfinite(st.actuator[0]):
                    why = " (its platform anchor is further than link_length from its slider line)"
                elif "off_plane" in st.extra:
                    why = (f" (its platform anchor is {st.extra['off_plane'][0] * UNIT_KINDS['length'].factor:.4g} "
                           f"{UNIT_KINDS['length'].display} off the plane its "
                           f"revolute joint allows: the position or orientation misses a dependent coordinate?)")
                raise DescriptionError(f"{self.name}: task.home: the home pose {self.home.tolist()} is not reachable "
                                       f"by leg {leg.name} ({leg.joints}){why}")
            out.append(leg.with_neutral(n, R[0].T @ (-n)))
        if units:
            # the legs are this mechanism's own, just built (build_geometry): given their
            # directions in place, as rows of one array (each leg its own rows)
            rows = np.array([v for _, b, q in units for v in (b, q)], dtype=float)
            for k, (i, _, _) in enumerate(units):
                d = out[i].__dict__
                d["base_ref"], d["platform_ref"] = rows[2 * k], rows[2 * k + 1]
        return out

    def home_platform_pose(self):
        """The platform pose (p (1, 3), R (1, 3, 3)) at ``home`` as the NumPy model computed it
        when the mechanism was built (the legs' neutral directions were taken there); None
        once ``home`` was changed. Shared arrays: not to be written."""
        kept = self.__dict__.get("_home_platform_pose")
        # the same bytes: the same home (a home equal otherwise, -0.0 for 0.0, is computed anew)
        if kept is None or kept[0].tobytes() != np.asarray(self.home, dtype=float).tobytes():
            return None
        return kept[1], kept[2]

    def _check_constraints(self, margins: bool = True):
        try:
            cons = self.constraints
        except DescriptionError as e:
            raise DescriptionError(f"{self.name}: {e}") from None
        except ValueError as e:
            raise DescriptionError(f"{self.name}: constraints: {e}") from None
        if not margins:
            return
        ctx = self.pose_context(self.home[None, :])
        for spec, c in zip(self.description.constraints, cons.values()):
            try:
                with np.errstate(all="ignore"):
                    c.margin(ctx)
            except DescriptionError as e:
                raise DescriptionError(f"{self.name}: {e}") from None
            except (ValueError, KeyError) as e:
                raise DescriptionError(f"{self.name}: {spec.path}: {e}") from None

    # -- the compiled path (parasynth.engine), NumPy reference in Mechanism ---------------------------
    def is_feasible(self, X, names=None, engine: str = "compiled") -> np.ndarray:
        return _engine.feasible(self, X, names, engine)

    def constraint_margins(self, X, names=None, engine: str = "compiled") -> dict[str, np.ndarray]:
        return _engine.margins(self, X, names, engine)

    def singularity_margin(self, X, engine: str = "compiled") -> np.ndarray:
        if _engine.use_compiled(self, engine, "singularity_margin"):
            return _engine.singularity_margin(self, X)
        return super().singularity_margin(X, engine="numpy")

    def structural_constraint_rank(self, X=None, engine: str = "compiled") -> int:
        # One pose: the NumPy reference costs a few milliseconds, compiling the constraint-rank
        # kernel seconds. It runs compiled only once compiled (or in numba's cache), and is never
        # a reason to compile: the same integer either way.
        if (_engine.effective_engine(engine) == "compiled" and _engine.ready("constraint_rank")
                and _engine.use_compiled(self, engine, "constraint rank")):
            return _engine.constraint_rank(self, X)
        return super().structural_constraint_rank(X, engine="numpy")

    for _m in (is_feasible, constraint_margins, singularity_margin, structural_constraint_rank):
        _m.__doc__ = getattr(Mechanism, _m.__name__).__doc__
    del _m

    # -- mobility with consistency checks ----------------------------------------------------------
    @property
    def constraint_rank(self) -> int:
        if self._constraint_rank is None:
            self._constraint_rank = self.structural_constraint_rank()
        return self._constraint_rank

    def mobility(self, X=None, warn: bool = True) -> DescribedMobility:
        """Screw-theory mobility (see :meth:`Mechanism.mobility`) plus checks of the description:

        * under-actuation: the actuators do not control every freedom;
        * more task coordinates than freedoms, or fewer without ``task.restricted: true``;
        * task coordinates that do not move the platform independently (at every pose near X);
        * a parametrisation that leaves the legs' constraints: a small step of a task coordinate
          makes a leg unreachable, or its motion does work against a leg's constraint wrench.

        Each finding is a message in ``issues`` and, with ``warn=True``, a
        :class:`DescriptionWarning`."""
        base = Mechanism.mobility(self, X)
        X0 = self.home if X is None else np.asarray(X, dtype=float)
        issues, inconsistent = [], False
        t = self.description.task
        n, dof = self.n_task, base.dof
        if not base.controlled:
            issues.append(
                f"{self.name}: under-actuated: the {self.n_actuators} actuator(s) {', '.join(self.actuators)} do not "
                f"control all {dof} freedoms ({base.type}); {max(len(base.uncontrolled_twists), 1)} freedom(s) stay "
                f"uncontrolled (see uncontrolled_twists; forward kinematics needs fixed={{...}})")
        if n > dof:
            inconsistent = True
            issues.append(
                f"{self.name}: inconsistent description: {n} task coordinates {self.task_coordinates} but the legs "
                f"leave {dof} freedom(s) ({base.type}, constraint rank {base.constraint_rank}); the parametrisation "
                f"describes motions the legs forbid")
        elif n < dof and not t.restricted:
            issues.append(
                f"{self.name}: the {n} task coordinates {self.task_coordinates} cover fewer than the {dof} freedoms "
                f"({base.type}) the legs allow; add coordinates, or set task.restricted: true if the restriction is "
                f"intended (e.g. a coupling such as x = z*tan(theta))")
        found = self._parametrisation_issues(X0)
        inconsistent |= bool(found)
        issues += found
        if warn:
            for msg in issues:
                warnings.warn(msg, DescriptionWarning, stacklevel=2)
        fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(Mobility)}
        return DescribedMobility(**fields, issues=tuple(issues), under_actuated=not base.controlled,
                                 consistent=not inconsistent)

    def _parametrisation_issues(self, X0) -> list[str]:
        L = self.length_scale
        n = self.n_task
        ang = np.array([c in self.angular_coordinates for c in self.task_coordinates])
        step = np.where(ang, 1e-3, 1e-3 * L)
        rng = np.random.default_rng(20240611)
        Xp = [X0 + s * step * np.eye(n)[j] for j in range(n) for s in (1.0, -1.0)]
        Xp += [X0 + step * rng.uniform(-1, 1, n) for _ in range(3)]
        Xp = np.array(Xp)
        out = []
        _, states, p = self.leg_states(Xp)
        reach = np.logical_and.reduce([st.reachable for st in states])
        if not np.all(reach[: 2 * n]):
            bad_coords = sorted({self.task_coordinates[k // 2] for k in np.flatnonzero(~reach[: 2 * n])},
                                key=self.task_coordinates.index)
            bad_legs = sorted({leg.name for leg, st in zip(self.legs, states) if not np.all(st.reachable[: 2 * n])})
            out.append(
                f"{self.name}: inconsistent parametrisation: a small step of {', '.join(bad_coords)} from the analysed "
                f"pose leaves the reach of leg(s) {', '.join(bad_legs)}; the task coordinates do not follow the motion "
                f"the legs allow (a dependent coordinate, e.g. a parasitic motion, is missing or wrong)")
            return out
        keep = np.flatnonzero(reach)  # (the random steps may leave the workspace near its boundary)
        Xp, p = Xp[keep], p[keep]
        states = [dataclasses.replace(st, **{f.name: _take(getattr(st, f.name), keep)
                                            for f in dataclasses.fields(st)}) for st in states]
        T = self._twist_map(Xp)
        Ts = T.copy()
        Ts[:, 3:] *= L
        colnorm = np.linalg.norm(Ts, axis=1)  # (M, n)
        # Task coordinates that do not move the platform independently, at every pose tried.
        deficient = []
        for k in range(Xp.shape[0]):
            s = np.linalg.svd(Ts[k], compute_uv=False)
            deficient.append(int(np.sum(s > 1e-8 * max(s[0], 1e-300))) < n if s.size else True)
        if all(deficient):
            zero = [c for c, v in zip(self.task_coordinates, colnorm[0]) if v <= 1e-12]
            extra = f" ({', '.join(zero)} do not move the platform)" if zero else ""
            out.append(f"{self.name}: the task coordinates {self.task_coordinates} are not independent: their rates "
                       f"move the platform in fewer than {n} directions at every pose near the analysed one{extra}")
        # Motions that do work against a leg's constraint wrench.
        worst = np.zeros(n)
        for leg, st in zip(self.legs, states):
            Tj = leg.joint_twists(st, p)
            for k, C in enumerate(reciprocal_basis(Tj, L)):
                if not C.shape[0]:
                    continue
                Cs = C.copy()
                Cs[:, 3:] /= L
                Cs /= np.linalg.norm(Cs, axis=1, keepdims=True)
                r = np.abs(Cs @ Ts[k]) / np.maximum(colnorm[k], 1e-300)
                worst = np.maximum(worst, np.max(r, axis=0))
        bad = [c for c, w in zip(self.task_coordinates, worst) if w > 1e-6]
        if bad:
            out.append(f"{self.name}: inconsistent parametrisation: the motion of {', '.join(bad)} does work against "
                       f"the legs' constraint wrenches (relative residual up to {worst.max():.2g}); the pose "
                       f"expressions do not follow the motion the legs allow")
        return out


def _take(v, idx):
    """Rows ``idx`` of a LegState field (arrays, or dicts of arrays)."""
    if isinstance(v, dict):
        return {k: _take(x, idx) for k, x in v.items()}
    return v[idx] if isinstance(v, np.ndarray) and v.ndim else v
