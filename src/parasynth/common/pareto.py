"""Pareto maths of parasynth: one module below both the study layer and the report.

Non-dominated sorting and the hypervolume are computed by ``moocore`` (exact, O(n log n)
algorithms for two and three objectives). What parasynth adds on top, as a thin layer:

* mixed senses: objectives are turned into minimisation (:func:`to_min`, ``maximize``
  columns negated) before anything else;
* finite values only: a design with a non-finite objective is never on a front;
* constraint domination (Deb; :func:`non_dominated_ranks`): a feasible design dominates an
  infeasible one; of two infeasible designs the one with the smaller total violation
  dominates; of two feasible designs the usual Pareto dominance applies;
* the NSGA-II crowding distance and the spread of a front by repeated truncation
  (:func:`crowding_distance`, :func:`spread_by_crowding`), with parasynth's tie rules;
* the knee of a front (:func:`knee_index`);
* the standing of a reference design (:func:`reference_standing`) and the comparison of
  re-evaluated designs beyond noise (:func:`compare_with_noise`).

The one dominance test of the package is :func:`dominators_of` (which rows dominate a point);
:func:`dominates` is its two-point form.
"""

from __future__ import annotations

from dataclasses import dataclass

import moocore
import numpy as np

__all__ = ["to_min", "dominates", "dominators_of", "non_dominated_ranks", "pareto_mask", "hypervolume",
           "FAR_FENCE", "inliers", "view_range", "default_reference_point", "knee_index", "knee_order", "crowding_distance", "spread_by_crowding", "ReferenceStanding",
           "reference_standing", "NoisyComparison", "compare_with_noise"]


def to_min(F, senses) -> np.ndarray:
    """Objective matrix (n, m) in minimisation form: maximise columns are negated."""
    F = np.asarray(F, dtype=float)
    sign = np.array([1.0 if s == "minimize" else -1.0 for s in senses])
    if F.ndim != 2 or F.shape[1] != len(sign):
        raise ValueError(f"objective matrix must be (n, {len(sign)}), got {F.shape}")
    bad = [s for s in senses if s not in ("minimize", "maximize")]
    if bad:
        raise ValueError(f"senses must be 'minimize' or 'maximize', got {bad}")
    return F * sign


