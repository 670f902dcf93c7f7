"""Robust design measures: any registered measure evaluated under manufacturing scatter.

``robust(name, tolerances=..., statistic=..., samples=..., seed=...)`` returns a
:class:`RobustMeasure`, a :class:`~parasynth.objectives.Measure` like the others (same
settings, same call), whose value is a statistic of the measure over ``samples`` scatter
draws of the mechanism::

    from parasynth import load_mechanism, robust
    m = robust("workspace_volume", tolerances={"slider_radius": "0.05 mm", "anchor_tolerance": "0.02 mm"},
               statistic="quantile", level=0.05, samples=32, seed=0)
    v = m(load_mechanism("5pus_upu"), n=4096)          # the 5 % quantile of the volume
    r = m.evaluate(load_mechanism("5pus_upu"), n=4096)  # RobustValue: value, standard error, draws

Scatter model
-------------
``tolerances`` names two kinds of scatter, each drawn uniformly within +-tolerance:

* **description parameters** (``slider_radius: "0.05 mm"``, ``hinge_rotation: "0.01 deg"``):
  every scalar element of the parameter is drawn independently and the mechanism is rebuilt
  from its description with the drawn value (so every leg built from it moves consistently);
  only parameters with a length or angle unit (``Params.UNITS``) can scatter;
* **per leg**, in the vocabulary of :mod:`parasynth.measures.accuracy` (``actuator_tolerance``,
  ``anchor_tolerance``, ``link_tolerance``, ``axis_tolerance``, ``spherical_clearance``,
  ``universal_clearance``): each leg's anchors, link length and joint axes independently, the
  clearances as balls, the actuators' errors, drawn as :func:`parasynth.measures.accuracy` draws them.

Per-leg scatter is evaluated on the mechanism **as built** (:class:`AsBuilt`): at a nominal
pose ``X`` the actuators hold their nominal inverse-kinematics values (plus their own error),
the actual platform pose solves the perturbed closure equations (a chord Newton iteration from
the nominal pose on the residuals of :func:`parasynth.measures.accuracy.closure_residuals`, compiled in
:mod:`parasynth.engine.closure` for every draw's poses in one batch, NumPy where a leg type has
no compiled closure), and
reachability, pose constraints, wrench system and indices are those of the perturbed legs at
that actual pose. (Re-solving the inverse kinematics at the nominal pose would be wrong for
legs of lower mobility: an RPS leg whose anchor moves along its revolute axis cannot reach the
nominal pose at all.) Task-coordinate ranges and expression constraints on the task
coordinates are judged on the commanded coordinates ``X``.

Feasibility of an as-built mechanism over a batch of poses is screened by the nominal
mechanism's compiled constraint margins: only poses whose nominal margins are all above
``-band`` (per margin unit) are solved as built, the others count as infeasible; the band
starts at ten times the largest scatter the tolerances allow and doubles, and the as-built
solve is repeated, whenever a solved pose's margins moved by more than half of it. The margins
at the actual pose are evaluated on the shell only, the poses with a nominal margin below
``+band``: a pose whose nominal margins all exceed the band is feasible as built once its
closure converges (no margin moves by half the band, as the shell's poses show;
``SHELL_ONLY = False`` evaluates every candidate pose, which the tests compare with). Poses the
nominal legs cannot reach count as unreachable as built.

Statistics
----------
``mean`` (standard error ``std / sqrt(k)``), ``quantile`` with its ``level`` (standard error
from the binomial spread of the order statistics: half the distance between the order
statistics ``k level -+ sqrt(k level (1 - level))``), ``worst`` (the least favourable draw for
the measure's sense, or for a constraint's bound; no standard error), ``first_order``
(``nominal -+ sum_j |dv/dx_j| tol_j`` towards the unfavourable side, sensitivities by central
differences with a step of a tenth of each tolerance; refused for measures counted on samples,
whose value jumps with every sample crossing the boundary: volumes, fractions, extents).

Common random numbers: the draws come from ``seed`` alone (parameter draws and leg draws from
separate streams), so every design sees the same scatter and the robust objective is as
smooth in the design as the nominal one.

A **chance constraint** (``probability``) is the fraction of draws whose value satisfies the
constraint's bound (``bound``: ``("min", value)`` or ``("max", value)``), standard error
``sqrt(P (1 - P) / k)``; see :meth:`RobustMeasure.probability_of`.
"""

from __future__ import annotations

import copy
import math
import warnings
import weakref
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .. import engine
from .accuracy import (TOLERANCE_SETTINGS, _actuated_row_mask, _compose, _leg_changes_batch, _length_rows, _perturbed_legs,
                       _pinv_rank6, _pose_jacobian, _sample_errors, closure_residuals, error_sources)
from ..model.constraints import PoseContext, SingularityMarginFloor
from ..model.legs import solve_geometry, supports
from ..model.mechanism import EngineFallbackWarning, Mechanism
from .objectives import OBJECTIVES, Measure
from .objectives import get as get_measure
from ..common.units import UNIT_KINDS, QuantityError, parse_quantity
from ..common.validation import MAX_SEED, check_count, is_real_number

__all__ = ["robust", "RobustMeasure", "RobustValue", "AsBuilt", "STATISTICS", "LEG_TOLERANCES",
           "resolve_tolerances", "SAMPLE_COUNTED", "check_robust_spec", "RobustError", "check_bound"]

STATISTICS = ("mean", "quantile", "worst", "first_order")
#: Per-leg tolerances, as :mod:`parasynth.measures.accuracy` names them, and their quantity kinds.
LEG_TOLERANCES = dict(TOLERANCE_SETTINGS)
#: Measures counted on workspace samples: ``first_order`` is refused for them (the value jumps
#: with each sample crossing the workspace boundary; no derivative to take).
SAMPLE_COUNTED = ("workspace_volume", "workspace_fraction", "workspace_face_fraction", "extent", "xy_isotropy",
                  "inscribed_box_volume", "inscribed_box_size", "usable_workspace_volume",
                  "usable_workspace_fraction", "singularity_free_radius", "good_transmission_volume")
#: Largest number of scatter draws.
MAX_DRAWS = 4096


class RobustError(ValueError):
    """A robust block that is not allowed; the message starts with the field path."""


#: {id(mechanism): (weak reference, redundant constraints)} of :meth:`RobustMeasure.applicable`.
_REDUNDANT: "OrderedDict[int, tuple]" = OrderedDict()


def check_mechanism_arg(mech, arg: str = "mech"):
    """``mech`` when it is a mechanism; :class:`RobustError` naming ``arg`` otherwise (a
    model's name given where the model is expected, a number, None)."""
    if hasattr(mech, "task_coordinates") and callable(getattr(mech, "is_feasible", None)):
        return mech
    hint = repr(mech) if isinstance(mech, str) else "'5pus_upu'"
    got = repr(mech) if len(repr(mech)) <= 60 else repr(mech)[:57] + "..."
    raise RobustError(f"{arg} must be a mechanism, e.g. parasynth.load_mechanism({hint}), got {got}")


