"""The compiled inverse kinematics of chain limbs (engine/chains.py) against the NumPy reference
(ChainLeg.solve) and against closed forms: the chain UP*S against the hand-written UPS, the
constraint couple of the RPUR against x x (R y); a mechanism of chain limbs evaluated compiled
without a fallback; the kernel compiled only where a chain limb is evaluated."""

import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

import parasynth
from _support import engine_fallbacks
from parasynth import engine
from parasynth.model.chains import IK_TOL, PRRS, PRUR, RPUR, RRPS, RRUR, RUU, SPU, URPU, chain_class, closed_form_solve
from parasynth.model.legs import UPS, LegState
from parasynth.model.mechanism import EngineFallbackWarning
from parasynth.model.spatial import rot_axis, rot_x, rot_y

pytestmark = pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba not available")

BASE = [0.3 * np.cos(0.4), 0.3 * np.sin(0.4), 0.0]
PLAT = [0.15 * np.cos(0.5), 0.15 * np.sin(0.5), 0.0]


def _chains():
    from parasynth.engine import chains

    return chains


def _general_poses(n, seed):
    """Positions around the limb's home and rotations about random axes."""
    rng = np.random.default_rng(seed)
    p = np.array([0.0, 0.0, 0.4]) + rng.uniform(-0.12, 0.12, (n, 3))
    axes = rng.normal(size=(n, 3))
    R = rot_axis(axes / np.linalg.norm(axes, axis=1, keepdims=True), rng.uniform(-0.6, 0.6, n))
    return p, R


