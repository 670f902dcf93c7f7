"""A design's few hundred poses of the singularity margin spread over threads in blocks of a
few poses that the threads claim (``engine.indices._kernel`` with ``_CLAIMING``): the same
numbers, bit for bit, as on one thread, and as the NumPy reference to rounding."""

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
    if len(X) * indices._CLAIMING["_margin_kernel"] < indices.WORK_MIN_NS:
        monkeypatch.setattr(indices, "WORK_MIN_NS", 1.0)  # spread even a small batch
    monkeypatch.setattr(core, "ADAPTIVE", False)  # threads whenever there are several
    calls = []
    real = core.over_blocks

    def spy(fn, n_blocks, parallel=True, claiming=False):
        calls.append((n_blocks, parallel, claiming))
        return real(fn, n_blocks, parallel, claiming)

    monkeypatch.setattr(core, "over_blocks", spy)
    monkeypatch.setattr(core, "_compiled_batch", lambda *a: calls.append((0, True, True)))
    try:
        core.set_threads(1)
        one = mech.singularity_margin(X)
        assert not any(par for _, par, _ in calls)  # one thread: no parallel batch (none handed to the crew)
        core.set_threads(None)
        if core.n_threads() < 2:
            pytest.skip("one thread only")
        calls.clear()
        split = mech.singularity_margin(X)
        # the margin's batch on every thread, each claiming blocks of a few poses
        assert (core.n_threads(), True, True) in calls
        block, nblk, par = core.blocking(len(X), 2, work=len(X) * 1e9, per_thread=core.CLAIMS_PER_THREAD,
                                         unit=indices.MIN_BLOCK)
        assert par and block < len(X) / 2 and block % indices.MIN_BLOCK == 0
    finally:
        core.set_threads(None)
    np.testing.assert_array_equal(split, one)
    ref = mech.singularity_margin(X, engine="numpy")
    np.testing.assert_allclose(split, ref, rtol=0, atol=1e-9)
    assert np.isfinite(one).sum() > len(X) // 2