def check_bound(bound, required: bool, arg: str = "bound"):
    """``bound`` as ``("min" | "max", float)``; None when it is not ``required`` and not given.
    :class:`RobustError` naming ``arg`` for another shape, side, or a value that is not a finite
    real number (NaN, inf, a boolean, a string)."""
    allowed = "('min' or 'max', a finite number in the measure's SI unit)"
    if bound is None:
        if required:
            raise RobustError(f"{arg} must be {allowed} for a chance constraint, got None")
        return None
    got = repr(bound) if len(repr(bound)) <= 60 else repr(bound)[:57] + "..."
    if isinstance(bound, (str, bytes)) or not isinstance(bound, (tuple, list)) or len(bound) != 2:
        raise RobustError(f"{arg} must be {allowed}, got {got}")
    side, value = bound
    if not isinstance(side, str) or side not in ("min", "max"):
        raise RobustError(f"{arg}: the side must be 'min' or 'max', got {side!r}")
    if not is_real_number(value) or not math.isfinite(float(value)):
        raise RobustError(f"{arg}: the value must be a finite number in the measure's SI unit, got {value!r}")
    return side, float(value)


# -- tolerances ------------------------------------------------------------------------------------
def resolve_tolerances(tolerances, units: Mapping | None = None, where: str = "tolerances",
                       study: bool = False) -> tuple[dict, dict]:
    """``tolerances`` split into (description parameters {name: SI}, leg tolerances {key: SI}).

    ``units``: the mechanism's ``Params.UNITS`` ({parameter: kind}); without it parameter names
    are not checked. ``study``: values come from a study file, so a bare number for a length or
    an angle is an error (give its unit). Raises :class:`RobustError` naming ``where.<key>``."""
    if not isinstance(tolerances, Mapping) or not tolerances:
        raise RobustError(f"{where}: give a mapping {{parameter or tolerance: value with unit}}, e.g. "
                          f"{{anchor_tolerance: 0.02 mm}}, got {tolerances!r}")
    params, legs = {}, {}
    for k, v in tolerances.items():
        if not isinstance(k, str):
            raise RobustError(f"{where}: keys are parameter or tolerance names, got {k!r}")
        if k in LEG_TOLERANCES:
            kind = LEG_TOLERANCES[k]
        else:
            if units is not None and k not in units:
                raise RobustError(f"{where}.{k}: not a parameter of the mechanism nor a per-leg tolerance; allowed: "
                                  f"{', '.join(LEG_TOLERANCES)}, or a length or angle parameter: "
                                  f"{', '.join(p for p, kd in units.items() if kd in ('length', 'angle'))}")
            kind = None if units is None else units.get(k)
            if units is not None and kind not in ("length", "angle"):
                raise RobustError(f"{where}.{k}: only parameters with a length or angle unit scatter "
                                  f"({k!r} is {kind or 'without a unit'})")
        x = _tolerance_value(v, kind, f"{where}.{k}", study)
        (legs if k in LEG_TOLERANCES else params)[k] = x
    return params, legs


def _tolerance_value(v, kind, where, study):
    if isinstance(v, str):
        if kind is None:  # a parameter of a mechanism not known yet: a length, else an angle
            try:
                x = parse_quantity(v, "length", field=where)
            except QuantityError:
                try:
                    x = parse_quantity(v, "angle", field=where)
                except QuantityError as e:
                    raise RobustError(str(e)) from None
        else:
            try:
                x = parse_quantity(v, kind, field=where)
            except QuantityError as e:
                raise RobustError(str(e)) from None
    elif study:
        raise RobustError(f"{where}: give the tolerance with its unit (e.g. '0.02 mm' or '0.01 deg'), got {v!r}")
    elif isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise RobustError(f"{where}: a tolerance is a number (SI) or a string with its unit, got {v!r}")
    else:
        x = float(v)
    if not math.isfinite(x) or x < 0:
        raise RobustError(f"{where}: a tolerance must be finite and >= 0, got {v!r}")
    return x


def check_robust_spec(statistic: str, level, samples, seed, probability=None, where: str = "robust",
                      measure: str | None = None) -> tuple:
    """The checked (statistic, level, samples, seed, probability); :class:`RobustError` naming
    ``where.<field>`` and what is allowed."""
    if not isinstance(statistic, str) or statistic not in STATISTICS:
        raise RobustError(f"{where}.statistic: must be one of {', '.join(STATISTICS)}, got {statistic!r}")
    if statistic == "quantile":
        if level is None:
            raise RobustError(f"{where}.level: the quantile statistic needs its level in (0, 1), e.g. 0.05")
        if isinstance(level, bool) or not isinstance(level, (int, float)) or not 0.0 < float(level) < 1.0:
            raise RobustError(f"{where}.level: must be a number in (0, 1), got {level!r}")
        level = float(level)
    elif level is not None:
        raise RobustError(f"{where}.level: only the quantile statistic takes a level (statistic is {statistic!r})")
    if statistic == "first_order" and measure in SAMPLE_COUNTED:
        raise RobustError(f"{where}.statistic: first_order needs a measure smooth in the scattered quantities; "
                          f"{measure!r} is counted on workspace samples (use mean, quantile or worst)")
    try:
        samples = check_count(f"{where}.samples", samples, 2, MAX_DRAWS, what="a number of scatter draws")
        seed = check_count(f"{where}.seed", seed, 0, MAX_SEED, what="an integer seed")
    except ValueError as e:
        raise RobustError(str(e)) from None
    if probability is not None:
        if isinstance(probability, bool) or not isinstance(probability, (int, float)) \
                or not 0.0 < float(probability) <= 1.0:
            raise RobustError(f"{where}.probability: must be a number in (0, 1], got {probability!r}")
        probability = float(probability)
    return statistic, level, samples, seed, probability


# -- the mechanism as built ------------------------------------------------------------------------
def _key(X):
    """A cache key of the poses X: its shape and a hash of every 61st row (each cache checks a
    hit with ``np.array_equal`` against the poses it holds)."""
    return (X.shape, hash(np.ascontiguousarray(X[::61]).tobytes()))