def _3t2r_poses(n, seed):
    """Half the poses of the 3T2R motion (R = Rx(a) Ry(b), reachable by RPUR and PRUR), half
    turned about the moving z as well (forbidden by their constraint couple)."""
    rng = np.random.default_rng(seed)
    p = np.array([0.0, 0.0, 0.4]) + rng.uniform(-0.08, 0.08, (n, 3))
    R = rot_x(rng.uniform(-0.4, 0.4, n)) @ rot_y(rng.uniform(-0.4, 0.4, n))
    R[n // 2:] = R[n // 2:] @ rot_axis(np.array([0.0, 0.0, 1.0]), rng.uniform(0.05, 0.3, n - n // 2))
    return p, R


def _span(W):
    """The orthogonal projector onto the span of the wrenches W (k, 6)."""
    if W.shape[0] == 0:
        return np.zeros((6, 6))
    Q, _ = np.linalg.qr(W.T)
    return Q @ Q.T


def _translations(n, seed):
    """Positions around the limb's home, the platform level (the motion of a translational RUU)."""
    p, _ = _general_poses(n, seed)
    return p, np.broadcast_to(np.eye(3), (n, 3, 3)).copy()


@pytest.mark.parametrize("cls, poses", [(RPUR, _3t2r_poses), (PRUR, _3t2r_poses), (SPU, _general_poses),
                                        (RRPS, _general_poses), (RRUR, _3t2r_poses), (URPU, _general_poses),
                                        (PRRS, _general_poses), (RUU, _translations)],
                         ids=["RPUR", "PRUR", "SPU", "RRPS", "RRUR", "URPU", "PRRS", "RUU"])
def test_compiled_chain_solve_agrees_with_numpy(cls, poses):
    leg = cls("L", base=BASE, platform=PLAT)
    p, R = poses(400, 3)
    ref = leg.solve(p, R)
    got = _chains().solve(leg, p, R)
    # reachability: the same, but for a residual within rounding of the threshold
    res = ref.extra["residual"]
    edge = np.abs(np.log10(np.maximum(res, 1e-300) / (1e3 * IK_TOL))) < 0.3
    assert np.array_equal(ref.reachable[~edge], got.reachable[~edge])
    ok = ref.reachable & got.reachable
    assert ok.sum() >= 100
    if poses is _3t2r_poses:  # the turned half is unreachable on both paths
        assert not ref.reachable[200:].any() and not got.reachable[200:].any()
        assert ref.reachable[:200].mean() > 0.5  # the solve from home reaches most of the motion
    np.testing.assert_allclose(got.actuator[ok], ref.actuator[ok], rtol=0, atol=1e-9)
    assert np.all(np.isnan(got.actuator[~got.reachable]))
    for f in ("base_point", "platform_point", "direction", "length"):
        np.testing.assert_allclose(getattr(got, f)[ok], getattr(ref, f)[ok], rtol=0, atol=1e-9, err_msg=f)
    assert set(got.angles) == set(ref.angles)
    for k in ref.angles:
        np.testing.assert_allclose(got.angles[k][ok], ref.angles[k][ok], rtol=0, atol=1e-9, err_msg=k)
    if leg.has_cones:  # the cone angles from the kernel's frames: the bodies' orientations of the NumPy forward
        frames = _chains().solve_arrays(leg, p, R, frames=True)["frames"]
        ref_frames = leg._forward(got.extra["q"])[4]
        for m, F in enumerate(ref_frames):
            np.testing.assert_allclose(frames[ok, m], F[ok], rtol=0, atol=1e-12, err_msg=f"frame {m}")
    # the constraint wrenches (NumPy's null space of the joint twists at either solution) span the same space
    Pc = np.asarray(p)[ok]
    Wr = leg.constraint_wrenches(_take(ref, ok), Pc)
    Wg = leg.constraint_wrenches(_take(got, ok), Pc)
    assert Wr.shape == Wg.shape
    for a, b in zip(Wr, Wg):
        np.testing.assert_allclose(_span(b), _span(a), rtol=0, atol=1e-8)


def _take(st, sel):
    """The leg state of the poses ``sel``."""
    out = LegState(st.actuator[sel], st.reachable[sel], st.base_point[sel], st.platform_point[sel],
                   st.direction[sel], st.length[sel], {k: v[sel] for k, v in st.angles.items()})
    out.extra.update({"q": st.extra["q"][sel], "residual": st.extra["residual"][sel],
                      "axes": [a[sel] for a in st.extra["axes"]],
                      "points": [None if c is None else c[sel] for c in st.extra["points"]]})
    return out


def test_chain_up_s_matches_the_closed_form_ups():
    """The chain "UP*S" (universal at the base anchor, actuated prismatic along the limb,
    spherical at the platform anchor) is the UPS: its compiled actuator value is the closed
    form's leg length |A - B|, every pose reachable."""
    UPS_chain = chain_class("UP*S")
    chain = UPS_chain("L", base=BASE, platform=PLAT)
    ups = UPS("L", base=BASE, platform=PLAT)
    p, R = _general_poses(500, 11)
    got = _chains().solve(chain, p, R)
    ref = ups.solve(p, R)
    assert got.reachable.all() and ref.reachable.all()
    length = np.linalg.norm(p + np.einsum("nij,j->ni", R, PLAT) - np.array(BASE), axis=1)  # by hand
    np.testing.assert_allclose(ref.actuator, length, rtol=0, atol=1e-12)
    # the numerical solve stops once its residual is below IK_TOL (1e-9 of the limb's length
    # and rad): against a closed form it agrees to a few times that
    tol = 10 * IK_TOL
    np.testing.assert_allclose(got.actuator, ref.actuator, rtol=0, atol=tol)
    np.testing.assert_allclose(got.platform_point, ref.platform_point, rtol=0, atol=tol)
    np.testing.assert_allclose(got.base_point, np.broadcast_to(BASE, got.base_point.shape), rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.direction, ref.direction, rtol=0, atol=tol)


def test_rpur_constraint_couple_is_x_cross_moving_y():
    """The RPUR's one constraint wrench at the compiled solution is a pure couple along
    x x (R y) (its base-side axes along x, platform-side ones along the platform's y)."""
    leg = RPUR("L", base=BASE, platform=PLAT)
    p, R = _3t2r_poses(200, 5)
    p, R = p[:100], R[:100]
    st = _chains().solve(leg, p, R)
    ok = st.reachable
    assert ok.sum() >= 60
    p, R, st = p[ok], R[ok], _take(st, ok)
    W = leg.constraint_wrenches(st, p)
    assert W.shape == (len(p), 1, 6)
    c = np.cross(np.array([1.0, 0.0, 0.0]), R[:, :, 1])
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    np.testing.assert_allclose(W[:, 0, :3], 0.0, atol=1e-9)
    np.testing.assert_allclose(np.abs(np.einsum("ni,ni->n", W[:, 0, 3:], c)), 1.0, atol=1e-9)


def test_mechanism_of_chain_limbs_is_compiled_and_agrees():
    """A 6-SPU (structures("3T3R")): feasibility and margins on the compiled path (no
    fallback warning), equal to the NumPy reference's."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        m = parasynth.structures("3T3R", leg_types=["SPU"], legs=[6])[0].mechanism()
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    X = lo + (hi - lo) * np.random.default_rng(2).uniform(0, 1, (600, len(lo)))
    with warnings.catch_warnings():
        warnings.simplefilter("error", EngineFallbackWarning)
        fc = engine.feasible(m, X)
        mc = engine.margins(m, X)
    fn = m.is_feasible(X, engine="numpy")
    mn = m.constraint_margins(X, engine="numpy")
    near = np.zeros(len(X), bool)
    for k in mn:
        fin = np.isfinite(mn[k])
        assert np.array_equal(fin, np.isfinite(mc[k])), k
        np.testing.assert_allclose(mc[k][fin], mn[k][fin], rtol=0, atol=1e-9, err_msg=k)
        near |= fin & (np.abs(mn[k]) < 1e-9)
    assert np.array_equal(fc[~near], fn[~near])
    assert 0 < fn.sum() < len(X)


def test_chain_kernel_one_signature_and_compiled_only_for_chain_limbs():
    """A mechanism without chain limbs never loads the chain kernel; a chain limb's solve uses
    the one specialisation of chains.signatures()."""
    code = ("import numpy as np, warnings; warnings.simplefilter('ignore')\n"
            "from parasynth import engine\n"
            "from parasynth.mechanisms import load_mechanism\n"
            "from parasynth.engine import chains\n"
            "m = load_mechanism('5pus_upu'); engine.exercise(m)\n"
            "print(len(chains._chain_kernel.signatures))\n"
            "from parasynth.model.chains import SPU\n"
            "leg = SPU('L', base=[0.3, 0.0, 0.0], platform=[0.1, 0.0, 0.0])\n"
            "chains.solve(leg, np.array([[0.0, 0.0, 0.4]]), np.eye(3)[None])\n"
            "disp, sig = chains.signatures()['_chain_kernel']\n"
            "print([tuple(s) for s in disp.signatures] == [tuple(sig)])\n")
    r = subprocess.run([sys.executable, "-c", code], env=dict(os.environ), capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["0", "True"], r.stdout + r.stderr


# -- the compiled closure (ChainLeg.closure_solve / closure_residuals) ---------------------------------
def _near_home(n, seed, amp=0.04, turn=0.1):
    """Poses near the limb's home (positions within ``amp``, rotations up to ``turn`` rad about
    random axes): the closure's least-squares reach converges there for every limb type, on or
    off its motion."""
    rng = np.random.default_rng(seed)
    p = np.array([0.0, 0.0, 0.4]) + rng.uniform(-amp, amp, (n, 3))
    axes = rng.normal(size=(n, 3))
    R = rot_axis(axes / np.linalg.norm(axes, axis=1, keepdims=True), rng.uniform(-turn, turn, n))
    return p, R


CHAIN_TYPES = [RPUR, PRUR, SPU, RRPS, RRUR, URPU, PRRS, RUU]


@pytest.mark.parametrize("cls", CHAIN_TYPES, ids=[c.__name__ for c in CHAIN_TYPES])
def test_compiled_closure_agrees_with_numpy(cls):
    """The compiled closure solve equals ChainLeg.closure_solve (two limbs of the same geometry,
    each with its own warm-start cache) on poses near home: the closure residuals to 1e-12 (they
    are dimensionless: position / limb length and rad), the joint coordinates to 1e-9; the same
    over a path of small steps (each solve warm-started from the last: the branch followed), and
    for a batch of a multiple of the size (the finite-difference Jacobian's perturbed poses)."""
    ref = cls("L", base=BASE, platform=PLAT)
    got = cls("L", base=BASE, platform=PLAT)
    p, R = _near_home(300, 7)
    for k in range(3):  # the first call from home, the others warm-started
        pk = p + 1e-3 * k
        qr, er = ref.closure_solve(pk, R)
        qg, eg = _chains().closure_solve(got, pk, R)
        np.testing.assert_allclose(eg, er, rtol=0, atol=1e-12)
        np.testing.assert_allclose(qg, qr, rtol=0, atol=1e-9)
        rr = ref.closure_residuals(pk, R)
        rg = _chains()._closure_of(got, pk, R)
        assert len(rg) == len(rr) == ref.n_closure
        for a, b in zip(rg, rr):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    # six perturbations of every pose: the warm start from the batch of 300 tiled
    E = np.repeat(np.eye(3)[None], 2, axis=0).reshape(6, 3) * np.array([1, 1, 1, -1, -1, -1])[:, None] * 1e-6
    pp = (p[None] + E[:, None, :]).reshape(-1, 3)
    RR = np.broadcast_to(R[None], (6,) + R.shape).reshape(-1, 3, 3)
    qr, er = ref.closure_solve(pp, RR)
    qg, eg = _chains().closure_solve(got, pp, RR)
    np.testing.assert_allclose(eg, er, rtol=0, atol=1e-12)
    np.testing.assert_allclose(qg, qr, rtol=0, atol=1e-9)
    # non-finite poses: NaN error on both
    pn = p[:4].copy()
    pn[1] = np.nan
    _, er = ref.closure_solve(pn, R[:4])
    _, eg = _chains().closure_solve(got, pn, R[:4])
    assert np.isnan(er[1]).all() and np.isnan(eg[1]).all()
    np.testing.assert_allclose(eg[[0, 2, 3]], er[[0, 2, 3]], rtol=0, atol=1e-12)


def test_compiled_closure_follows_the_branch_of_the_reference():
    """Along a path from home to 0.15 rad about x and back, each solve warm-started from the
    last: the compiled and the NumPy closure stay on the same branch (equal joint coordinates),
    and a compiled solve continues the cache the NumPy one left on the same limb (closure_start
    gives the compiled solution as the next start)."""
    ref = RPUR("L", base=BASE, platform=PLAT)
    got = RPUR("L", base=BASE, platform=PLAT)
    angles = np.r_[np.linspace(0.0, 0.15, 16), np.linspace(0.15, 0.0, 16)]
    p = np.array([[0.01, -0.02, 0.4]])
    for a in angles:
        R = rot_x(np.array([a])) @ rot_y(np.array([0.5 * a]))
        qr, er = ref.closure_solve(p, R)
        qg, eg = _chains().closure_solve(got, p, R)
        np.testing.assert_allclose(qg, qr, rtol=0, atol=1e-9)
        assert abs(float(er[0] @ ref._closure_dirs[:, 0])) < 1e-12  # on the 3T2R motion: assembles
    _, _, q0 = got.closure_start(p, R)
    np.testing.assert_array_equal(q0, qg)
    q1, _ = got.closure_solve(p, R)  # the NumPy solve from the compiled solution: already there
    np.testing.assert_allclose(q1, qg, rtol=0, atol=1e-12)


def test_closure_residuals_entry_point_uses_the_compiled_solve():
    """engine.closure_residuals: the compiled chain closure beside the closed-form legs' closure
    equations, equal to model.parasitic.closure_residuals; NumPy inside engine.reference()."""
    from parasynth.model import parasitic
    from parasynth.model.legs import RPS

    legs = [RPUR("L1", base=BASE, platform=PLAT), RPS("L2", base=[-0.3, 0.0, 0.0], platform=[-0.15, 0.0, 0.0],
                                                      r_axis=[0.0, 1.0, 0.0])]
    p, R = _near_home(50, 3)
    ref = parasitic.closure_residuals(legs, p, R, 0.4)
    legs[0]._closure_cache.clear()
    calls = []
    orig = _chains()._closure_kernel

    class Spy:
        def __call__(self, *a):
            calls.append(1)
            return orig(*a)

    _chains()._closure_kernel = Spy()
    try:
        got = engine.closure_residuals(legs, p, R, 0.4)
        assert calls
        n = len(calls)
        legs[0]._closure_cache.clear()
        with engine.reference():
            again = engine.closure_residuals(legs, p, R, 0.4)
        assert len(calls) == n
    finally:
        _chains()._closure_kernel = orig
    assert got.shape == ref.shape == (50, 2)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(again, ref)


# -- the compiled indices of mechanisms with chain limbs -------------------------------------------
@pytest.fixture(scope="module")
def chain_mechanisms():
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        for motion, types, legs in (("3T2R", ["RPUR", "PRUR", "RRUR"], [5]),
                                    ("3T3R", ["SPU", "RRPS", "URPU", "PRRS"], [6]), ("3T0R", ["RUU"], [3])):
            out += [s.mechanism() for s in parasynth.structures(motion, leg_types=types, legs=legs)]
    return out


def test_compiled_indices_of_chain_limbs_agree_with_numpy(chain_mechanisms):
    """Every chain limb type of the vocabulary (the 5-RPUR, 5-PRUR, 5-RRUR, 6-SPU, 6-RRPS,
    6-URPU, 6-PRRS, 3-RUU and the 3T3R mixes): the singularity margin, the transmission
    indices, the condition number, the leg directions and the constraint rank run compiled (no
    fallback warning) and equal the NumPy reference (ChainLeg.constraint_wrenches,
    actuation_wrench) on poses near home: margin and LTI to 1e-9, condition number to 1e-9
    relative, directions to 1e-12."""
    from parasynth.measures import indices as mi
    from parasynth.model.mechanism import Mechanism

    types = set()
    for m in chain_mechanisms:
        types |= {type(leg).__name__ for leg in m.legs}
        rng = np.random.default_rng(0)
        ang = np.isin(m.task_coordinates, m.angular_coordinates)
        X = m.home + rng.uniform(-1, 1, (120, len(m.home))) * np.where(ang, 0.1, 0.02)
        X[-1] = np.nan  # an invalid pose: NaN on both
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", EngineFallbackWarning)
            assert engine.coverage(m) == (True, "")
            a = m.singularity_margin(X)
            la = mi.local_transmission_index(m, X)
            ka = mi.local_condition_number(m, X)
            da, ra = engine.leg_directions(m, X)
            rank = m.structural_constraint_rank()
        assert not engine_fallbacks(m, caught), m.name
        b = m.singularity_margin(X, engine="numpy")
        fin = np.isfinite(b)
        assert fin.sum() >= 100, m.name
        assert np.array_equal(fin, np.isfinite(a)), m.name
        np.testing.assert_allclose(a[fin], b[fin], rtol=0, atol=1e-9, err_msg=m.name)
        lb = mi.local_transmission_index(m, X, engine="numpy")
        np.testing.assert_allclose(la[fin], lb[fin], rtol=0, atol=1e-9, err_msg=m.name)
        kb = mi.local_condition_number(m, X, engine="numpy")
        np.testing.assert_allclose(ka[fin], kb[fin], rtol=1e-9, atol=0, err_msg=m.name)
        _, st, _ = m.leg_states(X)
        db = np.stack([s.direction for s in st], 1)
        np.testing.assert_allclose(da[fin], db[fin], rtol=0, atol=1e-12, err_msg=m.name)
        assert rank == Mechanism.structural_constraint_rank(m, engine="numpy"), m.name
    assert {"RPUR", "PRUR", "RRUR", "SPU", "RRPS", "URPU", "PRRS", "RUU"} <= types


def test_compiled_margin_of_a_mixed_mechanism_at_explicit_poses(chain_mechanisms):
    """Chain limbs beside a closed-form leg (the 3-RUU/UPU of 3T0R: three RUU limbs and a
    central UPU, its motion solved on their closure equations): the compiled margin, also at
    explicit poses (engine.singularity_margin_at), equal to the NumPy margin of the states."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        m = next(s for s in parasynth.structures("3T0R", leg_types=["RUU", "UPU"])
                 if s.name == "3-RUU/UPU").mechanism()
    assert {type(leg).__name__ for leg in m.legs} == {"RUU", "UPU"}
    rng = np.random.default_rng(4)
    ang = np.isin(m.task_coordinates, m.angular_coordinates)
    X = m.home + rng.uniform(-1, 1, (80, len(m.home))) * np.where(ang, 0.1, 0.02)
    _, states, p = m.leg_states(X)
    R = m._pose(X)[1]
    reach = np.logical_and.reduce([s.reachable for s in states])
    ref = m.singularity_margin_of_states(states, p, reach)
    got = engine.singularity_margin_at(m.legs, p, R, m.n_actuators, m.constraint_rank, m.length_scale)
    assert got is not None and reach.sum() >= 60
    np.testing.assert_allclose(got[reach], ref[reach], rtol=0, atol=1e-9)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", EngineFallbackWarning)
        a = m.singularity_margin(X)
    assert not engine_fallbacks(m, caught)
    b = m.singularity_margin(X, engine="numpy")
    fin = np.isfinite(b)
    assert np.array_equal(fin, np.isfinite(a)) and fin.sum() >= 60
    np.testing.assert_allclose(a[fin], b[fin], rtol=0, atol=1e-9)


@pytest.mark.parametrize("motion,types", [("3T0R", ["RUU"]), ("2T2R", ["RPUR", "RPS"])])
def test_motion_solved_on_chain_limbs_poses_with_the_compiled_closure(motion, types):
    """A structure whose task.solve closes on chain limbs (the 3-RUU, the 4-RPUR/RPS): the
    compiled engine solves its dependent coordinates by the model's Gauss-Newton with the chain
    limbs' closure by the compiled solve; feasibility and margins agree with the NumPy engine,
    the unknowns with the NumPy solve to 1e-12, and the NumPy model keeps its own solve (the
    reference never sees the compiled closure's unknowns)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        s = next(s for s in parasynth.structures(motion, leg_types=types)
                 if any(hasattr(leg, "chain_arrays") for leg in s.mechanism()._solve_legs))
        m, ref = s.mechanism(), s.mechanism()
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    X = lo + (hi - lo) * np.random.default_rng(6).uniform(0, 1, (150, len(lo)))
    chains = _chains()
    asked = []
    real = m.solve_unknowns
    m.solve_unknowns = lambda Xq, chain=None: asked.append(chain) or real(Xq, chain=chain)
    fc, mc = engine.feasible(m, X), engine.margins(m, X)
    assert asked and all(c is chains._closure_of for c in asked)  # the compiled closure was used
    fn, mn = ref.is_feasible(X, engine="numpy"), ref.constraint_margins(X, engine="numpy")
    assert 0 < fn.sum() < len(X)
    assert np.array_equal(fc, fn)
    for k in mn:
        fin = np.isfinite(mn[k])
        assert np.array_equal(fin, np.isfinite(mc[k])), k
        np.testing.assert_allclose(mc[k][fin], mn[k][fin], rtol=0, atol=1e-9, err_msg=k)
    Uc = real(X, chain=chains._closure_of)
    Un = ref.solve_unknowns(X)
    ok = np.isfinite(Un).all(axis=1)
    assert ok.sum() > 0 and np.array_equal(ok, np.isfinite(Uc).all(axis=1))
    np.testing.assert_allclose(Uc[ok], Un[ok], rtol=0, atol=1e-12)
    # the compiled path left the model's own cache alone: asked again, it solves with the NumPy closure
    before = m._solve_cache
    engine.feasible(m, X)
    assert m._solve_cache is before


@pytest.mark.parametrize("motion,types", [("3T0R", ["RUU"]), ("2T2R", ["RPUR", "RPS"])])
def test_pose_batch_of_a_motion_closing_on_chain_limbs_solves_the_closure_compiled(motion, types):
    """The pose program does not hold a chain limb's closure: pose_batch of such a structure
    solves its dependent coordinates with the chain limbs' closure by the compiled solve (the
    twist map's implicit derivatives too), without a fallback warning, and gives the NumPy
    engine's validity and poses (to 1e-12) and twist maps (to 1e-8 of their size, pose by pose:
    both take five-point differences of closures solved to ~1e-14); the NumPy model keeps its
    own solve. The twist maps are compared one pose at a time on new models: a chain limb's
    closure starts each pose from the branch of the pose solved before it, and the NumPy
    reference's own twist map of a batch differs from its pose-by-pose one by up to ~1e-3 of its
    size at some poses of a 3-RUU (the rotation rows; docs/structures.md)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        s = next(s for s in parasynth.structures(motion, leg_types=types)
                 if any(hasattr(leg, "chain_arrays") for leg in s.mechanism()._solve_legs))
        m, ref = s.mechanism(), s.mechanism()
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    X = np.vstack([m.home, lo + (hi - lo) * np.random.default_rng(2).uniform(0, 1, (40, len(lo)))])
    chains = _chains()
    asked = []
    real = m.solve_unknowns
    m.solve_unknowns = lambda Xq, chain=None: asked.append(chain) or real(Xq, chain=chain)
    closures = []
    real_closure = m._closure
    m._closure = lambda Xq, Uq, chain=None: closures.append(chain) or real_closure(Xq, Uq, chain)
    before = m._solve_cache
    core = pytest.importorskip("parasynth.engine.core")
    core._WARNED.clear()
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        valid, p, R, T = engine.pose_batch(m, X, twist=True)
    assert not [x for x in w if issubclass(x.category, EngineFallbackWarning)], [str(x.message) for x in w]
    assert asked and all(c is chains._closure_of for c in asked)  # the unknowns: compiled closure
    assert closures and all(c is chains._closure_of for c in closures)  # and their derivatives
    assert m._solve_cache is before
    vn, pn, Rn, Tn = engine.pose_batch(ref, X, twist=True, engine="numpy")
    assert np.array_equal(valid, vn) and valid[0] and 0 < valid.sum()
    np.testing.assert_allclose(p[valid], pn[valid], rtol=0, atol=1e-12)
    np.testing.assert_allclose(R[valid], Rn[valid], rtol=0, atol=1e-12)
    scale = np.max(np.abs(Tn[valid]))
    for x in X[valid][:6]:
        Tc1 = engine.pose_batch(s.mechanism(), x[None], twist=True)[3][0]
        Tn1 = engine.pose_batch(s.mechanism(), x[None], twist=True, engine="numpy")[3][0]
        np.testing.assert_allclose(Tc1, Tn1, rtol=0, atol=1e-8 * scale)


def test_partial_unknowns_take_unsolved_rows_as_unsolved():
    """use_solved_unknowns(..., partial=True): NaN rows of the function's unknowns are taken as
    poses whose solve did not converge (as the NumPy solve marks them); a full set refuses them,
    and partial unknowns come from a function only."""
    m = next(s for s in parasynth.structures("1T2R") if s.name == "3-RPS").mechanism()
    X = np.array([m.home, m.home + np.array([0.01, 0.05, -0.05])])
    U = m.solved_unknowns(X).copy()
    m._solve_cache = None
    V = U.copy()
    V[1] = np.nan
    m.use_solved_unknowns(X, lambda: V, partial=True)
    assert np.array_equal(m.solved_unknowns(X), V, equal_nan=True)
    m._solve_cache = None
    m.use_solved_unknowns(X, lambda: V)  # not partial: the NumPy solve runs instead
    np.testing.assert_array_equal(m.solved_unknowns(X), U)
    with pytest.raises(ValueError, match="function"):
        m.use_solved_unknowns(X, V, partial=True)


# -- feasibility: a chain limb solved only where the legs before it keep their own limits ----------
@pytest.mark.parametrize("motion, types, legs", [("3T2R", ["RPUR"], [5]), ("2T2R", ["RPU", "URPU"], [4])],
                         ids=["5-RPUR", "2-RPU&2-URPU"])
def test_feasibility_solves_a_chain_limb_only_where_the_legs_before_it_keep_their_limits(motion, types, legs):
    """``engine.feasible`` of a structure with chain limbs (all chains: a 5-RPUR; closed-form RPU
    legs before two URPU chains): a chain limb is solved only at the poses where every leg
    before it keeps its own stroke and joint-angle limits (``leg_gate``) and where its own
    length (first joint centre to the target anchor) is not clearly outside its stroke
    (``_length_gate``), fewer poses than without these gates, and the answer is exactly that
    of the context with every limb solved at every pose reachable by the legs before it
    (``feasible_rows`` of the ungated context), and the NumPy reference's away from a
    boundary."""
    from parasynth.model.constraints import feasible_rows

    ch = _chains()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        # a short stroke (120 mm), so that the legs' own limits decide part of the poses
        m = parasynth.structures(motion, leg_types=types, legs=legs)[0].mechanism(stroke=0.12)
    assert any(type(c).__name__ in ("LegLengthRange", "JointAngleLimit") for c in m.constraints.values())
    rng = np.random.default_rng(5)
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    # half the poses near home (mostly feasible), half over the box (mostly not)
    ang = np.isin(m.task_coordinates, m.angular_coordinates)
    X = np.concatenate([m.home + rng.uniform(-1, 1, (300, len(lo))) * np.where(ang, 0.15, 0.06),
                        lo + (hi - lo) * rng.uniform(0, 1, (300, len(lo)))])
    solved = []
    orig = ch.solve

    def counting(leg, p, R, joint_angles=True, arrays=False):
        solved.append(p.shape[0])
        return orig(leg, p, R, joint_angles, arrays)

    ch.solve = counting
    try:
        cons = m._select(None)
        gated = ch.feasible(m, X)
        n_gated, first_gated = sum(solved), solved[0]
        solved.clear()
        ctx = ch.context(m, X)
        full = feasible_rows(ctx, cons)
        n_full = sum(solved)
    finally:
        ch.solve = orig
    # the length the gate reads before the solve: within its slack of the solved state's
    for leg, st in zip(m.legs, ctx.states):
        d = leg.chain_arrays() if hasattr(leg, "chain_arrays") else None
        if d is None or d["kinds"][0] != 0:
            continue
        r = st.reachable
        A = ctx.p[r] + np.einsum("nij,j->ni", ctx.R[r], leg.platform)
        gap = np.abs(np.linalg.norm(A - d["points"][0], axis=1) - st.length[r])
        assert r.any() and gap.max() <= 10.0 * ch.REACH_FACTOR * IK_TOL * d["length"], gap.max()
    assert n_gated < n_full, (n_gated, n_full)
    if motion == "3T2R":  # the first limb too: its stroke read from the target anchor before its solve
        assert first_gated < len(X), first_gated
    assert np.array_equal(gated, full)
    assert 0 < gated.sum() < len(X)
    ref = m.is_feasible(X, engine="numpy")
    mn = m.constraint_margins(X, engine="numpy")
    near = np.zeros(len(X), bool)
    for v in mn.values():
        near |= np.isfinite(v) & (np.abs(v) < 1e-9)
    assert np.array_equal(gated[~near], ref[~near])


def test_leg_gate_reads_only_the_limits_of_one_leg():
    """``leg_gate``: the stroke (ActuatorRange, LegLengthRange) and joint-angle limits of the
    given leg, None for constraints that need several legs (interference) or a subclass whose
    margin may differ."""
    from dataclasses import dataclass

    from parasynth.model.constraints import ActuatorRange, JointAngleLimit, LegInterference, LegLengthRange, leg_gate

    leg = UPS("L1", base=[0.3, 0.0, 0.0], platform=[0.1, 0.0, 0.0])
    st = leg.solve(np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.5], [0.0, 0.0, 0.7]]), np.repeat(np.eye(3)[None], 3, 0))
    q = st.actuator
    assert leg_gate([LegInterference("i", diameter=0.01)], leg, st) is None
    np.testing.assert_array_equal(leg_gate([ActuatorRange("a", lo=q[0] + 1e-9, hi=q[2])], leg, st),
                                  [False, True, True])
    np.testing.assert_array_equal(leg_gate([LegLengthRange("l", legs=("L2",), lo=1.0)], leg, st) is None, True)
    np.testing.assert_array_equal(leg_gate([LegLengthRange("l", legs=("L1",), lo=0.0, hi=q[1])], leg, st),
                                  [True, True, False])
    key = next(iter(st.angles))
    a = st.angles[key]
    lim = JointAngleLimit("j", key=key, lo=-np.inf, hi=float(np.sort(a)[1]))
    np.testing.assert_array_equal(leg_gate([lim], leg, st), a <= lim.hi)

    @dataclass(frozen=True)
    class Shifted(ActuatorRange):
        def margin(self, ctx):
            return super().margin(ctx) + 1.0

    assert leg_gate([Shifted("s", lo=10.0)], leg, st) is None


def test_the_margin_at_the_feasible_poses_reuses_the_feasibility_solve():
    """After ``engine.feasible`` a chain limb keeps its solve at the feasible poses: the
    singularity margin at exactly those poses (what the workspace measures ask) does not solve
    the limbs again and equals, bit for bit, the margin of a mechanism that solves them anew;
    at other poses the limbs are solved."""
    ch = _chains()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        s = parasynth.structures("3T2R", leg_types=["RPUR"], legs=[5])[0]
        m, fresh = s.mechanism(), s.mechanism()
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    X = lo + (hi - lo) * np.random.default_rng(8).uniform(0, 1, (400, len(lo)))
    ok = engine.feasible(m, X)
    assert 10 < ok.sum() < len(X)
    assert m.constraint_rank == fresh.constraint_rank  # (at home: the limbs solved there, once)
    calls = []
    orig = ch._chain_kernel

    def counting(*a):
        calls.append(a[0].shape[0])
        return orig(*a)

    ch._chain_kernel = counting
    try:
        kept = m.singularity_margin(X[ok])
        assert not calls
        other = m.singularity_margin(X[ok][::2])  # other poses: solved
        assert calls
    finally:
        ch._chain_kernel = orig
    ref = fresh.singularity_margin(X[ok])
    assert np.array_equal(kept, ref, equal_nan=True)
    np.testing.assert_array_equal(other, ref[::2])


def _wide_poses(n, seed, motion):
    """Poses of a motion (3T2R: rotations about x then the moving y; else level) over a box much
    wider than the limb's reach, so that most are out of it."""
    rng = np.random.default_rng(seed)
    p = np.array([0.0, 0.0, 0.4]) + rng.uniform(-0.5, 0.5, (n, 3))
    if motion == "3T2R":
        R = rot_x(rng.uniform(-0.4, 0.4, n)) @ rot_y(rng.uniform(-0.4, 0.4, n))
    else:
        R = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    return p, R


@pytest.mark.parametrize("cls, motion, test, trailing, least", [
    (RRUR, "3T2R", "axial", True, 0.99), (PRUR, "3T2R", "axial", True, 0.9), (RPUR, "3T2R", "cone", False, 0.8),
    (RUU, "3T0R", "axial", False, 0.3), (SPU, "3T3R", None, False, 0), (RRPS, "3T3R", None, False, 0),
    (URPU, "3T3R", None, False, 0), (PRRS, "3T3R", "axial", False, 0.3)],
    ids=["RRUR", "PRUR", "RPUR", "RUU", "SPU", "RRPS", "URPU", "PRRS"])
def test_the_reach_gate_refuses_only_poses_the_solve_does_not_reach(cls, motion, test, trailing, least):
    """``reach_gate`` refuses no pose that the compiled solve reaches, over random limbs (anchors
    and platform anchors) and poses mostly out of reach. The chains with the axial test (the
    anchor's component along the leading revolutes' axis against the reach of the chain after
    them, engine/chains.py ``axial_reach``: their leading revolutes parallel, their prismatic
    joints before them normal to them, only revolutes after: RRUR, PRUR, RUU, PRRS) are gated,
    and those whose revolutes after the leading ones are parallel to the last (RRUR, PRUR) also
    by the line test (``trailing_reach``): on these poses the two refuse all but a thousandth of
    the poses the solve does not reach for the RRUR, ~0.93 for the PRUR (the axial test alone:
    0.88, 0.42), ~0.35 for the RUU and PRRS. The RPUR (its slider along the limb after its first
    revolute) has the cone test (``cone_reach``: the universal joint's centre on the cone the
    slider sweeps, within the trailing link's reach of the anchor): ~0.84. The SPU's, RRPS's and
    URPU's six freedoms reach the poses about as far as their sliders go: not gated. Each test's
    own bound is checked on the solved configurations."""
    ch = _chains()
    rng = np.random.default_rng(17)
    refused = caught = unreached = 0
    for trial in range(6):
        ab, ap = rng.uniform(0, 2 * np.pi, 2)
        rb, rp = rng.uniform(0.15, 0.35), rng.uniform(0.05, 0.2)
        leg = cls("L", base=[rb * np.cos(ab), rb * np.sin(ab), 0.0], platform=[rp * np.cos(ap), rp * np.sin(ap), 0.0])
        p, R = _wide_poses(1500, trial, motion)
        ok = ch.reach_gate(leg, p, R)
        assert (ch.trailing_reach(leg) is not None) == trailing
        assert (ch.axial_reach(leg) is not None) == (test == "axial")
        assert (ch.cone_reach(leg) is not None) == (test == "cone")
        if test is None:
            assert ok is None
            continue
        reached = ch.solve(leg, p, R, joint_angles=False).reachable
        assert reached.any() and (~reached).any()
        assert not (reached & ~ok).any(), np.flatnonzero(reached & ~ok)
        refused += int((~ok).sum())
        caught += int((~ok & ~reached).sum())
        unreached += int((~reached).sum())
        out = ch.solve_arrays(leg, p[reached], R[reached])
        d = leg.chain_arrays()
        if test == "cone":
            # the universal joint's centre c of each solved configuration: on the cone about the
            # first axis (the same angle to it from the apex as at home, either nappe) and within
            # rho of the anchor moved back along the platform's last axis
            t = ch.cone_reach(leg)
            c = out["points"][:, 2]
            v = c - t["apex"]
            cosang = (v @ t["a"]) / np.linalg.norm(v, axis=1)
            np.testing.assert_allclose(np.abs(cosang), abs(t["cos"]), rtol=0, atol=1e-9)
            Ab = out["position"] - t["kb"] * (R[reached] @ t["b"])
            assert np.all(np.linalg.norm(Ab - c, axis=1) <= t["rho"] + 1e-9)
            continue
        # the axial test's own bound: the component along the leading axis of the anchor minus
        # that of the first joint centre after the leading freedoms never exceeds the reach of
        # the chain after them
        a, h, reach, _ = ch.axial_reach(leg)
        k = next(m for m in range(len(d["kinds"])) if not (
            (d["kinds"][m] == 0 and np.linalg.norm(np.cross(d["axes"][m], a)) < 1e-9)
            or (d["kinds"][m] == 1 and abs(d["axes"][m] @ a) < 1e-9)))
        np.testing.assert_allclose(out["points"][:, k] @ a, h, rtol=0, atol=1e-12)
        assert np.all(np.abs(out["position"] @ a - h) <= reach + 1e-12)
    if test is not None:
        assert refused == caught > 0  # every refused pose is one the solve does not reach (asserted above)
        assert caught >= least * unreached, caught / unreached


def test_a_context_for_constraints_that_read_no_joint_angle_skips_them_with_the_same_answers():
    """The chain engine's feasibility and margins of constraints none of which reads a passive
    joint angle (``Constraint.reads_angles``: strokes, lengths, interference) solve the legs
    without their angles (closed-form legs by ``solve_geometry``, chain limbs without frames),
    with the same answers as a context with them; a joint-angle limit among them brings the
    angles back."""
    from parasynth.model.constraints import JointAngleLimit, feasible_rows

    ch = _chains()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EngineFallbackWarning)
        m = parasynth.structures("2T2R", leg_types=["RPU", "RRPS"], legs=[4])[0].mechanism(stroke=0.2)
    rng = np.random.default_rng(8)
    lo, hi = (np.array(v) for v in zip(*[m.default_ranges()[k] for k in m.task_coordinates]))
    X = np.concatenate([m.home + rng.uniform(-0.05, 0.05, (300, len(lo))), lo + (hi - lo) * rng.uniform(0, 1, (300, len(lo)))])
    plain = [c.name for c in m.constraints.values() if not c.reads_angles]
    assert plain and ch.needs_angles(m._select(None)) == any(
        isinstance(c, JointAngleLimit) for c in m.constraints.values())
    asked = []
    orig = ch.solve

    def recording(leg, p, R, joint_angles=True, arrays=False):
        asked.append(joint_angles)
        return orig(leg, p, R, joint_angles, arrays)

    ch.solve = recording
    try:
        got = ch.feasible(m, X, plain)
        assert asked and not any(asked)
        margins = ch.margins(m, X, plain)
        asked.clear()
        ctx = ch.context(m, X)  # every angle
        assert asked and all(asked)
    finally:
        ch.solve = orig
    assert all(st.angles for st in ctx.states)
    cons = m._select(plain)
    assert np.array_equal(got, feasible_rows(ctx, cons) & ctx.reachable)
    assert 0 < got.sum() < len(X)
    for c in cons:
        ref = np.where(ctx.reachable, np.asarray(c.margin(ctx), float), -np.inf)
        np.testing.assert_array_equal(margins[c.name], np.where(np.isnan(ref), -np.inf, ref))
    # a joint-angle limit reads them: the context is built with them
    limited = m.with_constraints(JointAngleLimit("cone", key="S_platform_cone", hi=0.6))
    assert ch.needs_angles(limited._select(None)) and not limited.constraints["cone"].vacuous
    ok = ch.feasible(limited, X, plain + ["cone"])
    full = ch.context(limited, X)
    assert np.array_equal(ok, feasible_rows(full, limited._select(plain + ["cone"])) & full.reachable)
    assert ok.sum() < got.sum()
    # but not a cone limit of 180 deg (cone angles lie in [0, pi]): the feasibility leaves it out
    loose = m.with_constraints(JointAngleLimit("cone", key="S_platform_cone", hi=np.pi))
    assert loose.constraints["cone"].vacuous
    ch.solve = recording
    try:
        asked.clear()
        same = ch.feasible(loose, X, plain + ["cone"])
        assert asked and not any(asked)
    finally:
        ch.solve = orig
    assert np.array_equal(same, got)
    full = ch.context(loose, X)
    assert np.array_equal(same, feasible_rows(full, loose._select(plain + ["cone"])) & full.reachable)


