"""Pareto analysis with mixed senses and constraint domination.

Objectives are turned into minimisation internally (``maximize`` columns negated). Constraint
domination (Deb): a feasible design dominates an infeasible one; of two infeasible designs the
one with the smaller total violation dominates; of two feasible designs the usual Pareto
dominance applies.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["to_min", "dominates", "non_dominated_ranks", "pareto_mask", "hypervolume", "default_reference_point",
           "knee_index", "ReferenceStanding", "reference_standing", "NoisyComparison", "compare_with_noise"]


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


def dominates(a: np.ndarray, b: np.ndarray) -> bool:
    """Does ``a`` Pareto-dominate ``b`` (minimisation)?"""
    return bool(np.all(a <= b) and np.any(a < b))


def non_dominated_ranks(Fmin: np.ndarray, violation: np.ndarray | None = None) -> np.ndarray:
    """Front index of every design (0 = non-dominated) under constraint domination.

    ``violation`` (n,) >= 0, zero for feasible designs (default: all feasible). Designs with
    non-finite objectives get rank n (after every front)."""
    F = np.asarray(Fmin, dtype=float)
    n = len(F)
    v = np.zeros(n) if violation is None else np.asarray(violation, dtype=float)
    finite = np.all(np.isfinite(F), axis=1)
    feas = v <= 0
    dom = np.zeros((n, n), bool)  # dom[i, j]: i dominates j
    for i in np.flatnonzero(finite):
        if feas[i]:
            pareto = np.all(F[i] <= F, axis=1) & np.any(F[i] < F, axis=1)
            dom[i] = np.where(feas, pareto, True)
        else:
            dom[i] = ~feas & (v[i] < v)
        dom[i, i] = False
    ranks = np.full(n, n, dtype=int)
    idx = np.flatnonzero(finite)
    r = 0
    while idx.size:
        front = idx[~dom[np.ix_(idx, idx)].any(axis=0)]
        ranks[front] = r
        idx = np.setdiff1d(idx, front)
        r += 1
    return ranks


def pareto_mask(F, senses, feasible=None) -> np.ndarray:
    """Non-dominated *feasible* designs (bool mask); infeasible designs are never on it."""
    Fm = to_min(F, senses)
    feas = np.ones(len(Fm), bool) if feasible is None else np.asarray(feasible, bool)
    mask = np.zeros(len(Fm), bool)
    ok = feas & np.all(np.isfinite(Fm), axis=1)
    idx = np.flatnonzero(ok)
    sub = Fm[idx]
    for k, i in enumerate(idx):
        dominated = np.all(sub <= sub[k], axis=1) & np.any(sub < sub[k], axis=1)
        mask[i] = not dominated.any()
    return mask


def default_reference_point(Fmin: np.ndarray, margin: float = 0.1) -> np.ndarray:
    """Nadir of the given (minimisation) points plus ``margin`` of their range per objective
    (a unit margin where the range is zero)."""
    F = np.asarray(Fmin, dtype=float)
    lo, hi = F.min(axis=0), F.max(axis=0)
    span = np.where(hi > lo, hi - lo, np.maximum(np.abs(hi), 1.0))
    return hi + margin * span


def hypervolume(Fmin: np.ndarray, ref) -> float:
    """Exact hypervolume dominated by points ``Fmin`` (minimisation) and bounded by ``ref``.

    Recursive slicing along the last objective (fine for the few objectives and the front
    sizes of design studies). Points not strictly better than ``ref`` in every objective
    contribute nothing."""
    F = np.asarray(Fmin, dtype=float)
    ref = np.asarray(ref, dtype=float)
    if F.size == 0:
        return 0.0
    F = F[np.all(F < ref, axis=1)]
    if len(F) == 0:
        return 0.0
    return _hv(F, ref)


def _hv(F: np.ndarray, ref: np.ndarray) -> float:
    m = F.shape[1]
    if m == 1:
        return float(ref[0] - F[:, 0].min())
    if m == 2:
        P = F[np.argsort(F[:, 0])]
        vol, best_y = 0.0, ref[1]
        for x, y in P:
            if y < best_y:
                vol += (ref[0] - x) * (best_y - y)
                best_y = y
        return float(vol)
    order = np.argsort(F[:, -1])
    P = F[order]
    vol = 0.0
    for k in range(len(P)):
        z = P[k, -1]
        z_next = P[k + 1, -1] if k + 1 < len(P) else ref[-1]
        if z_next > z:
            vol += _hv(P[: k + 1, :-1], ref[:-1]) * (z_next - z)
    return float(vol)


def knee_index(Fmin: np.ndarray) -> int:
    """Index of the knee of a front (minimisation): in objectives normalised to [0, 1] over
    the front, the point farthest below the hyperplane through the extreme points (for two
    objectives, the chord between them); with a degenerate front, the point closest to the
    ideal point."""
    F = np.asarray(Fmin, dtype=float)
    if len(F) <= 2:
        return int(np.argmin(np.linalg.norm(_normalise(F), axis=1)))
    Z = _normalise(F)
    m = Z.shape[1]
    ext = np.array([np.argmin(Z[:, j]) for j in range(m)])
    E = Z[ext]
    try:
        # Hyperplane through the extreme points: n . z = 1.
        nvec = np.linalg.solve(E, np.ones(m))
        d = (1.0 - Z @ nvec) / np.linalg.norm(nvec)
        if len(np.unique(ext)) == m and np.all(np.isfinite(d)):
            return int(np.argmax(d))
    except np.linalg.LinAlgError:
        pass
    return int(np.argmin(np.linalg.norm(Z, axis=1)))


def _normalise(F):
    lo, hi = F.min(axis=0), F.max(axis=0)
    return (F - lo) / np.where(hi > lo, hi - lo, 1.0)


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
    feas = np.asarray(feasible, bool) & np.all(np.isfinite(Fm), axis=1)
    dom = feas & np.all(Fm <= r, axis=1) & np.any(Fm < r, axis=1)
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