class _Nominal:
    """What every draw of one built (nominal-leg) mechanism shares per batch of poses: the
    nominal margins (compiled engine) and, on a subset of the poses, the nominal pose, the
    closure target and the chord Newton matrix."""

    def __init__(self, built):
        self.built = built
        self.rows_len = _length_rows(built)
        self.act_rows = np.flatnonzero(_actuated_row_mask(built))
        self._margins: "OrderedDict[tuple, tuple]" = OrderedDict()
        self._prep: "OrderedDict[tuple, tuple]" = OrderedDict()
        self._cp = False

    @property
    def closure(self):
        """The compiled closure plan of the nominal legs (None: the closure runs on NumPy)."""
        if self._cp is False:
            self._cp = engine.closure_plan([self.built.legs])
        return self._cp

    def margins(self, X, names):
        """Nominal margins {name: (N,)} of the poses X (compiled engine), cached."""
        key = (_key(X), None if names is None else tuple(names))
        hit = self._margins.get(key)
        if hit is not None and np.array_equal(hit[0], X):
            return hit[1]
        M = self.built.constraint_margins(X, names=None if names is None else list(names))
        self._margins[key] = (X.copy(), M)
        if len(self._margins) > 6:
            self._margins.popitem(last=False)
        return M

    def prep(self, X, sel) -> dict:
        """Nominal ``p``, ``R``, closure target ``h0``, ``Gi`` and ``ok`` at the poses X[sel]."""
        key = (_key(X), hash(sel.tobytes()), sel.size)
        hit = self._prep.get(key)
        if hit is not None and np.array_equal(hit[0], X[sel]):
            return hit[1]
        b = self.built
        Xs = X[sel]
        valid = b.pose_valid(Xs)
        Xs = np.where(valid[:, None], Xs, b.home)
        with np.errstate(all="ignore"):
            p, R = b._pose(Xs)
            cp = self.closure
            if cp is not None:
                h0, Gt, reach = engine.closure_prep(cp, p, R, b.length_scale)
                reach &= valid
            else:
                states = [solve_geometry(leg, p, R) for leg in b.legs]
                reach = valid & np.logical_and.reduce([st.reachable for st in states])
                h0 = closure_residuals(b, p, R)
                Gt = _pose_jacobian(b, p, R)
            Gi = _chord_matrix(Gt, b)
        ok = reach & np.all(np.isfinite(Gi), axis=(1, 2)) & np.all(np.isfinite(h0), axis=1)
        out = {"p": p, "R": R, "h0": h0, "Gi": np.where(ok[:, None, None], Gi, 0.0), "ok": ok}
        self._prep[key] = (X[sel].copy(), out)
        if len(self._prep) > 8:
            self._prep.popitem(last=False)
        return out


def _chord_matrix(Gt, mech, rtol=1e-8):
    """The chord Newton matrix: ``accuracy._pinv_rank6`` (the least-squares inverse of the
    closure Jacobian, inf at singular poses), for a square Jacobian by one LU inverse per pose
    (the same matrix; a pose counts as singular when its 1-norm condition exceeds 1 / rtol)."""
    N, m = Gt.shape[:2]
    if m != 6:
        return _pinv_rank6(Gt, mech, rtol)
    L = mech.length_scale
    dc = np.array([1.0, 1.0, 1.0, 1.0 / L, 1.0 / L, 1.0 / L])
    dr = np.where(_length_rows(mech), 1.0 / L, 1.0)
    ok = np.all(np.isfinite(Gt), axis=(1, 2))
    Gs = np.where(ok[:, None, None], Gt, 0.0) * dr[None, :, None] * dc[None, None, :]
    Gs[~ok] = np.eye(6)
    try:
        Inv = np.linalg.inv(Gs)
    except np.linalg.LinAlgError:
        return _pinv_rank6(Gt, mech, rtol)
    cond = np.abs(Gs).sum(axis=1).max(axis=1) * np.abs(Inv).sum(axis=1).max(axis=1)
    Gi = dc[None, :, None] * Inv * dr[None, None, :]
    Gi[~ok] = np.nan
    Gi[ok & ~(cond < 1.0 / rtol)] = np.inf
    return Gi


def _newton(mech, legs, p0, R0, Gi, target, ok, scale, max_iter=20):
    """Chord Newton on the perturbed closure from the nominal poses: (converged, p, R)."""
    t = np.zeros((p0.shape[0], 6))
    conv = np.zeros(p0.shape[0], bool)
    with np.errstate(all="ignore"):
        for _ in range(max_iter):
            r = closure_residuals(mech, *_compose(p0, R0, t), legs=legs) - target
            conv = np.all(np.abs(r) <= 1e-12 * scale, axis=1)
            if np.all(conv | ~ok):
                break
            t = t - np.einsum("nim,nm->ni", Gi, np.where(np.isfinite(r), r, 0.0))
        p, R = _compose(p0, R0, t)
    return ok & conv, p, R


_GEOMETRY = ("base", "platform", "slider_axis", "u_axis", "r_axis", "u_platform_axis", "link_length", "base_ref",
             "platform_ref")


def _stacked_prep(group: "_Group", X, sels, counts, base: "_Nominal"):
    """The nominal pose, ``Gi``, ``ok`` and closure target of every draw's candidate poses, each
    draw with its own built mechanism (rebuilt from drawn parameters), in one stacked batch.
    The chord Newton matrix is the design's (``base``, unperturbed) at the same commanded
    poses, shared by the draws: a chord iteration needs only an approximation of the closure
    Jacobian, and the drawn parameters move it by their relative size (the iteration still
    converges to the closure of each draw's own legs)."""
    views = group.views
    v0 = views[0]
    Xs = np.concatenate([X[sel] for sel in sels])
    off = np.r_[0, np.cumsum(counts)]
    draw = np.repeat(np.arange(len(views)), counts)
    with np.errstate(all="ignore"):
        parts = [engine.pose_batch(v.built, Xs[off[j]:off[j + 1]]) for j, v in enumerate(views)]
        valid = np.concatenate([np.asarray(q[0], dtype=bool) for q in parts])
        p = np.concatenate([np.asarray(q[1], dtype=float) for q in parts])
        R = np.concatenate([np.asarray(q[2], dtype=float) for q in parts])
        cp = group.nominal_closure()
        if cp is not None:
            h0, _, reach = engine.closure_prep(cp, p, R, v0.length_scale, draw, jacobian=False)
            reach &= valid
        else:
            legs = _rows_legs([v.built for v in views], draw)
            states = [solve_geometry(leg, p, R) for leg in legs]
            reach = valid & np.logical_and.reduce([st.reachable for st in states])
            h0 = closure_residuals(v0.built, p, R, legs=legs)
        if all(sel is sels[0] or np.array_equal(sel, sels[0]) for sel in sels):  # screened alike
            q = base.prep(X, sels[0])
            rows = np.tile(np.arange(sels[0].size), len(sels))
            Gi, okb = q["Gi"][rows], q["ok"][rows]
        else:
            Gi = np.concatenate([base.prep(X, sel)["Gi"] for sel in sels])
            okb = np.concatenate([base.prep(X, sel)["ok"] for sel in sels])
    ok = reach & okb & np.all(np.isfinite(Gi), axis=(1, 2)) & np.all(np.isfinite(h0), axis=1)
    return p, R, np.where(ok[:, None, None], Gi, 0.0), ok, h0


def _rows_legs(views, draw, fields=None):
    """Legs whose geometry fields hold, row by row, the legs of draw ``draw[i]`` (the draws of
    a group evaluated in one batch; ``views``: objects with ``legs``; ``fields``: their
    :func:`_leg_fields`, when already stacked)."""
    fields = _leg_fields(views) if fields is None else fields
    out = []
    for leg, fl in zip(views[0].legs, fields):
        new = copy.copy(leg)
        for f, vals in fl.items():
            object.__setattr__(new, f, vals[draw])
        out.append(new)
    return out


