"""Feasibility and the platform positions' extents in one kernel pass
(``parasynth.engine.feasible_extents``), as ``workspace`` uses it.

Checked against what it replaces, computed apart: the feasibility of ``is_feasible`` and the
least / greatest platform position over the feasible poses from ``pose_batch`` (the compiled
program: equal to the last bit; the NumPy pose: to 1e-12). Also the cases where it must decline
(None): the NumPy engine, a singularity-margin floor; and ``workspace``'s extents and counts
against a NumPy-engine workspace of the same samples.
"""

from __future__ import annotations

import numpy as np
import pytest

import parasynth
from parasynth import engine
from parasynth.measures.workspace import workspace

MODELS = ["5pus_upu", "2rpu_2sps", "4ups_1rps", "hexapod_6pus", "3prs", "gough_stewart_6ups"]


def _poses(mech, n=3000, seed=3):
    rng = np.random.default_rng(seed)
    r = mech.default_ranges()
    X = np.repeat(np.asarray(mech.home, dtype=float)[None, :], n, axis=0)
    for j, c in enumerate(mech.task_coordinates):
        if c in r:
            lo, hi = r[c]
            w = hi - lo
            X[:, j] = rng.uniform(lo - 0.2 * w, hi + 0.2 * w, n)  # some poses outside the box
    return X


@pytest.mark.parametrize("name", MODELS)
def test_extents_equal_the_feasible_poses_positions(name):
    mech = parasynth.load_mechanism(name)
    X = _poses(mech)
    got = engine.feasible_extents(mech, X)
    if not engine.available(mech):
        assert got is None
        return
    assert got is not None
    ok, lo, hi = got
    ref = mech.is_feasible(X)
    np.testing.assert_array_equal(ok, ref)
    assert 0 < ok.sum() < len(X)  # neither vacuous nor trivial
    p_c = engine.pose_batch(mech, X[ok])[1]
    np.testing.assert_array_equal(lo, p_c.min(axis=0))
    np.testing.assert_array_equal(hi, p_c.max(axis=0))
    p_n = engine.pose_batch(mech, X[ok], engine="numpy")[1]
    np.testing.assert_allclose(lo, p_n.min(axis=0), rtol=0, atol=1e-12)
    np.testing.assert_allclose(hi, p_n.max(axis=0), rtol=0, atol=1e-12)


def test_no_feasible_pose_gives_infinite_extents():
    mech = parasynth.load_mechanism("5pus_upu")
    X = np.tile(np.asarray(mech.home, dtype=float), (300, 1))
    X[:, 2] = 50.0  # far above the reach of every leg
    ok, lo, hi = engine.feasible_extents(mech, X)
    assert not ok.any()
    assert np.all(lo == np.inf) and np.all(hi == -np.inf)


def test_declines_where_one_pass_is_not_the_answer():
    mech = parasynth.load_mechanism("5pus_upu")
    X = _poses(mech, 100)
    assert engine.feasible_extents(mech, X, engine="numpy") is None
    with pytest.raises(ValueError, match="engine"):
        engine.feasible_extents(mech, X, engine="fortran")


def test_workspace_extents_match_the_numpy_engine():
    mech = parasynth.load_mechanism("hexapod_6pus", link_length=0.71)
    a = workspace(mech, n=2**13, keep_points=False, progress=False)
    b = workspace(mech, n=2**13, keep_points=False, progress=False, engine="numpy")
    assert a.n_feasible == b.n_feasible > 0
    for ax in "xyz":
        np.testing.assert_allclose(a.extents[ax], b.extents[ax], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(a._raster.feasible, b._raster.feasible)


def test_declines_for_a_class_whose_is_feasible_checks_more():
    base = parasynth.load_mechanism("5pus_upu")

    class Stricter(type(base)):
        def is_feasible(self, X, names=None, engine="compiled"):
            return super().is_feasible(X, names, engine) & (np.asarray(X)[..., 0] > 0)

    mech = Stricter(base.params)
    X = _poses(mech, 500)
    assert engine.feasible_extents(mech, X) is None
    assert engine.feasible_extents(base, X) is not None
    ws = workspace(mech, n=2**12, keep_points=False, progress=False)
    ref = workspace(mech, n=2**12, keep_points=False, progress=False, engine="numpy")
    full = workspace(base, n=2**12, keep_points=False, progress=False)
    assert ws.n_feasible == ref.n_feasible < full.n_feasible  # the subclass's own check counted
    assert ws.extents["x"][0] >= 0.0
