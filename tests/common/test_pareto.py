"""Pareto maths (parasynth.common.pareto) against brute force, known values and Monte Carlo."""

import itertools

import numpy as np
import pytest

import parasynth.report as report_pkg
import parasynth.report.pareto as report_pareto
import parasynth.study.final as final_mod
from _support import brute_crowding, brute_force_front, brute_spread
from parasynth.common.pareto import (crowding_distance, default_reference_point, inliers, view_range, dominates, dominators_of, hypervolume, knee_index,
                                     non_dominated_ranks, pareto_mask, reference_standing, spread_by_crowding)


@pytest.mark.parametrize("seed", range(8))
def test_pareto_mask_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    n, m = 60, 2 + seed % 3
    F = rng.integers(0, 6, size=(n, m)).astype(float)  # ties on purpose
    senses = [("minimize", "maximize")[k % 2] for k in range(m)]
    feas = rng.random(n) > 0.3
    np.testing.assert_array_equal(pareto_mask(F, senses, feas), brute_force_front(F, senses, feas))


def test_constraint_domination_ranks():
    F = np.array([[1, 5], [2, 3], [3, 4], [4, 1], [5, 5]], float)
    v = np.array([0, 0, 0, 1.0, 0.5])
    r = non_dominated_ranks(F, v)
    # feasible fronts first ({0, 1}, then {2}); infeasible by violation (4: 0.5, then 3: 1.0)
    assert list(r) == [0, 0, 1, 3, 2]
    # no infeasible design ever ranks before a feasible one
    assert r[v > 0].min() > r[v == 0].max()


def test_hypervolume_known_values():
    assert hypervolume(np.array([[1.0, 5], [2, 3], [4, 1]]), [6, 6]) == pytest.approx(17.0)
    # one point: a box
    assert hypervolume(np.array([[1.0, 2, 3]]), [2, 4, 7]) == pytest.approx(1 * 2 * 4)
    # two boxes in 3-D with a known overlap: [0,2]x[0,1]x[0,1] and [0,1]x[0,2]x[0,1] from ref 2,2,1
    P = np.array([[0.0, 1, 0], [1, 0, 0]])
    assert hypervolume(P, [2, 2, 1]) == pytest.approx(2 + 2 - 1)
    # points not better than the reference contribute nothing
    assert hypervolume(np.array([[3.0, 3]]), [2, 2]) == 0.0


def test_hypervolume_against_monte_carlo():
    rng = np.random.default_rng(0)
    P = rng.random((12, 3))
    ref = np.ones(3) * 1.1
    exact = hypervolume(P, ref)
    S = rng.random((400_000, 3)) * 1.1
    dominated = np.zeros(len(S), bool)
    for p in P:
        dominated |= np.all(S >= p, axis=1)
    mc = dominated.mean() * 1.1**3
    assert exact == pytest.approx(mc, rel=0.01)


def test_knee_of_a_convex_front():
    x = np.linspace(0, 1, 21)
    F = np.column_stack([x, (1 - np.sqrt(x)) ** 2])  # symmetric about x = y, knee at x = 0.25
    k = knee_index(F)
    assert F[k, 0] == pytest.approx(0.25, abs=0.051)


def test_reference_standing_counts_dominators():
    F = np.array([[1.0, 1], [2, 2], [0.5, 3], [3, 0.5]])
    st = reference_standing(F, ["minimize", "minimize"], np.ones(4, bool), np.array([2.5, 2.5]), ["a", "b"])
    assert st.n_dominating == 2 and set(st.dominating_indices) == {0, 1}
    assert st.best_improvements["a"] == pytest.approx((2.5 - 1) / 2.5)


@pytest.mark.parametrize("seed", range(6))
def test_crowding_selection_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    n, m = 25, 2 + seed % 2
    if m == 2:
        x = np.sort(rng.random(n))
        F = np.column_stack([x, (1 - x) ** (0.5 + seed)])  # a front (minimisation), uneven spacing
    else:
        F = rng.dirichlet(np.ones(3), size=n)  # points on a simplex: mutually non-dominated
    np.testing.assert_allclose(crowding_distance(F), brute_crowding(F))
    for k in (3, 7, 12):
        sel = spread_by_crowding(F, k)
        assert list(sel) == brute_spread(F, k)
        # the extremes of every objective are kept when k allows
        for j in range(m if k >= 2 * m else 0):
            assert int(np.argmin(F[:, j])) in sel and int(np.argmax(F[:, j])) in sel


def brute_force_ranks(F, v):
    """Front index under constraint domination by repeated peeling, pair by pair."""
    n = len(F)
    finite = [bool(np.all(np.isfinite(F[i]))) for i in range(n)]

    def dom(i, j):
        fi, fj = v[i] <= 0, v[j] <= 0
        if fi and fj:
            return bool(np.all(F[i] <= F[j]) and np.any(F[i] < F[j]))
        if fi:
            return True
        if fj:
            return False
        return bool(v[i] < v[j])

    ranks = [n] * n
    left = [i for i in range(n) if finite[i]]
    r = 0
    while left:
        front = [j for j in left if not any(i != j and dom(i, j) for i in left)]
        for j in front:
            ranks[j] = r
        left = [j for j in left if j not in front]
        r += 1
    return np.array(ranks)