def _leg_fields(views) -> list:
    """Per leg {geometry field: (draws, ...) the draws' values stacked}."""
    return [{f: np.stack([np.asarray(getattr(v.legs[i], f), dtype=float) for v in views])
             for f in _GEOMETRY if hasattr(leg, f)} for i, leg in enumerate(views[0].legs)]


#: Constraint margins at the actual pose only where a nominal margin is within the band
#: (``_Group.feasible``); False: at every candidate pose (the reference the tests compare with).
SHELL_ONLY = True


class _Group:
    """The draws of one robust measure on one design, evaluated together: their feasibility
    over a batch of poses is solved in one stacked batch (every draw's candidate poses, each
    row with its draw's leg geometry), and the singularity margins of the candidate poses are
    kept for :meth:`AsBuilt.singularity_margin`."""

    def __init__(self, band, base: "_Nominal | None" = None):
        self.views: list = []
        #: the design's own (unperturbed) nominal: screens the draws rebuilt from drawn parameters
        self.base = base
        self.band = dict(band)
        self._records: "OrderedDict[tuple, dict]" = OrderedDict()
        self._stackable = None
        self._cp = self._cp_nominal = False
        self._dq = self._fields = None

    def stackable(self) -> bool:
        if self._stackable is None:
            v0 = self.views[0]
            cons0 = tuple(repr(c) for c in v0.constraints.values())
            self._stackable = len(self.views) > 1 and all(
                supports(leg, "stacked") for leg in v0.legs) and all(
                tuple(repr(c) for c in v.constraints.values()) == cons0 and len(v.legs) == len(v0.legs)
                for v in self.views)
        return self._stackable

    def closure(self):
        """The compiled closure plan of the draws' legs (None: NumPy)."""
        if self._cp is False:
            self._cp = engine.closure_plan([v.legs for v in self.views], self.fields())
        return self._cp

    def fields(self) -> list:
        """:func:`_leg_fields` of the draws' legs (stacked once)."""
        if self._fields is None:
            self._fields = _leg_fields(self.views)
        return self._fields

    def nominal_closure(self):
        """The compiled closure plan of the draws' built (unperturbed) legs (None: NumPy)."""
        if self._cp_nominal is False:
            built = [v.built for v in self.views]
            self._cp_nominal = engine.closure_plan([b.legs for b in built], _leg_fields(built))
        return self._cp_nominal

    def dq(self) -> np.ndarray:
        """(draws, closure rows): the draws' actuator errors on their closure rows."""
        if self._dq is None:
            v0 = self.views[0]
            m = v0._nominal.rows_len.size
            self._dq = np.zeros((len(self.views), m))
            if v0.dq.size:
                self._dq[:, v0._nominal.act_rows] = np.stack([v.dq for v in self.views])
        return self._dq

    def feasible(self, X, names, cons) -> dict:
        """The draws' feasibility at the poses X (one record: per draw its candidate poses
        ``sels``, their actual poses ``p``, ``R`` and feasibility ``ok``, stacked draw after draw).

        Candidate poses (nominal margins all above ``-band``) are solved as built (chord Newton,
        compiled); of those, the constraint margins are evaluated at the actual pose only where
        a nominal margin is below ``+band`` (the shell around the boundary): a pose whose every
        nominal margin exceeds the band is feasible as built once its closure converges, since
        no margin moves by as much as half the band (checked on the shell's poses, the band
        doubling and the shell solved again when one does). ``SHELL_ONLY = False`` evaluates the
        margins at every candidate pose."""
        key = (_key(X), None if names is None else tuple(names))
        hit = self._records.get(key)
        if hit is not None and np.array_equal(hit["X"], X):
            return hit
        views = self.views
        k = len(views)
        shared = len({id(v._nominal) for v in views}) == 1
        if shared or self.base is None:
            M = [v._nominal.margins(X, names) for v in views]
        else:  # draws rebuilt from drawn parameters: screened by the design's margins (the band grows
            M = [self.base.margins(X, names)] * k  # with what the drawn parameters move)
        units = {c.name: c.unit for c in cons}
        band = self.band
        v0 = views[0]
        scale = np.where(v0._nominal.rows_len, v0.length_scale, 1.0)
        rec = None
        for _ in range(8):
            sels, lows = [], []
            for Mv in M:
                cand = np.ones(X.shape[0], bool)
                low = np.zeros(X.shape[0], bool)
                for n, m in Mv.items():
                    b = band.get(units[n], np.inf)
                    cand &= np.isfinite(m) & (m >= -b)
                    low |= ~(m >= b)
                sel = np.flatnonzero(cand)
                sels.append(sel)
                lows.append(low[sel])
            counts = np.array([s_.size for s_ in sels])
            N = int(counts.sum())
            rec = {"X": X.copy(), "sels": sels, "counts": counts, "offsets": np.r_[0, np.cumsum(counts)],
                   "ok": np.zeros(N, bool), "p": None, "R": None, "sm": None, "tables": None}
            if not N:
                break
            draw = np.repeat(np.arange(k), counts)
            if shared:  # one nominal mechanism: its cached preparation, every draw from its rows
                q = v0._nominal.prep(X, sels[0])
                p0, R0, Gi, okn, h0 = (q[f] for f in ("p", "R", "Gi", "ok", "h0"))
                src = np.tile(np.arange(sels[0].size), k)
            else:  # every draw rebuilt from drawn parameters: their nominal legs stacked too
                p0, R0, Gi, okn, h0 = _stacked_prep(self, X, sels, counts, self.base)
                src = np.arange(N)
            cp = self.closure()
            if cp is not None:
                conv, p, R = engine.closure_solve(cp, p0, R0, Gi, h0, okn, self.dq(), scale, src, draw)
            else:
                conv, p, R = _newton(v0.built, _rows_legs(views, draw, self.fields()), p0[src], R0[src], Gi[src],
                                     h0[src] + self.dq()[draw], okn[src], scale)
            ok = conv.copy()
            shell = np.flatnonzero(conv & (np.concatenate(lows) if SHELL_ONLY else True))
            rec.update(p=p, R=R, ok=ok, draw=draw)
            if not shell.size:
                break
            legs = _rows_legs(views, draw[shell], self.fields())
            ps, Rs = p[shell], R[shell]
            with np.errstate(all="ignore"):
                states = [leg.solve(ps, Rs) for leg in legs]
            reach = np.logical_and.reduce([st.reachable for st in states])
            for st in states:
                st.reachable = st.reachable & reach
            act = np.stack([st.actuator for leg, st in zip(legs, states) if leg.is_actuated], axis=-1)
            Xs = np.concatenate([X[sel] for sel in sels])[shell]
            stack = AsBuilt(v0.built, legs, np.zeros(0), band, key=("stack", id(self)))
            ctx = PoseContext(Xs, ps, Rs, list(legs), states, reach, act, stack)
            oks = reach.copy()
            grow = False
            with np.errstate(invalid="ignore"):
                for c in cons:
                    m = np.asarray(c.margin(ctx), dtype=float)
                    m = np.where(reach & ~np.isnan(m), m, -np.inf)
                    oks &= m >= 0
                    b = band.get(c.unit, np.inf)
                    if np.isfinite(b):
                        mn = np.concatenate([Mv[c.name][sel] for Mv, sel in zip(M, sels)])[shell]
                        d = np.abs(m - mn)
                        d = d[np.isfinite(d)]
                        if d.size and d.max() > 0.5 * b:
                            band[c.unit] = 2.0 * max(b, d.max())
                            grow = True
            ok[shell] = oks
            if not grow:
                break
        self._records[key] = rec
        if len(self._records) > 4:
            self._records.popitem(last=False)
        return rec

    def _margins_of(self, rec) -> np.ndarray:
        """The singularity margins of a stacked record's feasible rows (NaN elsewhere): draw by
        draw on the compiled kernel at the actual poses (each draw's legs, UPU moments scaled
        over that draw's poses, as a measure evaluating that draw alone), else on NumPy."""
        ok, o = rec["ok"], rec["offsets"]
        sm = np.full(ok.size, np.nan)
        if not ok.any():
            return sm
        b = self.views[0].built
        rank = self.views[0]._constraint_rank
        if rank is None:
            rank = Mechanism.structural_constraint_rank(b, engine="numpy")
        for j, v in enumerate(self.views):
            rows = o[j] + np.flatnonzero(ok[o[j]:o[j + 1]])
            if not rows.size:
                continue
            p, R = rec["p"][rows], rec["R"][rows]
            out = engine.singularity_margin_at(v.legs, p, R, v.built.n_actuators, rank,
                                               v.built.length_scale)  # a rebuilt draw's own length scale
            if out is None:  # no compiled form: the NumPy margin of this draw's rows
                with np.errstate(all="ignore"):
                    states = [leg.solve(p, R) for leg in v.legs]
                one = AsBuilt(v.built, v.legs, np.zeros(0), self.band, key=("stack", id(self), j))
                out = one.singularity_margin_of_states(states, p, np.ones(rows.size, bool))
            sm[rows] = out
        return sm

    def singularity_margin(self, view_index: int, X):
        """The singularity margins (n,) of draw ``view_index`` at poses X when every row of X is a
        candidate pose of a stacked record (else None)."""
        for rec in reversed(self._records.values()):
            if rec.get("p") is None:
                continue
            if rec["tables"] is None:
                tabs = []
                for sel in rec["sels"]:
                    keys = _row_keys(rec["X"][sel])
                    order = np.argsort(keys)
                    tabs.append((keys[order], order))
                rec["tables"] = tabs
            keys, order = rec["tables"][view_index]
            if not keys.size:
                continue
            q = _row_keys(X)
            pos = np.clip(np.searchsorted(keys, q), 0, keys.size - 1)
            if not np.all(keys[pos] == q):
                continue
            rows = rec["offsets"][view_index] + order[pos]
            if not np.all(rec["ok"][rows]):
                return None  # margins are kept for the feasible poses (the measures' points) only
            if rec["sm"] is None:
                rec["sm"] = self._margins_of(rec)
            return rec["sm"][rows]
        return None