@pytest.mark.parametrize("cls, poses, form", [(RRPS, _general_poses, "RRP-S"), (SPU, _general_poses, "SP-U"),
                                              (RRUR, _3t2r_poses, "RR-UR"), (PRUR, _3t2r_poses, "PR-UR")],
                         ids=["RRPS", "SPU", "RRUR", "PRUR"])
def test_the_compiled_closed_form_agrees_with_the_reference_and_with_the_numerical_solve(cls, poses, form):
    """A closed form in the kernel: the coordinates of the NumPy closed form (to rounding), reached
    to rounding (the numerical solve stops at its tolerance, so the kernel took the closed form),
    a pose without a solution in the home working mode out of reach (residual infinite, as in
    NumPy); the same limb with its closed form taken away (``closed=False``) is solved by the
    kernel's Levenberg-Marquardt to the same coordinates within that tolerance."""
    leg = cls("L", base=BASE, platform=PLAT)
    assert leg.closed_form == form
    p, R = poses(2000, 8)
    out = _chains().solve_arrays(leg, p, R)
    q_ref, res_ref = leg.inverse(p, R)
    reach = out["residual"] < 1e3 * IK_TOL
    assert np.array_equal(reach, res_ref < 1e3 * IK_TOL) and reach.sum() >= 500
    np.testing.assert_allclose(out["q"][reach], q_ref[reach], rtol=0, atol=1e-12)
    assert out["residual"][reach].max() < 1e-13
    target = p + np.einsum("nij,j->ni", R, leg.platform)
    none = np.isnan(closed_form_solve(leg._closed, target, R)).any(axis=1)
    assert np.isinf(out["residual"][none]).all() and np.isfinite(out["residual"][~none]).all()
    bare = cls("L", base=BASE, platform=PLAT, closed=False)
    assert bare.closed_form is None
    num = _chains().solve_arrays(bare, p, R)
    ok = (num["residual"] < 1e3 * IK_TOL) & reach
    assert ok.sum() >= 0.9 * reach.sum() and num["residual"][ok].max() > 1e-13
    np.testing.assert_allclose(num["q"][ok], out["q"][ok], rtol=0, atol=1e-6)