@pytest.mark.parametrize("seed", range(10))
def test_constraint_domination_ranks_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    n, m = 40, 2 + seed % 3
    F = rng.integers(0, 5, size=(n, m)).astype(float)  # ties and duplicates on purpose
    v = np.where(rng.random(n) < 0.4, rng.integers(1, 4, n) / 2, 0.0)  # repeated violations
    F[rng.random(n) < 0.1, 0] = np.nan  # designs without finite objectives rank last
    if seed % 2:
        v[rng.random(n) < 0.1] = np.nan  # a violation that is not a number
    np.testing.assert_array_equal(non_dominated_ranks(F, v), brute_force_ranks(F, v))
    np.testing.assert_array_equal(non_dominated_ranks(F), brute_force_ranks(F, np.zeros(n)))


def test_all_infeasible_and_empty_ranks():
    F = np.array([[1.0, 2], [0, 0], [3, 3]])
    assert list(non_dominated_ranks(F, np.array([2.0, 1.0, 1.0]))) == [1, 0, 0]
    assert non_dominated_ranks(np.zeros((0, 2))).shape == (0,)
    assert not pareto_mask(np.zeros((0, 2)), ["minimize", "maximize"]).any()


def test_one_dominance_test():
    F = np.array([[1.0, 1], [1, 2], [2, 2], [0, 3], [np.nan, 0]])
    r = np.array([1.0, 2])
    np.testing.assert_array_equal(dominators_of(F, r), [True, False, False, False, False])
    assert dominates([1, 1], [1, 2]) and not dominates([1, 2], [1, 2]) and not dominates([0, 3], [1, 2])
    # every pair of a random set agrees with the definition
    G = np.random.default_rng(3).integers(0, 3, size=(15, 3)).astype(float)
    for a, b in itertools.product(G, G):
        assert dominates(a, b) == (all(a <= b) and any(a < b))


def _hv_by_inclusion_exclusion(P, ref):
    """Hypervolume of the union of the boxes [p, ref] by inclusion-exclusion (small sets)."""
    P = [p for p in P if np.all(p < ref)]
    total = 0.0
    for k in range(1, len(P) + 1):
        for sub in itertools.combinations(P, k):
            corner = np.max(sub, axis=0)
            total += (-1) ** (k + 1) * float(np.prod(np.maximum(ref - corner, 0.0)))
    return total


@pytest.mark.parametrize("seed", range(6))
def test_hypervolume_matches_inclusion_exclusion(seed):
    rng = np.random.default_rng(seed)
    m = 2 + seed % 3
    P = rng.random((9, m))
    ref = np.full(m, 0.95)
    assert hypervolume(P, ref) == pytest.approx(_hv_by_inclusion_exclusion(P, ref), rel=1e-12, abs=1e-15)


def test_public_names_are_the_one_definition():
    for name in ("hypervolume", "pareto_mask", "non_dominated_ranks", "knee_index", "reference_standing", "to_min",
                 "compare_with_noise"):
        assert getattr(report_pkg, name) is getattr(report_pareto, name)
    assert report_pkg.hypervolume is hypervolume and report_pareto.dominates is dominates
    assert final_mod.crowding_distance is crowding_distance and final_mod.spread_by_crowding is spread_by_crowding


def test_far_outliers_leave_the_reference_point_and_the_view():
    """Tukey's far fences by hand: 1..10 (kN) and one design near a singularity at 3.8e8. The
    quartiles (linear) are 3.5 and 8.5, the fences -11.5 and 23.5: the outlier is left out of
    the nadir of the reference point and of a view range, a front point beyond stays in."""
    v = [float(k) for k in range(1, 11)] + [3.8e8]
    assert sorted(inliers(v)) == [float(k) for k in range(1, 11)]
    assert list(inliers(v, fence=None)) == v
    assert list(inliers([1.0, 2.0, 1e9])) == [1.0, 2.0, 1e9]  # fewer than four: nothing to fence
    F = np.column_stack([v, [2.0 * x for x in v]])
    np.testing.assert_allclose(default_reference_point(F, fence=3.0), [10 + 0.1 * 9, 20 + 0.1 * 18])
    np.testing.assert_allclose(default_reference_point(F), [3.8e8 + 0.1 * (3.8e8 - 1), 7.6e8 + 0.1 * (7.6e8 - 2)])
    assert view_range(v, [], pad=0.0) == [1.0, 10.0]
    assert view_range(v, [30.0], pad=0.1) == pytest.approx([1.0 - 2.9, 30.0 + 2.9])
    assert view_range([np.nan], [np.inf]) is None