def _row_keys(X):
    """One comparable key per row of X (its bytes)."""
    Xc = np.ascontiguousarray(X, dtype=float)
    return Xc.view(np.dtype((np.void, Xc.dtype.itemsize * Xc.shape[1]))).ravel()


class AsBuilt(Mechanism):
    """The mechanism ``built`` with perturbed legs ``legs`` and actuator errors ``dq`` (m),
    evaluated as built: at a nominal pose the actuators hold their nominal inverse-kinematics
    values plus ``dq``, the actual pose solves the perturbed closure (chord Newton from the
    nominal pose), and everything pose-wise (reachability, constraint margins, wrench system,
    singularity margin, indices) is that of the perturbed legs at the actual pose. Poses where
    the iteration does not converge, or that the nominal legs cannot reach, are unreachable.

    The closure is solved on the compiled closure kernel (:mod:`parasynth.engine.closure`);
    the constraint margins at the actual pose and the wrench-based indices run on NumPy, the
    singularity margins of a group's draws on the compiled margin kernel at explicit poses.
    :meth:`is_feasible` screens the poses by the nominal compiled margins (module
    documentation). Draws of one group (``group``) are solved together, their margins at the
    actual pose evaluated on the shell only."""

    def __init__(self, built, legs, dq, band, nominal: _Nominal | None = None, key=None, group: _Group | None = None):
        self.built = built
        #: the commanded poses are the built mechanism's (engine.pose_batch answers with its program)
        self.pose_mechanism = built
        self.name = built.name
        self.params = built.params
        self.home = built.home
        self.length_scale = built.length_scale
        self.task_coordinates = built.task_coordinates
        self.angular_coordinates = built.angular_coordinates
        self.actuators = built.actuators
        self.actuator_kinds = built.actuator_kinds
        self.legs = tuple(legs)
        self.dq = np.asarray(dq, dtype=float)
        self._constraint_rank = built.constraint_rank
        self._constraints = built.constraints
        self.added_constraints = built.added_constraints
        self.band = dict(band)
        self._nominal = nominal if nominal is not None else _Nominal(built)
        self._group = group
        self._index = len(group.views) if group is not None else -1
        if group is not None:
            group.views.append(self)
        #: identifies this draw in the caches of workspaces and usable workspaces
        self.scatter_key = key if key is not None else id(self)
        self._workspace_memo: "OrderedDict[tuple, object]" = OrderedDict()
        self._solved: "OrderedDict[tuple, tuple]" = OrderedDict()
        self._cp = False

    def __repr__(self) -> str:
        return f"<AsBuilt {self.name!r} draw={self.scatter_key!r}>"

    # the parametrisation is the nominal one
    def default_ranges(self) -> dict:
        return self.built.default_ranges()

    def _pose(self, X):
        return self.built._pose(X)

    def _twist_map(self, X):
        return self.built._twist_map(X)

    def pose_valid(self, X):
        return self.built.pose_valid(X)

    def structural_constraint_rank(self, X=None, engine: str = "compiled") -> int:
        return self._constraint_rank

    def with_params(self, **changes):
        raise ValueError("an as-built mechanism has no parameters of its own: change the nominal mechanism")

    # -- the as-built solve -----------------------------------------------------------------------
    def _actual(self, X, sel):
        """(ok (n,), p (n, 3), R (n, 3, 3)) of the actual poses at nominal poses ``X[sel]``."""
        q = self._nominal.prep(X, sel)
        dq = np.zeros(self._nominal.rows_len.size)
        if self.dq.size:
            dq[self._nominal.act_rows] = self.dq
        scale = np.where(self._nominal.rows_len, self.length_scale, 1.0)
        if self._cp is False:
            self._cp = engine.closure_plan([self.legs])
        if self._cp is not None:
            n = q["p"].shape[0]
            return engine.closure_solve(self._cp, q["p"], q["R"], q["Gi"], q["h0"], q["ok"], dq, scale,
                                        np.arange(n), np.zeros(n, np.int64))
        return _newton(self, self.legs, q["p"], q["R"], q["Gi"], q["h0"] + dq, q["ok"], scale)

    def _context(self, X) -> PoseContext:
        Xa, _ = self._poses(X)
        key = _key(Xa)
        hit = self._solved.get(key)
        if hit is not None and np.array_equal(hit[0], Xa):
            return hit[1]
        ok, p, R = self._actual(Xa, np.arange(Xa.shape[0]))
        with np.errstate(all="ignore"):
            states = [leg.solve(p, R) for leg in self.legs]
        reach = ok & np.logical_and.reduce([st.reachable for st in states])
        for st in states:
            st.reachable = st.reachable & reach
        act = np.stack([st.actuator for leg, st in zip(self.legs, states) if leg.is_actuated], axis=-1)
        ctx = PoseContext(Xa, p, R, list(self.legs), states, reach, act, self)
        self._solved[key] = (Xa.copy(), ctx)
        if len(self._solved) > 4:
            self._solved.popitem(last=False)
        return ctx

    def leg_states(self, X):
        ctx = self._context(X)
        return ctx.X, ctx.states, ctx.p

    def pose_context(self, X):
        return self._context(X)

    def constraint_margins(self, X, names=None, engine: str = "compiled") -> dict:
        return self._constraint_margins_numpy(X, names)

    def singularity_margin(self, X, engine: str = "compiled"):
        Xa, single = self._poses(X)
        if self._group is not None and self._group.stackable():
            out = self._group.singularity_margin(self._index, Xa)
            if out is not None:
                return out[0] if single else out
        return Mechanism.singularity_margin(self, X, engine="numpy")

    def is_feasible(self, X, names=None, engine: str = "compiled"):
        """(N,) bool: reachable as built and every selected constraint satisfied at the actual
        pose; poses screened by the nominal margins (module documentation)."""
        Xa, single = self._poses(X)
        cons = self._select(names)
        if not cons:  # reachability only
            out = self._context(Xa).reachable.copy()
            return out[0] if single else out
        if self._group is not None and self._group.stackable():
            rec = self._group.feasible(Xa, names, cons)
            out = np.zeros(Xa.shape[0], bool)
            o = rec["offsets"]
            out[rec["sels"][self._index]] = rec["ok"][o[self._index]:o[self._index + 1]]
            return out[0] if single else out
        M = self._nominal.margins(Xa, names)
        units = {c.name: c.unit for c in cons}
        out = np.zeros(Xa.shape[0], bool)
        band = self._group.band if self._group is not None else self.band
        for _ in range(8):
            cand = np.ones(Xa.shape[0], bool)
            for n, m in M.items():
                cand &= np.isfinite(m) & (m >= -band.get(units[n], np.inf))
            sel = np.flatnonzero(cand)
            out[:] = False
            if not sel.size:
                break
            ctx = self._context(Xa[sel])
            ok = ctx.reachable.copy()
            grow = False
            with np.errstate(invalid="ignore"):
                for c in cons:
                    m = np.asarray(c.margin(ctx), dtype=float)
                    m = np.where(ctx.reachable & ~np.isnan(m), m, -np.inf)
                    ok &= m >= 0
                    b = band.get(c.unit, np.inf)
                    if np.isfinite(b):
                        d = np.abs(m - M[c.name][sel])
                        d = d[np.isfinite(d)]
                        if d.size and d.max() > 0.5 * b:
                            band[c.unit] = 2.0 * max(b, d.max())
                            grow = True
            out[sel] = ok
            if not grow:
                break
        return out[0] if single else out


