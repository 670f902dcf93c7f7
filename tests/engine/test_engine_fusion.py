"""Fused program instructions (parasynth.engine.program._fuse) compute exactly what the
unfused instructions compute: same poses, rotations, twist maps, margins and feasibility,
bit for bit, on every shipped mechanism and on random descriptions."""

import numpy as np
import pytest

from parasynth import load_mechanism
from parasynth.engine import core
from parasynth.engine import program as program_mod
from parasynth.mechanisms import list_mechanisms
from parasynth.mechanisms.description import DescribedMechanism

pytestmark = pytest.mark.skipif(not core.HAVE_NUMBA, reason="numba not importable")

FUSED = {program_mod.OPS[k] for k in ("madd", "msub", "rmsub", "mmadd", "mmsub")}


def _poses(mech, n=3000, seed=1):
    rng = np.random.default_rng(seed)
    scale = np.array([0.6 if c in mech.angular_coordinates else 0.4 * mech.length_scale
                      for c in mech.task_coordinates])
    return np.ascontiguousarray(mech.home + scale * rng.uniform(-1, 1, size=(n, mech.n_task)))


def _programs(mech, exprs, twist, monkeypatch):
    fused = program_mod.build_program(mech, exprs, twist)
    with monkeypatch.context() as m:
        m.setattr(program_mod, "_fuse", lambda code, uses: code)
        plain = program_mod.build_program(mech, exprs, twist)
    return fused, plain


def _same(a, b):
    return np.array_equal(a, b, equal_nan=True)


def _described():
    out = []
    for name in list_mechanisms():
        try:
            m = load_mechanism(name)
        except Exception:  # pragma: no cover - a model that needs arguments
            continue
        if isinstance(m, DescribedMechanism):
            out.append(name)
    return out


@pytest.mark.parametrize("name", _described())
def test_fused_pose_and_twist_bitwise(name, monkeypatch):
    mech = load_mechanism(name)
    X = _poses(mech)
    for twist in (False, True):
        fused, plain = _programs(mech, {}, twist, monkeypatch)
        assert fused.ins.shape[0] <= plain.ins.shape[0]
        c1, c2 = fused.constants(mech._penv), plain.constants(mech._penv)
        for prog in (fused, plain):
            prog.pose_limit = core._pose_limit(mech)
        r1 = core.run_pose(fused, c1, X, twist)
        r2 = core.run_pose(plain, c2, X, twist)
        assert np.array_equal(r1[0], r2[0])
        v = r1[0]
        for a, b in zip(r1[1:], r2[1:]):
            if a is not None:
                assert _same(a[v], b[v])


def test_fusion_applies_to_the_paper_models():
    """The rotation and position of the 5-PUS/UPU are sums of products: fused."""
    mech = load_mechanism("5pus_upu")
    prog = program_mod.build_program(mech, {}, False)
    ops = set(prog.ins[:, 0].tolist())
    assert ops & FUSED


@pytest.mark.parametrize("seed", range(4))
def test_fused_margins_and_feasibility_random(seed, monkeypatch):
    from test_engine import _random_mechanism

    mech = _random_mechanism(seed)
    cons = mech._select(None)
    _, _, _, _, exprs, expr_rows = core.leg_tables(mech, cons)
    fused, plain = _programs(mech, exprs, False, monkeypatch)
    X = _poses(mech, 4000, seed)
    outs = []
    for prog in (fused, plain):
        prog.pose_limit = core._pose_limit(mech)
        plan = core.build_plan(mech, cons)
        plan.program = prog
        plan.consts = prog.constants(mech._penv)
        plan.expr = np.array([(prog.margin_regs[n], ci) for n, ci in expr_rows], dtype=np.int64).reshape(-1, 2)
        outs.append((core.run_feasible(plan, X)[0], core.run_margins(plan, X)[0]))
    assert np.array_equal(outs[0][0], outs[1][0])
    assert _same(outs[0][1], outs[1][1])


@pytest.mark.parametrize("name", ["5pus_upu", "3rps", "gough_stewart_6ups"])
def test_huge_coordinates_in_the_kernel_as_in_numpy(name):
    """The compiled entry points test coordinate magnitudes in the kernel (no NumPy masking
    pass): huge lengths and angles give the NumPy answer."""
    from parasynth import engine

    mech = load_mechanism(name)
    X = np.repeat(mech.home[None, :], 8, axis=0)
    lengths = [j for j, c in enumerate(mech.task_coordinates) if c not in mech.angular_coordinates]
    angles = [j for j, c in enumerate(mech.task_coordinates) if c in mech.angular_coordinates]
    X[1, lengths[0]] = 2e6
    X[2, lengths[-1]] = -1e300
    X[3, lengths[0]] = 1e6  # at the limit: evaluated
    if angles:
        X[4, angles[0]] += 2 * np.pi * 1e6
        X[5, angles[-1]] = 1e300
        X[7, angles[0]] = np.inf  # not finite: rejected whether or not huge angles are masked
    X[6, 0] = np.nan
    ref = mech.is_feasible(X, engine="numpy")
    assert np.array_equal(engine.feasible(mech, X), ref)
    assert ref[0] and not ref[1] and not ref[2]
    m_ref = mech.constraint_margins(X, engine="numpy")
    m = engine.margins(mech, X)
    for k in m_ref:
        fin = np.isfinite(m_ref[k])
        assert np.array_equal(np.isneginf(m[k]), np.isneginf(m_ref[k]))
        assert np.allclose(m[k][fin], m_ref[k][fin], rtol=0, atol=1e-9)
    # the index kernels take the poses unmasked too (the pose program tests the limits)
    s_ref = mech.singularity_margin(X, engine="numpy")
    s = mech.singularity_margin(X)
    assert np.isnan(s_ref[1]) and np.isnan(s_ref[2])
    assert np.array_equal(np.isnan(s), np.isnan(s_ref))
    assert np.allclose(s[~np.isnan(s)], s_ref[~np.isnan(s_ref)], rtol=0, atol=1e-9)
