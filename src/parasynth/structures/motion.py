"""The task rule of a structure whose constraining limbs select no motion template: its finite
motion computed from the limbs (docs/structures.md, "Parasitic motion").

The pose is written with the six coordinates of the ``free`` template (``x, y, z`` of the
platform centre, ``alpha, beta, gamma`` of R = Rx Ry Rz). The limbs' closure equations
(:mod:`parasynth.model.parasitic`) vanish where every limb assembles; their Jacobian with
respect to the six coordinates spans the same space as the limbs' constraint wrenches at that
pose (each closure equation's gradient is the work of a constraint wrench). So:

1. a pose near the nominal home (``x = y = 0``, ``z = height``, level) where every limb
   assembles is found by a minimum-norm Gauss-Newton solve over the coordinates but z (the
   height kept), or, failing that, over all six; a solution counts only if it is near
   (:func:`home_is_near`: the platform tilted at most :data:`HOME_TILT_MAX` from level, its
   centre within :data:`HOME_OFFSET_MAX` length scales of the nominal one; any turn about the
   vertical): from a start where the limbs' equations are degenerate the minimum-norm steps
   may otherwise end at a platform on its side or metres away, a pose that depends on the
   last bits of the linear algebra (and so on the machine) and that no one would call home;
2. there the rank ``r`` of the closure Jacobian (lengths scaled by the length scale) counts the
   constraints, and ``6 - r`` is the number of freedoms; the motion type is ``nT mR`` with ``m``
   the rank of the rotational part of the freedoms' twists;
3. the ``r`` dependent coordinates are the columns of the Jacobian that are best conditioned
   (largest smallest singular value); among those within a factor 2 of the best, the
   independent coordinates come first in the order ``z, alpha, beta, x, y, gamma`` (the
   height and the tilts are the usual task coordinates, as z, alpha, beta of the 3-RPS); the
   task coordinates are then written in the order ``x, y, z, alpha, beta, gamma``;
4. the task section states the independent coordinates (home at the nominal values, ranges of
   the ``free`` template) and ``task.solve`` with the dependent ones, started from their values
   at the home pose.

The closure equations are evaluated by the NumPy reference (chain limbs too: their compiled
solve, :func:`parasynth.engine.closure_residuals`, is for many poses): a rule solves one pose
at a time, where the reference is faster than the compiled kernel's call (0.7 s against 1.6 s
for the 63 rules of the 1T2R enumeration), the compiled chain closure is not compiled for it
(4.7 s on an empty cache, on the critical path of a structure study's first run), and the rule
does not depend on what the compile cache holds. The rule is computed at the default shared dimensions; its home values of the dependent
coordinates only start the solve, so that other dimensions solve their own. Limits: a
structure whose closure Jacobian changes rank near home (a constraint singularity at home), or
whose limbs do not assemble near the nominal home, gets no rule (:class:`NoTaskRule` with the
reason); the solve follows the branch of the home pose and fails (NaN, the pose unreachable)
where it does not converge.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from .. import engine
from ..common.units import in_display
from ..mechanisms import parse_description
from ..model.parasitic import HOME_ITERATIONS, ParasiticError, closure_count, gauss_newton
from ..model.spatial import euler_rate_map, euler_to_matrix
from .vocabulary import TEMPLATES

__all__ = ["MotionRule", "NoTaskRule", "NoHome", "motion_rule", "home_is_near", "COORDINATES", "PREFERENCE",
           "HOME_TILT_MAX", "HOME_OFFSET_MAX"]

#: The six pose coordinates of the ``free`` template and their kinds.
COORDINATES = (("x", "length"), ("y", "length"), ("z", "length"), ("alpha", "angle"), ("beta", "angle"),
               ("gamma", "angle"))
#: The order in which coordinates are preferred as independent task coordinates.
PREFERENCE = ("z", "alpha", "beta", "x", "y", "gamma")
#: Names of the freedoms of each coordinate (as the ``free`` template's axes).
_AXIS_NAMES = {"x": "x", "y": "y", "z": "z", "alpha": "x", "beta": "moving y", "gamma": "moving z"}
_RANK_TOL = 1e-8
#: The largest tilt of the platform from level (rad) at an assembled home pose.
HOME_TILT_MAX = np.radians(45.0)
#: The largest distance of the platform centre from the nominal home's, horizontally and in
#: height, at an assembled home pose (in length scales: the description's ``base_radius``).
HOME_OFFSET_MAX = 1.0


class NoTaskRule(Exception):
    """No motion rule for a candidate; the message says why."""


class NoHome(NoTaskRule):
    """No motion rule for a candidate because its limbs assemble nowhere near the nominal home
    (:func:`home_is_near`); the message says what the nearest assembly found was, if any."""


@dataclass(frozen=True)
class MotionRule:
    """A computed task rule, used as a motion template: ``name`` (``"solved"``), ``motion``
    (``"1T2R"``...), ``task`` (the task section), ``axes`` (the freedoms' axes), ``doc``,
    ``independent`` and ``dependent`` coordinate names."""

    name: str
    motion: str
    task: dict
    axes: dict
    doc: str
    independent: tuple = ()
    dependent: tuple = ()


def _pose(V):
    return V[:, :3], euler_to_matrix("xyz", V[:, 3:])


def home_is_near(V, V0, L: float) -> str | None:
    """None if the pose ``V`` (x, y, z, alpha, beta, gamma) is near the nominal home ``V0``
    (length scale ``L``): tilted at most :data:`HOME_TILT_MAX` from level, its centre within
    :data:`HOME_OFFSET_MAX` * ``L`` of the nominal one horizontally and in height; else what is
    far, in words."""
    R = euler_to_matrix("xyz", np.asarray(V[3:], dtype=float)[None])[0]
    tilt = float(np.arccos(np.clip(R[2, 2], -1.0, 1.0)))
    off, dz = float(np.hypot(V[0] - V0[0], V[1] - V0[1])), float(abs(V[2] - V0[2]))
    far = []
    if not tilt <= HOME_TILT_MAX:
        far.append(f"the platform tilted {in_display(tilt, 'angle', '.0f')} from level (at most "
                   f"{in_display(HOME_TILT_MAX, 'angle', '.0f')})")
    if not off <= HOME_OFFSET_MAX * L:
        far.append(f"its centre {off / L:.2g} length scales off the vertical (at most {HOME_OFFSET_MAX:g})")
    if not dz <= HOME_OFFSET_MAX * L:
        far.append(f"its height {dz / L:.2g} length scales from the nominal one (at most {HOME_OFFSET_MAX:g})")
    return ", ".join(far) or None


def motion_rule(description: dict) -> MotionRule:
    """The task rule of the structure ``description`` (a generated description dict; its
    ``task`` is replaced). Raises :class:`NoTaskRule` naming the reason."""
    free = TEMPLATES["free"]
    desc = dict(description)
    desc["task"] = dict(free.task)
    try:
        d = parse_description(desc, description.get("name"))
        penv = {p.name: (np.float64(p.default) if p.shape == () else np.asarray(p.default, dtype=float))
                for p in d.params}
        legs, home, L = d.build_geometry(penv)
    except ValueError as e:
        raise NoTaskRule(f"the limbs cannot be built ({e})") from None
    try:
        k = sum(closure_count(leg) for leg in legs)
    except ParasiticError as e:  # a chain limb (model/chains.py): its motion from a template only
        raise NoTaskRule(f"no closure equations ({e}): a limb without them moves by a motion template only, and "
                         f"these limbs select none together") from None
    if k == 0:
        raise NoTaskRule("no limb has closure equations (use the free template)")
    scale = np.array([L, L, L, 1.0, 1.0, 1.0])

    def fun(X, U):
        p, R = _pose(U)
        return engine.closure_residuals(legs, p, R, L, engine="numpy")  # one pose: the reference (module doc)

    V0 = np.asarray(home, dtype=float)  # the free template's nominal home: x, y, z, alpha, beta, gamma
    # assemble with z at the nominal height first (a minimum-norm step may otherwise trade the
    # height for the closure, e.g. UPU legs turned vertical), then over all six coordinates;
    # an assembly far from the nominal home is none (home_is_near)
    far = None
    for free_idx in ([0, 1, 3, 4, 5], [0, 1, 2, 3, 4, 5]):
        fi = np.array(free_idx)

        def fun_free(X, U, fi=fi):
            W = np.broadcast_to(V0, (U.shape[0], 6)).copy()
            W[:, fi] = U
            return fun(None, W)

        with np.errstate(all="ignore"):
            Uf, ok = gauss_newton(fun_free, np.zeros((1, 0)), V0[fi], scale[fi], iterations=HOME_ITERATIONS)
        if ok[0]:
            V = V0.copy()
            V[fi] = Uf[0]
            far = home_is_near(V, V0, L)
            if far is None:
                break
            ok = np.zeros(1, dtype=bool)
    if not ok[0]:
        raise NoHome("the limbs' closure equations have no solution near the nominal home (x = y = 0, "
                     "z = height, level platform)" + (f"; the one found has {far}" if far else ""))
    # the closure Jacobian at the assembled pose, in scaled coordinates
    E = np.diag(1e-6 * scale)
    J = ((fun(None, V + E) - fun(None, V - E)) / 2e-6).T  # (k, 6)
    s = np.linalg.svd(J, compute_uv=False)
    r = int(np.sum(s > _RANK_TOL * max(s[0], 1e-300)))
    if r == 6:
        raise NoTaskRule("the limbs' closure equations leave the platform no freedom near home")
    if r == 0:
        raise NoTaskRule("the limbs' closure equations constrain nothing at home (a singular assembly)")
    names = [c for c, _ in COORDINATES]
    kinds = dict(COORDINATES)
    scored = []
    for D in itertools.combinations(range(6), r):
        sm = np.linalg.svd(J[:, D], compute_uv=False)[-1]
        indep = [names[j] for j in range(6) if j not in D]
        scored.append((sm, tuple(sorted(PREFERENCE.index(c) for c in indep)), D))
    best = max(sc[0] for sc in scored)
    if not best > _RANK_TOL * s[0]:  # pragma: no cover (r columns of a rank-r matrix are always found)
        raise NoTaskRule("no set of dependent coordinates solves the closure equations at home")
    sm, _, D = min((sc for sc in scored if sc[0] >= 0.5 * best), key=lambda sc: sc[1])
    dep = tuple(names[j] for j in D)
    ind = tuple(c for c in names if c not in dep)  # in the order x, y, z, alpha, beta, gamma
    # the motion type: freedoms = null space of J (scaled), angular part through the rate map
    _, _, Vt = np.linalg.svd(J)
    N = Vt[r:].T / scale[:, None]  # (6, 6 - r) coordinate rates
    omega = euler_rate_map("xyz", V[None, 3:])[0] @ N[3:]
    n_rot = int(np.sum(np.linalg.svd(omega * L, compute_uv=False) > _RANK_TOL)) if N.shape[1] else 0
    motion = f"{6 - r - n_rot}T{n_rot}R"
    # re-solve the dependent coordinates with the independent ones at their nominal values
    Vn = V0.copy()
    dj = np.array(D)

    def fun_dep(X, U):
        W = np.broadcast_to(Vn, (U.shape[0], 6)).copy()
        W[:, dj] = U
        return fun(None, W)

    with np.errstate(all="ignore"):
        U, ok = gauss_newton(fun_dep, np.zeros((1, 0)), V[dj], scale[dj], iterations=HOME_ITERATIONS)
        if not ok[0]:
            U, ok = gauss_newton(fun_dep, np.zeros((1, 0)), V0[dj], scale[dj], iterations=HOME_ITERATIONS)
    if not ok[0]:
        raise NoTaskRule(f"the dependent coordinates {', '.join(dep)} have no solution at the nominal values of "
                         f"{', '.join(ind)}")
    Vh = Vn.copy()
    Vh[dj] = U[0]
    far = home_is_near(Vh, V0, L)
    if far is not None:
        raise NoHome(f"the dependent coordinates {', '.join(dep)} solved at the nominal values of "
                     f"{', '.join(ind)} give a home far from the nominal one: {far}")
    t = free.task
    task = {
        "coordinates": {c: kinds[c] for c in ind},
        "solve": {"unknowns": {c: kinds[c] for c in dep}, "closure": "legs",
                  "start": {c: in_display(u, kinds[c], ".15g") for c, u in zip(dep, U[0])}},
        "position": ["x", "y", "z"],
        "orientation": {"convention": "xyz", "angles": ["alpha", "beta", "gamma"]},
        "home": {c: t["home"][c] for c in ind},
        "ranges": {c: t["ranges"][c] for c in ind},
    }
    axes = {"translations": tuple(_AXIS_NAMES[c] for c in ind if kinds[c] == "length"),
            "rotations": tuple(_AXIS_NAMES[c] for c in ind if kinds[c] == "angle")}
    doc = (f"computed from the limbs: {k} closure equation(s) of rank {r}, independent {', '.join(ind)}, "
           f"dependent {', '.join(dep)} solved by Gauss-Newton (task.solve)")
    return MotionRule("solved", motion, task, axes, doc, ind, dep)


_RULES: dict = {}


def candidate_rule(groups, describe):
    """``(rule, reason, drop)`` of a candidate's limb groups: its :class:`MotionRule` (reason
    and drop None), or None, why not and the drop reason of :mod:`.synthesis` (``"no home"``
    for :class:`NoHome`, else ``"no task rule"``). ``describe(template)`` writes the candidate's
    description with a template; the result is cached per groups (the rule depends only on the
    limbs and the default dimensions)."""
    if groups not in _RULES:
        try:
            _RULES[groups] = (motion_rule(describe(TEMPLATES["free"])), None, None)
        except NoTaskRule as e:
            _RULES[groups] = (None, str(e), "no home" if isinstance(e, NoHome) else "no task rule")
    return _RULES[groups]


def remember_rule(groups, rule) -> None:
    """Keep ``rule`` (``(rule, reason, drop)``, as :func:`candidate_rule` gives) as the rule of
    ``groups``: one found in another process (:mod:`.synthesis` spreads the candidates' rules
    over processes)."""
    _RULES.setdefault(groups, rule)