# -- draws -----------------------------------------------------------------------------------------
def _elements(params, names):
    """[(name, shape, flat nominal array)] of the scattered parameters."""
    out = []
    for n in names:
        v = getattr(params, n)
        a = np.asarray(v, dtype=float)
        out.append((n, a.shape, a.ravel().copy()))
    return out


def _as_value(a, shape):
    a = np.asarray(a, dtype=float).reshape(shape)
    if a.ndim == 0:
        return float(a)
    if a.ndim == 1:
        return tuple(float(x) for x in a)
    return tuple(_as_value(r, r.shape) for r in a)


@dataclass(frozen=True)
class RobustValue:
    """The outcome of a robust measure for one mechanism: ``value`` (the statistic, in the
    measure's unit), ``standard_error`` (None for ``worst`` and ``first_order``), ``nominal``
    (the measure on the nominal mechanism), ``values`` (per draw; for ``first_order`` the
    sensitivities times the tolerances), ``statistic``, ``level``, ``samples``, ``seed``."""

    value: float
    standard_error: float | None
    nominal: float
    values: tuple
    statistic: str
    level: float | None
    samples: int
    seed: int

    @property
    def loss(self) -> float:
        """``nominal - value`` (positive: the scatter costs that much)."""
        return self.nominal - self.value


_DRAW_CACHE: "OrderedDict[tuple, tuple]" = OrderedDict()
_DRAW_CACHE_SIZE = 4