@pytest.mark.parametrize("limb", [chain_class("RP*S"), chain_class("P*RS"), chain_class("UP*U"), chain_class("P*UU"),
                                  RPUR, RRUR, RRPS, SPU, chain_class("RP*U")],
                         ids=["RP*S", "P*RS", "UP*U", "P*UU", "RPUR", "RRUR", "RRPS", "SPU", "RP*U"])
def test_the_compiled_rows_of_a_chain_limb_are_the_reference_wrenches(limb):
    """The per-pose rows of a chain limb (``indices._chain_ext``: the constraint wrenches, the
    actuation wrench and its rate) at 300 poses of the limb's own motion (the forward kinematics
    of random joint coordinates) equal the NumPy reference's (``ChainLeg.constraint_wrenches``,
    ``actuation_wrench``, by NumPy's SVD and QR) to 1e-9: one constraint force (RP*S, P*RS,
    UP*U, P*UU) or couple (RPUR, RRUR) -- the compiled null vector by Householder, up to its
    sign --, none (RRPS, SPU), two (RP*U: by Jacobi, the same span)."""
    from parasynth.engine import indices

    leg = limb("L", base=BASE, platform=PLAT)
    rng = np.random.default_rng(3)
    q = rng.uniform(-0.3, 0.3, (300, len(leg.chain_arrays()["kinds"])))
    pos, R, _, _ = leg.forward(q)
    p = pos - np.einsum("nij,j->ni", R, leg.platform)
    ext = indices._chain_ext([leg], indices._legs_plan([leg]), p, R)
    st = _chains().solve(leg, p, R)
    assert st.reachable.all() and (ext[:, 0] == 1.0).all()  # every pose of the motion reached
    k = leg.n_closure
    W = leg.constraint_wrenches(st, p)
    Wg = ext[:, indices._EXT_C:indices._EXT_C + 6 * k].reshape(len(p), k, 6)
    assert W.shape == Wg.shape
    if k == 1:
        force = np.linalg.norm(W[:, 0, :3], axis=1) > 0.5
        assert force.all() == (leg.constraint_rows == ("length",)) and force.any() == force.all()
        sign = np.sign(np.einsum("ni,ni->n", W[:, 0], Wg[:, 0]))
        np.testing.assert_allclose(Wg[:, 0], sign[:, None] * W[:, 0], rtol=0, atol=1e-9)
    else:
        for a, b in zip(W, Wg):
            np.testing.assert_allclose(_span(b), _span(a), rtol=0, atol=1e-9)
    wa, rate = leg.actuation_wrench(st, p)
    np.testing.assert_allclose(ext[:, indices._EXT_A:indices._EXT_A + 6], wa, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ext[:, indices._EXT_S], rate, rtol=0, atol=1e-9)
