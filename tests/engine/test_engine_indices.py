"""Compiled pose-wise indices against the NumPy reference.

The reference is the NumPy path of the same definitions (``engine="numpy"``: LAPACK SVDs of
the legs' wrench systems built by :mod:`parasynth.model.legs`), on random poses of every shipped
mechanism and variant; the contract is agreement to 1e-9 (absolute for the margin and the
transmission indices, which lie in [0, 1]; relative for condition numbers). The one-sided
Jacobi SVD is checked against matrices of known singular values, and the constraint rank
against :meth:`Mechanism.mobility`.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

import parasynth
from parasynth.measures import objectives
from parasynth.engine import indices as ei
from parasynth.measures.indices import (global_conditioning_index, local_condition_number, local_transmission_index,
                                        output_transmission_index, pressure_angle_indices, singularity_margin_stats,
                                        transmission_indices)
from parasynth.model.legs import UPS
from parasynth.model.mechanism import Mechanism
from parasynth.measures.robustness import AsBuilt

pytestmark = pytest.mark.skipif(not ei.HAVE_NUMBA, reason="numba is not importable: no compiled indices")

ATOL = 1e-9
RTOL_KAPPA = 1e-9

#: Every shipped mechanism with its default parameters, and the variants of the paper models.
CONFIGS = [(name, {}) for name in parasynth.list_mechanisms()] + [
    ("2rpu_2sps", {"coupled": False}),
    ("5pus_upu", {"platform": "pentagonal"}),
    ("5pus_upu", {"hinge_layout": "scheme2"}),
]
IDS = [n + ("-" + "-".join(f"{k}={v}" for k, v in kw.items()) if kw else "") for n, kw in CONFIGS]

_MECHS: dict = {}


def _mech(name, kw):
    key = (name, tuple(sorted(kw.items())))
    if key not in _MECHS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _MECHS[key] = parasynth.load_mechanism(name, **kw)
    return _MECHS[key]


def _box(mech):
    """Sampling box: the model's default ranges, coordinates without a range +-0.3 (rad or m
    x 0.2) about home."""
    rg = mech.default_ranges()
    lo, hi = [], []
    for c, h in zip(mech.task_coordinates, mech.home):
        if c in rg:
            a, b = rg[c]
        else:
            w = 0.3 if c in mech.angular_coordinates else 0.06
            a, b = h - w, h + w
        lo.append(a)
        hi.append(b)
    return np.array(lo), np.array(hi)


def _poses(mech, n=400, seed=0):
    """Random reachable poses (up to ``n``) plus a few the legs cannot reach (NaN results
    expected) and one with a NaN coordinate."""
    rng = np.random.default_rng(seed)
    lo, hi = _box(mech)
    X = lo + (hi - lo) * rng.random((20 * n, mech.n_task))
    reach = mech.inverse_kinematics(X).reachable
    good = X[reach][:n]
    bad = X[~reach][:5]
    nan = np.full((1, mech.n_task), np.nan)
    return np.concatenate([good, bad, nan]), len(good)


@pytest.fixture(params=CONFIGS, ids=IDS)
def mech_poses(request):
    name, kw = request.param
    mech = _mech(name, kw)
    X, n_good = _poses(mech)
    assert n_good >= 50, f"{name}: too few reachable random poses to test ({n_good})"
    return mech, X, len(X) - n_good


def _same_nan(a, b):
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b))


# ---------------------------------------------------------------------------------------------
# Agreement with NumPy on every shipped mechanism
# ---------------------------------------------------------------------------------------------
def test_singularity_margin_agrees(mech_poses):
    mech, X, n_bad = mech_poses
    ref = mech.singularity_margin(X, engine="numpy")
    got = mech.singularity_margin(X, engine="compiled")
    _same_nan(ref, got)
    ok = np.isfinite(ref)
    assert ok.sum() >= 50
    np.testing.assert_allclose(got[ok], ref[ok], rtol=0, atol=ATOL)
    # NaN for the unreachable poses and the invalid one (listed last)
    assert np.all(np.isnan(got[-n_bad:]))


def test_singularity_margin_at_explicit_poses_of_perturbed_legs_agrees(mech_poses):
    """The compiled margin at explicit poses (the actual poses of a mechanism as built) of
    legs with moved anchors and tilted axes equals the NumPy margin of a mechanism with those
    legs at those poses, including poses off the parametrisation (a small twist applied)."""
    import copy

    from parasynth import engine
    from parasynth.measures.accuracy import _check_tolerances, _compose, _perturbed_legs, _sample_errors, error_sources

    mech, X, n_bad = mech_poses
    Xg = X[:-n_bad]
    src = error_sources(mech)
    tol = _check_tolerances({"anchor_tolerance": 2e-4, "axis_tolerance": 2e-3, "link_tolerance": 1e-4})
    e = _sample_errors(src, tol, 1, np.random.default_rng(3))[0]
    mob = mech.mobility()
    under = not mob.controlled or mob.redundant_constraints > 0
    if under:  # no pose as built (an uncontrolled freedom, or redundant constraints that a perturbed
        # rigid closure cannot meet): the lower-mobility legs keep their geometry
        full = [j for j, leg in enumerate(mech.legs) if leg.joints in ("SPS", "UPS")]
        e = np.where(np.isin(src.leg, full), e, 0.0)
    legs = _perturbed_legs(mech, src, e)
    p0, R0 = mech._pose(Xg)
    t = np.random.default_rng(4).uniform(-1, 1, (len(Xg), 6)) * np.r_[1e-3, 1e-3, 1e-3, 1e-2, 1e-2, 1e-2]
    p, R = _compose(p0, R0, t)  # off the parametrisation: unreachable by lower-mobility legs
    if under:
        p2, R2 = p0, R0  # the nominal poses: the unperturbed lower-mobility legs reach them
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ctx = AsBuilt(mech, legs, np.zeros(0), {}).pose_context(Xg)  # the actual poses as built: reachable
        p2, R2 = ctx.p, ctx.R
    p = np.concatenate([p, p2])
    R = np.concatenate([R, R2])
    ref_mech = copy.copy(mech)
    ref_mech.legs = tuple(legs)
    with np.errstate(all="ignore"):
        states = [leg.solve(p, R) for leg in legs]
    reach = np.logical_and.reduce([st.reachable for st in states])
    rank = mech.structural_constraint_rank(engine="numpy")
    ref_mech._constraint_rank = rank
    ref = Mechanism.singularity_margin_of_states(ref_mech, states, p, reach)
    got = engine.singularity_margin_at(legs, p, R, mech.n_actuators, rank, mech.length_scale)
    assert got is not None
    _same_nan(ref, got)
    ok = np.isfinite(ref)
    assert ok.sum() >= 40
    np.testing.assert_allclose(got[ok], ref[ok], rtol=0, atol=ATOL)
    base = np.tile(mech.singularity_margin(Xg, engine="numpy"), 2)
    assert np.nanmax(np.abs(got - base)) > 1e-6  # the perturbation changed the margins: not the nominal ones


def test_transmission_indices_agree(mech_poses):
    mech, X, n_bad = mech_poses
    ref = transmission_indices(mech, X)
    inp, out, lti = ei.transmission(mech, X)
    for a, b in ((ref.input, inp), (ref.output, out), (ref.lti, lti)):
        _same_nan(a, b)
        ok = np.isfinite(a)
        np.testing.assert_allclose(b[ok], a[ok], rtol=0, atol=ATOL)
    np.testing.assert_allclose(local_transmission_index(mech, X), lti, rtol=0, atol=0, equal_nan=True)
    np.testing.assert_allclose(output_transmission_index(mech, X), out, rtol=0, atol=0, equal_nan=True)
    np.testing.assert_allclose(local_transmission_index(mech, X, engine="numpy"), ref.lti, rtol=0, atol=0,
                               equal_nan=True)


def test_condition_number_agrees(mech_poses):
    mech, X, n_bad = mech_poses
    ref = local_condition_number(mech, X, engine="numpy")
    got = local_condition_number(mech, X)
    _same_nan(ref, got)
    np.testing.assert_array_equal(np.isinf(ref), np.isinf(got))
    ok = np.isfinite(ref)
    assert np.all(ref[ok] >= 1 - 1e-12)
    np.testing.assert_allclose(got[ok], ref[ok], rtol=RTOL_KAPPA, atol=0)
    # another length scale for the angular columns
    L = 0.37 * mech.length_scale
    np.testing.assert_allclose(local_condition_number(mech, X, length=L),
                               local_condition_number(mech, X, length=L, engine="numpy"), rtol=RTOL_KAPPA,
                               equal_nan=True)


def test_constraint_rank_matches_mobility(mech_poses):
    mech, _, _ = mech_poses
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        expected = mech.mobility().constraint_rank
    assert ei.constraint_rank(mech) == expected
    assert mech.structural_constraint_rank(engine="numpy") == expected
    assert mech.constraint_rank == expected


def test_single_pose_and_threaded_batches(mech_poses, monkeypatch):
    mech, X, n_bad = mech_poses
    ref = mech.singularity_margin(X, engine="numpy")
    assert np.ndim(mech.singularity_margin(X[0])) == 0
    assert abs(float(mech.singularity_margin(X[0])) - ref[0]) <= ATOL
    monkeypatch.setattr(ei, "PARALLEL_MIN", 1)  # the threaded kernels on the same poses
    got = mech.singularity_margin(X)
    np.testing.assert_allclose(got, ref, rtol=0, atol=ATOL, equal_nan=True)
    np.testing.assert_allclose(ei.transmission(mech, X)[2], transmission_indices(mech, X).lti, rtol=0, atol=ATOL,
                               equal_nan=True)
    np.testing.assert_allclose(local_condition_number(mech, X), local_condition_number(mech, X, engine="numpy"),
                               rtol=RTOL_KAPPA, equal_nan=True)


def test_margin_at_a_structural_singularity():
    """The pentagonal 5-PUS/UPU scheme is singular at its home pose (the paper's reason for
    the rectangular platform): both paths give (numerically) zero there, and agree nearby."""
    mech = _mech("5pus_upu", {"platform": "pentagonal"})
    ref = float(mech.singularity_margin(mech.home, engine="numpy"))
    got = float(mech.singularity_margin(mech.home))
    assert ref < 1e-8 and got < 1e-8
    assert abs(got - ref) <= ATOL
    eps = np.logspace(-9, -3, 7)
    X = mech.home + eps[:, None] * np.array([1.0, -0.5, 0.3, 1.0, -1.0])
    np.testing.assert_allclose(mech.singularity_margin(X), mech.singularity_margin(X, engine="numpy"), rtol=0,
                               atol=ATOL)


def test_pressure_angles_agree():
    for kw in ({}, {"coupled": False}):
        mech = _mech("2rpu_2sps", kw)
        X, _ = _poses(mech, 200, seed=3)
        for definition in ("paper", "pressure"):
            a = pressure_angle_indices(mech, X, definition, engine="numpy")
            b = pressure_angle_indices(mech, X, definition)
            for f in ("lambda1", "lambda2", "alpha", "beta"):
                np.testing.assert_allclose(getattr(b, f), getattr(a, f), rtol=0, atol=ATOL, equal_nan=True)


# ---------------------------------------------------------------------------------------------
# Measures and summaries reach the compiled path
# ---------------------------------------------------------------------------------------------
def test_measures_compiled_equal_numpy():
    mech = _mech("5pus_upu", {})
    kw = dict(n=2048, seed=0, ranges={"x": (-0.1, 0.1), "y": (-0.1, 0.1), "z": (-0.3, 0.1)})
    for name, extra in (("singularity_margin_min", {"quantile": 0.05}), ("min_lti", {"quantile": 0.1}),
                        ("mean_lti", {}), ("gci", {}), ("good_transmission_volume", {"threshold": 0.46})):
        f = objectives.get(name)
        a = f(mech, engine="numpy", **extra, **kw)
        b = f(mech, **extra, **kw)
        assert a > 0
        assert abs(a - b) <= ATOL * max(1.0, abs(a)), name
    X, _ = _poses(mech, 200, seed=5)
    s1 = singularity_margin_stats(mech, X, engine="numpy")
    s2 = singularity_margin_stats(mech, X)
    assert (s1.n, s1.n_unreachable, s1.argmin) == (s2.n, s2.n_unreachable, s2.argmin)
    assert abs(s1.mean - s2.mean) <= ATOL
    g1 = global_conditioning_index(mech, X, engine="numpy")
    g2 = global_conditioning_index(mech, X)
    assert g1.n == g2.n and abs(g1.value - g2.value) <= ATOL


def test_engine_argument_is_checked():
    mech = _mech("3rps", {})
    with pytest.raises(ValueError, match="engine must be one of"):
        mech.singularity_margin(mech.home, engine="fast")
    with pytest.raises(ValueError, match="engine"):
        local_transmission_index(mech, mech.home, engine="cuda")
    with pytest.raises(ValueError, match="engine"):
        local_condition_number(mech, mech.home, engine=None)
    five = _mech("5pus_upu", {})
    with pytest.raises(ValueError, match="engine"):
        objectives.get("singularity_margin_min")(five, n=256, ranges={"x": (-0.1, 0.1), "y": (-0.1, 0.1),
                                                                        "z": (-0.3, 0.1)}, engine="gpu")


def test_twist_space_condition_number_falls_back():
    mech = _mech("3rps", {})
    X, _ = _poses(mech, 50, seed=2)
    ei._WARNED.clear()
    with pytest.warns(UserWarning, match="space='twist' has no compiled form"):
        a = local_condition_number(mech, X, space="twist")
    b = local_condition_number(mech, X, space="twist", engine="numpy")
    np.testing.assert_array_equal(a, b)


# ---------------------------------------------------------------------------------------------
# A leg the kernels do not know runs on NumPy, said once
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _TwistedUPS(UPS):
    """A UPS leg whose actuation wrench is tilted: a construct the kernels do not cover."""

    joints: ClassVar[str] = "UPS"

    def actuation_wrench(self, st, P):
        w, s = super().actuation_wrench(st, P)
        return w * np.array([1.0, 1.0, 0.9, 1.0, 1.0, 1.0]), s


def test_uncovered_leg_falls_back_with_a_reason(caplog):
    import dataclasses

    base = _mech("gough_stewart_6ups", {})
    legs = list(base.legs)
    legs[0] = _TwistedUPS(**{f.name: getattr(legs[0], f.name) for f in dataclasses.fields(legs[0])})
    mech = object.__new__(type(base))
    mech.__dict__.update(base.__dict__)
    mech.legs = tuple(legs)
    mech._engine_indices_plan = None
    ok, why = ei.coverage(mech)
    assert not ok and "overrides UPS.actuation_wrench" in why and legs[0].name in why
    X, _ = _poses(base, 40, seed=4)
    ei._WARNED.clear()
    with warnings.catch_warnings(record=True) as rec, caplog.at_level(logging.INFO, logger="parasynth.engine"):
        warnings.simplefilter("always")
        a = mech.singularity_margin(X)
        mech.singularity_margin(X)
    msgs = [str(w.message) for w in rec if "singularity_margin" in str(w.message)]
    assert len(msgs) == 1 and "runs on NumPy" in msgs[0] and "actuation_wrench" in msgs[0]
    assert issubclass([w for w in rec if "singularity_margin" in str(w.message)][0].category, UserWarning)
    assert sum("singularity_margin" in r.getMessage() for r in caplog.records) == 1
    np.testing.assert_array_equal(a, mech.singularity_margin(X, engine="numpy"))
    # and the tilted wrench does change the answer, so the fallback is not a no-op
    assert np.nanmax(np.abs(a - base.singularity_margin(X, engine="numpy"))) > 1e-6


# ---------------------------------------------------------------------------------------------
# The one-sided Jacobi SVD
# ---------------------------------------------------------------------------------------------
def _known(rng, m, n, s):
    U, _ = np.linalg.qr(rng.standard_normal((m, m)))
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    S = np.zeros((m, n))
    S[np.arange(len(s)), np.arange(len(s))] = s
    return U @ S @ V.T


@pytest.mark.parametrize("m,n", [(6, 6), (5, 6), (6, 5), (7, 6), (6, 1), (3, 2), (4, 6), (6, 7), (3, 8)])
def test_jacobi_singular_values_of_known_matrices(m, n):
    rng = np.random.default_rng(m * 10 + n)
    k = min(m, n)
    for trial in range(30):
        s = np.sort(10.0 ** rng.uniform(-12 if trial % 2 else -3, 0, size=k))[::-1]
        M = _known(rng, m, n, s)
        Mt = np.ascontiguousarray(M.T)
        Vt = np.empty((n, n))
        sv = np.empty(n)
        sweeps = ei._jacobi_sv(Mt, m, n, Vt, True, sv)
        assert sweeps < 30
        got = np.sort(sv)[::-1][:k]
        # absolute accuracy eps * ||M|| for every singular value
        np.testing.assert_allclose(got, s, rtol=0, atol=1e-14)
        # right singular vectors: M V = (the rotated columns), V orthogonal
        np.testing.assert_allclose(M @ Vt.T, Mt.T, atol=1e-14)
        np.testing.assert_allclose(Vt @ Vt.T, np.eye(n), atol=1e-14)
        if m == 6 and n <= 6:  # the six-row variant, up to six columns
            Mt6 = np.ascontiguousarray(M.T)
            sv6 = np.empty(n)
            ei._jacobi_sv6(Mt6, n, sv6)
            np.testing.assert_allclose(np.sort(sv6)[::-1][:k], s, rtol=0, atol=1e-14)


def test_jacobi_small_singular_value_relative_accuracy():
    """Columns of very different scale (a graded matrix): the smallest singular value keeps
    its relative accuracy, which eigenvalues of M^T M lose (they square the conditioning)."""
    rng = np.random.default_rng(7)
    s = np.array([1.0, 0.5, 0.1, 1e-3, 1e-6, 1e-10])
    M = _known(rng, 6, 6, s)
    Mt = np.ascontiguousarray(M.T)
    sv = np.empty(6)
    ei._jacobi_sv6(Mt, 6, sv)
    smin = np.sort(sv)[0]
    assert abs(smin - 1e-10) <= 1e-15  # absolute eps-level error, i.e. ~1e-5 relative here
    gram = np.sqrt(np.abs(np.linalg.eigvalsh(M.T @ M)))[0]
    assert abs(gram - 1e-10) > abs(smin - 1e-10)  # the Gram route is worse


# ---------------------------------------------------------------------------------------------
# Random mechanisms from every leg type (generic over legs, nothing per model)
# ---------------------------------------------------------------------------------------------
from parasynth.model.legs import PRS, PUS, RPS, RPU, RUS, SPS, UPU  # noqa: E402
from parasynth.model.mechanism import Mechanism  # noqa: E402
from parasynth.model.spatial import euler_rate_map, euler_to_matrix  # noqa: E402


class _Free6(Mechanism):
    """x, y, z and z-y-x Euler angles; legs given."""

    name = "random_legs"
    task_coordinates = ("x", "y", "z", "a", "b", "c")
    angular_coordinates = frozenset({"a", "b", "c"})

    def _pose(self, X):
        return X[:, :3].copy(), euler_to_matrix("zyx", X[:, 3:])

    def _twist_map(self, X):
        T = np.zeros((X.shape[0], 6, 6))
        T[:, :3, :3] = np.eye(3)
        T[:, 3:, 3:] = euler_rate_map("zyx", X[:, 3:])
        return T


def _unit(v):
    return v / np.linalg.norm(v)


def _random_leg(rng, k, kind, p0, R0):
    """A leg of type ``kind`` that reaches the pose (p0, R0), its planar conditions met there."""
    plat = rng.uniform(-0.15, 0.15, 3)
    A = p0 + R0 @ plat
    base = A + np.array([0, 0, -1.0]) * rng.uniform(0.3, 0.8) + rng.uniform(-0.4, 0.4, 3)
    d = A - base
    name = f"L{k}"
    if kind is SPS:
        return SPS(name, base, plat)
    if kind is UPS:
        return UPS(name, base, plat, u_axis=_unit(rng.standard_normal(3)))
    if kind is UPU:
        return UPU(name, base, plat, u_axis=_unit(rng.standard_normal(3)),
                   u_platform_axis=_unit(rng.standard_normal(3)), passive=bool(rng.random() < 0.5))
    if kind is RPS:
        r = _unit(np.cross(d, rng.standard_normal(3)))
        return RPS(name, base, plat, r_axis=r, passive=bool(rng.random() < 0.3))
    if kind is RPU:
        r = _unit(np.cross(d, rng.standard_normal(3)))
        u = _unit(np.cross(r, rng.standard_normal(3)))
        return RPU(name, base, plat, r_axis=r, u_platform_axis=R0.T @ u)
    if kind is RUS:  # a crank through the pose's sphere at a random angle t0
        r = _unit(rng.standard_normal(3))
        c0 = _unit(np.cross(r, rng.standard_normal(3)))
        h, t0 = rng.uniform(0.05, 0.2), rng.uniform(-np.pi, np.pi)
        C = base + h * (np.cos(t0) * c0 + np.sin(t0) * np.cross(r, c0))
        return RUS(name, base, plat, r_axis=r, crank_direction=c0, crank_length=h,
                   link_length=float(np.linalg.norm(A - C)), branch=int(rng.choice([-1, 1])))
    e = _unit(rng.standard_normal(3) + np.array([0, 0, 2.0]))
    perp = np.linalg.norm(d - (d @ e) * e)
    L = perp / rng.uniform(0.3, 0.95)
    branch = int(rng.choice([-1, 1]))
    if kind is PUS:
        return PUS(name, base, plat, slider_axis=e, link_length=L, branch=branch,
                   u_axis=_unit(np.cross(e, rng.standard_normal(3))))
    r = _unit(np.cross(e, d))
    return PRS(name, base, plat, slider_axis=e, r_axis=r, link_length=L, branch=branch)


def _random_mechanism(seed):
    rng = np.random.default_rng(seed)
    X0 = np.r_[rng.uniform(-0.1, 0.1, 3), rng.uniform(-0.4, 0.4, 3)]
    p0, R0 = X0[:3], euler_to_matrix("zyx", X0[3:])
    kinds = [SPS, UPS, PUS, RPS, RPU, UPU, PRS, RUS]
    n = int(rng.integers(3, 8))
    legs = [_random_leg(rng, k, kinds[int(rng.integers(len(kinds)))], p0, R0) for k in range(n)]
    if not any(leg.is_actuated for leg in legs):
        legs[0] = _random_leg(rng, 0, SPS, p0, R0)
    return _Free6(None, legs, X0, float(rng.uniform(0.1, 0.5)))


def test_random_mechanisms_of_every_leg_type():
    seen = set()
    for seed in range(120):
        mech = _random_mechanism(seed)
        seen.update(type(leg).__name__ for leg in mech.legs)
        # the home pose (every planar condition met) and, for legs without one, poses nearby
        rng = np.random.default_rng(1000 + seed)
        X = np.vstack([mech.home, mech.home + rng.uniform(-0.02, 0.02, (20, 6))])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert ei.constraint_rank(mech) == mech.mobility().constraint_rank, seed
        a = mech.singularity_margin(X, engine="numpy")
        b = mech.singularity_margin(X)
        assert np.isfinite(a[0]), seed
        np.testing.assert_allclose(b, a, rtol=0, atol=ATOL, equal_nan=True, err_msg=f"seed {seed}")
        ref = transmission_indices(mech, X)
        inp, out, lti = ei.transmission(mech, X)
        np.testing.assert_allclose(out, ref.output, rtol=0, atol=ATOL, equal_nan=True, err_msg=f"seed {seed}")
        np.testing.assert_allclose(inp, ref.input, rtol=0, atol=ATOL, equal_nan=True, err_msg=f"seed {seed}")
        np.testing.assert_allclose(lti, ref.lti, rtol=0, atol=ATOL, equal_nan=True, err_msg=f"seed {seed}")
        ka = local_condition_number(mech, X, engine="numpy")
        kb = local_condition_number(mech, X)
        np.testing.assert_array_equal(np.isinf(ka), np.isinf(kb))
        np.testing.assert_allclose(kb, ka, rtol=RTOL_KAPPA, equal_nan=True, err_msg=f"seed {seed}")
    assert seen == {"SPS", "UPS", "PUS", "RPS", "RPU", "UPU", "PRS", "RUS"}


@pytest.mark.parametrize("big", [1e308, 1e200])
def test_a_pose_at_infinity_does_not_spoil_the_batch(big):
    """A huge coordinate gives NaN for that pose only, without floating-point warnings; the
    other poses keep the values they have alone."""
    for name in parasynth.list_mechanisms():
        mech = _mech(name, {})
        X = np.array([mech.home, mech.home])
        X[1, 0] = big
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            s = mech.singularity_margin(X)
            lti = local_transmission_index(mech, X)
            k = local_condition_number(mech, X)
        assert np.isnan(s[1]) and np.isnan(lti[1]) and np.isnan(k[1]), name
        assert abs(s[0] - float(mech.singularity_margin(mech.home, engine="numpy"))) <= ATOL, name
        assert abs(lti[0] - float(local_transmission_index(mech, mech.home, engine="numpy"))) <= ATOL, name


def test_constraint_rank_at_home_takes_the_pose_of_the_build(monkeypatch):
    """The compiled constraint rank at ``home`` takes the platform pose the NumPy model
    computed at the build (the pose the reference takes; no pose kernel for one pose), and a
    ``home`` moved afterwards is evaluated anew."""
    mech = parasynth.load_mechanism("5pus_upu.yaml")
    p, R = mech.home_platform_pose()
    p0, R0 = mech.pose(mech.home[None, :])
    assert np.array_equal(p, p0) and np.array_equal(R, R0)
    expected = mech.structural_constraint_rank(engine="numpy")

    def no_pose_kernel(*a, **k):
        raise AssertionError("the home pose was computed again")

    with monkeypatch.context() as mp:
        mp.setattr(ei, "_poses", no_pose_kernel)
        assert ei.constraint_rank(mech) == expected
    moved = mech.home + np.r_[np.full(3, 0.0), 0.01 * np.ones(mech.n_task - 3)][: mech.n_task]
    mech.home = moved
    assert mech.home_platform_pose() is None
    assert ei.constraint_rank(mech) == Mechanism.structural_constraint_rank(mech, engine="numpy")