@dataclass(frozen=True)
class RobustMeasure(Measure):
    """A registered measure under scatter (:func:`robust`); calling it gives the statistic,
    :meth:`evaluate` the :class:`RobustValue`."""

    base: str = ""
    param_tolerances: tuple = ()
    leg_tolerances: tuple = ()
    statistic: str = "mean"
    level: float | None = None
    samples: int = 32
    seed: int = 0

    # -- the draws of one mechanism ----------------------------------------------------------------
    def _resolved(self, mech):
        units = dict(getattr(type(mech.params), "UNITS", {}) or {})
        params, legs = dict(self.param_tolerances), dict(self.leg_tolerances)
        for n in params:
            if n not in units or units[n] not in ("length", "angle"):
                raise RobustError(f"robust({self.base!r}).tolerances.{n}: not a length or angle parameter of "
                                  f"{mech.name!r}")
        return params, legs

    def draws(self, mech) -> list:
        """The ``samples`` scatter draws of ``mech``: mechanisms (rebuilt with the drawn
        parameters, as built with the drawn leg errors), the same draws for every design.
        :class:`RobustError` when the scatter does not apply to ``mech`` (:meth:`applicable`)."""
        check_mechanism_arg(mech)
        params, legs = self._resolved(mech)
        key = (id(mech), tuple(sorted(params.items())), tuple(sorted(legs.items())), self.samples, self.seed)
        hit = _DRAW_CACHE.get(key)
        if hit is not None and hit[0]() is mech:
            _DRAW_CACHE.move_to_end(key)
            return hit[1]
        self.applicable(mech)
        out = _draw_mechanisms(mech, params, legs, self.samples, self.seed)
        _DRAW_CACHE[key] = (weakref.ref(mech), out)
        if len(_DRAW_CACHE) > _DRAW_CACHE_SIZE:
            _DRAW_CACHE.popitem(last=False)
        return out

    def applicable(self, mech) -> None:
        """The rule that decides whether this scatter applies to ``mech`` at all, the same for a
        study (:meth:`check`, ``parasynth validate``) and for every evaluation through the API
        (:meth:`evaluate`, :meth:`probability_of`, :meth:`values`, :meth:`draws`):
        :class:`RobustError` for a tolerance on a parameter without a length or angle unit, and
        for per-leg scatter on a mechanism that has redundant constraints (over-constrained, as
        the 2-RPU&2-SPS: a perturbed rigid closure has no solution, so every draw would be
        unreachable as built). Cached per mechanism object."""
        check_mechanism_arg(mech)
        params, legs = self._resolved(mech)
        if not any(legs.values()):
            return
        hit = _REDUNDANT.get(id(mech))
        if hit is not None and hit[0]() is mech:
            redundant = hit[1]
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                redundant = int(getattr(mech.mobility(), "redundant_constraints", 0) or 0)
            _REDUNDANT[id(mech)] = (weakref.ref(mech), redundant)
            while len(_REDUNDANT) > 64:
                _REDUNDANT.popitem(last=False)
        if redundant:
            given = ", ".join(k for k, v in legs.items() if v)
            raise RobustError(f"{mech.name}: per-leg scatter (tolerances {given}) needs a mechanism without "
                              f"redundant constraints ({redundant} here): the rigid closure of a perturbed over-constrained mechanism "
                              f"has no solution (as built it assembles only by deforming); scatter its "
                              f"description parameters instead, which keep its constraints consistent")

    def check(self, mech) -> None:
        """``ValueError`` (:class:`RobustError`) when the scatter cannot be applied to ``mech``:
        the rule of :meth:`applicable`, a drawn design that cannot be built, per-leg scatter on a
        mechanism whose closure equations do not fix the pose (under-actuated), or a home pose
        the mechanism cannot reach as built."""
        params, legs = self._resolved(mech)
        self.applicable(mech)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", EngineFallbackWarning)
            for m in _draw_mechanisms(mech, params, legs, 2, self.seed):
                if isinstance(m, AsBuilt) and not m._context(m.home[None, :]).reachable[0]:
                    raise RobustError(f"{mech.name}: the home pose is not reachable as built with these tolerances "
                                     f"(the perturbed closure has no solution near it)")

    def evaluate(self, mech, bound=None, **settings) -> RobustValue:
        """The :class:`RobustValue` of ``mech`` (settings as the base measure's; ``bound``
        ``("min"|"max", value)``, value a finite number in the measure's SI unit, or None: the
        side ``worst`` and ``first_order`` take). :class:`RobustError` naming ``mech`` or
        ``bound``, or when the scatter does not apply to ``mech`` (:meth:`applicable`)."""
        check_mechanism_arg(mech)
        bound = check_bound(bound, required=False)
        self.applicable(mech)
        base = get_measure(self.base)
        nominal = float(base(mech, **settings))
        worse = _worse_side(base.sense, bound)
        if self.statistic == "first_order":
            value, contrib = _first_order(self, base, mech, nominal, worse, settings)
            return RobustValue(value, None, nominal, tuple(contrib), "first_order", None, self.samples, self.seed)
        vals = self.values(mech, **settings)
        return _statistic(vals, self.statistic, self.level, worse, nominal, self.samples, self.seed)

    def values(self, mech, **settings) -> np.ndarray:
        """The base measure on every draw (samples,)."""
        check_mechanism_arg(mech)
        base = get_measure(self.base)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", EngineFallbackWarning)
            return np.array([float(base(m, **settings)) for m in self.draws(mech)])

    def probability_of(self, mech, bound, **settings) -> tuple[float, float, float]:
        """Chance constraint: (fraction of the draws whose value satisfies ``bound``
        ``("min"|"max", value)``, its standard error ``sqrt(P (1 - P) / k)``, the nominal value).
        ``bound`` is required (a finite number in the measure's SI unit); :class:`RobustError`
        as :meth:`evaluate`."""
        check_mechanism_arg(mech)
        side, b = check_bound(bound, required=True)
        self.applicable(mech)
        base = get_measure(self.base)
        nominal = float(base(mech, **settings))
        v = self.values(mech, **settings)
        ok = (v >= b) if side == "min" else (v <= b)
        P = float(np.mean(ok))
        return P, math.sqrt(P * (1.0 - P) / len(v)), nominal


def _worse_side(sense, bound):
    """+1 when larger values are worse, -1 when smaller ones are."""
    if bound is not None:
        return -1 if bound[0] == "min" else 1
    return -1 if sense == "maximize" else 1


def _statistic(vals, statistic, level, worse, nominal, samples, seed) -> RobustValue:
    v = np.asarray(vals, dtype=float)
    k = v.size
    if statistic == "mean":
        value = float(np.mean(v))
        se = float(np.std(v, ddof=1) / math.sqrt(k)) if k > 1 else math.nan
    elif statistic == "quantile":
        value = float(np.quantile(v, level))
        s = np.sort(v)
        half = math.sqrt(k * level * (1.0 - level))
        lo = int(np.clip(math.floor(k * level - half), 0, k - 1))
        hi = int(np.clip(math.ceil(k * level + half), 0, k - 1))
        se = float(0.5 * (s[hi] - s[lo]))
    else:  # worst
        value = float(np.max(v) if worse > 0 else np.min(v))
        se = None
    return RobustValue(value, se, nominal, tuple(float(x) for x in v), statistic, level, samples, seed)


def _draw_mechanisms(mech, params: dict, legs: dict, k: int, seed: int) -> list:
    ss = np.random.SeedSequence([int(seed), 0x5CA7])
    s_par, s_leg = ss.spawn(2)
    elems = _elements(mech.params, list(params))
    n_el = sum(e[2].size for e in elems)
    U = np.random.default_rng(s_par).uniform(-1.0, 1.0, size=(k, n_el)) if n_el else np.zeros((k, 0))
    E = None
    if legs and any(legs.values()):
        src = error_sources(mech)
        tol = {key: float(legs.get(key, 0.0)) for key in TOLERANCE_SETTINGS}
        E = _sample_errors(src, tol, k, np.random.default_rng(s_leg))
        act_cols = [j for j, kd in enumerate(src.kind) if kd == "actuator"]
        band = _initial_band(mech, params, tol)
    builts = []
    for s in range(k):
        built = mech
        if n_el:
            changes, j = {}, 0
            for (name, shape, a) in elems:
                d = U[s, j:j + a.size] * params[name]
                changes[name] = _as_value(a + d, shape)
                j += a.size
            built = mech.with_params(**changes)
            built._workspace_memo = OrderedDict()
        builts.append(built)
    if E is None:
        return builts
    nominal = _Nominal(mech)
    group = _Group(band, nominal)
    out = []
    for s, (built, legs_s) in enumerate(zip(builts, _drawn_legs(builts, src, E))):
        nom = nominal if built is mech else _Nominal(built)
        out.append(AsBuilt(built, legs_s, E[s, act_cols], band, nom, key=(id(mech), seed, s), group=group))
    return out


