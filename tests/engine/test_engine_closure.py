"""The compiled closure of legs as built (:mod:`parasynth.engine.closure`) against NumPy.

The reference is :func:`parasynth.measures.accuracy.closure_residuals` (the closure residuals of
perturbed legs), ``accuracy._pose_jacobian`` (central differences on it), the legs' own
``solve`` (reachability) and the NumPy chord Newton of :mod:`parasynth.measures.robustness`, on random
poses of every shipped mechanism, with several draws of leg scatter evaluated in one batch
(each row with its own draw's legs).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import parasynth
from parasynth import engine
from parasynth.measures.accuracy import (_check_tolerances, _compose, _leg_changes, _leg_changes_batch, _perturbed_legs,
                                         _pose_jacobian, _sample_errors, closure_residuals, error_sources)
from parasynth.engine import indices as ei
from parasynth.model.legs import solve_geometry
from parasynth.measures.robustness import _chord_matrix, _Nominal, _newton

pytestmark = pytest.mark.skipif(not ei.HAVE_NUMBA, reason="numba is not importable: no compiled closure")

CLOSED = {"SPS", "UPS", "PUS", "RPS", "RPU", "UPU", "PRS"}
TOL = {"anchor_tolerance": 2e-4, "axis_tolerance": 2e-3, "link_tolerance": 1e-4, "actuator_tolerance": 1e-4}


def _mech(name, kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return parasynth.load_mechanism(name, **kw)


# every shipped mechanism whose legs all have a closure residual (a RUS leg has none: the
# 6-RUS hexapod is left to the NumPy closure, test_a_leg_type_without_a_compiled_closure_gives_no_plan)
CONFIGS = [(name, {}) for name in parasynth.list_mechanisms()
           if all(leg.joints in CLOSED for leg in _mech(name, {}).legs)] + [("5pus_upu", {"platform": "pentagonal"})]
IDS = [n + ("-" + "-".join(f"{k}={v}" for k, v in kw.items()) if kw else "") for n, kw in CONFIGS]
def _reachable_poses(mech, n=200, seed=0):
    rng = np.random.default_rng(seed)
    rg = mech.default_ranges()
    lo = np.array([rg[c][0] if c in rg else h - (0.3 if c in mech.angular_coordinates else 0.06)
                   for c, h in zip(mech.task_coordinates, mech.home)])
    hi = np.array([rg[c][1] if c in rg else h + (0.3 if c in mech.angular_coordinates else 0.06)
                   for c, h in zip(mech.task_coordinates, mech.home)])
    X = lo + (hi - lo) * rng.random((20 * n, mech.n_task))
    return X[mech.inverse_kinematics(X).reachable][:n]


def _draws(mech, k, seed=3):
    """``k`` draws of leg scatter; on a mechanism with redundant constraints (no rigid closure
    as built otherwise) only its SPS and UPS legs scatter."""
    src = error_sources(mech)
    E = _sample_errors(src, _check_tolerances(TOL), k, np.random.default_rng(seed))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        redundant = mech.mobility().redundant_constraints
    if redundant:
        full = [j for j, leg in enumerate(mech.legs) if leg.joints in ("SPS", "UPS")]
        E = np.where(np.isin(src.leg, full) | (np.array(src.leg) < 0), E, 0.0)
    return src, E, [_perturbed_legs(mech, src, e) for e in E]


@pytest.fixture(params=CONFIGS, ids=IDS)
def case(request):
    mech = _mech(*request.param)
    assert all(leg.joints in CLOSED for leg in mech.legs), f"{mech.name}: a leg type without a compiled closure"
    X = _reachable_poses(mech)
    assert len(X) >= 50
    return mech, X


def test_a_leg_type_without_a_compiled_closure_gives_no_plan():
    """RUS legs have no closure residual (``accuracy._leg_residual`` refuses them): no plan, so
    that the caller's NumPy closure answers (and says why)."""
    from parasynth.model.legs import RUS

    rus = RUS(name="a", base=np.zeros(3), platform=np.full(3, 0.1))
    assert engine.closure_plan([[rus]]) is None
    ups = _mech("gough_stewart_6ups", {}).legs
    assert engine.closure_plan([ups]) is not None


def test_residuals_jacobian_and_reachability_agree(case):
    mech, X = case
    src, E, legs_k = _draws(mech, 3)
    p0, R0 = mech._pose(X)
    t = np.random.default_rng(5).uniform(-1, 1, (len(X), 6)) * np.r_[1e-3, 1e-3, 1e-3, 1e-2, 1e-2, 1e-2]
    p, R = _compose(p0, R0, t)  # off the parametrisation: residuals of every kind non-zero
    draw = np.random.default_rng(6).integers(0, 3, len(X))
    cp = engine.closure_plan(legs_k)
    h, _, reach = engine.closure_prep(cp, p, R, mech.length_scale, draw, jacobian=False)
    for d, legs in enumerate(legs_k):
        rows = draw == d
        with np.errstate(all="ignore"):
            ref = closure_residuals(mech, p[rows], R[rows], legs=legs)
            ref_reach = np.logical_and.reduce([solve_geometry(leg, p[rows], R[rows]).reachable for leg in legs])
        np.testing.assert_array_equal(np.isnan(h[rows]), np.isnan(ref))
        np.testing.assert_allclose(h[rows], ref, rtol=1e-12, atol=1e-14, equal_nan=True)
        np.testing.assert_array_equal(reach[rows], ref_reach)
    # the nominal legs at the nominal poses: reachable, and the Jacobian of the NumPy differences
    h0, Gt, reach0 = engine.closure_prep(engine.closure_plan([mech.legs]), p0, R0, mech.length_scale)
    assert reach0.all()
    np.testing.assert_allclose(h0, closure_residuals(mech, p0, R0), rtol=1e-12, atol=1e-14)
    ref_G = _pose_jacobian(mech, p0, R0)
    np.testing.assert_allclose(Gt, ref_G, rtol=1e-6, atol=1e-6 * np.abs(ref_G).max())