# -- dominance ------------------------------------------------------------------------------------
def dominators_of(Fmin, r) -> np.ndarray:
    """Boolean mask of the rows of ``Fmin`` (n, m; minimisation) that Pareto-dominate the point
    ``r`` (m,): no worse in every objective and better in at least one. A comparison with NaN
    is false, so a row or point with NaN dominates nothing and is dominated by nothing."""
    F = np.asarray(Fmin, dtype=float)
    r = np.asarray(r, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.all(F <= r, axis=-1) & np.any(F < r, axis=-1)


def dominates(a, b) -> bool:
    """Does ``a`` Pareto-dominate ``b`` (minimisation)?"""
    return bool(dominators_of(np.atleast_2d(a), b)[0])


def _finite_rows(F: np.ndarray) -> np.ndarray:
    return np.all(np.isfinite(F), axis=1) if F.size else np.zeros(len(F), bool)


def pareto_mask(F, senses, feasible=None) -> np.ndarray:
    """Non-dominated *feasible* designs (bool mask); infeasible designs and designs with a
    non-finite objective are never on it. Equal designs are all kept (weak non-dominance)."""
    Fm = to_min(F, senses)
    feas = np.ones(len(Fm), bool) if feasible is None else np.asarray(feasible, bool)
    mask = np.zeros(len(Fm), bool)
    idx = np.flatnonzero(feas & _finite_rows(Fm))
    if idx.size:
        mask[idx] = moocore.is_nondominated(Fm[idx], keep_weakly=True)
    return mask


def non_dominated_ranks(Fmin, violation=None) -> np.ndarray:
    """Front index of every design (0 = non-dominated) under constraint domination.

    ``violation`` (n,) >= 0, zero for feasible designs (default: all feasible). Feasible
    designs are sorted into Pareto fronts (``moocore.pareto_rank``); infeasible ones follow,
    one front per distinct violation, smallest first (a violation that is not a number ranks
    with the first of them, as nothing it can be compared with dominates it). Designs with
    non-finite objectives get rank n (after every front)."""
    F = np.asarray(Fmin, dtype=float)
    n = len(F)
    v = np.zeros(n) if violation is None else np.asarray(violation, dtype=float)
    finite = _finite_rows(F)
    feas = v <= 0
    ranks = np.full(n, n, dtype=int)
    fi = np.flatnonzero(finite & feas)
    base = 0
    if fi.size:
        ranks[fi] = moocore.pareto_rank(F[fi])
        base = int(ranks[fi].max()) + 1
    ii = np.flatnonzero(finite & ~feas)
    if ii.size:
        vi = v[ii]
        levels = np.unique(vi[~np.isnan(vi)])
        ranks[ii] = base + np.where(np.isnan(vi), 0, np.searchsorted(levels, vi))
    return ranks


# -- hypervolume -----------------------------------------------------------------------------------
#: Tukey's far fences: values more than this many interquartile ranges outside the quartiles are
#: far outliers (designs near a singularity reach forces of giganewtons; an axis or a reference
#: point spanning them says nothing about the designs that matter).
FAR_FENCE = 3.0


def inliers(values, fence: float | None = FAR_FENCE) -> np.ndarray:
    """The finite ``values`` inside Tukey's fences ``fence`` interquartile ranges outside the
    quartiles (all finite values with fewer than four of them, or with ``fence`` None)."""
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    if fence is None or len(v) < 4:
        return v
    q1, q3 = np.percentile(v, [25, 75])
    return v[(v >= q1 - fence * (q3 - q1)) & (v <= q3 + fence * (q3 - q1))]


def view_range(background, keep=(), pad: float = 0.08, fence: float | None = FAR_FENCE):
    """An axis's range for a plot: the span of the ``background`` values without their far
    outliers (:func:`inliers`) and of every finite value of ``keep`` (the front, marked designs),
    padded by ``pad`` of it; None where nothing is finite."""
    kept = np.asarray(keep, dtype=float).ravel()
    vals = np.concatenate([inliers(background, fence), kept[np.isfinite(kept)]])
    if not len(vals):
        return None
    lo, hi = float(vals.min()), float(vals.max())
    w = hi - lo if hi > lo else max(abs(hi), 1.0)
    return [lo - pad * w, hi + pad * w]


def default_reference_point(Fmin, margin: float = 0.1, fence: float | None = None) -> np.ndarray:
    """Nadir of the given (minimisation) points plus ``margin`` of their range per objective
    (a unit margin where the range is zero). With ``fence``, the nadir and the range of each
    objective leave out its far outliers (:func:`inliers`): a point beyond the reference point
    then adds nothing to a hypervolume."""
    F = np.asarray(Fmin, dtype=float)
    cols = [inliers(F[:, j], fence) for j in range(F.shape[1])] if fence is not None else None
    lo = np.array([c.min() for c in cols]) if cols else F.min(axis=0)
    hi = np.array([c.max() for c in cols]) if cols else F.max(axis=0)
    span = np.where(hi > lo, hi - lo, np.maximum(np.abs(hi), 1.0))
    return hi + margin * span


def hypervolume(Fmin, ref) -> float:
    """Exact hypervolume dominated by points ``Fmin`` (minimisation) and bounded by ``ref``
    (``moocore.hypervolume``). Points not strictly better than ``ref`` in every objective
    contribute nothing."""
    F = np.asarray(Fmin, dtype=float)
    ref = np.asarray(ref, dtype=float)
    if F.size == 0:
        return 0.0
    F = F[np.all(F < ref, axis=1)]
    if len(F) == 0:
        return 0.0
    return float(moocore.hypervolume(F, ref=ref))


# -- knee and spread -------------------------------------------------------------------------------
def _normalise(F):
    lo, hi = F.min(axis=0), F.max(axis=0)
    return (F - lo) / np.where(hi > lo, hi - lo, 1.0)


def knee_index(Fmin) -> int:
    """Index of the knee of a front (minimisation): in objectives normalised to [0, 1] over
    the front, the point farthest below the hyperplane through the extreme points (for two
    objectives, the chord between them); with a degenerate front, the point closest to the
    ideal point. The first of :func:`knee_order`."""
    return int(knee_order(Fmin)[0])


def knee_order(Fmin) -> np.ndarray:
    """The points of a front (minimisation) ranked by the knee criterion of :func:`knee_index`:
    farthest below the hyperplane through the extreme points first (ties by row order); with
    a degenerate front or at most two points, closest to the ideal point first. The ranking a
    recommendation walks when its first choice fails verification."""
    F = np.asarray(Fmin, dtype=float)
    n = len(F)
    if n == 0:
        return np.zeros(0, int)
    Z = _normalise(F)
    by_ideal = np.lexsort((np.arange(n), np.linalg.norm(Z, axis=1)))
    if n <= 2:
        return by_ideal
    m = Z.shape[1]
    ext = np.array([np.argmin(Z[:, j]) for j in range(m)])
    E = Z[ext]
    try:
        # Hyperplane through the extreme points: n . z = 1.
        nvec = np.linalg.solve(E, np.ones(m))
        d = (1.0 - Z @ nvec) / np.linalg.norm(nvec)
        if len(np.unique(ext)) == m and np.all(np.isfinite(d)):
            return np.lexsort((np.arange(n), -d))
    except np.linalg.LinAlgError:
        pass
    return by_ideal


def crowding_distance(F) -> np.ndarray:
    """NSGA-II crowding distance of the rows of ``F`` (n, m): per objective, the rows sorted by
    it, the two extremes get infinity and every other row the gap between its neighbours
    divided by the objective's range; distances summed over the objectives. An objective with
    zero range contributes nothing. Ties in an objective are ordered by row index."""
    F = np.asarray(F, dtype=float)
    n, m = F.shape
    d = np.zeros(n)
    if n <= 2:
        return np.full(n, np.inf)
    for j in range(m):
        order = np.lexsort((np.arange(n), F[:, j]))
        col = F[order, j]
        span = col[-1] - col[0]
        d[order[0]] = d[order[-1]] = np.inf
        if span > 0:
            d[order[1:-1]] += (col[2:] - col[:-2]) / span
    return d


def spread_by_crowding(F, k: int) -> np.ndarray:
    """Indices (ascending) of ``k`` rows of a front ``F`` spread along it: repeatedly drop the
    row with the smallest crowding distance among those left (recomputed after each drop;
    on a tie the later row goes), as in NSGA-II's truncation with recomputed crowding. The
    extremes of every objective stay as long as ``k`` allows."""
    F = np.asarray(F, dtype=float)
    keep = list(range(len(F)))
    if k <= 0:
        return np.array([], int)
    while len(keep) > k:
        d = crowding_distance(F[keep])
        worst = min(range(len(keep)), key=lambda i: (d[i], -i))
        keep.pop(worst)
    return np.array(keep, int)


# -- a reference design and noisy comparisons ------------------------------------------------------
@dataclass
class ReferenceStanding:
    """Where a reference design (the paper's) stands against the evaluated designs."""

    n_dominating: int
    dominating_indices: np.ndarray
    epsilon: float  # smallest additive shift (normalised objectives) by which the front reaches it
    best_improvements: dict  # objective -> best relative improvement among dominating designs
    on_front: bool


def reference_standing(F, senses, feasible, ref_values, labels) -> ReferenceStanding:
    """How many feasible designs dominate the reference and by how much.

    ``epsilon``: the additive epsilon indicator of the feasible front with respect to the
    reference in objectives normalised by their feasible range: > 0 means no design
    dominates it by that much, < 0 that some design is better by -epsilon in every
    objective (normalised)."""
    Fm = to_min(F, senses)
    r = to_min(np.atleast_2d(ref_values), senses)[0]
    feas = np.asarray(feasible, bool) & _finite_rows(Fm)
    dom = feas & dominators_of(Fm, r)
    idx = np.flatnonzero(dom)
    imp = {}
    for j, lab in enumerate(labels):
        if idx.size:
            best = Fm[idx, j].min()
            imp[lab] = float((r[j] - best) / abs(r[j])) if r[j] != 0 else float("nan")
    if feas.any():
        span = Fm[feas].max(axis=0) - Fm[feas].min(axis=0)
        span = np.where(span > 0, span, 1.0)
        eps = float(np.min(np.max((Fm[feas] - r) / span, axis=1)))
    else:
        eps = float("nan")
    on_front = not dom.any()
    return ReferenceStanding(int(dom.sum()), idx, eps, imp, on_front)


@dataclass
class NoisyComparison:
    """Design A against design B on re-evaluated objectives (means and standard errors).

    ``status[j]``: +1 A better than B on objective j by more than ``z`` combined standard
    errors, -1 worse by more, 0 within noise. ``diff[j]``: A - B in the objective's sense
    (> 0: A better), ``se[j]``: the combined standard error sqrt(se_A^2 + se_B^2) (NaN when
    a standard error is unknown: then the means decide and ``noise_known`` is False).
    ``verdict``: "dominates" (better beyond noise somewhere, worse beyond noise nowhere),
    "dominated" (the reverse), "trade-off" (both) or "within noise" (no difference beyond
    noise)."""

    status: np.ndarray
    diff: np.ndarray
    se: np.ndarray
    z: float
    noise_known: bool

    @property
    def verdict(self) -> str:
        better, worse = bool((self.status > 0).any()), bool((self.status < 0).any())
        if better and worse:
            return "trade-off"
        if better:
            return "dominates"
        if worse:
            return "dominated"
        return "within noise"


def compare_with_noise(a_mean, a_se, b_mean, b_se, senses, z: float = 2.0) -> NoisyComparison:
    """Compare design A with design B objective by objective, a difference counting only when
    it exceeds ``z`` combined standard errors (default 2: a two-sided test at about 95 % for
    independent estimates). Standard errors may be NaN (one repeat): the means then decide."""
    sign = np.array([1.0 if s == "maximize" else -1.0 for s in senses])
    a, b = np.asarray(a_mean, float), np.asarray(b_mean, float)
    sa, sb = np.asarray(a_se, float), np.asarray(b_se, float)
    diff = (a - b) * sign
    se = np.sqrt(sa**2 + sb**2)
    known = np.isfinite(se)
    thr = np.where(known, z * np.where(known, se, 0.0), 0.0)
    status = np.where(diff > thr, 1, np.where(diff < -thr, -1, 0))
    return NoisyComparison(status.astype(int), diff, se, float(z), bool(known.all()))