def _drawn_legs(builts, src, E) -> list:
    """Per draw ``s`` the legs of ``builts[s]`` with the errors ``E[s]`` applied, as
    :func:`parasynth.measures.accuracy` applies them (``_leg_changes``, here for all draws at once),
    set on copies without the constructors' checks (the changed fields are arrays of the
    checked shapes; a few hundred legs are drawn per design)."""
    items = {}
    for j, (kd, li, idx) in enumerate(zip(src.kind, src.leg, src.index)):
        if kd != "actuator" and np.any(E[:, j] != 0.0):
            items.setdefault(li, []).append((idx, E[:, j]))
    out = [list(b.legs) for b in builts]
    for li, it in items.items():
        changes = _leg_changes_batch([b.legs[li] for b in builts], it)
        for s, legs in enumerate(out):
            new = copy.copy(legs[li])
            for f, v in changes.items():
                object.__setattr__(new, f, float(v[s]) if f == "link_length" else v[s])
            legs[li] = new
    return out


def _initial_band(mech, params, tol) -> dict:
    L = mech.length_scale
    lin = (2 * math.sqrt(3) * tol["anchor_tolerance"] + tol["link_tolerance"] + tol["actuator_tolerance"]
           + 2 * tol["spherical_clearance"] + 2 * tol["universal_clearance"])
    units = getattr(type(mech.params), "UNITS", {}) or {}
    lin += sum(v for n, v in params.items() if units.get(n) == "length")
    ang = tol["axis_tolerance"] + sum(v for n, v in params.items() if units.get(n) == "angle")
    d_len = 10.0 * (lin + ang * L)
    d_ang = 10.0 * (lin / L + ang)
    # keyed by the margins' units: lengths and angles in SI, and the singularity-margin floor's
    return {UNIT_KINDS["length"].si: d_len, UNIT_KINDS["angle"].si: d_ang, SingularityMarginFloor.unit: d_ang}


def _first_order(rm: RobustMeasure, base: Measure, mech, nominal, worse, settings):
    """``nominal + worse * sum_j |dv/dx_j| tol_j`` by central differences (step tol_j / 10)."""
    params, legs = rm._resolved(mech)
    rm.applicable(mech)
    contrib = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        for (name, shape, a) in _elements(mech.params, list(params)):
            tol = params[name]
            if tol == 0:
                continue
            h = 0.1 * tol
            for i in range(a.size):
                vs = []
                for sgn in (1.0, -1.0):
                    b = a.copy()
                    b[i] += sgn * h
                    vs.append(float(base(mech.with_params(**{name: _as_value(b, shape)}), **settings)))
                contrib.append(abs(vs[0] - vs[1]) / (2 * h) * tol)
        if legs and any(legs.values()):
            src = error_sources(mech)
            tol = {key: float(legs.get(key, 0.0)) for key in TOLERANCE_SETTINGS}
            from_kind = {"actuator": "actuator_tolerance", "anchor": "anchor_tolerance", "link": "link_tolerance",
                         "axis": "axis_tolerance", "spherical_clearance": "spherical_clearance",
                         "universal_clearance": "universal_clearance"}
            act_cols = [j for j, kd in enumerate(src.kind) if kd == "actuator"]
            band = _initial_band(mech, params, tol)
            nom = _Nominal(mech)
            groups = {}
            for j, (kd, g) in enumerate(zip(src.kind, src.group)):
                t = tol[from_kind[kd]]
                if t > 0:
                    groups.setdefault(("g", g) if g >= 0 else ("j", j), []).append(j)
            for gkey, cols in groups.items():
                t = tol[from_kind[src.kind[cols[0]]]]
                h = 0.1 * t
                grad = []
                for j in cols:
                    vs = []
                    for sgn in (1.0, -1.0):
                        e = np.zeros(len(src))
                        e[j] = sgn * h
                        ab = AsBuilt(mech, _perturbed_legs(mech, src, e), e[act_cols], band, nom)
                        vs.append(float(base(ab, **settings)))
                    grad.append((vs[0] - vs[1]) / (2 * h))
                # a clearance ball: the gradient's norm times the radius; a box source: |g| tol
                contrib.append(float(np.linalg.norm(grad)) * t if gkey[0] == "g" else abs(grad[0]) * t)
    return nominal + worse * float(sum(contrib)), contrib


# -- the public constructor ------------------------------------------------------------------------
def robust(name: str, tolerances=None, statistic: str = "mean", samples: int = 32, seed: int = 0,
           level: float | None = None) -> RobustMeasure:
    """The registered measure ``name`` under manufacturing scatter, as a measure like the others
    (module documentation): ``tolerances`` {description parameter or per-leg tolerance: value}
    (SI numbers or strings with units), ``statistic`` one of :data:`STATISTICS` (``level`` for
    ``quantile``, e.g. 0.05), ``samples`` scatter draws, ``seed`` of the draws (the same draws for
    every design). ``name`` may also be a registered measure itself
    (``parasynth.objectives.get("workspace_volume")``), which stands for its name; a robust
    measure, an unregistered measure or anything else is a :class:`RobustError`."""
    if isinstance(name, RobustMeasure):
        raise RobustError(f"robust: {name.name!r} is already robust; give the name of the measure, "
                          f"e.g. robust({name.base!r}, ...)")
    if isinstance(name, Measure):
        if OBJECTIVES.get(name.name) is not name:
            raise RobustError(f"robust: name must be a registered measure or its name; {name.name!r} is not "
                              f"registered as this measure")
        name = name.name
    if not isinstance(name, str):
        got = repr(name) if len(repr(name)) <= 60 else repr(name)[:57] + "..."
        raise RobustError(f"robust: name must be the name of a registered measure (e.g. 'workspace_volume'; see "
                          f"parasynth list) or the measure itself, got {got}")
    try:
        base = get_measure(name)
    except ValueError as e:
        raise RobustError(f"robust: name: {e}") from None
    if isinstance(base, RobustMeasure):
        raise RobustError(f"robust: {name!r} is already robust")
    statistic, level, samples, seed, _ = check_robust_spec(statistic, level, samples, seed,
                                                           where=f"robust({name!r})", measure=name)
    params, legs = resolve_tolerances(tolerances, None, f"robust({name!r}).tolerances")
    if not any(params.values()) and not any(legs.values()):
        raise RobustError(f"robust({name!r}).tolerances: give at least one positive tolerance")
    doc = (f"{statistic}{'' if level is None else f' ({level:g})'} of {name!r} over {samples} scatter draws "
           f"(seed {seed}).\n\n{base.doc}")
    rm = RobustMeasure(name=f"robust:{name}", func=_call_of(name), unit=base.unit, sense=base.sense, doc=doc,
                         kind=base.kind, settings=base.settings, models=base.models, cost="expensive",
                         sample=base.sample, own_settings=base.own_settings, params=base.params, base=name,
                         param_tolerances=tuple(params.items()), leg_tolerances=tuple(legs.items()),
                         statistic=statistic, level=level, samples=samples, seed=seed)
    rm.func.measure = rm
    return rm


class _call_of:
    """The function of a robust measure: ``f(mech, **settings) -> statistic`` (bound to its
    :class:`RobustMeasure` when that is made)."""

    def __init__(self, name):
        self.name = name
        self.measure = None

    def __call__(self, mech, **settings):
        return self.measure.evaluate(mech, **settings).value

    def __repr__(self):
        return f"<robust function of {self.name!r}>"
