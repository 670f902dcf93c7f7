"""parasynth.common.stats.quantile against np.quantile: the same bits."""

import numpy as np
import pytest

from parasynth.common.stats import quantile


def _same(a: float, b: float) -> bool:
    return a == b or (np.isnan(a) and np.isnan(b))


@pytest.mark.parametrize("n", [1, 2, 3, 7, 100, 1001, 4096])
def test_quantile_is_numpys_linear_quantile(n):
    rng = np.random.default_rng(n)
    qs = [0.0, 1e-9, 0.01, 0.05, 0.25, 0.5, 0.5 + 1e-12, 0.75, 0.95, 0.999, 1.0] + list(rng.uniform(0, 1, 40))
    for data in (rng.normal(size=n), rng.exponential(size=n) * 1e-3, np.round(rng.normal(size=n), 1),
                 np.full(n, 2.5), -rng.uniform(size=n) * 1e300):
        v = data.copy()
        for q in qs:
            expected = float(np.quantile(data, q, method="lower" if q == 0 else "linear"))
            got = quantile(v, q)
            assert _same(got, expected), (n, q, got, expected)
        assert np.array_equal(v, data)  # not reordered


def test_quantile_with_infinite_values_and_interpolation_halves():
    v = np.array([1.0, np.inf, -np.inf, 3.0, 2.0])
    for q in (0.0, 0.1, 0.25, 0.5, 0.6, 0.75, 0.9, 1.0):
        assert _same(quantile(v, q), float(np.quantile(v, q, method="lower" if q == 0 else "linear"))), q
    # an index exactly half-way between two values takes the b - d (1 - g) branch
    w = np.array([0.1, 0.7])
    assert quantile(w, 0.5) == float(np.quantile(w, 0.5))


@pytest.mark.parametrize("q", [-0.1, 1.5, float("nan")])
def test_quantile_refuses_q_outside_0_1(q):
    with pytest.raises(ValueError, match="quantile must be in"):
        quantile(np.ones(3), q)


def test_quantile_of_nothing_is_an_error():
    with pytest.raises(ValueError, match="empty"):
        quantile(np.empty(0), 0.5)
