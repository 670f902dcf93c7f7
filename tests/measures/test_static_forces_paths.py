"""The two ways the static balance and the UPU constraint wrench are solved, checked against
LAPACK's least squares and SVD called independently: a well-conditioned square balance by the
inverse (the minimum-norm solution, which is the unique one), an ill-conditioned or singular one
by the SVD with its small singular values dropped; the reciprocal direction of five twists by a
QR factorisation (the SVD's null vector up to sign)."""
from __future__ import annotations

import numpy as np
import pytest

from parasynth.measures import indices as I
from parasynth.model.spatial import null_direction


class _System:
    """A stand-in for :class:`parasynth.measures.indices.WrenchSystem`: the equilibrium columns
    (N, 6, k) and the reachable poses."""

    def __init__(self, M, reachable=None):
        self._M = M
        self.reachable = np.ones(M.shape[0], dtype=bool) if reachable is None else reachable

    def matrix(self):
        return self._M


def _reference(M, w, L, rtol=1e-10):
    """numpy.linalg.lstsq of the scaled, column-normalised system, pose by pose."""
    out = []
    for Mi, wi in zip(M, w):
        Ms = Mi.copy()
        Ms[3:] /= L
        b = -np.r_[wi[:3], wi[3:] / L]
        cn = np.linalg.norm(Ms, axis=0)
        cn = np.where(cn > 0, cn, 1.0)
        y = np.linalg.lstsq(Ms / cn, b, rcond=rtol)[0]
        out.append(y / cn)
    return np.array(out)


def test_square_balances_agree_with_lstsq_conditioned_or_not():
    rng = np.random.default_rng(4)
    N, L = 64, 0.3
    M = rng.normal(size=(N, 6, 6))
    # ill-conditioned rows: one column nearly the sum of two others (condition ~1e12), one singular
    M[5, :, 5] = M[5, :, 0] + M[5, :, 1] + 1e-12 * rng.normal(size=6)
    M[9, :, 4] = 2.0 * M[9, :, 2]
    w = rng.normal(size=(N, 6))
    x, res, balanced, ok = I._lstsq_balance(_System(M), w, L)
    ref = _reference(M, w, L)
    assert ok.all()
    np.testing.assert_allclose(x, ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())
    regular = np.setdiff1d(np.arange(N), [5, 9])
    assert balanced[regular].all()  # a square regular system balances any load
    # the minimum-norm split of the singular row: no share along the dependent column pair
    np.testing.assert_allclose(x[9], ref[9], rtol=1e-9)
    # the direct solve is what answered the regular rows: forcing the SVD everywhere agrees
    old = I._DIRECT_COND
    try:
        I._DIRECT_COND = -1.0
        x_svd = I._lstsq_balance(_System(M), w, L)[0]
    finally:
        I._DIRECT_COND = old
    np.testing.assert_allclose(x[regular], x_svd[regular], rtol=1e-11, atol=1e-12)


def test_unreachable_poses_and_other_shapes():
    rng = np.random.default_rng(5)
    M = rng.normal(size=(6, 6, 6))
    M[2] = np.nan
    reach = np.ones(6, dtype=bool)
    reach[4] = False
    w = rng.normal(size=(6, 6))
    x, res, balanced, ok = I._lstsq_balance(_System(M, reach), w, 0.5)
    assert ok.tolist() == [True, True, False, True, False, True]
    assert np.isnan(x[[2, 4]]).all() and np.isfinite(x[[0, 1, 3, 5]]).all()
    keep = [0, 1, 3, 5]
    np.testing.assert_allclose(x[keep], _reference(M[keep], w[keep], 0.5), rtol=1e-10)
    # fewer columns than six (under-actuated) and more (redundant constraints): the SVD's answer
    for k in (5, 8):
        Mk = rng.normal(size=(10, 6, k))
        wk = rng.normal(size=(10, 6))
        np.testing.assert_allclose(I._lstsq_balance(_System(Mk), wk, 0.5)[0], _reference(Mk, wk, 0.5), rtol=1e-10)


@pytest.mark.parametrize("seed", [0, 1])
def test_the_reciprocal_direction_of_five_twists_is_the_svds_null_vector(seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(200, 5, 6))
    A[7, 4] = A[7, 0] - 2.0 * A[7, 3]  # rank four: one direction of the two-dimensional null space
    v = null_direction(A)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, rtol=1e-14)
    assert np.abs(np.einsum("nij,nj->ni", A, v)).max() < 1e-13
    full = [i for i in range(200) if i != 7]
    u = np.linalg.svd(A[full])[2][:, -1]  # the last right singular vector of each 5x6 system
    np.testing.assert_allclose(np.abs(np.einsum("ni,ni->n", u, v[full])), 1.0, atol=1e-12)
    A[3] = np.nan
    assert np.isnan(null_direction(A)[3]).all()