def test_chord_newton_agrees_with_numpy(case):
    """The actual poses of three draws of scatter, solved row by row in the kernel, equal the
    NumPy chord Newton's (convergence flags included), and close the perturbed closure."""
    mech, X = case
    if _under_actuated(mech, X):
        return
    src, E, legs_k = _draws(mech, 3)
    nom = _Nominal(mech)
    q = nom.prep(X, np.arange(len(X)))
    act = [j for j, kd in enumerate(src.kind) if kd == "actuator"]
    dq = np.zeros((3, q["h0"].shape[1]))
    dq[:, nom.act_rows] = E[:, act]
    scale = np.where(nom.rows_len, mech.length_scale, 1.0)
    src_rows = np.tile(np.arange(len(X)), 3)
    draw = np.repeat(np.arange(3), len(X))
    conv, p, R = engine.closure_solve(engine.closure_plan(legs_k), q["p"], q["R"], q["Gi"], q["h0"], q["ok"], dq,
                                      scale, src_rows, draw)
    assert conv.mean() > 0.5
    for d, legs in enumerate(legs_k):
        rows = draw == d
        c_ref, p_ref, R_ref = _newton(mech, legs, q["p"], q["R"], q["Gi"], q["h0"] + dq[d], q["ok"], scale)
        with np.errstate(all="ignore"):
            reach = np.logical_and.reduce([leg.solve(p_ref, R_ref).reachable for leg in legs])
        np.testing.assert_array_equal(conv[rows], c_ref & reach)
        ok = conv[rows]
        # the same closure solved to 1e-12 of its residuals' scale: the kernel stops each row once
        # it converged, NumPy iterates every row until all did (a difference within the tolerance
        # times the closure's conditioning)
        np.testing.assert_allclose(p[rows][ok], p_ref[ok], rtol=0, atol=1e-9 * mech.length_scale)
        np.testing.assert_allclose(R[rows][ok], R_ref[ok], rtol=0, atol=1e-9)
        res = closure_residuals(mech, p[rows][ok], R[rows][ok], legs=legs) - (q["h0"] + dq[d])[ok]
        assert np.max(np.abs(res) / scale) <= 1.01e-12  # the tolerance, up to the rounding of NumPy's residuals


def _under_actuated(mech, X) -> bool:
    """Whether fewer closure equations than six fix the pose: then there is no pose as built
    (the chord matrix is refused, and ``RobustMeasure.check`` refuses per-leg scatter)."""
    p, R = mech._pose(X[:2])
    _, Gt, _ = engine.closure_prep(engine.closure_plan([mech.legs]), p, R, mech.length_scale)
    if Gt.shape[1] >= 6:
        return False
    with pytest.raises(ValueError, match="under-actuated"):
        _chord_matrix(Gt, mech)
    return True


def test_chord_matrix_of_the_compiled_jacobian_inverts_it(case):
    mech, X = case
    if _under_actuated(mech, X):
        return
    p, R = mech._pose(X)
    _, Gt, _ = engine.closure_prep(engine.closure_plan([mech.legs]), p, R, mech.length_scale)
    Gi = _chord_matrix(Gt, mech)
    fine = np.all(np.isfinite(Gi), axis=(1, 2))
    if Gt.shape[1] == 6:
        assert fine.mean() > 0.5
        np.testing.assert_allclose(np.einsum("nij,njk->nik", Gi[fine], Gt[fine]), np.broadcast_to(np.eye(6), (fine.sum(), 6, 6)),
                                   atol=1e-6)


@pytest.mark.parametrize("name", ["5pus_upu", "3rps", "3prs", "2rpu_2sps"])
def test_batched_leg_draws_equal_draw_by_draw(name):
    """``accuracy._leg_changes_batch`` (every draw of a leg at once) gives, row by row, what
    ``_leg_changes`` gives for each draw's errors (zero errors included; the PRS legs of the
    3-PRS carry their revolute axis with the slider's tilt)."""
    mech = _mech(name, {})
    src = error_sources(mech)
    E = _sample_errors(src, _check_tolerances(TOL), 6, np.random.default_rng(1))
    E[2] = 0.0  # a draw without scatter
    for li, leg in enumerate(mech.legs):
        cols = [j for j, (kd, l_) in enumerate(zip(src.kind, src.leg)) if kd != "actuator" and l_ == li]
        batch = _leg_changes_batch([leg] * len(E), [(src.index[j], E[:, j]) for j in cols])
        for s, e in enumerate(E):
            one = _leg_changes(leg, [(src.index[j], e[j]) for j in cols if e[j] != 0.0])
            for f, v in one.items():
                np.testing.assert_allclose(batch[f][s], v, rtol=0, atol=1e-15)
            for f in set(batch) - set(one):  # a draw whose errors on this field are all zero
                np.testing.assert_allclose(batch[f][s], getattr(leg, f), rtol=0, atol=1e-15)
