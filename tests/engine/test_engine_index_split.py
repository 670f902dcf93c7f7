"""A design's few hundred poses of the singularity margin cut into ranges of poses spread over
threads (``engine.indices._kernel`` with ``_SPLIT``): the same numbers, bit for bit, as on one
thread, and as the NumPy reference to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from parasynth import load_mechanism
from parasynth.engine import core, indices

pytestmark = pytest.mark.skipif(not core.HAVE_NUMBA, reason="numba not available")


@pytest.mark.parametrize("name", ["5pus_upu", "hexapod_6pus", "2rpu_2sps"])
@pytest.mark.parametrize("n", [40, 150, 700])
def test_split_margin_equals_one_thread(name, n, monkeypatch):
    mech = load_mechanism(name)
    rng = np.random.default_rng(n)
    r = mech.default_ranges()
    X = np.repeat(np.asarray(mech.home, float)[None, :], 20 * n, axis=0)
    for j, c in enumerate(mech.task_coordinates):
        if c in r:
            X[:, j] = rng.uniform(*r[c], len(X))
    X = np.ascontiguousarray(X[mech.is_feasible(X)][:n])
    assert len(X) >= 20
    if len(X) * indices._SPLIT["_margin_kernel"][1] < indices.WORK_MIN_NS:
        monkeypatch.setattr(indices, "WORK_MIN_NS", 0.0)  # split even a small batch
    monkeypatch.setattr(core, "ADAPTIVE", False)  # threads whenever there are several
    calls = []
    real = indices._ranges

    def spy(*a):
        calls.append(a[-1])
        return real(*a)

    monkeypatch.setattr(indices, "_ranges", spy)
    try:
        core.set_threads(1)
        one = mech.singularity_margin(X)
        assert calls == []  # one thread: the chunks, not the ranges
        core.set_threads(None)
        if core.n_threads() < 2:
            pytest.skip("one thread only")
        split = mech.singularity_margin(X)
        assert calls == [True]
    finally:
        core.set_threads(None)
    np.testing.assert_array_equal(split, one)
    ref = mech.singularity_margin(X, engine="numpy")
    np.testing.assert_allclose(split, ref, rtol=0, atol=1e-9)
    assert np.isfinite(one).sum() > len(X) // 2
